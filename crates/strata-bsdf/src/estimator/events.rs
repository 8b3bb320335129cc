//! The event sequence of a walk, written once over [`Lane`]: the scalar
//! reference calls it on one walk (`f32`, `f64`), the wavefront engine on
//! eight or sixteen walks at once, the density walk of `pdf` on either. The
//! engines differ only in scheduling (loops and early returns there; masks,
//! queues, compaction and record loads here), so a lane of the wavefront
//! replays a scalar walk operation for operation by construction rather than
//! by two copies kept in step.
//!
//! Two levels: the kernels (a connection, a continuation, a chain segment,
//! roulette), and the steps of a walk built on them (the interface event, a
//! free flight, a collision's parts, the adjoint chain, the deterministic
//! terms), each taking the lanes it acts on as a mask and updating only
//! those. Where a walk goes next is [`super::layout`]'s, also over lanes.
//!
//! Notation (method.md §4): a walk carries its throughput `beta`; an
//! [`Connection`] is one segment of the adjoint chain sampled from `wo`: light
//! leaving a vertex along `u` reaches the viewer with the factor `v`, which
//! already holds the exit interface's value, the cosine of `u` and the
//! inverse density of `u` (next-event estimation "from the other side").

use super::layout::{depth_to_boundary, flight_limit, move_depth, LayerKind, Layout, MediumLanes};
use super::settings::Settings;
pub use super::settings::{MAX_CAP, MAX_EVENTS};
use crate::interface::{BsdfSample, InterfaceLanes};
use crate::lane::{Lane, LaneMask, Rgb, V3};
use crate::medium;
use crate::phase::PhaseLanes;
use std::borrow::Cow;

/// One segment of the adjoint chain, per lane.
#[derive(Clone, Copy, Debug)]
pub struct Connection<L: Lane> {
    /// Travel direction from the connecting vertex towards the exit.
    pub u: V3<L>,
    /// What light leaving along `u` contributes to `f(wi, wo)` per unit
    /// `f_vertex · transmittance`.
    pub v: Rgb<L>,
    /// Density of `-u` given `wo` when the exit is rough, so that the walk's
    /// own continuation can be weighted against it (MIS); 0 where no other
    /// strategy produces this connection (smooth exit).
    pub mis_pdf: L,
}

/// A segment of the adjoint chain with where it connects from, per lane:
/// vertices in `layer` (medium collisions) and on interface `start` (surface
/// vertices), with the transmittance `t` of a full crossing of the layer
/// along `conn.u` (what a surface vertex's connection crosses).
#[derive(Clone, Copy, Debug)]
pub struct ChainLink<L: Lane> {
    /// The connection.
    pub conn: Connection<L>,
    /// Transmittance of the whole layer along `conn.u`.
    pub t: Rgb<L>,
    /// The layer the segment crosses.
    pub layer: L,
    /// The interface it starts from.
    pub start: L,
}

impl<L: Lane> ChainLink<L> {
    /// The lanes whose link starts at interface `i` (per lane): the surface
    /// vertices there connect through it.
    #[inline(always)]
    pub fn starts_at(&self, i: L) -> L::Mask {
        self.start.eq(i)
    }

    /// The lanes whose link crosses layer `l` (per lane): the collisions
    /// there connect through it.
    #[inline(always)]
    pub fn crosses(&self, l: L) -> L::Mask {
        self.layer.eq(l)
    }
}

/// The adjoint chain never exceeds this many segments: a guard against a
/// lossless loop of delta interfaces. It is a depth cap, so it is biased:
/// the light of chains longer than this is dropped. Each further segment
/// needs one more delta bounce, which the chain survives only with
/// probability F·(Russian roulette), so the dropped weight is at most the
/// product of those probabilities over 256 bounces (method.md §4).
pub const MAX_CHAIN: usize = 256;

/// Power heuristic (exponent 2) for a strategy of density `a` against `b`,
/// computed from the ratio so that huge densities cannot overflow. Zero when
/// both densities are zero.
#[inline]
pub fn power_heuristic<L: Lane>(a: L, b: L) -> L {
    let zero = L::zero();
    let hi = a.max(b);
    let lo = a.min(b);
    let ok = hi.gt(zero);
    let r = L::div_or_zero(lo, hi, ok & hi.is_finite());
    let r2 = r * r;
    let big = L::one() / (L::one() + r2);
    L::select(ok, L::select(a.ge(b), big, r2 * big), zero)
}

