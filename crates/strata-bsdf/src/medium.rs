//! Homogeneous media between interfaces: free flight in depth, transmittance
//! and the spectral MIS of the hero channel. (Their phase functions are
//! [`crate::phase`]'s.)
//!
//! Its functions are `#[inline(always)]` (docs/architecture.md, *Code
//! generation is part of the design*).

use crate::lane::{Lane, LaneMask, Rgb};

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
    let (weight, ratios) = flight_weights(sigma_t, sh, dist, collide, albedo, ratios);
    FreeFlight {
        collide,
        distance: dist,
        weight,
        ratios,
    }
}

/// The throughput factor and channel ratios of a flight of `dist` with the
/// hero's extinction `sh`, that ends in a collision (lanes `collide`) or
/// passes: each channel's density over the hero's, normalized by their
/// mean under the walk's `ratios` (one-sample MIS over channels).
#[inline(always)]
fn flight_weights<L: Lane>(
    sigma_t: Rgb<L>,
    sh: L,
    dist: L,
    collide: L::Mask,
    albedo: Rgb<L>,
    ratios: Rgb<L>,
) -> (Rgb<L>, Rgb<L>) {
    let zero = L::zero();
    let has = sh.gt(zero);
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
    (
        Rgb::select(ok, x.scale(inv), Rgb::zero()),
        Rgb::select(ok, r.scale(inv), Rgb::one()),
    )
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

/// The largest collision probability a boosted free flight gives a crossing
/// ([`free_flight_grey_boosted`]), so that the weight of passing stays below
/// 2.
pub const MAX_BOOSTED: f64 = 0.5;

/// [`free_flight_grey`] with the collision made `boost` times as likely
/// (lanes with `boost > 1`; others are [`free_flight_grey`] exactly): the
/// flight collides before `max_dist` with probability
/// `q = max(P, min(boost · P, MAX_BOOSTED))`, `P = 1 − e^(−σt max_dist)`
/// its physical probability, at a distance drawn from the exponential truncated to
/// `max_dist`, and the weights `P / q` (collision, times the albedo) and
/// `(1 − P) / (1 − q)` (passing) keep every estimate unbiased. For rare
/// collisions that count (the control variate's walks score only paths that
/// collide: `events::FIRST_COLLISION_BOOST`). Out of line: only their walks
/// run it.
#[inline(never)]
pub fn free_flight_grey_boosted<L: Lane>(
    sigma_t: L,
    albedo: Rgb<L>,
    max_dist: L,
    u_dist: L,
    ratios: Rgb<L>,
    boost: L,
) -> FreeFlight<L> {
    let plain = free_flight_grey(sigma_t, albedo, max_dist, u_dist, ratios);
    let boosted = boost.gt(L::one());
    if !boosted.any() {
        return plain;
    }
    let one = L::one();
    let has = sigma_t.gt(L::zero());
    let p = L::select(has, -(-(sigma_t * max_dist)).exp_m1(), L::zero());
    // Never above MAX_BOOSTED (passing must stay possible: a path that
    // passes may collide later), never below the physical p.
    let q = (boost * p).min(L::splat(MAX_BOOSTED)).max(p);
    let collide = has & u_dist.lt(q);
    // Given a collision, u / q is uniform: the truncated exponential's inverse.
    let u = L::div_or_zero(u_dist, q, collide) * p;
    let t = L::div_or_zero(-(one - u).ln(), sigma_t, collide).min(max_dist);
    let w_col = L::div_or_zero(p, q, collide);
    let w_pass = L::div_or_zero(one - p, one - q, !collide);
    let flight = FreeFlight {
        collide,
        distance: L::select(collide, t, max_dist),
        weight: Rgb::select(collide, albedo.scale(w_col), Rgb::splat(w_pass)),
        ratios,
    };
    FreeFlight {
        collide: (boosted & flight.collide) | (!boosted & plain.collide),
        distance: L::select(boosted, flight.distance, plain.distance),
        weight: Rgb::select(boosted, flight.weight, plain.weight),
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
    let no = L::Mask::splat(false);
    let (w, r) = flight_weights(sigma_t, sh, dist, no, Rgb::one(), ratios);
    ((-(sh * dist)).exp(), w, r)
}

/// The density (per unit distance) with which [`sample_free_flight`] (hero
/// channel `hero`) collides at distance `dist`: `σ_h e^(−σ_h dist)`.
#[inline(always)]
pub fn collision_density_hero<L: Lane>(sigma_t: Rgb<L>, grey: bool, dist: L, hero: L) -> L {
    let sh = if grey {
        sigma_t.r
    } else {
        hero_sigma(sigma_t, hero)
    };
    sh * (-(sh * dist)).exp()
}

/// A collision at distance `dist`, in expectation of where it falls: the
/// density (per unit distance) with which [`sample_free_flight`] (hero
/// channel `hero`) collides there, and the throughput factor and channel
/// ratios it then gives (its collision branch).
#[inline(always)]
pub fn collision_at<L: Lane>(
    sigma_t: Rgb<L>,
    albedo: Rgb<L>,
    grey: bool,
    dist: L,
    hero: L,
    ratios: Rgb<L>,
) -> (L, Rgb<L>, Rgb<L>) {
    let density = collision_density_hero(sigma_t, grey, dist, hero);
    if grey {
        return (density, albedo, ratios);
    }
    let sh = hero_sigma(sigma_t, hero);
    let yes = L::Mask::splat(true);
    let (w, r) = flight_weights(sigma_t, sh, dist, yes, albedo, ratios);
    (density, w, r)
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

    /// Over the uniform (a midpoint rule of 10⁶ points), a boosted flight's
    /// weighted outcomes are the physical ones: collision probability ×
    /// albedo, the mean collision distance, the probability of passing;
    /// and boost 1 is the plain flight exactly.
    #[test]
    fn boosted_flights_keep_every_expectation() {
        let al = Rgb::<f64>::splat(0.7);
        let one = Rgb::one();
        for (sigma, dist) in [(1.0, 0.01), (2.0, 0.3), (0.5, 4.0), (3.0, 50.0)] {
            let p: f64 = 1.0 - (-sigma * dist).exp();
            // ∫₀^L t σ e^(−σt) dt.
            let mean_t = (1.0 - (1.0 + sigma * dist) * (-sigma * dist).exp()) / sigma;
            for boost in [1.0, 8.0, 64.0] {
                let n = 1_000_000;
                let (mut col, mut t, mut pass) = (0.0, 0.0, 0.0);
                for k in 0..n {
                    let u = (k as f64 + 0.5) / n as f64;
                    let ff = free_flight_grey_boosted(sigma, al, dist, u, one, boost);
                    if ff.collide {
                        assert!(ff.distance <= dist);
                        col += ff.weight.r;
                        t += ff.weight.r * ff.distance;
                    } else {
                        assert_eq!(ff.distance, dist);
                        pass += ff.weight.r;
                    }
                    if boost == 1.0 {
                        let plain = free_flight_grey(sigma, al, dist, u, one);
                        assert_eq!((ff.collide, ff.distance), (plain.collide, plain.distance));
                        assert_eq!(ff.weight.r, plain.weight.r);
                    }
                }
                let (col, t, pass) = (col / n as f64, t / n as f64, pass / n as f64);
                let what = format!("σ {sigma} L {dist} boost {boost}");
                // Relative 1e-3 (a midpoint rule on 10⁶ points resolves a
                // probability p to about 1e-6 / p), and never looser than 1e-5.
                let close = |x: f64, r: f64| (x - r).abs() <= (1e-3 * r).min(1e-5);
                assert!(close(col, 0.7 * p), "{what}: {col} vs {}", 0.7 * p);
                assert!(close(t, 0.7 * mean_t), "{what}: {t} vs {}", 0.7 * mean_t);
                assert!(close(pass, 1.0 - p), "{what}: {pass} vs {}", 1.0 - p);
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
