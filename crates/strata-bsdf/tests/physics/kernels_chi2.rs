//! Chi-square goodness of fit of every analytic direction sampler against its
//! own density (the harness is in `common/chi2.rs`).
//!
//! Samples are drawn with the f32 kernels from a fixed-seed `WalkRng`; the
//! density is the same kernel's `pdf` on the f64 lane, integrated over each
//! cell of a 40 × 80 equal-area grid of the sphere. Each fit also checks that
//! the density integrates to the fraction of samples the sampler reports valid
//! (within 4 binomial standard errors). The significance is 0.01 for the whole
//! file, Šidák-corrected over the `FITS` fits below.

use crate::common;

use common::chi2::{chi2_sf, gamma_p, ln_gamma, sidak, Fit, SphereGrid};
use common::dir;
use strata_bsdf::interface::InterfaceLanes;
use strata_bsdf::lane::{Lane, LaneMask, Rgb, V3};
use strata_bsdf::math::{sample_cosine_hemisphere, sample_uniform_sphere};
use strata_bsdf::microfacet::Microfacet;
use strata_bsdf::phase::hg::{hg_eval, hg_sample};

const GRID: SphereGrid = SphereGrid {
    n_cos: 40,
    n_phi: 80,
};
const SAMPLES: usize = 1_000_000;

/// Number of chi-square fits in this file (for the Šidák correction).
const FITS: usize = MICROFACET.len()
    + DIELECTRIC.len()
    + CONDUCTOR.len()
    + HG_G.len()
    + 3 /* Lambertian, cosine hemisphere, uniform sphere */;

fn alpha() -> f64 {
    sidak(0.01, FITS)
}

fn v32(d: [f64; 3]) -> V3<f32> {
    V3::new(d[0] as f32, d[1] as f32, d[2] as f32)
}
fn v64(d: V3<f32>) -> V3<f64> {
    V3::new(d.x as f64, d.y as f64, d.z as f64)
}
fn arr(d: V3<f32>) -> [f32; 3] {
    [d.x, d.y, d.z]
}
fn from_arr(d: [f64; 3]) -> V3<f64> {
    V3::new(d[0], d[1], d[2])
}

/// A direction at polar angle `theta` (degrees) or with `z = cos` when
/// `theta` is given as a cosine, mirrored below the surface when `below`.
#[derive(Clone, Copy, Debug)]
enum Inc {
    Theta(f64, f64),
    Cos(f64, f64),
}
impl Inc {
    fn dir(self, below: bool) -> [f64; 3] {
        let mut d = match self {
            Inc::Theta(t, p) => dir(t, p),
            Inc::Cos(c, p) => dir(c.acos().to_degrees(), p),
        };
        if below {
            d[2] = -d[2];
        }
        d
    }
}

fn microfacet<L: Lane>(ax: f64, ay: f64, beckmann: bool) -> Microfacet<L> {
    Microfacet {
        alpha_x: L::splat(ax),
        alpha_y: L::splat(ay),
        beckmann: L::Mask::splat(beckmann),
        separable: L::Mask::splat(false),
    }
}

fn base<L: Lane>(mf: Microfacet<L>) -> InterfaceLanes<L> {
    let f = L::Mask::splat(false);
    InterfaceLanes {
        n_above: L::one(),
        n_below: L::one(),
        mf,
        smooth: f,
        dielectric: f,
        conductor: f,
        diffuse: f,
        eta: Rgb::splat(L::one()),
        k: Rgb::zero(),
        albedo: Rgb::zero(),
        normal: V3::z_axis(),
        tilted: false,
        adjoint: false,
        run_all: false,
    }
}

/// A rough dielectric interface between IORs `n_above` and `n_below`.
fn dielectric<L: Lane>(n_above: f64, n_below: f64, mf: Microfacet<L>) -> InterfaceLanes<L> {
    InterfaceLanes {
        n_above: L::splat(n_above),
        n_below: L::splat(n_below),
        dielectric: L::Mask::splat(true),
        ..base(mf)
    }
}

/// A rough conductor (copper-like IOR).
fn conductor<L: Lane>(mf: Microfacet<L>) -> InterfaceLanes<L> {
    InterfaceLanes {
        conductor: L::Mask::splat(true),
        eta: Rgb::from_array([0.27, 0.68, 1.3]),
        k: Rgb::from_array([3.6, 2.6, 2.3]),
        ..base(mf)
    }
}

