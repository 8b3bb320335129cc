//! The bidirectional estimator of `eval` (method.md §4, the paper's second
//! estimator), written once over lanes: the scalar engine runs it on one
//! lane, the wavefront on one query-walk pair per lane.
//!
//! A walk traces a *light subpath* from `wi` (entering through the entrance
//! interface) and an *eye subpath* from `wo` (entering through the exit
//! interface, carrying light-sense values), then connects every light vertex
//! to every eye vertex that shares a layer with it. A connection draws its
//! direction from one vertex's lobe (its BSDF or phase function) and
//! evaluates the other vertex, with the transmittance between their depths;
//! each pair is connected twice, once from each side. Every contribution is
//! weighted by the power heuristic over all the strategies that could have
//! made its path (`Path::weight`), so that the weights of a path sum to one.
//!
//! **The path measure.** A path `v_1 … v_n` (entrance `v_1`, exit `v_n`)
//! with directions `d_1 … d_{n−1}` has the value `Π f(v_i) · Π G(d_i)`: an
//! interface's BSDF in the light's sense, or at a medium collision `σ_s`
//! times the phase function; a segment's transmittance times `|d.z|` once
//! per interface it joins, less one (method.md §3: the `1/|d.z|` of a depth
//! against the cosine of a solid angle). A strategy samples each direction
//! from one of its two vertices and each collision depth by a free flight
//! from one of its neighbours; its density is the product of those densities
//! (an interface reached without collision counts the probability of that).
//!
//! **Which strategies.** Splitting the path between `v_s` and `v_{s+1}`
//! (`1 ≤ s < n`), the light side samples `d_1 … d_{s−1}` and the depths of
//! `v_2 … v_s`, the eye side `d_{s+1} … d_{n−1}` and the depths of `v_{s+1} …
//! v_{n−1}`, and `d_s` is drawn by `v_s` (strategy `(s, L)`) or by `v_{s+1}`
//! (`(s, E)`). A strategy that would *evaluate* a smooth interface (`v_{s+1}`
//! for `L`, `v_s` for `E`) cannot make the path and is skipped; a smooth
//! interface that *samples* takes part with a density of 1 (the same
//! placeholder in every strategy, so the weights remain a partition of
//! unity). Russian roulette stays out of the densities, on every strategy
//! alike. Densities of collision depths are the channel mixture of the free
//! flight (`medium::collision_density`), a deterministic function of the
//! path, as every weight must be.
//!
//! **Subpaths.** Both are random walks of `sample()`'s kind: one vertex per
//! step ([`BidirWalk::step`]: sample a direction at the vertex, then a free
//! flight or a crossing to the next vertex), so that a subpath's vertices
//! are rows of lanes (structure of arrays) and a lane whose subpath ended
//! can begin another ([`BidirWalk::begin`]) while the others go on. Russian
//! roulette ends them, or the limit of `√max_events` vertices
//! ([`events::subpath_limit`]): a walk makes at most `max_events`
//! connections. The eye subpath samples interfaces from the side light leaves by and
//! weights each step with the light-sense value (`f(b → a)` rather than `f(a
//! → b)`: the η² of refraction and the shading normal's asymmetry included);
//! collisions need no change, as `σ_s · phase` is reciprocal.
//!
//! The estimator always combines its strategies by MIS (`Settings::mis`
//! concerns the unidirectional one). It keeps the paths of at most as many
//! vertices as a subpath may have (interface events and collisions,
//! entrance and exit included), whose every strategy the limited subpaths
//! reach: a cut of its own, not the unidirectional walk's, which the
//! default limit never makes on the stacks of the test suite.
//!
//! A phase function without a closed form (diffuse SGGX flakes) is
//! evaluated by its unbiased one-sample estimate, on uniforms of its own;
//! its weights take the isotropic density instead of its own (any function
//! of the path keeps them a partition of unity). A cap on the scattering
//! order (`Settings::max_scatter_order`) counts a path's collisions on both
//! subpaths: a subpath stops past it, a connection beyond it scores nothing.

use super::events;
use super::layout::{LayerKind, Layout, MediumLanes};
use super::settings::Settings;
use crate::interface::InterfaceLanes;
use crate::lane::{Lane, LaneMask, Rgb, MAX_LANES, V3};
use crate::medium;

/// The stack as the bidirectional walk reads it.
pub struct BidirWalk<'a, L: Lane> {
    /// Interfaces, top first.
    pub ifaces: &'a [InterfaceLanes<L>],
    /// Media, layer `l` between interfaces `l` and `l + 1`.
    pub media: &'a [MediumLanes<L>],
    /// Walk settings, with the subpaths' limit of events
    /// ([`events::subpath_limit`]) as theirs.
    settings: Settings,
}

impl<'a, L: Lane> BidirWalk<'a, L> {
    /// The walk of a stack's interfaces and media under `settings`.
    pub fn new(
        ifaces: &'a [InterfaceLanes<L>],
        media: &'a [MediumLanes<L>],
        settings: &Settings,
    ) -> Self {
        let settings = Settings {
            max_events: events::subpath_limit(settings.max_events),
            rr_threshold: 1.0,
            ..*settings
        };
        BidirWalk {
            ifaces,
            media,
            settings,
        }
    }
}

