//! The SIMD wavefront engine: many walks advance together in lanes.
//!
//! The same estimators as the scalar reference (sample, unidirectional eval,
//! approximate pdf, albedo), over batches of queries:
//!
//! * **Waves.** A wave holds a fixed number of walk slots whose state lives in
//!   structure-of-arrays columns ([`walks::Walks`]). Each round, every live walk
//!   advances by one event. Walks wait in queues by where they are:
//!   at interface `i`, or inside scattering layer `l`. A queue is processed in
//!   chunks of `W::LANES` walks, gathered into lanes, run through the shared
//!   event kernels ([`crate::estimator::events`], `interface`, `medium`) and
//!   scattered back. Every lane of a chunk sits at the same interface or layer,
//!   so the chunk's physics parameters are splatted constants.
//! * **Stream compaction.** Terminated walks leave their slot; the next round
//!   refills free slots with new walks (the next sample of the same query, or
//!   the next query), so queues stay full whatever the walk-length spread.
//!   [`Stats::occupancy`] measures the fraction of busy lanes.
//! * **Masks.** Partial chunks and finished lanes are masked; every kernel
//!   feeds inactive lanes safe values, so no lane produces a NaN.
//! * **Determinism.** Lane `j` draws from walk `j`'s own stream, seeded from
//!   `(seed, query, sample)` exactly as in the scalar engine, and consumes the
//!   same uniforms in the same order, so a walk gives the same value on either
//!   engine, bit for bit (tested on every walk). Results are
//!   reduced per query in the canonical block order
//!   ([`crate::estimator::BlockReducer`]), so they do not depend on the thread
//!   count, the batch composition or the wave size.
//! * **Threads.** A batch is cut into tasks of whole blocks, dealt in turn so
//!   that tasks cost alike whatever the order of the queries; rayon runs the
//!   tasks. Each task owns its wave: no shared mutable state, and memory
//!   bounded by the wave and task sizes. Which blocks share a task does not
//!   change any result. A serial call (one thread) runs its tasks in order
//!   on the calling thread.
//! * **Memory.** A thread keeps its waves, its tasks' queues and its calls'
//!   query columns and reducers between calls (grow-only, cleared per call),
//!   so that the `*_each` calls of a warm thread allocate nothing when they
//!   run serially (`tests/alloc_free.rs`). A call that finds its thread's
//!   buffers in use (re-entered) runs on fresh ones.
//! * **Pay for what the stack uses** ([`Plan`]): clear and absorbing layers are
//!   crossed inside the interface stage (transmittance, never free flight),
//!   grey media skip spectral MIS, smooth interfaces skip microfacet code, and
//!   an interface runs only its own kind's code. [`Plan::General`] turns all of
//!   that off (every layer runs free flight, every interface all code paths):
//!   the unspecialized walk the benchmarks compare against.

mod bidir;
mod deferred;
mod stages;
pub mod walks;

use super::accumulate::{BlockReducer, MeanVar, BLOCK};
use super::coat_lambertian::CoatLambertian;
use super::estimate::{Albedo, Estimate, WalkSample};
use super::events;
use super::layout::{LayerKind, Layout, MediumLanes};
use super::params::{LaneSets, SetTable};
use super::pdf::{PdfEstimate, PdfKind, PdfWalks};
use super::settings::Settings;
use super::terms;
use crate::interface::InterfaceLanes;
use crate::lane::{LaneMask, Wide, V3};
use crate::stack::LayerStack;
use stages::{PdfScratch, TaskBuffers};
use std::borrow::Cow;
use std::cell::RefCell;
use std::thread::LocalKey;
use walks::Walks;

pub use crate::lane::DefaultWide;

/// Walk slots per wave, per lane of width.
const SLOTS_PER_LANE: usize = 64;

/// Walks per task: the unit of work a thread takes. Tasks are whole blocks.
const TASK_WALKS: u64 = 32 * BLOCK;

/// A batch of at most this many walks (queries × walks per query) runs as
/// one task on the calling thread: handing work to another thread costs
/// more than such a batch takes (the criterion group `small` in
/// crates/strata-benches/benches/estimators.rs; docs/performance.md).
pub const SERIAL_WALKS: u64 = BLOCK;

