//! The physics kernels against closed forms and independent formulas written
//! here in f64 (never calling the code under test for the reference).
//!
//! Tolerances: the f64 lane must match to rounding (1e-13 or so, or a stated
//! conditioning bound); the f32 lane to its own precision (a few 1e-7
//! relative, or 64 ulps times the condition number of the quantity where the
//! problem is ill-conditioned: near the critical angle, near grazing
//! microfacets). Integrals use adaptive Gauss–Kronrod (`common/chi2.rs`) and
//! are compared within twice their own error estimate plus 1e-9 (1e-8 where
//! an approximation is involved). Monte Carlo means are compared with
//! |z| < 4.5 (30 comparisons, so a false alarm has probability ~2e-4).

use crate::common;

use common::chi2::{gauss_kronrod, SphereGrid};
use common::dir;
use common::reference::fresnel as fresnel_ref;
use common::reference::fresnel_conductor as conductor_ref;
use std::f64::consts::PI;
use strata_bsdf::fresnel;
use strata_bsdf::interface::InterfaceLanes;
use strata_bsdf::lane::{Lane, LaneMask, Rgb, V3};
use strata_bsdf::math::fastmath;
use strata_bsdf::microfacet::Microfacet;
use strata_bsdf::phase::hg::hg_eval;
use strata_bsdf::rng::{Stream, WalkRng};

// ---------------------------------------------------------------------------
// Independent references
// ---------------------------------------------------------------------------

/// The transmitted cosine of [`fresnel_ref`] (`common::reference::fresnel`) (0 under total internal reflection).
fn cos_t_ref(ci: f64, n1: f64, n2: f64) -> f64 {
    (1.0 - (n1 / n2).powi(2) * (1.0 - ci * ci)).max(0.0).sqrt()
}

/// Exact Beckmann Λ (for reference): (erf(a) - 1)/2 + e^{-a²} / (2a√π), with
/// erfc from its continued fraction / series (double precision).
fn erfc(x: f64) -> f64 {
    if x < 2.0 {
        // erf series: 2/√π Σ (-1)^n x^(2n+1) / (n! (2n+1))
        let mut term = x;
        let mut sum = x;
        let mut n = 0.0;
        loop {
            n += 1.0;
            term *= -x * x / n;
            let t = term / (2.0 * n + 1.0);
            sum += t;
            if t.abs() < 1e-17 * sum.abs() {
                break;
            }
        }
        1.0 - 2.0 / PI.sqrt() * sum
    } else {
        // Continued fraction (Lentz) for erfc.
        let tiny = 1e-300;
        let mut f = x;
        let mut c = x;
        let mut d = 0.0;
        for i in 1..500 {
            let an = i as f64 * 0.5;
            d = x + an * d;
            d = if d.abs() < tiny { tiny } else { d };
            c = x + an / c;
            c = if c.abs() < tiny { tiny } else { c };
            d = 1.0 / d;
            let del = c * d;
            f *= del;
            if (del - 1.0).abs() < 1e-16 {
                break;
            }
        }
        (-x * x).exp() / (PI.sqrt() * f)
    }
}

fn beckmann_lambda_exact(a: f64) -> f64 {
    (-erfc(a)) / 2.0 + (-a * a).exp() / (2.0 * a * PI.sqrt())
}

// ---------------------------------------------------------------------------
// Builders
// ---------------------------------------------------------------------------

fn microfacet<L: Lane>(ax: f64, ay: f64, beckmann: bool, separable: bool) -> Microfacet<L> {
    Microfacet {
        alpha_x: L::splat(ax),
        alpha_y: L::splat(ay),
        beckmann: L::Mask::splat(beckmann),
        separable: L::Mask::splat(separable),
    }
}

#[derive(Clone, Copy, Debug)]
enum Kind {
    Dielectric { n_above: f64, n_below: f64 },
    Conductor { eta: [f64; 3], k: [f64; 3] },
    Diffuse { albedo: [f64; 3] },
}

#[derive(Clone, Copy, Debug)]
struct Iface {
    kind: Kind,
    /// None: smooth.
    rough: Option<(f64, f64, bool, bool)>,
}

impl Iface {
    fn lanes<L: Lane>(&self) -> InterfaceLanes<L> {
        let f = L::Mask::splat(false);
        let t = L::Mask::splat(true);
        let (ax, ay, beck, sep) = self.rough.unwrap_or((1.0, 1.0, false, false));
        let mut it = InterfaceLanes {
            n_above: L::one(),
            n_below: L::one(),
            mf: microfacet(ax, ay, beck, sep),
            smooth: L::Mask::splat(self.rough.is_none()),
            dielectric: f,
            conductor: f,
            diffuse: f,
            eta: Rgb::one(),
            k: Rgb::zero(),
            albedo: Rgb::zero(),
            normal: V3::z_axis(),
            tilted: false,
            adjoint: false,
            run_all: false,
        };
        match self.kind {
            Kind::Dielectric { n_above, n_below } => {
                it.dielectric = t;
                it.n_above = L::splat(n_above);
                it.n_below = L::splat(n_below);
            }
            Kind::Conductor { eta, k } => {
                it.conductor = t;
                it.eta = Rgb::from_array(eta);
                it.k = Rgb::from_array(k);
            }
            Kind::Diffuse { albedo } => {
                it.diffuse = t;
                it.albedo = Rgb::from_array(albedo);
            }
        }
        it
    }
    /// IORs on the side of `a` and on the other side.
    fn sides(&self, a_up: bool) -> (f64, f64) {
        match self.kind {
            Kind::Dielectric { n_above, n_below } if a_up => (n_above, n_below),
            Kind::Dielectric { n_above, n_below } => (n_below, n_above),
            _ => (1.0, 1.0),
        }
    }
}

