//! The bidirectional estimator on lanes: one walk of a query per lane
//! ([`crate::estimator::bidir`] written once over lanes; the lanes of a
//! chunk are walks of one query, so that they share its parameters:
//! consecutive walks while tracing, walks of like subpath lengths while
//! connecting, where those vary). Each lane draws only where it is active,
//! so a lane replays the scalar engine's walk of its sample exactly. Queries are cut
//! into blocks of [`BLOCK`] walks, reduced in sample order and merged in
//! block order: the scalar engine's reduction, whatever the threads.

use super::{zero_sum, Pair, Queries, Unit, Wavefront, CALLS};
use crate::estimator::accumulate::{BlockReducer, MeanVar, BLOCK};
use crate::estimator::bidir::{with_kept_by_type, BidirWalk, Buffers};
use crate::estimator::Estimate;
use crate::lane::{Wide, V3};
use crate::rng::{seed_state_from, LaneRng, Stream};
use rayon::prelude::*;

/// A unit's walks between their tracing and their connections.
#[derive(Default)]
struct Regrouped<W: Wide> {
    /// The subpaths, per chunk of consecutive walks as they were traced.
    traced: Vec<Buffers<W>>,
    /// Per walk: where its subpaths are, their lengths, its random state.
    walks: Vec<Traced>,
    /// The walks in connection order: by subpath lengths.
    order: Vec<u32>,
    /// One chunk of walks of like lengths, gathered for their connections.
    joined: Buffers<W>,
    /// Per walk, its value.
    values: Vec<[f64; 3]>,
}

/// One traced walk.
struct Traced {
    chunk: usize,
    lane: usize,
    lengths: (usize, usize),
    state: [u32; 4],
}

impl<W: Wide> Wavefront<W> {
    /// The walk values of unit `u` (consecutive walks of one query), handed
    /// to `push` in sample order.
    ///
    /// Every pair of vertices of a walk's two subpaths is a connection, so a
    /// chunk of walks loops over the longest subpaths among its lanes. The
    /// unit's walks are therefore traced in chunks of consecutive walks,
    /// then regrouped by the lengths of their subpaths for the connections,
    /// each lane carrying its walk's subpaths and random state: a walk's
    /// value and draws are its own, whatever its company, so the values are
    /// the scalar engine's walk for walk.
    fn bidir_values(
        &self,
        q: &Queries,
        u: Unit,
        g: &mut Regrouped<W>,
        mut push: impl FnMut([f64; 3]),
    ) {
        let qi = u.query as usize;
        let (mut ifaces, mut media) = (Vec::new(), Vec::new());
        let walk = match q.lane_sets(W::LANES, |_| u.query) {
            None => BidirWalk {
                ifaces: &self.ifaces,
                media: &self.media,
                settings: &self.settings,
            },
            Some(sets) => {
                sets.ifaces_into(&self.ifaces, &mut ifaces);
                sets.media_into(&self.media, &mut media);
                BidirWalk {
                    ifaces: &ifaces,
                    media: &media,
                    settings: &self.settings,
                }
            }
        };
        let count = u.count as usize;
        if !walk.connects() {
            (0..count).for_each(|_| push([0.0; 3]));
            return;
        }
        let s = |c: &[Vec<f32>; 3]| {
            V3::new(
                W::splat(c[0][qi] as f64),
                W::splat(c[1][qi] as f64),
                W::splat(c[2][qi] as f64),
            )
        };
        let (wi, wo) = (s(&q.wi), s(&q.wo));
        // The random streams of the chunk of walks `first..first + lanes`
        // (a partial chunk's spare lanes repeat its last walk).
        let chunk_rng = |first: usize, lanes: usize| {
            LaneRng::<W>::from_states(|j| {
                let sample = u.first + (first + j.min(lanes - 1)) as u64;
                seed_state_from(q.prefix[qi], sample, Stream::Bidir)
            })
        };
        if !walk.subpath_lengths_vary() {
            // Chunk by chunk: regrouping would not pay.
            if g.traced.is_empty() {
                g.traced.push(Buffers::default());
            }
            let buf = &mut g.traced[0];
            for first in (0..count).step_by(W::LANES) {
                let lanes = (count - first).min(W::LANES);
                let mut rng = chunk_rng(first, lanes);
                let v = walk.run(wi, wo, buf, |m| rng.uniform(m));
                (0..lanes).for_each(|j| push([v.r.lane(j), v.g.lane(j), v.b.lane(j)]));
            }
            return;
        }
        let chunks = count.div_ceil(W::LANES);
        if g.traced.len() < chunks {
            g.traced.resize_with(chunks, Buffers::default);
        }
        g.walks.clear();
        for (c, buf) in g.traced[..chunks].iter_mut().enumerate() {
            let first = c * W::LANES;
            let lanes = (count - first).min(W::LANES);
            let mut rng = chunk_rng(first, lanes);
            walk.trace_both(wi, wo, buf, |m| rng.uniform(m));
            g.walks.extend((0..lanes).map(|lane| Traced {
                chunk: c,
                lane,
                lengths: buf.lengths(lane),
                state: rng.lane_state(lane),
            }));
        }
        let Regrouped {
            traced,
            walks,
            order,
            joined,
            values,
        } = g;
        order.clear();
        order.extend(0..count as u32);
        order.sort_unstable_by_key(|&w| walks[w as usize].lengths);
        values.resize(count, [0.0; 3]);
        for group in order.chunks(W::LANES) {
            let pick = |j: usize| &walks[group[j.min(group.len() - 1)] as usize];
            let rows = group.iter().fold((0, 0), |(y, z), &w| {
                let (ly, lz) = walks[w as usize].lengths;
                (y.max(ly), z.max(lz))
            });
            joined.gather(rows, |j| (&traced[pick(j).chunk], pick(j).lane));
            let mut rng = LaneRng::<W>::from_states(|j| pick(j).state);
            let v = walk.connect(joined, |m| rng.uniform(m));
            for (j, &w) in group.iter().enumerate() {
                values[w as usize] = [v.r.lane(j), v.g.lane(j), v.b.lane(j)];
            }
        }
        values[..count].iter().for_each(|&v| push(v));
    }

