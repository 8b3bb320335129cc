//! Single scattering in an index-matched slab (method.md §8), reflected and
//! transmitted, against closed forms written here.
//!
//! The slab is a medium between two dielectric interfaces whose IOR equals the
//! exterior's, so they are invisible (smooth, Fresnel 0, no radiance scaling).
//! With optical depth τ, single-scattering albedo a and phase function p
//! (normalized over the sphere, argument the cosine between the *travel*
//! directions before and after scattering: the light travels along -wi, then
//! along wo), and μ = |cos θ|:
//!
//! * reflection: f₁ = a p(-wi·wo) (1 - exp(-τ (1/μi + 1/μo))) / (μi + μo);
//! * transmission (wo below): light scattered at optical depth t has crossed
//!   t/μi on the way in and (τ - t)/μo on the way out, over a path dt/μo, so
//!   f₁ = a p(-wi·wo) / μi ∫₀^τ exp(-t/μi - (τ - t)/μo) dt/μo, that is
//!   f₁ = a p(-wi·wo) (exp(-τ/μo) - exp(-τ/μi)) / (μo - μi),
//!   which tends to a p τ exp(-τ/μ) / μ² as μi → μo (evaluated below with
//!   `exp_m1` so the limit is exact and nearby pairs do not cancel).
//!
//! `Settings { max_scatter_order: Some(1), .. }` makes the estimator compute
//! exactly f₁. The full estimator adds higher orders: it must be ≥ f₁, and
//! the excess is bounded by (a² p_max / μi) (1 - exp(-τ/μo)) / (1 - a) (each
//! order's source is at most a times the previous order's supremum, because a
//! beam through the slab has transmittance-weighted length ≤ 1 in optical
//! depth, and p integrates to 1), so at low albedo it is close to f₁.
//!
//! Tolerances: |z| < 4 from the estimator's standard error (one-sided for
//! the bounds), for about 360 comparisons: a false-alarm probability of ~2%
//! for a random seed (the seeds are fixed, so the test is deterministic).

use crate::common;
use common::reference::hg;
use common::*;
use strata_bsdf::estimator::scalar::{Scalar, ScalarEngine};
use strata_bsdf::Settings;

