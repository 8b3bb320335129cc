//! The brute-force baseline (position-based, binned) against the position-free
//! scalar estimator.
//!
//! The baseline estimates the `|cos|`-weighted average of `f` over a cone bin,
//! not `f(wo)`. So that the comparison carries no binning bias at all, the
//! reference here is that same bin average computed from the position-free
//! estimator: `eval` at directions drawn uniformly in the cone, times
//! `|cos| · (cone solid angle) / ∫_bin |cos|` (an unbiased Monte Carlo
//! integral over the bin). Both sides then estimate the same number, and the
//! tolerance is 4 combined standard errors. A separate test shows the bias the
//! bin average removes is real (one-interface stack, exact `f`).

use crate::common;
use common::*;
use strata_bsdf::estimator::scalar::ScalarEngine;
use strata_bsdf::rng::{Stream, WalkRng};
use strata_bsdf::{LayerStack, Settings};
use strata_reports::brute_force::{Bin, BruteForce, BruteSettings};

/// The bin average of `f` from the position-free estimator: mean and standard
/// error per channel, from `points` directions in the cone with
/// `walks` walks each.
fn bin_average(
    eng: &ScalarEngine<f32>,
    wi: [f64; 3],
    bin: &Bin,
    points: u64,
    walks: u64,
    seed: u64,
) -> ([f64; 3], [f64; 3]) {
    let scale = bin.cone_solid_angle() / bin.measure();
    let (mut s1, mut s2) = ([0.0f64; 3], [0.0f64; 3]);
    for k in 0..points {
        let mut rng = WalkRng::new(seed, 77, k, Stream::Pdf);
        let w = bin.sample_cone(rng.uniform() as f64, rng.uniform() as f64);
        let x = if bin.contains(w) {
            let e = eng.eval(wi, w, walks, seed, 1_000_000 + k);
            e.value.map(|v| v * w[2].abs() * scale)
        } else {
            [0.0; 3]
        };
        for c in 0..3 {
            s1[c] += x[c];
            s2[c] += x[c] * x[c];
        }
    }
    let n = points as f64;
    let mean = s1.map(|s| s / n);
    let se = [0, 1, 2].map(|c| ((s2[c] / n - mean[c] * mean[c]).max(0.0) / (n - 1.0)).sqrt());
    (mean, se)
}

struct Case {
    name: &'static str,
    toml: &'static str,
    wis: &'static [(f64, f64)],
    /// (theta, phi) of the query directions, in degrees (theta > 90: below).
    wos: &'static [(f64, f64)],
    walks: u64,
}

