//! Per-query parameters: parameter sets of a BSDF's shape.
//!
//! A renderer evaluates textures at every hit. A [`LayeredBsdf`] is built for
//! a stack's *shape* ([`crate::stack::Shape`]); [`ParamSets`] holds the numbers
//! of any stacks of that shape (built by [`LayeredBsdf::param_sets`]: it
//! validates them and derives their lanes, with no engine rebuilt), and the
//! `*_batch_sets` calls give each query its set by index. A query answers
//! exactly, bit for bit, what a BSDF built from its set's stack answers,
//! with the same settings, seed and key (`tests/api/param_sets.rs`).

use super::{directions2, one_each, BatchError, Estimator, LayeredBsdf, QueryError, Sample};
use crate::estimator::coat_lambertian::CoatLambertian;
use crate::estimator::params::SetTable;
use crate::estimator::pdf::PdfEstimate;
use crate::estimator::scalar::ScalarEngine;
use crate::estimator::wavefront::Sets;
use crate::estimator::{Albedo, Estimate, Settings};
use crate::stack::{LayerStack, Shape};
use glam::Vec3;
use std::fmt;

/// The parameter sets of one [`LayeredBsdf`]'s shape, ready for its batch
/// calls. Building one costs the validation of its stacks and a few
/// hundred bytes of numbers per set: no engine is rebuilt.
#[derive(Clone, Debug)]
pub struct ParamSets {
    /// What they were built for: the BSDF's shape, settings and estimator.
    shape: Shape,
    settings: Settings,
    estimator: Estimator,
    /// The walks follow the adjoint of tilted interfaces (importance mode).
    adjoint: bool,
    stacks: Vec<LayerStack>,
    /// The sets' numbers in the wavefront's one-lane form.
    table: SetTable,
    /// Per set, the scalar engine's form of its numbers (the scalar engine
    /// holds nothing but them).
    scalar: Vec<ScalarEngine<f32>>,
    /// Per set, what is known of it without walks (where the shape is a
    /// coat over a layer over a Lambertian base, and the set's integral is
    /// available: see [`LayeredBsdf::param_sets`]).
    coat: Vec<Option<CoatLambertian>>,
}

impl ParamSets {
    /// Number of sets.
    pub fn len(&self) -> usize {
        self.stacks.len()
    }

    /// No sets.
    pub fn is_empty(&self) -> bool {
        self.stacks.is_empty()
    }

    /// Set `s`'s stack.
    ///
    /// # Panics
    /// If `s` is not below [`ParamSets::len`] (as a slice's index).
    pub fn stack(&self, s: usize) -> &LayerStack {
        &self.stacks[s]
    }
}

/// Parameter sets that do not fit a BSDF.
#[derive(Clone, Debug, PartialEq)]
pub enum SetsError {
    /// Set `set`'s stack has another shape than the BSDF's.
    Shape {
        /// The set's index.
        set: usize,
        /// The first difference.
        why: String,
    },
    /// The sets were built by a BSDF of another shape, settings, estimator
    /// or (on a tilted stack) transport mode.
    Foreign,
}

impl fmt::Display for SetsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SetsError::Shape { set, why } => write!(
                f,
                "parameter set {set} has another shape than the material: {why} \
                 (a BSDF runs stacks of its own shape only)"
            ),
            SetsError::Foreign => write!(
                f,
                "these parameter sets were built by a BSDF of another shape, \
                 settings or estimator: build them with this one's param_sets"
            ),
        }
    }
}

impl std::error::Error for SetsError {}

/// Which parameter sets of a rough coat over a Lambertian base integrate
/// their own `R̄` (an integral, `estimator::coat_return`).
#[derive(Clone, Copy, Debug)]
pub(crate) enum Returns<'a> {
    /// Every set (explicit parameter sets and materials: a handful).
    Own,
    /// None: a set shares the `R̄` of this coat (a template's) where its
    /// coat and layer are the same, and is answered by the walks, without
    /// the control variate, where they are not. For per-query columns, where
    /// an integral per texel would cost far more than the walks; the rule is
    /// the query's own values against the template's, so an answer does not
    /// depend on the batch.
    SharedWith(Option<&'a CoatLambertian>),
}

/// Which parameters each query of a call has: the BSDF's own, or a set
/// each (`set[k]` for query `k`).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Per<'a>(Option<(&'a ParamSets, &'a [u32])>);

impl<'a> Per<'a> {
    /// Every query has the BSDF's own parameters.
    pub const OWN: Per<'static> = Per(None);

