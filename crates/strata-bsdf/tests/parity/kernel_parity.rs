//! Lane parity of the physics kernels, in the style of `wide`'s own tests:
//! every kernel evaluated on [`F32x8`] equals the same kernel on `f32` applied
//! lane by lane.
//!
//! **Budget: 0 ulp.** Every output (values, directions, masks) must be bit for
//! bit identical, signs of zero included. The kernels are written once over
//! `Lane`, use only IEEE-exact operations (`+ - * /`, `sqrt`, `abs`, `floor`,
//! comparisons, selects) plus the shared `fastmath` functions, and never fuse
//! multiply-adds, so nothing may differ; a difference of one ulp would let
//! lane `i` of the wavefront diverge from scalar walk `i`.
//!
//! Inputs are edge cases (±0, cos ±1, grazing cos ±1e-7, just before and just
//! past the critical angle of total internal reflection, alpha 1e-4 and 1,
//! g ±0.999, optical depth 1e4, zero sigma_t, uniforms 0 and 1 - 2^-24) mixed
//! with random inputs. Each input is rotated through all eight lane positions,
//! then the inputs are shuffled twice so each case also meets different
//! neighbours (lanes of different kinds force the SIMD kernel through code
//! paths the scalar one skips).
//!
//! Besides parity, no lane may ever produce NaN or infinity: every output of
//! both instances must be finite, and every kernel is also run on [`Ck`], an
//! `F32x8` that checks every intermediate result of every lane (masked-off
//! lanes included) and panics at the operation that produced a NaN or an
//! infinity.
//!
//! The file must pass on baseline x86-64 too (where `wide` runs `f32x8` as two
//! SSE halves): `RUSTFLAGS="-C target-cpu=x86-64" CARGO_TARGET_DIR=target/baseline
//! cargo test --release --test parity kernel_parity::`.

use std::fmt::Debug;
use std::ops::{Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Sub, SubAssign};

use strata_bsdf::fresnel;
use strata_bsdf::interface::InterfaceLanes;
use strata_bsdf::lane::{F32x8, Lane, LaneBits, LaneMask, Rgb, M8, V3};
use strata_bsdf::math::{fastmath, sample_cosine_hemisphere, sample_uniform_sphere, Frame};
use strata_bsdf::medium;
use strata_bsdf::microfacet::Microfacet;
use strata_bsdf::rng::{Stream, WalkRng};

// ---------------------------------------------------------------------------
// A lane that checks every intermediate result
// ---------------------------------------------------------------------------

/// Eight f32 lanes like [`F32x8`], but every arithmetic result is checked: a
/// NaN or infinity in any lane panics with the source location of the
/// operation (inside the kernel) that produced it.
#[derive(Clone, Copy, Debug, Default)]
struct Ck(F32x8);

#[track_caller]
fn ck(v: F32x8) -> Ck {
    let a = v.to_array();
    if a.iter().any(|x| !x.is_finite()) {
        panic!(
            "non-finite intermediate {a:?} produced at {}",
            std::panic::Location::caller()
        );
    }
    Ck(v)
}

macro_rules! ck_binop {
    ($tr:ident, $f:ident, $atr:ident, $af:ident, $op:tt) => {
        impl $tr for Ck {
            type Output = Ck;
            #[track_caller]
            fn $f(self, o: Ck) -> Ck {
                ck(self.0 $op o.0)
            }
        }
        impl $atr for Ck {
            #[track_caller]
            fn $af(&mut self, o: Ck) {
                *self = ck(self.0 $op o.0);
            }
        }
    };
}
ck_binop!(Add, add, AddAssign, add_assign, +);
ck_binop!(Sub, sub, SubAssign, sub_assign, -);
ck_binop!(Mul, mul, MulAssign, mul_assign, *);
ck_binop!(Div, div, DivAssign, div_assign, /);

impl Neg for Ck {
    type Output = Ck;
    fn neg(self) -> Ck {
        Ck(-self.0)
    }
}