// ---------------------------------------------------------------------------
// The harness's own special functions
// ---------------------------------------------------------------------------

#[test]
fn chi2_survival_matches_known_values() {
    // Exact forms: dof 2 is exponential, dof 4 is e^{-x/2} (1 + x/2).
    for x in [0.01, 0.5, 1.0, 3.0, 10.0, 40.0, 120.0] {
        let e2 = (-x / 2.0f64).exp();
        let e4 = e2 * (1.0 + x / 2.0);
        assert!(
            (chi2_sf(x, 2.0) - e2).abs() <= 1e-13 * e2.max(1e-300),
            "x {x}"
        );
        assert!(
            (chi2_sf(x, 4.0) - e4).abs() <= 1e-13 * e4.max(1e-300),
            "x {x}"
        );
    }
    // Table quantiles (upper tail probability, dof, quantile to 6-7 digits).
    for (p, dof, q) in [
        (0.05, 1.0, 3.841_459),
        (0.01, 1.0, 6.634_897),
        (0.95, 5.0, 1.145_476),
        (0.05, 10.0, 18.307_04),
        (0.01, 100.0, 135.806_7),
        (0.05, 1000.0, 1074.679),
        (0.5, 3.0, 2.365_974),
    ] {
        let got = chi2_sf(q, dof);
        assert!(
            (got - p).abs() < 2e-6 * (1.0 + dof / 100.0),
            "chi2 sf({q}, {dof}) = {got}, expected {p}"
        );
    }
    // Γ at integers and halves.
    assert!((ln_gamma(5.0) - 24f64.ln()).abs() < 1e-13);
    assert!((ln_gamma(0.5) - std::f64::consts::PI.sqrt().ln()).abs() < 1e-13);
    // Γ(n + 1/2) = (2n)! √π / (4^n n!), from sums of logarithms.
    let ln_fact = |n: u32| (1..=n).map(|k| (k as f64).ln()).sum::<f64>();
    for n in [1u32, 7, 100] {
        let exact =
            ln_fact(2 * n) + 0.5 * std::f64::consts::PI.ln() - n as f64 * 4f64.ln() - ln_fact(n);
        let got = ln_gamma(n as f64 + 0.5);
        assert!(
            (got - exact).abs() < 1e-12 * exact.abs().max(1.0),
            "lnΓ({n}.5)"
        );
        let got = ln_gamma(n as f64 + 1.0);
        assert!(
            (got - ln_fact(n)).abs() < 1e-12 * ln_fact(n).max(1.0),
            "lnΓ({n}+1)"
        );
    }
    // P(1, x) = 1 - e^{-x}; continuity across the series/continued-fraction switch.
    for x in [0.3, 1.99, 2.0, 2.01, 7.0] {
        assert!((gamma_p(1.0, x) - (1.0 - (-x).exp())).abs() < 1e-14);
    }
    assert!((sidak(0.01, 1) - 0.01).abs() < 1e-15);
    assert!(sidak(0.01, 40) < 0.01 / 40.0 * 1.01 && sidak(0.01, 40) > 0.01 / 40.0);
}

// ---------------------------------------------------------------------------
// Microfacet normal sampling
// ---------------------------------------------------------------------------

/// (alpha_x, alpha_y, Beckmann, incidence, from below)
const MICROFACET: [(f64, f64, bool, Inc, bool); 10] = [
    (0.5, 0.5, false, Inc::Theta(0.0, 0.0), false),
    (0.5, 0.5, false, Inc::Theta(45.0, 10.0), false),
    (0.3, 0.3, false, Inc::Theta(80.0, -50.0), false),
    (0.5, 0.5, false, Inc::Cos(0.02, 0.0), false),
    (0.2, 0.6, false, Inc::Theta(60.0, 30.0), false),
    (0.6, 0.15, false, Inc::Cos(0.02, 120.0), false),
    (1.0, 1.0, false, Inc::Theta(70.0, 200.0), true),
    (0.1, 0.1, false, Inc::Theta(30.0, 0.0), false),
    (0.3, 0.3, true, Inc::Theta(40.0, 0.0), false),
    (0.2, 0.5, true, Inc::Theta(70.0, 20.0), false),
];

