//! The density of `sample()`'s directions, estimated by walks (method.md §6).
//!
//! `sample(wi)` runs a Markov chain over (interface or depth, direction) and
//! returns the direction of the event that leaves the stack. The density of
//! `wo` is therefore a sum over the chain's *non-delta* vertices `v` (rough
//! interface events and medium collisions) of the density that `v`'s sampled
//! direction is the one whose delta-only continuation leaves along `wo`:
//!
//! ```text
//! p(wo) = E[ Σ_v  p_v(u) · J(u → wo) · P_exit(v, u) ]
//! ```
//!
//! * `p_v(u)`: the vertex's sampling density of the travel direction `u`.
//! * `u`: the direction in the vertex's layer that all smooth interfaces map
//!   to the *target*: `wo` itself through a smooth exit, or, through a rough
//!   exit, a direction just inside it sampled from `wo` by the exit's
//!   refraction lobe (tangential momentum `n sin θ` is conserved through a
//!   stack of parallel smooth interfaces, reflections included); one heading
//!   up and one heading down per vertex, where it exists.
//! * `J = (n_t / n_l)² |cos θ_t| / |cos θ_u|`, the solid-angle Jacobian of
//!   that mapping.
//! * `P_exit`: the probability that `sample()`'s walk, leaving `v` along `u`,
//!   meets only delta events and then leaves along `wo` (smooth exit) or
//!   arrives at the rough exit. It is estimated without bias by one
//!   continuation (`DensityWalk::delta_exit`) that samples the
//!   reflect-or-transmit choices and takes everything else in expectation: no
//!   collision across a scattering layer (with the walk's hero channel, as
//!   `sample()` samples it), Russian roulette's survival.
//!
//! A rough exit is reached two ways, combined by the power heuristic as
//! `eval` combines its next-event estimation and path continuation: by the
//! connection above (the sampled target's density `q`, the exit's density
//! `p_e` of `wo` for it: the vertex adds `p_v J P_exit p_e / q`), and by the
//! walk's own arrival, which adds `p_e` for its arrival direction; the walk
//! carries the density of its direction since its last non-delta vertex
//! through delta events (`rho`) for that weight. The exit's own vertex, met
//! from outside (the entrance reflection), adds its density of `wo` with
//! weight 1.
//!
//! A smooth exit over a rough interface (a clear coat over a rough base) has
//! the same two ways one interface deeper: the rough interface `k` across
//! the exit's layer scatters light into the one direction `u_w` that leaves
//! along `wo`. The walk's own visits to `k` evaluate `k`'s density of `u_w`
//! at their arrival direction (a peaked lobe at a random argument: heavy
//! tailed); the *inner connection* samples the arrival at `k` from `u_w` by
//! `k`'s own lobe and connects the vertices below (or above) to it, so the
//! vertex's density is evaluated instead; the power heuristic combines them.
//!
//! A collision reached straight from the walk's previous non-delta vertex
//! `v` in the same layer has two ways too. The walk's own collision `x`
//! adds `p(d → u)` at its arrival `d`: a peaked phase function at a random
//! argument, heavy tailed like `k`'s lobe above. The *medium connection*
//! makes `x` from the exit's side instead: it samples `x`'s arrival `d'`
//! by the phase function from the candidate `u` that heads for the exit
//! (for a phase function of the angle alone, `p(d' → u)` is that
//! density), and `x`'s depth backwards along `u` by the collision density
//! `C` of a flight entering where `u` leaves the layer; then `v`'s density
//! of `d'` times the flight's density of reaching `x` (`P`) replaces the
//! phase value. The two are weighted by the balance of squares of their
//! densities (`K = C p / P`; `P` leaves out the roulette after `v`, on both
//! sides, so the weights still sum to 1). It runs where the phase function
//! is peaked enough to pay for it (`PEAKED`).
//!
//! The two sampled targets (the rough exit's and `k`'s arrival) are drawn
//! once per walk, before its first event, and every vertex of the walk
//! connects to them: each vertex's term is still an unbiased estimate (the
//! targets are independent of the path); fresh targets at every vertex
//! would give each term its own (less correlated terms), but cost more
//! than their lower variance gives back (docs/performance.md, *The density
//! walks' levers*).
//!
//! The chain itself is `sample()`'s: the same kernels, hero channel, Russian
//! roulette and settings, on its own random stream. So each walk's sum is an
//! unbiased estimate of the density of `sample()` (the "unbiased, slow" pdf);
//! averaged over walks (as many as a pilot round says, its mean blended in),
//! bounded in length and mixed with a small uniform density it is the
//! approximate pdf `sample()` returns ([`super::pdf`]).
//!
//! The walk is written once over lanes: the scalar engine runs it on one lane,
//! the wavefront on one query-walk pair per lane. Lanes draw uniforms only
//! where they are active (`draw(mask)`), so lane `j` replays the one-lane walk
//! of its pair exactly.

use super::events::{self, Flight};
use super::layout::{depth_to_boundary, flight_limit, LayerKind, Layout, MediumLanes};
use super::settings::Settings;
use crate::interface::InterfaceLanes;
use crate::lane::{Lane, LaneMask, Rgb, V3};
use crate::medium;

/// The stack as the density walk reads it: per-interface and per-layer
/// parameters splatted over the lanes.
pub struct DensityWalk<'a, L: Lane> {
    /// Interfaces, top first.
    pub ifaces: &'a [InterfaceLanes<L>],
    /// Media, layer `l` between interfaces `l` and `l + 1`.
    pub media: &'a [MediumLanes<L>],
    /// `sample()`'s walk settings.
    pub settings: &'a Settings,
    /// Stop a walk after this many events (the approximate pdf's bound);
    /// `None`: only Russian roulette and the settings end it.
    pub max_events: Option<u32>,
}

/// What the walk carries between events, per lane.
#[derive(Clone, Copy)]
struct State<L: Lane> {
    beta: Rgb<L>,
    ratios: Rgb<L>,
    hero: L,
    events: L,
}

