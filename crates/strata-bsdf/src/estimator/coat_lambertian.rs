//! A dielectric coat over a layer over a Lambertian base: what
//! [`crate::Estimator::Auto`] knows of it without a walk.
//!
//! Over a clear or absorbing layer the whole BSDF is known: in closed form
//! under a smooth coat ([`SmoothCoatLambertian`]), factorized into two
//! sampled transmissions and a constant under a rough one
//! ([`RoughCoatLambertian`]). Over a *scattering* layer the same
//! expressions at the layer's `σt` give the paths that never collide in it,
//! `f₀`: `Auto`'s control variate adds `f₀` and lets the walks score only
//! the paths with a collision, where that pays
//! ([`CoatLambertian::control_variate_pays`]).

use super::accumulate::MeanVar;
use super::closed_form::SmoothCoatLambertian;
use super::coat_and_base::coat_and_base;
use super::estimate::WalkSample;
use super::rough_coat::RoughCoatLambertian;
use super::settings::Settings;
use crate::rng::WalkRng;
use crate::stack::{LayerStack, PhaseKind};
use std::sync::Arc;

/// The deepest grey medium on which [`crate::Estimator::Auto`] uses the
/// boosted control variate ([`CoatLambertian::control_variate_pays`]).
/// A conservative choice: the deepest measured stack inside the rule is at
/// τ 2; a grey τ 8 one about broke even at its worst pair, and the deep
/// example `jade` (which the other conditions leave out too) lost
/// efficiency (docs/performance.md).
pub const BOOSTED_CV_MAX_DEPTH: f64 = 2.0;

/// The darkest base (smallest albedo of a channel) over which
/// [`crate::Estimator::Auto`] uses the control variate under a *rough* coat
/// ([`CoatLambertian::control_variate_pays`]). Over a darker one the series
/// of bounces that the control variate takes out of the walks is short, and
/// sampling `f₀` costs about what it saves (docs/performance.md).
pub const ROUGH_CV_MIN_BASE: f64 = 0.5;

/// A coat over a layer over a Lambertian base, smooth or rough.
#[derive(Clone, Debug)]
pub enum CoatLambertian {
    /// A smooth coat: the closed form.
    Smooth(SmoothCoatLambertian),
    /// A rough coat: the factorization (its lanes make it large: shared,
    /// not copied, by the engines and parameter sets that hold it).
    Rough(Arc<RoughCoatLambertian>),
}

impl CoatLambertian {
    /// The whole BSDF of `stack` (a coat over a clear or absorbing layer
    /// over a Lambertian base), where `settings` allow it.
    pub fn of(stack: &LayerStack, settings: &Settings) -> Option<Self> {
        SmoothCoatLambertian::of(stack, settings)
            .map(CoatLambertian::Smooth)
            .or_else(|| RoughCoatLambertian::of(stack, settings).map(|r| Self::Rough(Arc::new(r))))
    }

    /// The part of `stack`'s BSDF carried by the paths without a collision
    /// in its layer (any layer), where `settings` allow it.
    pub fn unscattered(stack: &LayerStack, settings: &Settings) -> Option<Self> {
        Self::unscattered_with(stack, settings, false)
    }

    /// [`CoatLambertian::unscattered`], with `R̄` from the coat's table
    /// where `tabulated` (a per-query row: see
    /// [`SmoothCoatLambertian::unscattered_with`] and
    /// [`RoughCoatLambertian::tabulated`]).
    pub fn unscattered_with(
        stack: &LayerStack,
        settings: &Settings,
        tabulated: bool,
    ) -> Option<Self> {
        SmoothCoatLambertian::unscattered_with(stack, settings, tabulated)
            .map(CoatLambertian::Smooth)
            .or_else(|| {
                let r = RoughCoatLambertian::unscattered_with(stack, settings, tabulated)?;
                Some(Self::Rough(Arc::new(r)))
            })
    }

    /// The closed form, for a smooth coat.
    pub fn smooth(&self) -> Option<&SmoothCoatLambertian> {
        match self {
            CoatLambertian::Smooth(s) => Some(s),
            CoatLambertian::Rough(_) => None,
        }
    }

    /// The factorization, for a rough coat.
    pub fn rough(&self) -> Option<&RoughCoatLambertian> {
        match self {
            CoatLambertian::Smooth(_) => None,
            CoatLambertian::Rough(r) => Some(r),
        }
    }

    /// What it knows exactly at `(wi, wo)` (oriented frame): a smooth coat's
    /// closed form; nothing for a rough coat, whose coat reflection the
    /// engines' first-order term carries and whose rest is sampled
    /// ([`CoatLambertian::sampled`]).
    pub fn exact(&self, wi: [f64; 3], wo: [f64; 3]) -> [f64; 3] {
        match self {
            CoatLambertian::Smooth(s) => s.eval(wi, wo),
            CoatLambertian::Rough(_) => [0.0; 3],
        }
    }

