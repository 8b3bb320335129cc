//! Homogeneous media between interfaces: free flight in depth, transmittance
//! and the spectral MIS of the hero channel. (Their phase functions are
//! [`crate::phase`]'s.)
//!
//! Its functions are `#[inline(always)]` (docs/architecture.md, *Code
//! generation is part of the design*).

use crate::lane::{Lane, Rgb};

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
