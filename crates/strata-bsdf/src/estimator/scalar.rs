//! The scalar reference: one walk at a time, plain code, early returns.
//!
//! Generic over a one-lane number `S`: `f32` (the reference the wavefront
//! engine is held to) and `f64` (the accuracy oracle of the stability checks).
//! Every step of a walk is a shared one of [`super::events`], and where it
//! goes next is [`super::layout`]'s, both called on one lane (masks are
//! `true`); this file only loops over them and returns early.
//!
//! Directions inside a walk are *travel* directions `d`; an interface is
//! sampled with `a = -d`, the direction the light arrives from. Random numbers
//! are drawn in a fixed number per event, so that lane `j` of the wavefront
//! engine replays walk `j` exactly:
//!
//! | event | uniforms |
//! |---|---|
//! | start of a walk (hero channel) | 1 |
//! | interface | 3 (lobe choice, two for the direction) |
//! | Russian roulette, after every event that does not leave the stack | 1 |
//! | free flight in a scattering layer | 1 |
//! | phase function at a collision | 2 (4 for diffuse SGGX flakes) |
//! | its value for next-event estimation, diffuse SGGX flakes only (before the phase sampling) | 2 |
//!
//! The adjoint chain of `eval` draws from its own stream: 3 per interface,
//! then 1 for Russian roulette per further segment. A fixed chain
//! (`events::chain_is_fixed`) uses none of its draws, so it is computed once
//! per query, from the stream of the query's first walk.

use super::accumulate::{BlockReducer, MeanVar};
use super::coat_lambertian::CoatLambertian;
use super::estimate::{Albedo, Estimate, WalkSample};
use super::events::{self, ChainLink, ChainStack, Flight};
use super::layout::{toward_exit, LayerKind, Layout, MediumLanes};
use super::params::SetTable;
use super::settings::Settings;
use super::terms::{self, Terms};
use crate::interface::InterfaceLanes;
use crate::lane::{Lane, Rgb, V3};
use crate::rng::{query_prefix, Stream, WalkRng};
use crate::stack::LayerStack;
use std::borrow::Cow;
use std::sync::Arc;

/// A one-lane number: `f32` or `f64`.
pub trait Scalar: Lane<Mask = bool> + PartialOrd {
    /// Runs `f` with this thread's buffer for adjoint chains (as the last
    /// query left it: the chain's builder clears it), so that an eval
    /// allocates nothing once the thread has run one. If the buffer is in
    /// use on this thread already, `f` gets a fresh one.
    fn with_chain<R>(f: impl FnOnce(&mut Vec<Link<Self>>) -> R) -> R;
}

macro_rules! chain_buffer {
    ($t:ty) => {
        impl Scalar for $t {
            fn with_chain<R>(f: impl FnOnce(&mut Vec<Link<Self>>) -> R) -> R {
                thread_local! {
                    static CHAIN: std::cell::RefCell<Vec<Link<$t>>> =
                        const { std::cell::RefCell::new(Vec::new()) };
                }
                // Taken out while `f` runs (a nested call finds it empty);
                // from a thread-local's destructor, a fresh one.
                let kept =
                    CHAIN.try_with(|c| c.try_borrow_mut().map(|mut v| std::mem::take(&mut *v)));
                let mut v = kept.ok().and_then(Result::ok).unwrap_or_default();
                let r = f(&mut v);
                let _ = CHAIN.try_with(|c| {
                    if let Ok(mut k) = c.try_borrow_mut() {
                        if k.capacity() < v.capacity() {
                            *k = v;
                        }
                    }
                });
                r
            }
        }
    };
}
chain_buffer!(f32);
chain_buffer!(f64);

pub use super::events::MAX_CHAIN;

/// A segment of the adjoint chain with where it connects from (the
/// wavefront's links, on one lane).
pub type Link<S> = ChainLink<S>;

/// How a walk left the stack.
#[derive(Clone, Copy, Debug)]
struct Exit<S: Lane> {
    d: V3<S>,
    beta: Rgb<S>,
    specular: bool,
}