impl Lane for Ck {
    type Mask = M8;
    const LANES: usize = 8;
    fn splat(v: f64) -> Self {
        Ck(F32x8::splat(v))
    }
    fn from_fn(f: impl FnMut(usize) -> f64) -> Self {
        Ck(F32x8::from_fn(f))
    }
    fn lane(self, i: usize) -> f64 {
        self.0.lane(i)
    }
    #[track_caller]
    fn sqrt(self) -> Self {
        ck(self.0.sqrt())
    }
    fn abs(self) -> Self {
        Ck(self.0.abs())
    }
    fn min(self, o: Self) -> Self {
        Ck(self.0.min(o.0))
    }
    fn max(self, o: Self) -> Self {
        Ck(self.0.max(o.0))
    }
    #[track_caller]
    fn floor(self) -> Self {
        ck(self.0.floor())
    }
    fn exp(self) -> Self {
        fastmath::exp(self)
    }
    fn exp_m1(self) -> Self {
        fastmath::exp_m1(self)
    }
    fn ln(self) -> Self {
        fastmath::ln(self)
    }
    fn sin_cos_turns(self) -> (Self, Self) {
        fastmath::sin_cos_turns(self)
    }
    fn lt(self, o: Self) -> M8 {
        self.0.lt(o.0)
    }
    fn le(self, o: Self) -> M8 {
        self.0.le(o.0)
    }
    fn gt(self, o: Self) -> M8 {
        self.0.gt(o.0)
    }
    fn ge(self, o: Self) -> M8 {
        self.0.ge(o.0)
    }
    fn eq(self, o: Self) -> M8 {
        self.0.eq(o.0)
    }
    fn is_finite(self) -> M8 {
        self.0.is_finite()
    }
    fn select(m: M8, t: Self, f: Self) -> Self {
        Ck(F32x8::select(m, t.0, f.0))
    }
}

impl LaneBits for Ck {
    #[track_caller]
    fn pow2i(n: Self) -> Self {
        ck(F32x8::pow2i(n.0))
    }
    #[track_caller]
    fn frexp(self) -> (Self, Self) {
        let (m, e) = self.0.frexp();
        (ck(m), ck(e))
    }
}

// ---------------------------------------------------------------------------
// The harness
// ---------------------------------------------------------------------------

/// A kernel's outputs, flattened: values and masks.
struct Out<L: Lane> {
    v: Vec<L>,
    m: Vec<L::Mask>,
}

impl<L: Lane> Out<L> {
    fn new() -> Self {
        Out {
            v: Vec::new(),
            m: Vec::new(),
        }
    }
    fn val(&mut self, x: L) -> &mut Self {
        self.v.push(x);
        self
    }
    fn v3(&mut self, x: V3<L>) -> &mut Self {
        self.v.extend([x.x, x.y, x.z]);
        self
    }
    fn rgb(&mut self, x: Rgb<L>) -> &mut Self {
        self.v.extend([x.r, x.g, x.b]);
        self
    }
    fn mask(&mut self, m: L::Mask) -> &mut Self {
        self.m.push(m);
        self
    }
}

/// A kernel under test, generic over the lane type. `x` holds one input per
/// lane (one element for `f32`, eight for the eight-wide instances).
trait Kernel<T> {
    fn run<L: Lane>(&self, x: &[T]) -> Out<L>;
}

