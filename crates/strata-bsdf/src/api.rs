//! The public API: [`LayeredBsdf`], with eval, sample, pdf and albedo.
//!
//! Directions cross the boundary as `glam::Vec3` in the local frame (z = normal
//! of the stack's top; both directions pointing away from the surface). They
//! are normalized on the way in; a NaN, infinite or zero-length direction is a
//! [`QueryError`] naming the argument and its value, never a panic and never a
//! silent NaN.

use crate::estimator::scalar::ScalarEngine;
use crate::estimator::wavefront::{DefaultWide, Plan, Wavefront, PDF_CHUNK, SERIAL_WALKS};
use crate::estimator::{Albedo, Estimate, Sample, Settings};
use crate::lane::Lane;
use crate::rng::{mix64, Stream, WalkRng};
use crate::stack::LayerStack;
use glam::Vec3;
use std::fmt;
use std::sync::Arc;

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
    /// The vector has zero length.
    ZeroLength {
        /// `"wi"` or `"wo"`.
        argument: &'static str,
        /// The value given.
        value: [f32; 3],
    },
    /// A number of walks of 0: there would be no estimate.
    NoSamples {
        /// The argument (`"samples"`, `"n"`).
        argument: &'static str,
    },
    /// More walks per query than [`MAX_WALKS`].
    TooManySamples {
        /// The argument (`"samples"`, `"n"`).
        argument: &'static str,
        /// The number given.
        value: u64,
    },
    /// A batch's per-query argument does not have one entry per query.
    LengthMismatch {
        /// The argument (`"keys"`, `"sample_index"`).
        argument: &'static str,
        /// Its length.
        len: usize,
        /// The number of queries.
        queries: usize,
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
            QueryError::NoSamples { argument } => {
                write!(f, "{argument} = 0: at least one walk is needed")
            }
            QueryError::TooManySamples { argument, value } => write!(
                f,
                "{argument} = {value}: at most {MAX_WALKS} walks per query (2^40)"
            ),
            QueryError::LengthMismatch {
                argument,
                len,
                queries,
            } => write!(
                f,
                "{argument} has {len} entries for {queries} queries: give one per query"
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
        // Scaled by the largest component first, so that no finite nonzero
        // vector overflows or underflows on the way (1e200 or 1e-200).
        let m = d.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        if m == 0.0 {
            return Err(QueryError::ZeroLength { argument, value });
        }
        let s = d.map(|x| x / m);
        let l = (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt();
        Ok(Direction(s.map(|x| x / l)))
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

/// Which engine answers a query. The scalar and the wavefront engine give the
/// same results for the same seeds (walk by walk, bit for bit: they run the
/// same f32 operations; tested); `Auto` gives one of theirs.
///
/// The wavefront engine pays a fixed setup cost per call (preparing the
/// queries and a wave, about 0.6–1.5 µs), which its lanes repay many times over
/// on a batch, or on an `eval` of many walks, but not on a call of fewer walks
/// than it has lanes (a single `sample` or `pdf`): there the scalar engine is
/// the cheaper one (1.7–3.3× faster on a single `sample`; docs/performance.md).
/// [`Engine::Auto`], the default, picks per call. Calls of at most
/// [`SERIAL_WALKS`] walks (pdf batches of at most [`PDF_CHUNK`] queries) run
/// on the calling thread on either engine, with or without
/// [`LayeredBsdf::threads`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Engine {
    /// Per call: the scalar engine for calls of fewer walks (queries × walks
    /// per query) than the wavefront has lanes, and for a single `pdf` (the
    /// wavefront's pdf runs one query per lane); the wavefront otherwise.
    #[default]
    Auto,
    /// The scalar reference: one walk at a time.
    Scalar,
    /// The SIMD wavefront engine: walks in lanes, batches over threads.
    Wavefront,
}

impl Engine {
    /// The engine that answers a call of `queries` queries of `walks` walks
    /// each: `Scalar` or `Wavefront`, never `Auto`.
    pub fn resolve(self, queries: usize, walks: u64) -> Engine {
        match self {
            Engine::Auto
                if (queries as u64).saturating_mul(walks) < <DefaultWide as Lane>::LANES as u64 =>
            {
                Engine::Scalar
            }
            Engine::Auto => Engine::Wavefront,
            e => e,
        }
    }

    /// The engine that answers a pdf call of `queries` queries. The
    /// wavefront runs one query per lane, so a single query leaves seven of
    /// eight lanes idle whatever its walk count; at 4 queries and more it is
    /// the faster one on every representative stack (docs/performance.md),
    /// and from 2 on it fills at least two lanes.
    pub fn resolve_pdf(self, queries: usize) -> Engine {
        match self {
            Engine::Auto if queries < 2 => Engine::Scalar,
            Engine::Auto => Engine::Wavefront,
            e => e,
        }
    }
}

impl std::str::FromStr for Engine {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "auto" => Ok(Engine::Auto),
            "scalar" => Ok(Engine::Scalar),
            "wavefront" => Ok(Engine::Wavefront),
            _ => Err(format!(
                "unknown engine {s:?} (expected auto, scalar or wavefront)"
            )),
        }
    }
}