/// How much the walk is specialized to the stack.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Plan {
    /// Skip every stage the stack does not need (the default).
    #[default]
    Specialized,
    /// Run every stage for every walk: free flight in every layer, all code
    /// paths at every interface, spectral MIS everywhere. Same results in
    /// expectation (tested); it exists to measure what specialization saves.
    General,
}

/// Counters of a run.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Stats {
    /// Walks run.
    pub walks: u64,
    /// Walk segments: one walk advancing by one event in one stage.
    pub segments: u64,
    /// Chunks processed.
    pub chunks: u64,
    /// Lanes available in those chunks (`LANES` per chunk, 1 for the walks
    /// a draining task finishes on one lane).
    pub lanes: u64,
}

impl Stats {
    /// Fraction of lanes that carried a walk.
    pub fn occupancy(&self) -> f64 {
        if self.lanes == 0 {
            0.0
        } else {
            self.segments as f64 / self.lanes as f64
        }
    }
    fn add(&mut self, o: &Stats) {
        self.walks += o.walks;
        self.segments += o.segments;
        self.chunks += o.chunks;
        self.lanes += o.lanes;
    }
}

/// What the walks of a batch compute.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) enum Mode {
    /// Unidirectional eval: walks connect to `wo`.
    Eval,
    /// Analog walks (sample, albedo); the mode of an empty [`Queries`].
    #[default]
    Sample,
}

/// The queries of a batch, oriented and in f32 columns.
#[derive(Default)]
pub(crate) struct Queries {
    pub mode: Mode,
    /// Seeding prefix per query (`rng::query_prefix(seed, key)`).
    pub prefix: Vec<u64>,
    /// Light can enter (else every walk of the query is zero).
    pub valid: Vec<bool>,
    /// Mirrored (two-sided opaque stack lit from below).
    pub flipped: Vec<bool>,
    /// Oriented incident direction.
    pub wi: [Vec<f32>; 3],
    /// Oriented outgoing direction (eval).
    pub wo: [Vec<f32>; 3],
    /// Entrance interface.
    pub e_in: Vec<u16>,
    /// Exit interface (eval), as a lane value.
    pub e_out: Vec<f32>,
    /// Eval: every walk's adjoint chain is the same ([`events::chain_is_fixed`]).
    pub fixed: Vec<bool>,
    /// Where `fixed`, that chain's one link: its twelve
    /// [`walks::LinkLanes::fields`], then 1 if it exists (0 under total
    /// internal reflection).
    pub link0: Vec<[f32; 16]>,
    /// The queries have parameter sets of their own (else the engine's).
    pub varying: bool,
    /// Where `varying`: the call's parameter sets...
    pub table: SetTable,
    /// ...and each query's.
    pub set: Vec<u32>,
}

impl Queries {
    /// The indices of the queries light can enter.
    fn valid_ids(&self) -> Vec<u32> {
        let mut v = Vec::new();
        self.valid_ids_into(&mut v);
        v
    }

    /// [`Queries::valid_ids`] into `v` (cleared first).
    fn valid_ids_into(&self, v: &mut Vec<u32>) {
        v.clear();
        v.extend((0..self.valid.len() as u32).filter(|&q| self.valid[q as usize]));
    }

    /// Empties the columns for `m` queries of `mode` (every query invalid
    /// until `prepare_into` fills it), keeping their memory.
    fn reset(&mut self, mode: Mode, m: usize) {
        fn refill<T: Clone>(v: &mut Vec<T>, m: usize, x: T) {
            v.clear();
            v.resize(m, x);
        }
        self.mode = mode;
        self.prefix.clear();
        self.prefix.reserve(m);
        refill(&mut self.valid, m, false);
        refill(&mut self.flipped, m, false);
        for c in self.wi.iter_mut().chain(&mut self.wo) {
            refill(c, m, 0.0);
        }
        refill(&mut self.e_in, m, 0);
        refill(&mut self.e_out, m, 0.0);
        refill(&mut self.fixed, m, false);
        refill(&mut self.link0, m, [0.0; 16]);
        refill(&mut self.set, m, 0);
        self.varying = false;
    }