const CU: Kind = Kind::Conductor {
    eta: [0.27, 0.68, 1.3],
    k: [3.6, 2.6, 2.3],
};

fn v64(d: [f64; 3]) -> V3<f64> {
    V3::new(d[0], d[1], d[2])
}
fn v32(d: [f64; 3]) -> V3<f32> {
    V3::new(d[0] as f32, d[1] as f32, d[2] as f32)
}
fn up(v: V3<f32>) -> V3<f64> {
    V3::new(v.x as f64, v.y as f64, v.z as f64)
}
fn rgb64(v: Rgb<f32>) -> [f64; 3] {
    [v.r as f64, v.g as f64, v.b as f64]
}

/// The condition number that rounding errors in an interface value for the
/// pair (a, b) are amplified by, beyond a few ulps: 1/|a·h| and 1/|b·h| (dot
/// products that cancel near the edge of the microfacet configurations) and,
/// for transmission, the relative conditioning of 1 - F (which cancels as
/// F → 1, near total internal reflection or at grazing microfacets) and the
/// cancellation in the Jacobian's n_a a·h + n_b b·h. Computed in f64
/// with the reference Fresnel, independently of the kernel.
fn condition(it: &Iface, a: V3<f64>, b: V3<f64>) -> f64 {
    let (n_a, n_b) = it.sides(a.z > 0.0);
    let reflection = a.z * b.z > 0.0;
    let h = if reflection {
        a + b
    } else {
        -(a * n_a + b * n_b)
    };
    let h = h * (1.0 / h.length());
    let (ah, bh) = (a.dot(h).abs(), b.dot(h).abs());
    let mut c = 1.0 + 1.0 / ah + 1.0 / bh;
    if reflection {
        // F itself near total internal reflection: 2ε / (cos θt (cos θi + cos θt)),
        // relative to F >= its value at normal incidence (0 under TIR, where F
        // is exactly 1).
        let ct = cos_t_ref(ah, n_a, n_b);
        if ct > 0.0 && n_a != n_b {
            let f = fresnel_ref(ah, n_a, n_b);
            c += 2.0 / (ct * (ah + ct) * f);
        }
    } else {
        // F moves by ~2ε / (cos θt (cos θi + cos θt)) (see the Fresnel test),
        // and 1 - F by that much relative to itself; either side may be the
        // incident one (eval(b, a) computes F from b), so take the worse.
        let t = (1.0 - fresnel_ref(ah, n_a, n_b)).max(1e-300);
        c += 2.0 / (ah.min(bh) * (ah + bh) * t);
        // The Jacobian's (n_a a·h + n_b b·h)², whose terms have opposite signs.
        c += 2.0 * (n_a * ah + n_b * bh) / (n_a * ah - n_b * bh).abs().max(1e-300);
    }
    c
}

/// ∫ f over the sphere: nested adaptive Gauss–Kronrod with the careful error
/// check on a 10 × 20 grid (cells split at `breaks` in cos θ), to relative
/// accuracy `rel` per cell. Returns the integral and its error estimate.
fn sphere_integral(f: &dyn Fn([f64; 3]) -> f64, breaks: &[f64], rel: f64) -> (f64, f64) {
    let grid = SphereGrid {
        n_cos: 10,
        n_phi: 20,
    };
    let (cells, err) = grid.integrate(f, breaks, &|p: f64| rel * p + 1e-4 * rel, true);
    (cells.iter().sum(), err)
}

// ---------------------------------------------------------------------------
// Fresnel
// ---------------------------------------------------------------------------

const ETAS: [f64; 8] = [1.0001, 1.1, 1.33, 1.5, 2.0, 2.4, 4.0, 1.0 / 1.5];

#[test]
fn dielectric_fresnel_at_normal_incidence() {
    for eta in ETAS {
        // The f32 kernel sees the f32 value of eta.
        let e32 = eta as f32;
        let r64 = ((eta - 1.0) / (eta + 1.0)).powi(2);
        let e = e32 as f64;
        let r32 = ((e - 1.0) / (e + 1.0)).powi(2);
        for c in [1.0, -1.0] {
            let f = fresnel::dielectric::<f64>(c, eta);
            assert!(
                (f - r64).abs() <= 1e-14 * r64,
                "eta {eta} cos {c}: {f} vs {r64}"
            );
            let f = fresnel::dielectric::<f32>(c as f32, e32) as f64;
            assert!(
                (f - r32).abs() <= 4e-7 * r32,
                "f32 eta {eta} cos {c}: {f} vs {r32}"
            );
        }
    }
}