/// Counts a walk's events (interface events and collisions), for the walk
/// length statistics of the stability reports and the walks the limit of
/// events cut.
#[derive(Clone, Copy, Debug, Default)]
struct Counter(u32);

/// The layered BSDF, one walk at a time.
#[derive(Clone, Debug)]
pub struct ScalarEngine<S: Scalar> {
    pub(super) stack: Arc<LayerStack>,
    pub(super) layout: Layout,
    pub(super) ifaces: Vec<InterfaceLanes<S>>,
    pub(super) media: Vec<MediumLanes<S>>,
    pub(super) settings: Settings,
    /// What the stack returns of the light that enters it
    /// ([`super::body_return::body_return`]), for the lobe pdf.
    pub(super) body: f64,
    /// With the control variate: the exact part of `f` carried by paths
    /// without a medium collision, which the walks then leave out.
    pub(super) cv: Option<CoatLambertian>,
}

/// [`ScalarEngine::eval_without_walks`] on `stack`'s shape and IORs with
/// `top` its top interface (a parameter set's).
#[allow(clippy::too_many_arguments)]
pub fn eval_without_walks<S: Scalar>(
    stack: &LayerStack,
    top: &InterfaceLanes<S>,
    coat: &CoatLambertian,
    wi: [f64; 3],
    wo: [f64; 3],
    n: u64,
    seed: u64,
    query: u64,
) -> Estimate {
    let Some(o) = super::orient(stack, wi, Some(wo)) else {
        return MeanVar::zeros(n).estimate();
    };
    let (wi, wo) = (v3::<S>(o.wi), v3::<S>(o.apply(wo)));
    let prefix = query_prefix(seed, query);
    let terms = terms::eval_terms(top, true, Some(coat), wi, wo, n, prefix);
    Estimate {
        samples: n,
        ..MeanVar::new().estimate_with(&terms)
    }
}

impl ScalarEngine<f32> {
    /// This engine with set `s` of `table` as its numbers (and `stack`, if
    /// given, as its stack: a set whose IORs are its own), for the calls
    /// that run a parameter set's query on the scalar engine.
    pub fn for_set(&self, stack: Option<&Arc<LayerStack>>, table: &SetTable, s: usize) -> Self {
        ScalarEngine {
            stack: stack.map_or_else(|| Arc::clone(&self.stack), Arc::clone),
            layout: self.layout,
            ifaces: table.ifaces_of(s).to_vec(),
            // A layer's greyness is the engine's, as in the wavefront's
            // lanes: a grey row on a chromatic shape runs chromatic flights
            // on both engines.
            media: (table.media_of(s).iter().zip(&self.media))
                .map(|(m, own)| MediumLanes {
                    grey: own.grey,
                    ..*m
                })
                .collect(),
            settings: self.settings,
            body: table.body(s),
            cv: table.cv(s).cloned(),
        }
    }
}

/// What `eval` adds to a walk: the connections to the viewer (method.md §4).
struct Connect<'a, S: Scalar> {
    wo: V3<S>,
    /// The exit interface.
    exit: usize,
    exit_rough: bool,
    /// The layer next to the exit, and the interface across it.
    region: Option<(usize, usize)>,
    chain: &'a [Link<S>],
    /// The control variate is on: leave out the contributions of paths
    /// without a medium collision (its exact part holds them).
    collided_only: bool,
    acc: Rgb<S>,
    /// The path continuations from medium collisions, summed apart from
    /// `acc` and added to it when the walk ends: the wavefront engine defers
    /// them until it has a chunk's worth, and this keeps the two engines'
    /// sums in the same order.
    from_collisions: Rgb<S>,
}

impl<S: Scalar> ScalarEngine<S> {
    /// Prepares `stack` for the scalar engine.
    pub fn new(stack: &LayerStack, settings: Settings) -> Self {
        let n = stack.len();
        ScalarEngine {
            stack: Arc::new(stack.clone()),
            layout: Layout::new(stack),
            ifaces: (0..n).map(|i| stack.interface_lanes::<S>(i)).collect(),
            media: (0..n.saturating_sub(1))
                .map(|l| MediumLanes::new(stack, l))
                .collect(),
            settings,
            body: super::body_return::body_return(stack),
            cv: None,
        }
    }

