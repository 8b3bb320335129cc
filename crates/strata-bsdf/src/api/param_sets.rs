//! Parameter sets of a BSDF's shape ([`ParamSets`]), and which one each
//! query of a call has ([`Per`]).

use super::plan::EvalRoute;
use super::strategy::Estimator;
use crate::estimator::coat_lambertian::CoatLambertian;
use crate::estimator::params::SetTable;
use crate::estimator::wavefront::Sets;
use crate::estimator::Settings;
use crate::stack::{LayerStack, Shape};
use std::fmt;
use std::sync::Arc;

/// The parameter sets of one [`LayeredBsdf`](crate::LayeredBsdf)'s shape, ready for its batch
/// calls. Building one costs the validation of its stacks and a few
/// hundred bytes of numbers per set: no engine is rebuilt.
#[derive(Clone, Debug)]
pub struct ParamSets {
    /// What they were built for: the BSDF's shape, settings and estimator.
    pub(super) shape: Shape,
    pub(super) settings: Settings,
    pub(super) estimator: Estimator,
    /// The walks follow the adjoint of tilted interfaces (importance mode).
    pub(super) adjoint: bool,
    /// Per set, its stack; none for the rows of per-query columns
    /// ([`crate::PerQuery`]), which cannot change what the calls read of a
    /// stack beyond its numbers (its IORs, its sidedness): theirs is the
    /// BSDF's.
    pub(super) stacks: Vec<Arc<LayerStack>>,
    /// The sets' numbers in the wavefront's one-lane form (shared with the
    /// calls that run them).
    pub(super) table: Arc<SetTable>,
    /// Per set, what is known of it without walks (where the shape is a
    /// coat over a layer over a Lambertian base, and the set's integral is
    /// available: see `LayeredBsdf::build_sets`).
    pub(super) coat: Vec<Option<CoatLambertian>>,
    /// Per set, how its evals pick their estimator.
    pub(super) route: Vec<EvalRoute>,
}

/// The per-set parts of [`ParamSets`], borrowed to add sets.
pub(super) struct SetsMut<'a> {
    pub(super) table: &'a mut SetTable,
    pub(super) coat: &'a mut Vec<Option<CoatLambertian>>,
    pub(super) route: &'a mut Vec<EvalRoute>,
}

impl ParamSets {
    /// Number of sets.
    pub(super) fn len(&self) -> usize {
        self.coat.len()
    }

    /// Empties it, keeping its memory.
    pub(super) fn clear(&mut self) {
        self.stacks.clear();
        let n = self.shape.interfaces.len();
        self.table_mut().clear(n);
        self.coat.clear();
        self.route.clear();
    }

    /// Reserves room for `n` more sets, or says how many bytes (about) the
    /// allocator refused.
    pub(super) fn try_reserve(&mut self, n: usize) -> Result<(), usize> {
        let bytes = n.saturating_mul(std::mem::size_of::<Option<CoatLambertian>>() + 64);
        self.coat.try_reserve(n).map_err(|_| bytes)?;
        self.route.try_reserve(n).map_err(|_| bytes)?;
        self.table_mut().try_reserve(n).map_err(|_| bytes)
    }

    /// Its per-set parts, to add sets to (one check that the table is
    /// not shared, for any number of sets).
    pub(super) fn sets_mut(&mut self) -> SetsMut<'_> {
        self.table_mut();
        SetsMut {
            table: Arc::get_mut(&mut self.table).expect("unique"),
            coat: &mut self.coat,
            route: &mut self.route,
        }
    }

    /// The table, to change: a call that ran on it may still hold it, and
    /// then it is replaced by an empty one rather than copied.
    pub(super) fn table_mut(&mut self) -> &mut SetTable {
        if Arc::get_mut(&mut self.table).is_none() {
            self.table = Arc::new(SetTable::new(self.shape.interfaces.len()));
        }
        Arc::get_mut(&mut self.table).expect("unique")
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
    /// Every set, from the coat's table (`coat_return::SmoothReturn`,
    /// `RoughReturn`: within 1e-7 and 1e-6 of the quadrature): the rows of
    /// per-query columns written in place, where a quadrature per row
    /// would cost far more than its queries.
    Tabulated,
    /// None: rows written in place whose coat's IOR is their own (a
    /// dispersive IOR at each query's wavelength), where a table per IOR
    /// would cost far more than the walks that answer them instead.
    Walked,
}

/// Which parameters each query of a call has: the BSDF's own, or a set
/// each (`set[k]` for query `k`).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Per<'a>(pub(super) Option<(&'a ParamSets, &'a [u32])>);

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