    /// The sets of the lanes whose queries are `lq` (`None`: every query
    /// has the engine's own parameters). Inline: every event asks, and most
    /// calls have no sets.
    #[inline(always)]
    pub(crate) fn lane_sets(
        &self,
        lanes: usize,
        lq: impl Fn(usize) -> u32,
    ) -> Option<LaneSets<'_>> {
        self.varying
            .then(|| LaneSets::new(&self.table, lanes, |j| self.set[lq(j) as usize]))
    }
}

/// One query as given: `(wi, wo for eval, seeding key)`.
type QuerySpec = ([f64; 3], Option<[f64; 3]>, u64);

/// Which parameters each query of a call has.
#[derive(Clone, Copy, Debug, Default)]
pub enum Sets<'a> {
    /// The engine's own (its stack's), for every query.
    #[default]
    Own,
    /// Query `k` has set `set[k]` of the table (of the engine's shape).
    Table(&'a SetTable, &'a [u32]),
}

/// A validated `(wi, wo)` pair.
pub(crate) type Pair = ([f64; 3], [f64; 3]);

/// A run of consecutive samples of one query.
#[derive(Clone, Copy, Debug)]
struct Unit {
    query: u32,
    first: u64,
    count: u32,
}

/// What a finished walk leaves.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct WalkOut {
    /// Eval: the contribution. Sample: the weight (0 if absorbed).
    pub value: [f32; 3],
    /// Sample: the exit direction (oriented frame).
    pub dir: [f32; 3],
    /// Sample: the walk left the stack.
    pub exited: bool,
    /// Sample: it left on the entrance side.
    pub reflection: bool,
    /// Sample: every event was a delta.
    pub specular: bool,
    /// The walk reached the limit of events inside the stack: the limit
    /// ended it.
    pub cut: bool,
}

thread_local! {
    /// Waves kept for reuse by this thread (a few: one per call or task it
    /// runs at once, which work stealing can nest).
    static WAVES: RefCell<Vec<Walks>> = const { RefCell::new(Vec::new()) };
    /// The buffers of this thread's calls (query columns, reducers).
    static CALLS: RefCell<Option<CallBuffers>> = const { RefCell::new(None) };
    /// The buffers of the tasks this thread runs (units, walk outputs, queues).
    static TASKS: RefCell<Option<TaskScratch>> = const { RefCell::new(None) };
}

/// What a call keeps between calls on its thread.
#[derive(Default)]
struct CallBuffers {
    queries: Queries,
    valid: Vec<u32>,
    /// Sample: each query's sample index.
    index: Vec<u64>,
    red: Vec<BlockReducer>,
    red2: Vec<(BlockReducer, BlockReducer)>,
    /// Pdf: each query's sums of density walks, and a round's jobs.
    pdf: PdfScratch,
}

/// What a task keeps between tasks on its thread.
#[derive(Default)]
struct TaskScratch {
    ids: Vec<usize>,
    units: Vec<Unit>,
    out: Vec<WalkOut>,
    bufs: TaskBuffers,
}

/// Runs `f` on the buffers this thread keeps in `key`, taken out while `f`
/// runs: a call nested in `f` (work stealing, or a sink that calls the
/// engine) finds none and starts from empty ones, which it then keeps. A
/// call made while the thread's locals are torn down (from a thread-local's
/// destructor) runs on fresh buffers and keeps nothing.
pub(crate) fn with_kept<T: Default + 'static, R>(
    key: &'static LocalKey<RefCell<Option<T>>>,
    f: impl FnOnce(&mut T) -> R,
) -> R {
    let kept = key.try_with(|c| c.borrow_mut().take()).ok().flatten();
    let mut b = kept.unwrap_or_default();
    let r = f(&mut b);
    let _ = key.try_with(|c| *c.borrow_mut() = Some(b));
    r
}