/// Runs `k` on `F32x8`, on `Ck`, and on `f32` lane by lane, and asserts
/// bit-identical, finite results. The inputs are taken in order and rotated
/// through all eight lane positions (each input meets the same neighbours in
/// every lane), then twice more in shuffled order (new neighbours).
fn check<T: Copy + Debug, K: Kernel<T>>(name: &str, k: &K, inputs: &[T]) {
    assert!(!inputs.is_empty());
    let mut rng = WalkRng::new(0x9a71_7e57, name.len() as u64, 0, Stream::Walk);
    let mut order: Vec<usize> = (0..inputs.len()).collect();
    let mut compared = 0usize;
    for pass in 0..10 {
        let rotation = if pass < 8 { pass } else { 0 };
        if pass >= 8 {
            // Fisher–Yates with the test's own stream.
            for i in (1..order.len()).rev() {
                let j = (rng.next_u32() as usize) % (i + 1);
                order.swap(i, j);
            }
        }
        for start in (0..order.len()).step_by(8) {
            let chunk: [T; 8] =
                std::array::from_fn(|i| inputs[order[(start + i + rotation) % order.len()]]);
            let wide = k.run::<F32x8>(&chunk);
            let checked = k.run::<Ck>(&chunk);
            for lane in 0..8 {
                let one = k.run::<f32>(&chunk[lane..lane + 1]);
                assert_eq!(one.v.len(), wide.v.len());
                for (o, (s, (w, c))) in one.v.iter().zip(wide.v.iter().zip(&checked.v)).enumerate()
                {
                    let w = w.lane(lane) as f32;
                    let c = c.lane(lane) as f32;
                    assert!(
                        s.is_finite() && w.is_finite(),
                        "{name}: output {o} not finite (scalar {s}, lanes {w}) for {:?}",
                        chunk[lane]
                    );
                    assert!(
                        s.to_bits() == w.to_bits() && w.to_bits() == c.to_bits(),
                        "{name}: output {o} differs: scalar {s:e} ({:#x}), lanes {w:e} ({:#x}) for {:?}\nlane {lane} of {chunk:?}",
                        s.to_bits(),
                        w.to_bits(),
                        chunk[lane]
                    );
                    compared += 1;
                }
                for (o, (s, (w, c))) in one.m.iter().zip(wide.m.iter().zip(&checked.m)).enumerate()
                {
                    assert!(
                        *s == w.lane(lane) && *s == c.lane(lane),
                        "{name}: mask {o} differs: scalar {s}, lanes {} for {:?}",
                        w.lane(lane),
                        chunk[lane]
                    );
                }
            }
        }
    }
    eprintln!(
        "{name}: {} inputs, {compared} values compared",
        inputs.len()
    );
}

/// A lane value from one field of each lane's input.
fn ln<L: Lane, T>(x: &[T], f: impl Fn(&T) -> f32) -> L {
    L::from_fn(|i| f(&x[i]) as f64)
}
/// A mask from one boolean field of each lane's input.
fn mk<L: Lane, T>(x: &[T], f: impl Fn(&T) -> bool) -> L::Mask {
    ln::<L, T>(x, |t| if f(t) { 1.0 } else { 0.0 }).gt(L::zero())
}
fn v3<L: Lane, T>(x: &[T], f: impl Fn(&T) -> [f32; 3]) -> V3<L> {
    V3::new(ln(x, |t| f(t)[0]), ln(x, |t| f(t)[1]), ln(x, |t| f(t)[2]))
}
fn rgb<L: Lane, T>(x: &[T], f: impl Fn(&T) -> [f32; 3]) -> Rgb<L> {
    Rgb::new(ln(x, |t| f(t)[0]), ln(x, |t| f(t)[1]), ln(x, |t| f(t)[2]))
}

// ---------------------------------------------------------------------------
// Inputs
// ---------------------------------------------------------------------------

/// The cosine of the critical angle seen from the dense side of relative IOR `eta`.
fn cos_critical(eta: f64) -> f64 {
    (1.0 - 1.0 / (eta * eta)).sqrt()
}

/// Edge-case cosines (direction z components).
fn edge_cosines() -> Vec<f32> {
    let mut c = vec![
        1.0, -1.0, 0.0, -0.0, 1e-7, -1e-7, 0.02, -0.02, 0.5, -0.5, 0.999_999, -0.999_999,
    ];
    for eta in [1.5, 1.33] {
        let cc = cos_critical(eta) as f32;
        // Just before and just past total internal reflection, from the dense side.
        for d in [-1e-6f32, 1e-6, -1e-3, 1e-3] {
            c.push(cc + d);
            c.push(-(cc + d));
        }
        c.push(cc);
        c.push(-cc);
    }
    c
}

const U_EDGES: [f32; 7] = [
    0.0,
    0.5,
    1.0 - 1.0 / 16_777_216.0,
    1.0 / 16_777_216.0,
    0.25,
    0.75,
    0.123_456,
];
const ALPHA_EDGES: [f32; 5] = [1e-4, 1.0, 0.3, 0.05, 0.7];

/// A unit direction with `z = c` at azimuth `phi` turns, rounded to f32.
fn dir_cos(c: f32, phi: f64) -> [f32; 3] {
    let s = (1.0 - (c as f64) * (c as f64)).max(0.0).sqrt();
    let p = std::f64::consts::TAU * phi;
    if c.abs() == 1.0 {
        return [0.0, 0.0, c];
    }
    [(s * p.cos()) as f32, (s * p.sin()) as f32, c]
}