    /// Turns the control variate of `eval` on or off (off by default; it is
    /// what [`crate::Estimator::Auto`] uses). For a coat over a scattering
    /// (or any) layer over a Lambertian base
    /// ([`CoatLambertian::unscattered`]), `f = f₀ + f₊`: `f₀`, the paths
    /// that never collide in the medium, is added exactly (a smooth coat) or
    /// from its factorization's independent samples (a rough coat), and the walks
    /// estimate only `f₊` by leaving out every contribution of a path
    /// without a collision (next-event estimation and continuations from
    /// surface vertices before the walk's first collision: their segment to
    /// the exit crosses the layer by a transmittance). The walks themselves,
    /// their random numbers and their events are unchanged. Other stacks
    /// have no such `f₀`: for them this does nothing.
    pub fn with_control_variate(mut self, on: bool) -> Self {
        self.set_control_variate(on);
        self
    }

    /// [`ScalarEngine::with_control_variate`] in place.
    pub fn set_control_variate(&mut self, on: bool) {
        self.cv = on
            .then(|| CoatLambertian::unscattered(&self.stack, &self.settings))
            .flatten();
    }

    /// The control variate with a given `f₀` (what
    /// [`CoatLambertian::unscattered`] gives for this engine's stack, shared
    /// with other engines so that a rough coat's integral is computed once),
    /// or off.
    pub fn set_cv(&mut self, cv: Option<CoatLambertian>) {
        self.cv = cv;
    }

    /// [`ScalarEngine::set_cv`], by value.
    pub fn with_cv(mut self, cv: Option<CoatLambertian>) -> Self {
        self.set_cv(cv);
        self
    }

    /// `f` from what `coat` knows without walks, for a stack that is its
    /// whole BSDF ([`CoatLambertian::of`]): at the directions, precision and
    /// query streams of this engine's walks (as the control variate's part
    /// is added), with `n` samples of a rough coat's factorized part.
    pub fn eval_without_walks(
        &self,
        coat: &CoatLambertian,
        wi: [f64; 3],
        wo: [f64; 3],
        n: u64,
        seed: u64,
        query: u64,
    ) -> Estimate {
        eval_without_walks(&self.stack, &self.ifaces[0], coat, wi, wo, n, seed, query)
    }

    /// Makes the walks follow the adjoint of the tilted interfaces (the
    /// flow of importance; method.md §9): no effect on an untilted stack.
    pub fn set_adjoint(&mut self, on: bool) {
        for it in &mut self.ifaces {
            it.adjoint = on;
        }
    }

    /// Whether `eval` uses the control variate (it is on and the stack has
    /// the shape it needs).
    pub fn control_variate(&self) -> bool {
        self.cv.is_some()
    }

    /// The stack.
    pub fn stack(&self) -> &LayerStack {
        &self.stack
    }

    /// Its interfaces' numbers, top first.
    pub fn ifaces(&self) -> &[InterfaceLanes<S>] {
        &self.ifaces
    }

    /// The walk settings.
    pub fn settings(&self) -> Settings {
        self.settings
    }

    fn u(rng: &mut WalkRng) -> S {
        S::splat(rng.uniform() as f64)
    }

    /// Three uniforms for an interface event.
    pub(super) fn u3(rng: &mut WalkRng) -> (S, S, S) {
        let a = Self::u(rng);
        let b = Self::u(rng);
        (a, b, Self::u(rng))
    }

    /// Russian roulette; always draws one uniform. False if the walk ends.
    /// `scale`: [`events::survive_boosted`]'s (1: plain roulette).
    fn survive(&self, beta: &mut Rgb<S>, events: S, scale: S, rng: &mut WalkRng) -> bool {
        let u = Self::u(rng);
        if scale.gt(S::one()) {
            return events::survive_boosted(beta, events, u, true, &self.settings, scale);
        }
        events::survive(beta, events, u, true, &self.settings)
    }

    /// Whether a walk that made `length` events and ended with `exit`
    /// reached the limit of events inside the stack: the limit cut it.
    fn cut<T>(&self, exit: &Option<T>, length: Counter) -> bool {
        exit.is_none() && length.0 >= events::event_limit(self.settings.max_events)
    }

