//! The stages of a wave: starting walks, interface events, layer events; and the
//! round loop that passes walks between queues.
//!
//! Each stage runs the shared steps of `estimator::events` (and the layout's
//! decisions) in the order of the scalar reference's walk, with masks where
//! the scalar code returns early; what is here is scheduling: which lanes,
//! which queue next, what is loaded, stored or deferred.

use super::deferred::Deferred;
use super::engine::{Mode, Queries, Stats, Unit, WalkOut, Wavefront};
use super::walks::{lane_ids, lane_rows, Chunk, Link, LinkLanes, Stage, Walks, FREE};
use crate::estimator::density::{DensityWalk, WalkLanes};
use crate::estimator::events::{self, Connection};
use crate::estimator::events::{ChainStack, Flight};
use crate::estimator::layout::{toward_exit, LayerKind, MediumLanes, Next};
use crate::estimator::params::LaneSets;
use crate::estimator::pdf::{DensitySums, PdfEstimate, PdfKind, PdfWalks};
use crate::interface::InterfaceLanes;
use crate::lane::{load16, LaneMask, Rgb, Wide, MAX_LANES, V3};
use crate::rng::{seed_state_from, LaneRng, Stream};
use std::borrow::Cow;

/// Where the lanes of a chunk go after an event.
struct Outcome {
    /// Lanes whose walk goes on.
    going: u32,
    /// Lanes whose walk left the stack.
    exited: u32,
    /// The queues the going lanes join: lanes (a bitmask) and their queue,
    /// at most three groups (a layer's walks stay, or leave by its top or
    /// its bottom; an interface's go up or down). A lane is in one group.
    groups: [(u32, u16); 3],
}

impl Outcome {
    /// The queue all going lanes join, if they join one.
    #[inline(always)]
    fn together(&self) -> Option<u16> {
        let g = self.groups.iter().find(|g| g.0 & self.going != 0)?;
        (self.going & !g.0 == 0).then_some(g.1)
    }
}

/// A wave during one task: the walks, the task's outputs, the free slots.
pub(super) struct Wave<'a> {
    ws: &'a mut Walks,
    out: &'a mut [WalkOut],
    free: Vec<u32>,
    live: usize,
    /// No walk of the task is left to start.
    draining: bool,
    /// The queues of the next round, one per key: walks join the queue of
    /// their next event as they leave a chunk, so a round needs no sort.
    next: Vec<Vec<u32>>,
    /// Path continuations from collisions, waiting for a full chunk.
    deferred: Deferred,
    stats: Stats,
}

/// The buffers of a task that outlive it: a thread keeps one set and
/// reuses it task after task (grow-only, cleared per task).
#[derive(Default)]
pub(super) struct TaskBuffers {
    free: Vec<u32>,
    next: Vec<Vec<u32>>,
    launched: Vec<(u32, u64)>,
    queues: Vec<Vec<u32>>,
    deferred: Deferred,
}

/// `nkeys` empty queues with room for `slots` walks each (a queue never
/// holds more walks than the wave has slots), reusing what `v` holds.
fn reset_queues(v: &mut Vec<Vec<u32>>, nkeys: usize, slots: usize) {
    v.resize_with(nkeys, Vec::new);
    for queue in v.iter_mut() {
        queue.clear();
        queue.reserve(slots);
    }
}

impl Wave<'_> {
    /// Ends the walk in `slot` with `o` and frees the slot.
    #[inline(always)]
    fn finish(&mut self, slot: u32, o: WalkOut) {
        let s = slot as usize;
        self.out[self.ws.walk[s] as usize] = o;
        self.ws.key[s] = FREE;
        self.ws.chain[s].clear();
        self.free.push(slot);
        self.live -= 1;
    }

    /// Puts the walk in `slot` in queue `key` for the next round.
    #[inline(always)]
    fn enqueue(&mut self, slot: u32, key: u16) {
        self.ws.key[slot as usize] = key;
        self.next[key as usize].push(slot);
    }
}

/// Lane `j` of a connection, as f32.
fn conn_lane<W: Wide>(c: &Connection<W>, j: usize) -> Connection<f32> {
    let f = |x: W| x.lane(j) as f32;
    Connection {
        u: V3::new(f(c.u.x), f(c.u.y), f(c.u.z)),
        v: Rgb::new(f(c.v.r), f(c.v.g), f(c.v.b)),
        mis_pdf: f(c.mis_pdf),
    }
}

/// The engine's own lanes `own` without sets, else what `gather` makes of
/// them in the lanes' sets, built in `slot` (no copy of the lanes).
#[inline(always)]
fn in_slot<'s, T>(
    own: &'s T,
    sets: &Option<LaneSets>,
    slot: &'s mut Option<T>,
    gather: impl FnOnce(&LaneSets, &T) -> T,
) -> &'s T {
    match sets {
        None => own,
        Some(s) => slot.insert(gather(s, own)),
    }
}

/// Lane `j` of an RGB triple, as f32.
fn rgb_lane<W: Wide>(c: Rgb<W>, j: usize) -> Rgb<f32> {
    Rgb::new(c.r.lane(j) as f32, c.g.lane(j) as f32, c.b.lane(j) as f32)
}