/// A subpath vertex, per lane.
#[derive(Clone, Copy, Debug)]
pub struct Vertex<L: Lane> {
    /// Lanes where the subpath has this vertex.
    pub exists: L::Mask,
    /// On an interface (else a medium collision).
    pub surface: L::Mask,
    /// A smooth interface: its lobes are deltas, never evaluated.
    pub delta: L::Mask,
    /// Interface index (surface) or layer (collision).
    pub idx: L,
    /// Depth in layer `idx` (collisions).
    pub z: L,
    /// The subpath's arrival, pointing away from the vertex.
    pub a: V3<L>,
    /// The subpath's throughput on arrival (a collision's includes its `σ_s`).
    pub beta: Rgb<L>,
    /// The density of the direction the subpath sampled here (1 at a delta).
    pub own: L,
    /// The density with which this vertex samples the arrival `a` given
    /// that direction: the other side's (1 at a delta).
    pub other: L,
    /// The density of the free flight that reached this vertex from the
    /// previous one (a collision depth, or no collision up to an interface).
    pub land: L,
    /// The same along the next segment, from the next vertex.
    pub land_rev: L,
    /// Collisions among the subpath's vertices up to this one.
    pub order: L,
    /// The power-heuristic terms of the strategies that split the subpath
    /// between its first vertex and this one, relative to a strategy that
    /// splits it right after this vertex (see `Path::weight`): a connection
    /// reads them here instead of walking the subpath again.
    pub tail: L,
}

/// Subpaths being traced, one per lane: the vertex each is at (`v.exists`:
/// the lanes whose subpath goes on) and its walk's state.
#[derive(Clone, Copy, Debug)]
pub struct Tracing<L: Lane> {
    v: Vertex<L>,
    hero: L,
    ratios: Rgb<L>,
    events: L,
    order: L,
    /// Lanes whose vertex is their subpath's first.
    first: L::Mask,
    /// The subpath's last finished vertex, and the density the vertex
    /// before it sampled its direction with (for [`Vertex::tail`]).
    prev: Vertex<L>,
    prev_own: L,
    /// Finished vertices of the subpath.
    count: L,
    /// Lanes whose subpath the limit of events ended.
    cut: L::Mask,
}

impl<L: Lane> Tracing<L> {
    /// No subpath on any lane ([`BidirWalk::begin`] starts them).
    pub fn idle() -> Self {
        let zero = L::zero();
        Tracing {
            v: Vertex::idle(),
            hero: zero,
            ratios: Rgb::one(),
            events: zero,
            order: zero,
            first: L::Mask::splat(false),
            prev: Vertex::idle(),
            prev_own: L::one(),
            count: zero,
            cut: L::Mask::splat(false),
        }
    }

    /// The lanes whose subpath goes on.
    pub fn active(&self) -> L::Mask {
        self.v.exists
    }

    /// The lanes whose subpath the limit of events ended.
    pub fn cut(&self) -> L::Mask {
        self.cut
    }
}

/// Working memory of a walk: the two subpaths' vertices.
#[derive(Clone, Debug, Default)]
pub struct Buffers<L: Lane> {
    light: Vec<Vertex<L>>,
    eye: Vec<Vertex<L>>,
}

