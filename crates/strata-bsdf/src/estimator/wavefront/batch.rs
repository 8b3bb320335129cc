//! The engine's batch calls (eval, sample, pdf, albedo): a call's walks cut
//! into tasks of whole blocks over threads, reduced per query in the
//! canonical block order.

use super::buffers::{with_calls, with_kept, with_wave, TASKS};
use super::engine::{zero_sum, Mode, Pair, Queries, Sets, Stats, Unit, WalkOut, Wavefront};
use super::stages::PdfScratch;
use crate::estimator::accumulate::{BlockReducer, MeanVar, BLOCK};
use crate::estimator::estimate::{Albedo, Estimate, WalkSample};
use crate::estimator::pdf::{PdfEstimate, PdfKind, PdfWalks};
use crate::estimator::terms;
use crate::lane::{Wide, V3};

/// Walks per task: the unit of work a thread takes. Tasks are whole blocks.
const TASK_WALKS: u64 = 32 * BLOCK;

/// A batch of at most this many walks (queries × walks per query) runs as
/// one task on the calling thread: handing work to another thread costs
/// more than such a batch takes (the criterion group `small` in
/// crates/strata-benches/benches/estimators.rs; docs/performance.md).
pub const SERIAL_WALKS: u64 = BLOCK;

/// Units per task for a batch of `count` units of `walks_per_unit` walks
/// over `threads` threads: all of them for a batch of at most
/// [`SERIAL_WALKS`] walks, else at most [`TASK_WALKS`] walks' worth and small
/// enough that each thread gets several tasks (for balance).
fn units_per_task(count: usize, walks_per_unit: u64, threads: usize) -> usize {
    if (count as u64).saturating_mul(walks_per_unit) <= SERIAL_WALKS {
        return count;
    }
    let threads = threads.max(1);
    ((TASK_WALKS / walks_per_unit).max(1) as usize)
        .min(count.div_ceil(4 * threads))
        .max(1)
}

/// Queries per task of a pdf batch, which runs one query per lane: a batch
/// of at most this many runs on the calling thread.
pub const PDF_CHUNK: usize = 64;

