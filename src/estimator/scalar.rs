//! The scalar reference: one walk at a time, plain code, early returns.
//!
//! Generic over a scalar lane `S` (`f32`, the reference; `f64`, the oracle of
//! the stability checks). Every physical quantity goes through the shared
//! kernels (`interface`, `medium`); this file only decides what happens next.
//!
//! A walk's position is `(layer, z)`: layer `l` lies between interfaces `l` and
//! `l + 1`, and `z` is the depth below interface `l`. Directions are *travel*
//! directions inside the walk; an interface is sampled with `a = -d`, the
//! direction the light arrives from. Random numbers are drawn in a fixed number
//! per event (1 for the hero channel at the start, 3 at an interface, 1 per
//! free flight, 2 for a phase sample, 1 for Russian roulette after each event),
//! so the wavefront engine can replay a walk exactly.

use super::{power_heuristic, MeanVar, Settings};
use crate::interface::InterfaceLanes;
use crate::lane::{Lane, Rgb, V3};
use crate::medium;
use crate::rng::{Stream, WalkRng};
use crate::stack::LayerStack;

/// A one-lane number: `f32` or `f64`.
pub trait Scalar: Lane<Mask = bool> + PartialOrd {}
impl Scalar for f32 {}
impl Scalar for f64 {}

/// A medium with its parameters in the engine's precision.
#[derive(Clone, Copy, Debug)]
struct MediumS<S: Lane> {
    thickness: S,
    sigma_t: Rgb<S>,
    albedo: Rgb<S>,
    g: S,
    scatters: bool,
    attenuates: bool,
}

/// Where a direction leaving an interface goes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Next<S> {
    /// Into layer `l` at depth `z`.
    Layer(usize, S),
    /// Out of the stack through the top.
    OutTop,
    /// Out of the stack through the bottom.
    OutBottom,
}

/// One segment of the adjoint chain sampled from `wo` (see `docs/method-notes.md`):
/// light leaving interface `start` (or a collision in `layer`) along `u`
/// reaches the viewer with the cosine-weighted factor `v`.
#[derive(Clone, Copy, Debug)]
struct Segment<S: Lane> {
    layer: usize,
    start: usize,
    u: V3<S>,
    v: Rgb<S>,
    /// Density of `-u` from `wo` when the exit is rough (MIS with continuation);
    /// 0 when no other strategy can produce this connection.
    mis_pdf: S,
}

/// The layered BSDF, one walk at a time.
#[derive(Clone, Debug)]
pub struct ScalarEngine<S: Scalar> {
    pub(super) stack: LayerStack,
    pub(super) ifaces: Vec<InterfaceLanes<S>>,
    media: Vec<Option<MediumS<S>>>,
    settings: Settings,
}

impl<S: Scalar> ScalarEngine<S> {
    /// Prepares `stack` for the scalar engine.
    pub fn new(stack: &LayerStack, settings: Settings) -> Self {
        let n = stack.len();
        let ifaces = (0..n).map(|i| stack.interface_lanes::<S>(i)).collect();
        let media = (0..n.saturating_sub(1))
            .map(|l| {
                stack.medium(l).map(|m| MediumS {
                    thickness: S::splat(m.thickness),
                    sigma_t: Rgb::from_array(m.sigma_t),
                    albedo: Rgb::from_array(m.albedo),
                    g: S::splat(m.g),
                    scatters: m.scatters(),
                    attenuates: m.attenuates(),
                })
            })
            .collect();
        ScalarEngine {
            stack: stack.clone(),
            ifaces,
            media,
            settings,
        }
    }

    /// The stack.
    pub fn stack(&self) -> &LayerStack {
        &self.stack
    }

    pub(super) fn n(&self) -> usize {
        self.ifaces.len()
    }

    fn thickness(&self, l: usize) -> S {
        self.media[l].map_or(S::zero(), |m| m.thickness)
    }

    /// Where direction `d` leaving interface `i` goes.
    pub(super) fn next(&self, i: usize, d: V3<S>) -> Next<S> {
        if d.z > S::zero() {
            if i == 0 {
                Next::OutTop
            } else {
                Next::Layer(i - 1, self.thickness(i - 1))
            }
        } else if i + 1 == self.n() {
            Next::OutBottom
        } else {
            Next::Layer(i, S::zero())
        }
    }

