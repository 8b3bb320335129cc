//! The bidirectional estimator on lanes: one walk of a query per lane
//! ([`crate::estimator::bidir`] written once over lanes; the lanes of a
//! chunk are consecutive walks of one query, so that they share its
//! parameters). Each lane draws only where it is active, so lane `j`
//! replays the scalar engine's walk of its sample exactly. Queries are cut
//! into blocks of [`BLOCK`] walks, reduced in sample order and merged in
//! block order: the scalar engine's reduction, whatever the threads.

use super::{zero_sum, Pair, Queries, Unit, Wavefront, CALLS};
use crate::estimator::accumulate::{BlockReducer, MeanVar, BLOCK};
use crate::estimator::bidir::{BidirWalk, Buffers};
use crate::estimator::Estimate;
use crate::lane::{Wide, V3};
use crate::rng::{seed_state_from, LaneRng, Stream};
use rayon::prelude::*;

impl<W: Wide> Wavefront<W> {
    /// The walk values of unit `u` (consecutive walks of one query), handed
    /// to `push` in sample order.
    fn bidir_values(
        &self,
        q: &Queries,
        u: Unit,
        buf: &mut Buffers<W>,
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
        let s = |c: &[Vec<f32>; 3]| {
            V3::new(
                W::splat(c[0][qi] as f64),
                W::splat(c[1][qi] as f64),
                W::splat(c[2][qi] as f64),
            )
        };
        let (wi, wo) = (s(&q.wi), s(&q.wo));
        let count = u.count as u64;
        for first in (0..count).step_by(W::LANES) {
            let lanes = (count - first).min(W::LANES as u64) as usize;
            let sample = |j: usize| u.first + first + j.min(lanes - 1) as u64;
            let mut rng = LaneRng::<W>::from_states(|j| {
                seed_state_from(q.prefix[qi], sample(j), Stream::Bidir)
            });
            let v = walk.run(wi, wo, buf, |m| rng.uniform(m));
            for j in 0..lanes {
                push([v.r.lane(j), v.g.lane(j), v.b.lane(j)]);
            }
        }
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
                Buffers::with_kept(|buf| self.bidir_values(q, u, buf, |x| b.push(x)));
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
        let mut buf = Buffers::default();
        let mut v = Vec::with_capacity(samples as usize);
        for first in (0..samples).step_by(BLOCK as usize) {
            let count = BLOCK.min(samples - first) as u32;
            let u = Unit {
                query: 0,
                first,
                count,
            };
            self.bidir_values(&q, u, &mut buf, |x| v.push(x));
        }
        v
    }
}