/// The lanes whose walk has made as many events as `s` allows: its next
/// roulette ends it, and it counts as cut.
#[inline]
pub fn reached_limit<L: Lane>(events: L, s: &Settings) -> L::Mask {
    at_limit(events, s.max_events)
}

/// The lanes whose `events` reach the limit `max_events`.
#[inline]
fn at_limit<L: Lane>(events: L, max_events: u32) -> L::Mask {
    events.ge(L::splat(event_limit(max_events) as f64))
}

/// `max_events` as the engines apply it: within `1..=MAX_CAP`.
#[inline]
pub fn event_limit(max_events: u32) -> u32 {
    max_events.clamp(1, MAX_CAP)
}

/// The vertices a bidirectional subpath may have under `max_events`
/// ([`Settings::max_events`]): `⌊√max_events⌋`, at least 2.
#[inline]
pub fn subpath_limit(max_events: u32) -> u32 {
    event_limit(max_events).isqrt().max(2)
}

/// Russian roulette after `rr_start` events below the throughput
/// `threshold`, and the limit of events `cap`. Returns the new throughput
/// and the lanes that survive. Survivors past `rr_start` continue with
/// probability `q = min(1, max channel of beta / threshold)` and are divided
/// by it, so the estimate stays unbiased.
#[inline]
pub fn roulette<L: Lane>(
    beta: Rgb<L>,
    events: L,
    u: L,
    rr_start: u32,
    threshold: f64,
    cap: u32,
) -> (Rgb<L>, L::Mask) {
    let capped = at_limit(events, cap);
    let early = events.lt(L::splat(rr_start as f64));
    let q = survival(beta, threshold);
    let survive = u.lt(q);
    let alive = !capped & (early | survive);
    let scaled = beta.scale(L::div_or_zero(L::one(), q, survive));
    (Rgb::select(early, beta, scaled), alive)
}

/// The probability that a walk of throughput `beta` survives a roulette
/// of threshold `threshold`: `min(1, max channel of beta / threshold)`.
#[inline]
pub fn survival<L: Lane>(beta: Rgb<L>, threshold: f64) -> L {
    (beta.max_channel() * L::splat(1.0 / threshold)).min(L::one())
}

/// The least throughput threshold a walk's roulette takes
/// ([`Settings::rr_threshold`]).
pub const MIN_RR_THRESHOLD: f64 = 1e-3;

/// [`Settings::rr_threshold`] as the roulette takes it: in
/// `[MIN_RR_THRESHOLD, 1]`, NaN as 1.
#[inline]
pub fn rr_threshold(s: &Settings) -> f64 {
    match s.rr_threshold {
        t if t.is_nan() => 1.0,
        t => t.clamp(MIN_RR_THRESHOLD, 1.0),
    }
}

/// [`roulette`] with a walk's settings.
#[inline]
pub fn walk_roulette<L: Lane>(beta: Rgb<L>, events: L, u: L, s: &Settings) -> (Rgb<L>, L::Mask) {
    roulette(beta, events, u, s.rr_start, rr_threshold(s), s.max_events)
}

/// The walk's hero channel (0, 1 or 2, as a lane value) for spectral MIS.
#[inline]
pub fn hero_channel<L: Lane>(u: L) -> L {
    (u * L::splat(3.0)).floor().min(L::splat(2.0))
}

/// Next-event estimation from a vertex on an interface: light arriving from
/// `a` leaves along the connection's `u`, crosses the layer with transmittance
/// `t`, and reaches the viewer. `first` lanes are at the entrance vertex,
/// whose own sampling is transmission-only (it matters for the MIS density).
/// Returns the contribution per unit throughput.
#[inline]
pub fn connect_surface<L: Lane>(
    iface: &InterfaceLanes<L>,
    a: V3<L>,
    first: L::Mask,
    c: &Connection<L>,
    t: Rgb<L>,
    mis: bool,
) -> Rgb<L> {
    let f = iface.eval(a, c.u);
    let w = if mis {
        let pv = iface.pdf(a, c.u, first);
        L::select(
            c.mis_pdf.gt(L::zero()),
            power_heuristic(c.mis_pdf, pv),
            L::one(),
        )
    } else {
        L::one()
    };
    f * t * c.v.scale(w)
}