impl<W: Wide> Wavefront<W> {
    /// The sets of the chunk's lanes (`idx`: their slots), if the call's
    /// queries have their own.
    #[inline(always)]
    fn sets_of<'q>(q: &'q Queries, ws: &Walks, idx: &[u32]) -> Option<LaneSets<'q>> {
        q.lane_sets(W::LANES, |j| ws.query[idx[j] as usize])
    }

    /// Interface `i` in the lanes' sets (the engine's own without sets).
    #[inline(always)]
    pub(super) fn iface_in(&self, sets: &Option<LaneSets>, i: usize) -> Cow<'_, InterfaceLanes<W>> {
        match sets {
            None => Cow::Borrowed(&self.ifaces[i]),
            Some(s) => Cow::Owned(s.iface(&self.ifaces[i], i)),
        }
    }

    /// Layer `l` as the plan runs it, in the lanes' sets.
    #[inline(always)]
    pub(super) fn medium_in(&self, sets: &Option<LaneSets>, l: usize) -> Cow<'_, MediumLanes<W>> {
        match sets {
            None => Cow::Borrowed(&self.media[l]),
            Some(s) => Cow::Owned(s.medium(&self.media[l], l)),
        }
    }

    /// Layer `l` as the stack has it, in the lanes' sets.
    #[inline(always)]
    fn medium_spec_in(&self, sets: &Option<LaneSets>, l: usize) -> Cow<'_, MediumLanes<W>> {
        match sets {
            None => Cow::Borrowed(&self.media_spec[l]),
            Some(s) => Cow::Owned(s.medium(&self.media_spec[l], l)),
        }
    }

    /// The lanes whose eval walks leave out the control variate's paths.
    #[inline(always)]
    fn cv_in(&self, sets: &Option<LaneSets>) -> W::Mask {
        match sets {
            None => W::Mask::splat(self.cv.is_some()),
            Some(s) => s.cv::<W>(),
        }
    }

    /// The lanes whose walks boost their first collision
    /// ([`events::FIRST_COLLISION_BOOST`]): eval walks with the control
    /// variate, in a grey medium (scalar: `ScalarEngine::boosting`). `None`
    /// where no lane can, decided without looking at the lanes, so that the
    /// plain walks run the plain events' code alone.
    #[inline(always)]
    fn boosting(&self, eval: bool, sets: &Option<LaneSets>) -> Option<W::Mask> {
        let cv_possible = self.cv.is_some() || sets.is_some();
        (eval && cv_possible && events::boosts_first_collision(&self.media))
            .then(|| self.cv_in(sets))
    }

    /// Russian roulette of the lanes `m` ([`events::survive`], and
    /// [`events::survive_boosted`] after a boosted collision).
    #[inline(always)]
    fn survive(&self, c: &mut Chunk<W>, u: W, m: W::Mask, boosting: Option<W::Mask>) -> W::Mask {
        if let Some(b) = boosting.filter(|b| (m & *b).any()) {
            let (_, rr) = events::collision_boost(b, c.order, c.beta);
            return events::survive_boosted(&mut c.beta, c.events, u, m, &self.settings, rr);
        }
        events::survive(&mut c.beta, c.events, u, m, &self.settings)
    }

    /// Runs every walk of `task` in the wave `ws`; outputs go to `out` in
    /// task order. The task's queues and deferred rows live in `tb`, kept by
    /// the caller between tasks so that a warm thread allocates nothing.
    pub(super) fn run_task(
        &self,
        q: &Queries,
        task: &[Unit],
        ws: &mut Walks,
        out: &mut Vec<WalkOut>,
        tb: &mut TaskBuffers,
    ) -> Stats {
        let total: usize = task.iter().map(|u| u.count as usize).sum();
        out.clear();
        out.resize(total, WalkOut::default());
        let slots = ws.slots();
        ws.key.fill(FREE);
        let n = self.layout.n;
        let nkeys = 2 * n - 1;
        // Eval walks defer their continuations from collisions (MIS only).
        let defers = q.mode == Mode::Eval
            && self.settings.mis
            && (self.exits.iter()).any(|&(_, l, _)| self.media[l].kind == LayerKind::Scattering);
        let mut free = std::mem::take(&mut tb.free);
        free.clear();
        free.extend((0..slots as u32).rev());
        let mut deferred = std::mem::take(&mut tb.deferred);
        deferred.reset(self.exits.len(), if defers { total } else { 0 }, W::LANES);
        let mut wave = Wave {
            ws,
            out,
            free,
            live: 0,
            draining: false,
            next: std::mem::take(&mut tb.next),
            deferred,
            stats: Stats {
                walks: total as u64,
                ..Stats::default()
            },
        };
        reset_queues(&mut wave.next, nkeys, slots);
        let mut launched = std::mem::take(&mut tb.launched);
        launched.clear();
        launched.reserve(slots);
        // This round's queues (the previous round's `next`).
        let mut queues = std::mem::take(&mut tb.queues);
        reset_queues(&mut queues, nkeys, slots);
        let (mut unit, mut offset, mut w) = (0usize, 0u32, 0u32);
        loop {
            // Refill free slots with the next walks.
            launched.clear();
            while unit < task.len() {
                let Some(slot) = wave.free.pop() else { break };
                let u = task[unit];
                let k = u.first + offset as u64;
                let key = q.e_in[u.query as usize];
                wave.ws.claim(slot as usize, key, w, u.query);
                launched.push((slot, k));
                w += 1;
                offset += 1;
                if offset == u.count {
                    unit += 1;
                    offset = 0;
                }
            }
            wave.live += launched.len();
            wave.draining = unit >= task.len();
            // New walks start in lanes and take their first events at once.
            for chunk in launched.chunks(W::LANES) {
                self.start_walks(q, &mut wave, chunk);
            }
            if wave.live == 0 {
                if wave.draining {
                    break;
                }
                continue;
            }
            std::mem::swap(&mut queues, &mut wave.next);
            // Advance every queue by one event, a chunk of lanes at a time.
            for (key, queue) in queues.iter_mut().enumerate() {
                for chunk in queue.chunks(W::LANES) {
                    // The last few walks of a task run on one lane each, to
                    // their end: a lone walk would leave the other lanes idle.
                    if let Some(tail) = self.tail.as_ref().filter(|_| wave.draining) {
                        if chunk.len() * 8 <= W::LANES {
                            for &s in chunk {
                                tail.advance(q, &mut wave, &[s], true, key);
                            }
                            continue;
                        }
                    }
                    let idx = lane_ids(chunk, |s| s);
                    let idx = &idx[..W::LANES];
                    let active = W::mask_from_bitmask(lane_bits(chunk.len()));
                    self.advance(q, &mut wave, idx, active, key);
                }
                queue.clear();
            }
        }
        if defers {
            for x in 0..self.exits.len() {
                self.run_deferred(q, &mut wave.deferred, x, true);
            }
            let values = wave.out.iter_mut().map(|o| &mut o.value);
            wave.deferred.add_sums(values);
        }
        // The buffers go back for the thread's next task.
        *tb = TaskBuffers {
            free: wave.free,
            next: wave.next,
            launched,
            queues,
            deferred: wave.deferred,
        };
        wave.stats
    }

    /// Starts the walks of `chunk` (slot, sample index) in lanes: seeds their
    /// streams, samples their adjoint chains (eval), and runs their first
    /// events before their records are ever written.
    #[cfg_attr(feature = "profiling", inline(never))]
    fn start_walks(&self, q: &Queries, wave: &mut Wave, chunk: &[(u32, u64)]) {
        let idx = lane_ids(chunk, |(s, _)| s);
        let lq = lane_ids(&idx[..W::LANES], |s| wave.ws.query[s as usize]);
        let (idx, lq) = (&idx[..W::LANES], &lq[..W::LANES]);
        let active = W::mask_from_bitmask(lane_bits(chunk.len()));
        let rng = LaneRng::<W>::from_states(|j| {
            let (_, k) = chunk[j.min(chunk.len() - 1)];
            seed_state_from(q.prefix[lq[j] as usize], k, Stream::Walk)
        });
        let g = |col: &[f32]| W::gather(col, lq);
        let d = -V3::new(g(&q.wi[0]), g(&q.wi[1]), g(&q.wi[2]));
        let wo = V3::new(g(&q.wo[0]), g(&q.wo[1]), g(&q.wo[2]));
        let eval = q.mode == Mode::Eval;
        let mut c = Chunk::<W>::start(active, d, wo, g(&q.e_out), eval, rng);
        if eval && self.layout.n >= 2 {
            self.launch_chain(q, wave.ws, &mut c, chunk, idx, lq);
        }
        let key = q.e_in[lq[0] as usize];
        if chunk.iter().all(|&(s, _)| wave.ws.key[s as usize] == key) {
            self.advance_chunk(q, wave, idx, c, key as usize);
        } else {
            // Walks entering from both sides: each waits in its entrance's queue.
            c.scatter(wave.ws, idx);
            for &(s, _) in chunk {
                let key = wave.ws.key[s as usize];
                wave.enqueue(s, key);
            }
        }
    }

    /// Samples the adjoint chains of new eval walks (scalar:
    /// `ScalarEngine::adjoint_chain`). The first link goes to the chunk
    /// (`link0`, stored with the record when the chunk is); further links
    /// (smooth exits only) to the slot's overflow list.
    #[cfg_attr(feature = "profiling", inline(never))]
    fn launch_chain(
        &self,
        q: &Queries,
        ws: &mut Walks,
        c: &mut Chunk<W>,
        chunk: &[(u32, u64)],
        idx: &[u32],
        lq: &[u32],
    ) {
        let n = self.layout.n;
        let active = c.active;
        if Chunk::<W>::set_bits(W::bitmask(active)).all(|j| q.fixed[lq[j] as usize]) {
            // Every walk's chain is its query's, computed once in `prepare`.
            let f = load16::<W, 16>(&q.link0, lq, 0);
            c.link0 = LinkLanes::from_fields(&f);
            c.links = W::select(active, f[12], W::zero());
            return;
        }
        // (A lane with a fixed chain, in a chunk that mixes them, samples it
        // too: its draws go unused, and it comes out the same.)
        let mut rng = LaneRng::<W>::from_states(|j| {
            let (_, k) = chunk[j.min(chunk.len() - 1)];
            seed_state_from(q.prefix[lq[j] as usize], k, Stream::Adjoint)
        });
        let top = c.e_out.eq(W::zero());
        let sets = q.lane_sets(W::LANES, |j| lq[j]);
        let (e0, e1) = (self.iface_in(&sets, 0), self.iface_in(&sets, n - 1));
        let exit = InterfaceLanes::select(top, &e0, &e1);
        let u = (
            rng.uniform(active),
            rng.uniform(active),
            rng.uniform(active),
        );
        let media = |l: usize| self.medium_spec_in(&sets, l);
        let (first, ok) = events::first_link(&self.layout, &exit, media, c.wo, top, u);
        let ok = ok & active;
        c.link0 = first;
        c.links = W::select(ok, W::one(), W::zero());
        // Continue through delta interfaces while the chain stays smooth.
        let stack = ChainStack {
            // Only delta interfaces continue the chain (checked before the
            // per-lane gather of the interfaces, which is costly).
            smooth: |j: W| {
                let mut smooth = W::Mask::splat(false);
                for (i, it) in self.stack.interfaces().iter().enumerate() {
                    if it.smooth {
                        smooth = smooth | j.eq(W::splat(i as f64));
                    }
                }
                smooth
            },
            iface: |j: W| match &sets {
                None => InterfaceLanes::<W>::gather(&self.table, |k| j.lane(k) as usize),
                Some(s) => InterfaceLanes::<W>::gather(s.table().ifaces(), |k| {
                    s.block(k) * n + j.lane(k) as usize
                }),
            },
            media,
        };
        let links = &mut c.links;
        events::extend_chain(
            &self.layout,
            &self.settings,
            first,
            ok & exit.smooth,
            stack,
            |m| rng.uniform(m),
            |last, m| {
                *links = W::select(m, *links + W::one(), *links);
                for k in Chunk::<W>::lanes(m) {
                    ws.chain[idx[k] as usize].push(Link {
                        conn: conn_lane(&last.conn, k),
                        t_full: rgb_lane(last.t, k),
                        layer: last.layer.lane(k) as u16,
                        start: last.start.lane(k) as u16,
                    });
                }
            },
        );
    }

    /// Lanes of the chunk's walks' overflow links `k` (link `k + 1` of the
    /// chain; [`NO_LINK`] where a lane has none), if any lane has one.
    fn overflow_links(ws: &Walks, idx: &[u32], active: W::Mask, k: usize) -> Option<LinkLanes<W>> {
        // Per field, per lane: u (3), v (3), mis, t (3), layer, start.
        // Lanes without a link: a harmless direction, no layer, no interface.
        let mut f = [[0.0f32; 16]; 12];
        for i in [2, 7, 8, 9] {
            f[i] = [1.0; 16];
        }
        f[10] = [f32::MAX; 16];
        f[11] = [f32::MAX; 16];
        let mut any = false;
        for j in Chunk::<W>::lanes(active) {
            if let Some(l) = ws.chain[idx[j] as usize].get(k) {
                any = true;
                let c = &l.conn;
                let vals = [
                    c.u.x,
                    c.u.y,
                    c.u.z,
                    c.v.r,
                    c.v.g,
                    c.v.b,
                    c.mis_pdf,
                    l.t_full.r,
                    l.t_full.g,
                    l.t_full.b,
                    l.layer as f32,
                    l.start as f32,
                ];
                for (field, v) in f.iter_mut().zip(vals) {
                    field[j] = v;
                }
            }
        }
        let lanes = |i: usize| W::from_fn(|j| f[i][j] as f64);
        any.then(|| LinkLanes {
            conn: Connection {
                u: V3::new(lanes(0), lanes(1), lanes(2)),
                v: Rgb::new(lanes(3), lanes(4), lanes(5)),
                mis_pdf: lanes(6),
            },
            t: Rgb::new(lanes(7), lanes(8), lanes(9)),
            layer: lanes(10),
            start: lanes(11),
        })
    }

    /// Adds next-event estimation through every link of the lanes in
    /// `m` whose link passes `wanted`, with `contribution(link)` per unit
    /// throughput. Link order is the scalar engine's: the first link, then
    /// the overflow list.
    #[cfg_attr(feature = "profiling", inline(never))]
    fn connect_links(
        ws: &Walks,
        idx: &[u32],
        m: W::Mask,
        c: &mut Chunk<W>,
        wanted: impl Fn(&LinkLanes<W>) -> W::Mask,
        contribution: impl Fn(&LinkLanes<W>) -> Rgb<W>,
    ) {
        let nl = c.links;
        let first = c.link0;
        let mm = m & nl.gt(W::splat(0.5)) & wanted(&first);
        if mm.any() {
            c.acc = Rgb::select(mm, c.acc + c.beta * contribution(&first), c.acc);
        }
        let more = m & nl.gt(W::splat(1.5));
        let mut k = 0;
        while more.any() {
            let Some(lk) = Self::overflow_links(ws, idx, more, k) else {
                break;
            };
            let mm = more & wanted(&lk);
            if mm.any() {
                c.acc = Rgb::select(mm, c.acc + c.beta * contribution(&lk), c.acc);
            }
            k += 1;
        }
    }

    /// What a queue key's event needs loaded.
    fn stage_for(&self, q: &Queries, key: usize) -> Stage {
        let n = self.layout.n;
        let eval = q.mode == Mode::Eval;
        if key < n {
            Stage::Interface {
                acc: eval,
                links: eval && self.connects_at[key],
            }
        } else {
            Stage::Layer {
                acc: eval,
                links: eval && self.connects_in[key - n],
            }
        }
    }

    /// Advances a chunk of walks from queue `key` by one event, and keeps it
    /// in lanes for further events while all its lanes go on to the same
    /// queue (a chunk whose walks agree skips a store, a sort and a load per
    /// event); then stores it back. Continuing with some lanes idle was
    /// measured slower than regrouping them, except when the task is
    /// `draining` (no walk left to start): then the chunk keeps going with
    /// whatever lanes still agree.
    pub(super) fn advance(
        &self,
        q: &Queries,
        wave: &mut Wave,
        idx: &[u32],
        active: W::Mask,
        key: usize,
    ) {
        let c = Chunk::<W>::gather(wave.ws, idx, active, self.stage_for(q, key));
        self.advance_chunk(q, wave, idx, c, key);
    }

    /// [`Wavefront::advance`] for a chunk already in lanes.
    #[cfg_attr(feature = "profiling", inline(never))]
    fn advance_chunk(
        &self,
        q: &Queries,
        wave: &mut Wave,
        idx: &[u32],
        mut c: Chunk<W>,
        key: usize,
    ) {
        let n = self.layout.n;
        let mut key = key;
        // The chunk's lanes keep their walks (and sets) until it returns.
        let sets = Self::sets_of(q, wave.ws, idx);
        loop {
            c.ensure(wave.ws, idx, self.stage_for(q, key));
            let busy = W::bitmask(c.active);
            wave.stats.chunks += 1;
            wave.stats.lanes += W::LANES as u64;
            wave.stats.segments += busy.count_ones() as u64;
            let o = if key < n {
                self.interface_event(q, &sets, wave.ws, idx, &mut c, key)
            } else {
                self.layer_event(q, &sets, wave.ws, idx, &mut c, key - n, &mut wave.deferred)
            };
            let ended = busy & !o.going;
            if ended != 0 {
                self.finish_lanes(q, wave, idx, &c, ended, o.exited);
            }
            if o.going == 0 {
                return; // every walk ended: nothing to store
            }
            c.active = W::mask_from_bitmask(o.going);
            if let Some(next) = o.together() {
                if wave.draining || o.going.count_ones() as usize == W::LANES {
                    key = next as usize;
                    continue;
                }
            }
            c.scatter(wave.ws, idx);
            for (lanes, key) in o.groups {
                for j in Chunk::<W>::set_bits(lanes & o.going) {
                    wave.enqueue(idx[j], key);
                }
            }
            return;
        }
    }

    /// One interface event for a chunk of walks at interface `i`.
    #[cfg_attr(feature = "profiling", inline(never))]
    fn interface_event(
        &self,
        q: &Queries,
        sets: &Option<LaneSets>,
        ws: &Walks,
        idx: &[u32],
        c: &mut Chunk<W>,
        i: usize,
    ) -> Outcome {
        let n = self.layout.n;
        let eval = q.mode == Mode::Eval;
        let mis = self.settings.mis;
        let links = eval && self.connects_at[i];
        let active = c.active;
        let mut gathered = None;
        let iface = in_slot(&self.ifaces[i], sets, &mut gathered, |s, own| {
            s.iface(own, i)
        });
        let a = -c.d;
        let (wo, e_out) = (c.wo, c.e_out);
        // With the control variate, a walk that has not collided yet scores
        // nothing here: its connection crosses the layer by a transmittance,
        // a path without a collision, which the exact part holds (scalar:
        // `Connect::collided_only`).
        let cv = self.cv_in(sets);
        let scoring = if eval && cv.any() {
            events::scoring(active, c.order, cv)
        } else {
            active
        };
        // Next-event estimation from this surface vertex.
        if links {
            let at_i = W::splat(i as f64);
            let first = c.first;
            Self::connect_links(
                ws,
                idx,
                scoring,
                c,
                |k| k.starts_at(at_i),
                |k| events::surface_link(iface, a, first, k, mis),
            );
        }
        // Scatter at the interface.
        let u = (
            c.rng.uniform(active),
            c.rng.uniform(active),
            c.rng.uniform(active),
        );
        let transmit_only = c.first & W::Mask::splat(eval);
        let (s, alive) = events::interface_scatter(
            iface,
            a,
            u,
            transmit_only,
            active,
            &mut c.beta,
            &mut c.specular,
            &mut c.events,
        );
        let d = s.b;
        let up = d.z.gt(W::zero());
        // Path continuation towards a rough exit.
        if links {
            for &(e, l0, k0) in &self.exits {
                if k0 != i {
                    continue;
                }
                let m = alive & scoring & e_out.eq(W::splat(e as f64)) & toward(d, e);
                if m.any() {
                    let (ex, med) = (self.iface_in(sets, e), self.medium_in(sets, l0));
                    let add = events::surface_continuation(&ex, &med, wo, d, &s, c.beta, mis);
                    c.acc = Rgb::select(m, c.acc + add, c.acc);
                }
            }
        }
        c.first = W::Mask::splat(false);
        c.d = V3::select(alive, d, c.d);
        let (_, out) = self.layout.enter(W::splat(i as f64), up);
        let exited = alive & out;
        // Russian roulette.
        let cont = alive & !exited;
        let u = c.rng.uniform(cont);
        let boosting = self.boosting(eval, sets);
        let cont = self.survive(c, u, cont, boosting);
        // Enter the next layer; cross the ones that do not scatter right here.
        let mut stuck = W::Mask::splat(false);
        let mut keys = [FREE; 2]; // [up, down]
        for (dir, going_up) in [(0usize, true), (1, false)] {
            let Next::Layer { l, .. } = self.layout.next(i, going_up) else {
                continue;
            };
            let m = cont & if going_up { up } else { !up };
            // The layer's class and depth units are the shape's: its
            // numbers are gathered only to cross it here.
            let own = &self.media[l];
            let entry = own.entry(W::Mask::splat(going_up));
            if own.kind == LayerKind::Scattering {
                keys[dir] = (n + l) as u16;
                c.z = W::select(m, entry, c.z);
                continue;
            }
            keys[dir] = self.layout.boundary(l, going_up) as u16;
            if !m.any() {
                continue;
            }
            let med = self.medium_in(sets, l);
            stuck = stuck | events::cross_inert(&med, entry, d, m, &mut c.beta);
        }
        let up = W::bitmask(up);
        Outcome {
            going: W::bitmask(cont & !stuck),
            exited: W::bitmask(exited),
            groups: [(up, keys[0]), (!up, keys[1]), (0, FREE)],
        }
    }

    /// One layer event for a chunk of walks inside scattering layer `l`.
    #[cfg_attr(feature = "profiling", inline(never))]
    #[expect(
        clippy::too_many_arguments,
        reason = "the chunk's walks, slots and sets are borrowed apart from the chunk itself"
    )]
    fn layer_event(
        &self,
        q: &Queries,
        sets: &Option<LaneSets>,
        ws: &Walks,
        idx: &[u32],
        c: &mut Chunk<W>,
        l: usize,
        deferred: &mut Deferred,
    ) -> Outcome {
        let eval = q.mode == Mode::Eval;
        let mis = self.settings.mis;
        let links = eval && self.connects_in[l];
        let active = c.active;
        let mut gathered = None;
        let med = in_slot(&self.media[l], sets, &mut gathered, |s, own| {
            s.medium(own, l)
        });
        let d = c.d;
        let up = d.z.gt(W::zero());
        let ud = c.rng.uniform(active);
        let st = Flight {
            z: &mut c.z,
            beta: &mut c.beta,
            ratios: &mut c.ratios,
            order: &mut c.order,
        };
        let max_order = self.settings.max_scatter_order;
        let boosting = self.boosting(eval, sets);
        let boost = boosting
            .filter(|b| (active & *b).any())
            .map(|b| events::collision_boost(b, *st.order, *st.beta).0);
        let (col, pass) = events::free_flight(med, st, d, c.hero, ud, boost, active, max_order);
        let (wo, e_out) = (c.wo, c.e_out);
        // Next-event estimation from the collision.
        let e = events::estimate_uniforms(med, || c.rng.uniform(col));
        if links {
            let at_l = W::splat(l as f64);
            let z = c.z;
            Self::connect_links(
                ws,
                idx,
                col,
                c,
                |k| k.crosses(at_l),
                |k| events::collision_link(med, z, d, k, e, mis),
            );
        }
        let u = events::phase_uniforms(med, || c.rng.uniform(col));
        let dn = events::phase_scatter(med, d, u, col, &mut c.specular);
        // Path continuation from the collision towards a rough exit: only
        // some lanes need it, so it waits for a full chunk (`deferred`).
        if links && mis && med.phase.exact() {
            for (x, &(e, l0, _)) in self.exits.iter().enumerate() {
                if l0 != l {
                    continue;
                }
                let m = W::bitmask(col & e_out.eq(W::splat(e as f64)) & toward(dn, e));
                if m != 0 {
                    let dz_e = events::depth_ahead(med, c.z, dn);
                    let walk = W::gather_bits(&ws.walk, idx);
                    let query = W::gather_bits(&ws.query, idx);
                    deferred.push::<W>(x, m, (walk, query), (wo, d, dn, dz_e, c.beta));
                    if deferred.full(x, W::LANES) {
                        self.run_deferred(q, deferred, x, false);
                    }
                }
            }
        }
        events::after_collision(&mut c.d, &mut c.events, dn, col);
        let u = c.rng.uniform(col);
        let scattered = W::bitmask(self.survive(c, u, col, boosting));
        let n = self.layout.n;
        let up = W::bitmask(up);
        // Stay in the layer after a collision, or reach its top or bottom interface.
        let stay = (n + l) as u16;
        let top = self.layout.boundary(l, true) as u16;
        let bottom = self.layout.boundary(l, false) as u16;
        Outcome {
            going: scattered | W::bitmask(pass),
            exited: 0,
            groups: [
                (scattered, stay),
                (up & !scattered, top),
                (!up & !scattered, bottom),
            ],
        }
    }

    /// Ends the walks of lanes `ended` (those in `exited` left the stack):
    /// their outputs are transposed out of the lanes once for the chunk.
    #[cfg_attr(feature = "profiling", inline(never))]
    fn finish_lanes(
        &self,
        q: &Queries,
        wave: &mut Wave,
        idx: &[u32],
        c: &Chunk<W>,
        ended: u32,
        exited: u32,
    ) {
        let eval = q.mode == Mode::Eval;
        // Eval: the contribution whatever the ending. Sample: the weight of
        // a walk that left (one absorbed inside leaves 0).
        let v = if eval { c.acc } else { c.beta };
        let spec = W::select(c.specular, W::one(), W::zero());
        let d = c.d;
        let limit = events::event_limit(self.settings.max_events) as f32;
        let rows = lane_rows([d.x, d.y, d.z, v.r, v.g, v.b, spec, c.events]);
        for j in Chunk::<W>::set_bits(ended) {
            let r = rows[j];
            let out = if exited & (1 << j) != 0 {
                let qi = wave.ws.query[idx[j] as usize] as usize;
                WalkOut {
                    value: [r[3], r[4], r[5]],
                    dir: [r[0], r[1], r[2]],
                    exited: true,
                    reflection: (r[2] > 0.0) == (q.wi[2][qi] > 0.0),
                    specular: r[6] > 0.5,
                    cut: false,
                }
            } else {
                WalkOut {
                    value: if eval { [r[3], r[4], r[5]] } else { [0.0; 3] },
                    cut: r[7] >= limit,
                    ..WalkOut::default()
                }
            };
            wave.finish(idx[j], out);
        }
    }

    /// Pdfs of queries `qs` (a range of query indices) from density walks
    /// ([`PdfWalks`]: a pilot round, then the walks it sets), handed to
    /// `out` in query order. A round runs its query-walk pairs lane by lane,
    /// in order, so that one query of many walks fills the lanes as well as
    /// many queries of a few, and each query's sums run in walk order, as the
    /// scalar engine's do. `scratch` is working memory.
    pub(super) fn pdf_range(
        &self,
        q: &Queries,
        qs: std::ops::Range<usize>,
        walks: PdfWalks,
        kind: PdfKind,
        scratch: &mut PdfScratch,
        mut out: impl FnMut(usize, PdfEstimate),
    ) {
        let PdfScratch { pilot, fresh, jobs } = scratch;
        // The lanes' parameters where queries have sets (allocated only then).
        let sets = &mut (Vec::new(), Vec::new());
        let valid = |i: &usize| q.valid[qs.start + i];
        for s in [&mut *pilot, &mut *fresh] {
            s.clear();
            s.resize(qs.len(), DensitySums::default());
        }
        let p = walks.pilot();
        jobs.clear();
        jobs.reserve(qs.len());
        if p > 0 {
            jobs.extend((0..qs.len()).filter(valid).map(|i| (i as u32, 0..p)));
            self.pdf_round(q, qs.start, jobs, kind, pilot, sets);
        }
        jobs.clear();
        for i in (0..qs.len()).filter(valid) {
            let n = walks.after_pilot(&pilot[i]);
            jobs.push((i as u32, p..p.saturating_add(n)));
        }
        self.pdf_round(q, qs.start, jobs, kind, fresh, sets);
        for ((s, pilot), qi) in fresh.iter().zip(&*pilot).zip(qs) {
            let e = if q.valid[qi] {
                walks.finish(pilot, s, kind)
            } else {
                PdfEstimate::default()
            };
            out(qi, e);
        }
    }

    /// For each job `(i, ks)`, walks `ks` of query `first_query + i`, added
    /// to `sums[i]` in walk order. The jobs' pairs take the lanes in order,
    /// and lanes whose walks have ended take the next pairs while the
    /// others walk on (the density walks' lengths vary: a chunk run until
    /// its longest walk ends leaves lanes idle). Each lane still runs its
    /// pair's walk exactly ([`DensityWalk::start`]); walks end out of order,
    /// and [`InOrder`] adds their values in order. `sets` holds the lanes'
    /// gathered parameters where queries have sets.
    fn pdf_round(
        &self,
        q: &Queries,
        first_query: usize,
        jobs: &[PdfJob],
        kind: PdfKind,
        sums: &mut [DensitySums],
        (ifaces, media): &mut (Vec<InterfaceLanes<W>>, Vec<MediumLanes<W>>),
    ) {
        let mut pairs = jobs.iter().flat_map(|(i, ks)| ks.clone().map(|k| (*i, k)));
        // Per lane: its pair (query slot, walk index) and the pair's place
        // in the round (`IDLE`: none).
        const IDLE: u64 = u64::MAX;
        let (mut slot, mut index) = ([0u32; MAX_LANES], [0u64; MAX_LANES]);
        let mut place = [IDLE; MAX_LANES];
        let mut in_order = InOrder::new();
        let mut rng = LaneRng::<W>::from_states(|_| [0; 4]);
        let mut lanes: Option<WalkLanes<W>> = None;
        loop {
            let ended = !lanes.as_ref().map_or(0, |w| W::bitmask(w.alive));
            for j in (0..W::LANES).filter(|&j| ended & (1 << j) != 0) {
                if let (Some(w), true) = (&lanes, place[j] != IDLE) {
                    sums[slot[j] as usize].count_cut(w.cut.lane(j));
                    in_order.hand_in(place[j], slot[j], w.p.lane(j), sums);
                    place[j] = IDLE;
                }
            }
            // Idle lanes take the next pairs, once they are half the lanes
            // (starting walks has a cost of its own: the lanes' goals, their
            // random states).
            let mut fresh = 0u32;
            if (ended & lane_bits(W::LANES)).count_ones() as usize * 2 >= W::LANES {
                for j in (0..W::LANES).filter(|&j| ended & (1 << j) != 0) {
                    let Some((i, k)) = in_order.has_room().then(|| pairs.next()).flatten() else {
                        break;
                    };
                    (slot[j], index[j], place[j]) = (i, k, in_order.take());
                    fresh |= 1 << j;
                }
            }
            if fresh == 0 && lanes.as_ref().is_none_or(|w| !w.alive.any()) {
                return;
            }
            let ids: [u32; MAX_LANES] = std::array::from_fn(|j| first_query as u32 + slot[j]);
            let lq = &ids[..W::LANES];
            if fresh != 0 {
                if let Some(sets) = q.lane_sets(W::LANES, |j| lq[j]) {
                    // The lanes gather their sets' numbers.
                    sets.ifaces_into(&self.ifaces, ifaces);
                    sets.media_into(&self.media, media);
                }
            }
            let walk = DensityWalk {
                ifaces: if q.varying { ifaces } else { &self.ifaces },
                media: if q.varying { media } else { &self.media },
                settings: &self.settings,
                max_events: kind.max_events(),
            };
            if fresh != 0 {
                let g = |col: &[f32]| W::gather(col, lq);
                let wi = V3::new(g(&q.wi[0]), g(&q.wi[1]), g(&q.wi[2]));
                let wo = V3::new(g(&q.wo[0]), g(&q.wo[1]), g(&q.wo[2]));
                rng = LaneRng::from_states(|j| {
                    if fresh & (1 << j) != 0 {
                        seed_state_from(q.prefix[lq[j] as usize], index[j], Stream::Pdf)
                    } else {
                        rng.lane_state(j)
                    }
                });
                let m = W::mask_from_bitmask(fresh);
                match &mut lanes {
                    None => lanes = Some(walk.begin(wi, wo, m, |m| rng.uniform(m))),
                    Some(w) => walk.start(w, wi, wo, m, |m| rng.uniform(m)),
                }
            }
            if let Some(w) = &mut lanes {
                walk.step(w, |m| rng.uniform(m));
            }
        }
    }
}

