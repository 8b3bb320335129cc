//! The phase functions beyond Henyey–Greenstein, as kernels: SGGX
//! microflakes (specular and diffuse flakes, surface flakes and fibres) and
//! mixtures of lobes.
//!
//! * Identities, by f64 quadrature: the specular phase function integrates
//!   to 1; the projected area is `∫ max(0, ω·m) D(m) dm = σ(ω)`; S = I gives
//!   the isotropic `1/4π`; `σ(d) p(d → u) = σ(u) p(−u → −d)` (reciprocity).
//! * `sigma` against `sqrt(ωᵀSω)` from the full matrix.
//! * Chi-square (the harness of `common/chi2.rs`, Šidák-corrected over this
//!   file's fits at 0.01): the specular sampler against the specular value
//!   (which tests the visible-normal sampler against D), and mixtures'
//!   samplers against their values.
//! * Diffuse flakes: the sampler's histogram against uniform directions
//!   weighted by the one-sample estimate of the value (two estimators of
//!   the same density, compared cell by cell with their standard errors: a
//!   chi-square of their difference), so sampler and estimate agree.
//! * Single precision at roughness 0.01 against f64, and every lane of
//!   `F32x8` bit for bit against `f32`.

use crate::common;

use common::chi2::{chi2_sf, sidak, Fit, SphereGrid};
use strata_bsdf::lane::{F32x8, Lane, V3};
use strata_bsdf::phase::sggx::Sggx;
use strata_bsdf::phase::PhaseLanes;
use strata_bsdf::rng::{Stream, WalkRng};
use strata_bsdf::stack::Phase;

const GRID: SphereGrid = SphereGrid {
    n_cos: 40,
    n_phi: 80,
};
const SAMPLES: usize = 1_000_000;
const FITS: usize = SPECULAR.len() + MIXTURES.len();

fn alpha() -> f64 {
    sidak(0.01, FITS)
}

fn unit(v: [f64; 3]) -> [f64; 3] {
    let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    v.map(|x| x / l)
}
fn v64(v: [f64; 3]) -> V3<f64> {
    V3::new(v[0], v[1], v[2])
}
fn v32(v: [f64; 3]) -> V3<f32> {
    V3::new(v[0] as f32, v[1] as f32, v[2] as f32)
}
fn arr(v: V3<f32>) -> [f32; 3] {
    [v.x, v.y, v.z]
}

/// The flakes of a case: surface (true) or fibre, axis, roughness.
fn flakes<L: Lane>(surface: bool, axis: [f64; 3], r: f64) -> Sggx<L> {
    if surface {
        Sggx::surface(axis, r)
    } else {
        Sggx::fiber(axis, r)
    }
}

/// Midpoint quadrature of `f` over the sphere, `n × 2n` cells in (θ, φ)
/// about the axis `about`, weighted by `sin θ` (so that a lobe about it is
/// resolved in angle, to `π / n`).
fn sphere_quad(n: usize, about: [f64; 3], f: impl Fn(V3<f64>) -> f64) -> f64 {
    let fr = strata_bsdf::math::Frame::around(v64(about));
    let h = std::f64::consts::PI / n as f64;
    let mut s = 0.0;
    for i in 0..n {
        let t = (i as f64 + 0.5) * h;
        let (st, c) = t.sin_cos();
        for j in 0..2 * n {
            let p = (j as f64 + 0.5) * h;
            s += st * f(fr.to_world(V3::new(st * p.cos(), st * p.sin(), c)));
        }
    }
    s * h * h
}

/// `sqrt(ωᵀSω)` from S's full matrix.
fn sigma_full(surface: bool, a: [f64; 3], r: f64, w: V3<f64>) -> f64 {
    let w = [w.x, w.y, w.z];
    let r2 = r * r;
    let mut q = 0.0;
    for i in 0..3 {
        for j in 0..3 {
            let id = if i == j { 1.0 } else { 0.0 };
            let s = if surface {
                r2 * id + (1.0 - r2) * a[i] * a[j]
            } else {
                id - (1.0 - r2) * a[i] * a[j]
            };
            q += w[i] * s * w[j];
        }
    }
    q.sqrt()
}