struct Gen(WalkRng);
impl Gen {
    fn new(seed: u64) -> Self {
        Gen(WalkRng::new(seed, 1, 2, Stream::Walk))
    }
    fn u(&mut self) -> f32 {
        self.0.uniform()
    }
    fn range(&mut self, a: f32, b: f32) -> f32 {
        a + (b - a) * self.u()
    }
    fn pick<T: Copy>(&mut self, s: &[T]) -> T {
        s[(self.0.next_u32() as usize) % s.len()]
    }
    fn coin(&mut self, p: f32) -> bool {
        self.u() < p
    }
    /// An edge-case direction half of the time, a random one otherwise.
    fn dir(&mut self) -> [f32; 3] {
        let phi = if self.coin(0.3) {
            self.pick(&[0.0, 0.25, 0.5, 0.125])
        } else {
            self.u() as f64
        };
        let c = if self.coin(0.5) {
            self.pick(&edge_cosines())
        } else {
            self.range(-1.0, 1.0)
        };
        dir_cos(c, phi)
    }
    /// A direction with `z >= 0`.
    fn dir_up(&mut self) -> [f32; 3] {
        let d = self.dir();
        [d[0], d[1], d[2].abs()]
    }
    /// A uniform in [0, 1): an edge value a third of the time.
    fn uniform(&mut self) -> f32 {
        if self.coin(0.33) {
            self.pick(&U_EDGES)
        } else {
            self.u()
        }
    }
    fn alpha(&mut self) -> f32 {
        if self.coin(0.5) {
            self.pick(&ALPHA_EDGES)
        } else {
            self.range(1e-3, 1.0)
        }
    }
}

// ---------------------------------------------------------------------------
// Fresnel
// ---------------------------------------------------------------------------

const ETA_EDGES: [f32; 7] = [1.5, 1.33, 1.0 / 1.5, 1.0, 4.0, 1.0001, 0.25];

struct Dielectric;
impl Kernel<(f32, f32)> for Dielectric {
    fn run<L: Lane>(&self, x: &[(f32, f32)]) -> Out<L> {
        let mut o = Out::new();
        o.val(fresnel::dielectric(ln(x, |t| t.0), ln(x, |t| t.1)));
        o
    }
}

#[test]
fn fresnel_dielectric() {
    let mut g = Gen::new(1);
    let mut inputs = vec![];
    for c in edge_cosines() {
        for e in ETA_EDGES {
            inputs.push((c, e));
        }
    }
    for _ in 0..2000 {
        inputs.push((g.range(-1.0, 1.0), g.range(0.2, 5.0)));
    }
    check("fresnel::dielectric", &Dielectric, &inputs);
}

type ConductorIn = (f32, [f32; 3], [f32; 3]);
struct Conductor;
impl Kernel<ConductorIn> for Conductor {
    fn run<L: Lane>(&self, x: &[ConductorIn]) -> Out<L> {
        let mut o = Out::new();
        o.rgb(fresnel::conductor(
            ln(x, |t| t.0),
            rgb(x, |t| t.1),
            rgb(x, |t| t.2),
        ));
        o
    }
}

#[test]
fn fresnel_conductor() {
    let mut g = Gen::new(2);
    let iors: [([f32; 3], [f32; 3]); 5] = [
        ([0.27, 0.68, 1.3], [3.6, 2.6, 2.3]),
        ([1.5, 1.5, 1.5], [0.0, 0.0, 0.0]),
        ([0.05, 0.05, 0.05], [100.0, 100.0, 100.0]),
        ([2.9, 2.9, 2.4], [3.0, 3.0, 3.1]),
        ([1.0, 1.0, 1.0], [0.0, 0.0, 0.0]),
    ];
    let mut inputs = vec![];
    for c in edge_cosines() {
        for &(e, k) in &iors {
            // Incidence from above only (cos_i >= 0), keeping -0.
            inputs.push((if c == 0.0 { c } else { c.abs() }, e, k));
        }
    }
    for _ in 0..2000 {
        let e = [g.range(0.05, 4.0), g.range(0.05, 4.0), g.range(0.05, 4.0)];
        let k = [g.range(0.0, 8.0), g.range(0.0, 8.0), g.range(0.0, 8.0)];
        inputs.push((g.u(), e, k));
    }
    check("fresnel::conductor", &Conductor, &inputs);
}