/// Runs one case: every query and channel within 4 combined standard errors
/// of the bin average, with a relative standard error small enough (< 4 %)
/// that a wrong normalisation would be caught; albedos within 4 standard
/// errors of `ScalarEngine::albedo`; the weight lost through the slab's sides
/// negligible.
fn check(case: &Case, half_angle_deg: f64) {
    let st: LayerStack = stack(case.toml);
    let eng = ScalarEngine::<f32>::new(&st, Settings::default());
    let bs = BruteSettings {
        half_angle: half_angle_deg.to_radians(),
        ..BruteSettings::default()
    };
    let bf = BruteForce::new(&st, bs);
    for (qi, &(ti, pi)) in case.wis.iter().enumerate() {
        let wi = dir(ti, pi);
        let wos: Vec<[f64; 3]> = case.wos.iter().map(|&(t, p)| dir(t, p)).collect();
        let run = bf.run(wi, &wos, case.walks, 11, qi as u64);
        // The throughput lost through the slab's sides bounds the bias it
        // causes: it must be far below the albedo's standard error.
        for c in 0..3 {
            let se = run.albedo.reflected.stderr[c];
            assert!(
                run.lost_weight[c] < 0.01 * se,
                "{}: lost weight {:?} (fraction of walks {}) vs stderr {se}",
                case.name,
                run.lost_weight,
                run.lost_fraction()
            );
        }
        for (k, wo) in wos.iter().enumerate() {
            let bin = Bin::new(*wo, bs.half_angle);
            let (mean, se) = bin_average(&eng, wi, &bin, 20_000, 2, 100 + k as u64);
            let b = run.f[k];
            for c in 0..3 {
                let what = format!(
                    "{} wi {:?} wo {:?} ch {c}",
                    case.name,
                    (ti, pi),
                    case.wos[k]
                );
                let s = (b.stderr[c].powi(2) + se[c].powi(2)).sqrt();
                eprintln!(
                    "{what}: brute {:.5} ± {:.5}, position-free bin average {:.5} ± {:.5}",
                    b.value[c], b.stderr[c], mean[c], se[c]
                );
                assert!(mean[c] > 0.0, "{what}: the bin average is zero");
                assert!(
                    s / mean[c] < 0.04,
                    "{what}: relative standard error {} too large for a useful test",
                    s / mean[c]
                );
                assert_z(&what, b.value[c], mean[c], s, 4.0, 0.0);
            }
        }
        let a = eng.albedo(wi, 200_000, 5, qi as u64);
        for c in 0..3 {
            for (what, x, y) in [
                ("R", run.albedo.reflected, a.reflected),
                ("T", run.albedo.transmitted, a.transmitted),
            ] {
                let s = (x.stderr[c].powi(2) + y.stderr[c].powi(2)).sqrt();
                let what = format!("{} wi {:?} albedo {what} ch {c}", case.name, (ti, pi));
                eprintln!(
                    "{what}: brute {:.5} ± {:.5}, position-free {:.5} ± {:.5}",
                    x.value[c], x.stderr[c], y.value[c], y.stderr[c]
                );
                assert_z(&what, x.value[c], y.value[c], s, 4.0, 1e-12);
            }
        }
    }
}

#[test]
fn scattering_hg_medium_over_rough_copper() {
    check(
        &Case {
            name: "HG g 0.5 medium",
            toml: r#"
                [[layers]]
                interface = { kind = "dielectric", ior = 1.5, roughness = 0.3 }
                medium = { thickness = 1.0, sigma_t = 1.0, albedo = [0.5, 0.7, 0.95], phase = { kind = "hg", g = 0.5 } }
                [[layers]]
                interface = { kind = "conductor", preset = "Cu", roughness = 0.3 }
            "#,
            wis: &[(30.0, 0.0)],
            wos: &[(0.0, 0.0), (30.0, 180.0), (50.0, 90.0), (60.0, 0.0)],
            walks: 600_000,
        },
        10.0,
    );
}

#[test]
fn tinted_absorber_over_rough_copper() {
    check(
        &Case {
            name: "tinted absorber",
            toml: r#"
                [[layers]]
                interface = { kind = "dielectric", ior = 1.5, roughness = 0.3 }
                medium = { thickness = 1.0, sigma_t = [0.2, 0.5, 1.0], albedo = 0.0 }
                [[layers]]
                interface = { kind = "conductor", preset = "Cu", roughness = 0.4 }
            "#,
            wis: &[(40.0, 0.0)],
            wos: &[(10.0, 0.0), (40.0, 180.0), (45.0, 120.0)],
            walks: 600_000,
        },
        10.0,
    );
}

#[test]
fn transmissive_scattering_slab_with_chromatic_extinction() {
    check(
        &Case {
            name: "transmissive slab",
            toml: r#"
                [[layers]]
                interface = { kind = "dielectric", ior = 1.5, roughness = 0.2 }
                medium = { thickness = 1.0, sigma_t = [0.5, 1.0, 2.0], albedo = 0.8 }
                [[layers]]
                interface = { kind = "dielectric", ior = 1.0, roughness = 0.2 }
            "#,
            wis: &[(20.0, 0.0), (150.0, 45.0)],
            wos: &[(0.0, 0.0), (40.0, 90.0), (180.0, 0.0), (130.0, 180.0)],
            walks: 600_000,
        },
        10.0,
    );
}

