//! What can be wrong with a query, and where in a batch.

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
    /// A query's parameter set index names no set.
    NoSuchSet {
        /// The index given.
        value: u32,
        /// The number of sets.
        sets: usize,
    },
    /// Parameter sets built by a BSDF of another shape, settings or estimator.
    ForeignSets,
    /// A query's material index names no material.
    NoSuchMaterial {
        /// The index given.
        value: u32,
        /// The number of materials.
        materials: usize,
    },
    /// Rows given to a table whose query `k` is on row `k` (per-query
    /// columns).
    RowsNotTaken,
    /// The call's working memory could not be allocated (the allocator
    /// refused: the process is out of memory or address space).
    OutOfMemory {
        /// The call (`"eval"`, `"sample"`, `"pdf"`, `"pdf_unbiased"`,
        /// `"albedo"`, `"per_query"`).
        call: &'static str,
        /// The bytes asked for.
        bytes: usize,
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
            QueryError::NoSuchSet { value, sets } => write!(
                f,
                "set = {value}: there are {sets} parameter sets (0 to {})",
                sets.saturating_sub(1)
            ),
            QueryError::ForeignSets => write!(f, "{}", super::param_sets::SetsError::Foreign),
            QueryError::NoSuchMaterial { value, materials } => write!(
                f,
                "material = {value}: there are {materials} materials (0 to {})",
                materials.saturating_sub(1)
            ),
            QueryError::RowsNotTaken => write!(
                f,
                "rows: a table of per-query columns answers query k on its row k; give no rows"
            ),
            QueryError::OutOfMemory { call, bytes } => write!(
                f,
                "{call}: out of memory: cannot allocate {bytes} bytes of per-query working memory"
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
    pub(crate) fn call(error: QueryError) -> Self {
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

pub use crate::estimator::MAX_WALKS;

/// Checks a walk count passed as `argument` (`"samples"`, `"n"`): from 1 to
/// [`MAX_WALKS`]. The one check behind every call that takes a walk count,
/// for bindings to apply (and word) the same way before they build a BSDF.
///
/// ```
/// use strata_bsdf::{check_walks, MAX_WALKS};
/// assert!(check_walks("samples", 1).is_ok() && check_walks("samples", MAX_WALKS).is_ok());
/// let e = check_walks("samples", 0).unwrap_err();
/// assert_eq!(e.to_string(), "samples = 0: at least one walk is needed");
/// ```
pub fn check_walks(argument: &'static str, n: u64) -> Result<(), QueryError> {
    if n == 0 {
        Err(QueryError::NoSamples { argument })
    } else if n > MAX_WALKS {
        Err(QueryError::TooManySamples { argument, value: n })
    } else {
        Ok(())
    }
}

/// The largest thread pool [`LayeredBsdf::threads`](crate::LayeredBsdf::threads) builds: more threads
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