impl<W: Wide> Wavefront<W> {
    /// Runs the walks of `units` (an indexable sequence of `count` units)
    /// cut into tasks of whole units over rayon, or (`serial`, or a pool of
    /// one thread) in order on the calling thread. Each unit's walk outputs
    /// (in sample order) are condensed by `per_unit` (a block's mean and
    /// variance, or a sample); `sink` receives the results in unit order.
    /// Tasks run a window at a time, so memory is bounded by the window, not
    /// the batch. A serial run on a warm thread allocates nothing.
    #[allow(clippy::too_many_arguments)]
    fn run<R: Send>(
        &self,
        queries: &Queries,
        count: usize,
        unit: impl Fn(usize) -> Unit + Sync,
        per_unit: impl Fn(&[WalkOut]) -> R + Sync,
        mut sink: impl FnMut(Unit, R),
        serial: bool,
    ) -> Stats {
        if count == 0 {
            return Stats::default();
        }
        let threads = if serial {
            1
        } else {
            crate::pool::current_threads()
        };
        let serial = threads == 1;
        // Results do not depend on which units share a task: a unit's walks
        // and their reduction are its own, and units reach the sink in order.
        let walks_per_unit = unit(0).count.max(1) as u64;
        let per_task = units_per_task(count, walks_per_unit, threads);
        let tasks = count.div_ceil(per_task);
        let largest = (per_task.min(count) as u64).saturating_mul(walks_per_unit) as usize;
        let slots = self
            .slots
            .min(largest.div_ceil(W::LANES) * W::LANES)
            .max(W::LANES);
        if serial || tasks == 1 {
            // Tasks of consecutive units, one after the other: their results
            // are in unit order as they come, and every buffer is reused.
            return with_kept(&TASKS, |t| {
                let mut stats = Stats::default();
                for first in (0..count).step_by(per_task) {
                    t.units.clear();
                    t.units
                        .extend((first..count.min(first + per_task)).map(&unit));
                    let st = with_wave(slots, |ws| {
                        self.run_task(queries, &t.units, ws, &mut t.out, &mut t.bufs)
                    });
                    stats.add(&st);
                    let mut at = 0;
                    for u in &t.units {
                        let o = &t.out[at..at + u.count as usize];
                        at += u.count as usize;
                        sink(*u, per_unit(o));
                    }
                }
                stats
            });
        }
        let window = 4 * threads;
        let mut stats = Stats::default();
        for w0 in (0..tasks).step_by(window) {
            // The window's units are dealt to its tasks in turn (task j takes
            // units j, j + nt, ...), so that each task gets a share of every
            // kind of query and the tasks cost about the same.
            let first = w0 * per_task;
            let end = count.min((w0 + window) * per_task);
            let nt = (end - first).div_ceil(per_task);
            // Each worker reuses its own buffers; the results cross threads
            // in vectors of their own.
            let task = |j: usize| {
                with_kept(&TASKS, |t| {
                    t.ids.clear();
                    t.ids.extend((first + j..end).step_by(nt));
                    t.units.clear();
                    t.units.extend(t.ids.iter().map(|&i| unit(i)));
                    let st = with_wave(slots, |ws| {
                        self.run_task(queries, &t.units, ws, &mut t.out, &mut t.bufs)
                    });
                    let mut at = 0;
                    let res: Vec<(usize, Unit, R)> = (t.ids.iter().zip(&t.units))
                        .map(|(&i, u)| {
                            let o = &t.out[at..at + u.count as usize];
                            at += u.count as usize;
                            (i, *u, per_unit(o))
                        })
                        .collect();
                    (res, st)
                })
            };
            // A lone task runs on the calling thread: handing it to a pool's
            // thread would cost more than a single `sample` or `pdf` does.
            let results: Vec<_> = if nt == 1 {
                vec![task(0)]
            } else {
                crate::pool::par_map(nt, task)
            };
            // Back in unit order for the sink.
            let mut ordered: Vec<Option<(Unit, R)>> = (first..end).map(|_| None).collect();
            for (res, st) in results {
                stats.add(&st);
                for (i, u, r) in res {
                    ordered[i - first] = Some((u, r));
                }
            }
            for (u, r) in ordered.into_iter().flatten() {
                sink(u, r);
            }
        }
        stats
    }

    /// The valid queries' units of whole blocks, `samples` walks per query.
    pub(super) fn block_unit(
        valid: &[u32],
        samples: u64,
    ) -> (usize, impl Fn(usize) -> Unit + Sync + '_) {
        let per_query = samples.div_ceil(BLOCK).max(1) as usize;
        let count = if samples == 0 {
            0
        } else {
            // Saturates rather than wraps: an absurd count runs (for ever)
            // instead of silently running nothing. The API caps walks per
            // query at `MAX_WALKS`, far below this.
            valid.len().saturating_mul(per_query)
        };
        (count, move |u: usize| {
            let first = (u % per_query) as u64 * BLOCK;
            Unit {
                query: valid[u / per_query],
                first,
                count: BLOCK.min(samples - first) as u32,
            }
        })
    }

    /// The sum of each query's walks' values, reduced in block order, handed
    /// to `out` in query order; the reducers live in `red`, the valid
    /// queries' ids in `valid`.
    #[allow(clippy::too_many_arguments)]
    fn estimates(
        &self,
        queries: &Queries,
        valid: &mut Vec<u32>,
        red: &mut Vec<BlockReducer>,
        samples: u64,
        value: impl Fn(&WalkOut) -> [f64; 3] + Sync,
        serial: bool,
        mut out: impl FnMut(usize, MeanVar),
    ) -> Stats {
        queries.valid_ids_into(valid);
        red.clear();
        red.resize(queries.valid.len(), BlockReducer::new());
        let (count, unit) = Self::block_unit(valid, samples);
        // A block's walks in sample order, as the scalar engine pushes them.
        let block = |o: &[WalkOut]| {
            let mut b = MeanVar::new();
            o.iter().for_each(|o| b.push_walk(value(o), o.cut));
            b
        };
        let sink = |u: Unit, b: MeanVar| red[u.query as usize].push_block(&b);
        let stats = self.run(queries, count, unit, block, sink, serial);
        for (q, r) in red.iter().enumerate() {
            out(
                q,
                if queries.valid[q] {
                    r.finish()
                } else {
                    zero_sum(samples)
                },
            );
        }
        stats
    }

