//! The batch calls: [`Bsdf`] for a BSDF (one row), for [`Materials`] (a
//! row per material) and for [`PerQuery`] (a row per query).
//!
//! Every call checks its whole batch before it hands out an answer. The
//! calls that run walks to an estimate return the number of walks the
//! limit of events ended ([`LayeredBsdf::max_events`]), summed over the
//! batch (an albedo's reflected and transmitted fractions share their
//! walks, counted once).

use super::bsdf::{direction_at, direction_key, one_each, pdf_key, LayeredBsdf, Pair, Sample};
use super::columns::PerQuery;
use super::error::{check_walks, BatchError, Direction, QueryError};
use super::materials::Materials;
use super::param_sets::Per;
use super::queries::{Bsdf, Queries};
use super::vectors::{check_pairs, Vectors};
use crate::estimator::pdf::{PdfEstimate, PdfKind};
use crate::estimator::wavefront::{with_kept, Sets, PDF_CHUNK};
use crate::estimator::{Albedo, Estimate};
use glam::Vec3;
use std::borrow::Cow;

/// A BSDF is a table of one row: its own material.
impl Bsdf for LayeredBsdf {
    fn eval_into(
        &self,
        q: &Queries,
        out: &mut (dyn FnMut(usize, &Estimate) + Send),
    ) -> Result<u64, BatchError> {
        let wo = q.wo_or_none();
        self.pairs_count(&q.wi, &wo)?;
        q.check_rows(1)?;
        let walks = self.walks_of(q)?;
        self.evals(Per::OWN, &q.wi, &wo, q.keys, walks, out)
    }

    fn eval_pdf_into(
        &self,
        q: &Queries,
        evals: &mut (dyn FnMut(usize, &Estimate) + Send),
        pdfs: &mut (dyn FnMut(usize, f32) + Send),
    ) -> Result<u64, BatchError> {
        let wo = q.wo_or_none();
        self.pairs_count(&q.wi, &wo)?;
        q.check_rows(1)?;
        let walks = self.walks_of(q)?;
        self.eval_pdfs(Per::OWN, (&q.wi, &wo, q.keys, walks), evals, pdfs)
    }

    fn sample_into(
        &self,
        q: &Queries,
        out: &mut (dyn FnMut(usize, Option<&Sample>) + Send),
    ) -> Result<(), BatchError> {
        q.wi.count("wi")?;
        q.check_rows(1)?;
        self.samples_of(Per::OWN, &q.wi, q.keys, q.indices, 0, out)
    }

    fn pdf_into(
        &self,
        q: &Queries,
        out: &mut (dyn FnMut(usize, f32) + Send),
    ) -> Result<(), BatchError> {
        let wo = q.wo_or_none();
        let n = self.pairs_count(&q.wi, &wo)?;
        q.check_rows(1)?;
        check_pairs(&q.wi, &wo)?;
        self.pdfs(Per::OWN, n, |k| pair_at(&q.wi, &wo, k), out);
        Ok(())
    }

    fn pdf_unbiased_into(
        &self,
        q: &Queries,
        out: &mut (dyn FnMut(usize, &PdfEstimate) + Send),
    ) -> Result<u64, BatchError> {
        let wo = q.wo_or_none();
        self.pairs_count(&q.wi, &wo)?;
        q.check_rows(1)?;
        let walks = self.walks_of(q)?;
        check_pairs(&q.wi, &wo)?;
        Ok(self.pdfs_unbiased(Per::OWN, &q.wi, &wo, walks, out))
    }

    fn albedo_into(
        &self,
        q: &Queries,
        out: &mut (dyn FnMut(usize, &Albedo) + Send),
    ) -> Result<u64, BatchError> {
        let m = q.wi.count("wi")?;
        q.check_rows(1)?;
        let walks = self.walks_of(q)?;
        for k in 0..m {
            direction_at("wi", k, q.wi.get(k))?;
        }
        if let Some(k) = q.keys {
            one_each("keys", k.len(), m)?;
        }
        Ok(self.albedos(Per::OWN, &q.wi, walks, q.keys, out))
    }
}