    /// Whether walks that leave out the control variate's paths (`cv`)
    /// boost their first collision ([`events::FIRST_COLLISION_BOOST`]): in
    /// a grey medium.
    fn boosting(&self, cv: bool) -> bool {
        cv && events::boosts_first_collision(&self.media)
    }

    /// One walk from `wi`. With `connect` it is a walk of the unidirectional
    /// estimator (the entrance transmits only, and every vertex connects to
    /// the viewer); without, it is the analog walk of `sample`. The steps are
    /// the shared ones of [`events`] on one lane: this function only orders
    /// them and returns where a wavefront lane would be masked off.
    fn walk(
        &self,
        wi: V3<S>,
        mut connect: Option<&mut Connect<'_, S>>,
        rng: &mut WalkRng,
        length: &mut Counter,
    ) -> Option<Exit<S>> {
        let mis = self.settings.mis;
        let start = events::WalkStart::<S>::new(Self::u(rng));
        let cv = connect.as_ref().is_some_and(|c| c.collided_only);
        let boosting = self.boosting(cv);
        let hero = start.hero;
        let (mut beta, mut ratios) = (start.beta, start.ratios);
        let (mut events, mut order) = (start.events, start.order);
        let mut specular = start.specular;
        let mut i = self.layout.outer_lanes::<S>(wi.z > S::zero());
        let mut a = wi;
        let mut first = true;
        loop {
            let iface = &self.ifaces[index(i)];
            let scoring = events::scoring(true, order, cv);
            // Next-event estimation from this surface vertex.
            if let Some(c) = connect.as_deref_mut().filter(|_| scoring) {
                for link in c.chain.iter().filter(|k| k.starts_at(i)) {
                    c.acc += beta * events::surface_link(iface, a, first, link, mis);
                }
            }
            // Scatter at the interface.
            let u = Self::u3(rng);
            let transmit_only = first && connect.is_some();
            let (s, alive) = events::interface_scatter(
                iface,
                a,
                u,
                transmit_only,
                true,
                &mut beta,
                &mut specular,
                &mut events,
            );
            if !alive {
                return None;
            }
            length.0 = events.lane(0) as u32;
            let d = s.b;
            let up = d.z > S::zero();
            let (l, out) = self.layout.enter(i, up);
            // Path continuation: the new direction reaches a rough exit.
            if let Some(c) = connect.as_deref_mut() {
                if scoring
                    && !out
                    && c.exit_rough
                    && c.region.map(|r| r.1) == Some(index(i))
                    && toward_exit(d, c.exit == 0)
                {
                    let (ex, m) = (&self.ifaces[c.exit], &self.media[index(l)]);
                    c.acc += events::surface_continuation(ex, m, c.wo, d, &s, beta, mis);
                }
            }
            first = false;
            if out {
                return Some(Exit { d, beta, specular });
            }
            let (_, rr) = events::collision_boost::<S>(boosting, order, beta);
            if !self.survive(&mut beta, events, rr, rng) {
                return None;
            }
            // Cross layer l until the walk reaches one of its interfaces.
            let m = &self.media[index(l)];
            let mut z = m.entry(up);
            let mut d = d;
            if m.kind != LayerKind::Scattering {
                if events::cross_inert(m, z, d, true, &mut beta) {
                    return None;
                }
            } else {
                loop {
                    let st = Flight {
                        z: &mut z,
                        beta: &mut beta,
                        ratios: &mut ratios,
                        order: &mut order,
                    };
                    let max_order = self.settings.max_scatter_order;
                    let boost =
                        boosting.then(|| events::collision_boost::<S>(true, *st.order, *st.beta).0);
                    let u = Self::u(rng);
                    let (col, pass) =
                        events::free_flight(m, st, d, hero, u, boost, true, max_order);
                    if !col {
                        if pass {
                            break;
                        }
                        return None;
                    }
                    // Next-event estimation from this collision.
                    let e = events::estimate_uniforms(m, || Self::u(rng));
                    if let Some(c) = connect.as_deref_mut() {
                        for link in c.chain.iter().filter(|k| k.crosses(l)) {
                            c.acc += beta * events::collision_link(m, z, d, link, e, mis);
                        }
                    }
                    let u = events::phase_uniforms(m, || Self::u(rng));
                    let dn = events::phase_scatter(m, d, u, true, &mut specular);
                    // Path continuation from the collision towards a rough exit.
                    if let Some(c) = connect.as_deref_mut() {
                        if c.exit_rough
                            && mis
                            && m.phase.exact()
                            && c.region.map(|r| r.0) == Some(index(l))
                            && toward_exit(dn, c.exit == 0)
                        {
                            let dz = events::depth_ahead(m, z, dn);
                            let ex = &self.ifaces[c.exit];
                            c.from_collisions +=
                                events::collision_continuation(ex, m, c.wo, d, dn, dz, beta);
                        }
                    }
                    events::after_collision(&mut d, &mut events, dn, true);
                    length.0 = events.lane(0) as u32;
                    let (_, rr) = events::collision_boost::<S>(boosting, order, beta);
                    if !self.survive(&mut beta, events, rr, rng) {
                        return None;
                    }
                }
            }
            i = self.layout.arrive(l, d.z > S::zero());
            a = -d;
        }
    }

