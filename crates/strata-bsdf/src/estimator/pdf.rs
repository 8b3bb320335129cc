//! The fast approximate pdf of `sample()` (method.md §6).
//!
//! What it keeps:
//! * the entrance lobe exactly (`pdf` of the entrance interface for `wo` when
//!   the entrance is also the exit);
//! * the interior by short media-free walks: the entrance is sampled in full
//!   (so reflections there, already counted, add nothing to the interior), then
//!   interfaces are sampled, ignoring every medium, until the walk arrives back
//!   at the exit from inside. A rough exit adds its own density of refracting
//!   towards `wo`. A smooth exit is handled from the other side: the walk's
//!   vertex on the interface across the exit layer adds its density of the one
//!   direction that refracts to `wo`, times the refraction's solid-angle
//!   Jacobian and the exit's transmittance `1 - F`.
//!
//! What it neglects: media (scattering and attenuation), paths longer than
//! `2 n + 1` interface events, and (for a smooth exit) paths whose last non-delta
//! event lies deeper than the interface across the exit layer: where that
//! interface is smooth too (a smooth coat over another smooth interface), the
//! interior gets no density at all and the pdf is the uniform floor alone. It is therefore
//! not the density of `sample()`: it is mixed with a uniform density,
//! `pdf = 0.9 p + 0.1 / 4π`, so it is positive wherever `f` can be.
//!
//! The walk is written once over lanes ([`pdf_walk`]): the scalar engine runs
//! it on one lane, the wavefront engine on one query-sample pair per lane.

use super::scalar::{v3, Scalar, ScalarEngine};
use crate::fresnel;
use crate::interface::InterfaceLanes;
use crate::lane::{Lane, LaneMask, V3};
use crate::rng::{query_prefix, Stream, WalkRng};

/// Weight of the uniform density in the mixture.
pub const UNIFORM_FRACTION: f64 = 0.1;

/// Mixes the estimated density `p` with the uniform one.
pub fn mix_uniform(p: f64) -> f64 {
    let uniform = UNIFORM_FRACTION / (4.0 * std::f64::consts::PI);
    let p = (1.0 - UNIFORM_FRACTION) * p + uniform;
    if p.is_finite() {
        p
    } else {
        uniform
    }
}

/// One short media-free walk per lane (see the module docs): its estimate of
/// the interior's density of `wo` given `wi`. Lane `j` enters at interface
/// `e_in[j]` and leaves through `e_out[j]` (indices as lane values) of a stack
/// of `n >= 2` interfaces, each one's parameters splatted over the lanes in
/// `table`; `u3` gives three uniforms per event.
pub fn pdf_walk<L: Lane>(
    table: &[InterfaceLanes<L>],
    wi: V3<L>,
    wo: V3<L>,
    e_in: L,
    e_out: L,
    mut u3: impl FnMut() -> (L, L, L),
) -> L {
    let n = table.len();
    let zero = L::zero();
    // Lane j takes interface i[j]: a select per interface present (n is small).
    let at = |i: L| {
        let mut it = table[0];
        for (k, t) in table.iter().enumerate().skip(1) {
            let here = i.eq(L::splat(k as f64));
            if here.any() {
                it = InterfaceLanes::select(here, t, &it);
            }
        }
        it
    };
    let exit = at(e_out);
    let top_exit = e_out.eq(zero);
    // The interface across the exit layer.
    let k0 = L::select(top_exit, L::one(), L::splat(n as f64 - 2.0));
    // For a smooth exit: the one interior direction that leaves towards wo,
    // as a travel direction u0, and the density conversion to wo.
    let link = exit.sample(wo, zero, zero, zero, L::Mask::splat(true));
    let dp = link.b;
    let (n_o, n_in) = exit.sides(wo);
    let f = fresnel::dielectric(wo.z, exit.n_below / exit.n_above);
    let link_ok = exit.smooth & link.valid & dp.z.abs().gt(zero);
    // dω_in / dω_out for refraction, times the exit's transmittance.
    let conv = L::div_or_zero(
        (n_o / n_in).sqr() * wo.z.abs() * (L::one() - f),
        dp.z.abs(),
        link_ok,
    );
    let u0 = -dp;

    let mut p = zero;
    let mut alive = L::Mask::splat(true);
    let mut i = e_in;
    let mut a = wi;
    for _ in 0..2 * n + 1 {
        let it = at(i);
        // A smooth exit: the vertex across the exit layer adds its density of
        // the one direction that leaves towards wo. In a transmission query
        // through two interfaces that vertex is the entrance (event 0).
        let done = alive & link_ok & i.eq(k0);
        let v = (it.pdf(a, u0, L::Mask::splat(false)) * conv).max(zero);
        p = L::select(done, v, p);
        alive = alive & !done;
        let (us, u1, u2) = u3();
        let s = it.sample(a, us, u1, u2, L::Mask::splat(false));
        alive = alive & s.valid;
        let d = s.b;
        let up = d.z.gt(zero);
        let out = L::select(up, i, L::splat(n as f64 - 1.0) - i).eq(zero);
        alive = alive & !out;
        i = L::select(up, i - L::one(), i + L::one());
        let i_safe = L::select(alive, i, zero);
        i = i_safe;
        a = -d;
        let reach = alive & i.eq(e_out);
        let v = exit.pdf(a, wo, L::Mask::splat(false)).max(zero);
        p = L::select(reach & !exit.smooth, v, p);
        alive = alive & !reach;
        if !alive.any() {
            break;
        }
    }
    p
}

impl<S: Scalar> ScalarEngine<S> {
    /// The approximate pdf of `wo` for `sample(wi)`, from `samples` short walks.
    pub fn pdf(&self, wi: [f64; 3], wo: [f64; 3], samples: u32, seed: u64, query: u64) -> f64 {
        let Some(o) = super::orient(&self.stack, wi, Some(wo)) else {
            return 0.0;
        };
        let wi = v3::<S>(o.wi);
        let wo = v3::<S>(o.apply(wo));
        let e_in = self.layout.outer(wi.z > S::zero());
        let e_out = self.layout.outer(wo.z > S::zero());
        let mut p = 0.0;
        if e_in == e_out {
            p += self.ifaces[e_in].pdf(wi, wo, false).lane(0);
        }
        if self.layout.n >= 2 && samples > 0 {
            let mut sum = 0.0;
            let prefix = query_prefix(seed, query);
            for k in 0..samples {
                let mut rng = WalkRng::from_prefix(prefix, k as u64, Stream::Pdf);
                let (a, b) = (S::splat(e_in as f64), S::splat(e_out as f64));
                sum += pdf_walk(&self.ifaces, wi, wo, a, b, || Self::u3(&mut rng)).lane(0);
            }
            p += sum / samples as f64;
        }
        mix_uniform(p)
    }
}
