//! Fresnel reflectance of dielectric and conductor boundaries.
//!
//! Its functions are `#[inline(always)]` (docs/architecture.md, *Code
//! generation is part of the design*).

use crate::lane::{Lane, Rgb};

/// Unpolarized reflectance of a dielectric boundary.
///
/// `cos_i` is the cosine of the incident direction with the normal that points
/// into the region *above* the boundary; `eta = n_below / n_above`. A negative
/// `cos_i` means incidence from below (then the relative IOR is `1 / eta`).
/// Returns 1 under total internal reflection. Exact at `eta = 1` (returns 0),
/// with no cancellation near it. See [`dielectric_rt`] for the formulation.
#[inline(always)]
pub fn dielectric<L: Lane>(cos_i: L, eta: L) -> L {
    dielectric_rt(cos_i, eta).0
}

/// Reflectance `R` and transmittance `T = 1 - R` of a dielectric boundary
/// (arguments as [`dielectric`]), each computed without cancellation.
///
/// With `e` the relative IOR seen from the incident side, `d = e² - 1` and
/// `g = e cos θt = sqrt(cos²θi + d)`, the amplitudes are
/// `rs = (ci - g) / (ci + g) = -d / (ci + g)²` and
/// `rp = (e² ci - g) / (e² ci + g) = d (ci² (e² + 1) - 1) / (e² ci + g)²`:
/// both carry the factor `d`, computed as `(η - 1)(η + 1)` from `eta` itself
/// (never from a rounded `1 / eta`), so they vanish exactly at `eta = 1` and
/// keep full relative precision near it. The transmittance is computed
/// directly, `T = 2 ci g (1 / (ci + g)² + e² / (e² ci + g)²)`, which keeps its
/// relative precision where `R → 1` (at grazing incidence `1 - R` in single
/// precision loses it: at cos 1e-7 and η = 1.5 a smooth coat's `1 - F` was
/// 23 % off; see docs/numerics.md).
#[inline(always)]
pub fn dielectric_rt<L: Lane>(cos_i: L, eta: L) -> (L, L) {
    let one = L::one();
    let below = cos_i.lt(L::zero());
    let eta2 = eta * eta;
    let d_above = (eta - one) * (eta + one);
    // Seen from below: e = 1 / eta, e² - 1 = -(eta² - 1) / eta².
    let e2 = L::select(below, one / eta2, eta2);
    let d = L::select(below, -d_above / eta2, d_above);
    let ci = cos_i.abs().min(one);
    let g2 = ci * ci + d;
    let tir = g2.lt(L::zero());
    let g = g2.safe_sqrt();
    // (ci + g)² and (e² ci + g)², expanded with g² = ci² + d so that at grazing
    // incidence they equal d exactly (and F is exactly 1). Where d < 0 (the
    // dense side, short of TIR) |d| < ci², so nothing cancels. Both vanish only
    // at ci = g = 0, i.e. grazing incidence on an index-matched boundary
    // (d = 0), where the numerators vanish too.
    let ds = L::splat(2.0) * ci * (ci + g) + d;
    let dp = ci * (e2 * e2 * ci + L::splat(2.0) * e2 * g + ci) + d;
    let (ok_s, ok_p) = (ds.gt(L::zero()), dp.gt(L::zero()));
    let rs = L::div_or_zero(-d, ds, ok_s);
    let rp = L::div_or_zero(d * (ci * ci * (e2 + one) - one), dp, ok_p);
    let r = L::select(tir, one, L::splat(0.5) * (rs * rs + rp * rp));
    // 2 ci g / (ci + g)² <= 1/2: each term is finite even where ds is tiny.
    let cg2 = L::splat(2.0) * ci * g;
    let t = L::div_or_zero(cg2, ds, ok_s) + L::div_or_zero(cg2 * e2, dp, ok_p);
    (r, L::select(tir, L::zero(), t))
}

/// Unpolarized reflectance of a conductor with complex relative IOR `eta + i k`
/// (per channel, relative to the region above), for incidence cosine `cos_i >= 0`.
#[inline(always)]
pub fn conductor<L: Lane>(cos_i: L, eta: Rgb<L>, k: Rgb<L>) -> Rgb<L> {
    let ci = cos_i.abs().min(L::one());
    let c2 = ci * ci;
    let s2 = L::one() - c2;
    let per_channel = |eta: L, k: L| {
        // z = (eta + ik)² - sin²θ = t0 + i im; a + ib = sqrt(z). t0 is
        // written (eta² - 1) - k² + cos²θ: 1 - cos²θ would round away cos²θ
        // at grazing incidence.
        let t0 = (eta - L::one()) * (eta + L::one()) - k * k + c2;
        let im = L::splat(2.0) * eta * k;
        // a² + b² = |z|
        let a2b2 = (t0 * t0 + im * im).sqrt();
        // a² = (|z| + t0) / 2, which cancels when t0 < 0 (k > eta: every
        // metal); there it is written im² / (2 (|z| - t0)) instead.
        let neg = t0.lt(L::zero());
        let den = a2b2 - t0;
        let a2_neg = L::div_or_zero(L::splat(0.5) * im * im, den, neg & den.gt(L::zero()));
        let a = L::select(neg, a2_neg, L::splat(0.5) * (a2b2 + t0)).safe_sqrt();
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
#[inline(always)]
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