/// Next-event estimation from a medium collision: the walk travelling along
/// `d` scatters into the connection's `u` (phase function `phase`, whose
/// value is estimated from the uniforms `e` where it has no closed form),
/// and crosses the rest of the layer with transmittance `t`. The
/// `1 / |u.z|` is the position-free Jacobian (method.md §3).
#[inline]
pub fn connect_collision<L: Lane>(
    phase: &PhaseLanes<L>,
    d: V3<L>,
    c: &Connection<L>,
    t: Rgb<L>,
    e: (L, L),
    mis: bool,
) -> Rgb<L> {
    let ph = phase.eval(d, c.u, e);
    // An estimated value is no density for the power heuristic: such a
    // collision connects by next-event estimation alone (and has no
    // continuation, `collision_continuation`).
    let w = if mis && phase.exact() {
        L::select(
            c.mis_pdf.gt(L::zero()),
            power_heuristic(c.mis_pdf, ph),
            L::one(),
        )
    } else {
        L::one()
    };
    let cos_u = c.u.z.abs();
    let ok = cos_u.gt(L::zero());
    (t * c.v).scale(L::div_or_zero(ph * w, cos_u, ok))
}

/// Path continuation: the walk's sampled direction `d` (density `pv`) heads
/// straight for the rough exit through transmittance `t`; evaluate the exit
/// towards `wo`. A delta vertex (`delta`) cannot be reached by next-event
/// estimation, so it takes weight 1; otherwise the power heuristic against
/// the exit's own density of `-d` (transmission only, as the chain samples it).
#[inline]
pub fn continue_to_exit<L: Lane>(
    exit: &InterfaceLanes<L>,
    wo: V3<L>,
    d: V3<L>,
    pv: L,
    delta: L::Mask,
    t: Rgb<L>,
    mis: bool,
) -> Rgb<L> {
    let fe = exit.eval(-d, wo);
    let w = if mis {
        let pe = exit.pdf(wo, -d, L::Mask::splat(true));
        L::select(delta, L::one(), power_heuristic(pv, pe))
    } else {
        L::select(delta, L::one(), L::zero())
    };
    (t * fe).scale(w)
}

/// Transmittance of a full crossing of layer `layer` (per lane) of the
/// `layers` layers `media(l)` along the direction `u`.
#[cfg_attr(feature = "profiling", inline(never))]
pub fn full_crossing<'a, L: Lane>(
    media: impl Fn(usize) -> Cow<'a, MediumLanes<L>>,
    layers: usize,
    layer: L,
    u: V3<L>,
) -> Rgb<L> {
    let mut t = Rgb::one();
    for l in 0..layers {
        let here = layer.eq(L::splat(l as f64));
        if here.any() {
            let m = media(l);
            t = Rgb::select(here, m.transmittance(m.thickness, u), t);
        }
    }
    t
}

/// The first link of the adjoint chain from `wo` through `exit` (the top
/// interface where `top`, else the bottom one, of a stack of two interfaces
/// or more; uniforms `u`), with the full-crossing transmittance of the exit's
/// layer (`media`: the stack's layers), and the lanes where it exists.
#[inline]
pub fn first_link<'a, L: Lane>(
    layout: &Layout,
    exit: &InterfaceLanes<L>,
    media: impl Fn(usize) -> Cow<'a, MediumLanes<L>>,
    wo: V3<L>,
    top: L::Mask,
    u: (L, L, L),
) -> (ChainLink<L>, L::Mask) {
    let (conn, ok) = chain_start(exit, wo, u);
    let (layer, start) = layout.exit_region_lanes(top);
    let t = full_crossing(media, layout.n - 1, layer, conn.u);
    let link = ChainLink {
        conn,
        t,
        layer,
        start,
    };
    (link, ok)
}

/// What [`extend_chain`] reads of the stack, per lane.
pub struct ChainStack<FS, FI, FM> {
    /// The lanes whose interface `j` (per lane) is smooth: only delta
    /// interfaces continue the chain.
    pub smooth: FS,
    /// Interface `j` (per lane), asked for once a lane continues there.
    pub iface: FI,
    /// The stack's layers ([`full_crossing`]).
    pub media: FM,
}