impl<L: Lane> Buffers<L> {
    /// Fills these buffers with other walks' subpaths: lane `j` gets the
    /// light subpath `light(j) = (rows, lane)` (lane `lane` of those rows)
    /// and the eye subpath `eye(j)`, in `rows = (light, eye)` rows, the
    /// longest of those subpaths (a lane's rows past its own subpath are
    /// marked absent). Walks then run their connections in the company of
    /// walks as long as they are ([`BidirWalk::connect`]).
    pub fn gather<'b>(
        &mut self,
        rows: (usize, usize),
        light: impl Fn(usize) -> (&'b [Vertex<L>], usize),
        eye: impl Fn(usize) -> (&'b [Vertex<L>], usize),
    ) where
        L: 'b,
    {
        gather_rows(&mut self.light, rows.0, light);
        gather_rows(&mut self.eye, rows.1, eye);
    }
}

/// `out` row `r < len`, lane `j`: row `r` of the subpath `src(j)`, as in
/// [`Buffers::gather`]. (Arrays, not vectors: a warm walk allocates
/// nothing.)
fn gather_rows<'b, L: Lane + 'b>(
    out: &mut Vec<Vertex<L>>,
    len: usize,
    src: impl Fn(usize) -> (&'b [Vertex<L>], usize),
) {
    let src: [_; MAX_LANES] = std::array::from_fn(|j| src(j.min(L::LANES - 1)));
    // A lane's rows past its subpath hold the idle vertex's plain values:
    // the connections compute on every lane, and a subpath's last vertex
    // repeated there slowed them (docs/performance.md).
    let none = Vertex::idle();
    out.clear();
    for r in 0..len {
        let row: [_; MAX_LANES] = std::array::from_fn(|j| {
            let (rows, lane) = src[j];
            match rows.get(r) {
                Some(v) => (v, lane, v.exists.lane(lane)),
                None => (&none, lane, false),
            }
        });
        out.push(Vertex::gather(&row[..L::LANES]));
    }
}

impl<L: Lane> Vertex<L> {
    /// No vertex on any lane, its fields plain values (zeros and ones).
    pub fn idle() -> Self {
        let (zero, one, no) = (L::zero(), L::one(), L::Mask::splat(false));
        Vertex {
            exists: no,
            surface: no,
            delta: no,
            idx: zero,
            z: zero,
            a: V3::z_axis(),
            beta: Rgb::one(),
            own: one,
            other: one,
            land: one,
            land_rev: one,
            order: zero,
            tail: zero,
        }
    }

    /// `t` on the lanes of `m`, `f` elsewhere.
    pub fn select(m: L::Mask, t: &Self, f: &Self) -> Self {
        let mask = |a: L::Mask, b: L::Mask| (m & a) | (!m & b);
        let num = |a: L, b: L| L::select(m, a, b);
        Vertex {
            exists: mask(t.exists, f.exists),
            surface: mask(t.surface, f.surface),
            delta: mask(t.delta, f.delta),
            idx: num(t.idx, f.idx),
            z: num(t.z, f.z),
            a: V3::select(m, t.a, f.a),
            beta: Rgb::select(m, t.beta, f.beta),
            own: num(t.own, f.own),
            other: num(t.other, f.other),
            land: num(t.land, f.land),
            land_rev: num(t.land_rev, f.land_rev),
            order: num(t.order, f.order),
            tail: num(t.tail, f.tail),
        }
    }

    /// Lane `j` of the result is lane `lane` of `v` for `src[j] = (v, lane,
    /// exists)`.
    fn gather(src: &[(&Vertex<L>, usize, bool)]) -> Self {
        // Each field's lanes, read straight from the sources (a macro, not
        // closures over accessors, so that every read is inlined).
        macro_rules! lanes {
            ($t:ident, $($f:tt)+) => {
                $t::from_fn(|j| src[j].0.$($f)+.lane(src[j].1))
            };
        }
        Vertex {
            exists: L::Mask::from_fn(|j| src[j].2),
            surface: lanes!(LaneMask, surface),
            delta: lanes!(LaneMask, delta),
            idx: lanes!(Lane, idx),
            z: lanes!(Lane, z),
            a: V3::new(lanes!(Lane, a.x), lanes!(Lane, a.y), lanes!(Lane, a.z)),
            beta: Rgb::new(
                lanes!(Lane, beta.r),
                lanes!(Lane, beta.g),
                lanes!(Lane, beta.b),
            ),
            own: lanes!(Lane, own),
            other: lanes!(Lane, other),
            land: lanes!(Lane, land),
            land_rev: lanes!(Lane, land_rev),
            order: lanes!(Lane, order),
            tail: lanes!(Lane, tail),
        }
    }
}

thread_local! {
    /// This thread's working memory, one of each type, kept between calls so
    /// that a warm thread's bidirectional walks allocate nothing.
    static KEPT: std::cell::RefCell<Vec<Box<dyn std::any::Any>>> =
        const { std::cell::RefCell::new(Vec::new()) };
}

/// Runs `f` with this thread's kept `T` (a new one the first time), and
/// keeps it again, grown as `f` needed. (The wavefront's `with_kept` keeps
/// one type per static; the bidirectional walks' memory is generic over the
/// lane type, so it is kept by type instead.)
pub fn with_kept_by_type<T: Default + 'static, R>(f: impl FnOnce(&mut T) -> R) -> R {
    // (`try_with`: from a thread-local's destructor, fresh memory.)
    let kept = KEPT.try_with(|k| {
        let mut k = k.borrow_mut();
        let i = k.iter().position(|b| b.is::<T>())?;
        k.swap_remove(i).downcast::<T>().ok()
    });
    // (Kept boxed: unboxing would allocate a new box on every call.)
    let mut b: Box<T> = kept.ok().flatten().unwrap_or_default();
    let r = f(&mut b);
    let _ = KEPT.try_with(|k| k.borrow_mut().push(b));
    r
}

/// A connection's own values at one end: the vertex's term (value) in the
/// light's sense, and the densities with which it samples the connecting
/// direction (`own`) and, given it, its own arrival (`other`).
#[derive(Clone, Copy)]
struct End<L: Lane> {
    value: Rgb<L>,
    own: L,
    other: L,
}

/// Where a connection runs: the layer, the depth it crosses, the lanes
/// where the direction from one vertex reaches the other.
#[derive(Clone, Copy)]
struct Reach<L: Lane> {
    ok: L::Mask,
    layer: L,
    dz: L,
}

impl<L: Lane> BidirWalk<'_, L> {
    fn n(&self) -> usize {
        self.ifaces.len()
    }

    fn layout(&self) -> Layout {
        Layout { n: self.n() }
    }

    /// Interface `i[j]` on lane `j`.
    fn at(&self, i: L) -> InterfaceLanes<L> {
        super::layout::iface_at(self.ifaces, i)
    }

    fn thickness(&self, l: L) -> L {
        super::layout::thickness_at(self.media, l)
    }

    /// Transmittance across `dz` of layer `l` along `d`, and the densities
    /// of a free flight along that segment: no collision (an interface at
    /// its end), a collision at its end. Clear and absorbing layers are
    /// crossed without sampling (both densities 1).
    fn segment(&self, l: L, dz: L, d: V3<L>, m: L::Mask) -> (Rgb<L>, L, L) {
        let (mut t, mut p_nc, mut p_col) = (Rgb::one(), L::one(), L::one());
        let mu = d.z.abs();
        for (ll, med) in self.media.iter().enumerate() {
            let here = m & l.eq(L::splat(ll as f64));
            if !here.any() || med.kind == LayerKind::Clear {
                continue;
            }
            t = Rgb::select(here, med.transmittance(dz, d), t);
            if med.kind == LayerKind::Scattering {
                let s = med.sigma_along(d);
                let dist = super::layout::flight_limit(dz, mu);
                let nc = s.map(|x| (-(x * dist)).exp()).average();
                p_nc = L::select(here, nc, p_nc);
                p_col = L::select(here, medium::collision_density(s, dist, mu), p_col);
            }
        }
        (t, p_nc, p_col)
    }