    /// Every query has the BSDF's own parameters.
    pub fn is_own(&self) -> bool {
        self.0.is_none()
    }

    /// Query `k`'s set (0 without sets).
    pub fn set(&self, k: usize) -> usize {
        self.0.map_or(0, |(_, s)| s[k] as usize)
    }

    /// The same sets, for queries whose sets are `set`.
    pub fn with_set(&self, set: &'a [u32]) -> Per<'a> {
        Per(self.0.map(|(p, _)| (p, set)))
    }

    /// Query `k` alone.
    pub fn one(&self, k: usize) -> Per<'a> {
        Per(self.0.map(|(p, s)| (p, &s[k..k + 1])))
    }

    /// The wavefront's form.
    pub fn sets(&self) -> Sets<'a> {
        match self.0 {
            None => Sets::Own,
            Some((p, s)) => Sets::Table(&p.table, s),
        }
    }
}

impl LayeredBsdf {
    /// Parameter sets for this BSDF's batch calls: `stacks` must all have
    /// its shape ([`LayerStack::shape`]; error otherwise, naming the set).
    /// They hold this BSDF's settings and estimator choices (the control
    /// variate where it pays, the closed form where the shape has one), so
    /// a BSDF configured otherwise refuses them. Under a rough coat over a
    /// Lambertian base, a set whose coat or layer differs from this BSDF's
    /// integrates its own constant `R̄` (`estimator::coat_return`) the first
    /// time `eval` needs it.
    pub fn param_sets(
        &self,
        stacks: impl IntoIterator<Item = LayerStack>,
    ) -> Result<ParamSets, SetsError> {
        self.build_sets(stacks, Returns::Own)
    }

    /// [`LayeredBsdf::param_sets`], with `returns` saying which sets may
    /// integrate a rough coat's `R̄` of their own.
    pub(super) fn build_sets(
        &self,
        stacks: impl IntoIterator<Item = LayerStack>,
        returns: Returns,
    ) -> Result<ParamSets, SetsError> {
        let shape = self.shape.clone();
        let stacks: Vec<LayerStack> = stacks.into_iter().collect();
        for (set, st) in stacks.iter().enumerate() {
            if let Some(why) = shape.difference(&st.shape()) {
                return Err(SetsError::Shape { set, why });
            }
        }
        let settings = self.settings;
        let mut table = SetTable::new(shape.interfaces.len());
        let mut scalar = Vec::with_capacity(stacks.len());
        let mut coats = Vec::with_capacity(stacks.len());
        for st in &stacks {
            let coat = CoatLambertian::unscattered(st, &settings).and_then(|c| {
                let (with, own) = match returns {
                    Returns::Own => (self.coat.as_ref(), true),
                    Returns::SharedWith(t) => (t, false),
                };
                let same = match (with.and_then(CoatLambertian::rough), c.rough()) {
                    (_, None) => true,
                    (Some(o), Some(r)) => o.same_return(r),
                    (None, Some(_)) => false,
                };
                (own || same).then(|| with.map_or(c.clone(), |o| o.sharing_return(c)))
            });
            let cv = coat.clone().filter(|_| self.control_variate_for(st));
            table.push(st, cv.clone());
            let mut eng = ScalarEngine::new(st, settings).with_cv(cv);
            eng.set_adjoint(self.adjoint());
            scalar.push(eng);
            coats.push(coat);
        }
        table.set_adjoint(self.adjoint());
        Ok(ParamSets {
            shape,
            settings,
            estimator: self.estimator,
            adjoint: self.adjoint(),
            stacks,
            table,
            scalar,
            coat: coats,
        })
    }