/// The adjoint chain past its first link `first`, on the lanes `alive` (a
/// smooth exit's, where the first link exists): on through delta interfaces,
/// a segment per interface, each after a roulette, until a rough interface,
/// the outside, an absorbed lane or [`MAX_CHAIN`] segments. `draw(m)` returns
/// a uniform for the lanes of `m` (and draws for no other), `push(link, m)`
/// takes each new segment of the lanes `m`. Both engines build their chains
/// here: the scalar one a walk at a time, the wavefront a chunk of new walks.
/// Not inlined: only smooth exits' chains go past their first link, and
/// inlined into the start of walks the loop changed how LLVM inlined that
/// stage into the task loop (docs/performance.md).
#[inline(never)]
pub fn extend_chain<'a, L: Lane, FS, FI, FM>(
    layout: &Layout,
    settings: &Settings,
    first: ChainLink<L>,
    alive: L::Mask,
    stack: ChainStack<FS, FI, FM>,
    mut draw: impl FnMut(L::Mask) -> L,
    mut push: impl FnMut(&ChainLink<L>, L::Mask),
) where
    FS: Fn(L) -> L::Mask,
    FI: Fn(L) -> InterfaceLanes<L>,
    FM: Fn(usize) -> Cow<'a, MediumLanes<L>>,
{
    let mut last = first;
    let mut alive = alive;
    let mut events = 1u32;
    let mut len = 1usize;
    while alive.any() && len < MAX_CHAIN {
        let j = L::select(alive, last.start, L::zero());
        let cont = alive & (stack.smooth)(j);
        if !cont.any() {
            break;
        }
        let iface = (stack.iface)(j);
        let u = (draw(cont), draw(cont), draw(cont));
        let (c2, ok) = chain_step(&iface, &last.conn, last.t, u);
        // Light reached interface j travelling along c2.u: it crossed the
        // layer it enters leaving j the other way, from that layer's far side.
        let up = c2.u.z.lt(L::zero());
        let (layer, out) = layout.enter(j, up);
        let start = layout.arrive(layer, up);
        let mut next = cont & ok & !out;
        events += 1;
        let ur = draw(next);
        let (conn, surv) = chain_roulette(c2, L::splat(events as f64), ur, settings);
        next = next & surv;
        let layer = L::select(next, layer, L::zero());
        last = ChainLink {
            conn,
            t: full_crossing(&stack.media, layout.n - 1, layer, conn.u),
            layer,
            start,
        };
        push(&last, next);
        alive = next;
        len += 1;
    }
}

/// Whether the adjoint chain from exit `e` (an outer interface: 0 or the
/// last) is the same for every walk: a smooth exit's refraction is
/// deterministic ([`chain_start`] draws its uniforms but no lane uses them),
/// and the chain stops at the interface across the exit's layer unless that
/// one is smooth too. Engines then compute the chain once per query instead
/// of sampling it per walk: the walks' values are the same, and a clear
/// coat's walks cost one stream less.
pub fn chain_is_fixed(stack: &crate::stack::LayerStack, layout: &Layout, e: usize) -> bool {
    stack.interface(e).smooth
        && layout
            .exit_region(e)
            .is_none_or(|(_, k)| !stack.interface(k).smooth)
}

/// The first segment of the adjoint chain: sample the exit interface from
/// `wo`, transmission only, into the stack. Returns the connection and the
/// lanes where one exists (none under total internal reflection).
#[inline]
pub fn chain_start<L: Lane>(
    exit: &InterfaceLanes<L>,
    wo: V3<L>,
    u: (L, L, L),
) -> (Connection<L>, L::Mask) {
    let s = exit.sample(wo, u.0, u.1, u.2, L::Mask::splat(true));
    let dp = s.b; // pointing into the stack
                  // Smooth exit: (1 - F) (n_o / n_in)², the delta lobe of f(dp → wo) times |cos dp|.
    let (n_o, n_in) = exit.sides(wo);
    let v_smooth = s.weight.scale((n_o / n_in).sqr() * exit.reverse(wo, dp));
    // Rough exit: f(dp → wo) |cos dp| / p(dp | wo).
    let rough_ok = s.valid & !exit.smooth;
    let v_rough = exit
        .eval(dp, wo)
        .scale(L::div_or_zero(dp.z.abs(), s.pdf, rough_ok));
    let conn = Connection {
        u: -dp,
        v: Rgb::select(exit.smooth, v_smooth, v_rough),
        mis_pdf: L::select(exit.smooth, L::zero(), s.pdf),
    };
    (conn, s.valid)
}