    /// Whether the travel direction `d` from vertex `f` reaches vertex `t`
    /// (sharing a layer, heading the right way), and across which depth.
    fn reach(&self, f: &Vertex<L>, t: &Vertex<L>, d: V3<L>, m: L::Mask) -> Reach<L> {
        let zero = L::zero();
        let up = d.z.gt(zero);
        let (l_s, out) = self.layout().enter(f.idx, up);
        let layer = L::select(f.surface, l_s, f.idx);
        let ok = m & f.exists & t.exists & !(f.surface & out) & d.z.abs().gt(zero);
        let h = self.thickness(layer);
        let z0 = L::select(f.surface, L::select(up, h, zero), f.z);
        let to_surface = t.idx.eq(self.layout().arrive(layer, up));
        let ahead = L::select(up, z0 - t.z, t.z - z0).gt(zero);
        let to_collision = t.idx.eq(layer) & ahead;
        let ok = ok & ((t.surface & to_surface) | (!t.surface & to_collision));
        let z1 = L::select(t.surface, L::select(up, zero, h), t.z);
        Reach {
            ok,
            layer,
            dz: (z1 - z0).abs(),
        }
    }

    /// The phase function's density for the weights at the collision
    /// lanes `m` of vertex `v`, from the travel direction `d_in` into
    /// `d_out`: its value where it has a closed form, else the isotropic
    /// density (any function of the path serves the weights; this one is
    /// positive wherever the phase is).
    fn phase_density(&self, v: &Vertex<L>, d_in: V3<L>, d_out: V3<L>, m: L::Mask) -> L {
        let mut p = L::zero();
        for (ll, med) in self.media.iter().enumerate() {
            let here = m & v.idx.eq(L::splat(ll as f64));
            if here.any() {
                let none = (L::zero(), L::zero());
                let x = if med.phase.exact() {
                    med.phase.eval(d_in, d_out, none)
                } else {
                    L::splat(std::f64::consts::FRAC_1_PI / 4.0)
                };
                p = L::select(here, x, p);
            }
        }
        p
    }

    /// The phase function's value at the collision lanes `m` of vertex
    /// `v`: closed form, or an unbiased estimate from uniforms of its own.
    fn phase_value(
        &self,
        v: &Vertex<L>,
        d_in: V3<L>,
        d_out: V3<L>,
        m: L::Mask,
        draw: &mut impl FnMut(L::Mask) -> L,
    ) -> L {
        let mut p = L::zero();
        for (ll, med) in self.media.iter().enumerate() {
            let here = m & v.idx.eq(L::splat(ll as f64));
            let e = events::estimate_uniforms(med, || draw(here));
            if here.any() {
                p = L::select(here, med.phase.eval(d_in, d_out, e), p);
            }
        }
        p
    }

    /// Vertex `v`'s end of a connection leaving it along `o` (pointing away
    /// from it): its value in the light's sense (`eye`: `v` is an eye
    /// vertex, light arrives from `o`), and its densities (`endpoint`: the
    /// subpath's first vertex, which samples transmission only).
    fn end(
        &self,
        v: &Vertex<L>,
        o: V3<L>,
        eye: bool,
        endpoint: bool,
        m: L::Mask,
        draw: &mut impl FnMut(L::Mask) -> L,
    ) -> End<L> {
        let s = m & v.surface;
        let c = m & !v.surface;
        let one = L::one();
        let mut e = End {
            value: Rgb::zero(),
            own: one,
            other: one,
        };
        if s.any() {
            let it = self.at(v.idx);
            let f = if eye {
                it.eval(o, v.a)
            } else {
                it.eval(v.a, o)
            };
            let first = L::Mask::splat(endpoint);
            let no = L::Mask::splat(false);
            e.value = Rgb::select(s, f, e.value);
            e.own = L::select(s & !v.delta, it.pdf(v.a, o, first), e.own);
            e.other = L::select(s & !v.delta, it.pdf(o, v.a, no), e.other);
        }
        let p = self.phase_value(v, -v.a, o, c, draw);
        if c.any() {
            e.value = Rgb::select(c, Rgb::splat(p), e.value);
            e.own = L::select(c, self.phase_density(v, -v.a, o, c), e.own);
            e.other = L::select(c, self.phase_density(v, -o, v.a, c), e.other);
        }
        e
    }

