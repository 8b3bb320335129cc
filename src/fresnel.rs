//! Fresnel reflectance of dielectric and conductor boundaries.

use crate::lane::{Lane, Rgb};

/// Unpolarized reflectance of a dielectric boundary.
///
/// `cos_i` is the cosine of the incident direction with the normal that points
/// into the region *above* the boundary; `eta = n_below / n_above`. A negative
/// `cos_i` means incidence from below (then the relative IOR is `1 / eta`).
/// Returns 1 under total internal reflection. Exact at `eta = 1` (returns 0),
/// with no cancellation near it.
#[inline]
pub fn dielectric<L: Lane>(cos_i: L, eta: L) -> L {
    let below = cos_i.lt(L::zero());
    let eta = L::select(below, L::one() / eta, eta);
    let ci = cos_i.abs().min(L::one());
    let sin2_t = (L::one() - ci * ci) / (eta * eta);
    let tir = sin2_t.ge(L::one());
    let ct = (L::one() - sin2_t).safe_sqrt();
    // r_parallel and r_perpendicular; both denominators vanish only at ci = ct = 0.
    let dp = eta * ci + ct;
    let ds = ci + eta * ct;
    let ok = dp.gt(L::zero()) & ds.gt(L::zero()) & !tir;
    let rp = L::div_or_zero(eta * ci - ct, dp, ok);
    let rs = L::div_or_zero(ci - eta * ct, ds, ok);
    L::select(ok, L::splat(0.5) * (rp * rp + rs * rs), L::one())
}

/// Unpolarized reflectance of a conductor with complex relative IOR `eta + i k`
/// (per channel, relative to the region above), for incidence cosine `cos_i >= 0`.
#[inline]
pub fn conductor<L: Lane>(cos_i: L, eta: Rgb<L>, k: Rgb<L>) -> Rgb<L> {
    let ci = cos_i.abs().min(L::one());
    let c2 = ci * ci;
    let s2 = L::one() - c2;
    let per_channel = |eta: L, k: L| {
        let t0 = eta * eta - k * k - s2;
        // a² + b² = |(eta + ik)² - sin²|
        let a2b2 = (t0 * t0 + L::splat(4.0) * eta * eta * k * k).sqrt();
        let a = (L::splat(0.5) * (a2b2 + t0)).safe_sqrt();
        let t1 = a2b2 + c2;
        let t2 = L::splat(2.0) * a * ci;
        let tiny = L::splat(1e-30);
        let rs = (t1 - t2) / (t1 + t2).max(tiny);
        let t3 = c2 * a2b2 + s2 * s2;
        let t4 = t2 * s2;
        let rp = rs * (t3 - t4) / (t3 + t4).max(tiny);
        (L::splat(0.5) * (rs + rp)).clamp(L::zero(), L::one())
    };
    Rgb::new(
        per_channel(eta.r, k.r),
        per_channel(eta.g, k.g),
        per_channel(eta.b, k.b),
    )
}

/// Refracts `a` (pointing away from the boundary) through a microfacet with
/// unit normal `m` on `a`'s side; `eta = n_other / n_a`. Returns the refracted
/// direction (pointing away on the other side) and a mask, false under total
/// internal reflection (the direction is then unspecified but finite).
#[inline]
pub fn refract<L: Lane>(
    a: crate::lane::V3<L>,
    m: crate::lane::V3<L>,
    eta: L,
) -> (crate::lane::V3<L>, L::Mask) {
    let ci = a.dot(m);
    let sin2_t = (L::one() - ci * ci).max(L::zero()) / (eta * eta);
    let ok = sin2_t.lt(L::one());
    let ct = (L::one() - sin2_t).safe_sqrt();
    let inv = L::one() / eta;
    (-a * inv + m * (ci * inv - ct), ok)
}
