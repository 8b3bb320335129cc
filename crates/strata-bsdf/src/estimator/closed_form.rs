//! Stacks whose BSDF has a closed form: an evaluation with zero variance.
//!
//! A smooth dielectric coat over a non-scattering layer (clear or absorbing,
//! grey or coloured) over a Lambertian base scatters light only at the base,
//! and every path between two visits of the base is one deterministic
//! refraction or reflection: the sum over paths is a geometric series.
//! With light from `wi` in the exterior of IOR `n0` and the coat of IOR `n1`,
//!
//! ```text
//! f(wi, wo) = (n0/n1)² T(θi) T(θo) e^(−τ/μi′) e^(−τ/μo′) ρ / (π (1 − ρ R̄))
//! R̄ = 2 ∫₀¹ F_in(μ) e^(−2τ/μ) μ dμ
//! ```
//!
//! where `T = 1 − F` is the coat's Fresnel transmittance, `μ′` the cosine of
//! the refracted direction, τ the layer's optical depth (per channel) and
//! `F_in` the coat's reflectance seen from inside (1 beyond the critical
//! angle). The first factor is radiance leaving the denser coat; `R̄` is the
//! fraction of the base's diffuse exitance that the layer and the coat send
//! back to it. The unidirectional estimator converges to this value (tested
//! against it, and against the test suite's own formula), so
//! [`crate::Estimator::Auto`] answers such stacks' `eval` with it.
//!
//! Knowing `f`, `Auto` also samples these stacks without a walk
//! ([`SmoothCoatLambertian::sample`]): the coat's mirror reflection, or a
//! cosine-distributed direction weighted by `f cos θo / p`. Its pdf is
//! exact, where a walk's would be an estimate ([`super::pdf`]).
//!
//! With a *scattering* layer the same formula, at the layer's `σt`, is the
//! sum over the paths that never collide in it
//! ([`SmoothCoatLambertian::unscattered`]): the exact part of `Auto`'s
//! control variate, whose walks then score only the paths with a collision.

use super::{Settings, WalkSample};
use crate::fresnel;
use crate::rng::WalkRng;
use crate::stack::{InterfaceKind, LayerStack, PhaseKind};
use std::f64::consts::PI;

/// The deepest grey medium on which [`crate::Estimator::Auto`] uses the
/// boosted control variate ([`SmoothCoatLambertian::control_variate_pays`]).
/// A conservative choice: the deepest measured stack inside the rule is at
/// τ 2; a grey τ 8 one about broke even at its worst pair, and the deep
/// example `jade` (which the other conditions leave out too) lost by half.
pub const BOOSTED_CV_MAX_DEPTH: f64 = 2.0;

/// The closed form of a smooth coat over an absorbing layer over a
/// Lambertian base.
#[derive(Clone, Debug, PartialEq)]
pub struct SmoothCoatLambertian {
    /// The coat's `n_below / n_above`.
    eta: f64,
    /// Optical depth of the layer per channel (0 if it has none).
    tau: [f64; 3],
    /// The base's albedo.
    rho: [f64; 3],
    /// `R̄` per channel.
    r_bar: [f64; 3],
}

impl SmoothCoatLambertian {
    /// The closed form of `stack`, if it has one under `settings` (a depth
    /// cap truncates the series: then it has none).
    pub fn of(stack: &LayerStack, settings: &Settings) -> Option<Self> {
        if stack.medium(0).is_some_and(|m| m.scatters()) {
            return None;
        }
        Self::unscattered(stack, settings)
    }