    /// Samples a direction `o` leaving vertex `v` (lanes `m`): `o`, the
    /// value over the density (an interface's BSDF without its cosine, in
    /// the light's sense; 1 at a collision), the densities of [`End`], and
    /// the lanes where a direction was made (`endpoint`: the lanes at a
    /// subpath's first vertex, which samples transmission only).
    #[allow(clippy::type_complexity)]
    fn sample_end(
        &self,
        v: &Vertex<L>,
        eye: bool,
        endpoint: L::Mask,
        m: L::Mask,
        draw: &mut impl FnMut(L::Mask) -> L,
    ) -> (V3<L>, Rgb<L>, L, L, L::Mask) {
        let s_m = m & v.surface;
        let c_m = m & !v.surface;
        let zero = L::zero();
        let mut o = V3::z_axis();
        let mut w = Rgb::zero();
        let (mut own, mut other) = (L::one(), L::one());
        let mut ok = L::Mask::splat(false);
        let u = (draw(s_m), draw(s_m), draw(s_m));
        if s_m.any() {
            let it = self.at(v.idx);
            let s = it.sample(v.a, u.0, u.1, u.2, endpoint);
            let good = s_m & s.valid;
            let weight = if eye {
                eye_weight(&it, v.a, &s)
            } else {
                s.weight
            };
            let cos = s.b.z.abs();
            let wv = weight.scale(L::div_or_zero(L::one(), cos, cos.gt(zero)));
            o = V3::select(s_m, s.b, o);
            w = Rgb::select(good, wv, w);
            let rough = good & !s.delta;
            own = L::select(rough, s.pdf, own);
            let no = L::Mask::splat(false);
            other = L::select(rough, it.pdf(s.b, v.a, no), other);
            ok = ok | (good & (s.delta | s.pdf.gt(zero)));
        }
        for (ll, med) in self.media.iter().enumerate() {
            let here = c_m & v.idx.eq(L::splat(ll as f64));
            let u = events::phase_uniforms(med, || draw(here));
            if !here.any() {
                continue;
            }
            let d = med.phase.sample(-v.a, u);
            let p = self.phase_density(v, -v.a, d, here);
            o = V3::select(here, d, o);
            w = Rgb::select(here, Rgb::one(), w);
            own = L::select(here, p, own);
            other = L::select(here, self.phase_density(v, -d, v.a, here), other);
            ok = ok | (here & p.gt(zero));
        }
        (o, w, own, other, ok)
    }

    /// Starts subpaths from `w` (pointing away from the stack) on lanes
    /// `m` of `t`, drawing their first uniform (the hero channel's); the
    /// other lanes keep their subpaths.
    pub fn begin(
        &self,
        w: V3<L>,
        m: L::Mask,
        t: &mut Tracing<L>,
        draw: &mut impl FnMut(L::Mask) -> L,
    ) {
        let zero = L::zero();
        let last = L::splat(self.n() as f64 - 1.0);
        let start = events::WalkStart::<L>::new(draw(m));
        let i0 = L::select(w.z.gt(zero), zero, last);
        let v = Vertex {
            exists: m,
            surface: m,
            delta: self.at(i0).smooth,
            idx: i0,
            a: w,
            ..Vertex::idle()
        };
        t.v = Vertex::select(m, &v, &t.v);
        t.hero = L::select(m, start.hero, t.hero);
        t.ratios = Rgb::select(m, start.ratios, t.ratios);
        t.events = L::select(m, start.events, t.events);
        t.order = L::select(m, start.order, t.order);
        t.first = t.first | m;
        t.count = L::select(m, zero, t.count);
        t.cut = t.cut & !m;
    }

    /// One vertex of the subpath on every lane of `t` that has one (the
    /// eye subpath's if `eye`): samples its direction, flies to the next
    /// vertex, and returns the finished vertex (its `exists`: the lanes that
    /// had one). `t` moves on to the next vertex, where the subpath goes on.
    pub fn step(
        &self,
        t: &mut Tracing<L>,
        eye: bool,
        draw: &mut impl FnMut(L::Mask) -> L,
    ) -> Vertex<L> {
        let zero = L::zero();
        let last = L::splat(self.n() as f64 - 1.0);
        let mut v = t.v;
        let endpoint = t.first & v.exists;
        t.first = t.first & !v.exists;
        let (d, wv, own, other, ok) = self.sample_end(&v, eye, endpoint, v.exists, draw);
        v.own = L::select(ok, own, v.own);
        v.other = L::select(ok, other, v.other);
        let mut alive = ok;
        // The travel weight of the step: the sampled value over its
        // density, with the cosine a surface vertex's direction carries.
        let cos = L::select(v.surface, d.z.abs(), L::one());
        let mut beta = Rgb::select(alive, v.beta * wv.scale(cos), v.beta);
        t.events = L::select(alive, t.events + L::one(), t.events);
        let up = d.z.gt(zero);
        let (l_s, out_s) = self.layout().enter(v.idx, up);
        let layer = L::select(v.surface, l_s, v.idx);
        // (A direction exactly parallel to the layer collides in a
        // scattering layer and ends in an inert one, as in every walk:
        // `events::free_flight`, `events::cross_inert`.)
        alive = alive & !(v.surface & out_s);
        t.cut = t.cut | (alive & events::reached_limit(t.events, &self.settings));
        alive = events::survive(&mut beta, t.events, draw(alive), alive, &self.settings);
        // The flight to the next vertex.
        let h = self.thickness(layer);
        let z0 = L::select(v.surface, L::select(up, h, zero), v.z);
        let mut z = z0;
        let mut col = L::Mask::splat(false);
        for (ll, med) in self.media.iter().enumerate() {
            let m = alive & layer.eq(L::splat(ll as f64));
            if !m.any() {
                continue;
            }
            if med.kind != LayerKind::Scattering {
                alive = alive & !events::cross_inert(med, z0, d, m, &mut beta);
            } else {
                let fl = events::Flight {
                    z: &mut z,
                    beta: &mut beta,
                    ratios: &mut t.ratios,
                    order: &mut t.order,
                };
                let cap = self.settings.max_scatter_order;
                let (hit, pass) = events::free_flight(med, fl, d, t.hero, draw(m), None, m, cap);
                alive = alive & !(m & !hit & !pass);
                col = col | hit;
            }
        }
        let arrive = self.layout().arrive(layer, up);
        let z_end = L::select(col, z, L::select(up, zero, h));
        let (_, p_nc, p_col) = self.segment(layer, (z_end - z0).abs(), d, alive);
        v.land_rev = L::select(alive, L::select(v.surface, p_nc, p_col), v.land_rev);
        let next_i = L::select(col, layer, arrive);
        let it = self.at(L::select(alive, next_i, zero).max(zero).min(last));
        t.v = Vertex {
            exists: alive,
            surface: !col,
            delta: !col & it.smooth,
            idx: next_i,
            z: z_end,
            a: -d,
            beta,
            own: L::one(),
            other: L::one(),
            land: L::select(col, p_col, p_nc),
            land_rev: L::one(),
            order: t.order,
            tail: zero,
        };
        v.tail = tail(&v, &t.prev, t.prev_own, t.count);
        let done = v.exists;
        t.prev_own = L::select(done, t.prev.own, t.prev_own);
        t.prev = Vertex::select(done, &v, &t.prev);
        t.count = L::select(done, t.count + L::one(), t.count);
        v
    }