impl LayeredBsdf {
    /// The walks per query of a call, checked: the call's, or the
    /// configuration's `samples`.
    pub(super) fn walks_of(&self, q: &Queries) -> Result<u64, BatchError> {
        walks_of(q, self.samples)
    }

    /// The evals and pdfs of checked queries, from one check of the pairs:
    /// the evals to `evals`, then the pdfs to `pdfs`.
    fn eval_pdfs(
        &self,
        per: Per,
        (wi, wo, keys, walks): (&Vectors, &Vectors, Option<&[u64]>, u64),
        evals: impl FnMut(usize, &Estimate) + Send,
        pdfs: impl FnMut(usize, f32),
    ) -> Result<u64, BatchError> {
        let then = |q: &[(Pair, u64)]| self.pdfs(per, q.len(), |k| q[k].0, pdfs);
        self.evals_then(per, (wi, wo, keys, walks), evals, then)
    }

    /// The approximate pdf of the `n` checked pairs (`pair(k)`,
    /// normalized), handed to `put` in query order.
    fn pdfs(
        &self,
        per: Per,
        n: usize,
        pair: impl Fn(usize) -> Pair,
        mut put: impl FnMut(usize, f32),
    ) {
        if self.pdf_by_query_in(per, n) {
            for k in 0..n {
                let (a, b) = pair(k);
                put(k, self.pdf_one(per, k, a, b));
            }
            return;
        }
        if per.is_own() && (self.serial() || n <= PDF_CHUNK) {
            // On this thread, from the buffers it keeps: allocates nothing
            // once warm (the numbers of `pdf_validated`, lane for lane).
            let keyed = |k: usize| {
                let (a, b) = pair(k);
                ((a, b), pdf_key(a, b))
            };
            let (walks, kind) = (self.pdf_walks, PdfKind::Approximate);
            let put = |k: usize, e: PdfEstimate| put(k, e.value as f32);
            let own = Sets::Own;
            self.wave
                .pdf_each(own, n, keyed, walks, self.seed, kind, put);
            return;
        }
        let pairs: Vec<Pair> = (0..n).map(pair).collect();
        for (k, p) in self.pdf_validated(per, &pairs).into_iter().enumerate() {
            put(k, p);
        }
    }

    /// The unbiased pdfs of checked pairs, handed to `put`; the walks the
    /// limit ended.
    fn pdfs_unbiased(
        &self,
        per: Per,
        wi: &Vectors,
        wo: &Vectors,
        walks: u64,
        mut put: impl FnMut(usize, &PdfEstimate),
    ) -> u64 {
        let pairs: Vec<Pair> = (0..wi.len()).map(|k| pair_at(wi, wo, k)).collect();
        let est = self.pdf_unbiased_validated(per, &pairs, walks);
        est.iter().enumerate().for_each(|(k, e)| put(k, e));
        est.iter().map(|e| e.truncated).sum()
    }

    /// The albedos of checked directions, handed to `put`; the walks the
    /// limit ended (the reflected and transmitted fractions come from the
    /// same walks: counted once).
    fn albedos(
        &self,
        per: Per,
        wi: &Vectors,
        walks: u64,
        keys: Option<&[u64]>,
        mut put: impl FnMut(usize, &Albedo) + Send,
    ) -> u64 {
        let query = |k: usize| {
            let key = keys.map_or_else(|| direction_key(wi.get(k), wi.get(k)), |x| x[k]);
            (dir_at(wi, k), key)
        };
        let mut cut = 0;
        self.albedo_each(per, wi.len(), walks, query, |k, a| {
            cut += a.reflected.truncated;
            put(k, &a);
        });
        cut
    }

    /// The number of `(wi, wo)` queries, checking that the two agree.
    fn pairs_count(&self, wi: &Vectors, wo: &Vectors) -> Result<usize, BatchError> {
        let n = wi.count("wi")?;
        one_each("wo", wo.count("wo")?, n)?;
        Ok(n)
    }