/// One more segment of the adjoint chain through a delta interface: light
/// reaching the previous segment's start along `prev.u` (after crossing the
/// layer with transmittance `t`) came from direction `b`, sampled at the
/// interface. Returns the new connection (travel direction `-b`) and the
/// lanes where the interface produced a direction.
#[inline]
pub fn chain_step<L: Lane>(
    iface: &InterfaceLanes<L>,
    prev: &Connection<L>,
    t: Rgb<L>,
    u: (L, L, L),
) -> (Connection<L>, L::Mask) {
    let a = prev.u;
    let s = iface.sample(a, u.0, u.1, u.2, L::Mask::splat(false));
    let b = s.b;
    let (n_a, n_b) = iface.sides(a);
    // The adjoint of a refraction carries the inverse radiance factor.
    let refracted = (a.z * b.z).lt(L::zero());
    let eta2 = L::select(refracted, (n_a / n_b).sqr(), L::one());
    let conn = Connection {
        u: -b,
        v: (prev.v * t * s.weight).scale(eta2 * iface.reverse(a, b)),
        mis_pdf: L::zero(),
    };
    (conn, s.valid)
}

// ---------------------------------------------------------------- the steps
//
// The event sequence of a walk, step by step, over lanes: both engines call
// these in the same order, the scalar reference on one lane (`active` is then
// `true`, and it returns early where a lane would be masked off), the
// wavefront on a chunk of walks (it keeps the masks, and decides which queue
// a lane joins next). What each step draws, and in which order, is fixed
// here, so a lane of the wavefront replays a scalar walk by construction.

/// A walk's state before its first event, per lane.
#[derive(Clone, Copy, Debug)]
pub struct WalkStart<L: Lane> {
    /// The hero channel of spectral MIS.
    pub hero: L,
    /// Throughput (1).
    pub beta: Rgb<L>,
    /// Spectral MIS channel ratios (1).
    pub ratios: Rgb<L>,
    /// Events so far (0).
    pub events: L,
    /// Collisions so far (0).
    pub order: L,
    /// Every event so far was a delta (true).
    pub specular: L::Mask,
}

impl<L: Lane> WalkStart<L> {
    /// The start of a walk whose first uniform is `u` (the hero channel's).
    #[inline(always)]
    pub fn new(u: L) -> Self {
        WalkStart {
            hero: hero_channel(u),
            beta: Rgb::one(),
            ratios: Rgb::one(),
            events: L::zero(),
            order: L::zero(),
            specular: L::Mask::splat(true),
        }
    }
}

/// How much more likely the control variate's walks make their first
/// collision in a grey medium ([`medium::free_flight_grey_boosted`]): they
/// score only paths that collide, which at small optical depth are a few
/// walks in a hundred; with the boost several times as many score, each with
/// a weight that much smaller. A power of two, so that scaling a throughput
/// by it and back is exact.
pub const FIRST_COLLISION_BOOST: f64 = 8.0;

/// The largest throughput at which a walk still boosts its first collision
/// ([`collision_boost`]).
pub const BOOST_CEILING: f64 = 2.0;

/// Whether the control variate's walks on a stack with these media boost
/// their first collision: its one medium is grey (a chromatic one samples
/// its flights by a hero channel, which the boost does not cover).
pub fn boosts_first_collision<L: Lane>(media: &[MediumLanes<L>]) -> bool {
    media.first().is_some_and(|m| m.grey)
}