type RefractIn = ([f32; 3], [f32; 3], f32);
struct Refract;
impl Kernel<RefractIn> for Refract {
    fn run<L: Lane>(&self, x: &[RefractIn]) -> Out<L> {
        let (b, ok) = fresnel::refract(v3(x, |t| t.0), v3(x, |t| t.1), ln(x, |t| t.2));
        let mut o = Out::new();
        o.v3(b).mask(ok);
        o
    }
}

#[test]
fn fresnel_refract() {
    let mut g = Gen::new(3);
    let mut inputs = vec![];
    for _ in 0..3000 {
        let a = g.dir();
        // A microfacet normal on a's side: the macro normal or a random one.
        let m = if g.coin(0.3) {
            [0.0, 0.0, 1.0]
        } else {
            g.dir_up()
        };
        let s = if a[2] < 0.0 { -1.0 } else { 1.0 };
        let m = m.map(|c| c * s);
        let eta = if g.coin(0.5) {
            g.pick(&ETA_EDGES)
        } else {
            g.range(0.2, 5.0)
        };
        inputs.push((a, m, eta));
    }
    check("fresnel::refract", &Refract, &inputs);
}

// ---------------------------------------------------------------------------
// Microfacets
// ---------------------------------------------------------------------------

#[derive(Clone, Copy, Debug)]
struct MfIn {
    ax: f32,
    ay: f32,
    beckmann: bool,
    separable: bool,
    a: [f32; 3],
    b: [f32; 3],
    m: [f32; 3],
    u1: f32,
    u2: f32,
}

fn microfacet<L: Lane, T>(x: &[T], f: impl Fn(&T) -> (f32, f32, bool, bool)) -> Microfacet<L> {
    Microfacet {
        alpha_x: ln(x, |t| f(t).0),
        alpha_y: ln(x, |t| f(t).1),
        beckmann: mk::<L, T>(x, |t| f(t).2),
        separable: mk::<L, T>(x, |t| f(t).3),
    }
}

struct MicrofacetAll;
impl Kernel<MfIn> for MicrofacetAll {
    fn run<L: Lane>(&self, x: &[MfIn]) -> Out<L> {
        let mf = microfacet::<L, MfIn>(x, |t| (t.ax, t.ay, t.beckmann, t.separable));
        let a = v3(x, |t| t.a);
        let b = v3(x, |t| t.b);
        let m = v3(x, |t| t.m);
        let s = mf.sample(a, ln(x, |t| t.u1), ln(x, |t| t.u2));
        let mut o = Out::new();
        o.val(mf.d(m))
            .val(mf.lambda(a))
            .val(mf.g1(a))
            .val(mf.g(a, b))
            .v3(s)
            .val(mf.pdf(a, m))
            .val(mf.pdf(a, s))
            .val(mf.d(s));
        o
    }
}

#[test]
fn microfacet_kernels() {
    let mut g = Gen::new(4);
    let mut inputs = vec![];
    for _ in 0..6000 {
        let ax = g.alpha();
        let ay = if g.coin(0.5) { ax } else { g.alpha() };
        let m = match g.pick(&[0, 1, 2, 3]) {
            0 => [0.0, 0.0, 1.0],
            1 => dir_cos(g.pick(&[0.0, -0.0, 1e-7, -1e-7]), g.u() as f64),
            _ => g.dir(),
        };
        inputs.push(MfIn {
            ax,
            ay,
            beckmann: g.coin(0.4),
            separable: g.coin(0.4),
            a: g.dir(),
            b: g.dir(),
            m,
            u1: g.uniform(),
            u2: g.uniform(),
        });
    }
    check("microfacet", &MicrofacetAll, &inputs);
}

// ---------------------------------------------------------------------------
// Interfaces
// ---------------------------------------------------------------------------

#[derive(Clone, Copy, Debug)]
struct IfIn {
    /// 0 dielectric, 1 conductor, 2 diffuse.
    kind: u8,
    smooth: bool,
    n_above: f32,
    n_below: f32,
    ax: f32,
    ay: f32,
    beckmann: bool,
    separable: bool,
    eta: [f32; 3],
    k: [f32; 3],
    albedo: [f32; 3],
    a: [f32; 3],
    b: [f32; 3],
    u: [f32; 3],
    transmit_only: bool,
    /// The shading normal: the slab's `[0, 0, 1]` half of the time, so
    /// that vectors mix untilted lanes into tilted interfaces (which must
    /// give what the untilted code gives).
    normal: [f32; 3],
}

