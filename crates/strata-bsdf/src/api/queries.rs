//! One batch of queries, and the verbs every table of materials answers.
//!
//! A call takes a [`Queries`]: the incident directions, the outgoing ones
//! (for eval and pdf), and optionally each query's key, sample index, row
//! and the walks per query. It hands each query's answer to the caller's
//! closure in query order, once every input is known to be valid, so
//! nothing is handed out on an error. [`Bsdf`] is implemented by a
//! [`LayeredBsdf`](super::LayeredBsdf) (one row), by
//! [`Materials`](super::Materials) (a row per material) and by
//! [`PerQuery`](super::PerQuery) (a row per query): the C ABI and the
//! Python module call it through `&dyn Bsdf`.
//!
//! Keys: with `keys = None` a query is keyed by its directions' bits, as
//! the single-query methods key it, so the same pair always gives the same
//! estimate. With `Some(keys)` the renderer's sampler drives the streams:
//! query `k` draws from `(seed, keys[k])`. A sample draws from `(seed, key,
//! index)`: `indices[k]`, or by default `k` for an unkeyed query (as line
//! `k` of `strata sample` does) and 0 for a keyed one. A pdf takes no key:
//! it is a function of its two directions, so that the number a sample
//! carries is the one a later pdf gives.

use super::bsdf::Sample;
use super::error::{BatchError, QueryError};
use super::vectors::Vectors;
use crate::estimator::pdf::PdfEstimate;
use crate::estimator::{Albedo, Estimate};

/// The queries of one batch call.
#[derive(Clone, Copy, Debug)]
pub struct Queries<'a> {
    /// The incident direction of each query.
    pub wi: Vectors<'a>,
    /// The outgoing direction of each query, for eval and pdf.
    pub wo: Option<Vectors<'a>>,
    /// Each query's random stream (`None`: keyed by its directions).
    pub keys: Option<&'a [u64]>,
    /// Each sample's index in its stream (`None`: `k` unkeyed, 0 keyed).
    pub indices: Option<&'a [u64]>,
    /// Each query's row of the table that answers it (`None`: query `k` on
    /// row `k` of a table with a row per query, or row 0 of a BSDF).
    pub rows: Option<&'a [u32]>,
    /// Walks per query of eval, the unbiased pdf and albedo (`None`: the
    /// configuration's `samples`).
    pub walks: Option<u64>,
}

impl<'a> Queries<'a> {
    /// Queries on incident directions alone (sample, albedo).
    pub fn directions(wi: impl Into<Vectors<'a>>) -> Self {
        Queries {
            wi: wi.into(),
            wo: None,
            keys: None,
            indices: None,
            rows: None,
            walks: None,
        }
    }

    /// Queries on pairs of directions (eval, pdf).
    pub fn pairs(wi: impl Into<Vectors<'a>>, wo: impl Into<Vectors<'a>>) -> Self {
        Queries {
            wo: Some(wo.into()),
            ..Self::directions(wi)
        }
    }

    /// With each query's key.
    #[must_use]
    pub fn keys(self, keys: &'a [u64]) -> Self {
        Queries {
            keys: Some(keys),
            ..self
        }
    }

    /// With each sample's index in its stream.
    #[must_use]
    pub fn indices(self, indices: &'a [u64]) -> Self {
        Queries {
            indices: Some(indices),
            ..self
        }
    }

    /// With each query's row.
    #[must_use]
    pub fn rows(self, rows: &'a [u32]) -> Self {
        Queries {
            rows: Some(rows),
            ..self
        }
    }

    /// With `walks` walks per query.
    #[must_use]
    pub fn walks(self, walks: u64) -> Self {
        Queries {
            walks: Some(walks),
            ..self
        }
    }

    /// The number of queries.
    pub fn len(&self) -> usize {
        self.wi.len()
    }

    /// No queries.
    pub fn is_empty(&self) -> bool {
        self.wi.is_empty()
    }

    /// The outgoing directions, or none (which the length checks name).
    pub(super) fn wo_or_none(&self) -> Vectors<'a> {
        self.wo.unwrap_or(Vectors::Aos(&[]))
    }

    /// Checks that the rows name rows `0..rows` of a table of `rows`
    /// (`None` is every query on its own row).
    pub(super) fn check_rows(&self, rows: usize) -> Result<(), BatchError> {
        let Some(r) = self.rows else {
            return Ok(());
        };
        super::bsdf::one_each("rows", r.len(), self.len())?;
        match r.iter().position(|&x| x as usize >= rows) {
            Some(k) => Err(BatchError {
                index: Some(k),
                error: QueryError::NoSuchMaterial {
                    value: r[k],
                    materials: rows,
                },
            }),
            None => Ok(()),
        }
    }
}

/// The batch verbs: what a table of materials answers for a [`Queries`].
///
/// Each hands query `k`'s answer to `out(k, answer)`, in query order. Each
/// returns an error naming the argument (and the query) if an input
/// is invalid, before it hands out any answer; the calls that run walks to
/// an estimate return the number of walks the limit of events ended,
/// summed over the batch.
pub trait Bsdf {
    /// `f(wi, wo)` (without the cosine) of every pair, with its standard
    /// error.
    fn eval_into(
        &self,
        q: &Queries,
        out: &mut (dyn FnMut(usize, &Estimate) + Send),
    ) -> Result<u64, BatchError>;

    /// [`Bsdf::eval_into`] and [`Bsdf::pdf_into`] of the same pairs in one
    /// call (a renderer's light sample needs both): the evals first, then
    /// the pdfs, the numbers of the two calls.
    fn eval_pdf_into(
        &self,
        q: &Queries,
        evals: &mut (dyn FnMut(usize, &Estimate) + Send),
        pdfs: &mut (dyn FnMut(usize, f32) + Send),
    ) -> Result<u64, BatchError>;

    /// One sampled outgoing direction per query with its weight
    /// `f |cos θo| / p` and the pdf [`Bsdf::pdf_into`] gives for it; `None`
    /// if the walk was absorbed.
    fn sample_into(
        &self,
        q: &Queries,
        out: &mut (dyn FnMut(usize, Option<&Sample>) + Send),
    ) -> Result<(), BatchError>;

    /// The pdf of every pair for sampling's MIS: deterministic, the number
    /// a sample carries for its direction.
    fn pdf_into(
        &self,
        q: &Queries,
        out: &mut (dyn FnMut(usize, f32) + Send),
    ) -> Result<(), BatchError>;

    /// The density of sample's directions at every pair, estimated without
    /// bias by density walks, with its standard error. For references.
    fn pdf_unbiased_into(
        &self,
        q: &Queries,
        out: &mut (dyn FnMut(usize, &PdfEstimate) + Send),
    ) -> Result<u64, BatchError>;

    /// The reflected and transmitted fractions of light from every
    /// incident direction.
    fn albedo_into(
        &self,
        q: &Queries,
        out: &mut (dyn FnMut(usize, &Albedo) + Send),
    ) -> Result<u64, BatchError>;
}