/// The boost of a free flight of the lanes `m` and the scale of their
/// Russian roulette, where `boosting` (the control variate's walks in a
/// grey medium):
///
/// * before the first collision, while the throughput is at most
///   [`BOOST_CEILING`], [`FIRST_COLLISION_BOOST`] (1 elsewhere). A flight
///   that passes gains a weight of up to 2 ([`medium::MAX_BOOSTED`]);
///   boosting whatever the throughput would multiply those weights over the
///   bounces between base and coat, whose second moment can then grow
///   without bound (over a bright base under a coat that reflects much of
///   its light back). With the ceiling the throughput before the first
///   collision stays below twice it (interface events multiply it by at
///   most 1). The rule reads only the walk's past, so the estimate stays
///   unbiased.
/// * after it, [`FIRST_COLLISION_BOOST`] as the roulette's scale
///   ([`survive_boosted`]), so that the roulette does not end the walks the
///   boost made light (where the boost was clamped it keeps them a little
///   longer than needed: cost, not bias).
#[inline(always)]
pub fn collision_boost<L: Lane>(boosting: L::Mask, order: L, beta: Rgb<L>) -> (L, L) {
    let b = L::splat(FIRST_COLLISION_BOOST);
    let first = order.eq(L::zero());
    let light = beta.max_channel().le(L::splat(BOOST_CEILING));
    (
        L::select(boosting & first & light, b, L::one()),
        L::select(boosting & !first, b, L::one()),
    )
}

/// The lanes of `active` whose contributions to `eval` count: with the
/// control variate (`cv`), a walk scores nothing before its first collision
/// (`order` 0), whose paths the exact part holds (their segment to the exit
/// crosses the layer by a transmittance).
#[inline(always)]
pub fn scoring<L: Lane>(active: L::Mask, order: L, cv: L::Mask) -> L::Mask {
    active & (order.gt(L::zero()) | !cv)
}

/// The interface event: scatter the light arriving from `a` at `iface` with
/// the uniforms `u` (transmission only where `transmit_only`: the entrance of
/// an eval walk, whose reflection is the exact first-order term). Updates the
/// throughput, the specular flag and the event count of the lanes where a
/// direction was produced, and returns the sample and those lanes.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn interface_scatter<L: Lane>(
    iface: &InterfaceLanes<L>,
    a: V3<L>,
    u: (L, L, L),
    transmit_only: L::Mask,
    active: L::Mask,
    beta: &mut Rgb<L>,
    specular: &mut L::Mask,
    events: &mut L,
) -> (BsdfSample<L>, L::Mask) {
    let s = iface.sample(a, u.0, u.1, u.2, transmit_only);
    let alive = active & s.valid;
    *beta = Rgb::select(alive, *beta * s.weight, *beta);
    *specular = *specular & (s.delta | !alive);
    *events = L::select(alive, *events + L::one(), *events);
    (s, alive)
}

/// Russian roulette of the lanes `m` after an event that keeps them in the
/// stack ([`walk_roulette`] with the uniform `u`): updates their throughput
/// and returns those that survive.
#[inline(always)]
pub fn survive<L: Lane>(beta: &mut Rgb<L>, events: L, u: L, m: L::Mask, s: &Settings) -> L::Mask {
    let (b, alive) = walk_roulette(*beta, events, u, s);
    *beta = Rgb::select(m, b, *beta);
    m & alive
}

/// [`survive`] deciding on the throughput times `scale` (≥ 1): a walk
/// whose throughput a boosted collision divided by the boost survives about
/// as the unboosted walk would ([`FIRST_COLLISION_BOOST`]). Any survival
/// probability keeps the estimate unbiased; this one keeps the walks the
/// boost made light. Out of line: only the control variate's walks run it.
#[inline(never)]
pub fn survive_boosted<L: Lane>(
    beta: &mut Rgb<L>,
    events: L,
    u: L,
    m: L::Mask,
    s: &Settings,
    scale: L,
) -> L::Mask {
    let scaled = beta.scale(scale);
    let (b, alive) = walk_roulette(scaled, events, u, s);
    let b = b.scale(L::div_or_zero(L::one(), scale, scale.gt(L::zero())));
    *beta = Rgb::select(m, b, *beta);
    m & alive
}

/// The path continuation of an interface event (contribution, with the
/// throughput `beta`): the walk left interface `k0`, across the rough exit's
/// layer `med`, along `d` (its sample `s`), straight towards the exit.
#[inline(always)]
pub fn surface_continuation<L: Lane>(
    exit: &InterfaceLanes<L>,
    med: &MediumLanes<L>,
    wo: V3<L>,
    d: V3<L>,
    s: &BsdfSample<L>,
    beta: Rgb<L>,
    mis: bool,
) -> Rgb<L> {
    let t = med.transmittance(med.thickness, d);
    beta * continue_to_exit(exit, wo, d, s.pdf, s.delta, t, mis)
}