/// Where the walk's density goes out, per lane: fixed for a walk.
struct Goal<L: Lane> {
    wo: V3<L>,
    /// The exit interface, its index, the IOR outside it.
    exit: InterfaceLanes<L>,
    e_out: L,
    n_out: L,
    /// The region beyond the exit (`-1` above the stack, `n − 1` below).
    outside: L,
    /// The exit's layer; the interface across it, `k`, and the depth there.
    layer: L,
    k: L,
    inner: InterfaceLanes<L>,
    z_k: L,
    /// Lanes with an inner connection (smooth exit, rough `k`), and the
    /// direction `u_w` leaving `k` towards the exit that leaves along `wo`,
    /// with the Jacobian `dω_w / dω_o`.
    inner_on: L::Mask,
    u_w: V3<L>,
    j_w: L,
    /// The walk's targets: the rough exit's (from `wo`) and `k`'s (from
    /// `u_w`), drawn once per walk.
    exit_target: Target<L>,
    inner_target: Target<L>,
}

impl<L: Lane> Goal<L> {
    /// Lane by lane, `a` where `m` is set and `b` elsewhere.
    fn select(m: L::Mask, a: &Self, b: &Self) -> Self {
        let v = |x: L, y: L| L::select(m, x, y);
        let d = |x: V3<L>, y: V3<L>| V3::select(m, x, y);
        let it = |x: &InterfaceLanes<L>, y: &InterfaceLanes<L>| InterfaceLanes::select(m, x, y);
        Goal {
            wo: d(a.wo, b.wo),
            exit: it(&a.exit, &b.exit),
            e_out: v(a.e_out, b.e_out),
            n_out: v(a.n_out, b.n_out),
            outside: v(a.outside, b.outside),
            layer: v(a.layer, b.layer),
            k: v(a.k, b.k),
            inner: it(&a.inner, &b.inner),
            z_k: v(a.z_k, b.z_k),
            inner_on: (m & a.inner_on) | (!m & b.inner_on),
            u_w: d(a.u_w, b.u_w),
            j_w: v(a.j_w, b.j_w),
            exit_target: Target::select(m, &a.exit_target, &b.exit_target),
            inner_target: Target::select(m, &a.inner_target, &b.inner_target),
        }
    }
}

/// Density walks on lanes between two interface events
/// ([`DensityWalk::step`]): what a scheduler keeps to step them and to
/// start new walks on the lanes whose walk ended ([`DensityWalk::start`]).
pub struct WalkLanes<L: Lane> {
    /// Each lane's estimate so far; its walk's once it has ended.
    pub p: L,
    /// The lanes whose walk goes on.
    pub alive: L::Mask,
    /// The lanes whose walk the limit of events ended
    /// ([`crate::estimator::Settings::max_events`]).
    pub cut: L::Mask,
    st: State<L>,
    /// Collisions so far.
    order: L,
    /// The walk's density of its direction since its last non-delta vertex,
    /// carried through delta events in their solid angle ([`NO_DENSITY`]
    /// before the first one): the weight of its own arrival at a rough exit,
    /// or at k, against the connections. An estimated phase value may be
    /// 0 for a direction the walk sampled: its weight is then 0, not 1.
    rho: L,
    /// For the walk's own arrival at a rough exit, the medium connection's
    /// ratio `K` of its last collision, if that was its last non-delta
    /// vertex.
    k_b: L,
    /// The interface the walk arrives at, and its arrival direction.
    i: L,
    a: V3<L>,
    goal: Goal<L>,
}

impl<L: Lane> WalkLanes<L> {
    /// Lane by lane, `a` where `m` is set and `b` elsewhere.
    fn select(m: L::Mask, a: &Self, b: &Self) -> Self {
        let v = |x: L, y: L| L::select(m, x, y);
        let rgb = |x: Rgb<L>, y: Rgb<L>| Rgb::select(m, x, y);
        WalkLanes {
            p: v(a.p, b.p),
            alive: (m & a.alive) | (!m & b.alive),
            cut: (m & a.cut) | (!m & b.cut),
            st: State {
                beta: rgb(a.st.beta, b.st.beta),
                ratios: rgb(a.st.ratios, b.st.ratios),
                hero: v(a.st.hero, b.st.hero),
                events: v(a.st.events, b.st.events),
            },
            order: v(a.order, b.order),
            rho: v(a.rho, b.rho),
            k_b: v(a.k_b, b.k_b),
            i: v(a.i, b.i),
            a: V3::select(m, a.a, b.a),
            goal: Goal::select(m, &a.goal, &b.goal),
        }
    }
}

/// A non-delta vertex of the walk.
enum Vertex<'a, L: Lane> {
    /// An event at interface `i`, arriving from `a`.
    Surface {
        it: &'a InterfaceLanes<L>,
        a: V3<L>,
        i: L,
    },
    /// A collision at depth `z` of layer `l`, travelling along `d`, with
    /// the uniforms of two independent estimates of its phase value (where
    /// it has no closed form): one for the density, one for MIS weights;
    /// and the walk's density of arriving here (direction and depth) from
    /// its previous vertex, where the medium connection could have made
    /// this vertex instead (0 elsewhere).
    Collision {
        med: &'a MediumLanes<L>,
        d: V3<L>,
        l: L,
        z: L,
        e: [(L, L); 2],
        p_in: L,
    },
}

impl<L: Lane> Vertex<'_, L> {
    /// The vertex's sampling density of the travel direction `u`, the
    /// throughput factor `sample()` gives that direction, and the density
    /// again, for MIS weights: an estimate independent of the first where
    /// the density is estimated, so that the weight of a term does not
    /// correlate with its value.
    fn density(&self, u: V3<L>) -> (L, Rgb<L>, L) {
        match self {
            Vertex::Surface { it, a, .. } => {
                let (f, pv) = it.eval_pdf(*a, u);
                let ok = pv.gt(L::zero());
                let w = f.scale(L::div_or_zero(u.z.abs(), pv, ok));
                (pv, w, pv)
            }
            Vertex::Collision { med, d, e, .. } => {
                let phase = &med.phase;
                let pv = phase.eval(*d, u, e[0]);
                let pw = if phase.exact() {
                    pv
                } else {
                    phase.eval(*d, u, e[1])
                };
                (pv, Rgb::one(), pw)
            }
        }
    }
}