fn interface<L: Lane>(x: &[IfIn]) -> InterfaceLanes<L> {
    InterfaceLanes {
        n_above: ln(x, |t| t.n_above),
        n_below: ln(x, |t| t.n_below),
        mf: microfacet::<L, IfIn>(x, |t| (t.ax, t.ay, t.beckmann, t.separable)),
        smooth: mk::<L, IfIn>(x, |t| t.smooth),
        dielectric: mk::<L, IfIn>(x, |t| t.kind == 0),
        conductor: mk::<L, IfIn>(x, |t| t.kind == 1),
        diffuse: mk::<L, IfIn>(x, |t| t.kind == 2),
        eta: rgb(x, |t| t.eta),
        k: rgb(x, |t| t.k),
        albedo: rgb(x, |t| t.albedo),
        normal: v3(x, |t| t.normal),
        tilted: x.iter().any(|t| t.normal != [0.0, 0.0, 1.0]),
        adjoint: false,
        run_all: false,
    }
}

struct InterfaceAll;
impl Kernel<IfIn> for InterfaceAll {
    fn run<L: Lane>(&self, x: &[IfIn]) -> Out<L> {
        let it = interface::<L>(x);
        let a = v3(x, |t| t.a);
        let b = v3(x, |t| t.b);
        let t_only = mk::<L, IfIn>(x, |t| t.transmit_only);
        let s = it.sample(
            a,
            ln(x, |t| t.u[0]),
            ln(x, |t| t.u[1]),
            ln(x, |t| t.u[2]),
            t_only,
        );
        let mut o = Out::new();
        o.v3(s.b)
            .rgb(s.weight)
            .val(s.pdf)
            .mask(s.valid)
            .mask(s.delta)
            .rgb(it.eval(a, b))
            .val(it.pdf(a, b, t_only))
            .rgb(it.eval(a, s.b))
            .val(it.pdf(a, s.b, t_only))
            .rgb(it.eval(b, a))
            .val(it.pdf(b, a, t_only));
        o
    }
}

fn interface_inputs(g: &mut Gen, n: usize) -> Vec<IfIn> {
    let mut v = vec![];
    for _ in 0..n {
        let kind = g.pick(&[0u8, 0, 1, 2]);
        let n_above = g.pick(&[1.0f32, 1.0, 1.5, 1.33]);
        let n_below = if kind == 0 {
            if g.coin(0.5) {
                g.pick(&[1.5f32, 1.33, 1.0, 4.0, 1.0001, 1.2])
            } else {
                g.range(1.0, 3.0)
            }
        } else {
            n_above
        };
        let ax = g.alpha();
        let ay = if g.coin(0.6) { ax } else { g.alpha() };
        let (eta, k) = g.pick(&[
            ([0.27f32, 0.68, 1.3], [3.6f32, 2.6, 2.3]),
            ([0.18, 0.42, 1.37], [3.42, 2.35, 1.77]),
            ([1.5, 1.5, 1.5], [0.0, 0.0, 0.0]),
            ([0.05, 0.05, 0.05], [100.0, 100.0, 100.0]),
        ]);
        let a = g.dir();
        // b: random, the mirror of a, or straight through.
        let b = match g.pick(&[0, 0, 1, 2]) {
            1 => [-a[0], -a[1], a[2]],
            2 => [-a[0], -a[1], -a[2]],
            _ => g.dir(),
        };
        v.push(IfIn {
            kind,
            smooth: g.coin(0.3),
            n_above,
            n_below,
            ax,
            ay,
            beckmann: g.coin(0.3),
            separable: g.coin(0.3),
            eta,
            k,
            albedo: g.pick(&[[0.0f32, 0.0, 0.0], [1.0, 1.0, 1.0], [0.8, 0.5, 0.2]]),
            a,
            b,
            u: [g.uniform(), g.uniform(), g.uniform()],
            transmit_only: g.coin(0.3),
            normal: if g.coin(0.5) {
                [0.0, 0.0, 1.0]
            } else {
                let (x, y) = (g.uniform() - 0.5, g.uniform() - 0.5);
                let l = (x * x + y * y + 1.0).sqrt();
                [x / l, y / l, 1.0 / l]
            },
        });
    }
    v
}