/// Entering a layer that does not scatter (`med`: clear or absorbing) at
/// depth `z` along `d`: it is crossed at once, the throughput of the lanes
/// `m` taking its transmittance. Returns the lanes of `m` that travel exactly
/// sideways, which never arrive (their walks end).
#[inline(always)]
pub fn cross_inert<L: Lane>(
    med: &MediumLanes<L>,
    z: L,
    d: V3<L>,
    m: L::Mask,
    beta: &mut Rgb<L>,
) -> L::Mask {
    let mu = d.z.abs();
    let flat = m & mu.le(L::zero());
    if med.kind == LayerKind::Absorbing {
        let ok = m & !flat;
        let dz = depth_to_boundary(z, med.thickness, d.z.gt(L::zero()));
        *beta = Rgb::select(ok, *beta * med.transmittance(dz, d), *beta);
    }
    flat
}

/// The walk state a free flight updates.
pub struct Flight<'a, L: Lane> {
    /// Depth.
    pub z: &'a mut L,
    /// Throughput.
    pub beta: &'a mut Rgb<L>,
    /// Spectral MIS channel ratios.
    pub ratios: &'a mut Rgb<L>,
    /// Collisions so far.
    pub order: &'a mut L,
}

/// A free flight in scattering layer `med` from the walk's depth along `d`
/// (hero channel `hero`, uniform `u`), for the lanes `active`. Returns the
/// lanes that collide (moved to the collision's depth; a lane past the
/// optional scatter-order cap ends instead) and those that pass to the
/// layer's boundary. A direction exactly parallel to the layer collides (see
/// [`flight_limit`]); if it does not, it is in neither: its walk ends.
/// With `boost`, lanes whose boost is above 1 in a grey medium collide that
/// many times as often, with weights that compensate
/// ([`medium::free_flight_grey_boosted`]; ignored in a chromatic one);
/// `None` is the plain flight, with no work for the boost.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn free_flight<L: Lane>(
    med: &MediumLanes<L>,
    st: Flight<'_, L>,
    d: V3<L>,
    hero: L,
    u: L,
    boost: Option<L>,
    active: L::Mask,
    max_order: Option<u32>,
) -> (L::Mask, L::Mask) {
    let h = med.thickness;
    let mu = d.z.abs();
    let flat = active & mu.le(L::zero());
    let dz = depth_to_boundary(*st.z, h, d.z.gt(L::zero()));
    let sigma = med.sigma_along(d);
    let limit = flight_limit(dz, mu);
    let ff = match boost {
        Some(b) if med.grey => {
            medium::free_flight_grey_boosted(sigma.r, med.albedo, limit, u, *st.ratios, b)
        }
        _ => medium::sample_free_flight(sigma, med.albedo, med.grey, limit, hero, u, *st.ratios),
    };
    *st.beta = Rgb::select(active, *st.beta * ff.weight, *st.beta);
    *st.ratios = Rgb::select(active, ff.ratios, *st.ratios);
    let pass = active & !ff.collide & !flat;
    let mut col = active & ff.collide;
    *st.order = L::select(col, *st.order + L::one(), *st.order);
    if let Some(k) = max_order {
        col = col & !st.order.gt(L::splat(k as f64));
    }
    *st.z = L::select(col, move_depth(*st.z, d.z, ff.distance, h), *st.z);
    (col, pass)
}

/// Next-event estimation from the surface vertex on `iface` where light
/// arrives from `a` (at the entrance where `first`), through one link `k` of
/// the adjoint chain that starts there (per unit throughput): it crosses the
/// whole layer.
#[inline(always)]
pub fn surface_link<L: Lane>(
    iface: &InterfaceLanes<L>,
    a: V3<L>,
    first: L::Mask,
    k: &ChainLink<L>,
    mis: bool,
) -> Rgb<L> {
    connect_surface(iface, a, first, &k.conn, k.t, mis)
}