#[test]
fn dielectric_fresnel_against_independent_formula() {
    let n = 4001;
    for eta in ETAS {
        for i in 0..n {
            let c = -1.0 + 2.0 * i as f64 / (n - 1) as f64;
            let (n1, n2) = if c >= 0.0 { (1.0, eta) } else { (eta, 1.0) };
            let want = fresnel_ref(c.abs(), n1, n2);
            // Near the critical angle F has an infinite slope in cos θt: an
            // absolute error ε in cos²θt moves cos θt by ε / (2 cos θt), and
            // |dF / dcos θt| <= 4 / (cos θi + cos θt), in the reference as in
            // the kernel.
            let ct = cos_t_ref(c.abs(), n1, n2);
            let got = fresnel::dielectric::<f64>(c, eta);
            let tol = 1e-13 + 8.0 * f64::EPSILON / (ct * (c.abs() + ct)).max(1e-300);
            assert!(
                (got - want).abs() <= tol.min(1.0),
                "f64 eta {eta} cos {c}: {got} vs {want}"
            );
            let c32 = c as f32;
            let e32 = eta as f32;
            let (n1, n2) = if c32 >= 0.0 {
                (1.0, e32 as f64)
            } else {
                (e32 as f64, 1.0)
            };
            let ci = (c32 as f64).abs();
            let want = fresnel_ref(ci, n1, n2);
            let ct = cos_t_ref(ci, n1, n2);
            let got = fresnel::dielectric::<f32>(c32, e32) as f64;
            let tol = 4e-7 + 8.0 * f32::EPSILON as f64 / (ct * (ci + ct)).max(1e-300);
            assert!(
                (got - want).abs() <= tol.min(1.0),
                "f32 eta {eta} cos {c32}: {got} vs {want} (tol {tol:e})"
            );
        }
    }
}

#[test]
fn dielectric_fresnel_total_internal_reflection_and_index_match() {
    for eta in [1.33f64, 1.5, 2.4, 4.0] {
        let crit = (1.0 - 1.0 / (eta * eta)).sqrt();
        for i in 0..=1000 {
            // From the dense side, beyond the critical angle (|cos| < crit).
            let c = crit * (1.0 - 1e-9) * i as f64 / 1000.0;
            assert_eq!(
                fresnel::dielectric::<f64>(-c, eta),
                1.0,
                "eta {eta} cos -{c}"
            );
            // The same boundary with the dense side above (eta < 1).
            assert_eq!(
                fresnel::dielectric::<f64>(c, 1.0 / eta),
                1.0,
                "eta 1/{eta} cos {c}"
            );
            let c32 = (c * (1.0 - 1e-6)) as f32;
            assert_eq!(fresnel::dielectric::<f32>(-c32, eta as f32), 1.0);
        }
    }
    // Index matched: exactly 0 at every angle, from both sides.
    for i in 0..=2000 {
        let c = -1.0 + i as f64 / 1000.0;
        assert_eq!(fresnel::dielectric::<f64>(c, 1.0), 0.0, "cos {c}");
        assert_eq!(fresnel::dielectric::<f32>(c as f32, 1.0), 0.0, "cos {c}");
    }
}

const METALS: [(f64, f64); 7] = [
    (0.27, 3.6),
    (0.18, 3.42),
    (1.5, 0.0),
    (2.9, 3.0),
    (0.05, 100.0),
    (1.0, 0.0),
    (1.2, 7.0),
];

#[test]
fn conductor_fresnel_closed_forms() {
    for (n, k) in METALS {
        let r0 = ((n - 1.0).powi(2) + k * k) / ((n + 1.0).powi(2) + k * k);
        let f = fresnel::conductor::<f64>(1.0, Rgb::splat(n), Rgb::splat(k));
        assert!((f.r - r0).abs() <= 1e-13, "n {n} k {k}: {} vs {r0}", f.r);
        let f = fresnel::conductor::<f32>(1.0, Rgb::splat(n as f32), Rgb::splat(k as f32));
        assert!(
            (f.g as f64 - r0).abs() <= 5e-7,
            "f32 n {n} k {k}: {} vs {r0}",
            f.g
        );
        for i in 0..=2000 {
            let c = i as f64 / 2000.0;
            if c == 0.0 && (n, k) == (1.0, 0.0) {
                // No boundary at all, seen at grazing incidence: 0/0.
                continue;
            }
            let want = conductor_ref(c, n, k);
            let got = fresnel::conductor::<f64>(c, Rgb::splat(n), Rgb::splat(k)).b;
            assert!(
                (got - want).abs() <= 1e-12,
                "n {n} k {k} cos {c}: {got} vs {want}"
            );
            let c32 = c as f32;
            let want = conductor_ref(c32 as f64, n as f32 as f64, k as f32 as f64);
            let got = fresnel::conductor::<f32>(c32, Rgb::splat(n as f32), Rgb::splat(k as f32)).r;
            assert!(
                (got as f64 - want).abs() <= 5e-7,
                "f32 n {n} k {k} cos {c32}: {got} vs {want}"
            );
        }
    }
    // A conductor with k = 0 and n > 1 is a dielectric seen from outside.
    for i in 0..=100 {
        let c = i as f64 / 100.0;
        let f = fresnel::conductor::<f64>(c, Rgb::splat(1.5), Rgb::zero()).r;
        assert!((f - fresnel_ref(c, 1.0, 1.5)).abs() < 1e-12);
    }
}