    /// The part of `stack`'s BSDF carried by the paths that never collide in
    /// its medium, for a smooth coat over any layer (clear, absorbing or
    /// scattering) over a Lambertian base: [`SmoothCoatLambertian::of`] the
    /// same stack with the medium made a pure absorber of the same `σt`. A
    /// path that crosses the layer without colliding has transmittance
    /// `e^(−σt d/μ)` whatever the albedo, so these paths are exactly the
    /// absorber's paths. It is the exact part of the control variate of
    /// [`crate::Estimator::Auto`]: the walks then score only the paths with
    /// a collision (`ScalarEngine::with_control_variate`). Where the medium
    /// does not scatter it is the whole BSDF. `None` for other stacks, and
    /// under a depth cap (which truncates these paths too).
    pub fn unscattered(stack: &LayerStack, settings: &Settings) -> Option<Self> {
        // A tilted normal breaks the closed form's planar geometry; an
        // extinction that depends on the azimuth (SGGX) its 1D integrals.
        let tilted = stack.interfaces().iter().any(|i| i.tilted());
        let directional = stack
            .medium(0)
            .is_some_and(|m| m.phase_kind().directional());
        if stack.len() != 2 || settings.max_depth.is_some() || tilted || directional {
            return None;
        }
        let (coat, base) = (stack.interface(0), stack.interface(1));
        if coat.kind != InterfaceKind::Dielectric
            || !coat.smooth
            || base.kind != InterfaceKind::Diffuse
        {
            return None;
        }
        let tau = stack.medium(0).map_or([0.0; 3], |m| m.optical_depth());
        let eta = coat.n_below / coat.n_above;
        let r_bar = tau.map(|t| internal_reflectance(eta, t));
        Some(SmoothCoatLambertian {
            eta,
            tau,
            rho: base.albedo,
            r_bar,
        })
    }

    /// Whether [`crate::Estimator::Auto`] uses the control variate on
    /// `stack`: it has the shape ([`SmoothCoatLambertian::unscattered`]),
    /// its medium scatters, and either
    ///
    /// * the medium is grey (one extinction and one albedo for the three
    ///   channels), of optical depth at most [`BOOSTED_CV_MAX_DEPTH`], with a
    ///   Henyey–Greenstein phase function: its walks then boost their first
    ///   collision ([`super::events::FIRST_COLLISION_BOOST`]), and every such
    ///   stack measured a gain at the median (and at every pair but one); or
    /// * the medium scatters little against what the base reflects,
    ///   `max_c(τ_c a_c) <= 0.1 min_c ρ_c` (optical depth `τ`,
    ///   single-scattering albedo `a`, base albedo `ρ`).
    ///
    /// Elsewhere (a chromatic albedo, a mixture of lobes, or chromatic
    /// extinction, which the boost does not cover) the control variate
    /// measured more variance per unit of time at some pairs: a collided
    /// path scores about what the uncollided one it replaces would have, and
    /// the boosted walks' longer roulette costs time; deeper grey media are
    /// left out by choice ([`BOOSTED_CV_MAX_DEPTH`])
    /// (`tests/layered_control_variate.rs`, measured in docs/performance.md).
    /// A mixture of a single lobe counts as a mixture here.
    pub fn control_variate_pays(stack: &LayerStack, settings: &Settings) -> bool {
        let Some(cv) = Self::unscattered(stack, settings) else {
            return false;
        };
        let Some(m) = stack.medium(0).filter(|m| m.scatters()) else {
            return false;
        };
        let scatter = (0..3).map(|c| cv.tau[c] * m.albedo[c]).fold(0.0, f64::max);
        let base = cv.rho.iter().copied().fold(f64::INFINITY, f64::min);
        let grey = m.grey() && m.albedo.iter().all(|&a| a == m.albedo[0]);
        let boosted_pays =
            grey && cv.tau[0] <= BOOSTED_CV_MAX_DEPTH && m.phase_kind() == PhaseKind::Hg;
        boosted_pays || scatter <= 0.1 * base
    }

    /// `f(wi, wo)` per channel for directions in the stack's oriented frame
    /// (both above the coat; the caller mirrors two-sided queries and
    /// answers 0 where light cannot enter or leave).
    pub fn eval(&self, wi: [f64; 3], wo: [f64; 3]) -> [f64; 3] {
        let (ci, co) = (wi[2], wo[2]);
        if ci <= 0.0 || co <= 0.0 {
            return [0.0; 3];
        }
        let (ti, mi) = self.enter(ci);
        let (to, mo) = self.enter(co);
        if ti == 0.0 || to == 0.0 {
            // Total reflection outside a coat less dense than the exterior:
            // no light enters or leaves (and μ′ = 0 would make 0/0 below).
            return [0.0; 3];
        }
        let scale = ti * to / (PI * self.eta * self.eta);
        std::array::from_fn(|c| {
            let att = if self.tau[c] > 0.0 {
                (-self.tau[c] / mi).exp() * (-self.tau[c] / mo).exp()
            } else {
                1.0
            };
            scale * att * self.rho[c] / (1.0 - self.rho[c] * self.r_bar[c])
        })
    }

