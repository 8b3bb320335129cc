//! The SIMD wavefront engine: many walks advance together in lanes.
//!
//! The same estimators as the scalar reference (sample, unidirectional eval,
//! approximate pdf, albedo), over batches of queries:
//!
//! * **Waves.** A wave holds a fixed number of walk slots whose state lives in
//!   structure-of-arrays columns ([`walks::Walks`]). Each round, every live walk
//!   advances by one event. Walks are sorted into queues by where they are:
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
//!   engine (up to the rare rounding-induced branch flip; tested). Results are
//!   reduced per query in the canonical block order
//!   ([`crate::estimator::BlockReducer`]), so they do not depend on the thread
//!   count, the batch composition or the wave size.
//! * **Threads.** A batch is cut into tasks of whole blocks, independently of
//!   the thread count; rayon runs the tasks. Each task owns its wave: no shared
//!   mutable state, and memory bounded by the wave and task sizes.
//! * **Pay for what the stack uses** ([`Plan`]): clear and absorbing layers are
//!   crossed inside the interface stage (transmittance, never free flight),
//!   grey media skip spectral MIS, smooth interfaces skip microfacet code, and
//!   an interface runs only its own kind's code. [`Plan::General`] turns all of
//!   that off (every layer runs free flight, every interface all code paths):
//!   the unspecialized walk the benchmarks compare against.

mod stages;
pub mod walks;

use super::accumulate::{BlockReducer, MeanVar, BLOCK};
use super::layout::{LayerKind, Layout, MediumLanes};
use super::{Albedo, Estimate, Sample, Settings};
use crate::interface::InterfaceLanes;
use crate::lane::{F32x8, Wide, V3};
use crate::stack::LayerStack;
use rayon::prelude::*;
use walks::Walks;

/// The lane type of the wavefront engine: the one place the width is set.
pub type DefaultWide = F32x8;

/// Walk slots per wave, per lane of width.
const SLOTS_PER_LANE: usize = 128;

/// Walks per task: the unit of work a thread takes. Tasks are whole blocks.
const TASK_WALKS: u64 = 16 * BLOCK;

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
    /// Lanes available in those chunks (`chunks × LANES`).
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
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Mode {
    /// Unidirectional eval: walks connect to `wo`.
    Eval,
    /// Analog walks (sample, albedo).
    Sample,
}

/// The queries of a batch, oriented and in f32 columns.
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
}

/// One query as given: `(wi, wo for eval, seeding key)`.
type QuerySpec = ([f64; 3], Option<[f64; 3]>, u64);

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
}

