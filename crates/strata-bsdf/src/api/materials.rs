//! Heterogeneous batches: the queries of many materials, of any shapes, in
//! one call.
//!
//! A renderer's wavefront holds hits on many materials. [`Materials`] takes
//! them all: materials of one shape share one BSDF (one pair of engines)
//! and become its parameter sets; a call groups its queries by shape, runs
//! each group as one batch of per-query sets, and puts the answers back in
//! query order. A query answers bit for bit what a BSDF of its material
//! alone answers, with the same configuration and key
//! (`tests/api/param_sets.rs`).

use super::bsdf::{one_each, LayeredBsdf, Sample};
use super::error::{BatchError, QueryError};
use super::param_sets::{ParamSets, Returns};
use crate::estimator::pdf::PdfEstimate;
use crate::estimator::{Albedo, Estimate};
use crate::stack::LayerStack;
use glam::Vec3;

/// Materials of any shapes, for batches that mix them.
#[derive(Clone, Debug)]
pub struct Materials {
    /// One BSDF per shape, with its materials as parameter sets.
    groups: Vec<(LayeredBsdf, ParamSets)>,
    /// Per material: its group and its set there.
    of: Vec<(u32, u32)>,
    /// The template's walks per eval (keyed slice calls take them).
    samples: u64,
}

impl Materials {
    /// The materials `stacks` (material `m` is the `m`-th), each answered
    /// with `template`'s configuration: its walk settings, samples, seed,
    /// estimator, engine, transport mode, start side and threads.
    pub fn new(template: &LayeredBsdf, stacks: impl IntoIterator<Item = LayerStack>) -> Self {
        Self::building(template, stacks, false)
    }

    /// [`Materials::new`]; `columns`: the materials are per-query columns of
    /// `template`, which share its rough coat's integral `R̄` or are walked
    /// ([`Returns::SharedWith`]).
    pub(super) fn building(
        template: &LayeredBsdf,
        stacks: impl IntoIterator<Item = LayerStack>,
        columns: bool,
    ) -> Self {
        let returns = match columns {
            true => Returns::SharedWith(template.coat.as_ref()),
            false => Returns::Own,
        };
        let mut members: Vec<(LayeredBsdf, Vec<LayerStack>)> = Vec::new();
        let mut of = Vec::new();
        for st in stacks {
            let shape = st.shape();
            let g = match members.iter().position(|(b, _)| b.shape == shape) {
                Some(g) => g,
                None => {
                    members.push((template.with_stack(st.clone()), Vec::new()));
                    members.len() - 1
                }
            };
            of.push((g as u32, members[g].1.len() as u32));
            members[g].1.push(st);
        }
        let groups = (members.into_iter())
            .map(|(b, stacks)| {
                let sets = b
                    .build_sets(stacks, returns)
                    .expect("a group's stacks share its shape");
                (b, sets)
            })
            .collect();
        Materials {
            groups,
            of,
            samples: template.samples,
        }
    }

    /// Materials `unique[of[m]]` for `m` in `0..of.len()`: repeated ones
    /// share one parameter set.
    pub(super) fn repeated(mut self, of: &[u32]) -> Self {
        self.of = of.iter().map(|&u| self.of[u as usize]).collect();
        self
    }

    /// The template's walks per eval.
    pub(super) fn samples(&self) -> u64 {
        self.samples
    }

    /// Number of materials.
    pub fn len(&self) -> usize {
        self.of.len()
    }

    /// No materials.
    pub fn is_empty(&self) -> bool {
        self.of.is_empty()
    }

    /// Number of distinct shapes (one BSDF each).
    pub fn shapes(&self) -> usize {
        self.groups.len()
    }