/// A batch call that cannot be run: which query, and why.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BatchError {
    /// Index of the query in the batch; `None` when the fault is in an
    /// argument of the whole call (a walk count, the length of a per-query
    /// argument).
    pub index: Option<usize>,
    /// What is wrong.
    pub error: QueryError,
}

impl BatchError {
    /// A fault in an argument of the whole call.
    fn call(error: QueryError) -> Self {
        BatchError { index: None, error }
    }
}

impl fmt::Display for BatchError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.index {
            Some(i) => write!(f, "query {i}: {}", self.error),
            None => write!(f, "{}", self.error),
        }
    }
}

impl std::error::Error for BatchError {}

/// The most walks one query may ask for, 2^40: beyond it the walk counts of
/// a batch could overflow, and a query would run for weeks anyway.
pub const MAX_WALKS: u64 = 1 << 40;

/// The largest thread pool [`LayeredBsdf::threads`] builds: more threads
/// than cores never helps, and each one reserves a stack.
pub const MAX_THREADS: usize = 1024;

/// A thread pool that cannot be built.
#[derive(Debug)]
pub enum ThreadsError {
    /// More threads than [`MAX_THREADS`].
    TooMany(usize),
    /// The operating system refused (rayon's error).
    Pool(rayon::ThreadPoolBuildError),
}

impl fmt::Display for ThreadsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ThreadsError::TooMany(n) => {
                write!(
                    f,
                    "threads = {n}: at most {MAX_THREADS} (0 means one per core)"
                )
            }
            ThreadsError::Pool(e) => write!(f, "cannot build a thread pool: {e}"),
        }
    }
}

impl std::error::Error for ThreadsError {}

