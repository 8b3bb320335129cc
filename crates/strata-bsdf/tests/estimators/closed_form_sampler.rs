//! `Auto`'s walk-free samplers for a coat over a clear or absorbing layer
//! over a Lambertian base, with an exact pdf: under a smooth coat
//! (`estimator::closed_form`) the coat's mirror reflection or a
//! cosine-distributed direction; under a rough one (`estimator::rough_coat`)
//! the coat's reflection lobe or a cosine-distributed direction, weighted by
//! one sample of the factorization.
//!
//! * **Weights**: the weighted histogram of its non-specular directions
//!   against the integral of `eval`'s `f · cos θo` over each cell (the closed
//!   form, which `tests/physics/layered_oracles.rs` checks against the walks and the
//!   test suite's own formula; the factorization, which
//!   `tests/physics/rough_coat.rs` checks against the walks), and its mean weight
//!   against the directional albedo of the *walks* (an independent
//!   estimator: neither in it).
//! * **Density**: a chi-square test of its histogram against its pdf, the
//!   mirror reflection's share (smooth) or the share of no direction (rough:
//!   reflections the microfacet sends below the horizon) against what the
//!   pdf's integral leaves, and (smooth) that integral against `1 − F(θi)`.
//! * **Consistency**: `pdf`, `Sample::pdf` and `pdf_unbiased` (standard
//!   error 0) are the same number; `Unidirectional` keeps the walks.

use crate::common;
use crate::common::batches::Batches;
use common::chi2::chi2_sf;
use std::f64::consts::{PI, TAU};
use strata_bsdf::{Estimator, LayerStack, LayeredBsdf};

const STACKS: [(&str, &str); 6] = [
    ("smooth coat / white Lambertian", common::SMOOTH_COAT_WHITE),
    (
        "2.2 coat, coloured absorber / Lambertian",
        common::DENSE_COAT_ABSORBER,
    ),
    (
        "coat less dense than the exterior / Lambertian",
        r#"
        exterior_ior = 1.6
        [[layers]]
        interface = { kind = "dielectric", ior = 1.385640646 }
        medium = { thickness = 0.5, sigma_t = 0.4, albedo = 0.0 }
        [[layers]]
        interface = { kind = "diffuse", albedo = [0.9, 0.5, 0.2] }
        "#,
    ),
    (
        "two-sided coat / Lambertian, lit from below",
        r#"
        two_sided = true
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5 }
        [[layers]]
        interface = { kind = "diffuse", albedo = 0.6 }
        "#,
    ),
    (
        "rough coat (α 0.3), coloured absorber / Lambertian",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5, roughness = 0.3 }
        medium = { thickness = 0.5, sigma_t = [0.2, 0.6, 1.2], albedo = 0.0 }
        [[layers]]
        interface = { kind = "diffuse", albedo = [0.9, 0.6, 0.3] }
        "#,
    ),
    (
        "rough two-sided Beckmann coat (α 0.2, separable) / Lambertian, lit from below",
        r#"
        two_sided = true
        [[layers]]
        interface = { kind = "dielectric", ior = 1.7, roughness = 0.2, distribution = "beckmann", shadowing = "separable" }
        [[layers]]
        interface = { kind = "diffuse", albedo = 0.7 }
        "#,
    ),
];

fn rough(name: &str) -> bool {
    name.starts_with("rough")
}

fn bsdf(toml: &str) -> LayeredBsdf {
    LayeredBsdf::new(LayerStack::from_toml_str(toml).unwrap()).seed(11)
}

/// Light from 35° (from below for the two-sided stack). The coat less dense
/// than the exterior (η = √3/2) lets light out in the cone cos θ > 1/2,
/// whose edge is a cell boundary (the pdf is discontinuous there).
fn wi_of(name: &str) -> glam::Vec3 {
    let t = 35f32.to_radians();
    let z = if name.contains("below") { -1.0 } else { 1.0 };
    glam::Vec3::new(t.sin(), 0.0, z * t.cos())
}

/// Cells of the hemisphere light leaves by: `N_MU` bands uniform in |cos θ|
/// by `N_PHI` sectors, each of solid angle `2π / (N_MU N_PHI)`.
const N_MU: usize = 6;
const N_PHI: usize = 8;
const CELLS: usize = N_MU * N_PHI;
const D_OMEGA: f64 = TAU / CELLS as f64;