    // ------------------------------------------------------------------ sample

    /// The analog random walk from `wi` (method.md §5). `None` if the walk was
    /// absorbed (or `wi` sees nothing). Directions are in the stack's frame.
    pub fn sample(&self, wi: [f64; 3], rng: &mut WalkRng) -> Option<WalkSample> {
        self.sample_counted(wi, rng).0
    }

    /// [`ScalarEngine::sample`], also returning the walk's number of events
    /// (interface events and medium collisions; 0 if no light enters).
    pub fn sample_counted(&self, wi: [f64; 3], rng: &mut WalkRng) -> (Option<WalkSample>, u32) {
        let mut n = Counter::default();
        let s = self.sample_inner(wi, rng, &mut n);
        (s, n.0)
    }

    fn sample_inner(&self, wi: [f64; 3], rng: &mut WalkRng, n: &mut Counter) -> Option<WalkSample> {
        let o = super::orient(&self.stack, wi, None)?;
        let wi_v = v3::<S>(o.wi);
        let ex = self.walk(wi_v, None, rng, n)?;
        let wo = o.apply([ex.d.x.lane(0), ex.d.y.lane(0), ex.d.z.lane(0)]);
        Some(WalkSample {
            wo: glam::Vec3::new(wo[0] as f32, wo[1] as f32, wo[2] as f32),
            weight: rgb_f64(ex.beta).map(|x| x as f32),
            reflection: (ex.d.z > S::zero()) == (wi_v.z > S::zero()),
            specular: ex.specular,
        })
    }

    /// Directional albedo from `n` walks of [`ScalarEngine::sample`]:
    /// reflected and transmitted fractions with standard errors.
    pub fn albedo(&self, wi: [f64; 3], n: u64, seed: u64, query: u64) -> Albedo {
        if super::orient(&self.stack, wi, None).is_none() {
            // No light enters: every walk gives zero (in constant time).
            let zero = MeanVar::zeros(n).estimate();
            return Albedo {
                reflected: zero,
                transmitted: zero,
            };
        }
        let mut r = BlockReducer::new();
        let mut t = BlockReducer::new();
        let prefix = query_prefix(seed, query);
        for k in 0..n {
            let mut rng = WalkRng::from_prefix(prefix, k, Stream::Walk);
            let (mut xr, mut xt) = ([0.0; 3], [0.0; 3]);
            let mut length = Counter::default();
            let s = self.sample_inner(wi, &mut rng, &mut length);
            let cut = self.cut(&s, length);
            if let Some(s) = s {
                let w = s.weight.map(|x| x as f64);
                if s.reflection {
                    xr = w;
                } else {
                    xt = w;
                }
            }
            r.push_walk(xr, cut);
            t.push_walk(xt, cut);
        }
        Albedo {
            reflected: r.finish().estimate(),
            transmitted: t.finish().estimate(),
        }
    }

    // -------------------------------------------------------------------- eval