    /// The eval of every pair, handed to `out` in query order once every
    /// input is known to be valid; returns the walks the limit ended. Calls
    /// that run query by query (the scalar engine, a closed form) allocate
    /// nothing, nor do serial wavefront batches on a warm thread; parallel
    /// ones allocate in rayon.
    fn evals(
        &self,
        per: Per,
        wi: &Vectors,
        wo: &Vectors,
        keys: Option<&[u64]>,
        walks: u64,
        out: impl FnMut(usize, &Estimate) + Send,
    ) -> Result<u64, BatchError> {
        self.evals_then(per, (wi, wo, keys, walks), out, |_| ())
    }

    /// [`LayeredBsdf::evals`], then `then` of the checked queries (each
    /// pair normalized, and its key); `walks` is checked.
    fn evals_then(
        &self,
        per: Per,
        (wi, wo, keys, walks): (&Vectors, &Vectors, Option<&[u64]>, u64),
        mut out: impl FnMut(usize, &Estimate) + Send,
        then: impl FnOnce(&[(Pair, u64)]),
    ) -> Result<u64, BatchError> {
        let n = wi.len();
        // Each query's directions, normalized and keyed once (the engines
        // read a query several times), in a buffer the thread keeps.
        with_kept(&QUERIES, |queries| {
            queries.clear();
            for k in 0..n {
                let (a, b) = (wi.get(k), wo.get(k));
                let pair = (direction_at("wi", k, a)?, direction_at("wo", k, b)?);
                queries.push((pair, direction_key(a, b)));
            }
            if let Some(keys) = keys {
                one_each("keys", keys.len(), n)?;
                for (q, &key) in queries.iter_mut().zip(keys) {
                    q.1 = key;
                }
            }
            let queries = &queries[..];
            let mut cut = 0;
            self.eval_each(
                per,
                n,
                walks,
                |k| queries[k],
                |k, e| {
                    cut += e.truncated;
                    out(k, &e)
                },
            );
            then(queries);
            Ok(cut)
        })
    }

    /// The sample of every query, handed to `out` in query order: query `k`
    /// draws sample index `indices[k]`, or by default `first + k` of its
    /// direction's key unkeyed, or 0 of its key. Allocates nothing on the
    /// scalar engine, nor serially on a warm thread.
    fn samples_of(
        &self,
        per: Per,
        wi: &Vectors,
        keys: Option<&[u64]>,
        indices: Option<&[u64]>,
        first: usize,
        mut out: impl FnMut(usize, Option<&Sample>),
    ) -> Result<(), BatchError> {
        let n = wi.len();
        for k in 0..n {
            direction_at("wi", k, wi.get(k))?;
        }
        if let Some(k) = keys {
            one_each("keys", k.len(), n)?;
        }
        if let Some(i) = indices {
            one_each("indices", i.len(), n)?;
        }
        let stream = |k: usize| {
            let (key, index) = match keys {
                Some(x) => (x[k], 0),
                None => (direction_key(wi.get(k), wi.get(k)), (first + k) as u64),
            };
            (key, indices.map_or(index, |i| i[k]))
        };
        let query = |k: usize| {
            let (key, index) = stream(k);
            (dir_at(wi, k), key, index)
        };
        self.sample_each(per, n, query, |k, s| out(k, s.as_ref()));
        Ok(())
    }
}

/// The batch calls of [`Materials`]: query `k` on material `rows[k]` (or
/// material `k` without rows), keyed and indexed as a [`LayeredBsdf`] keys
/// its queries, so that a query answers what the BSDF of its material alone
/// answers. Nothing is handed out before every query is known to be valid.
impl Bsdf for Materials {
    fn eval_into(
        &self,
        q: &Queries,
        out: &mut (dyn FnMut(usize, &Estimate) + Send),
    ) -> Result<u64, BatchError> {
        let pairs = pairs_of(&q.wi, &q.wo_or_none())?;
        let rows = self.rows_of(q)?;
        let keys = keys_or(q.keys, &pairs, |p| direction_key(p.0, p.1));
        let walks = walks_of(q, self.samples())?;
        let est = self.eval_batch_keyed(&rows, &pairs, walks, &keys)?;
        est.iter().enumerate().for_each(|(k, e)| out(k, e));
        Ok(est.iter().map(|e| e.truncated).sum())
    }