    /// Traces a subpath from `w` (pointing away from the stack) on every
    /// lane, in step: the light subpath from `wi`, or (`eye`) the eye
    /// subpath from `wo`. Returns the lanes whose subpath the limit of
    /// events ended.
    fn trace(
        &self,
        w: V3<L>,
        eye: bool,
        out: &mut Vec<Vertex<L>>,
        draw: &mut impl FnMut(L::Mask) -> L,
    ) -> L::Mask {
        out.clear();
        let mut t = Tracing::idle();
        self.begin(w, L::Mask::splat(true), &mut t, draw);
        while t.active().any() {
            out.push(self.step(&mut t, eye, draw));
        }
        t.cut()
    }

    /// One bidirectional walk per lane: its estimate of `f(wi, wo)` without
    /// the first-order term (the entrance alone, which the engines add
    /// exactly), and the lanes where the limit of events ended a subpath.
    /// `draw(m)` returns a uniform for every lane of `m`.
    pub fn run(
        &self,
        wi: V3<L>,
        wo: V3<L>,
        buf: &mut Buffers<L>,
        mut draw: impl FnMut(L::Mask) -> L,
    ) -> (Rgb<L>, L::Mask) {
        if !self.connects() {
            return (Rgb::zero(), L::Mask::splat(false));
        }
        let cut = self.trace_both(wi, wo, buf, &mut draw);
        (self.connect(buf, draw), cut)
    }

    /// Whether the lengths of subpaths vary much from walk to walk: in a
    /// scattering layer or between three interfaces or more (where the
    /// wavefront refills a lane as its subpath ends, and regroups walks by
    /// their lengths before connecting).
    pub fn subpath_lengths_vary(&self) -> bool {
        self.n() >= 3 || (self.media.iter()).any(|m| m.kind == LayerKind::Scattering)
    }

    /// Whether the stack has paths to connect (two interfaces or more).
    pub fn connects(&self) -> bool {
        self.n() >= 2
    }

    /// The first half of [`Self::run`]: the light subpath from `wi`, then
    /// the eye subpath from `wo`, into `buf`; the lanes where the limit of
    /// events ended either.
    fn trace_both(
        &self,
        wi: V3<L>,
        wo: V3<L>,
        buf: &mut Buffers<L>,
        mut draw: impl FnMut(L::Mask) -> L,
    ) -> L::Mask {
        let light = self.trace(wi, false, &mut buf.light, &mut draw);
        light | self.trace(wo, true, &mut buf.eye, &mut draw)
    }

    /// The second half of [`Self::run`]: every connection of the traced
    /// subpaths, drawing after their tracing. A lane's value depends only
    /// on its own subpaths and draws, so the wavefront may regroup traced
    /// walks before connecting them.
    pub fn connect(&self, buf: &Buffers<L>, mut draw: impl FnMut(L::Mask) -> L) -> Rgb<L> {
        let Buffers { light, eye } = buf;
        let mut acc = Rgb::zero();
        for jy in 0..light.len() {
            for jz in 0..eye.len() {
                let (y, z) = (&light[jy], &eye[jz]);
                let within = match self.settings.max_scatter_order {
                    Some(k) => (y.order + z.order).le(L::splat(k as f64)),
                    None => L::Mask::splat(true),
                };
                // The limit keeps the paths of at most as many vertices
                // as a subpath may have, whose every strategy the limited
                // subpaths reach.
                if jy + jz + 2 > self.settings.max_events as usize {
                    continue;
                }
                let m = y.exists & z.exists & within & share_layer(y, z);
                if !m.any() {
                    continue;
                }
                let path = Path { light, eye, jy, jz };
                // (s, L): y draws the direction, z is evaluated.
                let (d, wy, own_y, other_y, ok) =
                    self.sample_end(y, false, L::Mask::splat(jy == 0), m & !z.delta, &mut draw);
                let r = self.reach(y, z, d, ok);
                if r.ok.any() {
                    let ez = self.end(z, -d, true, jz == 0, r.ok, &mut draw);
                    let (t, p_nc, p_col) = self.segment(r.layer, r.dz, d, r.ok);
                    let g = t.scale(geometry(y, z, d));
                    let conn = Conn {
                        c_l: own_y,
                        c_e: ez.own,
                        other_y,
                        other_z: ez.other,
                        land_y: L::select(y.surface, p_nc, p_col),
                        land_z: L::select(z.surface, p_nc, p_col),
                    };
                    let mis = path.weight(&conn, true, r.ok);
                    let c = y.beta * wy * g * ez.value * z.beta;
                    acc += Rgb::select(r.ok, c.scale(mis), Rgb::zero());
                }
                // (s, E): z draws the direction, y is evaluated.
                let (o, wz, own_z, other_z, ok) =
                    self.sample_end(z, true, L::Mask::splat(jz == 0), m & !y.delta, &mut draw);
                let d = -o;
                let r = self.reach(z, y, o, ok);
                if r.ok.any() {
                    let ey = self.end(y, d, false, jy == 0, r.ok, &mut draw);
                    let (t, p_nc, p_col) = self.segment(r.layer, r.dz, d, r.ok);
                    let g = t.scale(geometry(y, z, d));
                    let conn = Conn {
                        c_l: ey.own,
                        c_e: own_z,
                        other_y: ey.other,
                        other_z,
                        land_y: L::select(y.surface, p_nc, p_col),
                        land_z: L::select(z.surface, p_nc, p_col),
                    };
                    let mis = path.weight(&conn, false, r.ok);
                    let c = y.beta * ey.value * g * wz * z.beta;
                    acc += Rgb::select(r.ok, c.scale(mis), Rgb::zero());
                }
            }
        }
        acc
    }
}