/// Runs `f` on a wave of `slots` slots, reusing one this thread kept: the
/// smallest that holds `slots` without growing, else the largest (which
/// grows), so that a warm thread serves any batch up to its largest so far
/// without allocating. (Results do not depend on the wave.)
fn with_wave<R>(slots: usize, f: impl FnOnce(&mut Walks) -> R) -> R {
    // (`try_with`: from a thread-local's destructor, a fresh wave.)
    let kept = WAVES.try_with(|w| {
        let mut w = w.borrow_mut();
        let cap = |i: &usize| w[*i].capacity();
        let i = (0..w.len())
            .filter(|i| cap(i) >= slots)
            .min_by_key(cap)
            .or_else(|| (0..w.len()).max_by_key(cap))?;
        Some(w.swap_remove(i))
    });
    let mut ws = kept.ok().flatten().unwrap_or_else(|| Walks::new(slots));
    ws.set_slots(slots);
    let r = f(&mut ws);
    let _ = WAVES.try_with(|w| {
        let mut w = w.borrow_mut();
        if w.len() >= 4 {
            w.remove(0);
        }
        w.push(ws);
    });
    r
}

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

/// The reduction of `samples` walks that all gave zero.
fn zero_sum(samples: u64) -> MeanVar {
    MeanVar::zeros(samples)
}

/// The layered BSDF on SIMD lanes, prepared for one stack.
#[derive(Clone, Debug)]
pub struct Wavefront<W: Wide = DefaultWide> {
    stack: LayerStack,
    layout: Layout,
    settings: Settings,
    plan: Plan,
    /// Interfaces splatted over lanes.
    ifaces: Vec<InterfaceLanes<W>>,
    /// Interfaces in f32, for lanes that sit at different interfaces.
    table: Vec<InterfaceLanes<f32>>,
    /// Layers as the plan runs them.
    media: Vec<MediumLanes<W>>,
    /// Layers as the stack has them (for the chain's transmittances).
    media_spec: Vec<MediumLanes<W>>,
    /// The rough exits `(exit, layer next to it, interface across)`: where
    /// path continuations connect.
    exits: Vec<(usize, usize, usize)>,
    /// The same engine on one lane, which finishes the last walks of a task
    /// (none for the one-lane engine itself).
    tail: Option<Box<Wavefront<f32>>>,
    /// Interfaces where some eval walk may connect to the viewer (a chain
    /// link starts there): the others skip loading the chain.
    connects_at: Vec<bool>,
    /// Layers where some eval walk may connect to the viewer.
    connects_in: Vec<bool>,
    /// Per interface (true for outer ones only) as an exit: its adjoint chain
    /// is the same for every walk ([`events::chain_is_fixed`]), computed once
    /// per query in `prepare`.
    fixed_chain: Vec<bool>,
    /// With the control variate: the exact part of `f` carried by paths
    /// without a medium collision, which the walks then leave out
    /// ([`Wavefront::with_control_variate`]).
    cv: Option<CoatLambertian>,
    slots: usize,
}

