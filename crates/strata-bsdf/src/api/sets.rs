//! The rows of a table: the parameter sets of a BSDF's shape
//! (`api::param_sets`), and the calls that answer a batch on them.
//!
//! A [`LayeredBsdf`] is built for a stack's *shape*
//! ([`crate::stack::Shape`]); [`ParamSets`] holds the numbers of any stacks
//! of that shape (validated, their lanes derived, with no engine rebuilt),
//! and the `*_batch_sets` calls give each query its set by index. A query
//! answers exactly, bit for bit, what a BSDF built from its set's stack
//! answers, with the same settings, seed and key: [`Materials`] groups its
//! materials by shape into sets (`tests/api/param_sets.rs`).
//!
//! [`Materials`]: super::Materials

use super::bsdf::{directions2, one_each, LayeredBsdf, Sample};
use super::error::{BatchError, QueryError};
use super::param_sets::{ParamSets, Per, Returns, SetsError, SetsMut};
use crate::estimator::coat_lambertian::CoatLambertian;
use crate::estimator::params::SetTable;
use crate::estimator::pdf::PdfEstimate;
use crate::estimator::rough_coat::RoughCoatLambertian;
use crate::estimator::{Albedo, Estimate};
use crate::stack::LayerStack;
use glam::Vec3;
use std::sync::Arc;

impl LayeredBsdf {
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
        let mut sets = self.empty_sets();
        let mut adding = sets.sets_mut();
        for st in &stacks {
            self.push_set(&mut adding, st, returns);
        }
        sets.stacks = stacks.into_iter().map(Arc::new).collect();
        Ok(sets)
    }

    /// Whether this BSDF built `sets` (or one of its shape, settings,
    /// estimator and transport mode, which build the same).
    pub(super) fn built(&self, sets: &ParamSets) -> bool {
        sets.shape == self.shape
            && sets.settings == self.settings
            && sets.estimator == self.estimator
            && sets.adjoint == self.adjoint()
    }

    /// `sets` emptied and made this BSDF's, keeping their memory.
    pub(super) fn reuse_sets(&self, mut sets: ParamSets) -> ParamSets {
        sets.shape.clone_from(&self.shape);
        sets.settings = self.settings;
        sets.estimator = self.estimator;
        sets.adjoint = self.adjoint();
        sets.clear();
        sets
    }

    /// No parameter sets yet, for this BSDF.
    pub(super) fn empty_sets(&self) -> ParamSets {
        ParamSets {
            shape: self.shape.clone(),
            settings: self.settings,
            estimator: self.estimator,
            adjoint: self.adjoint(),
            stacks: Vec::new(),
            table: Arc::new(SetTable::new(self.shape.interfaces.len())),
            coat: Vec::new(),
            route: Vec::new(),
        }
    }

    /// Adds the numbers of `st` (of this BSDF's shape) to `sets` as their
    /// next set, with every choice its stack makes (the walk-free form, the
    /// control variate, the estimator of its evals) decided here.
    pub(super) fn push_set(&self, sets: &mut SetsMut, st: &LayerStack, returns: Returns) {
        if matches!(returns, Returns::Walked) {
            return self.push_set_with(sets, st, None);
        }
        let tabulated = matches!(returns, Returns::Tabulated);
        // A row written in place keeps the shape and IORs: its walk-free
        // form is this BSDF's with the row's numbers.
        match (tabulated, &self.coat) {
            (true, Some(CoatLambertian::Smooth(own))) => {
                let coat = Some(CoatLambertian::Smooth(own.with_numbers_of(st)));
                return self.push_set_with(sets, st, coat);
            }
            (true, Some(CoatLambertian::Rough(_))) => {
                let coat =
                    RoughCoatLambertian::of_row(st).map(|r| CoatLambertian::Rough(Arc::new(r)));
                return self.push_set_with(sets, st, coat);
            }
            _ => {}
        }
        let coat = CoatLambertian::unscattered_with(st, &self.settings, tabulated).and_then(|c| {
            let (with, own) = match returns {
                Returns::Own => (self.coat.as_ref(), true),
                Returns::SharedWith(t) => (t, false),
                Returns::Tabulated | Returns::Walked => return Some(c),
            };
            let same = match (with.and_then(CoatLambertian::rough), c.rough()) {
                (_, None) => true,
                (Some(o), Some(r)) => o.same_return(r),
                (None, Some(_)) => false,
            };
            (own || same).then(|| with.map_or(c.clone(), |o| o.sharing_return(c)))
        });
        self.push_set_with(sets, st, coat);
    }

    /// [`LayeredBsdf::push_set`] once the set's walk-free form, if any, is
    /// known.
    fn push_set_with(&self, sets: &mut SetsMut, st: &LayerStack, coat: Option<CoatLambertian>) {
        let cv = coat
            .as_ref()
            .filter(|_| self.control_variate_for(st))
            .cloned();
        // A set with a walk-free form has a walk-free sampler too; only a
        // rough coat's reads lanes (its first-order term).
        let lobe_pdf = coat.is_none() || !self.walks_can_be_skipped();
        let lanes = lobe_pdf || matches!(coat, Some(CoatLambertian::Rough(_)));
        sets.table.push(st, cv, lobe_pdf, lanes);
        sets.table.set_adjoint_of_last(self.adjoint());
        sets.coat.push(coat);
        sets.route.push(self.estimator.route(st));
    }

    /// Checks that `sets` were built for this BSDF, and that every query's
    /// index names one of them.
    fn check_sets<'a>(
        &self,
        sets: &'a ParamSets,
        set: &'a [u32],
        queries: usize,
    ) -> Result<Per<'a>, BatchError> {
        if !self.built(sets) {
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

    /// [`LayeredBsdf::eval_batch_keyed`] where query `k` has the parameters
    /// of set `set[k]`.
    pub(super) fn eval_batch_sets_keyed(
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

    /// [`LayeredBsdf::sample_batch_keyed`] where query `k` has the
    /// parameters of set `set[k]`.
    pub(super) fn sample_batch_sets_keyed(
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
    pub(super) fn pdf_batch_sets(
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
    pub(super) fn pdf_unbiased_batch_sets(
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
    pub(super) fn albedo_batch_sets_keyed(
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