#[test]
fn refraction_obeys_snell() {
    let mut rng = WalkRng::new(11, 0, 0, Stream::Walk);
    for i in 0..20_000 {
        let u = |r: &mut WalkRng| r.uniform() as f64;
        let a = dir(u(&mut rng).acos().to_degrees(), 360.0 * u(&mut rng));
        let m = dir(60.0 * u(&mut rng), 360.0 * u(&mut rng));
        if a[0] * m[0] + a[1] * m[1] + a[2] * m[2] <= 1e-6 {
            continue;
        }
        let eta = [1.5, 1.0 / 1.5, 1.33, 2.4][i % 4];
        let (b, ok) = fresnel::refract(v64(a), v64(m), eta);
        let (a, m) = (v64(a), v64(m));
        let ci = a.dot(m);
        let sin_i = (1.0 - ci * ci).sqrt();
        let tir = sin_i / eta >= 1.0;
        assert_eq!(ok, !tir, "TIR mask at sin {sin_i} eta {eta}");
        if tir {
            continue;
        }
        let bm = b.dot(m);
        assert!((b.length() - 1.0).abs() < 1e-12, "|b| = {}", b.length());
        assert!(bm < 0.0, "b must cross the microfacet");
        let sin_t = (1.0 - bm * bm).max(0.0).sqrt();
        assert!(
            (sin_t * eta - sin_i).abs() < 1e-9,
            "Snell: {sin_t} * {eta} vs {sin_i}"
        );
        // Coplanar: b lies in the plane of a and m, on the other side of m.
        let cross = V3::new(
            a.y * m.z - a.z * m.y,
            a.z * m.x - a.x * m.z,
            a.x * m.y - a.y * m.x,
        );
        assert!(b.dot(cross).abs() < 1e-12);
        assert!(
            b.dot(a - m * ci) <= 1e-12,
            "tangential parts must be opposite"
        );
    }
}

// ---------------------------------------------------------------------------
// Lambertian
// ---------------------------------------------------------------------------

#[test]
fn lambertian_value_and_albedo() {
    let albedo = [0.8, 0.5, 0.0];
    let it = Iface {
        kind: Kind::Diffuse { albedo },
        rough: Some((1.0, 1.0, false, false)),
    };
    let l64 = it.lanes::<f64>();
    let l32 = it.lanes::<f32>();
    let mut rng = WalkRng::new(12, 0, 0, Stream::Walk);
    for _ in 0..1000 {
        let a = dir(89.9 * rng.uniform() as f64, 360.0 * rng.uniform() as f64);
        let b = dir(89.9 * rng.uniform() as f64, 360.0 * rng.uniform() as f64);
        let f = l64.eval(v64(a), v64(b));
        for (c, &al) in [f.r, f.g, f.b].iter().zip(&albedo) {
            assert!((c - al / PI).abs() <= 1e-15);
        }
        let f = l32.eval(v32(a), v32(b));
        assert!((f.r as f64 - 0.8 / PI).abs() <= 1e-7);
        // Below the surface: nothing.
        let bb = [b[0], b[1], -b[2]];
        assert_eq!(rgb64(l32.eval(v32(a), v32(bb))), [0.0; 3]);
        assert_eq!(rgb64(l32.eval(v32(bb), v32(a))), [0.0; 3]);
    }
    let a = v64(dir(40.0, 0.0));
    let (alb, err) = sphere_integral(&|b| l64.eval(a, v64(b)).r * b[2].abs(), &[], 1e-8);
    assert!(
        (alb - 0.8).abs() <= 2.0 * err + 1e-9,
        "albedo {alb} ± {err}"
    );
}

// ---------------------------------------------------------------------------
// Microfacet distributions
// ---------------------------------------------------------------------------

const ALPHAS: [(f64, f64); 6] = [
    (0.05, 0.05),
    (0.2, 0.2),
    (0.5, 0.5),
    (1.0, 1.0),
    (0.1, 0.5),
    (1.0, 0.3),
];

#[test]
fn microfacet_distributions_are_normalized() {
    for (ax, ay) in ALPHAS {
        for beck in [false, true] {
            let mf = microfacet::<f64>(ax, ay, beck, false);
            let (v, err) = sphere_integral(&|m| mf.d(v64(m)) * m[2].max(0.0), &[], 1e-8);
            assert!(
                (v - 1.0).abs() <= 2.0 * err + 1e-9,
                "∫ D cos, ({ax}, {ay}) beckmann={beck}: {v} ± {err}"
            );
        }
    }
}