/// A sampled target of a connection: a travel direction `t` in the region
/// of IOR `n_t`, sampled with density `q` by a rough interface, whose own
/// density of what follows is `pe`.
#[derive(Clone, Copy)]
struct Target<L: Lane> {
    t: V3<L>,
    n_t: L,
    /// The region `t` travels in (layer index; `-1` above the stack).
    region: L,
    q: L,
    pe: L,
    /// The interface's BSDF value for the arrival towards `leave`, where
    /// asked for (the inner connection goes on through it).
    f: Rgb<L>,
    ok: L::Mask,
}

impl<L: Lane> Target<L> {
    /// Lane by lane, `a` where `m` is set and `b` elsewhere.
    fn select(m: L::Mask, a: &Self, b: &Self) -> Self {
        let v = |x: L, y: L| L::select(m, x, y);
        Target {
            t: V3::select(m, a.t, b.t),
            n_t: v(a.n_t, b.n_t),
            region: v(a.region, b.region),
            q: v(a.q, b.q),
            pe: v(a.pe, b.pe),
            f: Rgb::select(m, a.f, b.f),
            ok: (m & a.ok) | (!m & b.ok),
        }
    }

    /// A rough interface `it`'s connection from the travel direction `leave`
    /// (leaving it): the arrival sampled by its lobe from `leave`, and its
    /// density of `leave` for that arrival; with `value`, also its BSDF
    /// value for that pair (one kernel computes both).
    fn sample(
        it: &InterfaceLanes<L>,
        i: L,
        leave: V3<L>,
        transmit_only: L::Mask,
        value: bool,
        m: L::Mask,
        draw: &mut impl FnMut(L::Mask) -> L,
    ) -> Self {
        let zero = L::zero();
        if !m.any() {
            return Target {
                t: V3::z_axis(),
                n_t: zero,
                region: zero,
                q: zero,
                pe: zero,
                f: Rgb::zero(),
                ok: m,
            };
        }
        let (u0, u1, u2) = (draw(m), draw(m), draw(m));
        let s = it.sample(leave, u0, u1, u2, transmit_only);
        let b = s.b; // the arrival, pointing away from the interface
        let ok = m & s.valid & s.pdf.gt(zero);
        let (f, pe) = match value {
            true => it.eval_pdf(b, leave),
            false => (Rgb::zero(), it.pdf(b, leave, L::Mask::splat(false))),
        };
        Target {
            t: -b,
            n_t: L::select(b.z.gt(zero), it.n_above, it.n_below),
            region: L::select(b.z.gt(zero), i - L::one(), i),
            q: L::select(ok, s.pdf, zero),
            pe: L::select(ok, pe, zero),
            f: Rgb::select(ok, f, Rgb::zero()),
            ok,
        }
    }

    /// The share of a vertex that reaches `t` with density `pv` (in `t`'s
    /// solid angle): `pv · pe / q`, by the power heuristic against the
    /// walk's own arrival, whose density the weight takes as `pw` (`pv`
    /// itself, or an independent estimate of it).
    fn value(&self, pv: L, pw: L) -> L {
        let ok = self.ok & self.q.gt(L::zero());
        L::div_or_zero(pv * self.pe, self.q, ok) * events::power_heuristic(self.q, pw)
    }
}

/// The walk's arrival density before its first non-delta vertex: none
/// (a density is never negative).
const NO_DENSITY: f64 = -1.0;

/// The power-heuristic weight of the walk's own arrival, of density `rho`
/// ([`NO_DENSITY`] if it has none), against a connection of density `q`:
/// 1 where only the walk makes the path (no density, or `q` = 0), else
/// `rho² / (rho² + q²)`, which is 0 where an estimated phase value was 0
/// (the connection takes such paths whole, weight `q² / (q² + 0)`).
#[inline(always)]
fn own_weight<L: Lane>(rho: L, q: L) -> L {
    let alone = rho.lt(L::zero()) | q.le(L::zero());
    L::select(alone, L::one(), events::power_heuristic(rho, q))
}

/// The second moment `4π ∫ p²` of a phase function from which the density
/// walk connects its medium (`DensityWalk::medium_connects`):
/// Henyey–Greenstein with `g ≈ 0.58`.
const PEAKED: f64 = 3.0;

/// The density, per unit depth, with which a walk flying from depth `z0`
/// along `d` in layer `med` collides at depth `z` (hero channel `hero`),
/// whatever it meets beyond.
fn flight_density<L: Lane>(med: &MediumLanes<L>, z0: L, z: L, d: V3<L>, hero: L) -> L {
    let mu = d.z.abs();
    let ok = mu.gt(L::zero());
    let dist = L::div_or_zero((z - z0).abs(), mu, ok);
    let den = medium::collision_density_hero(med.sigma_along(d), med.grey, dist, hero);
    L::div_or_zero(den, mu, ok)
}

/// The medium connection's density, per unit depth, of a collision at
/// depth `z` of layer `med` that leaves along `u`: the collision density
/// of a flight that starts where `u` leaves the layer and runs back along
/// `-u`.
fn backward_density<L: Lane>(med: &MediumLanes<L>, z: L, u: V3<L>, hero: L) -> L {
    let dz = depth_to_boundary(z, med.thickness, u.z.gt(L::zero()));
    flight_density(med, dz, L::zero(), u, hero)
}

/// How a delta event at `it` from `a` to `b` changes a density of
/// directions: the solid-angle ratio `dω_a / dω_b` of a refraction,
/// `(n_b² |cos b|) / (n_a² |cos a|)`, cosines in the interface's shading
/// frame; 1 for a reflection.
fn refraction_jacobian<L: Lane>(it: &InterfaceLanes<L>, a: V3<L>, b: V3<L>) -> L {
    let refracted = (a.z * b.z).lt(L::zero());
    let (n_a, n_b) = it.sides(a);
    let (ca, cb) = (it.cos_local(a), it.cos_local(b));
    let ok = refracted & (n_a * ca).gt(L::zero());
    let j = L::div_or_zero(n_b * n_b * cb, n_a * n_a * ca, ok);
    L::select(refracted, j, L::one())
}