impl<W: Wide> Wavefront<W> {
    /// Prepares `stack`: its feature set selects which stages run.
    pub fn new(stack: &LayerStack, settings: Settings, plan: Plan) -> Self {
        let n = stack.len();
        let general = plan == Plan::General;
        let ifaces = (0..n)
            .map(|i| InterfaceLanes {
                run_all: general,
                ..stack.interface_lanes::<W>(i)
            })
            .collect();
        let media = (0..n.saturating_sub(1))
            .map(|l| {
                let m = MediumLanes::<W>::new(stack, l);
                if general {
                    MediumLanes {
                        kind: LayerKind::Scattering,
                        grey: false,
                        ..m
                    }
                } else {
                    m
                }
            })
            .collect();
        let layout = Layout::new(stack);
        let mut exits = vec![0];
        if stack.transmissive() && n > 1 {
            exits.push(n - 1);
        }
        // Chain links start where the exit regions are; a smooth exit's chain
        // may continue anywhere.
        let chains = exits.iter().any(|&e| stack.interface(e).smooth);
        let mut connects_at = vec![chains; n];
        let mut connects_in = vec![chains; n.saturating_sub(1)];
        for &e in &exits {
            if let Some((l0, k0)) = layout.exit_region(e) {
                connects_at[k0] = true;
                connects_in[l0] = true;
            }
        }
        let exits = exits
            .into_iter()
            .filter(|&e| !stack.interface(e).smooth)
            .filter_map(|e| layout.exit_region(e).map(|(l0, k0)| (e, l0, k0)))
            .collect();
        Wavefront {
            fixed_chain: (0..n)
                .map(|e| (e == 0 || e == n - 1) && events::chain_is_fixed(stack, &layout, e))
                .collect(),
            tail: (W::LANES > 1).then(|| Box::new(Wavefront::<f32>::new(stack, settings, plan))),
            exits,
            connects_at,
            connects_in,
            stack: stack.clone(),
            layout: Layout::new(stack),
            settings,
            plan,
            ifaces,
            table: (0..n).map(|i| stack.interface_lanes::<f32>(i)).collect(),
            media,
            media_spec: (0..n.saturating_sub(1))
                .map(|l| MediumLanes::new(stack, l))
                .collect(),
            cv: None,
            slots: SLOTS_PER_LANE * W::LANES,
        }
    }

    /// Turns the control variate of eval on or off, as
    /// `ScalarEngine::with_control_variate` does (the same walks leave out
    /// the same contributions, so the two engines still agree walk by walk).
    pub fn with_control_variate(mut self, on: bool) -> Self {
        self.set_control_variate(on);
        self
    }

    /// Makes the walks follow the adjoint of the tilted interfaces, as
    /// `ScalarEngine::set_adjoint` does.
    pub fn set_adjoint(&mut self, on: bool) {
        for it in &mut self.ifaces {
            it.adjoint = on;
        }
        for it in &mut self.table {
            it.adjoint = on;
        }
        if let Some(t) = self.tail.as_mut() {
            t.set_adjoint(on);
        }
    }

    /// [`Wavefront::with_control_variate`] in place.
    pub fn set_control_variate(&mut self, on: bool) {
        self.cv = on
            .then(|| CoatLambertian::unscattered(&self.stack, &self.settings))
            .flatten();
        if let Some(t) = self.tail.as_mut() {
            t.set_control_variate(on);
        }
    }

    /// The control variate with a given `f₀`, as `ScalarEngine::set_cv`.
    pub fn set_cv(&mut self, cv: Option<CoatLambertian>) {
        if let Some(t) = self.tail.as_mut() {
            t.set_cv(cv.clone());
        }
        self.cv = cv;
    }

    /// [`Wavefront::set_cv`], by value.
    pub fn with_cv(mut self, cv: Option<CoatLambertian>) -> Self {
        self.set_cv(cv);
        self
    }

    /// Whether eval uses the control variate (it is on and the stack has the
    /// shape it needs).
    pub fn control_variate(&self) -> bool {
        self.cv.is_some()
    }

    /// Sets the number of walk slots per wave (rounded up to whole chunks).
    /// Results do not depend on it; occupancy and memory do.
    pub fn with_slots(mut self, slots: usize) -> Self {
        self.slots = slots.max(1).div_ceil(W::LANES) * W::LANES;
        self
    }

    /// The stack.
    pub fn stack(&self) -> &LayerStack {
        &self.stack
    }

    /// The plan.
    pub fn plan(&self) -> Plan {
        self.plan
    }

    /// The walk settings.
    pub fn settings(&self) -> Settings {
        self.settings
    }

    fn prepare(&self, mode: Mode, seed: u64, sets: Sets, pairs: &[QuerySpec]) -> Queries {
        let mut q = Queries::default();
        self.prepare_into(&mut q, mode, seed, sets, pairs.len(), |k| pairs[k]);
        q
    }

