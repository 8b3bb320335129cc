//! Henyey–Greenstein, the phase function of most media (with `g = 0`, the
//! isotropic one: one code path serves both).
//!
//! Directions are *travel* directions: a walk moving along `d` scatters into
//! `d'`, and the phase function depends on `μ = d · d'` (forward scattering
//! for `g > 0`). Its functions are `#[inline(always)]` (docs/architecture.md,
//! *Code generation is part of the design*).

use crate::lane::{Lane, V3};
use crate::math::Frame;

/// `1 / 4π`: the isotropic phase function's value, HG's factor.
const INV_4PI: f64 = 1.0 / (4.0 * std::f64::consts::PI);

/// Henyey–Greenstein phase function value for `μ = d·d'`.
///
/// Given `1 - μ` and `1 + μ` separately, so that the denominator
/// `1 + g² - 2gμ` is written as a sum of non-negative terms,
/// `(1 - g)² + 2g(1 - μ)` for `g >= 0` and `(1 + g)² - 2g(1 + μ)` for `g < 0`:
/// near the peak of a strongly forward or backward phase function
/// (`|g| = 0.999`, peak width 1e-3 rad) the plain form cancels to 23 % error
/// in single precision. See [`hg_eval_dirs`], which takes the directions.
#[inline(always)]
pub fn hg_eval_1mp<L: Lane>(g: L, one_minus_mu: L, one_plus_mu: L) -> L {
    let one = L::one();
    let two = L::splat(2.0);
    let fwd = g.ge(L::zero());
    let denom = L::select(
        fwd,
        (one - g).sqr() + two * g * one_minus_mu.max(L::zero()),
        (one + g).sqr() - two * g * one_plus_mu.max(L::zero()),
    );
    // Zero only for |g| = 1 exactly (a delta lobe, never evaluated).
    let ok = denom.gt(L::zero());
    L::div_or_zero(
        L::splat(INV_4PI) * (one - g) * (one + g),
        denom * denom.sqrt(),
        ok,
    )
}

/// Henyey–Greenstein phase function value for `μ = d·d'` (see
/// [`hg_eval_1mp`]; here `1 ∓ μ` come from `μ` itself, so they are only as
/// precise as `μ`).
#[inline(always)]
pub fn hg_eval<L: Lane>(g: L, mu: L) -> L {
    hg_eval_1mp(g, L::one() - mu, L::one() + mu)
}

/// Henyey–Greenstein phase function value for scattering from travel
/// direction `d` into `u` (unit vectors). `1 - μ = |d - u|² / 2` and
/// `1 + μ = |d + u|² / 2` keep their relative precision near the peak, where
/// `1 - d·u` would lose it (and would also pick up the rounding of the two
/// vectors' lengths, ~1e-7, as large as `1 - μ` itself at `g = 0.999`).
#[inline(always)]
pub fn hg_eval_dirs<L: Lane>(g: L, d: V3<L>, u: V3<L>) -> L {
    let h = L::splat(0.5);
    let m = d - u;
    let p = d + u;
    hg_eval_1mp(g, h * m.dot(m), h * p.dot(p))
}

/// Samples `d'` from Henyey–Greenstein around the travel direction `d`.
/// Exact inversion, so the weight is 1 and the density is [`hg_eval`].
///
/// The inversion gives `1 - μ` directly, without cancellation:
/// with `s = (1 - g²) / (1 - g + 2gv)`,
/// `1 - μ = (1 - g)(1 - v)(s + 1 - g) / (1 - g + 2gv)` for `g > 0`; a
/// negative `g` mirrors it (`μ(-g, u) = -μ(g, 1 - u)`). The plain
/// `μ = (1 + g² - s²) / 2g` rounds near `μ = 1`: at `g = 0.999` in single
/// precision it put 6 % of the samples at exactly `μ = 1` instead of 1 %.
#[inline(always)]
pub fn hg_sample<L: Lane>(g: L, d: V3<L>, u1: L, u2: L) -> V3<L> {
    let one = L::one();
    let two = L::splat(2.0);
    // One form for every g: at g = 0 it is exactly the isotropic
    // `1 - μ = 2 (1 - u)`, and no g is sampled as another (a cut-off to the
    // isotropic sampler below some |g| would be weighted as HG all the same).
    let neg = g.lt(L::zero());
    let ga = g.abs();
    let v = L::select(neg, one - u1, u1);
    let den = one - ga + two * ga * v;
    let s = (one - ga) * (one + ga) / den;
    // e = 1 - μ for the mirrored (g >= 0) lobe.
    let e = ((one - ga) * (one - v) * (s + one - ga) / den).clamp(L::zero(), two);
    let mu = L::select(neg, e - one, one - e);
    let sin = (e * (two - e)).safe_sqrt();
    let (sp, cp) = u2.sin_cos_turns();
    Frame::around(d).to_world(V3::new(sin * cp, sin * sp, mu))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hg_is_normalized() {
        // ∫ p dω = 2π ∫ p(μ) dμ, midpoint rule on a fine grid.
        for g in [-0.9f64, -0.3, 0.0, 0.5, 0.9] {
            let n = 200_000;
            let mut s = 0.0;
            for i in 0..n {
                let mu = -1.0 + (i as f64 + 0.5) * 2.0 / n as f64;
                s += hg_eval(g, mu) * 2.0 / n as f64;
            }
            s *= 2.0 * std::f64::consts::PI;
            assert!((s - 1.0).abs() < 1e-3, "g = {g}: {s}");
        }
    }

    /// The sampler inverts HG's CDF at every g, however small: against the
    /// plain inversion `μ = (1 + g² - s²) / 2g` in f64, which is accurate
    /// at these g (and isotropic, `μ = 2u - 1`, at g = 0).
    #[test]
    fn hg_sample_inverts_the_cdf_at_small_g() {
        for g in [0.0f64, 1e-6, -2e-5, 5e-4, -9e-4, 2e-3, 0.3] {
            for k in 0..200 {
                let u = (k as f64 + 0.5) / 200.0;
                let d = hg_sample(g as f32, V3::new(0.0, 0.0, 1.0), u as f32, 0.25);
                let want = if g == 0.0 {
                    2.0 * u - 1.0
                } else {
                    let s = (1.0 - g * g) / (1.0 - g + 2.0 * g * u);
                    (1.0 + g * g - s * s) / (2.0 * g)
                };
                assert!(
                    (d.z as f64 - want).abs() < 2e-6,
                    "g = {g}, u = {u}: mu = {} vs {want}",
                    d.z
                );
            }
        }
    }
}