    /// Checks that `sets` were built for this BSDF, and that every query's
    /// index names one of them.
    fn check_sets<'a>(
        &self,
        sets: &'a ParamSets,
        set: &'a [u32],
        queries: usize,
    ) -> Result<Per<'a>, BatchError> {
        if sets.shape != self.shape
            || sets.settings != self.settings
            || sets.estimator != self.estimator
            || sets.adjoint != self.adjoint()
        {
            return Err(BatchError::call(QueryError::ForeignSets));
        }
        one_each("set", set.len(), queries)?;
        if let Some((k, &value)) = set
            .iter()
            .enumerate()
            .find(|(_, &s)| s as usize >= sets.len())
        {
            return Err(BatchError {
                index: Some(k),
                error: QueryError::NoSuchSet {
                    value,
                    sets: sets.len(),
                },
            });
        }
        Ok(Per(Some((sets, set))))
    }

    /// Query `k`'s stack.
    pub(super) fn stack_in<'a>(&'a self, per: Per<'a>, k: usize) -> &'a LayerStack {
        match per.0 {
            None => self.stack(),
            Some((p, s)) => &p.stacks[s[k] as usize],
        }
    }

    /// Query `k`'s scalar engine.
    pub(super) fn scalar_in<'a>(&'a self, per: Per<'a>, k: usize) -> &'a ScalarEngine<f32> {
        match per.0 {
            None => &self.scalar,
            Some((p, s)) => &p.scalar[s[k] as usize],
        }
    }

    /// What answers query `k`'s eval without walks, if anything
    /// ([`LayeredBsdf::eval_without_walks`], per set).
    pub(super) fn without_walks_in<'a>(
        &'a self,
        per: Per<'a>,
        k: usize,
    ) -> Option<&'a CoatLambertian> {
        match per.0 {
            None => self.without_walks(),
            // The estimator and the layer's class are the shape's: the same
            // for every set; whether the set has a walk-free form is its own.
            Some((p, s)) => self
                .walks_can_be_skipped()
                .then_some(p.coat[s[k] as usize].as_ref())
                .flatten(),
        }
    }

    /// [`LayeredBsdf::eval_batch`] where query `k` has the parameters of
    /// set `set[k]`.
    pub fn eval_batch_sets(
        &self,
        sets: &ParamSets,
        set: &[u32],
        pairs: &[(Vec3, Vec3)],
    ) -> Result<Vec<Estimate>, BatchError> {
        self.eval_batch_sets_keyed(sets, set, pairs, self.samples, &super::pair_keys(pairs))
    }

    /// [`LayeredBsdf::eval_batch_keyed`] where query `k` has the parameters
    /// of set `set[k]`.
    pub fn eval_batch_sets_keyed(
        &self,
        sets: &ParamSets,
        set: &[u32],
        pairs: &[(Vec3, Vec3)],
        samples: u64,
        keys: &[u64],
    ) -> Result<Vec<Estimate>, BatchError> {
        let per = self.check_sets(sets, set, pairs.len())?;
        self.eval_checked(per, pairs, samples, keys)
    }

    /// [`LayeredBsdf::sample_batch`] where query `k` has the parameters of
    /// set `set[k]`.
    pub fn sample_batch_sets(
        &self,
        sets: &ParamSets,
        set: &[u32],
        wis: &[Vec3],
        sample_index: &[u64],
    ) -> Result<Vec<Option<Sample>>, BatchError> {
        self.sample_batch_sets_keyed(sets, set, wis, &super::dir_keys(wis), sample_index)
    }

    /// [`LayeredBsdf::sample_batch_keyed`] where query `k` has the
    /// parameters of set `set[k]`.
    pub fn sample_batch_sets_keyed(
        &self,
        sets: &ParamSets,
        set: &[u32],
        wis: &[Vec3],
        keys: &[u64],
        sample_index: &[u64],
    ) -> Result<Vec<Option<Sample>>, BatchError> {
        let per = self.check_sets(sets, set, wis.len())?;
        self.sample_checked(per, wis, keys, sample_index)
    }

    /// [`LayeredBsdf::pdf_batch`] where query `k` has the parameters of set
    /// `set[k]`.
    pub fn pdf_batch_sets(
        &self,
        sets: &ParamSets,
        set: &[u32],
        pairs: &[(Vec3, Vec3)],
    ) -> Result<Vec<f32>, BatchError> {
        let per = self.check_sets(sets, set, pairs.len())?;
        Ok(self.pdf_validated(per, &directions2(pairs)?))
    }

    /// [`LayeredBsdf::pdf_unbiased_batch`] where query `k` has the
    /// parameters of set `set[k]`.
    pub fn pdf_unbiased_batch_sets(
        &self,
        sets: &ParamSets,
        set: &[u32],
        pairs: &[(Vec3, Vec3)],
        samples: u64,
    ) -> Result<Vec<PdfEstimate>, BatchError> {
        let per = self.check_sets(sets, set, pairs.len())?;
        self.pdf_unbiased_checked(per, pairs, samples)
    }

    /// [`LayeredBsdf::albedo_batch_keyed`] where query `k` has the
    /// parameters of set `set[k]`.
    pub fn albedo_batch_sets_keyed(
        &self,
        sets: &ParamSets,
        set: &[u32],
        wis: &[Vec3],
        n: u64,
        keys: &[u64],
    ) -> Result<Vec<Albedo>, BatchError> {
        let per = self.check_sets(sets, set, wis.len())?;
        self.albedo_checked(per, wis, n, keys)
    }
}