#[test]
fn microfacet_normal_sampling() {
    for (k, &(ax, ay, beck, inc, below)) in MICROFACET.iter().enumerate() {
        let m32 = microfacet::<f32>(ax, ay, beck);
        let m64 = microfacet::<f64>(ax, ay, beck);
        let w32 = v32(inc.dir(below));
        let w64 = v64(w32);
        let sampler = move |u: [f32; 4]| Some(arr(m32.sample(w32, u[0], u[1])));
        let pdf = move |m: [f64; 3]| m64.pdf(w64, from_arr(m));
        let r = Fit {
            name: format!(
                "{} ({ax}, {ay}) from {inc:?} below={below}",
                if beck { "Beckmann" } else { "GGX" }
            ),
            grid: GRID,
            samples: SAMPLES,
            seed: 100 + k as u64,
            sampler: &sampler,
            pdf: &pdf,
            cos_breaks: vec![],
        }
        .check(alpha());
        eprintln!("microfacet {k}: {r:?}");
    }
}

// ---------------------------------------------------------------------------
// Rough dielectric: reflection and transmission together
// ---------------------------------------------------------------------------

/// (n_above, n_below, alpha_x, alpha_y, Beckmann, incidence, from below, transmit_only)
#[allow(clippy::type_complexity)]
const DIELECTRIC: [(f64, f64, f64, f64, bool, Inc, bool, bool); 17] = [
    (
        1.0,
        1.5,
        0.3,
        0.3,
        false,
        Inc::Theta(0.0, 0.0),
        false,
        false,
    ),
    (
        1.0,
        1.5,
        0.3,
        0.3,
        false,
        Inc::Theta(60.0, 15.0),
        false,
        false,
    ),
    (
        1.0,
        1.5,
        0.5,
        0.5,
        false,
        Inc::Cos(0.02, -90.0),
        false,
        false,
    ),
    // From inside: the critical angle of 1.5 is 41.81°.
    (
        1.0,
        1.5,
        0.3,
        0.3,
        false,
        Inc::Theta(35.0, 0.0),
        true,
        false,
    ),
    (
        1.0,
        1.5,
        0.3,
        0.3,
        false,
        Inc::Theta(41.0, 70.0),
        true,
        false,
    ),
    (
        1.0,
        1.5,
        0.3,
        0.3,
        false,
        Inc::Theta(43.0, 0.0),
        true,
        false,
    ),
    (1.0, 1.5, 0.3, 0.3, false, Inc::Cos(0.02, 30.0), true, false),
    // Water (critical angle 48.75°).
    (
        1.0,
        1.33,
        0.4,
        0.4,
        false,
        Inc::Theta(70.0, 0.0),
        false,
        false,
    ),
    (
        1.0,
        1.33,
        0.2,
        0.2,
        false,
        Inc::Theta(49.0, -20.0),
        true,
        false,
    ),
    // Anisotropic, both sides.
    (
        1.0,
        1.5,
        0.1,
        0.4,
        false,
        Inc::Theta(50.0, 45.0),
        false,
        false,
    ),
    (
        1.0,
        1.5,
        0.4,
        0.15,
        false,
        Inc::Theta(40.0, 100.0),
        true,
        false,
    ),
    // Beckmann.
    (
        1.0,
        1.5,
        0.3,
        0.3,
        true,
        Inc::Theta(45.0, 0.0),
        false,
        false,
    ),
    (1.0, 1.5, 0.3, 0.3, true, Inc::Theta(43.0, 0.0), true, false),
    // The dense side above (an interface seen from a coating towards air).
    (
        1.5,
        1.0,
        0.3,
        0.3,
        false,
        Inc::Theta(43.0, 10.0),
        false,
        false,
    ),
    // Transmission alone.
    (
        1.0,
        1.5,
        0.3,
        0.3,
        false,
        Inc::Theta(45.0, 0.0),
        false,
        true,
    ),
    (1.0, 1.5, 0.3, 0.3, false, Inc::Theta(43.0, 0.0), true, true),
    (1.0, 1.33, 0.5, 0.5, false, Inc::Cos(0.02, 60.0), true, true),
];