    fn eval_pdf_into(
        &self,
        q: &Queries,
        evals: &mut (dyn FnMut(usize, &Estimate) + Send),
        pdfs: &mut (dyn FnMut(usize, f32) + Send),
    ) -> Result<u64, BatchError> {
        // Every pair is checked by the first call, so the second cannot
        // fail after the first handed out its answers.
        Vectors::check_pairs(&q.wi, &q.wo_or_none(), q.keys)?;
        self.rows_of(q)?;
        let cut = self.eval_into(q, evals)?;
        self.pdf_into(q, pdfs)?;
        Ok(cut)
    }

    fn sample_into(
        &self,
        q: &Queries,
        out: &mut (dyn FnMut(usize, Option<&Sample>) + Send),
    ) -> Result<(), BatchError> {
        let wis = dirs_of(&q.wi)?;
        let rows = self.rows_of(q)?;
        let n = wis.len();
        let keys = keys_or(q.keys, &wis, |&w| direction_key(w, w));
        let own: Vec<u64>;
        let indices = match (q.indices, q.keys) {
            (Some(i), _) => i,
            (None, Some(_)) => {
                own = vec![0; n];
                &own
            }
            (None, None) => {
                own = (0..n as u64).collect();
                &own
            }
        };
        let s = self.sample_batch_keyed(&rows, &wis, &keys, indices)?;
        s.iter().enumerate().for_each(|(k, s)| out(k, s.as_ref()));
        Ok(())
    }

    fn pdf_into(
        &self,
        q: &Queries,
        out: &mut (dyn FnMut(usize, f32) + Send),
    ) -> Result<(), BatchError> {
        let pairs = pairs_of(&q.wi, &q.wo_or_none())?;
        let rows = self.rows_of(q)?;
        let pdf = self.pdf_batch(&rows, &pairs)?;
        pdf.into_iter().enumerate().for_each(|(k, p)| out(k, p));
        Ok(())
    }

    fn pdf_unbiased_into(
        &self,
        q: &Queries,
        out: &mut (dyn FnMut(usize, &PdfEstimate) + Send),
    ) -> Result<u64, BatchError> {
        let pairs = pairs_of(&q.wi, &q.wo_or_none())?;
        let rows = self.rows_of(q)?;
        let walks = walks_of(q, self.samples())?;
        let est = self.pdf_unbiased_batch(&rows, &pairs, walks)?;
        est.iter().enumerate().for_each(|(k, e)| out(k, e));
        Ok(est.iter().map(|e| e.truncated).sum())
    }

    fn albedo_into(
        &self,
        q: &Queries,
        out: &mut (dyn FnMut(usize, &Albedo) + Send),
    ) -> Result<u64, BatchError> {
        let wis = dirs_of(&q.wi)?;
        let rows = self.rows_of(q)?;
        let keys = keys_or(q.keys, &wis, |&w| direction_key(w, w));
        let walks = walks_of(q, self.samples())?;
        let albedos = self.albedo_batch_keyed(&rows, &wis, walks, &keys)?;
        albedos.iter().enumerate().for_each(|(k, a)| out(k, a));
        Ok(albedos.iter().map(|a| a.reflected.truncated).sum())
    }
}

impl Materials {
    /// Each query's material: its row, or material `k` for query `k`
    /// without rows.
    fn rows_of<'q>(&self, q: &Queries<'q>) -> Result<Cow<'q, [u32]>, BatchError> {
        match q.rows {
            Some(r) => {
                one_each("rows", r.len(), q.len())?;
                Ok(Cow::Borrowed(r))
            }
            // Without rows, a batch has a query per material.
            None if q.len() != self.len() => Err(BatchError::call(QueryError::LengthMismatch {
                argument: "rows",
                len: 0,
                queries: q.len(),
            })),
            None => Ok(Cow::Owned(Materials::identity(q.len()))),
        }
    }
}

/// The walks per query of a call, checked: the call's (named `walks` in an
/// error), or the configuration's `samples`.
fn walks_of(q: &Queries, samples: u64) -> Result<u64, BatchError> {
    let (argument, walks) = match q.walks {
        Some(w) => ("walks", w),
        None => ("samples", samples),
    };
    check_walks(argument, walks).map_err(BatchError::call)?;
    Ok(walks)
}