    /// `sample()`'s exact form for these stacks, in the stack's oriented
    /// frame (`wi` above the coat), from three uniforms: the coat's mirror
    /// reflection with probability `F(θi)`, its own Fresnel reflectance
    /// (weight 1), otherwise a cosine-distributed direction in the cone the
    /// coat lets light out through (the whole hemisphere unless the exterior
    /// is the denser side), weight `f cos θo / p`. Its density
    /// ([`SmoothCoatLambertian::pdf`]) is known in closed form, so the pdf
    /// it returns is the density of its directions, and its weights are
    /// bounded (`f cos θo / p ∝ T(θo) e^(−τ/μi′) e^(−τ/μo′) ρ / (1 − ρ R̄)`):
    /// no walk, no noise in the pdf. `None` for `wi` below the coat (a coat
    /// that lets no light in gives the mirror, weight 1).
    pub fn sample(&self, wi: [f64; 3], u: [f64; 3]) -> Option<ExactSample> {
        if wi[2] <= 0.0 {
            return None;
        }
        let ti = self.enter(wi[2]).0;
        if u[0] >= ti {
            return Some(ExactSample {
                wo: [-wi[0], -wi[1], wi[2]],
                weight: [1.0; 3],
                specular: true,
            });
        }
        // Cosine-distributed: sin² θ uniform on [0, sin² θc).
        let s2 = u[1] * self.cone();
        let (r, phi) = (s2.sqrt(), 2.0 * PI * u[2]);
        let wo = [r * phi.cos(), r * phi.sin(), (1.0 - s2).max(0.0).sqrt()];
        let p = self.pdf(wi, wo);
        if p == 0.0 {
            return None;
        }
        let f = self.eval(wi, wo);
        Some(ExactSample {
            wo,
            weight: f.map(|v| v * wo[2] / p),
            specular: false,
        })
    }

    /// The density (solid angle) of [`SmoothCoatLambertian::sample`]'s
    /// non-delta directions: `(1 − F(θi)) cos θo / (π sin² θc)` inside the
    /// cone the coat lets light out through, 0 elsewhere. Oriented frame,
    /// as `sample`.
    pub fn pdf(&self, wi: [f64; 3], wo: [f64; 3]) -> f64 {
        let s2 = 1.0 - wo[2] * wo[2];
        if wi[2] <= 0.0 || wo[2] <= 0.0 || s2 >= self.cone() || self.enter(wo[2]).0 == 0.0 {
            return 0.0;
        }
        self.enter(wi[2]).0 * wo[2] / (PI * self.cone())
    }

    /// `sin² θc` of the cone of directions outside that refract into the
    /// coat: 1, or `η²` where the exterior is denser (`η < 1`).
    fn cone(&self) -> f64 {
        (self.eta * self.eta).min(1.0)
    }

    /// [`SmoothCoatLambertian::sample`] for a query on `stack` (any
    /// orientation: a two-sided stack lit from below is turned over),
    /// drawing its uniforms from `rng`, as a walk's sample.
    pub fn sample_query(
        &self,
        stack: &LayerStack,
        wi: [f64; 3],
        rng: &mut WalkRng,
    ) -> Option<WalkSample> {
        let o = super::orient(stack, wi, None)?;
        let u = [(); 3].map(|_| rng.uniform() as f64);
        let s = self.sample(o.wi, u)?;
        let wo = o.apply(s.wo).map(|x| x as f32);
        Some(WalkSample {
            wo: glam::Vec3::from(wo),
            weight: s.weight.map(|x| x as f32),
            reflection: true,
            specular: s.specular,
        })
    }

    /// [`SmoothCoatLambertian::pdf`] for a query on `stack` (0 where `wo`
    /// leaves on a side light cannot leave by).
    pub fn pdf_query(&self, stack: &LayerStack, wi: [f64; 3], wo: [f64; 3]) -> f64 {
        match super::orient(stack, wi, Some(wo)) {
            Some(o) => self.pdf(o.wi, o.apply(wo)),
            None => 0.0,
        }
    }

