//! The layered estimators against the closed form of a smooth dielectric coat
//! over a Lambertian base with no medium (method.md §8):
//!
//! f(wi, wo) = (1 - F(θi)) (1 - F(θo)) ρ / (π η² (1 - ρ F̄_in)),
//!
//! with F the Fresnel reflectance seen from outside and F̄_in the
//! cosine-weighted internal reflectance (total internal reflection included).
//! Fresnel is written in the test (`common::reference`), independently of the
//! crate. The base's albedo is given per channel as (0, 0.5, 1), so every eval
//! checks the three albedos at once (channel 0 must be exactly 0).
//!
//! Tolerance: |z| < 4 per comparison, z from the estimator's own standard
//! error. There are about 100 non-trivial comparisons, so a correct estimator
//! fails one with probability about 100 × 6e-5 < 1% for a random seed; the seeds
//! are fixed, so the test is deterministic. The reference is exact up to the
//! quadrature of F̄_in (error < 1e-9) and the f32 arithmetic of the engine
//! (relative 1e-5 allowance, far below the standard errors of about 0.5%).

use crate::common;
use common::reference::fresnel;
use common::*;
use strata_bsdf::estimator::scalar::{Scalar, ScalarEngine};
use strata_bsdf::{Estimator, Settings};

/// Cosine-weighted hemispherical average of the reflectance seen from inside a
/// medium of relative IOR `eta`: ∫ F(μ) 2μ dμ over μ in (0, 1), midpoint rule.
fn fbar_inside(eta: f64) -> f64 {
    let n = 200_000;
    let mut s = 0.0;
    for k in 0..n {
        let mu = (k as f64 + 0.5) / n as f64;
        s += fresnel(mu, eta, 1.0) * 2.0 * mu / n as f64;
    }
    s
}

/// The base albedo per channel.
const RHO: [f64; 3] = [0.0, 0.5, 1.0];

/// Direction pairs (θi, θo, φo) in degrees, φi = 0: normal, oblique and grazing
/// (85°) incidence and exit, forward, backward and sideways.
const PAIRS: [(f64, f64, f64); 7] = [
    (0.0, 0.0, 0.0),
    (0.0, 60.0, 90.0),
    (30.0, 45.0, 180.0),
    (60.0, 15.0, 30.0),
    (85.0, 50.0, 0.0),
    (40.0, 85.0, 270.0),
    (85.0, 85.0, 180.0),
];

/// The closed form for base albedo `rho`, cosines `ci`, `co` (both > 0).
fn closed_form(eta: f64, fbar_in: f64, rho: f64, ci: f64, co: f64) -> f64 {
    (1.0 - fresnel(ci, 1.0, eta)) * (1.0 - fresnel(co, 1.0, eta)) * rho
        / (std::f64::consts::PI * eta * eta * (1.0 - rho * fbar_in))
}

fn check_coat<S: Scalar>(eta: f64, pairs: &[(f64, f64, f64)], n: u64, seed: u64, label: &str) {
    let st = stack(&format!(
        r#"
        [[layers]]
        interface = {{ kind = "dielectric", ior = {eta} }}
        [[layers]]
        interface = {{ kind = "diffuse", albedo = [{}, {}, {}] }}
        "#,
        RHO[0], RHO[1], RHO[2]
    ));
    let eng = ScalarEngine::<S>::new(&st, Settings::default());
    let fb = fbar_inside(eta);
    for (q, &(ti, to, po)) in pairs.iter().enumerate() {
        let wi = dir(ti, 0.0);
        let wo = dir(to, po);
        let e = eng.eval(wi, wo, n, seed, q as u64);
        let mut z = [0.0; 3];
        for c in 0..3 {
            let exact = closed_form(eta, fb, RHO[c], wi[2], wo[2]);
            assert_z(
                &format!("{label}: eta {eta} rho {} θi {ti} θo {to} φo {po}", RHO[c]),
                e.value[c],
                exact,
                e.stderr[c],
                4.0,
                1e-5 * exact,
            );
            if RHO[c] > 0.0 {
                // The comparison is informative: the error bar is a small
                // fraction of the value.
                assert!(e.stderr[c] < 0.02 * exact, "{label}: {e:?} vs {exact}");
                z[c] = (e.value[c] - exact) / e.stderr[c];
            }
        }
        eprintln!(
            "{label} eta {eta} θi {ti} θo {to}: z = {:+.2} {:+.2}",
            z[1], z[2]
        );
    }
}

/// The f32 reference engine: IORs from nearly index-matched (1.0001, where the
/// coat is almost invisible) to 4 (strong total internal reflection, long walks).
#[test]
fn smooth_coat_over_lambertian_matches_closed_form() {
    for eta in [1.0001, 1.33, 1.5, 2.5, 4.0] {
        check_coat::<f32>(eta, &PAIRS, 60_000, 11, "f32");
    }
}

/// The f64 instance of the same estimator, on a subset.
#[test]
fn smooth_coat_over_lambertian_matches_closed_form_f64() {
    for eta in [1.0001, 1.5, 4.0] {
        check_coat::<f64>(eta, &PAIRS[..4], 60_000, 12, "f64");
    }
}

/// The same closed form through the public API (`LayeredBsdf`), which
/// normalizes glam directions and derives its own query keys.
#[test]
fn smooth_coat_over_lambertian_through_the_public_api() {
    let eta = 1.5;
    let st = stack(&format!(
        r#"
        [[layers]]
        interface = {{ kind = "dielectric", ior = {eta} }}
        [[layers]]
        interface = {{ kind = "diffuse", albedo = [{}, {}, {}] }}
        "#,
        RHO[0], RHO[1], RHO[2]
    ));
    // The walks, and the library's own closed form (`Estimator::Auto`).
    for estimator in [Estimator::Unidirectional, Estimator::Auto] {
        let bsdf = strata_bsdf::LayeredBsdf::new(st.clone())
            .samples(60_000)
            .seed(3)
            .estimator(estimator);
        let fb = fbar_inside(eta);
        for &(ti, to, po) in &PAIRS[1..4] {
            let (wi, wo) = (dir(ti, 0.0), dir(to, po));
            // Not normalized on purpose: the API normalizes.
            let e = bsdf
                .eval(vec3(wi) * 2.5, vec3(wo) * 0.5)
                .expect("valid directions");
            for (c, &rho) in RHO.iter().enumerate() {
                let exact = closed_form(eta, fb, rho, wi[2], wo[2]);
                let what = format!("api: rho {rho} θi {ti} θo {to}");
                assert_z(&what, e.value[c], exact, e.stderr[c], 4.0, 1e-4 * exact);
                if rho > 0.0 {
                    // Informative: the error bar is a small fraction of the value.
                    assert!(e.stderr[c] < 0.02 * exact, "{what}: {e:?} vs {exact}");
                }
                if estimator == Estimator::Auto {
                    assert_eq!(e.stderr[c], 0.0, "{what}: the closed form is exact");
                }
            }
        }
    }
}