    /// Samples the adjoint chain from `wo` through the exit interface `e`, and
    /// on through delta interfaces while the exit side is smooth.
    pub fn adjoint_chain(&self, wo: V3<S>, e: usize, rng: &mut WalkRng, out: &mut Vec<Link<S>>) {
        out.clear();
        if self.layout.n < 2 {
            return;
        }
        let media = |l: usize| Cow::Borrowed(&self.media[l]);
        let exit = &self.ifaces[e];
        let u = Self::u3(rng);
        let (first, ok) = events::first_link(&self.layout, exit, media, wo, e == 0, u);
        if !ok {
            return;
        }
        out.push(first);
        // Continue through delta interfaces: their vertices cannot connect.
        let stack = ChainStack {
            smooth: |j: S| self.stack.interface(index(j)).smooth,
            iface: |j: S| self.ifaces[index(j)],
            media,
        };
        events::extend_chain(
            &self.layout,
            &self.settings,
            first,
            exit.smooth,
            stack,
            |m| if m { Self::u(rng) } else { S::zero() },
            |link, m| {
                if m {
                    out.push(*link)
                }
            },
        );
    }

    /// The unidirectional estimator (method.md §4): mean of `n` walks plus the
    /// exact first-order term, with its standard error.
    pub fn eval(&self, wi: [f64; 3], wo: [f64; 3], n: u64, seed: u64, query: u64) -> Estimate {
        self.estimate(wi, wo, n, |f| self.eval_walks(wi, wo, n, seed, query, f))
    }

    /// Each walk's value of the unidirectional estimator, in sample order
    /// (without the first-order term and the control variate's exact part):
    /// for parity tests and diagnostics.
    pub fn eval_walk_values(
        &self,
        wi: [f64; 3],
        wo: [f64; 3],
        n: u64,
        seed: u64,
        query: u64,
    ) -> Vec<[f64; 3]> {
        walk_values(n, |f| self.eval_walks(wi, wo, n, seed, query, f))
    }

    /// The bidirectional estimator (method.md §4, [`super::bidir`]): mean
    /// of `n` walks plus the exact first-order term, with its standard
    /// error.
    pub fn eval_bidir(
        &self,
        wi: [f64; 3],
        wo: [f64; 3],
        n: u64,
        seed: u64,
        query: u64,
    ) -> Estimate {
        self.estimate(wi, wo, n, |f| {
            self.eval_bidir_walks(wi, wo, n, seed, query, f)
        })
    }

    /// Each walk's value of the bidirectional estimator, in sample order
    /// (without the first-order term): for parity tests.
    pub fn eval_bidir_walk_values(
        &self,
        wi: [f64; 3],
        wo: [f64; 3],
        n: u64,
        seed: u64,
        query: u64,
    ) -> Vec<[f64; 3]> {
        walk_values(n, |f| self.eval_bidir_walks(wi, wo, n, seed, query, f))
    }

    /// An estimate from `walks`, which hands each of `n` walk values to its
    /// argument and returns the terms added to their mean; the reduction of `n`
    /// zeros, in constant time, where no walk can contribute.
    fn estimate(
        &self,
        wi: [f64; 3],
        wo: [f64; 3],
        n: u64,
        walks: impl FnOnce(&mut dyn FnMut([f64; 3], bool)) -> Terms,
    ) -> Estimate {
        if super::orient(&self.stack, wi, Some(wo)).is_none() {
            return MeanVar::zeros(n).estimate();
        }
        let mut red = BlockReducer::new();
        let terms = walks(&mut |x, cut| red.push_walk(x, cut));
        red.finish().estimate_with(&terms)
    }

