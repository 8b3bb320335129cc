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
//! back to it (from a table of its quadrature per IOR,
//! [`coat_return::SmoothReturn`]). The unidirectional estimator converges
//! to this value (tested against it, and against the test suite's own
//! formula), so [`crate::Estimator::Auto`] answers such stacks' `eval` with
//! it.
//!
//! Knowing `f`, `Auto` also samples these stacks without a walk
//! ([`SmoothCoatLambertian::sample`]): the coat's mirror reflection, or a
//! cosine-distributed direction weighted by `f cos θo / p`. Its pdf is
//! exact, where a walk's would be an estimate ([`super::pdf`]).
//!
//! With a *scattering* layer the same formula, at the layer's `σt`, is the
//! sum over the paths that never collide in it
//! ([`SmoothCoatLambertian::unscattered`]): the exact part of `Auto`'s
//! control variate, whose walks then score only the paths with a collision
//! ([`super::coat_lambertian`]). A rough coat's BSDF factorizes the same
//! way, with integrals in place of the Fresnel terms
//! ([`super::rough_coat`]).

use super::coat_and_base::coat_and_base;
use super::coat_return;
use super::settings::Settings;
use crate::fresnel;
use crate::stack::LayerStack;
use std::f64::consts::PI;

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
        Self::unscattered_with(stack, settings, false)
    }

    /// [`SmoothCoatLambertian::unscattered`], with `R̄` from the coat's
    /// table ([`coat_return::SmoothReturn`], within 1e-7 of the quadrature)
    /// where `tabulated`: what a per-query row takes, where a quadrature
    /// per row would cost more than its queries.
    pub fn unscattered_with(
        stack: &LayerStack,
        settings: &Settings,
        tabulated: bool,
    ) -> Option<Self> {
        let (coat, _) = coat_and_base(stack, settings)?;
        if !coat.smooth {
            return None;
        }
        Some(Self::of_numbers(
            coat.n_below / coat.n_above,
            stack,
            tabulated,
        ))
    }

    /// The closed form of `stack`, a stack of this one's shape and IORs
    /// (a per-query row written in place), with `R̄` from the coat's table:
    /// [`SmoothCoatLambertian::unscattered_with`]'s tabulated form, without
    /// analysing the stack's shape again.
    pub fn with_numbers_of(&self, stack: &LayerStack) -> Self {
        Self::of_numbers(self.eta, stack, true)
    }

    /// The closed form of `stack`, whose shape has one and whose coat's
    /// relative IOR is `eta`: its layer's optical depth, its base's albedo
    /// and `R̄`, from the coat's table where `tabulated`.
    fn of_numbers(eta: f64, stack: &LayerStack, tabulated: bool) -> Self {
        let tau = stack.medium(0).map_or([0.0; 3], |m| m.optical_depth());
        let r_bar = if tabulated {
            coat_return::SmoothReturn::r_bar_of(eta, tau)
        } else if tau[0] == tau[1] && tau[1] == tau[2] {
            [coat_return::smooth(eta, tau[0]); 3]
        } else {
            coat_return::smooth_channels(eta, tau)
        };
        SmoothCoatLambertian {
            eta,
            tau,
            rho: stack.interface(1).albedo,
            r_bar,
        }
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
        if wi[2] <= 0.0 || !self.in_cone(wo[2]) || self.enter(wo[2]).0 == 0.0 {
            return 0.0;
        }
        self.enter(wi[2]).0 * wo[2] / (PI * self.cone())
    }

    /// `sin² θc` of the cone of directions outside that refract into the
    /// coat: 1, or `η²` where the exterior is denser (`η < 1`).
    fn cone(&self) -> f64 {
        (self.eta * self.eta).min(1.0)
    }

    /// Whether a direction above at cosine `c` is inside that cone. Without
    /// a critical angle (`η >= 1`) every direction above is: `1 − c²` would
    /// round to 1 below `c ≈ 1e-8` and leave a grazing direction out (a
    /// grazing mirror sample then carried pdf 0).
    fn in_cone(&self, c: f64) -> bool {
        c > 0.0 && (self.eta >= 1.0 || 1.0 - c * c < self.cone())
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{materials, LayeredBsdf};
    use glam::Vec3;

    /// A per-query row's closed form takes `R̄` from the coat's table,
    /// within 1e-7 of the quadrature a material's own takes.
    #[test]
    fn a_rows_closed_form_takes_r_bar_from_the_table() {
        let toml = "[[layers]]\n\
                    interface = { kind = \"dielectric\", ior = 1.5 }\n\
                    medium = { thickness = 2.0, sigma_t = [0.0, 0.05, 1.0], albedo = 0.0 }\n\
                    [[layers]]\n\
                    interface = { kind = \"diffuse\", albedo = 0.8 }\n";
        let stack = LayerStack::from_toml_str(toml).expect("a stack");
        let settings = Settings::default();
        let own = SmoothCoatLambertian::of(&stack, &settings).expect("a closed form");
        let row = SmoothCoatLambertian::unscattered_with(&stack, &settings, true).expect("one");
        assert_eq!(row.tau, [0.0, 0.1, 2.0]);
        let table = coat_return::SmoothReturn::for_eta(1.5).r_bar(row.tau);
        assert_eq!(row.r_bar.map(f64::to_bits), table.map(f64::to_bits));
        let quadrature = coat_return::smooth_channels(1.5, row.tau);
        assert_eq!(own.r_bar, quadrature);
        for (r, q) in row.r_bar.iter().zip(quadrature) {
            assert!((r - q).abs() < 1e-7, "{r} vs {q}");
        }
    }

    /// A grazing mirror sample of a walk-free stack carries a positive pdf,
    /// the one `pdf` gives for its direction, down to the most grazing
    /// incidence the library lets light in at (`MIN_COS`): `1 − cos²` once
    /// rounded to 1 below cos 1e-8 and put the direction outside the cone.
    #[test]
    fn grazing_mirror_samples_carry_a_positive_pdf() {
        let stack = materials::builtin("clear_coat_lambertian").expect("built in");
        let bsdf = LayeredBsdf::new(stack);
        assert!(bsdf.sample_is_exact());
        for c in [2e-18f32, 1e-16, 1e-13, 1e-10, 1e-9, 3e-9, 1e-8, 1e-6, 1e-3] {
            let wi = Vec3::new(1.0, 0.0, c);
            let mut mirrors = 0;
            for index in 0..32 {
                let s = bsdf
                    .sample(wi, index)
                    .expect("valid")
                    .expect("light enters");
                if s.specular {
                    mirrors += 1;
                    let m = wi.normalize();
                    let mirror = Vec3::new(-m.x, -m.y, m.z);
                    assert!((s.wo - mirror).length() < 1e-6, "cos {c}: {}", s.wo);
                    assert!(s.wo.z > 0.0, "cos {c}: {}", s.wo);
                    assert!(s.pdf > 0.0 && s.pdf.is_finite(), "cos {c}: pdf {}", s.pdf);
                    assert_eq!(s.pdf, bsdf.pdf(wi, s.wo).expect("valid"), "cos {c}");
                }
            }
            assert!(mirrors > 0, "cos {c}: no mirror sample");
        }
    }
}
