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
//!   continuation ([`DensityWalk::delta_exit`]) that samples the
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
//! The chain itself is `sample()`'s: the same kernels, hero channel, Russian
//! roulette and settings, on its own random stream. So each walk's sum is an
//! unbiased estimate of the density of `sample()` (the "unbiased, slow" pdf);
//! averaged over a few walks, bounded in length and mixed with a small uniform
//! density it is the approximate pdf `sample()` returns ([`super::pdf`]).
//!
//! The walk is written once over lanes: the scalar engine runs it on one lane,
//! the wavefront on one query-walk pair per lane. Lanes draw uniforms only
//! where they are active (`draw(mask)`), so lane `j` replays the one-lane walk
//! of its pair exactly.

use super::events;
use super::layout::{depth_to_boundary, flight_limit, move_depth, LayerKind, MediumLanes};
use super::Settings;
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

/// A vertex's connection to the exit ([`DensityWalk::connection`]).
#[derive(Clone, Copy)]
struct Connection<L: Lane> {
    /// The direction the candidate's continuation must leave the smooth
    /// interfaces along: `wo`, or the sampled travel direction at a rough exit.
    target: V3<L>,
    /// The index of the region `target` lies in.
    n_target: L,
    /// Lanes with a connection.
    ok: L::Mask,
    /// Lanes whose exit is rough.
    rough: L::Mask,
    /// The rough exit's density of `wo` for light arriving along `target`.
    pe: L,
    /// The density `target` was sampled with.
    q: L,
}

impl<L: Lane> Connection<L> {
    /// The connection's share of the density, for a vertex that samples
    /// `target` with density `pv` (in `target`'s solid angle): `pv` itself
    /// through a smooth exit; through a rough one, `pv · pe / q` weighted by
    /// the power heuristic against the walk's own arrival.
    fn value(&self, pv: L) -> L {
        let ok = self.q.gt(L::zero());
        let rough = L::div_or_zero(pv * self.pe, self.q, ok) * events::power_heuristic(self.q, pv);
        L::select(self.rough, rough, pv)
    }
}

/// How a delta event at `it` from `a` to `b` changes a density of
/// directions: the solid-angle ratio `dω_a / dω_b` of a refraction,
/// `(n_b² |cos b|) / (n_a² |cos a|)`; 1 for a reflection.
fn refraction_jacobian<L: Lane>(it: &InterfaceLanes<L>, a: V3<L>, b: V3<L>) -> L {
    let refracted = (a.z * b.z).lt(L::zero());
    let (n_a, n_b) = it.sides(a);
    let ok = refracted & (n_a * a.z).abs().gt(L::zero());
    let j = L::div_or_zero(n_b * n_b * b.z.abs(), n_a * n_a * a.z.abs(), ok);
    L::select(refracted, j, L::one())
}

