//! The public API: [`LayeredBsdf`], with eval, sample, pdf and albedo.
//!
//! Directions cross the boundary as `glam::Vec3` in the local frame (z = normal
//! of the stack's top; both directions pointing away from the surface). They
//! are normalized on the way in; a NaN, infinite or zero-length direction is a
//! [`QueryError`] naming the argument and its value, never a panic and never a
//! silent NaN.

use crate::estimator::scalar::ScalarEngine;
use crate::estimator::{Albedo, Estimate, Sample, Settings};
use crate::rng::{mix64, Stream, WalkRng};
use crate::stack::LayerStack;
use glam::Vec3;
use std::fmt;

/// A direction argument that cannot be used.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum QueryError {
    /// A component is NaN or infinite.
    NonFinite {
        /// `"wi"` or `"wo"`.
        argument: &'static str,
        /// The value given.
        value: [f32; 3],
    },
    /// The vector has zero length (or too small to normalize).
    ZeroLength {
        /// `"wi"` or `"wo"`.
        argument: &'static str,
        /// The value given.
        value: [f32; 3],
    },
}

impl fmt::Display for QueryError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            QueryError::NonFinite { argument, value } => write!(
                f,
                "{argument} = [{}, {}, {}] is not a direction: components must be finite",
                value[0], value[1], value[2]
            ),
            QueryError::ZeroLength { argument, value } => write!(
                f,
                "{argument} = [{}, {}, {}] is not a direction: it has zero length",
                value[0], value[1], value[2]
            ),
        }
    }
}

impl std::error::Error for QueryError {}

/// A validated unit direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Direction([f64; 3]);

impl Direction {
    /// Normalizes `v`, or says why it is not a direction.
    pub fn new(argument: &'static str, v: Vec3) -> Result<Self, QueryError> {
        Self::from_f64(argument, [v.x as f64, v.y as f64, v.z as f64])
    }

    /// Normalizes `d` (f64 components), or says why it is not a direction.
    pub fn from_f64(argument: &'static str, d: [f64; 3]) -> Result<Self, QueryError> {
        let value = d.map(|x| x as f32);
        if !d.iter().all(|x| x.is_finite()) {
            return Err(QueryError::NonFinite { argument, value });
        }
        let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        if l.is_nan() || l <= 1e-30 || !l.is_finite() {
            return Err(QueryError::ZeroLength { argument, value });
        }
        Ok(Direction(d.map(|x| x / l)))
    }

    /// As a glam vector (f32).
    pub fn to_vec3(self) -> Vec3 {
        Vec3::new(self.0[0] as f32, self.0[1] as f32, self.0[2] as f32)
    }
    /// The unit vector in f64.
    pub fn get(self) -> [f64; 3] {
        self.0
    }
}

/// A layered BSDF ready to query.
///
/// Every query is deterministic: its random streams are seeded from the
/// BSDF's seed and a query key. The single-query methods derive the key from
/// the directions' bits (so the same `(wi, wo)` always gives the same answer,
/// and different directions get independent streams); the `_with` variants
/// take the key explicitly.
#[derive(Clone, Debug)]
pub struct LayeredBsdf {
    scalar: ScalarEngine<f32>,
    settings: Settings,
    samples: u64,
    pdf_samples: u32,
    seed: u64,
}

impl LayeredBsdf {
    /// Default number of walks per `eval`.
    pub const DEFAULT_SAMPLES: u64 = 256;
    /// Default number of short walks per `pdf`.
    pub const DEFAULT_PDF_SAMPLES: u32 = 4;

    /// A BSDF over `stack` with default settings.
    pub fn new(stack: LayerStack) -> Self {
        Self::with_settings(stack, Settings::default())
    }

    /// A BSDF with explicit walk settings.
    pub fn with_settings(stack: LayerStack, settings: Settings) -> Self {
        LayeredBsdf {
            scalar: ScalarEngine::new(&stack, settings),
            settings,
            samples: Self::DEFAULT_SAMPLES,
            pdf_samples: Self::DEFAULT_PDF_SAMPLES,
            seed: 0,
        }
    }

    /// Sets the number of walks per `eval` (at least 1).
    pub fn samples(mut self, n: u64) -> Self {
        self.samples = n.max(1);
        self
    }

    /// Sets the number of short walks per `pdf`.
    pub fn pdf_samples(mut self, n: u32) -> Self {
        self.pdf_samples = n;
        self
    }

    /// Sets the seed of every random stream.
    pub fn seed(mut self, seed: u64) -> Self {
        self.seed = seed;
        self
    }

    /// The stack.
    pub fn stack(&self) -> &LayerStack {
        self.scalar.stack()
    }

    /// The walk settings.
    pub fn settings(&self) -> Settings {
        self.settings
    }

    /// The scalar reference engine.
    pub fn scalar(&self) -> &ScalarEngine<f32> {
        &self.scalar
    }

    /// `f(wi, wo)` (without the cosine) with its standard error.
    pub fn eval(&self, wi: Vec3, wo: Vec3) -> Result<Estimate, QueryError> {
        let (a, b) = (Direction::new("wi", wi)?, Direction::new("wo", wo)?);
        Ok(self.scalar.eval(
            a.get(),
            b.get(),
            self.samples,
            self.seed,
            direction_key(wi, wo),
        ))
    }

    /// `f(wi, wo)` from `samples` walks with query key `query`.
    pub fn eval_with(
        &self,
        wi: Vec3,
        wo: Vec3,
        samples: u64,
        query: u64,
    ) -> Result<Estimate, QueryError> {
        let (a, b) = (Direction::new("wi", wi)?, Direction::new("wo", wo)?);
        Ok(self
            .scalar
            .eval(a.get(), b.get(), samples, self.seed, query))
    }

    /// Samples an outgoing direction for light from `wi`; `None` if the walk
    /// was absorbed. `sample_index` selects the random stream.
    pub fn sample(&self, wi: Vec3, sample_index: u64) -> Result<Option<Sample>, QueryError> {
        let a = Direction::new("wi", wi)?;
        let mut rng = WalkRng::new(self.seed, direction_key(wi, wi), sample_index, Stream::Walk);
        Ok(self.scalar.sample(a.get(), &mut rng))
    }

    /// The approximate pdf of `wo` for `sample(wi)` (see [`crate::estimator::pdf`]).
    pub fn pdf(&self, wi: Vec3, wo: Vec3) -> Result<f32, QueryError> {
        let (a, b) = (Direction::new("wi", wi)?, Direction::new("wo", wo)?);
        Ok(self.scalar.pdf(
            a.get(),
            b.get(),
            self.pdf_samples,
            self.seed,
            direction_key(wi, wo),
        ) as f32)
    }

    /// Reflected and transmitted fractions of light from `wi`, from `n` walks.
    pub fn albedo(&self, wi: Vec3, n: u64) -> Result<Albedo, QueryError> {
        let a = Direction::new("wi", wi)?;
        Ok(self
            .scalar
            .albedo(a.get(), n, self.seed, direction_key(wi, wi)))
    }
}

/// A query key from the bits of two directions.
pub fn direction_key(wi: Vec3, wo: Vec3) -> u64 {
    let mut k = 0x5bd1_e995u64;
    for x in wi.to_array().into_iter().chain(wo.to_array()) {
        k = mix64(k ^ x.to_bits() as u64);
    }
    k
}
