//! Estimators of the layered BSDF.
//!
//! * [`scalar`]: the reference, one walk at a time, generic over `f32` (the
//!   reference) and `f64` (the accuracy oracle).
//! * [`events`]: the event kernels both engines call, written once over lanes.
//! * [`layout`]: the stack's topology as the walks see it.
//! * [`bidir`]: the bidirectional estimator of `eval`.
//! * [`density`]: the density walk, the density of `sample` at a direction.
//! * [`pdf`]: the approximate and unbiased pdfs of `sample` from it.
//! * [`coat_lambertian`]: a coat over a layer over a Lambertian base, which
//!   `Auto` answers without walks ([`closed_form`] under a smooth coat,
//!   [`rough_coat`] under a rough one; [`coat_return`], the integral both
//!   need), or with walks of collided paths only.
//!
//! Both follow `docs/method.md`; the differences from the paper and from the
//! authors' code are listed in `docs/architecture.md`.

mod accumulate;
pub mod bidir;
pub mod closed_form;
pub mod coat_lambertian;
pub mod coat_return;
pub mod density;
pub mod events;
pub mod layout;
mod orient;
pub mod params;
pub mod pdf;
pub mod rough_coat;
pub mod scalar;
pub mod wavefront;

pub use crate::math::MIN_COS;
pub use accumulate::{BlockReducer, MeanVar, BLOCK};
#[doc(hidden)]
pub use orient::orient;

/// Walk controls shared by the estimators.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    /// Russian roulette starts after this many events (interface or medium).
    /// It is unbiased: survivors are reweighted.
    pub rr_start: u32,
    /// The limit of events (interface events and collisions) per walk: a
    /// walk that reaches it ends there, and its result counts it as cut.
    /// The default, [`events::MAX_EVENTS`], bounds the time and memory of a
    /// walk on any stack (docs/numerics.md, *Walk length*) without changing
    /// an answer of the stress suite; below it the estimate loses
    /// the energy of longer paths, which is biased. A bidirectional walk
    /// connects every vertex of one subpath to every vertex of the other, so
    /// its subpaths end at `√max_events` vertices. Values are taken in
    /// `1..=`[`events::MAX_CAP`].
    pub max_events: u32,
    /// Keep only paths with at most this many medium scattering events
    /// (`Some(1)` gives single scattering, the analytic check of method.md §8).
    pub max_scatter_order: Option<u32>,
    /// Combine next-event estimation and path continuation with MIS (power
    /// heuristic); `false` uses next-event estimation alone where it applies,
    /// and the pdf's density walks leave out their medium connection (an
    /// unbiased estimate either way: `tests/estimators/pdf_density.rs` compares them).
    pub mis: bool,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            rr_start: 4,
            max_events: events::MAX_EVENTS,
            max_scatter_order: None,
            mis: true,
        }
    }
}

/// A Monte Carlo estimate per RGB channel with its standard error.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Estimate {
    /// The mean.
    pub value: [f64; 3],
    /// The standard error of the mean.
    pub stderr: [f64; 3],
    /// Number of independent walks.
    pub samples: u64,
    /// How many of them reached the limit of events
    /// ([`Settings::max_events`]) and ended there: their paths' energy
    /// beyond it is missing from `value`.
    pub truncated: u64,
}

/// What an eval adds to the mean of its walks: deterministic terms (the
/// first-order term, a smooth coat's closed form) and, for a rough coat over
/// a Lambertian base, the mean of independent samples of its factorized part
/// (`rough_coat`), whose variance adds to the walks'.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Terms {
    /// Added exactly.
    pub exact: [f64; 3],
    /// Added with its standard error.
    pub sampled: Option<MeanVar>,
}

impl MeanVar {
    /// The estimate of the walks plus `terms`: the means add, and the
    /// variances of the means of independent samples add.
    pub fn estimate_with(&self, terms: &Terms) -> Estimate {
        let mut e = self.estimate_plus(terms.exact);
        if let Some(s) = terms.sampled {
            let x = s.estimate();
            for c in 0..3 {
                e.value[c] += x.value[c];
                e.stderr[c] = e.stderr[c].hypot(x.stderr[c]);
            }
        }
        e
    }
}

/// Directional albedo: reflected and transmitted fractions.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Albedo {
    /// Reflected fraction per channel.
    pub reflected: Estimate,
    /// Transmitted fraction per channel.
    pub transmitted: Estimate,
}

/// One walk of the sampler, as the engines return it (the API adds the pdf:
/// [`crate::Sample`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WalkSample {
    /// The outgoing direction (unit, pointing away from the surface).
    pub wo: glam::Vec3,
    /// `f(wi, wo) |cos θo| / p(wo)`: an unbiased estimate, the walk's throughput.
    pub weight: [f32; 3],
    /// The walk left on the side it entered (reflection).
    pub reflection: bool,
    /// Every event of the walk was a delta (the direction is a specular one).
    pub specular: bool,
}