    /// The layer adjacent to exit interface `e`, and the interface across it.
    pub(super) fn exit_region(&self, e: usize) -> (usize, usize) {
        let n = self.n();
        match (e, n) {
            (_, 1) => (usize::MAX, usize::MAX),
            (0, _) => (0, 1),
            _ => (n - 2, n - 2),
        }
    }

    /// Depth left to the boundary `d` heads for, and that interface's index.
    fn to_boundary(&self, l: usize, z: S, d: V3<S>) -> (S, usize) {
        if d.z > S::zero() {
            (z, l)
        } else {
            ((self.thickness(l) - z).max(S::zero()), l + 1)
        }
    }

    /// Transmittance over depth `dz` along `d` in layer `l` (1 if clear).
    fn transmittance(&self, l: usize, dz: S, d: V3<S>) -> Rgb<S> {
        match self.media[l] {
            Some(m) if m.attenuates => medium::transmittance(m.sigma_t, dz, d.z.abs()),
            _ => Rgb::one(),
        }
    }

    /// Russian roulette after `settings.rr_start` events; always consumes one
    /// uniform. Returns false if the walk ends.
    fn survive(&self, beta: &mut Rgb<S>, events: u32, rng: &mut WalkRng) -> bool {
        let u = S::splat(rng.uniform() as f64);
        if let Some(cap) = self.settings.max_depth {
            if events >= cap {
                return false;
            }
        }
        if events < self.settings.rr_start {
            return true;
        }
        let q = beta.max_channel().min(S::one());
        if !q.gt(S::zero()) {
            return false;
        }
        if u < q {
            *beta = beta.scale(S::one() / q);
            true
        } else {
            false
        }
    }

    /// Three uniforms for an interface event.
    pub(super) fn u3(rng: &mut WalkRng) -> (S, S, S) {
        let a = rng.uniform() as f64;
        let b = rng.uniform() as f64;
        let c = rng.uniform() as f64;
        (S::splat(a), S::splat(b), S::splat(c))
    }

    // ------------------------------------------------------------------ sample

    /// The analog random walk from `wi` (method.md §5). `None` if the walk was
    /// absorbed (or `wi` sees nothing). Directions are in the stack's frame.
    pub fn sample(&self, wi: [f64; 3], rng: &mut WalkRng) -> Option<super::Sample> {
        let o = super::orient(&self.stack, wi, None)?;
        let n = self.n();
        let wi_v = v3::<S>(o.wi);
        let mut i = if wi_v.z > S::zero() { 0 } else { n - 1 };
        let mut a = wi_v;
        let mut beta = Rgb::<S>::one();
        let mut specular = true;
        let mut events = 0u32;
        let mut order = 0u32;
        let hero = hero_channel::<S>(rng);
        let mut ratios = Rgb::<S>::one();
        loop {
            // Interface event.
            let (us, u1, u2) = Self::u3(rng);
            let s = self.ifaces[i].sample(a, us, u1, u2, false);
            if !s.valid {
                return None;
            }
            beta *= s.weight;
            specular &= s.delta;
            let mut d = s.b;
            events += 1;
            let (l, mut z) = match self.next(i, d) {
                Next::Layer(l, z) => (l, z),
                Next::OutTop | Next::OutBottom => {
                    let wo = o.apply([d.x.lane(0), d.y.lane(0), d.z.lane(0)]);
                    return Some(super::Sample {
                        wo: glam::Vec3::new(wo[0] as f32, wo[1] as f32, wo[2] as f32),
                        weight: rgb_f32(beta),
                        reflection: (d.z > S::zero()) == (wi_v.z > S::zero()),
                        specular,
                    });
                }
            };
            if !self.survive(&mut beta, events, rng) {
                return None;
            }
            // Travel through layer l until the walk reaches an interface.
            loop {
                let (dz, next_i) = self.to_boundary(l, z, d);
                match self.media[l] {
                    Some(m) if m.scatters => {
                        let mu = d.z.abs();
                        let ud = S::splat(rng.uniform() as f64);
                        let max_t = if mu > S::zero() {
                            dz / mu
                        } else {
                            S::splat(f64::MAX)
                        };
                        let ff = medium::free_flight(m.sigma_t, m.albedo, max_t, hero, ud, ratios);
                        beta *= ff.weight;
                        ratios = ff.ratios;
                        if !ff.collide {
                            if mu <= S::zero() {
                                return None;
                            }
                            i = next_i;
                            break;
                        }
                        order += 1;
                        if self.settings.max_scatter_order.is_some_and(|k| order > k) {
                            return None;
                        }
                        z = move_depth(z, d, ff.distance);
                        let (u1, u2) = (
                            S::splat(rng.uniform() as f64),
                            S::splat(rng.uniform() as f64),
                        );
                        d = medium::hg_sample(m.g, d, u1, u2);
                        specular = false;
                        events += 1;
                        if !self.survive(&mut beta, events, rng) {
                            return None;
                        }
                    }
                    Some(m) if m.attenuates => {
                        beta *= medium::transmittance(m.sigma_t, dz, d.z.abs());
                        i = next_i;
                        break;
                    }
                    _ => {
                        if d.z == S::zero() {
                            return None;
                        }
                        i = next_i;
                        break;
                    }
                }
            }
            a = -d;
        }
    }