#[test]
fn visible_normals_are_normalized() {
    // GGX: exact Smith Λ, so ∫ G1(w) max(0, w·m) D(m) / w.z dω = 1.
    for (ax, ay) in [(0.05, 0.05), (0.5, 0.5), (0.1, 0.5), (1.0, 0.3)] {
        let mf = microfacet::<f64>(ax, ay, false, false);
        for (theta, phi) in [(0.0, 0.0), (60.0, 100.0), (89.9, 200.0)] {
            let w = v64(dir(theta, phi));
            let g1 = mf.g1(w);
            let f = |m: [f64; 3]| g1 * w.dot(v64(m)).max(0.0) * mf.d(v64(m)) / w.z;
            let (v, err) = sphere_integral(&f, &[], 1e-8);
            assert!(
                (v - 1.0).abs() <= 2.0 * err + 1e-9,
                "GGX visible normals ({ax}, {ay}) θ {theta}: {v} ± {err}"
            );
        }
    }
    // Beckmann: Λ is Walter et al.'s rational fit, so the same integral is
    // 1 + (Λ_exact - Λ_fit) / (1 + Λ_fit). Check the fit against the exact Λ
    // (its published accuracy is a few 1e-3 relative in G1) and the integral
    // against what that fit implies.
    for (ax, ay) in [(0.2, 0.2), (0.1, 0.5)] {
        let mf = microfacet::<f64>(ax, ay, true, false);
        for (theta, phi) in [(30.0, 10.0), (85.0, 45.0)] {
            let w = v64(dir(theta, phi));
            let t = theta.to_radians().tan();
            let (c, s) = (phi.to_radians().cos(), phi.to_radians().sin());
            let alpha = (ax * ax * c * c + ay * ay * s * s).sqrt();
            let exact = beckmann_lambda_exact(1.0 / (alpha * t));
            let fit = mf.lambda(w);
            let g1_err = ((1.0 + exact) / (1.0 + fit) - 1.0).abs();
            assert!(
                g1_err < 4e-3,
                "Beckmann G1 fit error {g1_err} at a = {}",
                1.0 / (alpha * t)
            );
            let g1 = mf.g1(w);
            let f = |m: [f64; 3]| g1 * w.dot(v64(m)).max(0.0) * mf.d(v64(m)) / w.z;
            let (v, err) = sphere_integral(&f, &[], 1e-8);
            let want = (1.0 + exact) / (1.0 + fit);
            assert!(
                (v - want).abs() <= 2.0 * err + 1e-8,
                "Beckmann visible normals ({ax}, {ay}) θ {theta}: {v} ± {err}, expected {want}"
            );
        }
    }
}

#[test]
fn henyey_greenstein_normalization_and_mean_cosine() {
    for g in [-0.99, -0.9, -0.5, 0.0, 0.3, 0.9, 0.99] {
        let norm = gauss_kronrod(
            &mut |mu| 2.0 * PI * hg_eval(g, mu),
            [-1.0, 1.0],
            1e-10,
            25,
            true,
        );
        assert!(
            (norm.value - 1.0).abs() <= 2.0 * norm.err + 1e-9,
            "g {g}: ∫ p = {norm:?}"
        );
        let mean = gauss_kronrod(
            &mut |mu| 2.0 * PI * mu * hg_eval(g, mu),
            [-1.0, 1.0],
            1e-10,
            25,
            true,
        );
        assert!(
            (mean.value - g).abs() <= 2.0 * mean.err + 1e-9,
            "g {g}: mean cosine {mean:?}"
        );
    }
}

// ---------------------------------------------------------------------------
// Interfaces
// ---------------------------------------------------------------------------

fn rough_cases() -> Vec<Iface> {
    let mut v = vec![];
    for (ax, ay) in [(0.3, 0.3), (0.1, 0.5), (0.7, 0.7)] {
        for beck in [false, true] {
            for sep in [false, true] {
                let r = Some((ax, ay, beck, sep));
                v.push(Iface {
                    kind: Kind::Dielectric {
                        n_above: 1.0,
                        n_below: 1.5,
                    },
                    rough: r,
                });
                v.push(Iface {
                    kind: Kind::Dielectric {
                        n_above: 1.33,
                        n_below: 1.0,
                    },
                    rough: r,
                });
                v.push(Iface { kind: CU, rough: r });
            }
        }
    }
    v.push(Iface {
        kind: Kind::Diffuse {
            albedo: [0.9, 0.5, 0.1],
        },
        rough: Some((1.0, 1.0, false, false)),
    });
    v
}

#[test]
fn sampled_weights_match_eval_and_pdf() {
    let mut rng = WalkRng::new(13, 0, 0, Stream::Walk);
    let mut worst = 0.0f64;
    let mut checked = 0;
    for it in rough_cases() {
        let l32 = it.lanes::<f32>();
        for k in 0..4000 {
            let c = if k % 50 == 0 {
                0.02
            } else {
                rng.uniform() as f64
            };
            let mut a = dir(c.acos().to_degrees(), 360.0 * rng.uniform() as f64);
            if rng.uniform() < 0.5 {
                a[2] = -a[2];
            }
            let t_only = rng.uniform() < 0.3;
            let a = v32(a);
            let u = [rng.uniform(), rng.uniform(), rng.uniform()];
            let s = l32.sample(a, u[0], u[1], u[2], t_only);
            let w = rgb64(s.weight);
            assert!(w.iter().all(|x| x.is_finite() && *x >= 0.0));
            if !s.valid {
                assert_eq!(w, [0.0; 3], "invalid samples weigh nothing");
                continue;
            }
            assert!(!s.delta);
            let pdf = l32.pdf(a, s.b, t_only);
            assert_eq!(s.pdf.to_bits(), pdf.to_bits(), "sample pdf vs pdf()");
            assert!(pdf > 0.0);
            let f = rgb64(l32.eval(a, s.b));
            let cond = condition(&it, up(a), up(s.b));
            for ch in 0..3 {
                let want = f[ch] * (s.b.z as f64).abs() / pdf as f64;
                let rel = (w[ch] - want).abs() / want.max(1e-30);
                worst = worst.max(rel / cond);
                assert!(
                    rel <= 64.0 * f32::EPSILON as f64 * cond,
                    "{it:?} a {a:?} t_only {t_only}: weight {} vs eval cos / pdf {want} (rel {rel:e})",
                    w[ch]
                );
            }
            checked += 1;
        }
    }
    eprintln!("{checked} samples, worst relative difference / condition {worst:e}");
    assert!(checked > 50_000);
}

