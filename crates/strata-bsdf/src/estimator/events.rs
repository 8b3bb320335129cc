//! The event kernels of a walk, written once over [`Lane`]: the scalar
//! reference calls them on one walk (`f32`, `f64`), the wavefront engine on
//! eight or sixteen walks at once. The engines differ only in control flow
//! (early returns there, masks and compaction here), so a lane of the
//! wavefront replays a scalar walk operation for operation.
//!
//! Notation (method.md §4): a walk carries its throughput `beta`; an
//! [`Connection`] is one segment of the adjoint chain sampled from `wo`: light
//! leaving a vertex along `u` reaches the viewer with the factor `v`, which
//! already holds the exit interface's value, the cosine of `u` and the
//! inverse density of `u` (next-event estimation "from the other side").

use super::layout::Layout;
use super::Settings;
use crate::interface::InterfaceLanes;
use crate::lane::{Lane, LaneMask, Rgb, V3};
use crate::medium;

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

/// The largest event cap honoured exactly (see [`Settings::max_depth`]).
pub const MAX_CAP: u32 = 1 << 24;

/// Russian roulette after `rr_start` events, and the optional hard cap.
/// Returns the new throughput and the lanes that survive. Survivors past
/// `rr_start` continue with probability `q = min(1, max channel of beta)` and
/// are divided by it, so the estimate stays unbiased.
#[inline]
pub fn roulette<L: Lane>(
    beta: Rgb<L>,
    events: L,
    u: L,
    rr_start: u32,
    cap: Option<u32>,
) -> (Rgb<L>, L::Mask) {
    // Events are counted in single precision by the wavefront engine, exactly
    // up to 2^24; a cap above that is treated as 2^24 by every engine.
    let capped = match cap {
        Some(c) => events.ge(L::splat(c.min(MAX_CAP) as f64)),
        None => L::Mask::splat(false),
    };
    let early = events.lt(L::splat(rr_start as f64));
    let q = beta.max_channel().min(L::one());
    let survive = u.lt(q);
    let alive = !capped & (early | survive);
    let scaled = beta.scale(L::div_or_zero(L::one(), q, survive));
    (Rgb::select(early, beta, scaled), alive)
}

/// [`roulette`] with a walk's settings.
#[inline]
pub fn walk_roulette<L: Lane>(beta: Rgb<L>, events: L, u: L, s: &Settings) -> (Rgb<L>, L::Mask) {
    roulette(beta, events, u, s.rr_start, s.max_depth)
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
/// `d` scatters into the connection's `u` (phase function with asymmetry
/// `g`), and crosses the rest of the layer with transmittance `t`. The
/// `1 / |u.z|` is the position-free Jacobian (method.md §3).
#[inline]
pub fn connect_collision<L: Lane>(
    g: L,
    d: V3<L>,
    c: &Connection<L>,
    t: Rgb<L>,
    mis: bool,
) -> Rgb<L> {
    let ph = medium::hg_eval_dirs(g, d, c.u);
    let w = if mis {
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