    /// Directional albedo from `n` walks of [`ScalarEngine::sample`]:
    /// reflected and transmitted fractions with standard errors.
    pub fn albedo(&self, wi: [f64; 3], n: u64, seed: u64, query: u64) -> super::Albedo {
        let mut r = MeanVar::new();
        let mut t = MeanVar::new();
        for k in 0..n {
            let mut rng = WalkRng::new(seed, query, k, Stream::Walk);
            let (mut xr, mut xt) = ([0.0; 3], [0.0; 3]);
            if let Some(s) = self.sample(wi, &mut rng) {
                let w = s.weight.map(|x| x as f64);
                if s.reflection {
                    xr = w;
                } else {
                    xt = w;
                }
            }
            r.push(xr);
            t.push(xt);
        }
        super::Albedo {
            reflected: r.estimate(),
            transmitted: t.estimate(),
        }
    }

    // -------------------------------------------------------------------- eval

    /// Samples the adjoint chain from `wo` through the exit interface `e`
    /// (and on through delta interfaces when the exit is smooth).
    fn adjoint_chain(&self, wo: V3<S>, e: usize, rng: &mut WalkRng, out: &mut Vec<Segment<S>>) {
        out.clear();
        let n = self.n();
        if n < 2 {
            return;
        }
        let ex = &self.ifaces[e];
        let (us, u1, u2) = Self::u3(rng);
        let s = ex.sample(wo, us, u1, u2, true);
        if !s.valid {
            return;
        }
        let dp = s.b; // into the stack
        let (layer, start) = self.exit_region(e);
        let smooth = self.stack.interface(e).smooth;
        let v = if smooth {
            // (1 - F) (n_o / n_in)²: the delta lobe of f(d' → wo), times |cos d'|.
            let (n_o, n_in) = sides(ex, wo);
            s.weight.scale((n_o / n_in).sqr())
        } else {
            ex.eval(dp, wo).scale(dp.z.abs() / s.pdf)
        };
        out.push(Segment {
            layer,
            start,
            u: -dp,
            v,
            mis_pdf: if smooth { S::zero() } else { s.pdf },
        });
        if !smooth {
            return;
        }
        // Continue through delta interfaces: their vertices cannot connect.
        let mut events = 1u32;
        loop {
            let last = *out.last().expect("chain has a segment");
            let j = last.start;
            if !self.stack.interface(j).smooth || out.len() >= MAX_CHAIN {
                return;
            }
            let crossed =
                last.v * self.transmittance(last.layer, self.thickness(last.layer), last.u);
            let (us, u1, u2) = Self::u3(rng);
            let a = last.u;
            let s = self.ifaces[j].sample(a, us, u1, u2, false);
            if !s.valid {
                return;
            }
            let b = s.b;
            let mut v = crossed * s.weight;
            if (a.z * b.z) < S::zero() {
                let (n_a, n_b) = sides(&self.ifaces[j], a);
                v = v.scale((n_a / n_b).sqr());
            }
            let (layer, start) = if b.z > S::zero() {
                if j == 0 {
                    return;
                }
                (j - 1, j - 1)
            } else {
                if j + 1 == n {
                    return;
                }
                (j, j + 1)
            };
            events += 1;
            let u = S::splat(rng.uniform() as f64);
            if events > self.settings.rr_start {
                let q = v.max_channel().min(S::one());
                if !u.lt(q) {
                    return;
                }
                v = v.scale(S::one() / q);
            }
            out.push(Segment {
                layer,
                start,
                u: -b,
                v,
                mis_pdf: S::zero(),
            });
        }
    }

