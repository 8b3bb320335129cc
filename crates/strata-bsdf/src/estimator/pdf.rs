//! The pdfs of `sample()` (method.md §6), both from the density walk of
//! [`super::density`]:
//!
//! * **approximate** (what `pdf()` and `sample()` return): the mean of a few
//!   density walks, each stopped after [`APPROX_EVENTS`] events, mixed with
//!   a uniform density, `pdf = 0.9 p + 0.1 / 4π`, so that it is positive
//!   wherever `f` can be. It is deterministic for a pair of directions (the
//!   walks are keyed by them). What it neglects: paths longer than the bound,
//!   and the noise of a few walks (it is an unbiased estimate of the density
//!   of walks of at most [`APPROX_EVENTS`] events, then mixed);
//! * **unbiased**: the mean of many unbounded density walks, with its
//!   standard error: the density of `sample()`'s directions, for references
//!   and tests.

use super::density::DensityWalk;
use super::scalar::{v3, Scalar, ScalarEngine};
use crate::rng::{query_prefix, Stream, WalkRng};

/// Weight of the uniform density in the approximate pdf's mixture.
pub const UNIFORM_FRACTION: f64 = 0.1;

/// The approximate pdf's bound on a density walk's events: more than any
/// stack of the examples needs for 99 % of its density, and a bound on the
/// cost of a pdf in stacks whose walks are long (a white medium).
pub const APPROX_EVENTS: u32 = 64;

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

/// Which pdf of `sample()`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PdfKind {
    /// Bounded walks mixed with a uniform density (the default; what
    /// `sample()` returns).
    #[default]
    Approximate,
    /// Unbounded walks, no mixture: the density itself, with its standard
    /// error.
    Unbiased,
}

impl std::str::FromStr for PdfKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "approx" => Ok(PdfKind::Approximate),
            "unbiased" => Ok(PdfKind::Unbiased),
            _ => Err(format!("unknown pdf {s:?} (expected approx or unbiased)")),
        }
    }
}

impl PdfKind {
    /// The density walk's bound on events.
    pub fn max_events(self) -> Option<u32> {
        match self {
            PdfKind::Approximate => Some(APPROX_EVENTS),
            PdfKind::Unbiased => None,
        }
    }
}

/// A pdf estimate: the mean of density walks and its standard error.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PdfEstimate {
    /// The density (solid angle, stack frame).
    pub value: f64,
    /// The standard error of `value` (0 for an exact one).
    pub stderr: f64,
    /// Number of walks.
    pub samples: u64,
}

/// Sums of density walks, in walk order (so that engines agree bit for bit).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DensitySums {
    sum: f64,
    sum_sq: f64,
    n: u64,
}

impl DensitySums {
    /// Adds one walk's density.
    #[inline]
    pub fn push(&mut self, x: f64) {
        self.sum += x;
        self.sum_sq += x * x;
        self.n += 1;
    }

    /// Adds `x` to every walk's density (an exact part, no variance).
    pub fn estimate_plus(&self, x: f64) -> PdfEstimate {
        if self.n == 0 {
            return PdfEstimate {
                value: x,
                ..PdfEstimate::default()
            };
        }
        let n = self.n as f64;
        let mean = self.sum / n;
        let var = if self.n > 1 {
            ((self.sum_sq - n * mean * mean) / (n - 1.0)).max(0.0)
        } else {
            0.0
        };
        PdfEstimate {
            value: x + mean,
            stderr: (var / n).sqrt(),
            samples: self.n,
        }
    }

    /// The pdf of this kind from these sums.
    pub fn finish(&self, kind: PdfKind) -> PdfEstimate {
        let e = self.estimate_plus(0.0);
        match kind {
            PdfKind::Unbiased => e,
            PdfKind::Approximate => PdfEstimate {
                value: mix_uniform(e.value),
                stderr: (1.0 - UNIFORM_FRACTION) * e.stderr,
                samples: e.samples,
            },
        }
    }
}

impl<S: Scalar> ScalarEngine<S> {
    /// The approximate pdf of `wo` for `sample(wi)`, from `samples` walks.
    pub fn pdf(&self, wi: [f64; 3], wo: [f64; 3], samples: u32, seed: u64, query: u64) -> f64 {
        self.pdf_estimate(wi, wo, samples as u64, seed, query, PdfKind::Approximate)
            .value
    }

    /// A pdf of `wo` for `sample(wi)` from `samples` density walks.
    pub fn pdf_estimate(
        &self,
        wi: [f64; 3],
        wo: [f64; 3],
        samples: u64,
        seed: u64,
        query: u64,
        kind: PdfKind,
    ) -> PdfEstimate {
        let Some(o) = super::orient(&self.stack, wi, Some(wo)) else {
            return PdfEstimate::default();
        };
        let wi = v3::<S>(o.wi);
        let wo = v3::<S>(o.apply(wo));
        let walk = DensityWalk {
            ifaces: &self.ifaces,
            media: &self.media,
            settings: &self.settings,
            max_events: kind.max_events(),
        };
        let prefix = query_prefix(seed, query);
        let mut sums = DensitySums::default();
        for k in 0..samples {
            let mut rng = WalkRng::from_prefix(prefix, k, Stream::Pdf);
            let draw = |m: bool| {
                if m {
                    S::splat(rng.uniform() as f64)
                } else {
                    S::zero()
                }
            };
            sums.push(walk.run(wi, wo, draw).lane(0));
        }
        sums.finish(kind)
    }
}