#[test]
fn smooth_interfaces_have_exact_delta_weights() {
    for eta in [1.5f64, 1.33, 2.4, 1.0 / 1.5] {
        let it = Iface {
            kind: Kind::Dielectric {
                n_above: 1.0,
                n_below: eta,
            },
            rough: None,
        };
        let l32 = it.lanes::<f32>();
        for i in 0..=200 {
            let c = -1.0 + i as f64 / 100.0;
            if c == 0.0 {
                continue;
            }
            let a = v32(dir(c.acos().to_degrees(), 37.0));
            let ci = (a.z as f64).abs();
            let (n1, n2) = if a.z > 0.0 {
                (1.0, eta as f32 as f64)
            } else {
                (eta as f32 as f64, 1.0)
            };
            let f = fresnel_ref(ci, n1, n2);
            let ct = cos_t_ref(ci, n1, n2);
            let tol = 1e-6 + 8.0 * f32::EPSILON as f64 / ct.max(1e-300);
            // Transmission alone: the weight is 1 - F, the direction obeys Snell.
            let s = l32.sample(a, 0.5, 0.5, 0.5, true);
            assert!(s.delta && s.pdf == 0.0);
            if f < 1.0 - tol {
                assert!(s.valid, "eta {eta} cos {c}: refraction must be valid");
                let w = s.weight.g as f64;
                assert!(
                    (w - (1.0 - f)).abs() <= tol,
                    "eta {eta} cos {c}: T {w} vs {}",
                    1.0 - f
                );
                assert_eq!(s.weight.r, s.weight.b);
                let b = up(s.b);
                assert!(b.z * a.z as f64 <= 0.0);
                assert!(
                    (b.z.abs() - ct).abs() <= 4e-6 / ct.max(1e-3),
                    "cos t {} vs {ct}",
                    b.z
                );
                assert!(
                    (b.x * n2 + a.x as f64 * n1).abs() < 1e-5,
                    "tangential momentum"
                );
            } else if f >= 1.0 {
                assert!(!s.valid && s.weight.r == 0.0, "TIR: no transmission");
            }
            // Both lobes: reflection is chosen with probability F and weighs 1;
            // transmission weighs 1 too, so R + T = 1 in expectation.
            for (us, expect_reflect) in [(f * (1.0 - 1e-4) - 1e-6, true), (f + 1e-4 + tol, false)] {
                if !(0.0..1.0).contains(&us) {
                    continue;
                }
                let s = l32.sample(a, us as f32, 0.5, 0.5, false);
                assert!(s.valid && s.delta && s.pdf == 0.0);
                assert_eq!(rgb64(s.weight), [1.0; 3], "eta {eta} cos {c}");
                let b = up(s.b);
                let reflected = b.z * a.z as f64 > 0.0;
                assert_eq!(reflected, expect_reflect, "eta {eta} cos {c} u {us} F {f}");
                if reflected {
                    assert_eq!(s.b.x, -a.x);
                    assert_eq!(s.b.y, -a.y);
                    assert_eq!(s.b.z, a.z);
                }
            }
            // R + T = 1: the reflected fraction of a stratified u_select is F.
            let n = 20_000;
            let refl = (0..n)
                .filter(|&j| {
                    let s = l32.sample(a, (j as f32 + 0.5) / n as f32, 0.5, 0.5, false);
                    s.b.z * a.z > 0.0
                })
                .count() as f64
                / n as f64;
            assert!(
                (refl - f).abs() <= 1.0 / n as f64 + tol,
                "eta {eta} cos {c}: R {refl} vs {f}"
            );
        }
    }
    // Smooth conductor: mirror direction, weight F(cos θ) per channel.
    let it = Iface {
        kind: CU,
        rough: None,
    };
    let l32 = it.lanes::<f32>();
    let Kind::Conductor { eta, k } = CU else {
        unreachable!()
    };
    for i in 1..=100 {
        let a = v32(dir((i as f64 / 100.0).acos().to_degrees(), 20.0));
        let s = l32.sample(a, 0.3, 0.3, 0.3, false);
        assert!(s.valid && s.delta && s.pdf == 0.0);
        assert_eq!((s.b.x, s.b.y, s.b.z), (-a.x, -a.y, a.z));
        let w = rgb64(s.weight);
        for ch in 0..3 {
            let want = conductor_ref(a.z as f64, eta[ch], k[ch]);
            assert!(
                (w[ch] - want).abs() < 5e-7,
                "conductor ch {ch}: {} vs {want}",
                w[ch]
            );
        }
        // Smooth lobes are never evaluated.
        let b = s.b;
        assert_eq!(rgb64(l32.eval(a, b)), [0.0; 3]);
        assert_eq!(l32.pdf(a, b, false), 0.0);
    }
}