/// Next-event estimation from a collision at depth `z` in layer `med`
/// through one link `k` of the adjoint chain that crosses it (per unit
/// throughput): the transmittance of the rest of the layer along `k.conn.u`,
/// and the phase function from `d` (estimated from the collision's uniforms
/// `e` where it has no closed form: every link may share them, as each
/// link's term is unbiased on its own).
#[inline(always)]
pub fn collision_link<L: Lane>(
    med: &MediumLanes<L>,
    z: L,
    d: V3<L>,
    k: &ChainLink<L>,
    e: (L, L),
    mis: bool,
) -> Rgb<L> {
    let u = k.conn.u;
    let dz = depth_to_boundary(z, med.thickness, u.z.gt(L::zero()));
    let t = med.transmittance(dz, u);
    connect_collision(&med.phase, d, &k.conn, t, e, mis)
}

/// The uniforms a collision in `med` estimates its phase value with, for
/// its next-event estimations (none unless the phase needs them), drawn by
/// `draw`.
#[inline(always)]
pub fn estimate_uniforms<L: Lane>(med: &MediumLanes<L>, mut draw: impl FnMut() -> L) -> (L, L) {
    if med.phase.estimate_uniforms() > 0 {
        (draw(), draw())
    } else {
        (L::zero(), L::zero())
    }
}

/// The uniforms phase sampling in `med` takes (a fixed number per phase
/// kind), drawn by `draw`.
#[inline(always)]
pub fn phase_uniforms<L: Lane>(med: &MediumLanes<L>, mut draw: impl FnMut() -> L) -> [L; 4] {
    let n = med.phase.sample_uniforms();
    let mut u = [L::zero(); 4];
    for x in u.iter_mut().take(n) {
        *x = draw();
    }
    u
}

/// The collision's new direction (phase sampling with the uniforms `u`,
/// weight 1); the lanes that collided (`col`) are no longer specular.
#[inline(always)]
pub fn phase_scatter<L: Lane>(
    med: &MediumLanes<L>,
    d: V3<L>,
    u: [L; 4],
    col: L::Mask,
    specular: &mut L::Mask,
) -> V3<L> {
    *specular = *specular & !col;
    med.phase.sample(d, u)
}

/// Depth left, from the collision at depth `z`, to the side of layer `med`
/// that the new direction `dn` heads for: what the collision continuation
/// needs of the walk's position (the wavefront stores it with a deferred row).
#[inline(always)]
pub fn depth_ahead<L: Lane>(med: &MediumLanes<L>, z: L, dn: V3<L>) -> L {
    depth_to_boundary(z, med.thickness, dn.z.gt(L::zero()))
}

/// The collision continuation (contribution, with the throughput `beta`,
/// MIS on; only for a phase with a closed form, [`PhaseLanes::exact`]): the
/// walk scattered from `d` into `dn`, which heads straight for the rough
/// exit across `dz` of layer `med`; evaluate the exit towards `wo`, weighted
/// against the chain's density of `-dn`.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn collision_continuation<L: Lane>(
    exit: &InterfaceLanes<L>,
    med: &MediumLanes<L>,
    wo: V3<L>,
    d: V3<L>,
    dn: V3<L>,
    dz: L,
    beta: Rgb<L>,
) -> Rgb<L> {
    let t = med.transmittance(dz, dn);
    let pv = med.phase.eval(d, dn, (L::zero(), L::zero()));
    let no = L::Mask::splat(false);
    beta * continue_to_exit(exit, wo, dn, pv, no, t, true)
}

/// After a collision (lanes `col`): the walk travels along `dn` and counts
/// one more event.
#[inline(always)]
pub fn after_collision<L: Lane>(d: &mut V3<L>, events: &mut L, dn: V3<L>, col: L::Mask) {
    *d = V3::select(col, dn, *d);
    *events = L::select(col, *events + L::one(), *events);
}

/// One roulette of a further segment of the adjoint chain (the chain's
/// `events`-th, uniform `u`): the new connection's value and whether it
/// survives. The chain is never capped (its own guard is its length).
#[inline(always)]
pub fn chain_roulette<L: Lane>(
    c: Connection<L>,
    events: L,
    u: L,
    s: &Settings,
) -> (Connection<L>, L::Mask) {
    let (v, alive) = roulette(c.v, events, u, s.rr_start, 1.0, MAX_CAP);
    (Connection { v, ..c }, alive)
}
