//! The bidirectional estimator on lanes: one walk of a query per lane
//! ([`crate::estimator::bidir`] written once over lanes; the lanes of a
//! chunk are walks of one query, so that they share its parameters). Where
//! subpath lengths vary, a lane takes the next walk as soon as its subpath
//! ends, and walks of like subpath lengths are connected together; elsewhere
//! a chunk's consecutive walks are traced and connected in step. Each lane
//! draws only where it is active, so a lane replays the scalar engine's walk
//! of its sample exactly. Queries are cut into blocks of [`BLOCK`] walks,
//! reduced in sample order and merged in block order: the scalar engine's
//! reduction, whatever the threads.

use super::buffers::with_calls;
use super::engine::{zero_sum, Mode, Pair, Queries, Sets, Unit, Wavefront};
use crate::estimator::accumulate::{BlockReducer, MeanVar, BLOCK};
use crate::estimator::bidir::{with_kept_by_type, BidirWalk, Buffers, Tracing, Vertex};
use crate::estimator::estimate::Estimate;
use crate::lane::{LaneMask, Wide, MAX_LANES, V3};
use crate::rng::{seed_state_from, LaneRng, Stream};

/// A unit's walks between their tracing and their connections.
#[derive(Default)]
struct Regrouped<W: Wide> {
    /// One chunk's subpaths, where walks are not regrouped.
    chunk: Buffers<W>,
    /// The light and the eye subpaths' vertices: lane `j` of these rows
    /// holds the subpaths that lane `j` traced, one after another.
    light: Vec<Vertex<W>>,
    eye: Vec<Vertex<W>>,
    /// Per walk: where its subpaths are, its random state after them.
    walks: Vec<Traced>,
    /// The walks in connection order: by subpath lengths.
    order: Vec<u32>,
    /// One chunk of walks of like lengths, gathered for their connections.
    joined: Buffers<W>,
    /// Per walk, its value.
    values: Vec<[f64; 3]>,
}

/// Where one subpath's vertices are: lane `lane` of rows `first..first + len`.
#[derive(Clone, Copy, Default)]
struct Span {
    lane: usize,
    first: usize,
    len: usize,
}

impl Span {
    /// The subpath's rows in `rows`, and its lane.
    fn of<'r, W: Wide>(&self, rows: &'r [Vertex<W>]) -> (&'r [Vertex<W>], usize) {
        (&rows[self.first..self.first + self.len], self.lane)
    }
}

/// One traced walk.
#[derive(Clone, Copy, Default)]
struct Traced {
    light: Span,
    eye: Span,
    state: [u32; 4],
    /// The limit of events ended one of its subpaths.
    cut: bool,
}

/// Traces one subpath of each walk of `walks` from `w` into `rows`: the
/// light subpath, from walk `k`'s random state `seed(k)`, or (`eye`) the eye
/// subpath, from the state its light subpath left. A lane takes the next
/// walk as soon as its subpath ends, so that lanes do not wait for the
/// longest subpath of a chunk; each walk records where its vertices are and
/// its state after them. A lane draws only for its own walk, so each walk's
/// draws are the scalar engine's.
fn trace_refilled<W: Wide>(
    walk: &BidirWalk<W>,
    w: V3<W>,
    eye: bool,
    walks: &mut [Traced],
    rows: &mut Vec<Vertex<W>>,
    seed: impl Fn(usize) -> [u32; 4],
) {
    let count = walks.len();
    rows.clear();
    let mut t = Tracing::<W>::idle();
    // (Idle lanes draw nothing: their state is never used.)
    let mut rng = LaneRng::<W>::from_states(|_| [0; 4]);
    // Per lane: its next row, and its walk and that walk's first row.
    let mut cursor = [0usize; MAX_LANES];
    let mut slot: [Option<(usize, usize)>; MAX_LANES] = [None; MAX_LANES];
    let mut next = 0;
    loop {
        let active = t.active();
        let mut fresh = [false; MAX_LANES];
        for j in (0..W::LANES).filter(|&j| !active.lane(j)) {
            if let Some((k, first)) = slot[j].take() {
                let len = cursor[j] - first;
                let span = Span {
                    lane: j,
                    first,
                    len,
                };
                let traced = &mut walks[k];
                match eye {
                    true => traced.eye = span,
                    false => traced.light = span,
                }
                traced.state = rng.lane_state(j);
                traced.cut |= t.cut().lane(j);
            }
            if next < count {
                slot[j] = Some((next, cursor[j]));
                fresh[j] = true;
                next += 1;
            }
        }
        let fresh = W::Mask::from_fn(|j| fresh[j]);
        if fresh.any() {
            rng = LaneRng::from_states(|j| match slot[j] {
                Some((k, _)) if fresh.lane(j) && eye => walks[k].state,
                Some((k, _)) if fresh.lane(j) => seed(k),
                _ => rng.lane_state(j),
            });
            walk.begin(w, fresh, &mut t, &mut |m| rng.uniform(m));
        }
        if !t.active().any() {
            return;
        }
        let row = walk.step(&mut t, eye, &mut |m| rng.uniform(m));
        for j in (0..W::LANES).filter(|&j| row.exists.lane(j)) {
            let r = cursor[j];
            if r == rows.len() {
                rows.push(row);
            } else {
                let lane = W::Mask::from_fn(|i| i == j);
                rows[r] = Vertex::select(lane, &row, &rows[r]);
            }
            cursor[j] += 1;
        }
    }
}