#[test]
fn interface_reciprocity() {
    let mut rng = WalkRng::new(14, 0, 0, Stream::Walk);
    let mut nonzero = 0;
    let (mut worst64, mut worst32) = (0.0f64, 0.0f64);
    for it in rough_cases() {
        let l64 = it.lanes::<f64>();
        let l32 = it.lanes::<f32>();
        for _ in 0..2000 {
            let u = |r: &mut WalkRng| r.uniform() as f64;
            let mut a = dir(u(&mut rng).acos().to_degrees(), 360.0 * u(&mut rng));
            let mut b = dir(u(&mut rng).acos().to_degrees(), 360.0 * u(&mut rng));
            if u(&mut rng) < 0.5 {
                a[2] = -a[2];
            }
            if u(&mut rng) < 0.5 {
                b[2] = -b[2];
            }
            let (n_a, n_b) = it.sides(a[2] > 0.0);
            let (ab, ba) = (l64.eval(v64(a), v64(b)), l64.eval(v64(b), v64(a)));
            // Reflection: f(a, b) = f(b, a); transmission: f(a, b) / n_b² = f(b, a) / n_a².
            let (sa, sb) = if a[2] * b[2] > 0.0 {
                (1.0, 1.0)
            } else {
                (1.0 / (n_b * n_b), 1.0 / (n_a * n_a))
            };
            let cond = condition(&it, v64(a), v64(b));
            for (x, y) in [(ab.r, ba.r), (ab.g, ba.g), (ab.b, ba.b)] {
                let (x, y) = (x * sa, y * sb);
                let rel = (x - y).abs() / x.abs().max(y.abs()).max(1e-300);
                worst64 = worst64.max(rel / cond);
                assert!(
                    rel <= 64.0 * f64::EPSILON * cond,
                    "{it:?}: f(a,b) {x} vs f(b,a) {y} for a {a:?} b {b:?} (rel {rel:e}, condition {cond:e})"
                );
                if x > 0.0 {
                    nonzero += 1;
                }
            }
            let (ab, ba) = (l32.eval(v32(a), v32(b)), l32.eval(v32(b), v32(a)));
            let (x, y) = (ab.g as f64 * sa, ba.g as f64 * sb);
            let rel = (x - y).abs() / x.abs().max(y.abs()).max(1e-300);
            worst32 = worst32.max(rel / cond);
            assert!(
                rel <= 64.0 * f32::EPSILON as f64 * cond,
                "f32 {it:?}: f(a,b) {x} vs f(b,a) {y} for a {a:?} b {b:?} (rel {rel:e}, condition {cond:e})"
            );
        }
    }
    eprintln!("worst relative difference / condition: f64 {worst64:e}, f32 {worst32:e}");
    assert!(nonzero > 10_000, "too few non-zero pairs: {nonzero}");
}

#[test]
fn single_interface_albedo() {
    // ∫ f(a, b) |b.z| db by quadrature (f64, to a relative 1e-6) never exceeds
    // 1, and equals the mean weight of the f32 sampler (an independent Monte
    // Carlo estimate), with and without transmit_only.
    let glass = Kind::Dielectric {
        n_above: 1.0,
        n_below: 1.5,
    };
    let dense_above = Kind::Dielectric {
        n_above: 1.33,
        n_below: 1.0,
    };
    let cases = [
        Iface {
            kind: glass,
            rough: Some((0.3, 0.3, false, false)),
        },
        Iface {
            kind: dense_above,
            rough: Some((0.1, 0.5, true, true)),
        },
        Iface {
            kind: glass,
            rough: Some((0.7, 0.7, false, true)),
        },
        Iface {
            kind: CU,
            rough: Some((0.3, 0.3, false, false)),
        },
        Iface {
            kind: CU,
            rough: Some((0.7, 0.2, true, true)),
        },
        Iface {
            kind: Kind::Diffuse {
                albedo: [0.9, 0.5, 0.1],
            },
            rough: Some((1.0, 1.0, false, false)),
        },
    ];
    let mut rng = WalkRng::new(15, 0, 0, Stream::Walk);
    for it in cases {
        let dielectric = matches!(it.kind, Kind::Dielectric { .. });
        let l64 = it.lanes::<f64>();
        let l32 = it.lanes::<f32>();
        for (theta, below) in [(20.0, false), (70.0, false), (40.0, true), (85.0, true)] {
            if below && !dielectric {
                continue;
            }
            let mut a = dir(theta, 30.0);
            if below {
                a[2] = -a[2];
            }
            let (n_a, n_b) = it.sides(!below);
            let a64 = v64(a);
            for t_only in [false, true] {
                if t_only && !dielectric {
                    continue;
                }
                let f = |b: [f64; 3]| {
                    if t_only && b[2] * a[2] > 0.0 {
                        return 0.0;
                    }
                    l64.eval(a64, v64(b)).g * b[2].abs()
                };
                // Split the bands where the generalized half vector of
                // transmission reaches the horizon (the density jumps there).
                let (alb, err) = sphere_integral(&f, &[-(n_a / n_b) * a[2]], 1e-6);
                assert!(
                    alb <= 1.0 + 2.0 * err + 1e-9,
                    "{it:?} θ {theta} below {below}: albedo {alb} > 1"
                );
                let n = 200_000;
                let (mut s1, mut s2) = (0.0, 0.0);
                let a32 = v32(a);
                for _ in 0..n {
                    let s = l32.sample(a32, rng.uniform(), rng.uniform(), rng.uniform(), t_only);
                    let w = s.weight.g as f64;
                    s1 += w;
                    s2 += w * w;
                }
                let mean = s1 / n as f64;
                let se = ((s2 / n as f64 - mean * mean) / (n - 1) as f64).sqrt();
                let z = (mean - alb) / se.max(1e-12);
                eprintln!("{it:?} θ {theta} below {below} t_only {t_only}: ∫ f cos {alb:.6} ± {err:.1e}, sampler {mean:.6} ± {se:.1e}");
                assert!(
                    (mean - alb).abs() <= 4.5 * se + 2.0 * err + 1e-7,
                    "{it:?} θ {theta} below {below} t_only {t_only}: sampler {mean} ± {se} vs ∫ f cos {alb} ± {err} (z {z:.2})"
                );
            }
        }
    }
}