/// How many of a pdf round's walks may have ended ahead of the first that
/// has not ([`Wavefront::pdf_round`]).
const PDF_WINDOW: usize = 256;

/// A pdf round's walk values, which end out of order, added to their
/// queries' sums in the order of their places in the round (the scalar
/// engine's order, so that the sums agree bit for bit).
struct InOrder {
    /// Per place modulo [`PDF_WINDOW`]: the walk's query slot, its value,
    /// whether it has ended.
    window: [(u32, f64, bool); PDF_WINDOW],
    /// Places handed out, and places added.
    taken: u64,
    added: u64,
}

impl InOrder {
    fn new() -> Self {
        InOrder {
            window: [(0, 0.0, false); PDF_WINDOW],
            taken: 0,
            added: 0,
        }
    }

    /// Whether another walk may start: the window holds every place from
    /// the first not added.
    fn has_room(&self) -> bool {
        self.taken < self.added + PDF_WINDOW as u64
    }

    /// The next place.
    fn take(&mut self) -> u64 {
        self.taken += 1;
        self.taken - 1
    }

    /// The value `p` of the walk at `place`, of query slot `i`; adds every
    /// value now in order to `sums`.
    fn hand_in(&mut self, place: u64, i: u32, p: f64, sums: &mut [DensitySums]) {
        let at = |place: u64| (place % PDF_WINDOW as u64) as usize;
        self.window[at(place)] = (i, p, true);
        while let (i, p, true) = self.window[at(self.added)] {
            sums[i as usize].push(p);
            self.window[at(self.added)].2 = false;
            self.added += 1;
        }
    }
}