/// A slab: optical depth `tau[c]` per channel (thickness 2, so σt = τ/2),
/// albedo per channel, HG `g` (0: the isotropic phase function, written as
/// such), inside an exterior of IOR `n_ext` matched by both interfaces (whose
/// roughness must not matter).
fn slab(tau: [f64; 3], albedo: [f64; 3], g: f64, n_ext: f64) -> strata_bsdf::LayerStack {
    let phase = if g == 0.0 {
        r#"{ kind = "isotropic" }"#.to_string()
    } else {
        format!(r#"{{ kind = "hg", g = {g} }}"#)
    };
    stack(&format!(
        r#"
        exterior_ior = {n_ext}
        [[layers]]
        interface = {{ kind = "dielectric", ior = {n_ext}, roughness = 0.3 }}
        medium = {{ thickness = 2.0, sigma_t = [{}, {}, {}], albedo = [{}, {}, {}], phase = {phase} }}
        [[layers]]
        interface = {{ kind = "dielectric", ior = {n_ext} }}
        "#,
        tau[0] / 2.0,
        tau[1] / 2.0,
        tau[2] / 2.0,
        albedo[0],
        albedo[1],
        albedo[2],
    ))
}

/// The single-scattering closed form for one channel.
fn single(tau: f64, a: f64, g: f64, wi: [f64; 3], wo: [f64; 3]) -> f64 {
    let mu_i = wi[2].abs();
    let mu_o = wo[2].abs();
    let cos = -(wi[0] * wo[0] + wi[1] * wo[1] + wi[2] * wo[2]);
    let p = hg(g, cos);
    if wi[2] * wo[2] > 0.0 {
        a * p * -(-tau * (1.0 / mu_i + 1.0 / mu_o)).exp_m1() / (mu_i + mu_o)
    } else {
        // (e^{-τ/μo} - e^{-τ/μi}) / (μo - μi) = e^{-τ/μi} expm1(x)/x · τ/(μi μo),
        // x = τ (μo - μi) / (μi μo).
        let x = tau * (mu_o - mu_i) / (mu_i * mu_o);
        let r = if x == 0.0 { 1.0 } else { x.exp_m1() / x };
        a * p * (-tau / mu_i).exp() * r * tau / (mu_i * mu_o)
    }
}

/// (θi, φi, θo, φo) in degrees: reflection, then transmission (θo > 90°),
/// including μi = μo exactly and near-grazing directions.
const PAIRS: [(f64, f64, f64, f64); 8] = [
    (0.0, 0.0, 30.0, 0.0),
    (40.0, 0.0, 40.0, 60.0),
    (60.0, 0.0, 20.0, 180.0),
    (75.0, 0.0, 80.0, 10.0),
    (0.0, 0.0, 180.0, 0.0),
    (40.0, 0.0, 140.0, 200.0),
    (30.0, 0.0, 120.0, 0.0),
    (70.0, 0.0, 170.0, 90.0),
];

fn check_single<S: Scalar>(g: f64, n_ext: f64, n: u64, seed: u64, label: &str) {
    let albedo = [0.3, 0.8, 1.0];
    let settings = Settings {
        max_scatter_order: Some(1),
        ..Settings::default()
    };
    for (t, tau0) in [0.1, 1.0, 10.0].into_iter().enumerate() {
        // Chromatic extinction: the channels have different optical depths.
        let tau = [tau0, 0.6 * tau0, 1.3 * tau0];
        let eng = ScalarEngine::<S>::new(&slab(tau, albedo, g, n_ext), settings);
        for (q, &(ti, pi, to, po)) in PAIRS.iter().enumerate() {
            let (wi, wo) = (dir(ti, pi), dir(to, po));
            let e = eng.eval(wi, wo, n, seed, (t * 100 + q) as u64);
            let mut zs = [0.0; 3];
            for c in 0..3 {
                let exact = single(tau[c], albedo[c], g, wi, wo);
                let what = format!(
                    "{label} g {g} τ {} a {} θi {ti} θo {to} φo {po}",
                    tau[c], albedo[c]
                );
                assert!(exact > 0.0, "{what}: degenerate case");
                assert_z(&what, e.value[c], exact, e.stderr[c], 4.0, 1e-5 * exact);
                // The check is informative: the error bar is a small fraction
                // (largest, about 12%, for τ = 10 transmitted towards a more
                // grazing direction, where rare deep collisions dominate).
                assert!(e.stderr[c] < 0.15 * exact, "{what}: {e:?} vs {exact}");
                zs[c] = (e.value[c] - exact) / e.stderr[c];
            }
            eprintln!(
                "{label} g {g} τ {tau0} θi {ti} θo {to}: z {:+.2} {:+.2} {:+.2}",
                zs[0], zs[1], zs[2]
            );
        }
    }
}

#[test]
fn single_scattering_isotropic_matches_closed_form() {
    check_single::<f32>(0.0, 1.0, 100_000, 3, "f32");
}

#[test]
fn single_scattering_hg_matches_closed_form() {
    // Forward and backward scattering; the second slab sits in an exterior of
    // IOR 1.33 matched by its interfaces.
    check_single::<f32>(0.7, 1.0, 100_000, 4, "f32");
    check_single::<f32>(-0.4, 1.33, 100_000, 5, "f32");
}

#[test]
fn single_scattering_f64_engine_matches_closed_form() {
    check_single::<f64>(0.5, 1.0, 100_000, 6, "f64");
}

/// The full estimator adds the higher orders: f ≥ f₁ always, and at low albedo
/// f - f₁ ≤ (a² p_max / μi) (1 - exp(-τ/μo)) / (1 - a) (module docs), which is
/// about a f₁: the full estimator converges to single scattering.
#[test]
fn full_estimator_bounds_single_scattering() {
    for (g, albedo) in [
        (0.0, [0.02, 0.05, 0.1]),
        (0.6, [0.02, 0.05, 0.1]),
        (0.0, [0.5, 0.9, 0.99]),
    ] {
        let tau = [1.0, 0.5, 3.0];
        let eng = Walks::new(&slab(tau, albedo, g, 1.0), Settings::default());
        let p_max = hg(g, 1.0);
        for (q, &(ti, pi, to, po)) in PAIRS.iter().enumerate() {
            let (wi, wo) = (dir(ti, pi), dir(to, po));
            let e = eng.eval(wi, wo, 100_000, 8, q as u64);
            for c in 0..3 {
                let a = albedo[c];
                let f1 = single(tau[c], a, g, wi, wo);
                let what = format!("g {g} τ {} a {a} θi {ti} θo {to}", tau[c]);
                let z = (e.value[c] - f1) / e.stderr[c];
                assert!(
                    z > -4.0,
                    "{what}: full {e:?} below single scattering {f1} (z = {z:.2})"
                );
                if a <= 0.1 {
                    let bound =
                        a * a * p_max / wi[2].abs() * -(-tau[c] / wo[2].abs()).exp_m1() / (1.0 - a);
                    assert!(
                        e.value[c] - f1 <= bound + 4.0 * e.stderr[c],
                        "{what}: full {e:?} exceeds single scattering {f1} by more than {bound}"
                    );
                    eprintln!(
                        "{what}: (f - f1)/f1 = {:.4} ± {:.4}, bound {:.4}",
                        (e.value[c] - f1) / f1,
                        e.stderr[c] / f1,
                        bound / f1
                    );
                }
            }
        }
    }
}
