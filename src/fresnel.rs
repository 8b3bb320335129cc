//! Fresnel reflectance of dielectric and conductor boundaries.

use crate::lane::{Lane, Rgb};

/// Unpolarized reflectance of a dielectric boundary.
///
/// `cos_i` is the cosine of the incident direction with the normal that points
/// into the region *above* the boundary; `eta = n_below / n_above`. A negative
/// `cos_i` means incidence from below (then the relative IOR is `1 / eta`).
/// Returns 1 under total internal reflection. Exact at `eta = 1` (returns 0).
/// See [`dielectric_rt`] for the formulation.
#[inline]
pub fn dielectric<L: Lane>(cos_i: L, eta: L) -> L {
    dielectric_rt(cos_i, eta).0
}

/// Reflectance `R` and transmittance `T = 1 - R` of a dielectric boundary
/// (arguments as [`dielectric`]), each computed without cancellation.
///
/// With `ci`, `ct` the cosines on the two sides and `η` the relative IOR,
/// `ds = ci + η ct` and `dp = η ci + ct`, the amplitude ratios are written
///
/// * `rs = (ci - η ct) / ds = (1 - η²) / ds²`,
/// * `rp = (η ci - ct) / dp = (η² - 1)(ci² (η² + 1) - 1) / (η² dp²)`,
///
/// so that near `η = 1` they carry the factor `1 - η²` (computed as
/// `(η - 1)(η + 1)`, exact given `η`) instead of a difference of two nearly
/// equal cosines; `ct² = (η² - 1 + ci²) / η²` likewise. `T` is
///
/// * `T = 2 η ci ct (1 / ds² + 1 / dp²)`,
///
/// which at grazing incidence, where `R → 1`, keeps its full relative
/// precision (`1 - R` in single precision loses it: at cos 1e-7 and η = 1.5
/// the smooth coat's `1 - F` was 10 % off; see docs/numerics.md).
#[inline]
pub fn dielectric_rt<L: Lane>(cos_i: L, eta: L) -> (L, L) {
    let one = L::one();
    // η² - 1 from above, and from below (η → 1/η) without rounding 1/η first.
    let d = (eta - one) * (eta + one);
    let below = cos_i.lt(L::zero());
    let eta = L::select(below, one / eta, eta);
    let e2m1 = L::select(below, -d * eta * eta, d);
    let ci = cos_i.abs().min(one);
    let eta2 = eta * eta;
    // ct² = 1 - (1 - ci²) / η², written as a sum where η > 1.
    let ct2 = (e2m1 + ci * ci) / eta2;
    let tir = ct2.le(L::zero());
    let ct = ct2.safe_sqrt();
    // Both denominators vanish only at ci = ct = 0.
    let ds = ci + eta * ct;
    let dp = eta * ci + ct;
    let ok = dp.gt(L::zero()) & ds.gt(L::zero()) & !tir;
    let ds2 = ds * ds;
    let dp2 = dp * dp;
    let rs = L::div_or_zero(-e2m1, ds2, ok);
    let rp = L::div_or_zero(e2m1 * (ci * ci * (eta2 + one) - one), eta2 * dp2, ok);
    let r = L::splat(0.5) * (rs * rs + rp * rp);
    let t = L::splat(2.0)
        * eta
        * ci
        * ct
        * (L::div_or_zero(one, ds2, ok) + L::div_or_zero(one, dp2, ok));
    (L::select(ok, r, one), L::select(ok, t, L::zero()))
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
        // a = Re sqrt((eta + ik)² - sin²): (a2b2 + t0) / 2 cancels when
        // k > eta (every metal; at k = 1e3 it had lost every digit), so take
        // the larger of a², b² as (a2b2 + |t0|) / 2 and the other from ab = eta k.
        let big = (L::splat(0.5) * (a2b2 + t0.abs())).sqrt();
        let small = L::div_or_zero(eta * k, big, big.gt(L::zero()));
        let a = L::select(t0.ge(L::zero()), big, small);
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
