//! What the estimators return: an estimate with its standard error, a
//! directional albedo, one walk of the sampler.

/// A Monte Carlo estimate per RGB channel with its standard error.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Estimate {
    /// The mean.
    pub value: [f64; 3],
    /// The standard error of the mean.
    pub stderr: [f64; 3],
    /// Number of independent walks.
    pub samples: u64,
    /// How many of them reached the limit of events
    /// ([`Settings::max_events`](super::Settings::max_events)) and ended there: their paths' energy
    /// beyond it is missing from `value`.
    pub truncated: u64,
}

/// Directional albedo: reflected and transmitted fractions.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Albedo {
    /// Reflected fraction per channel.
    pub reflected: Estimate,
    /// Transmitted fraction per channel.
    pub transmitted: Estimate,
}

/// One walk of the sampler, as the engines return it (the API adds the pdf:
/// [`crate::api::Sample`]).
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