thread_local! {
    /// Waves kept for reuse by this thread (a few, of the sizes last used).
    static WAVES: std::cell::RefCell<Vec<Walks>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// Runs `f` on a wave of `slots` slots, reusing one this thread kept.
fn with_wave<R>(slots: usize, f: impl FnOnce(&mut Walks) -> R) -> R {
    let kept = WAVES.with(|w| {
        let mut w = w.borrow_mut();
        let i = w.iter().position(|x| x.slots() == slots)?;
        Some(w.swap_remove(i))
    });
    let mut ws = kept.unwrap_or_else(|| Walks::new(slots));
    let r = f(&mut ws);
    WAVES.with(|w| {
        let mut w = w.borrow_mut();
        if w.len() >= 4 {
            w.remove(0);
        }
        w.push(ws);
    });
    r
}

/// The estimate of `samples` walks that all gave zero.
fn zero_estimate(samples: u64) -> Estimate {
    let mut r = BlockReducer::new();
    (0..samples).for_each(|_| r.push([0.0; 3]));
    r.finish().estimate()
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
    /// Interfaces where some eval walk may connect to the viewer (a chain
    /// link starts there): the others skip loading the chain.
    connects_at: Vec<bool>,
    /// Layers where some eval walk may connect to the viewer.
    connects_in: Vec<bool>,
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
            slots: SLOTS_PER_LANE * W::LANES,
        }
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

    fn prepare(&self, mode: Mode, seed: u64, pairs: &[QuerySpec]) -> Queries {
        let m = pairs.len();
        let f3 = || [vec![0.0f32; m], vec![0.0f32; m], vec![0.0f32; m]];
        let mut q = Queries {
            mode,
            prefix: Vec::with_capacity(m),
            valid: vec![false; m],
            flipped: vec![false; m],
            wi: f3(),
            wo: f3(),
            e_in: vec![0; m],
            e_out: vec![0.0; m],
        };
        for (k, &(wi, wo, key)) in pairs.iter().enumerate() {
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
                q.e_out[k] = self.layout.outer(b.z > 0.0) as f32;
            }
        }
        q
    }

    /// Runs `units` cut into tasks over rayon; returns every walk's output in
    /// unit order, and the counters.
    fn run(&self, queries: &Queries, units: &[Unit]) -> (Vec<WalkOut>, Stats) {
        // Tasks: consecutive units up to TASK_WALKS walks (independent of threads).
        let mut tasks: Vec<&[Unit]> = Vec::new();
        let mut start = 0;
        let mut walks = 0u64;
        for (k, u) in units.iter().enumerate() {
            if walks > 0 && walks + u.count as u64 > TASK_WALKS {
                tasks.push(&units[start..k]);
                start = k;
                walks = 0;
            }
            walks += u.count as u64;
        }
        if start < units.len() {
            tasks.push(&units[start..]);
        }
        // A wave no larger than the largest task (a single query needs few slots).
        let largest = tasks
            .iter()
            .map(|t| t.iter().map(|u| u.count as usize).sum::<usize>())
            .max()
            .unwrap_or(0);
        let slots = self
            .slots
            .min(largest.div_ceil(W::LANES) * W::LANES)
            .max(W::LANES);
        let results: Vec<(Vec<WalkOut>, Stats)> = tasks
            .par_iter()
            .map(|task| {
                with_wave(slots, |ws| {
                    let mut out = Vec::new();
                    let stats = self.run_task(queries, task, ws, &mut out);
                    (out, stats)
                })
            })
            .collect();
        let mut stats = Stats::default();
        let mut all = Vec::with_capacity(units.iter().map(|u| u.count as usize).sum());
        for (o, s) in results {
            all.extend(o);
            stats.add(&s);
        }
        (all, stats)
    }

    /// Units of whole blocks for `samples` walks of every query.
    fn block_units(queries: usize, samples: u64) -> Vec<Unit> {
        let mut units = Vec::new();
        for q in 0..queries {
            let mut k = 0;
            while k < samples {
                let c = BLOCK.min(samples - k);
                units.push(Unit {
                    query: q as u32,
                    first: k,
                    count: c as u32,
                });
                k += c;
            }
        }
        units
    }

    /// Reduces walk values per query in block order.
    fn reduce(
        units: &[Unit],
        outs: &[WalkOut],
        queries: usize,
        value: impl Fn(&WalkOut) -> [f64; 3],
    ) -> Vec<MeanVar> {
        let mut red = vec![BlockReducer::new(); queries];
        let mut at = 0;
        for u in units {
            let mut block = MeanVar::new();
            for o in &outs[at..at + u.count as usize] {
                block.push(value(o));
            }
            at += u.count as usize;
            red[u.query as usize].push_block(&block);
        }
        red.into_iter().map(|r| r.finish()).collect()
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
        let (queries, units, outs, stats) = self.eval_walks(pairs, samples, seed, keys);
        let sums = Self::reduce(&units, &outs, pairs.len(), |o| o.value.map(|x| x as f64));
        let est = (0..pairs.len())
            .map(|q| {
                if !queries.valid[q] {
                    return zero_estimate(samples);
                }
                let wi = V3::new(queries.wi[0][q], queries.wi[1][q], queries.wi[2][q]);
                let wo = V3::new(queries.wo[0][q], queries.wo[1][q], queries.wo[2][q]);
                let e_in = queries.e_in[q] as usize;
                // First-order term: the entrance alone, when it is also the exit.
                let direct = if e_in == queries.e_out[q] as usize {
                    super::scalar::rgb_f64(self.table[e_in].eval(wi, wo))
                } else {
                    [0.0; 3]
                };
                sums[q].estimate_plus(direct)
            })
            .collect();
        (est, stats)
    }

    /// Each walk's value of the unidirectional estimator (without the
    /// first-order term), query by query in sample order: for parity tests
    /// and diagnostics.
    pub fn eval_walk_values(
        &self,
        pairs: &[([f64; 3], [f64; 3])],
        samples: u64,
        seed: u64,
        keys: &[u64],
    ) -> Vec<Vec<[f64; 3]>> {
        let (queries, units, outs, _) = self.eval_walks(pairs, samples, seed, keys);
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
        let mut at = 0;
        for u in &units {
            for o in &outs[at..at + u.count as usize] {
                v[u.query as usize].push(o.value.map(|x| x as f64));
            }
            at += u.count as usize;
        }
        v
    }

    fn eval_walks(
        &self,
        pairs: &[([f64; 3], [f64; 3])],
        samples: u64,
        seed: u64,
        keys: &[u64],
    ) -> (Queries, Vec<Unit>, Vec<WalkOut>, Stats) {
        assert_eq!(pairs.len(), keys.len(), "one key per query");
        let spec: Vec<_> = pairs
            .iter()
            .zip(keys)
            .map(|(&(wi, wo), &k)| (wi, Some(wo), k))
            .collect();
        let queries = self.prepare(Mode::Eval, seed, &spec);
        let units: Vec<Unit> = Self::block_units(pairs.len(), samples)
            .into_iter()
            .filter(|u| queries.valid[u.query as usize])
            .collect();
        let (outs, stats) = self.run(&queries, &units);
        (queries, units, outs, stats)
    }

    /// Directional albedo of every incident direction, `samples` walks each.
    pub fn albedo_batch(
        &self,
        wis: &[[f64; 3]],
        samples: u64,
        seed: u64,
        keys: &[u64],
    ) -> (Vec<Albedo>, Stats) {
        assert_eq!(wis.len(), keys.len(), "one key per query");
        let spec: Vec<_> = wis.iter().zip(keys).map(|(&w, &k)| (w, None, k)).collect();
        let queries = self.prepare(Mode::Sample, seed, &spec);
        let units: Vec<Unit> = Self::block_units(wis.len(), samples)
            .into_iter()
            .filter(|u| queries.valid[u.query as usize])
            .collect();
        let (outs, stats) = self.run(&queries, &units);
        let pick = |refl: bool| {
            move |o: &WalkOut| {
                if o.exited && o.reflection == refl {
                    o.value.map(|x| x as f64)
                } else {
                    [0.0; 3]
                }
            }
        };
        let r = Self::reduce(&units, &outs, wis.len(), pick(true));
        let t = Self::reduce(&units, &outs, wis.len(), pick(false));
        let zero = || zero_estimate(samples);
        let res = (0..wis.len())
            .map(|q| {
                if queries.valid[q] {
                    Albedo {
                        reflected: r[q].estimate(),
                        transmitted: t[q].estimate(),
                    }
                } else {
                    Albedo {
                        reflected: zero(),
                        transmitted: zero(),
                    }
                }
            })
            .collect();
        (res, stats)
    }

    /// One analog walk per query: query `q` is light from `wis[q]`, seeded by
    /// `(seed, keys[q], sample_index[q])` (the scalar engine's stream).
    pub fn sample_batch(
        &self,
        wis: &[[f64; 3]],
        seed: u64,
        keys: &[u64],
        sample_index: &[u64],
    ) -> (Vec<Option<Sample>>, Stats) {
        assert_eq!(wis.len(), keys.len(), "one key per query");
        assert_eq!(wis.len(), sample_index.len(), "one sample index per query");
        let spec: Vec<_> = wis.iter().zip(keys).map(|(&w, &k)| (w, None, k)).collect();
        let queries = self.prepare(Mode::Sample, seed, &spec);
        let units: Vec<Unit> = (0..wis.len())
            .filter(|&q| queries.valid[q])
            .map(|q| Unit {
                query: q as u32,
                first: sample_index[q],
                count: 1,
            })
            .collect();
        let (outs, stats) = self.run(&queries, &units);
        let mut res = vec![None; wis.len()];
        for (u, o) in units.iter().zip(&outs) {
            let q = u.query as usize;
            if !o.exited {
                continue;
            }
            let mut d = o.dir;
            if queries.flipped[q] {
                d[2] = -d[2];
            }
            res[q] = Some(Sample {
                wo: glam::Vec3::from(d),
                weight: o.value,
                reflection: o.reflection,
                specular: o.specular,
            });
        }
        (res, stats)
    }

    /// The approximate pdf of every `(wi, wo)` pair (see [`crate::estimator::pdf`]),
    /// `samples` short walks each, one query-sample pair per lane.
    pub fn pdf_batch(
        &self,
        pairs: &[([f64; 3], [f64; 3])],
        samples: u32,
        seed: u64,
        keys: &[u64],
    ) -> Vec<f64> {
        assert_eq!(pairs.len(), keys.len(), "one key per query");
        let spec: Vec<_> = pairs
            .iter()
            .zip(keys)
            .map(|(&(wi, wo), &k)| (wi, Some(wo), k))
            .collect();
        let queries = self.prepare(Mode::Eval, seed, &spec);
        let chunk = 64usize;
        let idx: Vec<usize> = (0..pairs.len()).collect();
        idx.par_chunks(chunk)
            .flat_map_iter(|qs| self.pdf_queries(&queries, qs, samples))
            .collect()
    }
}