    /// [`Wavefront::prepare`] of the `m` queries `spec(0..m)` (called once
    /// each, in order) into `q`, reusing its memory.
    fn prepare_into(
        &self,
        q: &mut Queries,
        mode: Mode,
        seed: u64,
        sets: Sets,
        m: usize,
        mut spec: impl FnMut(usize) -> QuerySpec,
    ) {
        q.reset(mode, m);
        if let Sets::Table(table, set) = sets {
            assert_eq!(set.len(), m, "one set per query");
            q.varying = true;
            q.table.copy_from(table);
            q.set.copy_from_slice(set);
        }
        for k in 0..m {
            let (wi, wo, key) = spec(k);
            q.prefix.push(crate::rng::query_prefix(seed, key));
            let Some(o) = super::orient(&self.stack, wi, wo) else {
                continue;
            };
            let a = super::scalar::v3::<f32>(o.wi);
            q.valid[k] = true;
            q.flipped[k] = o.flipped;
            q.wi[0][k] = a.x;
            q.wi[1][k] = a.y;
            q.wi[2][k] = a.z;
            q.e_in[k] = self.layout.outer(a.z > 0.0) as u16;
            if let Some(wo) = wo {
                let b = super::scalar::v3::<f32>(o.apply(wo));
                q.wo[0][k] = b.x;
                q.wo[1][k] = b.y;
                q.wo[2][k] = b.z;
                let e = self.layout.outer(b.z > 0.0);
                q.e_out[k] = e as f32;
                if self.fixed_chain[e] && self.layout.n >= 2 {
                    q.fixed[k] = true;
                    q.link0[k] = match q.varying {
                        false => self.fixed_link(e, b),
                        true => fixed_link_of(&q.table, q.set[k] as usize, e, b),
                    };
                }
            }
        }
    }

    /// The one link of the fixed adjoint chain from exit `e` towards `wo`,
    /// as a row of [`Queries::link0`]: computed in lanes exactly as
    /// `launch_chain` would for each walk (its uniforms go unused).
    fn fixed_link(&self, e: usize, wo: V3<f32>) -> [f32; 16] {
        let s = |x: f32| W::splat(x as f64);
        let wo = V3::new(s(wo.x), s(wo.y), s(wo.z));
        let media = |l: usize| Cow::Borrowed(&self.media_spec[l]);
        link_row(&self.ifaces[e], media, self.layout.n, e, wo)
    }

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
    fn block_unit(valid: &[u32], samples: u64) -> (usize, impl Fn(usize) -> Unit + Sync + '_) {
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
        with_kept(&CALLS, |c| {
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
    fn estimate_with_terms(&self, queries: &Queries, q: usize, sum: MeanVar, cv: bool) -> Estimate {
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
                (queries.table.iface(s, e_in), queries.table.cv(s))
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
        with_kept(&CALLS, |c| {
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
        with_kept(&CALLS, |c| {
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
                        super::orient::turned_over(&self.stack, o.dir)
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
        with_kept(&CALLS, |c| {
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

/// The one link of a fixed adjoint chain from exit `e` towards `wo` on
/// lanes of `W`, as a row of [`Queries::link0`] (lane 0's; every lane's is
/// the same).
fn link_row<'a, W: Wide>(
    exit: &InterfaceLanes<W>,
    media: impl Fn(usize) -> Cow<'a, MediumLanes<W>>,
    n: usize,
    e: usize,
    wo: V3<W>,
) -> [f32; 16] {
    let top = W::Mask::splat(e == 0);
    let u = (W::zero(), W::zero(), W::zero());
    let (l, ok) = events::first_link(&Layout { n }, exit, media, wo, top, u);
    let f = l.fields();
    let mut row = [0.0f32; 16];
    for (r, x) in row.iter_mut().zip(f) {
        *r = x.lane(0) as f32;
    }
    row[12] = if ok.lane(0) { 1.0 } else { 0.0 };
    row
}

/// [`Wavefront::fixed_link`] for a query of parameter set `s` of `table`,
/// on one lane (which gives every wider lane's numbers).
fn fixed_link_of(table: &SetTable, s: usize, e: usize, wo: V3<f32>) -> [f32; 16] {
    let media = |l: usize| Cow::Borrowed(table.medium(s, l));
    link_row(table.iface(s, e), media, table.interfaces(), e, wo)
}