impl<W: Wide> Wavefront<W> {
    /// The walk values of unit `u` (consecutive walks of one query), handed
    /// to `push` in sample order.
    ///
    /// Every pair of vertices of a walk's two subpaths is a connection, so a
    /// chunk of walks loops over the longest subpaths among its lanes, and
    /// a chunk traced in step waits for its longest subpath. Where lengths
    /// vary, the unit's light subpaths are therefore traced with lanes
    /// refilled as subpaths end, then its eye subpaths the same way, and the
    /// walks are regrouped by the lengths of their subpaths for the
    /// connections, each lane carrying its walk's subpaths and random state:
    /// a walk's value and draws are its own, whatever its company, so the
    /// values are the scalar engine's walk for walk.
    fn bidir_values(
        &self,
        q: &Queries,
        u: Unit,
        g: &mut Regrouped<W>,
        mut push: impl FnMut([f64; 3], bool),
    ) {
        let qi = u.query as usize;
        let (mut ifaces, mut media) = (Vec::new(), Vec::new());
        let walk = match q.lane_sets(W::LANES, |_| u.query) {
            None => BidirWalk::new(&self.ifaces, &self.media, &self.settings),
            Some(sets) => {
                sets.ifaces_into(&self.ifaces, &mut ifaces);
                sets.media_into(&self.media, &mut media);
                BidirWalk::new(&ifaces, &media, &self.settings)
            }
        };
        let count = u.count as usize;
        if !walk.connects() {
            (0..count).for_each(|_| push([0.0; 3], false));
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
        // Walk `k`'s random stream, and those of the chunk of walks `first..
        // first + lanes` (a partial chunk's spare lanes repeat its last walk).
        let seed = |k: usize| seed_state_from(q.prefix[qi], u.first + k as u64, Stream::Bidir);
        let chunk_rng = |first: usize, lanes: usize| {
            LaneRng::<W>::from_states(|j| seed(first + j.min(lanes - 1)))
        };
        if !walk.subpath_lengths_vary() {
            // Chunk by chunk, the lanes in step: refilled lanes need the
            // regrouping, which would not pay here (docs/performance.md).
            for first in (0..count).step_by(W::LANES) {
                let lanes = (count - first).min(W::LANES);
                let mut rng = chunk_rng(first, lanes);
                let (v, cut) = walk.run(wi, wo, &mut g.chunk, |m| rng.uniform(m));
                (0..lanes).for_each(|j| push([v.r.lane(j), v.g.lane(j), v.b.lane(j)], cut.lane(j)));
            }
            return;
        }
        let Regrouped {
            light,
            eye,
            walks,
            order,
            joined,
            values,
            ..
        } = g;
        walks.clear();
        walks.resize(count, Traced::default());
        trace_refilled(&walk, wi, false, walks, light, seed);
        trace_refilled(&walk, wo, true, walks, eye, seed);
        order.clear();
        order.extend(0..count as u32);
        order.sort_unstable_by_key(|&w| {
            let t = &walks[w as usize];
            (t.light.len, t.eye.len)
        });
        values.resize(count, [0.0; 3]);
        for group in order.chunks(W::LANES) {
            let pick = |j: usize| &walks[group[j.min(group.len() - 1)] as usize];
            let rows = group.iter().fold((0, 0), |(y, z), &w| {
                let t = &walks[w as usize];
                (y.max(t.light.len), z.max(t.eye.len))
            });
            joined.gather(rows, |j| pick(j).light.of(light), |j| pick(j).eye.of(eye));
            let mut rng = LaneRng::<W>::from_states(|j| pick(j).state);
            let v = walk.connect(joined, |m| rng.uniform(m));
            for (j, &w) in group.iter().enumerate() {
                values[w as usize] = [v.r.lane(j), v.g.lane(j), v.b.lane(j)];
            }
        }
        (values[..count].iter().zip(&walks[..count])).for_each(|(&v, t)| push(v, t.cut));
    }

    /// Bidirectional eval of the `m` queries `query(k) = (pair, key)` with
    /// `samples` walks each, handed to `out` in query order: blocks of
    /// walks run in parallel on the current pool unless `serial`.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn eval_bidir_each(
        &self,
        sets: Sets,
        m: usize,
        mut query: impl FnMut(usize) -> (Pair, u64),
        samples: u64,
        seed: u64,
        serial: bool,
        mut out: impl FnMut(usize, Estimate),
    ) {
        with_calls(|c| {
            self.prepare_into(&mut c.queries, Mode::Eval, seed, sets, m, |k| {
                let ((wi, wo), key) = query(k);
                (wi, Some(wo), key)
            });
            let q = &c.queries;
            q.valid_ids_into(&mut c.valid);
            let (count, unit) = Self::block_unit(&c.valid, samples);
            let run = |u: usize| {
                let u = unit(u);
                let mut b = MeanVar::new();
                with_kept_by_type(|g: &mut Regrouped<W>| {
                    self.bidir_values(q, u, g, |x, cut| b.push_walk(x, cut))
                });
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
                let blocks: Vec<(Unit, MeanVar)> = crate::pool::par_map(count, run);
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
        let sets = Sets::Own;
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
        let q = self.prepare(Mode::Eval, seed, Sets::Own, &[(wi, Some(wo), key)]);
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
            self.bidir_values(&q, u, &mut g, |x, _| v.push(x));
        }
        v
    }
}