impl<L: Lane> DensityWalk<'_, L> {
    fn n(&self) -> usize {
        self.ifaces.len()
    }

    /// Lane `j` takes interface `i[j]`.
    fn at(&self, i: L) -> InterfaceLanes<L> {
        super::layout::iface_at(self.ifaces, i)
    }

    /// Whether interface `i` (per lane) is smooth.
    fn smooth_at(&self, i: L) -> L::Mask {
        super::layout::iface_smooth_at(self.ifaces, i)
    }

    /// The thickness of layer `l` (per lane) in depth units.
    fn thickness(&self, l: L) -> L {
        super::layout::thickness_at(self.media, l)
    }

    /// Where the walks of lanes `m` send their density out towards `wo`,
    /// with their targets drawn.
    fn goal(&self, wo: V3<L>, m: L::Mask, draw: &mut impl FnMut(L::Mask) -> L) -> Goal<L> {
        let n = self.n();
        let zero = L::zero();
        let last = L::splat(n as f64 - 1.0);
        let top = wo.z.gt(zero);
        let e_out = L::select(top, zero, last);
        let exit = self.at(e_out);
        let two = n >= 2;
        let layer = L::select(top, zero, L::splat(n as f64 - 2.0).max(zero));
        let k = L::select(top, L::one().min(last), L::splat(n as f64 - 2.0).max(zero));
        let inner = self.at(k);
        let n_out = L::select(top, exit.n_above, exit.n_below);
        let on = L::Mask::splat(two) & exit.smooth & !inner.smooth;
        let outside = L::select(top, -L::one(), last);
        let (u_w, j_w, ok) = self.candidate(layer, top, wo, n_out, outside, on);
        let no = L::Mask::splat(false);
        let yes = L::Mask::splat(true);
        let exit_target = Target::sample(&exit, e_out, wo, yes, false, m & !exit.smooth, draw);
        let inner_target = Target::sample(&inner, k, u_w, no, true, m & ok, draw);
        Goal {
            exit_target,
            inner_target,
            wo,
            exit,
            e_out,
            n_out,
            outside,
            layer,
            k,
            z_k: L::select(top, self.thickness(layer), zero),
            inner,
            inner_on: ok,
            u_w,
            j_w,
        }
    }

    /// One walk per lane from `wi` (stack frame, pointing away from the
    /// stack): its estimate of the density of `wo` (see the module docs).
    /// `draw(m)` returns a uniform for every lane of `m`. Also returns the
    /// lanes whose walk the limit of events ended.
    pub fn run(&self, wi: V3<L>, wo: V3<L>, mut draw: impl FnMut(L::Mask) -> L) -> (L, L::Mask) {
        let mut w = self.begin(wi, wo, L::Mask::splat(true), &mut draw);
        while w.alive.any() {
            self.step(&mut w, &mut draw);
        }
        (w.p, w.cut)
    }

    /// A walk from `wi` towards `wo` on each lane of `m`, before its first
    /// event (the other lanes have none).
    pub fn begin(
        &self,
        wi: V3<L>,
        wo: V3<L>,
        m: L::Mask,
        mut draw: impl FnMut(L::Mask) -> L,
    ) -> WalkLanes<L> {
        let zero = L::zero();
        let last = L::splat(self.n() as f64 - 1.0);
        let s0 = events::WalkStart::<L>::new(draw(m));
        WalkLanes {
            p: zero,
            alive: m,
            cut: L::Mask::splat(false),
            st: State {
                beta: s0.beta,
                ratios: s0.ratios,
                hero: s0.hero,
                events: s0.events,
            },
            order: s0.order,
            rho: L::splat(NO_DENSITY),
            k_b: zero,
            i: L::select(wi.z.gt(zero), zero, last),
            a: wi,
            goal: self.goal(wo, m, &mut draw),
        }
    }

    /// Lanes `m` of `w` start a new walk from `wi` towards `wo`; the other
    /// lanes walk on. Lane `j` then runs the walk it would run alone: a
    /// scheduler refills the lanes whose walk ended without changing any
    /// walk's draws.
    pub fn start(
        &self,
        w: &mut WalkLanes<L>,
        wi: V3<L>,
        wo: V3<L>,
        m: L::Mask,
        draw: impl FnMut(L::Mask) -> L,
    ) {
        *w = WalkLanes::select(m, &self.begin(wi, wo, m, draw), w);
    }

    /// One interface event of every live walk of `w`, and its crossing of
    /// the layer beyond.
    pub fn step(&self, w: &mut WalkLanes<L>, mut draw: impl FnMut(L::Mask) -> L) {
        let zero = L::zero();
        let layout = Layout { n: self.n() };
        // sample()'s specular flag: the density walk has no use for it.
        let mut specular = L::Mask::splat(false);
        let goal = &w.goal;
        let wo = goal.wo;
        let (i, a) = (w.i, w.a);
        let (mut p, mut alive, mut st, mut order) = (w.p, w.alive, w.st, w.order);
        let (mut rho, mut k_b) = (w.rho, w.k_b);
        let it = self.at(i);
        let rough = alive & !it.smooth;
        // Arriving at a rough exit: its density of wo, weighted against
        // the connection that sampled this direction from wo.
        let direct = rough & i.eq(goal.e_out);
        if direct.any() {
            let v = it.pdf(a, wo, L::Mask::splat(false)).max(zero);
            let q = goal.exit.pdf(wo, a, L::Mask::splat(true));
            let w = own_weight(rho, q);
            let k = L::select(q.gt(zero), k_b, zero);
            // Against the medium connection: 1 / (1 + K²).
            let w_b = events::power_heuristic(L::one(), k);
            p += L::select(direct, v * w * w_b, zero);
        }
        if rough.any() {
            let v = Vertex::Surface { it: &it, a, i };
            p += self.connect(goal, &v, st, rho, rough, &mut draw);
        }
        // The interface event of sample()'s walk (the same steps as the
        // engines' walks, in `events`).
        let u = (draw(alive), draw(alive), draw(alive));
        let no = L::Mask::splat(false);
        let (s, ok) = events::interface_scatter(
            &it,
            a,
            u,
            no,
            alive,
            &mut st.beta,
            &mut specular,
            &mut st.events,
        );
        alive = ok;
        let d = s.b;
        rho = L::select(s.delta, rho * refraction_jacobian(&it, a, d), s.pdf);
        // Lanes whose direction was sampled by a non-delta vertex in the
        // layer they cross, with no event since: a collision on the way is
        // one the medium connection could also make.
        let mut straight = !s.delta;
        k_b = L::select(s.delta, k_b, zero);
        let up = d.z.gt(zero);
        let (l, out) = layout.enter(i, up);
        alive = alive & !out;
        w.cut = w.cut | (alive & events::reached_limit(st.events, self.settings));
        alive = alive & self.survive(&mut st, alive, draw(alive));
        // Cross the layer until the walk reaches one of its interfaces.
        if alive.any() {
            let mut z = L::select(up, self.thickness(l), zero);
            let mut d = V3::select(alive, d, V3::z_axis());
            let mut flying = alive;
            while flying.any() {
                for (ll, med) in self.media.iter().enumerate() {
                    let here = flying & l.eq(L::splat(ll as f64));
                    if !here.any() {
                        continue;
                    }
                    if med.kind != LayerKind::Scattering {
                        alive = alive & !events::cross_inert(med, z, d, here, &mut st.beta);
                        flying = flying & !here;
                    } else {
                        let z0 = z;
                        let fl = Flight {
                            z: &mut z,
                            beta: &mut st.beta,
                            ratios: &mut st.ratios,
                            order: &mut order,
                        };
                        let max_order = self.settings.max_scatter_order;
                        let u = draw(here);
                        let (hit, pass) =
                            events::free_flight(med, fl, d, st.hero, u, None, here, max_order);
                        // Flat lanes that pass, and lanes past the cap, end.
                        alive = alive & !(here & !hit & !pass);
                        flying = flying & !(here & !hit);
                        if !hit.any() {
                            continue;
                        }
                        let e = [(); 2].map(|_| events::estimate_uniforms(med, || draw(hit)));
                        let made = hit & straight & self.medium_connects(med);
                        let p_in = if made.any() {
                            let f = flight_density(med, z0, z, d, st.hero);
                            L::select(made, rho * f, zero)
                        } else {
                            zero
                        };
                        let v = Vertex::Collision {
                            med,
                            d,
                            l,
                            z,
                            e,
                            p_in,
                        };
                        p += self.connect(goal, &v, st, rho, hit, &mut draw);
                        let u = events::phase_uniforms(med, || draw(hit));
                        let dn = events::phase_scatter(med, d, u, hit, &mut specular);
                        // The arrival density, for the next vertex's MIS weight.
                        let er = events::estimate_uniforms(med, || draw(hit));
                        let h = med.phase.eval(d, dn, er);
                        let toward = L::select(wo.z.gt(zero), dn.z, -dn.z).gt(zero);
                        let made = hit & p_in.gt(zero) & toward;
                        if made.any() {
                            let c = backward_density(med, z, dn, st.hero);
                            k_b = L::select(hit, L::div_or_zero(c * h, p_in, made), k_b);
                        } else {
                            k_b = L::select(hit, zero, k_b);
                        }
                        rho = L::select(hit, h, rho);
                        straight = straight | hit;
                        events::after_collision(&mut d, &mut st.events, dn, hit);
                        w.cut = w.cut | (hit & events::reached_limit(st.events, self.settings));
                        let keep = self.survive(&mut st, hit, draw(hit));
                        alive = alive & !(hit & !keep);
                        flying = flying & !(hit & !keep);
                    }
                }
                flying = flying & alive;
            }
            w.i = L::select(alive, layout.arrive(l, d.z.gt(zero)), zero);
            w.a = -d;
        }
        (w.p, w.alive, w.st, w.order) = (p, alive, st, order);
        (w.rho, w.k_b) = (rho, k_b);
    }

    /// Every connection of a non-delta vertex (lanes `m`, walk state `st`,
    /// its arrival density `rho`): to the exit through smooth interfaces
    /// (towards `wo`, or towards the walk's target at a rough exit), and
    /// the inner connection through `k` (to its target there); one
    /// candidate heading up and one heading down each.
    fn connect(
        &self,
        g: &Goal<L>,
        v: &Vertex<'_, L>,
        st: State<L>,
        rho: L,
        m: L::Mask,
        draw: &mut impl FnMut(L::Mask) -> L,
    ) -> L {
        let zero = L::zero();
        let last = L::splat(self.n() as f64 - 1.0);
        let top = g.wo.z.gt(zero);
        let rough_exit = m & !g.exit.smooth;
        let (exit_target, inner_target) = (&g.exit_target, &g.inner_target);
        let inner_on = m & g.inner_on;
        // The sides a candidate can leave the vertex by: the layer, the
        // depth it starts from, the lanes where it exists.
        let sides = match v {
            Vertex::Surface { i, .. } => [
                (*i - L::one(), self.thickness(*i - L::one()), i.gt(zero)),
                (*i, zero, i.lt(last)),
            ],
            Vertex::Collision { l, z, .. } => [(*l, *z, m), (*l, *z, m)],
        };
        // The candidate leaving into layer l that smooth interfaces map to
        // t: its direction, its density at the vertex in t's solid angle,
        // the walk's state after the vertex samples it, the lanes.
        // A candidate whose first interface is rough, and not where it
        // stops, has no delta-only path: skipped before any work (it would
        // draw nothing either, so the walk is the same), as is a connection
        // no lane makes.
        let leave = |l: L, up: bool, t: V3<L>, n_t: L, r_t: L, ok: L::Mask, stop: L| {
            let first = if up { l } else { l + L::one() };
            let ok = ok & (self.smooth_at(first) | first.eq(stop));
            if !ok.any() {
                return (V3::z_axis(), zero, zero, st, ok, zero);
            }
            let (u, jac, ok) = self.candidate(l, L::Mask::splat(up), t, n_t, r_t, ok);
            let (pv, w, pw) = v.density(u);
            let s = State {
                beta: st.beta * w,
                ..st
            };
            (u, pv * jac, pw * jac, s, ok & pv.gt(zero), pv)
        };
        let mut p = zero;
        for (side, &(l, z, has)) in sides.iter().enumerate() {
            let up = side == 0;
            // To the exit: wo itself (smooth), or the rough exit's target.
            let t = V3::select(rough_exit, exit_target.t, g.wo);
            let n_t = L::select(rough_exit, exit_target.n_t, g.n_out);
            let r_t = L::select(rough_exit, exit_target.region, g.outside);
            let ok = m & has & (exit_target.ok | g.exit.smooth);
            let (u, pv, pw, s, ok, h) = leave(l, up, t, n_t, r_t, ok, g.e_out);
            if ok.any() {
                let (pe, _) = self.delta_exit(l, z, u, s, g.e_out, g.wo.z, ok, draw);
                let share = L::select(rough_exit, exit_target.value(pv, pw), pv);
                // The walk's own arrival at k, towards u_w: against the inner connection.
                let w_own = match v {
                    Vertex::Surface { i, a, .. } => {
                        let toward = if up { top } else { !top };
                        let at_k = ok & inner_on & i.eq(g.k) & toward;
                        if at_k.any() {
                            let q = g.inner.pdf(g.u_w, *a, L::Mask::splat(false));
                            L::select(at_k, own_weight(rho, q), L::one())
                        } else {
                            L::one()
                        }
                    }
                    // The walk's own collision, against the medium
                    // connection, which could have made it.
                    Vertex::Collision { med, z, p_in, .. } => {
                        let toward = if up { top } else { !top };
                        let made = ok & p_in.gt(zero) & toward;
                        if made.any() {
                            let c = backward_density(med, *z, u, st.hero);
                            L::select(made, events::power_heuristic(*p_in, c * h), L::one())
                        } else {
                            L::one()
                        }
                    }
                };
                p += L::select(ok, share * pe * w_own, zero);
            }
            // Through k to u_w: arrive at k along the sampled target.
            let t = inner_target.t;
            let ok = inner_on & has & inner_target.ok;
            let (u, pv, pw, s, ok, _) =
                leave(l, up, t, inner_target.n_t, inner_target.region, ok, g.k);
            if ok.any() {
                let (p1, mut s1) = self.delta_exit(l, z, u, s, g.k, t.z, ok, draw);
                let ok = ok & p1.gt(zero);
                if ok.any() {
                    // k's event towards u_w, then on to wo.
                    let pe = inner_target.pe;
                    let wk = inner_target.f.scale(L::div_or_zero(g.u_w.z.abs(), pe, ok));
                    s1.beta *= wk;
                    let (p2, _) =
                        self.delta_exit(g.layer, g.z_k, g.u_w, s1, g.e_out, g.wo.z, ok, draw);
                    let share = inner_target.value(pv, pw) * g.j_w;
                    p += L::select(ok, share * p1 * p2, zero);
                }
            }
        }
        p + self.connect_medium(g, v, st, m, exit_target, draw)
    }

    /// The lanes where the medium connection runs in the layer of `med`
    /// (only with MIS on, `Settings::mis`: it needs MIS weights): a
    /// scattering medium whose phase function has a closed form and
    /// depends on the angle alone (so that `p(d → u)`, as a density of
    /// `d`, is what sampling from `u` gives), in a stack whose delta paths
    /// conserve tangential momentum, with no cap on scattering orders; and
    /// where it pays: a phase function peaked enough (`4π ∫ p² ≥ PEAKED`)
    /// that the walk's own collisions, which evaluate it at a random
    /// argument, are noisier than the connection's work costs
    /// (docs/performance.md measures both sides).
    fn medium_connects(&self, med: &MediumLanes<L>) -> L::Mask {
        let runs = self.settings.mis
            && med.kind == LayerKind::Scattering
            && !med.directional
            && med.phase.exact()
            && self.settings.max_scatter_order.is_none()
            && !self.tilted_delta();
        if runs {
            med.phase.second_moment().ge(L::splat(PEAKED))
        } else {
            L::Mask::splat(false)
        }
    }

    /// The medium connection of a non-delta vertex `v` (lanes `m`, walk
    /// state `st`) through the exit target `target` (the module docs): for
    /// each layer `v`'s next direction can enter and each candidate `u`
    /// there heading to the exit, a collision `x` sampled from the exit's
    /// side (its arrival `d'` by the phase function from `u`, its depth
    /// backwards along `u`), connected to `v` by `v`'s density of `d'` and
    /// the flight's density of reaching `x`. Weighted against the walk's
    /// own collision by the balance of squares, `K = C h / P`.
    fn connect_medium(
        &self,
        g: &Goal<L>,
        v: &Vertex<'_, L>,
        st: State<L>,
        m: L::Mask,
        target: &Target<L>,
        draw: &mut impl FnMut(L::Mask) -> L,
    ) -> L {
        let zero = L::zero();
        let one = L::one();
        let last = L::splat(self.n() as f64 - 1.0);
        let top = g.wo.z.gt(zero);
        let rough_exit = m & !g.exit.smooth;
        let t = V3::select(rough_exit, target.t, g.wo);
        let n_t = L::select(rough_exit, target.n_t, g.n_out);
        let r_t = L::select(rough_exit, target.region, g.outside);
        let exit_share = L::select(
            rough_exit,
            L::div_or_zero(target.pe, target.q, target.ok & target.q.gt(zero)),
            one,
        );
        let m = m & (target.ok | g.exit.smooth);
        // Where x can be, and where the flight to it starts: the layer above
        // a surface vertex (entered heading up) and the one below (heading
        // down), or a collision's own layer.
        let none = L::Mask::splat(false);
        let starts = match v {
            Vertex::Surface { i, .. } => [
                (*i - one, self.thickness(*i - one), i.gt(zero), Some(true)),
                (*i, zero, i.lt(last), Some(false)),
            ],
            Vertex::Collision { l, z, .. } => [(*l, *z, m, None), (*l, *z, none, None)],
        };
        let mut p = zero;
        for &(l, z0, has, heads_up) in &starts {
            for (ll, med) in self.media.iter().enumerate() {
                let here = m & has & l.eq(L::splat(ll as f64)) & self.medium_connects(med);
                if !here.any() {
                    continue;
                }
                // The candidate heading for the exit (one that heads away
                // and reflects back is left to the walk).
                let first = L::select(top, l, l + one);
                let ok = here & (self.smooth_at(first) | first.eq(g.e_out));
                let (u, jac, ok) = self.candidate(l, top, t, n_t, r_t, ok);
                if ok.any() {
                    // x's arrival: the phase function depends on d'·u alone,
                    // so sampling from u gives the density p(d' → u) = h.
                    let w = events::phase_uniforms(med, || draw(ok));
                    let dp = med.phase.sample(u, w);
                    let h = med.phase.eval(dp, u, (zero, zero));
                    // x's depth, backwards along u from where u leaves the
                    // layer, with the density c per unit depth.
                    let mu = u.z.abs();
                    let sigma = medium::hero_sigma(med.sigma_along(u), st.hero);
                    let has_s = ok & sigma.gt(zero) & mu.gt(zero);
                    let back = L::div_or_zero(-(one - draw(ok)).ln() * mu, sigma, has_s);
                    let zx = L::select(top, back, med.thickness - back);
                    let c = backward_density(med, zx, u, st.hero);
                    // The flight from v to x along d': the right way, inside.
                    let dz = zx - z0;
                    let heads = match heads_up {
                        Some(true) => dp.z.gt(zero),
                        Some(false) => dp.z.lt(zero),
                        None => (dz * dp.z).lt(zero),
                    };
                    let mud = dp.z.abs();
                    let ok = has_s & back.lt(med.thickness) & heads & mud.gt(zero);
                    let dist = L::div_or_zero(dz.abs(), mud, ok);
                    let (den, fw, fr) = medium::collision_at(
                        med.sigma_along(dp),
                        med.albedo,
                        med.grey,
                        dist,
                        st.hero,
                        st.ratios,
                    );
                    let (pv, wv, _) = v.density(dp);
                    let pp = pv * L::div_or_zero(den, mud, ok);
                    // sample()'s walk reaching x: v's event, its roulette
                    // (in expectation), the flight.
                    let mut sx = State {
                        beta: st.beta * wv,
                        ..st
                    };
                    sx.events += one;
                    let q_v = self.survival(&mut sx);
                    sx.beta *= fw;
                    sx.ratios = fr;
                    let ok = ok & pp.gt(zero) & q_v.gt(zero);
                    if ok.any() {
                        let (pe, _) = self.delta_exit(l, zx, u, sx, g.e_out, g.wo.z, ok, draw);
                        // (P / c h) · h · w_B with w_B = K² / (1 + K²), from
                        // the ratio of the densities (no squares to overflow).
                        let w_b = events::power_heuristic(c * h, pp);
                        let value = L::div_or_zero(pp, c, ok & c.gt(zero)) * w_b;
                        p += L::select(ok, value * q_v * jac * exit_share * pe, zero);
                    }
                }
            }
        }
        p
    }

    /// Russian roulette of `sample()`'s walk (and the approximate pdf's
    /// bound) on lanes `m`: updates their throughput, returns the survivors.
    fn survive(&self, st: &mut State<L>, m: L::Mask, u: L) -> L::Mask {
        let alive = events::survive(&mut st.beta, st.events, u, m, self.settings);
        let bounded = match self.max_events {
            Some(k) => st.events.lt(L::splat(k as f64)),
            None => L::Mask::splat(true),
        };
        alive & bounded
    }

    /// Some smooth interface is tilted: delta paths through it do not
    /// conserve tangential momentum, so a candidate is traced interface by
    /// interface and only the path that transmits at every delta event maps
    /// to the target (one with reflections leaves another way: method.md
    /// §9 says what this leaves out).
    fn tilted_delta(&self) -> bool {
        self.ifaces.iter().any(|it| it.tilted && it.smooth.any())
    }

    /// [`DensityWalk::candidate`] through tilted interfaces: `t` refracted
    /// back through each interface between region `r_t` and layer `l`, the
    /// nearest first, with the Jacobian of each refraction in its shading
    /// frame; none where an interface on the way is rough or reflects
    /// totally, or where the result does not head `up` (or down) as asked.
    fn candidate_tilted(
        &self,
        l: L,
        up: L::Mask,
        t: V3<L>,
        r_t: L,
        m: L::Mask,
    ) -> (V3<L>, L, L::Mask) {
        let zero = L::zero();
        let (mut u, mut jac, mut ok) = (t, L::one(), m);
        let n = self.n();
        let cross = |j: usize, act: L::Mask, u: &mut V3<L>, jac: &mut L, ok: &mut L::Mask| {
            let act = act & *ok;
            if !act.any() {
                return;
            }
            let it = &self.ifaces[j];
            let s = it.sample(*u, zero, zero, zero, L::Mask::splat(true));
            let (n_a, n_b) = it.sides(*u);
            let (ca, cb) = (it.cos_local(*u), it.cos_local(s.b));
            let step = L::div_or_zero(n_a * n_a * ca, n_b * n_b * cb, act & cb.gt(zero));
            *ok = *ok & !(act & !(it.smooth & s.valid));
            *jac = L::select(act, *jac * step, *jac);
            *u = V3::select(act, -s.b, *u);
        };
        for j in 0..n {
            let jj = L::splat(j as f64);
            let act = up & jj.gt(r_t) & l.ge(jj);
            cross(j, act, &mut u, &mut jac, &mut ok);
        }
        for j in (0..n).rev() {
            let jj = L::splat(j as f64);
            let act = !up & r_t.ge(jj) & jj.gt(l);
            cross(j, act, &mut u, &mut jac, &mut ok);
        }
        let heads = L::select(up, u.z, -u.z).gt(zero);
        (u, jac, ok & heads)
    }

    /// The travel direction in layer `l` (per lane), heading up (`up`) or
    /// down, that smooth interfaces map to the direction `t` in a region of
    /// IOR `n_t`; the Jacobian `dω_u / dω_t`; the lanes of `m` where it
    /// exists (not evanescent).
    /// `t` travels in region `r_t` (a layer index, `-1` above the stack).
    fn candidate(
        &self,
        l: L,
        up: L::Mask,
        t: V3<L>,
        n_t: L,
        r_t: L,
        m: L::Mask,
    ) -> (V3<L>, L, L::Mask) {
        if self.tilted_delta() {
            return self.candidate_tilted(l, up, t, r_t, m);
        }
        let zero = L::zero();
        let n_l =
            super::layout::iface_field_at(self.ifaces, l.max(zero), |it| it.n_below, L::select);
        let r = L::div_or_zero(n_t, n_l, m & n_l.gt(zero));
        let (tx, ty) = (t.x * r, t.y * r);
        let c2 = L::one() - tx * tx - ty * ty;
        let ok = m & c2.gt(zero);
        let cz = c2.safe_sqrt();
        let u = V3::new(tx, ty, L::select(up, cz, -cz));
        let jac = L::div_or_zero(r * r * t.z.abs(), cz, ok);
        (u, jac, ok)
    }

    /// An unbiased estimate, on lanes `m`, of the probability that
    /// `sample()`'s walk at depth `z` of layer `l`, having just sampled the
    /// travel direction `u` (its state `st` before the event's roulette),
    /// meets only delta events and then leaves through the smooth outer
    /// interface `stop`, or arrives at the rough interface `stop` travelling
    /// with the sign of `toward` in z; and the walk's state there.
    /// Reflect-or-transmit choices are sampled; crossings and Russian
    /// roulette are taken in expectation. 0 where the continuation meets
    /// another rough interface or leaves elsewhere. It ends: a lossless loop
    /// of delta events would need a clear layer whose smooth boundaries both
    /// reflect `u` totally, and a delta path cannot enter such a layer (the
    /// direction does not exist beside it), while `u` starts next to a rough
    /// interface or in a scattering layer, which each pass leaves with
    /// probability below 1.
    #[allow(clippy::too_many_arguments)]
    fn delta_exit(
        &self,
        l: L,
        z: L,
        u: V3<L>,
        st: State<L>,
        stop: L,
        toward: L,
        m: L::Mask,
        draw: &mut impl FnMut(L::Mask) -> L,
    ) -> (L, State<L>) {
        let zero = L::zero();
        let last = L::splat(self.n() as f64 - 1.0);
        let mut st = st;
        st.events += L::one();
        let mut prob = L::select(m, self.survival(&mut st), zero);
        let mut live = m & prob.gt(zero);
        let (mut l, mut z, mut u) = (l, z, u);
        let mut p = zero;
        let mut end = st;
        while live.any() {
            // Cross the rest of layer l along u.
            let up = u.z.gt(zero);
            let mu = u.z.abs();
            live = live & mu.gt(zero);
            for (ll, med) in self.media.iter().enumerate() {
                let here = live & l.eq(L::splat(ll as f64));
                if !here.any() || med.kind == LayerKind::Clear {
                    continue;
                }
                let dz = depth_to_boundary(z, med.thickness, up);
                if med.kind == LayerKind::Absorbing {
                    let t = med.transmittance(dz, u);
                    st.beta = Rgb::select(here, st.beta * t, st.beta);
                    continue;
                }
                let (q, w, r) = medium::no_collision(
                    med.sigma_along(u),
                    med.grey,
                    flight_limit(dz, mu),
                    st.hero,
                    st.ratios,
                );
                prob = L::select(here, prob * q, prob);
                st.beta = Rgb::select(here, st.beta * w, st.beta);
                st.ratios = Rgb::select(here, r, st.ratios);
            }
            // The interface it reaches: a rough stop (the end), another delta
            // event, or a rough interface (no delta-only path).
            let j = L::select(up, l, l + L::one());
            let it = self.at(j);
            let arrived = live & j.eq(stop) & !it.smooth & (u.z * toward).gt(zero);
            p = L::select(arrived, prob, p);
            end = State {
                beta: Rgb::select(arrived, st.beta, end.beta),
                ratios: Rgb::select(arrived, st.ratios, end.ratios),
                ..end
            };
            end.events = L::select(arrived, st.events, end.events);
            live = live & it.smooth & prob.gt(zero);
            if !live.any() {
                break;
            }
            let s = it.sample(-u, draw(live), zero, zero, L::Mask::splat(false));
            live = live & s.valid;
            if self.tilted_delta() {
                // Only the path that transmits throughout maps to the target.
                live = live & (s.b.z * u.z).gt(zero);
            }
            st.beta = Rgb::select(live, st.beta * s.weight, st.beta);
            st.events = L::select(live, st.events + L::one(), st.events);
            let b = s.b;
            let b_up = b.z.gt(zero);
            let out = (b_up & j.eq(zero)) | (!b_up & j.eq(last));
            let reached = live & out & j.eq(stop);
            p = L::select(reached, prob, p);
            live = live & !out;
            let q = self.survival(&mut st);
            prob = L::select(live, prob * q, prob);
            live = live & prob.gt(zero);
            l = L::select(b_up, j - L::one(), j);
            z = L::select(b_up, self.thickness(l), zero);
            u = b;
        }
        (p, end)
    }

    /// Russian roulette in expectation: the probability that `sample()`'s
    /// walk survives its roulette after `st.events` events (0 past the cap or
    /// the bound), and the survivor's throughput.
    fn survival(&self, st: &mut State<L>) -> L {
        let zero = L::zero();
        let early = st.events.lt(L::splat(self.settings.rr_start as f64));
        let q = events::survival(st.beta, events::rr_threshold(self.settings));
        let (b, ok) = events::walk_roulette(st.beta, st.events, zero, self.settings);
        st.beta = b;
        let bounded = match self.max_events {
            Some(k) => st.events.lt(L::splat(k as f64)),
            None => L::Mask::splat(true),
        };
        L::select(ok & bounded, L::select(early, L::one(), q), zero)
    }
}