    /// The unidirectional estimator (method.md §4): mean of `n` walks plus the
    /// exact first-order term, with its standard error.
    pub fn eval(
        &self,
        wi: [f64; 3],
        wo: [f64; 3],
        n: u64,
        seed: u64,
        query: u64,
    ) -> super::Estimate {
        let mut acc = MeanVar::new();
        let Some(o) = super::orient(&self.stack, wi, Some(wo)) else {
            for _ in 0..n {
                acc.push([0.0; 3]);
            }
            return acc.estimate();
        };
        let wi = v3::<S>(o.wi);
        let wo = v3::<S>(o.apply(wo));
        let nn = self.n();
        let e_in = if wi.z > S::zero() { 0 } else { nn - 1 };
        let e_out = if wo.z > S::zero() { 0 } else { nn - 1 };
        // First-order term: the entrance alone, when it is also the exit.
        let direct = if e_in == e_out {
            rgb_f64(self.ifaces[e_in].eval(wi, wo))
        } else {
            [0.0; 3]
        };
        let mut chain = Vec::with_capacity(8);
        for k in 0..n {
            let mut rng_a = WalkRng::new(seed, query, k, Stream::Adjoint);
            self.adjoint_chain(wo, e_out, &mut rng_a, &mut chain);
            let mut rng = WalkRng::new(seed, query, k, Stream::Walk);
            let x = self.eval_walk(wi, wo, e_in, e_out, &chain, &mut rng);
            acc.push(rgb_f64(x));
        }
        acc.estimate_plus(direct)
    }

    /// One walk of the unidirectional estimator; returns its estimate of
    /// `f - first-order term`.
    fn eval_walk(
        &self,
        wi: V3<S>,
        wo: V3<S>,
        e_in: usize,
        e_out: usize,
        chain: &[Segment<S>],
        rng: &mut WalkRng,
    ) -> Rgb<S> {
        let mut acc = Rgb::<S>::zero();
        let exit = &self.ifaces[e_out];
        let exit_rough = !self.stack.interface(e_out).smooth;
        // The layer next to the exit and the interface across it: continuations
        // from there reach the exit directly.
        let (l0, k0) = self.exit_region(e_out);
        let toward_exit = |d: V3<S>| {
            if e_out == 0 {
                d.z > S::zero()
            } else {
                d.z < S::zero()
            }
        };
        let mis = self.settings.mis;

        let mut i = e_in;
        let mut a = wi;
        let mut beta = Rgb::<S>::one();
        let mut first = true;
        let mut events = 0u32;
        let mut order = 0u32;
        let hero = hero_channel::<S>(rng);
        let mut ratios = Rgb::<S>::one();
        loop {
            let iface = &self.ifaces[i];
            // Next-event estimation from this surface vertex.
            for seg in chain.iter().filter(|s| s.start == i) {
                let f = iface.eval(a, seg.u);
                if f.max_channel() <= S::zero() {
                    continue;
                }
                let t = self.transmittance(seg.layer, self.thickness(seg.layer), seg.u);
                let w = if mis && seg.mis_pdf > S::zero() {
                    let pv = iface.pdf(a, seg.u, first);
                    S::splat(power_heuristic(seg.mis_pdf.lane(0), pv.lane(0)))
                } else {
                    S::one()
                };
                acc += beta * f * t * seg.v.scale(w);
            }
            // Continue the walk.
            let (us, u1, u2) = Self::u3(rng);
            let s = iface.sample(a, us, u1, u2, first);
            if !s.valid {
                return acc;
            }
            beta *= s.weight;
            let mut d = s.b;
            first = false;
            events += 1;
            let next = self.next(i, d);
            // Continuation reaches a rough exit: evaluate it towards wo.
            if exit_rough && i == k0 && toward_exit(d) {
                if let Next::Layer(l, _) = next {
                    let t = self.transmittance(l, self.thickness(l), d);
                    let fe = exit.eval(-d, wo);
                    // A delta vertex cannot be reached by next-event estimation;
                    // without MIS, next-event estimation takes the rest.
                    let w = if s.delta {
                        S::one()
                    } else if !mis {
                        S::zero()
                    } else {
                        let pe = exit.pdf(wo, -d, true);
                        S::splat(power_heuristic(s.pdf.lane(0), pe.lane(0)))
                    };
                    acc += beta * t * fe.scale(w);
                }
            }
            let (l, mut z) = match next {
                Next::Layer(l, z) => (l, z),
                _ => return acc,
            };
            if !self.survive(&mut beta, events, rng) {
                return acc;
            }
            // Travel through layer l.
            loop {
                let (dz, next_i) = self.to_boundary(l, z, d);
                match self.media[l] {
                    Some(m) if m.scatters => {
                        let mu = d.z.abs();
                        let ud = S::splat(rng.uniform() as f64);
                        let max_t = if mu > S::zero() {
                            dz / mu
                        } else {
                            S::splat(f64::MAX)
                        };
                        let ff = medium::free_flight(m.sigma_t, m.albedo, max_t, hero, ud, ratios);
                        beta *= ff.weight;
                        ratios = ff.ratios;
                        if !ff.collide {
                            if mu <= S::zero() {
                                return acc;
                            }
                            i = next_i;
                            break;
                        }
                        order += 1;
                        if self.settings.max_scatter_order.is_some_and(|k| order > k) {
                            return acc;
                        }
                        z = move_depth(z, d, ff.distance);
                        // Next-event estimation from this medium vertex.
                        for seg in chain.iter().filter(|s| s.layer == l) {
                            let ph = medium::hg_eval(m.g, d.dot(seg.u));
                            let (dz_e, _) = self.to_boundary(l, z, seg.u);
                            let t = medium::transmittance(m.sigma_t, dz_e, seg.u.z.abs());
                            let w = if mis && seg.mis_pdf > S::zero() {
                                S::splat(power_heuristic(seg.mis_pdf.lane(0), ph.lane(0)))
                            } else {
                                S::one()
                            };
                            let cos_u = seg.u.z.abs();
                            if cos_u > S::zero() {
                                acc += beta * t * seg.v.scale(ph * w / cos_u);
                            }
                        }
                        let (u1, u2) = (
                            S::splat(rng.uniform() as f64),
                            S::splat(rng.uniform() as f64),
                        );
                        let dn = medium::hg_sample(m.g, d, u1, u2);
                        // Continuation reaches a rough exit from this layer.
                        if exit_rough && mis && l == l0 && toward_exit(dn) {
                            let (dz_e, _) = self.to_boundary(l, z, dn);
                            let t = medium::transmittance(m.sigma_t, dz_e, dn.z.abs());
                            let fe = exit.eval(-dn, wo);
                            let pv = medium::hg_eval(m.g, d.dot(dn));
                            let pe = exit.pdf(wo, -dn, true);
                            let w = S::splat(power_heuristic(pv.lane(0), pe.lane(0)));
                            acc += beta * t * fe.scale(w);
                        }
                        d = dn;
                        events += 1;
                        if !self.survive(&mut beta, events, rng) {
                            return acc;
                        }
                    }
                    Some(m) if m.attenuates => {
                        beta *= medium::transmittance(m.sigma_t, dz, d.z.abs());
                        i = next_i;
                        break;
                    }
                    _ => {
                        if d.z == S::zero() {
                            return acc;
                        }
                        i = next_i;
                        break;
                    }
                }
            }
            a = -d;
        }
    }
}