const CASES: [(bool, [f64; 3], f64); 5] = [
    (true, [0.0, 0.0, 1.0], 0.3),
    (true, [0.6, 0.0, 0.8], 0.1),
    (false, [1.0, 0.0, 0.0], 0.3),
    (false, [0.0, 0.6, 0.8], 0.7),
    (true, [0.0, 0.0, 1.0], 1.0),
];

#[test]
fn sigma_is_the_quadratic_form_and_the_projected_area() {
    for (surface, a, r) in CASES {
        let s = flakes::<f64>(surface, a, r);
        for w in [
            [0.0, 0.0, 1.0],
            unit([1.0, 2.0, -0.5]),
            unit([0.3, -0.9, 0.1]),
        ] {
            let w = v64(w);
            let want = sigma_full(surface, a, r, w);
            assert!((s.sigma(w) - want).abs() < 1e-12, "{surface} {a:?} {r}");
            // ∫ max(0, ω·m) D(m) dm = σ(ω), quadrature about the flakes' axis.
            let area = sphere_quad(800, a, |m| w.dot(m).max(0.0) * s.d(m));
            assert!(
                (area - want).abs() < 2e-3 * want,
                "{surface} {a:?} r {r}: ∫ (ω·m)+ D = {area}, σ = {want}"
            );
        }
    }
}

#[test]
fn specular_flakes_are_normalized_reciprocal_and_spheres_isotropic() {
    for (surface, a, r) in CASES {
        let s = flakes::<f64>(surface, a, r);
        for d in [unit([0.2, 0.1, -1.0]), unit([1.0, -0.3, 0.05]), a] {
            let d = v64(d);
            // The lobe is about the mirror image of ωi = −d in the axis
            // (surface flakes) or spread around it: integrate about both.
            let mass = sphere_quad(1000, [-d.x, -d.y, -d.z], |u| s.specular_eval(d, u));
            assert!(
                (mass - 1.0).abs() < 3e-3,
                "{surface} {a:?} r {r}: ∫ p = {mass}"
            );
            for u in [unit([0.5, 0.5, 0.7]), unit([-0.2, 0.9, -0.4])] {
                let u = v64(u);
                let x = s.sigma(d) * s.specular_eval(d, u);
                let y = s.sigma(u) * s.specular_eval(-u, -d);
                assert!((x - y).abs() <= 1e-12 * x.abs().max(1.0), "{x} vs {y}");
                if r == 1.0 {
                    let iso = 1.0 / (4.0 * std::f64::consts::PI);
                    assert!((s.specular_eval(d, u) - iso).abs() < 1e-12);
                }
            }
        }
    }
}

/// Specular fits: (surface, axis, roughness, travel direction).
const SPECULAR: [(bool, [f64; 3], f64, [f64; 3]); 6] = [
    (true, [0.0, 0.0, 1.0], 0.1, [0.5, 0.0, -0.866]),
    (true, [0.6, 0.0, 0.8], 0.3, [0.0, 0.0, -1.0]),
    (true, [1.0, 0.0, 0.0], 0.7, [0.0, 0.995, -0.0998]),
    (true, [0.0, 0.0, 1.0], 1.0, [0.3, -0.5, 0.81]),
    (false, [0.0, 0.6, 0.8], 0.3, [0.7, 0.0, -0.714]),
    (false, [1.0, 0.0, 0.0], 0.1, [0.0, 0.6, -0.8]),
];

