//! Homogeneous media between interfaces: phase functions and free flight in depth.
//!
//! Directions here are *travel* directions: a walk moving along `d` scatters
//! into `d'`, and the phase function depends on `μ = d · d'` (forward
//! scattering for `g > 0`). Henyey–Greenstein with `g = 0` is the isotropic
//! phase function, so one code path serves both.
//!
//! Its functions are `#[inline(always)]` (docs/architecture.md, *Code
//! generation is part of the design*).

use crate::lane::{Lane, Rgb, V3};
use crate::math::Frame;

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

/// Transmittance `exp(-σt · Δz / |d.z|)` per channel over a depth `dz >= 0`
/// along a direction with `|d.z| = mu > 0`.
#[inline(always)]
pub fn transmittance<L: Lane>(sigma_t: Rgb<L>, dz: L, mu: L) -> Rgb<L> {
    sigma_t.map(|st| channel_transmittance(st, dz, mu))
}

/// [`transmittance`] of one channel: a grey medium needs only this one.
#[inline(always)]
pub fn channel_transmittance<L: Lane>(sigma_t: L, dz: L, mu: L) -> L {
    (-(sigma_t * (dz / mu.max(L::splat(1e-30))))).exp()
}

/// The outcome of a free flight.
///
/// Colour uses path-level ("hero channel") spectral MIS: a walk draws one
/// channel `h` at its start and samples every distance with `σt[h]`; it carries,
/// besides its throughput `β`, the ratios `r[c] = p_c(path) / p_h(path)` of the
/// path's density had channel `c` been the hero. The balance heuristic over
/// channels weights channel `c` by `1 / mean(r)`; the kernel keeps `mean(r) = 1`
/// by renormalizing, so `β` is always the MIS-weighted throughput. (method.md
/// §7 draws a channel per event instead: unbiased too, but its weights multiply
/// along a path and their variance grows; see docs/architecture.md.)
#[derive(Clone, Copy, Debug)]
pub struct FreeFlight<L: Lane> {
    /// Lanes where the walk collides inside the layer.
    pub collide: L::Mask,
    /// Distance travelled along the direction (to the collision or to the boundary).
    pub distance: L,
    /// Factor for the throughput (albedo at a collision; transmittance ratios).
    pub weight: Rgb<L>,
    /// The walk's new channel-density ratios (mean 1).
    pub ratios: Rgb<L>,
}

/// The extinction of the hero channel `hero` (0, 1 or 2 as a lane value).
#[inline(always)]
pub fn hero_sigma<L: Lane>(sigma_t: Rgb<L>, hero: L) -> L {
    L::select(
        hero.lt(L::splat(0.5)),
        sigma_t.r,
        L::select(hero.lt(L::splat(1.5)), sigma_t.g, sigma_t.b),
    )
}

/// Samples a free flight of at most `max_dist` in a medium of extinction
/// `sigma_t` and single-scattering albedo `albedo`, for a walk with hero
/// channel `hero` and channel-density ratios `ratios` (see [`FreeFlight`]).
#[inline(always)]
pub fn free_flight<L: Lane>(
    sigma_t: Rgb<L>,
    albedo: Rgb<L>,
    max_dist: L,
    hero: L,
    u_dist: L,
    ratios: Rgb<L>,
) -> FreeFlight<L> {
    let zero = L::zero();
    let sh = hero_sigma(sigma_t, hero);
    let has = sh.gt(zero);
    let t = L::div_or_zero(-(L::one() - u_dist).ln(), sh, has);
    let collide = has & t.lt(max_dist);
    let dist = L::select(collide, t, max_dist);
    // T_c / T_h = exp(-(σc - σh) d), kept finite for absurd optical depths.
    let rel = sigma_t.map(|s| {
        (-(s - sh) * dist)
            .clamp(L::splat(-87.0), L::splat(80.0))
            .exp()
    });
    // At a collision the densities also carry σc / σh.
    let sig = sigma_t.map(|s| L::div_or_zero(s, sh, has));
    let y = Rgb::select(collide, sig * rel, rel);
    let x = Rgb::select(collide, y * albedo, y);
    let r = ratios * y;
    let s = r.average();
    let ok = s.gt(zero);
    let inv = L::div_or_zero(L::one(), s, ok);
    FreeFlight {
        collide,
        distance: dist,
        weight: Rgb::select(ok, x.scale(inv), Rgb::zero()),
        ratios: Rgb::select(ok, r.scale(inv), Rgb::one()),
    }
}