impl<L: Lane> DensityWalk<'_, L> {
    fn n(&self) -> usize {
        self.ifaces.len()
    }

    /// Lane `j` takes interface `i[j]`.
    fn at(&self, i: L) -> InterfaceLanes<L> {
        let mut it = self.ifaces[0];
        for (k, t) in self.ifaces.iter().enumerate().skip(1) {
            let here = i.eq(L::splat(k as f64));
            if here.any() {
                it = InterfaceLanes::select(here, t, &it);
            }
        }
        it
    }

    /// One walk per lane from `wi` (stack frame, pointing away from the
    /// stack): its estimate of the density of `wo` (see the module docs).
    /// `draw(m)` returns a uniform for every lane of `m`.
    pub fn run(&self, wi: V3<L>, wo: V3<L>, mut draw: impl FnMut(L::Mask) -> L) -> L {
        let n = self.n();
        let zero = L::zero();
        let last = L::splat(n as f64 - 1.0);
        let top_exit = wo.z.gt(zero);
        let e_out = L::select(top_exit, zero, last);
        let exit = self.at(e_out);
        // The index outside wo's side and inside the exit, for the Jacobians.
        let n_out = L::select(top_exit, exit.n_above, exit.n_below);
        let n_in = L::select(top_exit, exit.n_below, exit.n_above);

        let mut p = zero;
        let mut alive = L::Mask::splat(true);
        let mut st = State {
            beta: Rgb::one(),
            ratios: Rgb::one(),
            hero: events::hero_channel(draw(alive)),
            events: zero,
        };
        let mut order = zero;
        // The walk's density of its current direction since its last
        // non-delta vertex, carried through delta events in their solid
        // angle (0 before the first one): the weight of its arrival at a
        // rough exit against the connections.
        let mut rho = zero;
        let mut i = L::select(wi.z.gt(zero), zero, last);
        let mut a = wi;
        while alive.any() {
            let it = self.at(i);
            let rough = alive & !it.smooth;
            // Arriving at a rough exit: its density of wo, weighted against
            // the connection that sampled this direction from wo.
            let direct = rough & i.eq(e_out);
            if direct.any() {
                let v = it.pdf(a, wo, L::Mask::splat(false)).max(zero);
                let q = exit.pdf(wo, a, L::Mask::splat(true));
                let w = L::select(rho.gt(zero), events::power_heuristic(rho, q), L::one());
                p += L::select(direct, v * w, zero);
            }
            // A rough vertex connects to the exit through smooth interfaces.
            if rough.any() {
                let c = self.connection(wo, &exit, n_out, n_in, rough, &mut draw);
                for up in [true, false] {
                    // The layer the candidate enters: above i (up) or below it.
                    let has = if up { i.gt(zero) } else { i.lt(last) };
                    let l = if up { i - L::one() } else { i };
                    let m = rough & has & c.ok;
                    if !m.any() {
                        continue;
                    }
                    let (u, jac, ok) = self.candidate(l, up, c.target, c.n_target, m);
                    let pv = it.pdf(a, u, L::Mask::splat(false));
                    let m = ok & pv.gt(zero);
                    if !m.any() {
                        continue;
                    }
                    let w = it.eval(a, u).scale(L::div_or_zero(u.z.abs(), pv, m));
                    let s = State {
                        beta: st.beta * w,
                        ..st
                    };
                    let z = if up { self.thickness(l) } else { zero };
                    let pe = self.delta_exit(l, z, u, s, e_out, m, &mut draw);
                    p += L::select(m, c.value(pv * jac) * pe, zero);
                }
            }
            // The interface event of sample()'s walk.
            let (us, u1, u2) = (draw(alive), draw(alive), draw(alive));
            let s = it.sample(a, us, u1, u2, L::Mask::splat(false));
            alive = alive & s.valid;
            st.beta = Rgb::select(alive, st.beta * s.weight, st.beta);
            st.events = L::select(alive, st.events + L::one(), st.events);
            let d = s.b;
            rho = L::select(s.delta, rho * refraction_jacobian(&it, a, d), s.pdf);
            let up = d.z.gt(zero);
            let out = (up & i.eq(zero)) | (!up & i.eq(last));
            alive = alive & !out;
            alive = alive & self.survive(&mut st, alive, draw(alive));
            if !alive.any() {
                break;
            }
            // Cross the layer until the walk reaches one of its interfaces.
            let l = L::select(up, i - L::one(), i);
            let mut z = L::select(up, self.thickness(l), zero);
            let mut d = V3::select(alive, d, V3::z_axis());
            let mut flying = alive;
            while flying.any() {
                for (ll, med) in self.media.iter().enumerate() {
                    let here = flying & l.eq(L::splat(ll as f64));
                    if !here.any() {
                        continue;
                    }
                    let mu = d.z.abs();
                    let flat = mu.le(zero);
                    let dz = depth_to_boundary(z, med.thickness, d.z.gt(zero));
                    match med.kind {
                        LayerKind::Clear => {
                            alive = alive & !(here & flat);
                            flying = flying & !here;
                        }
                        LayerKind::Absorbing => {
                            alive = alive & !(here & flat);
                            let t = med.transmittance(dz, mu);
                            st.beta = Rgb::select(here, st.beta * t, st.beta);
                            flying = flying & !here;
                        }
                        LayerKind::Scattering => {
                            let ff = medium::sample_free_flight(
                                med.sigma_t,
                                med.albedo,
                                med.grey,
                                flight_limit(dz, mu),
                                st.hero,
                                draw(here),
                                st.ratios,
                            );
                            st.beta = Rgb::select(here, st.beta * ff.weight, st.beta);
                            st.ratios = Rgb::select(here, ff.ratios, st.ratios);
                            let passed = here & !ff.collide;
                            alive = alive & !(passed & flat);
                            flying = flying & !passed;
                            let hit = here & ff.collide;
                            if !hit.any() {
                                continue;
                            }
                            order = L::select(hit, order + L::one(), order);
                            let over = match self.settings.max_scatter_order {
                                Some(k) => hit & order.gt(L::splat(k as f64)),
                                None => L::Mask::splat(false),
                            };
                            alive = alive & !over;
                            flying = flying & !over;
                            let hit = hit & !over;
                            z = L::select(hit, move_depth(z, d.z, ff.distance, med.thickness), z);
                            // A collision is a non-delta vertex.
                            let c = self.connection(wo, &exit, n_out, n_in, hit, &mut draw);
                            for up in [true, false] {
                                let m = hit & c.ok;
                                if !m.any() {
                                    continue;
                                }
                                let (u, jac, ok) = self.candidate(l, up, c.target, c.n_target, m);
                                if !ok.any() {
                                    continue;
                                }
                                let pv = medium::hg_eval_dirs(med.g, d, u);
                                let pe = self.delta_exit(l, z, u, st, e_out, ok, &mut draw);
                                p += L::select(ok, c.value(pv * jac) * pe, zero);
                            }
                            let dn = medium::hg_sample(med.g, d, draw(hit), draw(hit));
                            rho = L::select(hit, medium::hg_eval_dirs(med.g, d, dn), rho);
                            d = V3::select(hit, dn, d);
                            st.events = L::select(hit, st.events + L::one(), st.events);
                            let keep = self.survive(&mut st, hit, draw(hit));
                            alive = alive & !(hit & !keep);
                            flying = flying & !(hit & !keep);
                        }
                    }
                }
                flying = flying & alive;
            }
            i = L::select(alive, L::select(d.z.gt(zero), l, l + L::one()), zero);
            a = -d;
        }
        p
    }

    /// Where a vertex's connection to the exit aims (lanes `m`): for a
    /// smooth exit, `wo` itself; for a rough one, a travel direction towards
    /// the exit sampled from `wo` (the exit's refraction lobe), with the
    /// exit's density of `wo` for it and the sampling density, for MIS
    /// against the walk's own arrival at the exit.
    fn connection(
        &self,
        wo: V3<L>,
        exit: &InterfaceLanes<L>,
        n_out: L,
        n_in: L,
        m: L::Mask,
        draw: &mut impl FnMut(L::Mask) -> L,
    ) -> Connection<L> {
        let zero = L::zero();
        let rough = m & !exit.smooth;
        let mut c = Connection {
            target: wo,
            n_target: n_out,
            ok: m,
            rough,
            pe: zero,
            q: zero,
        };
        if rough.any() {
            let (u0, u1, u2) = (draw(rough), draw(rough), draw(rough));
            let s = exit.sample(wo, u0, u1, u2, L::Mask::splat(true));
            let ok = rough & s.valid & s.pdf.gt(zero);
            let b = s.b;
            c.target = V3::select(rough, -b, wo);
            c.n_target = L::select(rough, n_in, n_out);
            c.ok = (m & exit.smooth) | ok;
            c.pe = L::select(ok, exit.pdf(b, wo, L::Mask::splat(false)), zero);
            c.q = L::select(ok, s.pdf, zero);
        }
        c
    }

    /// Russian roulette of `sample()`'s walk (and the approximate pdf's
    /// bound) on lanes `m`: updates their throughput, returns the survivors.
    fn survive(&self, st: &mut State<L>, m: L::Mask, u: L) -> L::Mask {
        let (b, ok) = events::walk_roulette(st.beta, st.events, u, self.settings);
        st.beta = Rgb::select(m, b, st.beta);
        let bounded = match self.max_events {
            Some(k) => st.events.lt(L::splat(k as f64)),
            None => L::Mask::splat(true),
        };
        m & ok & bounded
    }

    /// The thickness of layer `l` (per lane) in depth units.
    fn thickness(&self, l: L) -> L {
        let mut h = L::zero();
        for (k, m) in self.media.iter().enumerate() {
            h = L::select(l.eq(L::splat(k as f64)), m.thickness, h);
        }
        h
    }

    /// The travel direction in layer `l` (per lane), heading up or down, that
    /// smooth interfaces map to `wo`; the Jacobian `dω_u / dω_o`; the lanes
    /// of `m` where it exists (not evanescent).
    fn candidate(&self, l: L, up: bool, wo: V3<L>, n_out: L, m: L::Mask) -> (V3<L>, L, L::Mask) {
        let zero = L::zero();
        let n_l = self.at(l).n_below;
        let r = L::div_or_zero(n_out, n_l, m & n_l.gt(zero));
        let (tx, ty) = (wo.x * r, wo.y * r);
        let c2 = L::one() - tx * tx - ty * ty;
        let ok = m & c2.gt(zero);
        let cz = c2.safe_sqrt();
        let u = V3::new(tx, ty, if up { cz } else { -cz });
        let jac = L::div_or_zero(r * r * wo.z.abs(), cz, ok);
        (u, jac, ok)
    }

    /// An unbiased estimate, on lanes `m`, of the probability that
    /// `sample()`'s walk at depth `z` of layer `l`, having just sampled the
    /// travel direction `u` (its state `st` before the event's roulette),
    /// meets only delta events and then leaves through a smooth `e_out` or
    /// arrives at a rough one. Reflect-or-transmit choices are sampled;
    /// crossings and Russian roulette are taken in expectation. 0 where the
    /// continuation meets another rough interface or leaves through the other
    /// side.
    #[allow(clippy::too_many_arguments)]
    fn delta_exit(
        &self,
        l: L,
        z: L,
        u: V3<L>,
        st: State<L>,
        e_out: L,
        m: L::Mask,
        draw: &mut impl FnMut(L::Mask) -> L,
    ) -> L {
        let zero = L::zero();
        let last = L::splat(self.n() as f64 - 1.0);
        let mut st = st;
        st.events += L::one();
        let mut prob = L::select(m, self.survival(&mut st), zero);
        let mut live = m & prob.gt(zero);
        let (mut l, mut z, mut u) = (l, z, u);
        let mut p = zero;
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
                    let t = med.transmittance(dz, mu);
                    st.beta = Rgb::select(here, st.beta * t, st.beta);
                    continue;
                }
                let (q, w, r) = medium::no_collision(
                    med.sigma_t,
                    med.grey,
                    flight_limit(dz, mu),
                    st.hero,
                    st.ratios,
                );
                prob = L::select(here, prob * q, prob);
                st.beta = Rgb::select(here, st.beta * w, st.beta);
                st.ratios = Rgb::select(here, r, st.ratios);
            }
            // The interface it reaches: a rough exit (the end), another delta
            // event, or a rough interface (no delta-only path).
            let j = L::select(up, l, l + L::one());
            let it = self.at(j);
            let arrived = live & j.eq(e_out) & !it.smooth;
            p = L::select(arrived, prob, p);
            live = live & it.smooth & prob.gt(zero);
            if !live.any() {
                break;
            }
            let s = it.sample(-u, draw(live), zero, zero, L::Mask::splat(false));
            live = live & s.valid;
            st.beta = Rgb::select(live, st.beta * s.weight, st.beta);
            st.events = L::select(live, st.events + L::one(), st.events);
            let b = s.b;
            let b_up = b.z.gt(zero);
            let out = (b_up & j.eq(zero)) | (!b_up & j.eq(last));
            let reached = live & out & j.eq(e_out);
            p = L::select(reached, prob, p);
            live = live & !out;
            let q = self.survival(&mut st);
            prob = L::select(live, prob * q, prob);
            live = live & prob.gt(zero);
            l = L::select(b_up, j - L::one(), j);
            z = L::select(b_up, self.thickness(l), zero);
            u = b;
        }
        p
    }

    /// Russian roulette in expectation: the probability that `sample()`'s
    /// walk survives its roulette after `st.events` events (0 past the cap or
    /// the bound), and the survivor's throughput.
    fn survival(&self, st: &mut State<L>) -> L {
        let zero = L::zero();
        let early = st.events.lt(L::splat(self.settings.rr_start as f64));
        let q = st.beta.max_channel().min(L::one());
        let (b, ok) = events::walk_roulette(st.beta, st.events, zero, self.settings);
        st.beta = b;
        let bounded = match self.max_events {
            Some(k) => st.events.lt(L::splat(k as f64)),
            None => L::Mask::splat(true),
        };
        L::select(ok & bounded, L::select(early, L::one(), q), zero)
    }
}