    /// What it samples at `(wi, wo)` (oriented frame): `n` samples of a rough
    /// coat's factorized part from the query's streams (`prefix`); `None`
    /// for a smooth coat.
    pub fn sampled(&self, wi: [f64; 3], wo: [f64; 3], n: u64, prefix: u64) -> Option<MeanVar> {
        self.rough().map(|r| r.sample_mean(wi, wo, n, prefix))
    }

    /// `sample()` without a walk for a query on `stack` (any orientation: a
    /// two-sided stack lit from below is turned over), drawing its uniforms
    /// from `rng` as a walk's sample: the smooth coat's closed-form sampler
    /// (three uniforms), the rough coat's mixture of its lobe and a cosine
    /// lobe (seven). Its pdf, [`CoatLambertian::pdf_query`], is exact.
    pub fn sample_query(
        &self,
        stack: &LayerStack,
        wi: [f64; 3],
        rng: &mut WalkRng,
    ) -> Option<WalkSample> {
        let o = super::orient(stack, wi, None)?;
        let mut u = || rng.uniform() as f64;
        let s = match self {
            CoatLambertian::Smooth(c) => c.sample(o.wi, [(); 3].map(|_| u())),
            CoatLambertian::Rough(c) => c.sample(o.wi, [(); 7].map(|_| u())),
        }?;
        let wo = o.apply(s.wo).map(|x| x as f32);
        Some(WalkSample {
            wo: glam::Vec3::from(wo),
            weight: s.weight.map(|x| x as f32),
            reflection: true,
            specular: s.specular,
        })
    }

    /// The density of [`CoatLambertian::sample_query`]'s directions for a
    /// query on `stack` (0 where `wo` leaves on a side light cannot leave
    /// by).
    pub fn pdf_query(&self, stack: &LayerStack, wi: [f64; 3], wo: [f64; 3]) -> f64 {
        let Some(o) = super::orient(stack, wi, Some(wo)) else {
            return 0.0;
        };
        match self {
            CoatLambertian::Smooth(c) => c.pdf(o.wi, o.apply(wo)),
            CoatLambertian::Rough(c) => c.pdf(o.wi, o.apply(wo)),
        }
    }

    /// `other`, sharing this one's integral `R̄` where both are rough with
    /// the same coat and layer (see [`RoughCoatLambertian::sharing_return`]).
    pub fn sharing_return(&self, other: CoatLambertian) -> CoatLambertian {
        match (self, other) {
            (CoatLambertian::Rough(a), CoatLambertian::Rough(b)) => {
                CoatLambertian::Rough(Arc::new(a.sharing_return((*b).clone())))
            }
            (_, other) => other,
        }
    }

    /// Whether [`crate::Estimator::Auto`] uses the control variate on
    /// `stack`: it has the shape ([`CoatLambertian::unscattered`]), its
    /// medium scatters, and, under a **smooth** coat, either
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
    /// left out by choice ([`BOOSTED_CV_MAX_DEPTH`]). A mixture of a single
    /// lobe counts as a mixture here.
    ///
    /// Under a **rough** coat, whose `f₀` is sampled, only where the medium
    /// scatters little against what the base reflects (as above) over a
    /// base no darker than [`ROUGH_CV_MIN_BASE`]: under rough coats the grey
    /// media of the first rule lost efficiency at some pair or gained
    /// little.
    ///
    /// Measured in `tests/estimators/layered_control_variate.rs`
    /// (`control_variate_efficiency`; docs/performance.md).
    pub fn control_variate_pays(stack: &LayerStack, settings: &Settings) -> bool {
        // The shape of `unscattered`, without building it.
        let Some((coat, _)) = coat_and_base(stack, settings) else {
            return false;
        };
        if !coat.smooth && !RoughCoatLambertian::in_domain(coat) {
            return false;
        }
        let Some(m) = stack.medium(0).filter(|m| m.scatters()) else {
            return false;
        };
        let tau = m.optical_depth();
        let rho = stack.interface(1).albedo;
        let scatter = (0..3).map(|c| tau[c] * m.albedo[c]).fold(0.0, f64::max);
        let base = rho.iter().copied().fold(f64::INFINITY, f64::min);
        let little = scatter <= 0.1 * base;
        if !stack.interface(0).smooth {
            return little && base >= ROUGH_CV_MIN_BASE;
        }
        let grey = m.grey() && m.albedo.iter().all(|&a| a == m.albedo[0]);
        let boosted_pays =
            grey && tau[0] <= BOOSTED_CV_MAX_DEPTH && m.phase_kind() == PhaseKind::Hg;
        boosted_pays || little
    }
}