/// Free flight in a medium whose `sigma_t` is the same in every channel:
/// no spectral MIS is needed, so the channel ratios pass through unchanged and
/// the weight is the albedo at a collision, 1 otherwise. (The general
/// [`free_flight`] gives the same result with more work.)
#[inline(always)]
pub fn free_flight_grey<L: Lane>(
    sigma_t: L,
    albedo: Rgb<L>,
    max_dist: L,
    u_dist: L,
    ratios: Rgb<L>,
) -> FreeFlight<L> {
    let has = sigma_t.gt(L::zero());
    let t = L::div_or_zero(-(L::one() - u_dist).ln(), sigma_t, has);
    let collide = has & t.lt(max_dist);
    FreeFlight {
        collide,
        distance: L::select(collide, t, max_dist),
        weight: Rgb::select(collide, albedo, Rgb::one()),
        ratios,
    }
}

/// Free flight with the variant the medium needs: [`free_flight_grey`] when
/// `grey` (the same `sigma_t` in every channel), [`free_flight`] otherwise.
#[inline(always)]
pub fn sample_free_flight<L: Lane>(
    sigma_t: Rgb<L>,
    albedo: Rgb<L>,
    grey: bool,
    max_dist: L,
    hero: L,
    u_dist: L,
    ratios: Rgb<L>,
) -> FreeFlight<L> {
    if grey {
        free_flight_grey(sigma_t.r, albedo, max_dist, u_dist, ratios)
    } else {
        free_flight(sigma_t, albedo, max_dist, hero, u_dist, ratios)
    }
}

/// A crossing of `dist` without collision, in expectation: the probability
/// that [`sample_free_flight`] (hero channel `hero`) passes it, and the
/// throughput factor and channel ratios it then gives (its no-collision
/// branch).
#[inline(always)]
pub fn no_collision<L: Lane>(
    sigma_t: Rgb<L>,
    grey: bool,
    dist: L,
    hero: L,
    ratios: Rgb<L>,
) -> (L, Rgb<L>, Rgb<L>) {
    if grey {
        return ((-(sigma_t.r * dist)).exp(), Rgb::one(), ratios);
    }
    let sh = hero_sigma(sigma_t, hero);
    let rel = sigma_t.map(|s| {
        (-(s - sh) * dist)
            .clamp(L::splat(-87.0), L::splat(80.0))
            .exp()
    });
    let r = ratios * rel;
    let s = r.average();
    let ok = s.gt(L::zero());
    let inv = L::div_or_zero(L::one(), s, ok);
    (
        (-(sh * dist)).exp(),
        Rgb::select(ok, rel.scale(inv), Rgb::zero()),
        Rgb::select(ok, r.scale(inv), Rgb::one()),
    )
}

/// The density in depth of a collision at distance `t` along a direction with
/// `|d.z| = mu`: `p̄_s(t) / mu` (method.md §3, the 1/|cos| of the position-free RTE).
#[inline(always)]
pub fn collision_density<L: Lane>(sigma_t: Rgb<L>, t: L, mu: L) -> L {
    let tr = sigma_t.map(|s| (-(s * t)).exp());
    (sigma_t * tr).average() / mu.max(L::splat(1e-30))
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

    #[test]
    fn free_flight_grey_weights_are_albedo_and_one() {
        let st = Rgb::<f64>::splat(2.0);
        let al = Rgb::<f64>::splat(0.7);
        let one = Rgb::one();
        let ff = free_flight(st, al, 10.0, 0.0, 0.5, one);
        assert!(ff.collide);
        assert!((ff.weight.r - 0.7).abs() < 1e-12);
        let ff = free_flight(st, al, 0.01, 2.0, 0.5, one);
        assert!(!ff.collide);
        assert!((ff.weight.g - 1.0).abs() < 1e-12);
    }
}