/// A layered BSDF ready to query.
///
/// Every query is deterministic: its random streams are seeded from the
/// BSDF's seed and a query key. The plain methods derive the key from the
/// directions' bits (so the same `(wi, wo)` always gives the same answer,
/// alone or in a batch, on either engine; the two engines agree bit for
/// bit, and [`Engine::Auto`] picks one by the size of the call); the
/// `_keyed` variants take the keys explicitly, so that a renderer can draw
/// fresh noise per call.
///
/// ```
/// use strata_bsdf::{Engine, LayeredBsdf, LayerStack};
/// use glam::Vec3;
/// let stack = LayerStack::from_toml_str(r#"
///     [[layers]]
///     interface = { kind = "dielectric", ior = 1.5 }
///     [[layers]]
///     interface = { kind = "diffuse", albedo = 0.8 }
/// "#).unwrap();
/// let bsdf = LayeredBsdf::new(stack).samples(512);
/// let pairs = [(Vec3::Z, Vec3::new(0.5, 0.0, 0.8)), (Vec3::new(0.3, 0.0, 0.9), Vec3::Z)];
/// let batch = bsdf.eval_batch(&pairs).unwrap();
/// // A batch answers exactly what single queries answer, on either engine.
/// let single = bsdf.clone().engine(Engine::Scalar).eval(pairs[1].0, pairs[1].1).unwrap();
/// assert_eq!(batch[1].value, single.value);
/// ```
#[derive(Clone, Debug)]
pub struct LayeredBsdf {
    scalar: ScalarEngine<f32>,
    wave: Wavefront<DefaultWide>,
    settings: Settings,
    engine: Engine,
    samples: u64,
    pdf_samples: u32,
    seed: u64,
    pool: Option<Arc<rayon::ThreadPool>>,
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
            wave: Wavefront::new(&stack, settings, Plan::Specialized),
            settings,
            engine: Engine::default(),
            samples: Self::DEFAULT_SAMPLES,
            pdf_samples: Self::DEFAULT_PDF_SAMPLES,
            seed: 0,
            pool: None,
        }
    }

    /// Sets the number of walks per `eval` (at least 1; a call with more
    /// than [`MAX_WALKS`] is a [`QueryError::TooManySamples`]).
    pub fn samples(mut self, n: u64) -> Self {
        self.samples = n.max(1);
        self
    }

    /// Sets the number of short walks per `pdf` (at least 1).
    pub fn pdf_samples(mut self, n: u32) -> Self {
        self.pdf_samples = n.max(1);
        self
    }

    /// Sets the seed of every random stream.
    pub fn seed(mut self, seed: u64) -> Self {
        self.seed = seed;
        self
    }

    /// Chooses the engine.
    pub fn engine(mut self, engine: Engine) -> Self {
        self.engine = engine;
        self
    }

    /// Runs the wavefront engine's batches on a pool of `n` threads (by
    /// default, rayon's global pool; `n = 0` also means one thread per
    /// core). Calls of at most [`SERIAL_WALKS`] walks (and pdf batches of at
    /// most [`PDF_CHUNK`] queries) run on the calling thread whatever the
    /// pool. Results do not depend on it. At most [`MAX_THREADS`].
    pub fn threads(mut self, n: usize) -> Result<Self, ThreadsError> {
        if n > MAX_THREADS {
            return Err(ThreadsError::TooMany(n));
        }
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .map_err(ThreadsError::Pool)?;
        self.pool = Some(Arc::new(pool));
        Ok(self)
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

    /// The wavefront engine.
    pub fn wavefront(&self) -> &Wavefront<DefaultWide> {
        &self.wave
    }

    /// Runs `f` on this BSDF's thread pool, if it has one, when the work
    /// (`queries` queries of `walks` walks each) is more than
    /// [`SERIAL_WALKS`]; less runs as one task on the calling thread (a
    /// hand-over to a pool's thread costs more than such a batch).
    fn install<R: Send>(&self, queries: usize, walks: u64, f: impl FnOnce() -> R + Send) -> R {
        self.install_if((queries as u64).saturating_mul(walks) > SERIAL_WALKS, f)
    }

    /// Runs `f` on this BSDF's pool, if it has one and `parallel` is set.
    fn install_if<R: Send>(&self, parallel: bool, f: impl FnOnce() -> R + Send) -> R {
        match &self.pool {
            Some(p) if parallel => p.install(f),
            _ => f(),
        }
    }

    // ------------------------------------------------------------ single queries

    /// `f(wi, wo)` (without the cosine) with its standard error.
    pub fn eval(&self, wi: Vec3, wo: Vec3) -> Result<Estimate, QueryError> {
        self.eval_with(wi, wo, self.samples, direction_key(wi, wo))
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
        walk_count("samples", samples)?;
        Ok(match self.engine.resolve(1, samples) {
            Engine::Scalar => self
                .scalar
                .eval(a.get(), b.get(), samples, self.seed, query),
            _ => self.install(1, samples, || {
                self.wave
                    .eval_batch(&[(a.get(), b.get())], samples, self.seed, &[query])
                    .0[0]
            }),
        })
    }

    /// Samples an outgoing direction for light from `wi`; `None` if the walk
    /// was absorbed. `sample_index` selects the random stream.
    pub fn sample(&self, wi: Vec3, sample_index: u64) -> Result<Option<Sample>, QueryError> {
        Ok(self
            .sample_batch_keyed(&[wi], &[direction_key(wi, wi)], &[sample_index])
            .map_err(|e| e.error)?[0])
    }

    /// The approximate pdf of `wo` for `sample(wi)` (see [`crate::estimator::pdf`]).
    pub fn pdf(&self, wi: Vec3, wo: Vec3) -> Result<f32, QueryError> {
        Ok(self.pdf_batch(&[(wi, wo)]).map_err(|e| e.error)?[0])
    }

    /// Reflected and transmitted fractions of light from `wi`, from `n` walks.
    pub fn albedo(&self, wi: Vec3, n: u64) -> Result<Albedo, QueryError> {
        Ok(self
            .albedo_batch_keyed(&[wi], n, &[direction_key(wi, wi)])
            .map_err(|e| e.error)?[0])
    }

    // ------------------------------------------------------------------ batches

    /// `f(wi, wo)` for every pair, `samples()` walks each; query keys from
    /// the directions (the same answers as [`LayeredBsdf::eval`]).
    pub fn eval_batch(&self, pairs: &[(Vec3, Vec3)]) -> Result<Vec<Estimate>, BatchError> {
        let keys: Vec<u64> = pairs.iter().map(|&(a, b)| direction_key(a, b)).collect();
        self.eval_batch_keyed(pairs, self.samples, &keys)
    }

    /// `f(wi, wo)` for every pair with `samples` walks and explicit keys.
    pub fn eval_batch_keyed(
        &self,
        pairs: &[(Vec3, Vec3)],
        samples: u64,
        keys: &[u64],
    ) -> Result<Vec<Estimate>, BatchError> {
        let dirs = directions2(pairs)?;
        one_each("keys", keys.len(), pairs.len())?;
        walk_count("samples", samples).map_err(BatchError::call)?;
        Ok(match self.engine.resolve(dirs.len(), samples) {
            Engine::Scalar => dirs
                .iter()
                .zip(keys)
                .map(|(&(a, b), &k)| self.scalar.eval(a, b, samples, self.seed, k))
                .collect(),
            _ => self.install(dirs.len(), samples, || {
                self.wave.eval_batch(&dirs, samples, self.seed, keys).0
            }),
        })
    }

    /// One sampled direction per incident direction; `sample_index[k]`
    /// selects query `k`'s random stream; keys from the directions.
    pub fn sample_batch(
        &self,
        wis: &[Vec3],
        sample_index: &[u64],
    ) -> Result<Vec<Option<Sample>>, BatchError> {
        let keys: Vec<u64> = wis.iter().map(|&a| direction_key(a, a)).collect();
        self.sample_batch_keyed(wis, &keys, sample_index)
    }

    /// [`LayeredBsdf::sample_batch`] with explicit keys.
    pub fn sample_batch_keyed(
        &self,
        wis: &[Vec3],
        keys: &[u64],
        sample_index: &[u64],
    ) -> Result<Vec<Option<Sample>>, BatchError> {
        let dirs = directions1(wis)?;
        one_each("keys", keys.len(), wis.len())?;
        one_each("sample_index", sample_index.len(), wis.len())?;
        Ok(match self.engine.resolve(dirs.len(), 1) {
            Engine::Scalar => dirs
                .iter()
                .zip(keys.iter().zip(sample_index))
                .map(|(&a, (&k, &i))| {
                    let mut rng = WalkRng::new(self.seed, k, i, Stream::Walk);
                    self.scalar.sample(a, &mut rng)
                })
                .collect(),
            _ => self.install(dirs.len(), 1, || {
                self.wave
                    .sample_batch(&dirs, self.seed, keys, sample_index)
                    .0
            }),
        })
    }

    /// The approximate pdf for every pair; keys from the directions.
    pub fn pdf_batch(&self, pairs: &[(Vec3, Vec3)]) -> Result<Vec<f32>, BatchError> {
        let dirs = directions2(pairs)?;
        let keys: Vec<u64> = pairs.iter().map(|&(a, b)| direction_key(a, b)).collect();
        let p: Vec<f64> = match self.engine.resolve_pdf(dirs.len()) {
            Engine::Scalar => dirs
                .iter()
                .zip(&keys)
                .map(|(&(a, b), &k)| self.scalar.pdf(a, b, self.pdf_samples, self.seed, k))
                .collect(),
            _ => self.install_if(dirs.len() > PDF_CHUNK, || {
                self.wave
                    .pdf_batch(&dirs, self.pdf_samples, self.seed, &keys)
            }),
        };
        Ok(p.into_iter().map(|x| x as f32).collect())
    }

    /// Directional albedo of every incident direction, `n` walks each; keys
    /// from the directions.
    pub fn albedo_batch(&self, wis: &[Vec3], n: u64) -> Result<Vec<Albedo>, BatchError> {
        let keys: Vec<u64> = wis.iter().map(|&a| direction_key(a, a)).collect();
        self.albedo_batch_keyed(wis, n, &keys)
    }

    /// [`LayeredBsdf::albedo_batch`] with explicit keys.
    pub fn albedo_batch_keyed(
        &self,
        wis: &[Vec3],
        n: u64,
        keys: &[u64],
    ) -> Result<Vec<Albedo>, BatchError> {
        let dirs = directions1(wis)?;
        one_each("keys", keys.len(), wis.len())?;
        walk_count("n", n).map_err(BatchError::call)?;
        Ok(match self.engine.resolve(dirs.len(), n) {
            Engine::Scalar => dirs
                .iter()
                .zip(keys)
                .map(|(&a, &k)| self.scalar.albedo(a, n, self.seed, k))
                .collect(),
            _ => self.install(dirs.len(), n, || {
                self.wave.albedo_batch(&dirs, n, self.seed, keys).0
            }),
        })
    }
}