#[test]
fn rough_dielectric_reflection_and_transmission() {
    for (k, &(na, nb, ax, ay, beck, inc, below, t_only)) in DIELECTRIC.iter().enumerate() {
        let i32 = dielectric::<f32>(na, nb, microfacet(ax, ay, beck));
        let i64 = dielectric::<f64>(na, nb, microfacet(ax, ay, beck));
        let a32 = v32(inc.dir(below));
        let a64 = v64(a32);
        let sampler = move |u: [f32; 4]| {
            let s = i32.sample(a32, u[0], u[1], u[2], t_only);
            s.valid.then(|| arr(s.b))
        };
        let pdf = move |b: [f64; 3]| i64.pdf(a64, from_arr(b), t_only);
        // The transmitted density jumps where the generalized half vector
        // -(n_a a + n_b b) reaches the horizon: at b.z = -(n_a / n_b) a.z.
        let (n_a, n_b) = if below { (nb, na) } else { (na, nb) };
        let r = Fit {
            name: format!(
                "dielectric {na}/{nb} ({ax}, {ay}) beckmann={beck} from {inc:?} below={below} transmit_only={t_only}"
            ),
            grid: GRID,
            samples: SAMPLES,
            seed: 200 + k as u64,
            sampler: &sampler,
            pdf: &pdf,
            cos_breaks: vec![-(n_a / n_b) * a64.z],
        }
        .check(alpha());
        eprintln!("dielectric {k}: {r:?}");
    }
}

// ---------------------------------------------------------------------------
// Rough conductor, Lambertian, warps
// ---------------------------------------------------------------------------

/// (alpha_x, alpha_y, Beckmann, incidence)
const CONDUCTOR: [(f64, f64, bool, Inc); 4] = [
    (0.3, 0.3, false, Inc::Theta(30.0, 0.0)),
    (0.1, 0.4, false, Inc::Theta(75.0, 60.0)),
    (0.5, 0.5, false, Inc::Cos(0.02, 10.0)),
    (0.3, 0.3, true, Inc::Theta(60.0, -30.0)),
];

#[test]
fn rough_conductor() {
    for (k, &(ax, ay, beck, inc)) in CONDUCTOR.iter().enumerate() {
        let i32 = conductor::<f32>(microfacet(ax, ay, beck));
        let i64 = conductor::<f64>(microfacet(ax, ay, beck));
        let a32 = v32(inc.dir(false));
        let a64 = v64(a32);
        let sampler = move |u: [f32; 4]| {
            let s = i32.sample(a32, u[0], u[1], u[2], false);
            s.valid.then(|| arr(s.b))
        };
        let pdf = move |b: [f64; 3]| i64.pdf(a64, from_arr(b), false);
        let r = Fit {
            name: format!("conductor ({ax}, {ay}) beckmann={beck} from {inc:?}"),
            grid: GRID,
            samples: SAMPLES,
            seed: 300 + k as u64,
            sampler: &sampler,
            pdf: &pdf,
            cos_breaks: vec![],
        }
        .check(alpha());
        eprintln!("conductor {k}: {r:?}");
    }
}

#[test]
fn lambertian_and_warps() {
    let diffuse = |l: Microfacet<f32>| InterfaceLanes {
        diffuse: true,
        albedo: Rgb::new(0.8, 0.5, 0.2),
        ..base(l)
    };
    let d32 = diffuse(microfacet(1.0, 1.0, false));
    let d64 = InterfaceLanes::<f64> {
        diffuse: true,
        albedo: Rgb::new(0.8, 0.5, 0.2),
        ..base(microfacet(1.0, 1.0, false))
    };
    let a32 = v32(dir(30.0, 40.0));
    let a64 = v64(a32);
    let sampler = move |u: [f32; 4]| {
        let s = d32.sample(a32, u[0], u[1], u[2], false);
        s.valid.then(|| arr(s.b))
    };
    let pdf = move |b: [f64; 3]| d64.pdf(a64, from_arr(b), false);
    let cos_hemi = |u: [f32; 4]| Some(arr(sample_cosine_hemisphere(u[0], u[1])));
    let cos_pdf = |b: [f64; 3]| (b[2] / std::f64::consts::PI).max(0.0);
    let sphere = |u: [f32; 4]| Some(arr(sample_uniform_sphere(u[0], u[1])));
    let sphere_pdf = |_: [f64; 3]| 0.25 / std::f64::consts::PI;
    type Case<'a> = (
        &'a str,
        &'a dyn Fn([f32; 4]) -> Option<[f32; 3]>,
        &'a dyn Fn([f64; 3]) -> f64,
    );
    let cases: [Case; 3] = [
        ("Lambertian interface", &sampler, &pdf),
        ("cosine hemisphere", &cos_hemi, &cos_pdf),
        ("uniform sphere", &sphere, &sphere_pdf),
    ];
    for (k, (name, s, p)) in cases.into_iter().enumerate() {
        let r = Fit {
            name: name.into(),
            grid: GRID,
            samples: SAMPLES,
            seed: 400 + k as u64,
            sampler: s,
            pdf: p,
            cos_breaks: vec![],
        }
        .check(alpha());
        eprintln!("{name}: {r:?}");
    }
}