    /// Unidirectional eval of every `(wi, wo)` pair with `samples` walks each;
    /// `keys[q]` seeds query `q` (the scalar engine's `query` argument).
    pub fn eval_batch(
        &self,
        pairs: &[([f64; 3], [f64; 3])],
        samples: u64,
        seed: u64,
        keys: &[u64],
    ) -> (Vec<Estimate>, Stats) {
        self.eval_batch_in(Sets::Own, pairs, samples, seed, keys)
    }

    /// [`Wavefront::eval_batch`] with each query's parameters from `sets`.
    pub fn eval_batch_in(
        &self,
        sets: Sets,
        pairs: &[([f64; 3], [f64; 3])],
        samples: u64,
        seed: u64,
        keys: &[u64],
    ) -> (Vec<Estimate>, Stats) {
        assert_eq!(pairs.len(), keys.len(), "one key per query");
        let mut est = Vec::with_capacity(pairs.len());
        let query = |k: usize| (pairs[k], keys[k]);
        let push = |_, e| est.push(e);
        let stats = self.eval_each(sets, pairs.len(), query, samples, seed, false, push);
        (est, stats)
    }

    /// [`Wavefront::eval_batch`] of the `m` queries `query(k) = (pair, key)`
    /// (each called once, in order), handed to `out` in query order: serial
    /// (see [`Wavefront::run`]) on a warm thread, it allocates nothing.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn eval_each(
        &self,
        sets: Sets,
        m: usize,
        mut query: impl FnMut(usize) -> (Pair, u64),
        samples: u64,
        seed: u64,
        serial: bool,
        mut out: impl FnMut(usize, Estimate),
    ) -> Stats {
        with_calls(|c| {
            self.prepare_into(&mut c.queries, Mode::Eval, seed, sets, m, |k| {
                let ((wi, wo), key) = query(k);
                (wi, Some(wo), key)
            });
            let q = &c.queries;
            let value = |o: &WalkOut| o.value.map(|x| x as f64);
            let finish = |k: usize, sum: MeanVar| out(k, self.eval_estimate(q, k, sum));
            self.estimates(q, &mut c.valid, &mut c.red, samples, value, serial, finish)
        })
    }

    /// Query `k`'s estimate from the sum of its walks: with the first-order
    /// term (the entrance alone, when it is also the exit) and the control
    /// variate's exact part.
    fn eval_estimate(&self, queries: &Queries, q: usize, sum: MeanVar) -> Estimate {
        self.estimate_with_terms(queries, q, sum, true)
    }

    /// [`Wavefront::eval_estimate`], with the control variate's exact part
    /// only where `cv` (the bidirectional walks score every path).
    pub(super) fn estimate_with_terms(
        &self,
        queries: &Queries,
        q: usize,
        sum: MeanVar,
        cv: bool,
    ) -> Estimate {
        if !queries.valid[q] {
            return sum.estimate();
        }
        let wi = V3::new(queries.wi[0][q], queries.wi[1][q], queries.wi[2][q]);
        let wo = V3::new(queries.wo[0][q], queries.wo[1][q], queries.wo[2][q]);
        let e_in = queries.e_in[q] as usize;
        let (entrance, exact) = match queries.varying {
            false => (&self.table[e_in], self.cv.as_ref()),
            true => {
                let s = queries.set[q] as usize;
                (queries.table().iface(s, e_in), queries.table().cv(s))
            }
        };
        let cv = exact.filter(|_| cv);
        let same = e_in == queries.e_out[q] as usize;
        let (n, prefix) = (sum.count(), queries.prefix[q]);
        sum.estimate_with(&terms::eval_terms(entrance, same, cv, wi, wo, n, prefix))
    }

    /// Each walk's value of the unidirectional estimator (without the
    /// first-order term and the control variate's exact part), query by query in sample order: for parity tests
    /// and diagnostics (its memory grows with the batch).
    pub fn eval_walk_values(
        &self,
        pairs: &[([f64; 3], [f64; 3])],
        samples: u64,
        seed: u64,
        keys: &[u64],
    ) -> Vec<Vec<[f64; 3]>> {
        self.eval_walk_values_in(Sets::Own, pairs, samples, seed, keys)
    }

    /// [`Wavefront::eval_walk_values`] with each query's parameters from `sets`.
    pub fn eval_walk_values_in(
        &self,
        sets: Sets,
        pairs: &[([f64; 3], [f64; 3])],
        samples: u64,
        seed: u64,
        keys: &[u64],
    ) -> Vec<Vec<[f64; 3]>> {
        let queries = self.eval_queries(sets, pairs, seed, keys);
        let valid = queries.valid_ids();
        let mut v: Vec<Vec<[f64; 3]>> = queries
            .valid
            .iter()
            .map(|&ok| {
                if ok {
                    Vec::new()
                } else {
                    vec![[0.0; 3]; samples as usize]
                }
            })
            .collect();
        let (count, unit) = Self::block_unit(&valid, samples);
        let values = |o: &[WalkOut]| -> Vec<[f64; 3]> {
            o.iter().map(|o| o.value.map(|x| x as f64)).collect()
        };
        let sink = |u: Unit, x: Vec<[f64; 3]>| v[u.query as usize].extend(x);
        self.run(&queries, count, unit, values, sink, false);
        v
    }

    fn eval_queries(
        &self,
        sets: Sets,
        pairs: &[([f64; 3], [f64; 3])],
        seed: u64,
        keys: &[u64],
    ) -> Queries {
        assert_eq!(pairs.len(), keys.len(), "one key per query");
        let spec: Vec<_> = pairs
            .iter()
            .zip(keys)
            .map(|(&(wi, wo), &k)| (wi, Some(wo), k))
            .collect();
        self.prepare(Mode::Eval, seed, sets, &spec)
    }

    /// Directional albedo of every incident direction, `samples` walks each.
    pub fn albedo_batch(
        &self,
        wis: &[[f64; 3]],
        samples: u64,
        seed: u64,
        keys: &[u64],
    ) -> (Vec<Albedo>, Stats) {
        self.albedo_batch_in(Sets::Own, wis, samples, seed, keys)
    }

    /// [`Wavefront::albedo_batch`] with each query's parameters from `sets`.
    pub fn albedo_batch_in(
        &self,
        sets: Sets,
        wis: &[[f64; 3]],
        samples: u64,
        seed: u64,
        keys: &[u64],
    ) -> (Vec<Albedo>, Stats) {
        assert_eq!(wis.len(), keys.len(), "one key per query");
        let mut res = Vec::with_capacity(wis.len());
        let query = |k: usize| (wis[k], keys[k]);
        let push = |_, a| res.push(a);
        let stats = self.albedo_each(sets, wis.len(), query, samples, seed, false, push);
        (res, stats)
    }

    /// [`Wavefront::albedo_batch`] of the `m` queries `query(k) = (wi, key)`
    /// (each called once, in order), handed to `out` in query order: serial
    /// on a warm thread, it allocates nothing.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn albedo_each(
        &self,
        sets: Sets,
        m: usize,
        mut query: impl FnMut(usize) -> ([f64; 3], u64),
        samples: u64,
        seed: u64,
        serial: bool,
        mut out: impl FnMut(usize, Albedo),
    ) -> Stats {
        with_calls(|c| {
            self.prepare_into(&mut c.queries, Mode::Sample, seed, sets, m, |k| {
                let (wi, key) = query(k);
                (wi, None, key)
            });
            let queries = &c.queries;
            // Reflected and transmitted fractions share the walks: reduce both at once.
            queries.valid_ids_into(&mut c.valid);
            let red = &mut c.red2;
            red.clear();
            red.resize(m, (BlockReducer::new(), BlockReducer::new()));
            let (count, unit) = Self::block_unit(&c.valid, samples);
            let block = |o: &[WalkOut]| {
                let (mut r, mut t) = (MeanVar::new(), MeanVar::new());
                for o in o {
                    let w = o.value.map(|x| x as f64);
                    let (refl, trans) = (o.exited && o.reflection, o.exited && !o.reflection);
                    r.push_walk(if refl { w } else { [0.0; 3] }, o.cut);
                    t.push_walk(if trans { w } else { [0.0; 3] }, o.cut);
                }
                (r, t)
            };
            let sink = |u: Unit, (r, t): (MeanVar, MeanVar)| {
                let q = &mut red[u.query as usize];
                q.0.push_block(&r);
                q.1.push_block(&t);
            };
            let stats = self.run(queries, count, unit, block, sink, serial);
            for (q, (r, t)) in red.iter().enumerate() {
                let (r, t) = if queries.valid[q] {
                    (r.finish(), t.finish())
                } else {
                    (zero_sum(samples), zero_sum(samples))
                };
                let a = Albedo {
                    reflected: r.estimate(),
                    transmitted: t.estimate(),
                };
                out(q, a);
            }
            stats
        })
    }

    /// [`Wavefront::sample_batch`] of the `m` queries `query(k) = (wi, key,
    /// sample index)` (each called once, in order), handed to `out` in query
    /// order (`None`: absorbed, or no light enters): serial on a warm thread,
    /// it allocates nothing.
    pub(crate) fn sample_each(
        &self,
        sets: Sets,
        m: usize,
        mut query: impl FnMut(usize) -> ([f64; 3], u64, u64),
        seed: u64,
        serial: bool,
        mut out: impl FnMut(usize, Option<WalkSample>),
    ) -> Stats {
        with_calls(|c| {
            c.index.clear();
            let index = &mut c.index;
            self.prepare_into(&mut c.queries, Mode::Sample, seed, sets, m, |k| {
                let (wi, key, i) = query(k);
                index.push(i);
                (wi, None, key)
            });
            let queries = &c.queries;
            queries.valid_ids_into(&mut c.valid);
            let (valid, index) = (&c.valid, &c.index);
            let unit = |u: usize| Unit {
                query: valid[u],
                first: index[valid[u] as usize],
                count: 1,
            };
            // Queries without a walk (no light enters) are handed over as
            // absorbed, in order, as the walks that skip them end.
            let mut next = 0;
            let sink = |u: Unit, o: WalkOut| {
                let q = u.query as usize;
                for k in next..q {
                    out(k, None);
                }
                next = q + 1;
                let s = o.exited.then(|| {
                    let d = if queries.flipped[q] {
                        crate::estimator::orient::turned_over(&self.stack, o.dir)
                    } else {
                        o.dir
                    };
                    WalkSample {
                        wo: glam::Vec3::from(d),
                        weight: o.value,
                        reflection: o.reflection,
                        specular: o.specular,
                    }
                });
                out(q, s);
            };
            let stats = self.run(queries, valid.len(), unit, |o| o[0], sink, serial);
            for k in next..m {
                out(k, None);
            }
            stats
        })
    }

    /// A pdf of the `m` pairs `query(k) = (pair, key)` (each called once,
    /// in order), from `walks` density walks each, handed to `out` in query
    /// order, on the calling thread, from buffers this thread keeps (a warm
    /// thread allocates nothing): the numbers of [`Wavefront::pdf_batch`].
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn pdf_each(
        &self,
        sets: Sets,
        m: usize,
        mut query: impl FnMut(usize) -> (Pair, u64),
        walks: impl Into<PdfWalks>,
        seed: u64,
        kind: PdfKind,
        out: impl FnMut(usize, PdfEstimate),
    ) {
        let walks = walks.into();
        with_calls(|c| {
            self.prepare_into(&mut c.queries, Mode::Eval, seed, sets, m, |k| {
                let ((wi, wo), key) = query(k);
                (wi, Some(wo), key)
            });
            self.pdf_range(&c.queries, 0..m, walks, kind, &mut c.pdf, out);
        })
    }

    /// One analog walk per query: query `q` is light from `wis[q]`, seeded by
    /// `(seed, keys[q], sample_index[q])` (the scalar engine's stream).
    pub fn sample_batch(
        &self,
        wis: &[[f64; 3]],
        seed: u64,
        keys: &[u64],
        sample_index: &[u64],
    ) -> (Vec<Option<WalkSample>>, Stats) {
        self.sample_batch_in(Sets::Own, wis, seed, keys, sample_index)
    }

    /// [`Wavefront::sample_batch`] with each query's parameters from `sets`.
    pub fn sample_batch_in(
        &self,
        sets: Sets,
        wis: &[[f64; 3]],
        seed: u64,
        keys: &[u64],
        sample_index: &[u64],
    ) -> (Vec<Option<WalkSample>>, Stats) {
        assert_eq!(wis.len(), keys.len(), "one key per query");
        assert_eq!(wis.len(), sample_index.len(), "one sample index per query");
        let mut res = Vec::with_capacity(wis.len());
        let query = |k: usize| (wis[k], keys[k], sample_index[k]);
        let push = |_, s| res.push(s);
        let stats = self.sample_each(sets, wis.len(), query, seed, false, push);
        (res, stats)
    }

    /// A pdf of every `(wi, wo)` pair (see [`crate::estimator::pdf`]) from
    /// `walks` density walks each (a count, or [`PdfWalks`]: a pilot round,
    /// then the walks it sets), one query-walk pair per lane.
    pub fn pdf_batch(
        &self,
        pairs: &[([f64; 3], [f64; 3])],
        walks: impl Into<PdfWalks>,
        seed: u64,
        keys: &[u64],
        kind: PdfKind,
    ) -> Vec<PdfEstimate> {
        self.pdf_batch_in(Sets::Own, pairs, walks, seed, keys, kind)
    }

    /// [`Wavefront::pdf_batch`] with each query's parameters from `sets`.
    pub fn pdf_batch_in(
        &self,
        sets: Sets,
        pairs: &[([f64; 3], [f64; 3])],
        walks: impl Into<PdfWalks>,
        seed: u64,
        keys: &[u64],
        kind: PdfKind,
    ) -> Vec<PdfEstimate> {
        let walks = walks.into();
        assert_eq!(pairs.len(), keys.len(), "one key per query");
        let spec: Vec<_> = pairs
            .iter()
            .zip(keys)
            .map(|(&(wi, wo), &k)| (wi, Some(wo), k))
            .collect();
        let queries = self.prepare(Mode::Eval, seed, sets, &spec);
        let n = pairs.len();
        let chunk = |qs: std::ops::Range<usize>| {
            let mut res = Vec::with_capacity(qs.len());
            let scratch = &mut PdfScratch::default();
            self.pdf_range(&queries, qs, walks, kind, scratch, |_, e| res.push(e));
            res
        };
        if n <= PDF_CHUNK {
            // One chunk: on the calling thread (see `SERIAL_WALKS`).
            return chunk(0..n);
        }
        let chunks = crate::pool::par_map(n.div_ceil(PDF_CHUNK), |c| {
            chunk(c * PDF_CHUNK..((c + 1) * PDF_CHUNK).min(n))
        });
        chunks.into_iter().flatten().collect()
    }
}