#[test]
fn interface_kernels() {
    let mut g = Gen::new(5);
    let inputs = interface_inputs(&mut g, 8000);
    check("interface", &InterfaceAll, &inputs);
}

// ---------------------------------------------------------------------------
// Media
// ---------------------------------------------------------------------------

const G_EDGES: [f32; 9] = [0.999, -0.999, 0.0, -0.0, 1e-4, -1e-3, 1e-3, 0.5, -0.9];
const SIGMA_EDGES: [[f32; 3]; 5] = [
    [0.0, 0.0, 0.0],
    [1e4, 1e4, 1e4],
    [1.0, 1.0, 1.0],
    [0.0, 1.0, 1e4],
    [0.2, 0.5, 1.0],
];

#[derive(Clone, Copy, Debug)]
struct MedIn {
    g: f32,
    mu_cos: f32,
    d: [f32; 3],
    u1: f32,
    u2: f32,
    sigma_t: [f32; 3],
    albedo: [f32; 3],
    dz: f32,
    mu: f32,
    hero: f32,
    ratios: [f32; 3],
}

struct MediumAll;
impl Kernel<MedIn> for MediumAll {
    fn run<L: Lane>(&self, x: &[MedIn]) -> Out<L> {
        let g = ln(x, |t| t.g);
        let st = rgb(x, |t| t.sigma_t);
        let dz = ln(x, |t| t.dz);
        let mu = ln(x, |t| t.mu);
        let ff = medium::free_flight(
            st,
            rgb(x, |t| t.albedo),
            L::div_or_zero(dz, mu, mu.gt(L::zero())),
            ln(x, |t| t.hero),
            ln(x, |t| t.u1),
            rgb(x, |t| t.ratios),
        );
        let mut o = Out::new();
        o.val(strata_bsdf::phase::hg::hg_eval(g, ln(x, |t| t.mu_cos)))
            .v3(strata_bsdf::phase::hg::hg_sample(
                g,
                v3(x, |t| t.d),
                ln(x, |t| t.u1),
                ln(x, |t| t.u2),
            ))
            .rgb(medium::transmittance(st, dz, mu))
            .mask(ff.collide)
            .val(ff.distance)
            .rgb(ff.weight)
            .rgb(ff.ratios)
            .val(medium::collision_density(st, ff.distance, mu))
            .val(medium::collision_density(st, dz, mu))
            .val(medium::hero_sigma(st, ln(x, |t| t.hero)));
        o
    }
}

#[test]
fn medium_kernels() {
    let mut g = Gen::new(6);
    let mut inputs = vec![];
    for _ in 0..6000 {
        let sigma_t = if g.coin(0.5) {
            g.pick(&SIGMA_EDGES)
        } else {
            [g.range(0.0, 10.0), g.range(0.0, 10.0), g.range(0.0, 10.0)]
        };
        inputs.push(MedIn {
            g: if g.coin(0.5) {
                g.pick(&G_EDGES)
            } else {
                g.range(-0.99, 0.99)
            },
            mu_cos: if g.coin(0.3) {
                g.pick(&[1.0, -1.0, 0.0, -0.0, 0.999_999])
            } else {
                g.range(-1.0, 1.0)
            },
            d: g.dir(),
            u1: g.uniform(),
            u2: g.uniform(),
            sigma_t,
            albedo: g.pick(&[[0.0f32, 0.0, 0.0], [1.0, 1.0, 1.0], [0.5, 0.7, 0.95]]),
            dz: g.pick(&[0.0f32, 1.0, 1e-6, 0.5, 1e4]),
            mu: if g.coin(0.5) {
                g.pick(&[1.0f32, 1e-7, 0.0, 0.5, 0.02])
            } else {
                g.u()
            },
            hero: g.pick(&[0.0f32, 1.0, 2.0]),
            ratios: g.pick(&[
                [1.0f32, 1.0, 1.0],
                [3.0, 0.0, 0.0],
                [0.5, 1.5, 1.0],
                [1e-20, 2.0, 1.0],
            ]),
        });
    }
    check("medium", &MediumAll, &inputs);
}

// ---------------------------------------------------------------------------
// Warps, frames, fastmath
// ---------------------------------------------------------------------------