/// A pdf round's job: walks `ks` of the `i`th query of a range.
type PdfJob = (u32, std::ops::Range<u64>);

/// A pdf call's working memory: each query's sums of its pilot walks and of
/// its fresh walks, and a round's jobs.
#[derive(Default)]
pub(crate) struct PdfScratch {
    pilot: Vec<DensitySums>,
    fresh: Vec<DensitySums>,
    jobs: Vec<PdfJob>,
}

/// Lanes `0..n` set.
fn lane_bits(n: usize) -> u32 {
    if n >= 32 {
        u32::MAX
    } else {
        (1u32 << n) - 1
    }
}

/// Lanes whose direction `d` heads for exit interface `e` (0: the top).
#[inline(always)]
fn toward<W: Wide>(d: V3<W>, e: usize) -> W::Mask {
    toward_exit(d, W::Mask::splat(e == 0))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Walks that end out of order reach their sums in the order of their
    /// places (values whose sum depends on the order show it), and no walk
    /// starts past the window.
    #[test]
    fn in_order_adds_in_place_order_within_the_window() {
        let value = |place: u64| {
            if place % 3 == 0 {
                1e16
            } else {
                1.0 + place as f64
            }
        };
        let slot = |place: u64| (place % 2) as u32;
        let mut want = [DensitySums::default(); 2];
        for place in 0..PDF_WINDOW as u64 {
            want[slot(place) as usize].push(value(place));
        }
        let mut got = [DensitySums::default(); 2];
        let mut w = InOrder::new();
        let places: Vec<u64> = (0..PDF_WINDOW).map(|_| w.take()).collect();
        assert!(!w.has_room());
        // The first place ends last: nothing is added before it.
        for &place in places.iter().skip(1).rev() {
            w.hand_in(place, slot(place), value(place), &mut got);
        }
        assert_eq!(got, [DensitySums::default(); 2]);
        assert!(!w.has_room());
        w.hand_in(0, slot(0), value(0), &mut got);
        assert_eq!(got, want);
        assert!(w.has_room());
        assert_eq!(w.take(), PDF_WINDOW as u64);
    }
}