/// A walk count from 1 to [`MAX_WALKS`].
fn walk_count(argument: &'static str, n: u64) -> Result<(), QueryError> {
    if n == 0 {
        Err(QueryError::NoSamples { argument })
    } else if n > MAX_WALKS {
        Err(QueryError::TooManySamples { argument, value: n })
    } else {
        Ok(())
    }
}

/// One entry of a per-query argument for every query.
fn one_each(argument: &'static str, len: usize, queries: usize) -> Result<(), BatchError> {
    if len == queries {
        Ok(())
    } else {
        Err(BatchError::call(QueryError::LengthMismatch {
            argument,
            len,
            queries,
        }))
    }
}

fn directions1(wis: &[Vec3]) -> Result<Vec<[f64; 3]>, BatchError> {
    wis.iter()
        .enumerate()
        .map(|(index, &w)| {
            Direction::new("wi", w)
                .map(|d| d.get())
                .map_err(|error| BatchError {
                    index: Some(index),
                    error,
                })
        })
        .collect()
}

/// A validated `(wi, wo)` pair.
type Pair = ([f64; 3], [f64; 3]);

fn directions2(pairs: &[(Vec3, Vec3)]) -> Result<Vec<Pair>, BatchError> {
    pairs
        .iter()
        .enumerate()
        .map(|(index, &(a, b))| {
            let e = |error| BatchError {
                index: Some(index),
                error,
            };
            Ok((
                Direction::new("wi", a).map_err(e)?.get(),
                Direction::new("wo", b).map_err(e)?.get(),
            ))
        })
        .collect()
}

/// A query key from the bits of two directions.
pub fn direction_key(wi: Vec3, wo: Vec3) -> u64 {
    let mut k = 0x5bd1_e995u64;
    for x in wi.to_array().into_iter().chain(wo.to_array()) {
        k = mix64(k ^ x.to_bits() as u64);
    }
    k
}
