//! The engine's state and what its calls pass around: [`Wavefront`] (the
//! stack's lanes and the plan, built once per stack), the queries of a
//! call in columns ([`Queries`]), the units of work, the counters; and the
//! preparation of a call's queries.

use crate::estimator::accumulate::MeanVar;
use crate::estimator::coat_lambertian::CoatLambertian;
use crate::estimator::events;
use crate::estimator::layout::{LayerKind, Layout, MediumLanes};
use crate::estimator::params::{LaneSets, SetTable};
use crate::estimator::settings::Settings;
use crate::interface::InterfaceLanes;
use crate::lane::{DefaultWide, LaneMask, Wide, V3};
use crate::stack::LayerStack;
use std::borrow::Cow;
use std::sync::Arc;

/// Walk slots per wave, per lane of width.
const SLOTS_PER_LANE: usize = 64;

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
    pub(super) fn add(&mut self, o: &Stats) {
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
    /// Where `varying`: the call's parameter sets (held for the call,
    /// released by [`Queries::release`] so that their owner can reuse
    /// them)...
    pub table: Option<Arc<SetTable>>,
    /// ...and each query's.
    pub set: Vec<u32>,
}

impl Queries {
    /// The indices of the queries light can enter.
    pub(super) fn valid_ids(&self) -> Vec<u32> {
        let mut v = Vec::new();
        self.valid_ids_into(&mut v);
        v
    }

    /// [`Queries::valid_ids`] into `v` (cleared first).
    pub(super) fn valid_ids_into(&self, v: &mut Vec<u32>) {
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
        self.table = None;
    }

    /// The call's parameter sets (`varying` calls only).
    pub(crate) fn table(&self) -> &SetTable {
        self.table
            .as_deref()
            .expect("a varying call holds its sets")
    }

    /// Lets go of the call's parameter sets.
    pub(crate) fn release(&mut self) {
        self.table = None;
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
        let table = self.table.as_deref().filter(|_| self.varying)?;
        Some(LaneSets::new(table, lanes, |j| self.set[lq(j) as usize]))
    }
}

/// One query as given: `(wi, wo for eval, seeding key)`.
pub(super) type QuerySpec = ([f64; 3], Option<[f64; 3]>, u64);

/// Which parameters each query of a call has.
#[derive(Clone, Copy, Debug, Default)]
pub enum Sets<'a> {
    /// The engine's own (its stack's), for every query.
    #[default]
    Own,
    /// Query `k` has set `set[k]` of the table (of the engine's shape).
    Table(&'a Arc<SetTable>, &'a [u32]),
}

/// A validated `(wi, wo)` pair.
pub(crate) type Pair = ([f64; 3], [f64; 3]);

/// A run of consecutive samples of one query.
#[derive(Clone, Copy, Debug)]
pub(super) struct Unit {
    pub(super) query: u32,
    pub(super) first: u64,
    pub(super) count: u32,
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

/// The reduction of `samples` walks that all gave zero.
pub(super) fn zero_sum(samples: u64) -> MeanVar {
    MeanVar::zeros(samples)
}

/// The layered BSDF on SIMD lanes, prepared for one stack.
#[derive(Clone, Debug)]
pub struct Wavefront<W: Wide = DefaultWide> {
    pub(super) stack: LayerStack,
    pub(super) layout: Layout,
    pub(super) settings: Settings,
    pub(super) plan: Plan,
    /// Interfaces splatted over lanes.
    pub(super) ifaces: Vec<InterfaceLanes<W>>,
    /// Interfaces in f32, for lanes that sit at different interfaces.
    pub(super) table: Vec<InterfaceLanes<f32>>,
    /// Layers as the plan runs them.
    pub(super) media: Vec<MediumLanes<W>>,
    /// Layers as the stack has them (for the chain's transmittances).
    pub(super) media_spec: Vec<MediumLanes<W>>,
    /// The rough exits `(exit, layer next to it, interface across)`: where
    /// path continuations connect.
    pub(super) exits: Vec<(usize, usize, usize)>,
    /// The same engine on one lane, which finishes the last walks of a task
    /// (none for the one-lane engine itself).
    pub(super) tail: Option<Box<Wavefront<f32>>>,
    /// Interfaces where some eval walk may connect to the viewer (a chain
    /// link starts there): the others skip loading the chain.
    pub(super) connects_at: Vec<bool>,
    /// Layers where some eval walk may connect to the viewer.
    pub(super) connects_in: Vec<bool>,
    /// Per interface (true for outer ones only) as an exit: its adjoint chain
    /// is the same for every walk ([`events::chain_is_fixed`]), computed once
    /// per query in `prepare`.
    pub(super) fixed_chain: Vec<bool>,
    /// With the control variate: the exact part of `f` carried by paths
    /// without a medium collision, which the walks then leave out
    /// ([`Wavefront::with_control_variate`]).
    pub(super) cv: Option<CoatLambertian>,
    pub(super) slots: usize,
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

    pub(super) fn prepare(
        &self,
        mode: Mode,
        seed: u64,
        sets: Sets,
        pairs: &[QuerySpec],
    ) -> Queries {
        let mut q = Queries::default();
        self.prepare_into(&mut q, mode, seed, sets, pairs.len(), |k| pairs[k]);
        q
    }

    /// [`Wavefront::prepare`] of the `m` queries `spec(0..m)` (called once
    /// each, in order) into `q`, reusing its memory.
    pub(super) fn prepare_into(
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
            q.table = Some(Arc::clone(table));
            q.set.copy_from_slice(set);
        }
        for k in 0..m {
            let (wi, wo, key) = spec(k);
            q.prefix.push(crate::rng::query_prefix(seed, key));
            let Some(o) = crate::estimator::orient(&self.stack, wi, wo) else {
                continue;
            };
            let a = crate::estimator::scalar::v3::<f32>(o.wi);
            q.valid[k] = true;
            q.flipped[k] = o.flipped;
            q.wi[0][k] = a.x;
            q.wi[1][k] = a.y;
            q.wi[2][k] = a.z;
            q.e_in[k] = self.layout.outer(a.z > 0.0) as u16;
            if let Some(wo) = wo {
                let b = crate::estimator::scalar::v3::<f32>(o.apply(wo));
                q.wo[0][k] = b.x;
                q.wo[1][k] = b.y;
                q.wo[2][k] = b.z;
                let e = self.layout.outer(b.z > 0.0);
                q.e_out[k] = e as f32;
                if self.fixed_chain[e] && self.layout.n >= 2 {
                    q.fixed[k] = true;
                    q.link0[k] = match q.varying {
                        false => self.fixed_link(e, b),
                        true => fixed_link_of(q.table(), q.set[k] as usize, e, b),
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