#[test]
fn specular_sampler_fits_its_value() {
    for (k, (surface, a, r, d)) in SPECULAR.into_iter().enumerate() {
        let d = unit(d);
        let s32 = flakes::<f32>(surface, a, r);
        let s64 = flakes::<f64>(surface, a, r);
        let sampler = move |u: [f32; 4]| Some(arr(s32.specular_sample(v32(d), u[0], u[1])));
        let pdf = move |w: [f64; 3]| s64.specular_eval(v64(d), v64(w));
        Fit {
            name: format!("SGGX specular surface={surface} axis {a:?} r {r}"),
            grid: GRID,
            samples: SAMPLES,
            seed: 900 + k as u64,
            sampler: &sampler,
            pdf: &pdf,
            cos_breaks: vec![],
        }
        .check(alpha());
    }
}

/// The validated phase of a medium whose `phase = { text }` (lines of
/// `key = value`), on f64 lanes.
fn phase(text: &str) -> PhaseLanes<f64> {
    let toml = format!(
        "[[layers]]\ninterface = {{ kind = \"dielectric\", ior = 1.5 }}\n\
         medium = {{ thickness = 1, sigma_t = 1, phase = {{ {} }} }}\n\
         [[layers]]\ninterface = {{ kind = \"diffuse\", albedo = 0.5 }}\n",
        text.replace('\n', ", ")
    );
    let st = strata_bsdf::LayerStack::from_toml_str(&toml).unwrap();
    let p: Phase = st.medium(0).unwrap().phase.clone();
    PhaseLanes::new(&p, p.kind())
}

/// The same phase on f32 lanes.
fn lanes32<L: Lane>(p: &PhaseLanes<f64>) -> PhaseLanes<L> {
    PhaseLanes {
        kind: p.kind,
        g: L::splat(p.g as f32 as f64),
        p: p.p.map(|x| L::splat(x as f32 as f64)),
    }
}

const MIXTURES: [&str; 2] = [
    "kind = \"mixture\"\ncomponents = [{ weight = 0.8, kind = \"hg\", g = 0.8 }, { weight = 0.2, kind = \"hg\", g = -0.8 }]",
    "kind = \"mixture\"\ncomponents = [{ weight = 0.5, kind = \"hg\", g = 0.3 }, { weight = 0.3, kind = \"isotropic\" }, { weight = 0.2, kind = \"hg\", g = -0.95 }]",
];
const DIFFUSE: [&str; 3] = [
    "kind = \"sggx\"\nflakes = \"surface\"\naxis = [0.6, 0.0, 0.8]\nroughness = 0.2\nscattering = \"diffuse\"",
    "kind = \"sggx\"\nflakes = \"fiber\"\naxis = [1.0, 0.0, 0.0]\nroughness = 0.4\nscattering = \"diffuse\"",
    "kind = \"sggx\"\nflakes = \"surface\"\naxis = [0.0, 0.0, 1.0]\nroughness = 1.0\nscattering = \"diffuse\"",
];

#[test]
fn mixture_samplers_fit_their_values() {
    let d = unit([0.3, -0.5, 0.81]);
    for (k, text) in MIXTURES.iter().enumerate() {
        let p64 = phase(text);
        let p32 = lanes32::<f32>(&p64);
        let sampler = move |u: [f32; 4]| Some(arr(p32.sample(v32(d), u)));
        let pdf = move |w: [f64; 3]| p64.eval(v64(d), v64(w), (0.0, 0.0));
        Fit {
            name: format!("phase {text}"),
            grid: GRID,
            samples: SAMPLES,
            seed: 950 + k as u64,
            sampler: &sampler,
            pdf: &pdf,
            cos_breaks: vec![],
        }
        .check(alpha());
    }
}