    /// Bidirectional eval of the `m` queries `query(k) = (pair, key)` with
    /// `samples` walks each, handed to `out` in query order: blocks of
    /// walks run in parallel on the current pool unless `serial`.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn eval_bidir_each(
        &self,
        sets: super::Sets,
        m: usize,
        mut query: impl FnMut(usize) -> (Pair, u64),
        samples: u64,
        seed: u64,
        serial: bool,
        mut out: impl FnMut(usize, Estimate),
    ) {
        super::with_kept(&CALLS, |c| {
            self.prepare_into(&mut c.queries, super::Mode::Eval, seed, sets, m, |k| {
                let ((wi, wo), key) = query(k);
                (wi, Some(wo), key)
            });
            let q = &c.queries;
            q.valid_ids_into(&mut c.valid);
            let (count, unit) = Self::block_unit(&c.valid, samples);
            let run = |u: usize| {
                let u = unit(u);
                let mut b = MeanVar::new();
                with_kept_by_type(|g: &mut Regrouped<W>| self.bidir_values(q, u, g, |x| b.push(x)));
                (u, b)
            };
            c.red.clear();
            c.red.resize(m, BlockReducer::new());
            if serial || count <= 1 {
                // Block by block into the reducers: nothing to collect.
                for (u, b) in (0..count).map(run) {
                    c.red[u.query as usize].push_block(&b);
                }
            } else {
                let blocks: Vec<(Unit, MeanVar)> = (0..count).into_par_iter().map(run).collect();
                for (u, b) in &blocks {
                    c.red[u.query as usize].push_block(b);
                }
            }
            for k in 0..m {
                let sum = match q.valid[k] {
                    true => c.red[k].finish(),
                    false => zero_sum(samples),
                };
                let e = self.estimate_with_terms(q, k, sum, false);
                out(k, e);
            }
        })
    }

    /// Bidirectional eval of every `(wi, wo)` pair with `samples` walks
    /// each; `keys[q]` seeds query `q` (the scalar engine's `query`).
    pub fn eval_bidir_batch(
        &self,
        pairs: &[([f64; 3], [f64; 3])],
        samples: u64,
        seed: u64,
        keys: &[u64],
    ) -> Vec<Estimate> {
        assert_eq!(pairs.len(), keys.len(), "one key per query");
        let mut est = Vec::with_capacity(pairs.len());
        let query = |k: usize| (pairs[k], keys[k]);
        let sets = super::Sets::Own;
        self.eval_bidir_each(sets, pairs.len(), query, samples, seed, false, |_, e| {
            est.push(e)
        });
        est
    }

    /// Each walk's value of the bidirectional estimator for one query, in
    /// sample order (without the first-order term): for parity tests.
    pub fn eval_bidir_walk_values(
        &self,
        wi: [f64; 3],
        wo: [f64; 3],
        samples: u64,
        seed: u64,
        key: u64,
    ) -> Vec<[f64; 3]> {
        let q = self.prepare(
            super::Mode::Eval,
            seed,
            super::Sets::Own,
            &[(wi, Some(wo), key)],
        );
        if !q.valid[0] {
            return vec![[0.0; 3]; samples as usize];
        }
        let mut g = Regrouped::default();
        let mut v = Vec::with_capacity(samples as usize);
        for first in (0..samples).step_by(BLOCK as usize) {
            let count = BLOCK.min(samples - first) as u32;
            let u = Unit {
                query: 0,
                first,
                count,
            };
            self.bidir_values(&q, u, &mut g, |x| v.push(x));
        }
        v
    }
}