// ---------------------------------------------------------------------------
// Henyey–Greenstein
// ---------------------------------------------------------------------------

const HG_G: [f64; 4] = [-0.9, 0.0, 0.5, 0.9];

#[test]
fn henyey_greenstein() {
    // A travel direction off the axes, so the frame around it is exercised.
    let d = {
        let v = [0.3f64, -0.5, 0.81];
        let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        v32([v[0] / l, v[1] / l, v[2] / l])
    };
    let d64 = v64(d);
    for (k, &g) in HG_G.iter().enumerate() {
        let sampler = move |u: [f32; 4]| Some(arr(hg_sample(g as f32, d, u[0], u[1])));
        let pdf = move |w: [f64; 3]| hg_eval(g, d64.dot(from_arr(w)));
        let r = Fit {
            name: format!("HG g = {g}"),
            grid: GRID,
            samples: SAMPLES,
            seed: 500 + k as u64,
            sampler: &sampler,
            pdf: &pdf,
            cos_breaks: vec![],
        }
        .check(alpha());
        eprintln!("HG {g}: {r:?}");
    }
}

// ---------------------------------------------------------------------------
// Tilted shading normals
// ---------------------------------------------------------------------------

#[test]
fn tilted_interfaces() {
    // The sampler's histogram against the pdf of the tilted interface: the
    // shading frame's density where both directions lie on the slab's side
    // of the shading normal, 0 elsewhere (method.md §9).
    let tilt = |l: &mut InterfaceLanes<f32>, m: &mut InterfaceLanes<f64>| {
        let n = [0.35f32, -0.2, 0.915];
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        let n = n.map(|x| x / len);
        l.normal = V3::new(n[0], n[1], n[2]);
        m.normal = V3::new(n[0] as f64, n[1] as f64, n[2] as f64);
        l.tilted = true;
        m.tilted = true;
    };
    let mut cases = Vec::new();
    for (k, inc) in [Inc::Theta(30.0, 0.0), Inc::Theta(70.0, -10.0)]
        .into_iter()
        .enumerate()
    {
        let mut d32 = dielectric::<f32>(1.0, 1.5, microfacet(0.3, 0.3, false));
        let mut d64 = dielectric::<f64>(1.0, 1.5, microfacet(0.3, 0.3, false));
        tilt(&mut d32, &mut d64);
        let mut c32 = conductor::<f32>(microfacet(0.2, 0.4, false));
        let mut c64 = conductor::<f64>(microfacet(0.2, 0.4, false));
        tilt(&mut c32, &mut c64);
        cases.push((
            format!("tilted dielectric from {inc:?}"),
            d32,
            d64,
            inc,
            400 + k as u64,
        ));
        cases.push((
            format!("tilted conductor from {inc:?}"),
            c32,
            c64,
            inc,
            410 + k as u64,
        ));
    }
    for (name, i32, i64, inc, seed) in cases {
        let a32 = v32(inc.dir(false));
        let a64 = v64(a32);
        let sampler = move |u: [f32; 4]| {
            let s = i32.sample(a32, u[0], u[1], u[2], false);
            s.valid.then(|| arr(s.b))
        };
        let pdf = move |b: [f64; 3]| i64.pdf(a64, from_arr(b), false);
        let r = Fit {
            name: name.clone(),
            grid: GRID,
            samples: SAMPLES,
            seed,
            sampler: &sampler,
            pdf: &pdf,
            cos_breaks: vec![],
        }
        .check(alpha());
        eprintln!("{name}: {r:?}");
    }
}