struct WarpsFrame;
impl Kernel<([f32; 2], [f32; 3], [f32; 3])> for WarpsFrame {
    fn run<L: Lane>(&self, x: &[([f32; 2], [f32; 3], [f32; 3])]) -> Out<L> {
        let u1 = ln(x, |t| t.0[0]);
        let u2 = ln(x, |t| t.0[1]);
        let f = Frame::around(v3(x, |t| t.1));
        let mut o = Out::new();
        o.v3(sample_cosine_hemisphere(u1, u2))
            .v3(sample_uniform_sphere(u1, u2))
            .v3(f.t)
            .v3(f.b)
            .v3(f.n)
            .v3(f.to_world(v3(x, |t| t.2)));
        o
    }
}

#[test]
fn warps_and_frames() {
    let mut g = Gen::new(7);
    let mut inputs = vec![];
    for u1 in U_EDGES {
        for u2 in U_EDGES {
            inputs.push(([u1, u2], g.dir(), g.dir()));
        }
    }
    for c in edge_cosines() {
        for phi in [0.0, 0.25, 0.5, 0.75, 0.3] {
            inputs.push(([g.u(), g.u()], dir_cos(c, phi), g.dir()));
        }
    }
    for _ in 0..2000 {
        inputs.push(([g.u(), g.u()], g.dir(), g.dir()));
    }
    check("warps and Frame", &WarpsFrame, &inputs);
}

struct FastMath;
impl Kernel<[f32; 4]> for FastMath {
    fn run<L: Lane>(&self, x: &[[f32; 4]]) -> Out<L> {
        let (s, c) = ln::<L, _>(x, |t| t[3]).sin_cos_turns();
        let mut o = Out::new();
        o.val(ln::<L, _>(x, |t| t[0]).exp())
            .val(ln::<L, _>(x, |t| t[1]).exp_m1())
            .val(ln::<L, _>(x, |t| t[2]).ln())
            .val(s)
            .val(c);
        o
    }
}

/// The next f32 below / above a positive `x`.
fn below(x: f32) -> f32 {
    f32::from_bits(x.to_bits() - 1)
}
fn above(x: f32) -> f32 {
    f32::from_bits(x.to_bits() + 1)
}

#[test]
fn fastmath_functions() {
    use std::f32::consts::{FRAC_1_SQRT_2, LN_2};
    let mut g = Gen::new(8);
    let exp_edges = [
        0.0f32,
        -0.0,
        -87.0,
        -87.5,
        -100.0,
        88.0,
        88.7,
        100.0,
        f32::INFINITY,
        f32::NEG_INFINITY,
        1e-8,
        -1e-8,
        0.35,
        -0.35,
        below(0.35),
        LN_2,
        -LN_2,
        below(LN_2),
        above(LN_2),
        1.0,
        -1.0,
    ];
    let ln_edges = [
        0.0f32,
        -0.0,
        -1.0,
        f32::MIN_POSITIVE,
        1e-40,
        1.0,
        f32::MAX,
        f32::INFINITY,
        FRAC_1_SQRT_2,
        below(FRAC_1_SQRT_2),
        above(FRAC_1_SQRT_2),
        1.0 - 1.0 / 16_777_216.0,
        1.0 / 16_777_216.0,
    ];
    let turn_edges = [
        0.0f32,
        -0.0,
        0.125,
        0.25,
        0.375,
        0.5,
        0.625,
        0.75,
        0.875,
        1.0,
        -0.25,
        3.75,
        0.999_999_94,
    ];
    let mut inputs = vec![];
    for i in 0..exp_edges.len().max(ln_edges.len()).max(turn_edges.len()) {
        let e = exp_edges[i % exp_edges.len()];
        inputs.push([
            e,
            e,
            ln_edges[i % ln_edges.len()],
            turn_edges[i % turn_edges.len()],
        ]);
    }
    for _ in 0..20_000 {
        let e = g.range(-90.0, 90.0);
        let l = f32::from_bits(g.0.next_u32() & 0x7fff_ffff);
        let l = if l.is_finite() { l } else { 1.0 };
        inputs.push([e, g.range(-2.0, 2.0), l, g.range(-2.0, 3.0)]);
    }
    check("fastmath", &FastMath, &inputs);
}