fn cell_of(w: glam::Vec3) -> usize {
    let mu = (w.z.abs() as f64).min(1.0);
    let phi = (w.y as f64).atan2(w.x as f64) + PI;
    let i = ((mu * N_MU as f64) as usize).min(N_MU - 1);
    let j = ((phi / TAU * N_PHI as f64) as usize).min(N_PHI - 1);
    i * N_PHI + j
}

/// The point of cell `c` at fractions `(s, t)`, on the side of `sign`.
fn cell_point(c: usize, s: f64, t: f64, sign: f32) -> glam::Vec3 {
    let (i, j) = (c / N_PHI, c % N_PHI);
    let mu = (i as f64 + s) / N_MU as f64;
    let phi = (j as f64 + t) / N_PHI as f64 * TAU - PI;
    let r = (1.0 - mu * mu).max(0.0).sqrt();
    glam::Vec3::new(
        (r * phi.cos()) as f32,
        (r * phi.sin()) as f32,
        sign * mu as f32,
    )
}

/// The mean of `g` over cell `c` on a 16 × 16 midpoint grid (the integrands
/// are smooth: the grid's error is far below the tests' noise).
fn cell_mean(c: usize, sign: f32, g: &dyn Fn(glam::Vec3) -> f64) -> f64 {
    let k = 16;
    let mut sum = 0.0;
    for a in 0..k {
        for b in 0..k {
            let (s, t) = ((a as f64 + 0.5) / k as f64, (b as f64 + 0.5) / k as f64);
            sum += g(cell_point(c, s, t, sign));
        }
    }
    sum / (k * k) as f64
}

struct Drawn {
    /// Per cell: the count, and the sums of weight and weight² per channel.
    count: Vec<u64>,
    w: Vec<[f64; 3]>,
    w2: Vec<[f64; 3]>,
    specular: u64,
    /// Sum and sum of squares of the total weight per channel.
    total: [f64; 3],
    total2: [f64; 3],
}

fn draw(b: &LayeredBsdf, wi: glam::Vec3, n: usize) -> Drawn {
    let wis = vec![wi; n];
    let keys = vec![5u64; n];
    let idx: Vec<u64> = (0..n as u64).collect();
    let mut d = Drawn {
        count: vec![0; CELLS],
        w: vec![[0.0; 3]; CELLS],
        w2: vec![[0.0; 3]; CELLS],
        specular: 0,
        total: [0.0; 3],
        total2: [0.0; 3],
    };
    for s in b
        .sample_batch_keyed(&wis, &keys, &idx)
        .unwrap()
        .iter()
        .flatten()
    {
        assert!(s.reflection && s.wo.z * wi.z > 0.0, "{s:?}");
        assert!((s.wo.length() - 1.0).abs() < 1e-5, "{s:?}");
        for c in 0..3 {
            // Bounded: below 2 under a smooth coat; under a rough one by
            // F G/G1 over the lobe's share plus π f over the cosine's.
            let w = s.weight[c] as f64;
            assert!(w.is_finite() && (0.0..20.0).contains(&w), "{s:?}");
            d.total[c] += w;
            d.total2[c] += w * w;
        }
        if s.specular {
            let mirror = glam::Vec3::new(-wi.x, -wi.y, wi.z);
            assert!((s.wo - mirror).length() < 1e-5, "{s:?}");
            d.specular += 1;
            continue;
        }
        let k = cell_of(s.wo);
        d.count[k] += 1;
        for c in 0..3 {
            let w = s.weight[c] as f64;
            d.w[k][c] += w;
            d.w2[k][c] += w * w;
        }
    }
    d
}