/// Diffuse flakes: the sampler's histogram (counts) against uniformly
/// distributed directions weighted by `4π` times the one-sample estimate of
/// the value, cell by cell on a coarse grid, with both standard errors: a
/// chi-square of their difference.
#[test]
fn diffuse_sampler_and_estimate_agree() {
    let grid = SphereGrid {
        n_cos: 10,
        n_phi: 20,
    };
    let n = 400_000usize;
    for (k, text) in DIFFUSE.iter().enumerate() {
        let p = phase(text);
        let d = v64(unit([0.3, -0.5, 0.81]));
        let mut rng = WalkRng::new(77, k as u64, 0, Stream::Walk);
        let mut u4 = || {
            let mut u = [0.0; 4];
            for x in &mut u {
                *x = rng.uniform() as f64;
            }
            u
        };
        let cells = grid.len();
        let (mut c1, mut w1, mut w2) = (vec![0.0; cells], vec![0.0; cells], vec![0.0; cells]);
        for _ in 0..n {
            let v = p.sample(d, u4());
            assert!((v.length() - 1.0).abs() < 1e-9);
            c1[grid.cell([v.x, v.y, v.z])] += 1.0;
            let u = u4();
            let w = strata_bsdf::math::sample_uniform_sphere(u[0], u[1]);
            let x = 4.0 * std::f64::consts::PI * p.eval(d, w, (u[2], u[3]));
            let cell = grid.cell([w.x, w.y, w.z]);
            w1[cell] += x;
            w2[cell] += x * x;
        }
        let nf = n as f64;
        let (mut stat, mut dof) = (0.0, 0);
        for c in 0..cells {
            let pa = c1[c] / nf;
            let va = pa * (1.0 - pa) / nf;
            let pb = w1[c] / nf;
            let vb = (w2[c] / nf - pb * pb) / nf;
            if va + vb > 0.0 {
                stat += (pa - pb).powi(2) / (va + vb);
                dof += 1;
            }
        }
        let pv = chi2_sf(stat, dof as f64);
        assert!(pv > 1e-3, "{text}: chi2 {stat} on {dof} cells, p = {pv}");
        // The estimate integrates to 1 over the sphere.
        let total: f64 = w1.iter().sum::<f64>() / nf;
        let var: f64 = (w2.iter().sum::<f64>() / nf - total * total) / nf;
        assert!(
            (total - 1.0).abs() < 5.0 * var.sqrt(),
            "{text}: ∫ p = {total}"
        );
    }
}

#[test]
fn single_precision_holds_at_roughness_0_01() {
    for surface in [true, false] {
        let a = unit([0.2, 0.1, 1.0]);
        let (s32, s64) = (
            flakes::<f32>(surface, a, 0.01),
            flakes::<f64>(surface, a, 0.01),
        );
        let d = unit([0.4, 0.0, -0.9]);
        let mut rng = WalkRng::new(5, 0, 0, Stream::Walk);
        for _ in 0..2000 {
            // Directions the sampler gives (near the peak), in f32 and f64.
            let (u1, u2) = (rng.uniform(), rng.uniform());
            let u = s32.specular_sample(v32(d), u1, u2);
            let u64_ = V3::new(u.x as f64, u.y as f64, u.z as f64);
            let (x, y) = (
                s32.specular_eval(v32(d), u) as f64,
                s64.specular_eval(v64(d), u64_),
            );
            assert!(x.is_finite() && y.is_finite());
            assert!(
                (x - y).abs() <= 2e-2 * y + 1e-6,
                "{surface}: f32 {x} vs f64 {y}"
            );
            let w = v32(d);
            let sx = s32.sigma(w) as f64;
            let sy = s64.sigma(v64(d));
            assert!((sx - sy).abs() <= 1e-6 * sy, "σ {sx} vs {sy}");
        }
    }
}