/// The caller's keys, or each query's key from its directions.
fn keys_or<'k, T>(
    keys: Option<&'k [u64]>,
    queries: &[T],
    key: impl Fn(&T) -> u64,
) -> Cow<'k, [u64]> {
    match keys {
        Some(k) => Cow::Borrowed(k),
        None => Cow::Owned(queries.iter().map(key).collect()),
    }
}

/// The batch calls of [`PerQuery`]: [`Materials`]' calls on the materials
/// of [`Materials::per_query`] (query `k` on row `k`; a call takes no
/// rows), run a chunk at a time: the same numbers, bit for bit. Every
/// argument is checked before the first chunk runs, so nothing is handed
/// out on an error; a chunk's buffers are allocated fallibly when the call
/// starts ([`QueryError::OutOfMemory`](super::QueryError::OutOfMemory)).
impl Bsdf for PerQuery<'_> {
    fn eval_into(
        &self,
        q: &Queries,
        out: &mut (dyn FnMut(usize, &Estimate) + Send),
    ) -> Result<u64, BatchError> {
        let (wi, wo, keys) = (q.wi, q.wo_or_none(), q.keys);
        self.pairs_checked(q, true)?;
        let walks = self.template.walks_of(q)?;
        let mut cut = 0;
        let in_place = self.in_place_chunks("eval", false, |per, r| {
            let (a, b) = (wi.range(r.clone()), wo.range(r.clone()));
            let keys = keys.map(|x| &x[r.clone()]);
            let put = |k: usize, e: &Estimate| out(r.start + k, e);
            cut += self.rows_bsdf().evals(per, &a, &b, keys, walks, put)?;
            Ok(())
        });
        if let Some(done) = in_place {
            return done.map(|()| cut);
        }
        let (mut pairs, mut own) = (self.buffer("eval")?, self.buffer("eval")?);
        self.chunks("eval", |m, ids, r| {
            pairs.clear();
            pairs.extend(r.clone().map(|k| (wi.get(k), wo.get(k))));
            let keys = match keys {
                Some(x) => &x[r.clone()],
                None => {
                    own.clear();
                    own.extend(pairs.iter().map(|p| direction_key(p.0, p.1)));
                    &own[..]
                }
            };
            let est = m.eval_batch_keyed(ids, &pairs, walks, keys)?;
            for (k, e) in r.clone().zip(&est) {
                cut += e.truncated;
                out(k, e);
            }
            Ok(())
        })?;
        Ok(cut)
    }

    /// Each row's table found once.
    fn eval_pdf_into(
        &self,
        q: &Queries,
        evals: &mut (dyn FnMut(usize, &Estimate) + Send),
        pdfs: &mut (dyn FnMut(usize, f32) + Send),
    ) -> Result<u64, BatchError> {
        let (wi, wo, keys) = (q.wi, q.wo_or_none(), q.keys);
        self.pairs_checked(q, true)?;
        let walks = self.template.walks_of(q)?;
        let mut cut = 0;
        let in_place = self.in_place_chunks("eval_pdf", false, |per, r| {
            let (a, b) = (wi.range(r.clone()), wo.range(r.clone()));
            let keys = keys.map(|x| &x[r.clone()]);
            let evals = |k: usize, e: &Estimate| evals(r.start + k, e);
            let pdfs = |k: usize, p: f32| pdfs(r.start + k, p);
            cut += (self.rows_bsdf()).eval_pdfs(per, (&a, &b, keys, walks), evals, pdfs)?;
            Ok(())
        });
        if let Some(done) = in_place {
            return done.map(|()| cut);
        }
        // Rows that are materials: the two calls (every pair is checked
        // above, so the second cannot fail after the first handed out).
        let cut = self.eval_into(q, evals)?;
        self.pdf_into(q, pdfs)?;
        Ok(cut)
    }

    fn sample_into(
        &self,
        q: &Queries,
        out: &mut (dyn FnMut(usize, Option<&Sample>) + Send),
    ) -> Result<(), BatchError> {
        self.directions_checked(q, true)?;
        let (wi, keys, indices) = (q.wi, q.keys, q.indices);
        let in_place = self.in_place_chunks("sample", false, |per, r| {
            let keys = keys.map(|x| &x[r.clone()]);
            let indices = indices.map(|x| &x[r.clone()]);
            let a = wi.range(r.clone());
            let start = r.start;
            let put = |k: usize, s: Option<&Sample>| out(start + k, s);
            (self.rows_bsdf()).samples_of(per, &a, keys, indices, start, put)
        });
        if let Some(done) = in_place {
            return done;
        }
        let (mut wis, mut index) = (self.buffer("sample")?, self.buffer("sample")?);
        let mut own = self.buffer("sample")?;
        self.chunks("sample", |m, ids, r| {
            wis.clear();
            wis.extend(r.clone().map(|k| wi.get(k)));
            index.clear();
            match (indices, keys) {
                (Some(x), _) => index.extend_from_slice(&x[r.clone()]),
                (None, Some(_)) => index.resize(r.len(), 0),
                (None, None) => index.extend(r.clone().map(|k| k as u64)),
            }
            let keys = match keys {
                Some(x) => &x[r.clone()],
                None => {
                    own.clear();
                    own.extend(wis.iter().map(|&w| direction_key(w, w)));
                    &own[..]
                }
            };
            let s = m.sample_batch_keyed(ids, &wis, keys, &index)?;
            for (k, s) in r.zip(&s) {
                out(k, s.as_ref());
            }
            Ok(())
        })
    }

    fn pdf_into(
        &self,
        q: &Queries,
        out: &mut (dyn FnMut(usize, f32) + Send),
    ) -> Result<(), BatchError> {
        let (wi, wo) = (q.wi, q.wo_or_none());
        self.pairs_checked(q, false)?;
        let in_place = self.in_place_chunks("pdf", false, |per, r| {
            let (a, b) = (wi.range(r.clone()), wo.range(r.clone()));
            let put = |k: usize, p: f32| out(r.start + k, p);
            (self.rows_bsdf()).pdfs(per, r.len(), |k| pair_at(&a, &b, k), put);
            Ok(())
        });
        if let Some(done) = in_place {
            return done;
        }
        let mut pairs = self.buffer("pdf")?;
        self.chunks("pdf", |m, ids, r| {
            pairs.clear();
            pairs.extend(r.clone().map(|k| (wi.get(k), wo.get(k))));
            for (k, p) in r.zip(m.pdf_batch(ids, &pairs)?) {
                out(k, p);
            }
            Ok(())
        })
    }

    fn pdf_unbiased_into(
        &self,
        q: &Queries,
        out: &mut (dyn FnMut(usize, &PdfEstimate) + Send),
    ) -> Result<u64, BatchError> {
        let (wi, wo) = (q.wi, q.wo_or_none());
        self.pairs_checked(q, false)?;
        let walks = self.template.walks_of(q)?;
        let mut cut = 0;
        let in_place = self.in_place_chunks("pdf_unbiased", false, |per, r| {
            let (a, b) = (wi.range(r.clone()), wo.range(r.clone()));
            let put = |k: usize, e: &PdfEstimate| out(r.start + k, e);
            cut += (self.rows_bsdf()).pdfs_unbiased(per, &a, &b, walks, put);
            Ok(())
        });
        if let Some(done) = in_place {
            return done.map(|()| cut);
        }
        let mut pairs = self.buffer("pdf_unbiased")?;
        self.chunks("pdf_unbiased", |m, ids, r| {
            pairs.clear();
            pairs.extend(r.clone().map(|k| (wi.get(k), wo.get(k))));
            for (k, e) in r.zip(&m.pdf_unbiased_batch(ids, &pairs, walks)?) {
                cut += e.truncated;
                out(k, e);
            }
            Ok(())
        })?;
        Ok(cut)
    }

    fn albedo_into(
        &self,
        q: &Queries,
        out: &mut (dyn FnMut(usize, &Albedo) + Send),
    ) -> Result<u64, BatchError> {
        self.directions_checked(q, false)?;
        let walks = self.template.walks_of(q)?;
        let (wi, keys) = (q.wi, q.keys);
        let mut cut = 0;
        let in_place = self.in_place_chunks("albedo", true, |per, r| {
            let keys = keys.map(|x| &x[r.clone()]);
            let a = wi.range(r.clone());
            let put = |k: usize, x: &Albedo| out(r.start + k, x);
            cut += self.rows_bsdf().albedos(per, &a, walks, keys, put);
            Ok(())
        });
        if let Some(done) = in_place {
            return done.map(|()| cut);
        }
        let (mut wis, mut own) = (self.buffer("albedo")?, self.buffer("albedo")?);
        self.chunks("albedo", |mats, ids, r| {
            wis.clear();
            wis.extend(r.clone().map(|k| wi.get(k)));
            let keys = match keys {
                Some(x) => &x[r.clone()],
                None => {
                    own.clear();
                    own.extend(wis.iter().map(|&w| direction_key(w, w)));
                    &own[..]
                }
            };
            for (k, a) in r.zip(&mats.albedo_batch_keyed(ids, &wis, walks, keys)?) {
                cut += a.reflected.truncated;
                out(k, a);
            }
            Ok(())
        })?;
        Ok(cut)
    }
}