/// The weighted histogram against `∫ f cos` per cell, and the total weight
/// against the walks' albedo.
#[test]
fn weights_are_f_cos_over_the_density() {
    let n = 400_000;
    for (name, toml) in STACKS {
        let b = bsdf(toml);
        assert!(b.sample_is_exact(), "{name}");
        let wi = wi_of(name);
        let d = draw(&b, wi, n);
        let sign = wi.z.signum();
        for k in 0..CELLS {
            let f = |w: glam::Vec3| b.eval(wi, w).unwrap().value;
            let exact: Vec<f64> = (0..3)
                .map(|c| D_OMEGA * cell_mean(k, sign, &|w| f(w)[c] * w.z.abs() as f64))
                .collect();
            for (c, exact) in exact.iter().enumerate() {
                let mean = d.w[k][c] / n as f64;
                let var = (d.w2[k][c] / n as f64 - mean * mean).max(0.0) / n as f64;
                let z = (mean - exact) / var.sqrt().max(1e-12);
                assert!(
                    z.abs() < 4.5,
                    "{name} cell {k} channel {c}: {mean:.6} vs ∫ f cos {exact:.6} (z {z:.1})"
                );
            }
        }
        // The albedo of independent walks (the unidirectional estimator has no
        // closed form in it).
        let walks = b.clone().estimator(Estimator::Unidirectional);
        let a = walks.albedo(wi, 400_000).unwrap();
        for c in 0..3 {
            let mean = d.total[c] / n as f64;
            let var = (d.total2[c] / n as f64 - mean * mean).max(0.0) / n as f64;
            let r = &a.reflected;
            let se = (var + r.stderr[c] * r.stderr[c]).sqrt();
            assert!(
                (mean - r.value[c]).abs() < 4.0 * se,
                "{name} channel {c}: mean weight {mean:.5} vs the walks' albedo {:.5} ± {:.5}",
                r.value[c],
                r.stderr[c]
            );
        }
    }
}

/// The histogram against the pdf (chi-square), the mirror's share against
/// `F(θi)`, the pdf's integral against `1 − F(θi)`.
#[test]
fn the_pdf_is_the_density_of_the_samples() {
    let n = 400_000;
    let alpha = common::chi2::sidak(1e-3, STACKS.len());
    for (name, toml) in STACKS {
        let b = bsdf(toml);
        let wi = wi_of(name);
        let d = draw(&b, wi, n);
        let sign = wi.z.signum();
        let pdf = |w: glam::Vec3| b.pdf(wi, w).unwrap() as f64;
        let shares: Vec<f64> = (0..CELLS)
            .map(|k| D_OMEGA * cell_mean(k, sign, &pdf))
            .collect();
        let diffuse: f64 = shares.iter().sum();
        let (mut stat, mut dof) = (0.0, 0);
        for (k, &p) in shares.iter().enumerate() {
            let (o, e) = (d.count[k] as f64, p * n as f64);
            if e == 0.0 {
                assert_eq!(d.count[k], 0, "{name} cell {k}: samples where the pdf is 0");
                continue;
            }
            stat += (o - e) * (o - e) / e;
            dof += 1;
        }
        let pval = chi2_sf(stat, dof as f64);
        assert!(
            pval > alpha,
            "{name}: chi-square {stat:.1} on {dof} cells, p {pval:.2e}"
        );
        // The mirror reflection takes the rest: the coat's Fresnel
        // reflectance, which the pdf's integral must leave to it. Under a
        // rough coat no sample is specular, and the rest is the lobe's share
        // that the single-scattering model loses (no direction).
        let drawn = d.count.iter().sum::<u64>();
        let share = if rough(name) {
            assert_eq!(d.specular, 0, "{name}");
            (n as u64 - drawn) as f64 / n as f64
        } else {
            assert!(drawn + d.specular == n as u64, "{name}: none absorbed");
            d.specular as f64 / n as f64
        };
        let se = (diffuse * (1.0 - diffuse) / n as f64).sqrt();
        assert!(
            (share - (1.0 - diffuse)).abs() < 4.0 * se + 1e-4,
            "{name}: the rest {share:.5}, pdf integral {diffuse:.5}"
        );
        if rough(name) {
            continue;
        }
        let (n0, n1) = if name.contains("less dense") {
            (1.6, 1.385640646)
        } else {
            (1.0, 1.5)
        };
        let n1 = if name.contains("2.2") { 2.2 } else { n1 };
        let fresnel = fresnel_dielectric(wi.z.abs() as f64, n1 / n0);
        assert!(
            (diffuse - (1.0 - fresnel)).abs() < 2e-3,
            "{name}: ∫ pdf {diffuse:.5} vs 1 − F(θi) {:.5}",
            1.0 - fresnel
        );
    }
}

/// Unpolarized Fresnel reflectance of a smooth dielectric from outside.
fn fresnel_dielectric(ci: f64, eta: f64) -> f64 {
    let s2 = (1.0 - ci * ci) / (eta * eta);
    if s2 >= 1.0 {
        return 1.0;
    }
    let ct = (1.0 - s2).sqrt();
    let rs = (ci - eta * ct) / (ci + eta * ct);
    let rp = (eta * ci - ct) / (eta * ci + ct);
    0.5 * (rs * rs + rp * rp)
}