#[test]
fn smooth_coat_over_lambertian_excludes_the_mirror_reflection() {
    // (30°, 180°) is the mirror direction of wi: the delta reflection off the
    // smooth coat lands in that bin and must not count in f.
    check(
        &Case {
            name: "smooth coat over Lambertian",
            toml: r#"
                [[layers]]
                interface = { kind = "dielectric", ior = 1.5 }
                [[layers]]
                interface = { kind = "diffuse", albedo = [0.8, 0.5, 0.2] }
            "#,
            wis: &[(30.0, 0.0)],
            wos: &[(0.0, 0.0), (30.0, 180.0), (70.0, 45.0)],
            walks: 400_000,
        },
        10.0,
    );
}

/// The binning bias is real and is what the bin average accounts for: on a
/// single rough conductor (where `eval` is exact and deterministic) the
/// baseline's estimate at the specular peak agrees with the bin average of
/// the exact `f`, and is many standard errors below the peak value itself.
#[test]
fn binning_bias_is_the_lobe_curvature_over_the_bin() {
    let st = stack(
        r#"
        [[layers]]
        interface = { kind = "conductor", eta = 1.5, k = 3.0, roughness = 0.15 }
        "#,
    );
    let eng = ScalarEngine::<f32>::new(&st, Settings::default());
    let wi = dir(30.0, 0.0);
    let wo = dir(30.0, 180.0);
    let d = 10f64.to_radians();
    let bf = BruteForce::new(
        &st,
        BruteSettings {
            half_angle: d,
            ..BruteSettings::default()
        },
    );
    let run = bf.run(wi, &[wo], 400_000, 3, 0);
    let b = run.f[0];
    // Bin average of the exact f by a midpoint rule in the cone's polar
    // coordinates (f is smooth: 400 × 400 points are far more than enough).
    let bin = Bin::new(wo, d);
    let axis = bin.axis();
    let t = [axis[2], 0.0, -axis[0]]; // unit, orthogonal to axis (axis.y = 0)
    let bb = [0.0, 1.0, 0.0];
    let (nr, np) = (400, 400);
    let mut num = 0.0;
    for i in 0..nr {
        let rho = (i as f64 + 0.5) * d / nr as f64;
        for j in 0..np {
            let psi = (j as f64 + 0.5) * 2.0 * std::f64::consts::PI / np as f64;
            let (s, c) = rho.sin_cos();
            let w = [0, 1, 2].map(|k| c * axis[k] + s * (psi.cos() * t[k] + psi.sin() * bb[k]));
            let f = eng.eval(wi, w, 1, 0, 0).value[0];
            num += f * w[2] * s * (d / nr as f64) * (2.0 * std::f64::consts::PI / np as f64);
        }
    }
    let avg = num / bin.measure();
    let peak = eng.eval(wi, wo, 1, 0, 0).value[0];
    eprintln!(
        "brute {} ± {}, bin average {avg}, peak {peak}",
        b.value[0], b.stderr[0]
    );
    assert_z(
        "brute vs bin average",
        b.value[0],
        avg,
        b.stderr[0],
        4.0,
        1e-4 * avg,
    );
    assert!(
        peak - b.value[0] > 10.0 * b.stderr[0],
        "the binning bias should be visible: peak {peak}, brute {} ± {}",
        b.value[0],
        b.stderr[0]
    );
}

#[test]
fn runs_are_deterministic_and_lose_no_weight() {
    let st = stack(
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5, roughness = 0.2 }
        medium = { thickness = 1.0, sigma_t = 10.0, albedo = 0.99 }
        [[layers]]
        interface = { kind = "diffuse", albedo = 0.5 }
        "#,
    );
    let bf = BruteForce::new(&st, BruteSettings::default());
    let wos = [dir(10.0, 0.0)];
    let a = bf.run(dir(45.0, 0.0), &wos, 20_000, 9, 4);
    let b = bf.run(dir(45.0, 0.0), &wos, 20_000, 9, 4);
    assert_eq!(a, b);
    assert!(
        a.lost_weight.iter().all(|&w| w < 1e-6),
        "{:?}",
        a.lost_weight
    );
}