impl PerQuery<'_> {
    /// Checks a call on pairs before anything runs: no rows (query `k` is
    /// on row `k`), one pair per query, each of two directions, and keys
    /// (if given) one per query. Where the call's own checks run first
    /// (`call_checks`: eval and sample check every direction and key of a
    /// chunk before they hand out) and the batch is one chunk of rows in
    /// place, only the lengths (which slicing a chunk needs).
    fn pairs_checked(&self, q: &Queries, call_checks: bool) -> Result<usize, BatchError> {
        let (wi, wo, keys) = (&q.wi, &q.wo_or_none(), q.keys);
        let n = if call_checks && self.one_chunk_in_place() {
            let n = wi.count("wi")?;
            one_each("wo", wo.count("wo")?, n)?;
            if let Some(k) = keys {
                one_each("keys", k.len(), n)?;
            }
            n
        } else {
            Vectors::check_pairs(wi, wo, keys)?
        };
        self.check_queries(q, n)
    }

    /// [`PerQuery::pairs_checked`] for a call on incident directions, and
    /// its sample indices (if given) one per query.
    fn directions_checked(&self, q: &Queries, call_checks: bool) -> Result<usize, BatchError> {
        let (wi, keys) = (&q.wi, q.keys);
        let n = if call_checks && self.one_chunk_in_place() {
            let n = wi.count("wi")?;
            if let Some(k) = keys {
                one_each("keys", k.len(), n)?;
            }
            n
        } else {
            Vectors::check_directions(wi, keys)?
        };
        if let Some(i) = q.indices {
            one_each("indices", i.len(), n)?;
        }
        self.check_queries(q, n)
    }

    /// The batch has a query per row, and no rows of its own.
    fn check_queries(&self, q: &Queries, n: usize) -> Result<usize, BatchError> {
        if q.rows.is_some() {
            return Err(BatchError::call(QueryError::RowsNotTaken));
        }
        one_each("wi", n, self.queries)?;
        Ok(n)
    }
}

/// The pairs of a batch, checking that `wi` and `wo` have one each.
fn pairs_of(wi: &Vectors, wo: &Vectors) -> Result<Vec<(Vec3, Vec3)>, BatchError> {
    let n = wi.count("wi")?;
    one_each("wo", wo.count("wo")?, n)?;
    Ok((0..n).map(|k| (wi.get(k), wo.get(k))).collect())
}

/// The directions of a batch.
fn dirs_of(wi: &Vectors) -> Result<Vec<Vec3>, BatchError> {
    Ok((0..wi.count("wi")?).map(|k| wi.get(k)).collect())
}

thread_local! {
    /// The checked queries of this thread's eval calls.
    static QUERIES: std::cell::RefCell<Option<Vec<(Pair, u64)>>> =
        const { std::cell::RefCell::new(None) };
}

/// Direction `k` of a checked batch.
fn dir_at(v: &Vectors, k: usize) -> [f64; 3] {
    Direction::new("wi", v.get(k)).map_or([0.0; 3], Direction::get)
}

/// Pair `k` of a checked batch.
fn pair_at(wi: &Vectors, wo: &Vectors, k: usize) -> Pair {
    (dir_at(wi, k), dir_at(wo, k))
}