/// `a · b` for non-negative factors, 0 where either is 0 (no `0 · ∞`).
#[inline(always)]
fn mul0<L: Lane>(a: L, b: L) -> L {
    let zero = L::zero();
    L::select(a.gt(zero) & b.gt(zero), a * b, zero)
}

/// The squared terms of the two strategies that join vertex `v` to the
/// vertex `prev` before it on its subpath, with the direction between them
/// drawn by `prev` (unless `v` is a delta) or by `v` (unless `prev` is).
#[inline(always)]
fn joins<L: Lane>(v: &Vertex<L>, prev: &Vertex<L>) -> L {
    let zero = L::zero();
    let by_prev = L::select(v.delta, zero, prev.own * prev.own);
    let by_v = L::select(prev.delta, zero, v.other * v.other);
    by_prev + by_v
}

/// [`Vertex::tail`] of the `count`-th vertex `v` of a subpath (from 0),
/// after `prev` and before it the vertex that sampled with density
/// `prev_own`: the terms of the split before `v`, plus the previous tail
/// carried across `prev` by the ratio of `prev`'s densities from its two
/// neighbours. (`Path::weight` spells out the same sum term by term.)
#[inline(always)]
fn tail<L: Lane>(v: &Vertex<L>, prev: &Vertex<L>, prev_own: L, count: L) -> L {
    let zero = L::zero();
    let from_next = v.other * prev.land_rev;
    let from_prev = prev_own * prev.land;
    let rho = L::div_or_zero(from_next, from_prev, from_prev.gt(zero));
    let carried = joins(v, prev) + mul0(rho * rho, prev.tail);
    let first = count.lt(L::splat(0.5));
    let second = count.lt(L::splat(1.5));
    L::select(first, zero, L::select(second, joins(v, prev), carried))
}

/// The lanes where vertices `y` and `z` lie in a common layer (an
/// interface borders two, a collision is in one) and are not on the same
/// interface: only there can a direction join them.
fn share_layer<L: Lane>(y: &Vertex<L>, z: &Vertex<L>) -> L::Mask {
    let one = L::one();
    let both = y.surface & z.surface;
    let apart = (y.idx - z.idx).abs().eq(one);
    let none = !y.surface & !z.surface;
    let same = y.idx.eq(z.idx);
    // One on an interface `i`, the other in layer `l`: `l` is `i − 1` or `i`.
    let (i, l) = (
        L::select(y.surface, y.idx, z.idx),
        L::select(y.surface, z.idx, y.idx),
    );
    let borders = l.eq(i) | l.eq(i - one);
    (both & apart) | (none & same) | (!both & !none & borders)
}

/// The light-sense weight of an eye subpath's interface sample `s` drawn
/// from `a` (the side light leaves by): `f(b → a) |b.z| / pdf` for a rough
/// lobe; for a delta lobe, its discrete weight turned around (the shading
/// normal's factor, and the η² of a refraction: `(n_a / n_b)²`).
fn eye_weight<L: Lane>(
    it: &InterfaceLanes<L>,
    a: V3<L>,
    s: &crate::interface::BsdfSample<L>,
) -> Rgb<L> {
    let zero = L::zero();
    let rough = it
        .eval(s.b, a)
        .scale(L::div_or_zero(s.b.z.abs(), s.pdf, s.pdf.gt(zero)));
    let (n_a, n_b) = it.sides(a);
    let refracted = (a.z * s.b.z).lt(zero);
    let eta2 = L::select(
        refracted,
        L::div_or_zero(n_a * n_a, n_b * n_b, n_b.gt(zero)),
        L::one(),
    );
    let delta = s.weight.scale(it.reverse(a, s.b) * eta2);
    Rgb::select(s.delta, delta, rough)
}

/// The segment's cosine factor between `y` and `z` along `d`: `|d.z|` once
/// per interface it joins, less one (see the module docs).
fn geometry<L: Lane>(y: &Vertex<L>, z: &Vertex<L>, d: V3<L>) -> L {
    let mu = d.z.abs();
    let inv = L::div_or_zero(L::one(), mu, mu.gt(L::zero()));
    let both = y.surface & z.surface;
    let none = !y.surface & !z.surface;
    L::select(both, mu, L::select(none, inv, L::one()))
}