#[test]
fn lanes_are_the_scalar_kernels_bit_for_bit() {
    let texts = [
        "kind = \"hg\"\ng = 0.4",
        MIXTURES[0],
        MIXTURES[1],
        "kind = \"sggx\"\nflakes = \"surface\"\naxis = [0.6, 0.0, 0.8]\nroughness = 0.05",
        "kind = \"sggx\"\nflakes = \"fiber\"\naxis = [0.0, 1.0, 0.0]\nroughness = 0.3",
        DIFFUSE[0],
    ];
    let mut rng = WalkRng::new(6, 0, 0, Stream::Walk);
    let dirn = |rng: &mut WalkRng| {
        let v =
            strata_bsdf::math::sample_uniform_sphere(rng.uniform() as f64, rng.uniform() as f64);
        [v.x, v.y, v.z]
    };
    for text in texts {
        let p64 = phase(text);
        let (p1, p8) = (lanes32::<f32>(&p64), lanes32::<F32x8>(&p64));
        let ds: Vec<[f64; 3]> = (0..8).map(|_| dirn(&mut rng)).collect();
        let us: Vec<[f64; 3]> = (0..8).map(|_| dirn(&mut rng)).collect();
        let uu: Vec<[f32; 4]> = (0..8)
            .map(|_| [rng.uniform(), rng.uniform(), rng.uniform(), rng.uniform()])
            .collect();
        let lane = |f: &dyn Fn(usize) -> f64| F32x8::from_fn(f);
        let d8 = V3::new(
            lane(&|j| ds[j][0]),
            lane(&|j| ds[j][1]),
            lane(&|j| ds[j][2]),
        );
        let u8_ = V3::new(
            lane(&|j| us[j][0]),
            lane(&|j| us[j][1]),
            lane(&|j| us[j][2]),
        );
        let r8 = std::array::from_fn(|k| lane(&|j| uu[j][k] as f64));
        let e8 = (r8[0], r8[1]);
        let (f8, s8, g8) = (p8.eval(d8, u8_, e8), p8.sample(d8, r8), p8.sigma_scale(d8));
        for j in 0..8 {
            let (d, u) = (v32(ds[j]), v32(us[j]));
            let e = (uu[j][0], uu[j][1]);
            let s = p1.sample(d, uu[j]);
            let bits = |x: f32| x.to_bits();
            let l = |x: F32x8| (x.lane(j) as f32).to_bits();
            assert_eq!(l(f8), bits(p1.eval(d, u, e)), "{text}: eval lane {j}");
            assert_eq!(l(g8), bits(p1.sigma_scale(d)), "{text}: sigma lane {j}");
            assert_eq!(l(s8.x), bits(s.x), "{text}: sample lane {j}");
            assert_eq!(l(s8.y), bits(s.y), "{text}: sample lane {j}");
            assert_eq!(l(s8.z), bits(s.z), "{text}: sample lane {j}");
            assert!(s.x.is_finite() && s.z.is_finite());
        }
    }
}

#[test]
fn no_nan_at_the_axis_and_across_it() {
    for surface in [true, false] {
        for r in [1e-4, 0.01, 1.0] {
            let a = unit([0.0, 0.6, 0.8]);
            let s = flakes::<f32>(surface, a, r);
            let across = unit([1.0, 0.0, 0.0]);
            for d in [a, a.map(|x| -x), across, [0.0, 0.0, 1.0]] {
                let d = v32(d);
                for u in [d, -d, v32(a), v32(across)] {
                    for (u1, u2) in [(0.0, 0.0), (0.5, 0.5), (0.9999999, 0.25)] {
                        let v = s.specular_sample(d, u1, u2);
                        let w = s.diffuse_sample(d, [u1, u2, u1, u2]);
                        for x in [
                            s.sigma(d),
                            s.d(u),
                            s.specular_eval(d, u),
                            s.diffuse_estimate(d, u, u1, u2),
                            v.x,
                            v.y,
                            v.z,
                            w.x,
                            w.z,
                        ] {
                            assert!(x.is_finite(), "{surface} r {r} d {d:?} u {u:?}: {x}");
                        }
                        assert!((v.length() - 1.0).abs() < 1e-5, "{v:?}");
                    }
                }
            }
        }
    }
}