/// `pdf`, `Sample::pdf` and `pdf_unbiased` agree, the pdf is 0 on the side
/// light cannot leave by, and `Unidirectional` keeps the walks (its
/// unbiased pdf has a standard error).
#[test]
fn one_pdf_everywhere() {
    for (name, toml) in STACKS {
        let b = bsdf(toml);
        let wi = wi_of(name);
        for s in b
            .sample_batch(&vec![wi; 64], &(0..64).collect::<Vec<_>>())
            .unwrap()
        {
            let s = s.unwrap();
            let p = b.pdf(wi, s.wo).unwrap();
            assert_eq!(s.pdf, p, "{name}: {s:?}");
            let u = b.pdf_unbiased(wi, s.wo, 16).unwrap();
            assert_eq!((u.value as f32, u.stderr), (p, 0.0), "{name}");
            let back = glam::Vec3::new(s.wo.x, s.wo.y, -s.wo.z);
            if !name.contains("two-sided") {
                assert_eq!(b.pdf(wi, back).unwrap(), 0.0, "{name}");
            }
        }
        let walks = b.clone().estimator(Estimator::Unidirectional);
        assert!(!walks.sample_is_exact());
        assert_eq!(b.eval_is_exact(), !rough(name), "{name}");
        let wo = glam::Vec3::new(0.0, 0.3, 0.9).normalize() * wi.z.signum();
        let u = walks.pdf_unbiased(wi, wo, 256).unwrap();
        assert!(u.stderr > 0.0, "{name}: the walks' pdf has noise");
        // Both are densities of `sample()`'s directions, of different walks:
        // the same order of magnitude, not the same number.
        let p = b.pdf(wi, wo).unwrap() as f64;
        assert!(p > 0.0 && u.value > 0.2 * p && u.value < 5.0 * p, "{name}");
    }
}

/// What the walk-free sampler gives a renderer against the walks' sampler
/// (`Estimator::Unidirectional`) on two rough coats over Lambertian bases:
/// the variance of the weight (first channel; for BSDF sampling under
/// uniform light it is the estimator's variance) and the time per sample
/// with its pdf (a batch on the calling pool), for docs/performance.md:
/// `cargo test --release -p strata-bsdf --test estimators closed_form_sampler:: --
/// --ignored --nocapture`.
#[test]
#[ignore]
fn walk_free_sampler_against_the_walks() {
    let stacks = [
        (
            "pbrt-v4's rough coat (α 0.1) over a weak absorber",
            "[[layers]]\ninterface = { kind = \"dielectric\", ior = 1.5, roughness = 0.1 }\n\
             medium = { thickness = 0.01, sigma_t = 1.0, albedo = 0.0 }\n\
             [[layers]]\ninterface = { kind = \"diffuse\", albedo = 0.8 }\n",
        ),
        (STACKS[4].0, STACKS[4].1),
    ];
    let n = 200_000;
    for (name, toml) in stacks {
        let free = bsdf(toml);
        let walks = free.clone().estimator(Estimator::Unidirectional);
        println!("== {name}");
        for t in [0.0f32, 30.0, 60.0, 85.0] {
            let wi = glam::Vec3::new(t.to_radians().sin(), 0.0, t.to_radians().cos());
            let mut line = format!("θi {t:>2}:");
            for (label, b) in [("walk-free", &free), ("walks", &walks)] {
                let idx: Vec<u64> = (0..n as u64).collect();
                let time = std::time::Instant::now();
                let s = b
                    .sample_batch_keyed(&vec![wi; n], &vec![3; n], &idx)
                    .unwrap();
                let us = time.elapsed().as_secs_f64() / n as f64 * 1e6;
                let w: Vec<f64> = s
                    .iter()
                    .map(|x| x.map_or(0.0, |x| x.weight[0] as f64))
                    .collect();
                let mean = w.iter().sum::<f64>() / n as f64;
                let var = w.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / n as f64;
                line +=
                    &format!("  {label}: mean weight {mean:.4}, variance {var:.4}, {us:.2} µs;");
            }
            println!("{line}");
        }
    }
}
