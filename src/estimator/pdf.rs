//! The fast approximate pdf of `sample()` (method.md §6).
//!
//! What it keeps:
//! * the entrance lobe exactly (`pdf` of the entrance interface for `wo` when
//!   the entrance is also the exit);
//! * the interior by a short media-free walk: the entrance is sampled in full
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
//! event lies deeper than the interface across the exit layer. It is therefore
//! not the density of `sample()`: it is mixed with a uniform density,
//! `pdf = 0.9 p + 0.1 / 4π`, so it is positive wherever `f` can be.

use super::scalar::{sides, v3, Next, Scalar, ScalarEngine};
use crate::fresnel;
use crate::lane::V3;
use crate::rng::{Stream, WalkRng};

/// Weight of the uniform density in the mixture.
pub const UNIFORM_FRACTION: f64 = 0.1;

impl<S: Scalar> ScalarEngine<S> {
    /// The approximate pdf of `wo` for `sample(wi)`, from `samples` short walks.
    pub fn pdf(&self, wi: [f64; 3], wo: [f64; 3], samples: u32, seed: u64, query: u64) -> f64 {
        let uniform = UNIFORM_FRACTION / (4.0 * std::f64::consts::PI);
        let Some(o) = super::orient(&self.stack, wi, Some(wo)) else {
            return 0.0;
        };
        let wi = v3::<S>(o.wi);
        let wo = v3::<S>(o.apply(wo));
        let n = self.n();
        let e_in = if wi.z > S::zero() { 0 } else { n - 1 };
        let e_out = if wo.z > S::zero() { 0 } else { n - 1 };
        let mut p = 0.0;
        if e_in == e_out {
            p += self.ifaces[e_in].pdf(wi, wo, false).lane(0);
        }
        if n >= 2 && samples > 0 {
            let mut sum = 0.0;
            for k in 0..samples {
                let mut rng = WalkRng::new(seed, query, k as u64, Stream::Pdf);
                sum += self.pdf_walk(wi, wo, e_in, e_out, &mut rng);
            }
            p += sum / samples as f64;
        }
        let p = (1.0 - UNIFORM_FRACTION) * p + uniform;
        if p.is_finite() {
            p
        } else {
            uniform
        }
    }

    fn pdf_walk(&self, wi: V3<S>, wo: V3<S>, e_in: usize, e_out: usize, rng: &mut WalkRng) -> f64 {
        let n = self.n();
        let exit = &self.ifaces[e_out];
        let exit_smooth = self.stack.interface(e_out).smooth;
        let (_, k0) = self.exit_region(e_out);
        // For a smooth exit: the one interior direction that leaves towards wo,
        // as a travel direction u0, and the density conversion to wo.
        let smooth_link = if exit_smooth {
            let s = exit.sample(wo, S::zero(), S::zero(), S::zero(), true);
            if s.valid {
                let dp = s.b;
                let (n_o, n_in) = sides(exit, wo);
                let f = fresnel::dielectric(wo.z, exit.n_below / exit.n_above);
                // dω_in / dω_out for refraction, times the exit's transmittance.
                let jac = (n_o / n_in).sqr() * wo.z.abs() / dp.z.abs().max(S::splat(1e-12));
                Some((-dp, (jac * (S::one() - f)).lane(0)))
            } else {
                None
            }
        } else {
            None
        };
        let mut i = e_in;
        let mut a = wi;
        let max_events = 2 * n + 1;
        for event in 0..max_events {
            let it = &self.ifaces[i];
            if event > 0 && i == k0 {
                if let Some((u0, conv)) = smooth_link {
                    return (it.pdf(a, u0, false).lane(0) * conv).max(0.0);
                }
            }
            let (us, u1, u2) = Self::u3(rng);
            let s = it.sample(a, us, u1, u2, false);
            if !s.valid {
                return 0.0;
            }
            let d = s.b;
            match self.next(i, d) {
                Next::OutTop | Next::OutBottom => return 0.0,
                Next::Layer(l, _) => {
                    i = if d.z > S::zero() { l } else { l + 1 };
                }
            }
            a = -d;
            if i == e_out && !exit_smooth {
                return exit.pdf(a, wo, false).lane(0).max(0.0);
            }
            if i == e_out {
                return 0.0;
            }
        }
        0.0
    }
}