/// What a connection knows of its path beyond the stored vertices: the
/// densities of its direction from each end (`c_l` from the light vertex,
/// `c_e` from the eye vertex), of each end's arrival given it, and of a free
/// flight along it landing at each end.
struct Conn<L: Lane> {
    c_l: L,
    c_e: L,
    other_y: L,
    other_z: L,
    land_y: L,
    land_z: L,
}

/// The path of a connection: light vertices `0..=jy`, eye vertices
/// `0..=jz`, in the light's order `v_1 … v_n` = `light[0..=jy]`,
/// `eye[jz..=0]`.
struct Path<'a, L: Lane> {
    light: &'a [Vertex<L>],
    eye: &'a [Vertex<L>],
    jy: usize,
    jz: usize,
}

/// Products of density ratios are kept below this, so that a later zero
/// cannot meet an infinity.
const RATIO_CAP: f64 = 1e30;

impl<L: Lane> Path<'_, L> {
    fn n(&self) -> usize {
        self.jy + self.jz + 2
    }

    fn delta(&self, i: usize) -> L::Mask {
        if i <= self.jy + 1 {
            self.light[i - 1].delta
        } else {
            self.eye[self.n() - i].delta
        }
    }

    /// `(F_i, B_i)` for `2 ≤ i ≤ n − 1`: the densities of generating vertex
    /// `v_i` from `v_{i−1}` (direction and flight) and from `v_{i+1}`.
    fn densities(&self, i: usize, c: &Conn<L>) -> (L, L) {
        let s = self.jy + 1;
        if i <= s {
            let j = i - 1;
            let y = &self.light[j];
            let f = self.light[j - 1].own * y.land;
            let b = if j == self.jy {
                c.c_e * c.land_y
            } else if j + 1 == self.jy {
                c.other_y * y.land_rev
            } else {
                self.light[j + 1].other * y.land_rev
            };
            (f, b)
        } else {
            let j = self.n() - i;
            let z = &self.eye[j];
            let b = self.eye[j - 1].own * z.land;
            let f = if j == self.jz {
                c.c_l * c.land_z
            } else if j + 1 == self.jz {
                c.other_z * z.land_rev
            } else {
                self.eye[j + 1].other * z.land_rev
            };
            (f, b)
        }
    }

    /// `(c_L(k), c_E(k))`: the density of `d_k` drawn by `v_k`, and by
    /// `v_{k+1}`.
    fn directions(&self, k: usize, c: &Conn<L>) -> (L, L) {
        let s = self.jy + 1;
        let n = self.n();
        let c_l = if k < s {
            self.light[k - 1].own
        } else if k == s {
            c.c_l
        } else if n - k == self.jz {
            c.other_z
        } else {
            self.eye[n - k].other
        };
        let c_e = if k > s {
            self.eye[n - k - 1].own
        } else if k == s {
            c.c_e
        } else if k == self.jy {
            c.other_y
        } else {
            self.light[k].other
        };
        (c_l, c_e)
    }

    /// The power-heuristic weight of this connection's strategy (`(s, L)`
    /// where `light_draws`, else `(s, E)`), over every strategy of the path
    /// (lanes `m`). From `s` towards each end, strategy `k`'s share is one
    /// ratio of vertex densities per step; the connection changes the
    /// densities of the two nearest vertices on each side only, so the
    /// shares of the rest are the subpath's own sum, scaled
    /// ([`Vertex::tail`]): O(1) per connection.
    fn weight(&self, c: &Conn<L>, light_draws: bool, m: L::Mask) -> L {
        let zero = L::zero();
        let cap = L::splat(RATIO_CAP);
        let (n, s) = (self.n(), self.jy + 1);
        let mine = if light_draws { c.c_l } else { c.c_e };
        let inv = L::div_or_zero(L::one(), mine, mine.gt(zero));
        // Strategy k's share, `r = R_k / R_s` (see the module docs).
        // A product that reached 0 stays 0 (no `0 · ∞`), one that overflows
        // stays at the cap.
        let times = |r: L, x: L| L::select(r.gt(zero), (r * x).min(cap), zero);
        let term = |k: usize, r: L| {
            let (c_l, c_e) = self.directions(k, c);
            let l = times(times(r, c_l), inv);
            let e = times(times(r, c_e), inv);
            L::select(self.delta(k + 1), zero, l * l) + L::select(self.delta(k), zero, e * e)
        };
        // Strategies beyond the connection's neighbours: a subpath's tail
        // at its vertex next but one, carried by that vertex's share.
        let rest = |r: L, tail: L| {
            let q = times(r, inv);
            mul0(q * q, tail)
        };
        let mut sum = term(s, L::one());
        let mut r = L::one();
        for k in s + 1..n.min(s + 3) {
            let (f, b) = self.densities(k, c);
            r = times(r, L::div_or_zero(f, b, b.gt(zero)));
            sum += match k == s + 1 {
                true => term(k, r),
                false => rest(r, self.eye[self.jz - 1].tail),
            };
        }
        r = L::one();
        for k in (s.saturating_sub(2).max(1)..s).rev() {
            let (f, b) = self.densities(k + 1, c);
            r = times(r, L::div_or_zero(b, f, f.gt(zero)));
            sum += match k + 1 == s {
                true => term(k, r),
                false => rest(r, self.light[self.jy - 1].tail),
            };
        }
        L::select(
            m & sum.gt(zero),
            L::div_or_zero(L::one(), sum, sum.gt(zero)),
            zero,
        )
    }
}