/// The walk's hero channel (0, 1 or 2) for spectral MIS: one uniform.
fn hero_channel<S: Scalar>(rng: &mut WalkRng) -> S {
    (S::splat(rng.uniform() as f64) * S::splat(3.0))
        .floor()
        .min(S::splat(2.0))
}

/// The adjoint chain never exceeds this many segments (a guard against a
/// lossless loop of delta interfaces; Russian roulette ends real chains long
/// before it).
const MAX_CHAIN: usize = 256;

/// `(n_a, n_b)`: IOR on the side of `a` and on the other side of an interface.
pub(super) fn sides<S: Scalar>(it: &InterfaceLanes<S>, a: V3<S>) -> (S, S) {
    if a.z > S::zero() {
        (it.n_above, it.n_below)
    } else {
        (it.n_below, it.n_above)
    }
}

/// Depth after travelling `t` along `d` from depth `z` (depth grows downwards).
fn move_depth<S: Scalar>(z: S, d: V3<S>, t: S) -> S {
    (z - d.z * t).max(S::zero())
}

pub(super) fn v3<S: Scalar>(w: [f64; 3]) -> V3<S> {
    let l = (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt();
    V3::new(S::splat(w[0] / l), S::splat(w[1] / l), S::splat(w[2] / l))
}

fn rgb_f64<S: Scalar>(c: Rgb<S>) -> [f64; 3] {
    [c.r.lane(0), c.g.lane(0), c.b.lane(0)]
}

fn rgb_f32<S: Scalar>(c: Rgb<S>) -> [f32; 3] {
    rgb_f64(c).map(|x| x as f32)
}