    /// Runs `run` once per group that has queries, with the group's BSDF
    /// and sets, the indices of its queries (in query order) and their sets,
    /// and puts its answers back in query order. Errors name the query's
    /// index in the whole batch.
    fn split<R: Clone>(
        &self,
        material: &[u32],
        mut run: impl FnMut(&LayeredBsdf, &ParamSets, &[usize], &[u32]) -> Result<Vec<R>, BatchError>,
    ) -> Result<Vec<R>, BatchError> {
        if let Some((k, &value)) =
            (material.iter().enumerate()).find(|(_, &m)| m as usize >= self.len())
        {
            return Err(BatchError {
                index: Some(k),
                error: QueryError::NoSuchMaterial {
                    value,
                    materials: self.len(),
                },
            });
        }
        let mut out: Vec<Option<R>> = vec![None; material.len()];
        let (mut ids, mut sets) = (Vec::new(), Vec::new());
        for (g, (bsdf, ps)) in self.groups.iter().enumerate() {
            ids.clear();
            sets.clear();
            for (k, &m) in material.iter().enumerate() {
                let (mg, s) = self.of[m as usize];
                if mg as usize == g {
                    ids.push(k);
                    sets.push(s);
                }
            }
            if ids.is_empty() {
                continue;
            }
            let res = run(bsdf, ps, &ids, &sets).map_err(|e| BatchError {
                index: e.index.map(|i| ids[i]),
                ..e
            })?;
            for (&k, r) in ids.iter().zip(res) {
                out[k] = Some(r);
            }
        }
        Ok(out
            .into_iter()
            .map(|r| r.expect("every query ran"))
            .collect())
    }

    /// `f(wi, wo)` of every pair on its material, from `samples` walks with
    /// explicit keys.
    pub(super) fn eval_batch_keyed(
        &self,
        material: &[u32],
        pairs: &[(Vec3, Vec3)],
        samples: u64,
        keys: &[u64],
    ) -> Result<Vec<Estimate>, BatchError> {
        lengths("material", material.len(), pairs.len())?;
        lengths("keys", keys.len(), pairs.len())?;
        self.split(material, |b, ps, ids, set| {
            let (p, k) = (pick(pairs, ids), pick(keys, ids));
            b.eval_batch_sets_keyed(ps, set, &p, samples, &k)
        })
    }

    /// One sample per incident direction on its material, from the stream
    /// `(keys[k], sample_index[k])`.
    pub(super) fn sample_batch_keyed(
        &self,
        material: &[u32],
        wis: &[Vec3],
        keys: &[u64],
        sample_index: &[u64],
    ) -> Result<Vec<Option<Sample>>, BatchError> {
        lengths("material", material.len(), wis.len())?;
        lengths("keys", keys.len(), wis.len())?;
        lengths("sample_index", sample_index.len(), wis.len())?;
        self.split(material, |b, ps, ids, set| {
            let (w, k, i) = (pick(wis, ids), pick(keys, ids), pick(sample_index, ids));
            b.sample_batch_sets_keyed(ps, set, &w, &k, &i)
        })
    }

    /// The approximate pdf of every pair on its material.
    pub(super) fn pdf_batch(
        &self,
        material: &[u32],
        pairs: &[(Vec3, Vec3)],
    ) -> Result<Vec<f32>, BatchError> {
        lengths("material", material.len(), pairs.len())?;
        self.split(material, |b, ps, ids, set| {
            b.pdf_batch_sets(ps, set, &pick(pairs, ids))
        })
    }

    /// The unbiased pdf of every pair on its material, `samples` density
    /// walks each.
    pub(super) fn pdf_unbiased_batch(
        &self,
        material: &[u32],
        pairs: &[(Vec3, Vec3)],
        samples: u64,
    ) -> Result<Vec<PdfEstimate>, BatchError> {
        lengths("material", material.len(), pairs.len())?;
        self.split(material, |b, ps, ids, set| {
            b.pdf_unbiased_batch_sets(ps, set, &pick(pairs, ids), samples)
        })
    }

    /// The directional albedo of every incident direction on its material,
    /// `n` walks each, with explicit keys.
    pub(super) fn albedo_batch_keyed(
        &self,
        material: &[u32],
        wis: &[Vec3],
        n: u64,
        keys: &[u64],
    ) -> Result<Vec<Albedo>, BatchError> {
        lengths("material", material.len(), wis.len())?;
        lengths("keys", keys.len(), wis.len())?;
        self.split(material, |b, ps, ids, set| {
            b.albedo_batch_sets_keyed(ps, set, &pick(wis, ids), n, &pick(keys, ids))
        })
    }
}

/// The entries `ids` of `v`.
fn pick<T: Copy>(v: &[T], ids: &[usize]) -> Vec<T> {
    ids.iter().map(|&k| v[k]).collect()
}

/// One entry of a per-query argument per query.
fn lengths(argument: &'static str, len: usize, queries: usize) -> Result<(), BatchError> {
    one_each(argument, len, queries)
}