    /// The coat's transmittance from outside at incidence cosine `c`, and the
    /// cosine of the refracted direction.
    fn enter(&self, c: f64) -> (f64, f64) {
        let t = fresnel::dielectric_rt(c, self.eta).1;
        let s2 = (1.0 - c * c) / (self.eta * self.eta);
        (t, (1.0 - s2).max(0.0).sqrt())
    }
}

/// A direction of [`SmoothCoatLambertian::sample`] (oriented frame).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExactSample {
    /// The outgoing direction (unit, above the coat).
    pub wo: [f64; 3],
    /// `f(wi, wo) cos θo / p(wo)` per channel (1 for the mirror reflection,
    /// whose weight is the discrete `F / F`).
    pub weight: [f64; 3],
    /// The coat's mirror reflection.
    pub specular: bool,
}

/// `R̄ = 2 ∫₀¹ F_in(μ) e^(−2τ/μ) μ dμ` for a coat of relative IOR `eta`,
/// by Gauss–Legendre quadrature. Beyond the critical cosine `μc`, `F_in`
/// falls like `1 − c √(μ − μc)`: the substitution `μ = μc + t²` makes the
/// integrand smooth there, and the quadrature converges to f64 rounding.
fn internal_reflectance(eta: f64, tau: f64) -> f64 {
    // From inside, the cosine is negative in `fresnel`'s convention.
    let f = |mu: f64| -> f64 {
        let r = fresnel::dielectric_rt(-mu, eta).0;
        let att = if tau > 0.0 {
            (-2.0 * tau / mu).exp()
        } else {
            1.0
        };
        2.0 * r * att * mu
    };
    let critical = if eta > 1.0 {
        (1.0 - 1.0 / (eta * eta)).sqrt()
    } else {
        0.0
    };
    let below = gauss_legendre(&f, 0.0, critical, 64);
    let above = gauss_legendre(
        &|t: f64| f(critical + t * t) * 2.0 * t,
        0.0,
        (1.0 - critical).sqrt(),
        64,
    );
    below + above
}

/// `∫ₐᵇ f` by 8-point Gauss–Legendre on `panels` equal panels.
fn gauss_legendre(f: &impl Fn(f64) -> f64, a: f64, b: f64, panels: usize) -> f64 {
    const X: [f64; 4] = [
        0.183_434_642_495_649_8,
        0.525_532_409_916_329,
        0.796_666_477_413_626_7,
        0.960_289_856_497_536_3,
    ];
    const W: [f64; 4] = [
        0.362_683_783_378_362,
        0.313_706_645_877_887_3,
        0.222_381_034_453_374_5,
        0.101_228_536_290_376_3,
    ];
    let h = (b - a) / panels as f64;
    (0..panels)
        .map(|p| {
            let (m, r) = (a + (p as f64 + 0.5) * h, 0.5 * h);
            X.iter()
                .zip(W)
                .map(|(&x, w)| w * r * (f(m - r * x) + f(m + r * x)))
                .sum::<f64>()
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quadrature_is_exact_where_it_can_be_checked() {
        // ∫₀¹ 2μ dμ = 1, and a smooth integrand converges: against the
        // midpoint rule on a fine grid.
        assert!((gauss_legendre(&|m| 2.0 * m, 0.0, 1.0, 4) - 1.0).abs() < 1e-15);
        let n = 2_000_000;
        for (eta, tau) in [(1.5, 0.0), (1.5, 0.3), (2.2, 0.01), (1.0 / 1.3, 0.5)] {
            let mid: f64 = (0..n)
                .map(|k| {
                    let mu = (k as f64 + 0.5) / n as f64;
                    let r = fresnel::dielectric_rt(-mu, eta).0;
                    2.0 * r * (-2.0 * tau / mu).exp() * mu / n as f64
                })
                .sum();
            let gl = internal_reflectance(eta, tau);
            assert!(
                (gl - mid).abs() < 1e-7,
                "eta {eta} tau {tau}: {gl} vs {mid}"
            );
        }
    }
}