    /// Runs the `n` walks of an eval query, handing each walk's value to
    /// `f`; returns the terms added to their mean (first order, control
    /// variate).
    fn eval_walks(
        &self,
        wi: [f64; 3],
        wo: [f64; 3],
        n: u64,
        seed: u64,
        query: u64,
        f: &mut dyn FnMut([f64; 3], bool),
    ) -> Terms {
        let Some(o) = super::orient(&self.stack, wi, Some(wo)) else {
            (0..n).for_each(|_| f([0.0; 3], false));
            return Terms::default();
        };
        let wi = v3::<S>(o.wi);
        let wo = v3::<S>(o.apply(wo));
        let e_in = self.layout.outer(wi.z > S::zero());
        let e_out = self.layout.outer(wo.z > S::zero());
        // A fixed chain is the same for every walk: the first walk's serves all.
        let fixed = events::chain_is_fixed(&self.stack, &self.layout, e_out);
        let prefix = query_prefix(seed, query);
        S::with_chain(|chain| {
            for k in 0..n {
                if k == 0 || !fixed {
                    let mut rng_a = WalkRng::from_prefix(prefix, k, Stream::Adjoint);
                    self.adjoint_chain(wo, e_out, &mut rng_a, chain);
                }
                let mut c = Connect {
                    wo,
                    exit: e_out,
                    exit_rough: !self.stack.interface(e_out).smooth,
                    region: self.layout.exit_region(e_out),
                    chain,
                    collided_only: self.cv.is_some(),
                    acc: Rgb::zero(),
                    from_collisions: Rgb::zero(),
                };
                let mut rng = WalkRng::from_prefix(prefix, k, Stream::Walk);
                let mut length = Counter::default();
                let exit = self.walk(wi, Some(&mut c), &mut rng, &mut length);
                f(rgb_f64(c.acc + c.from_collisions), self.cut(&exit, length));
            }
        });
        // First-order term: the entrance alone, when it is also the exit.
        let entrance = &self.ifaces[e_in];
        let cv = self.cv.as_ref();
        terms::eval_terms(entrance, e_in == e_out, cv, wi, wo, n, prefix)
    }

    /// Runs the `n` bidirectional walks of an eval query, handing each
    /// walk's value to `f`; returns the first-order term.
    fn eval_bidir_walks(
        &self,
        wi: [f64; 3],
        wo: [f64; 3],
        n: u64,
        seed: u64,
        query: u64,
        f: &mut dyn FnMut([f64; 3], bool),
    ) -> Terms {
        let Some(o) = super::orient(&self.stack, wi, Some(wo)) else {
            (0..n).for_each(|_| f([0.0; 3], false));
            return Terms::default();
        };
        let wi = v3::<S>(o.wi);
        let wo = v3::<S>(o.apply(wo));
        let walk = super::bidir::BidirWalk::new(&self.ifaces, &self.media, &self.settings);
        let prefix = query_prefix(seed, query);
        super::bidir::with_kept_by_type(|buf: &mut super::bidir::Buffers<S>| {
            for k in 0..n {
                let mut rng = WalkRng::from_prefix(prefix, k, Stream::Bidir);
                let draw = |m: bool| if m { Self::u(&mut rng) } else { S::zero() };
                let (x, cut) = walk.run(wi, wo, buf, draw);
                f(rgb_f64(x), cut);
            }
        });
        let e_in = self.layout.outer(wi.z > S::zero());
        let e_out = self.layout.outer(wo.z > S::zero());
        terms::eval_terms(&self.ifaces[e_in], e_in == e_out, None, wi, wo, n, prefix)
    }
}

/// The `n` walk values `walks` hands to its argument, in order.
fn walk_values(
    n: u64,
    walks: impl FnOnce(&mut dyn FnMut([f64; 3], bool)) -> Terms,
) -> Vec<[f64; 3]> {
    let mut v = Vec::with_capacity(n as usize);
    walks(&mut |x, _| v.push(x));
    v
}

/// A layer or interface index carried as a lane value, as a `usize`.
#[inline(always)]
fn index<S: Lane>(i: S) -> usize {
    i.lane(0) as usize
}

/// A unit direction in the engine's precision (normalized in f64 first).
pub(super) fn v3<S: Scalar>(w: [f64; 3]) -> V3<S> {
    let l = (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt();
    V3::new(S::splat(w[0] / l), S::splat(w[1] / l), S::splat(w[2] / l))
}

pub(super) fn rgb_f64<S: Scalar>(c: Rgb<S>) -> [f64; 3] {
    [c.r.lane(0), c.g.lane(0), c.b.lane(0)]
}