// ---------------------------------------------------------------------------
// fastmath
// ---------------------------------------------------------------------------

/// Distance in ulps between two f32 values (equal-signed zeros are 0 apart).
fn ulps(a: f32, b: f32) -> u64 {
    fn ord(x: f32) -> i64 {
        let b = x.to_bits() as i32 as i64;
        if b < 0 {
            i32::MIN as i64 - b
        } else {
            b
        }
    }
    (ord(a) - ord(b)).unsigned_abs()
}

/// Asserts `got` is within `max_ulps` of the correctly rounded `want`.
#[track_caller]
fn assert_ulps(what: &str, x: f32, got: f32, want: f64, max_ulps: u64) -> u64 {
    let d = ulps(got, want as f32);
    assert!(
        d <= max_ulps,
        "{what}({x:e} = {:#x}) = {got:e}, correctly rounded {:e}: {d} ulps",
        x.to_bits(),
        want as f32
    );
    d
}

/// All f32 in `[lo, hi]` with bit patterns on a stride (plus both ends).
fn f32_range(lo: f32, hi: f32, stride: u32) -> impl Iterator<Item = f32> {
    assert!(lo >= 0.0 && hi >= lo);
    (lo.to_bits()..=hi.to_bits())
        .step_by(stride as usize)
        .map(f32::from_bits)
        .chain([hi])
}

#[test]
fn fastmath_within_two_ulps() {
    // exp on [-87, 88].
    let mut worst = 0;
    for x in f32_range(0.0, 88.0, 61).chain(f32_range(0.0, 87.0, 61).map(|x| -x)) {
        worst = worst.max(assert_ulps("exp", x, fastmath::exp(x), (x as f64).exp(), 2));
    }
    eprintln!("exp: worst {worst} ulp");
    // ln on the positive normal numbers (and exhaustively on [0.5, 2)).
    let mut worst = 0;
    for x in f32_range(f32::MIN_POSITIVE, f32::MAX, 101).chain(f32_range(0.5, 2.0, 1)) {
        worst = worst.max(assert_ulps("ln", x, fastmath::ln(x), (x as f64).ln(), 2));
    }
    eprintln!("ln: worst {worst} ulp");
    // sin and cos of turns on [0, 1]: the f64 reference reduces exactly first.
    let mut worst = 0;
    for t in f32_range(0.0, 1.0, 37).chain(f32_range(0.24, 0.26, 1)) {
        let (s, c) = fastmath::sin_cos_turns(t);
        let td = t as f64;
        let q = (4.0 * td).round();
        let x = std::f64::consts::TAU * (td - q / 4.0);
        let (xs, xc) = x.sin_cos();
        let (ws, wc) = match (q as i64).rem_euclid(4) {
            0 => (xs, xc),
            1 => (xc, -xs),
            2 => (-xs, -xc),
            _ => (-xc, xs),
        };
        worst = worst.max(assert_ulps("sin_turns", t, s, ws, 2));
        worst = worst.max(assert_ulps("cos_turns", t, c, wc, 2));
    }
    eprintln!("sin_cos_turns: worst {worst} ulp");
    // exp_m1 on [-87, 88]: the Taylor branch near 0 and exp(x) - 1 beyond.
    let mut worst = 0;
    for x in f32_range(0.0, 88.0, 61).chain(f32_range(0.0, 87.0, 61).map(|x| -x)) {
        worst = worst.max(assert_ulps(
            "exp_m1",
            x,
            fastmath::exp_m1(x),
            (x as f64).exp_m1(),
            2,
        ));
    }
    eprintln!("exp_m1: worst {worst} ulp");
}
