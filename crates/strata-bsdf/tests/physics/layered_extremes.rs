//! Extreme but valid inputs: a sweep over combinations of roughness (smooth,
//! alpha 1e-4 and 1), IOR (1.0001 and 4), optical depth (0 and 1e4), medium
//! albedo (0 and 1), phase (g = ±0.99), bottoms (white and black Lambertian,
//! a near-specular conductor, rough and index-matched dielectrics) and
//! directions (cos θ = 1e-6 and 1, above and below), on the f32 and f64
//! engines. Nothing may be NaN or infinite: eval's value and standard error,
//! sample's direction (unit length, on the side its flag says) and weight
//! (≥ 0), pdf (≥ 0); and R + T ≤ 1 + 4σ.
//!
//! Cheap by design: 4 walks per query, 165 stacks × 25 direction pairs per
//! engine. The costliest corner is a lossless medium of optical depth 1e4:
//! nothing is absorbed, so Russian roulette cannot shorten its walks. With
//! g = 0.99 (transport depth 100) under a nearly index-matched coat a walk
//! takes ~0.05–100 ms; under an IOR-4 coat, which traps light by total
//! internal reflection outside a 14.5° cone, 10–600 ms (measured), so that
//! combination runs once, separately, with fewer queries; backward
//! scattering at that depth (a ~1e8-step random walk) is covered with an
//! absorbing medium only.

use crate::common;
use common::*;
use strata_bsdf::estimator::scalar::{Scalar, ScalarEngine};
use strata_bsdf::rng::{Stream, WalkRng};
use strata_bsdf::{LayerStack, Settings};

/// The top interfaces of the sweep.
fn tops() -> Vec<String> {
    let mut v = Vec::new();
    for ior in [1.0001, 4.0] {
        for alpha in [0.0, 1e-4, 1.0] {
            v.push(format!(
                r#"{{ kind = "dielectric", ior = {ior}, roughness = {alpha} }}"#
            ));
        }
    }
    v
}

/// Media: `None` or (optical depth, albedo, g). Depth 0 makes the phase
/// irrelevant, so it is paired with one g.
fn media() -> Vec<Option<(f64, f64, f64)>> {
    vec![
        None,
        Some((0.0, 0.0, 0.99)),
        Some((0.0, 1.0, -0.99)),
        Some((1e4, 0.0, -0.99)),
        Some((1e4, 0.0, 0.99)),
        Some((1e4, 1.0, 0.99)),
    ]
}

fn bottoms() -> Vec<String> {
    vec![
        r#"{ kind = "diffuse", albedo = 1.0 }"#.to_string(),
        r#"{ kind = "diffuse", albedo = 0.0 }"#.to_string(),
        r#"{ kind = "conductor", preset = "Ag", roughness = 1e-4 }"#.to_string(),
        r#"{ kind = "dielectric", ior = 4.0, roughness = 1.0 }"#.to_string(),
        r#"{ kind = "dielectric", ior = 1.0001 }"#.to_string(),
    ]
}

fn material(top: &str, medium: Option<(f64, f64, f64)>, bottom: &str) -> String {
    let medium = match medium {
        None => String::new(),
        Some((tau, albedo, g)) => format!(
            "medium = {{ thickness = {tau}, sigma_t = 1.0, albedo = {albedo}, phase = {{ kind = \"hg\", g = {g} }} }}\n"
        ),
    };
    format!("[[layers]]\ninterface = {top}\n{medium}[[layers]]\ninterface = {bottom}\n")
}

/// Directions with cos θ = ±1e-6 and ±1.
fn directions() -> Vec<[f64; 3]> {
    let s = (1.0f64 - 1e-12).sqrt();
    vec![
        [0.0, 0.0, 1.0],
        [s, 0.0, 1e-6],
        [-s * 0.6, s * 0.8, 1e-6],
        [0.0, 0.0, -1.0],
        [s, 0.0, -1e-6],
    ]
}

fn check_case<S: Scalar>(st: &LayerStack, label: &str, walks: u64, seed: u64) {
    let eng = ScalarEngine::<S>::new(st, Settings::default());
    let dirs = directions();
    for (i, &wi) in dirs.iter().enumerate() {
        for (j, &wo) in dirs.iter().enumerate() {
            let key = (i * 10 + j) as u64;
            let e = eng.eval(wi, wo, walks, seed, key);
            for c in 0..3 {
                assert!(
                    e.value[c].is_finite() && e.value[c] >= 0.0 && e.stderr[c].is_finite(),
                    "{label}: eval({wi:?}, {wo:?}) = {e:?}"
                );
            }
            let p = eng.pdf(wi, wo, 4, seed, key);
            assert!(
                p.is_finite() && p >= 0.0,
                "{label}: pdf({wi:?}, {wo:?}) = {p}"
            );
        }
        for k in 0..walks {
            let mut rng = WalkRng::new(seed, 1000 + i as u64, k, Stream::Walk);
            if let Some(s) = eng.sample(wi, &mut rng) {
                let w = s.wo;
                let len = w.length();
                assert!(
                    w.is_finite() && (len - 1.0).abs() < 1e-3,
                    "{label}: sample({wi:?}) wo = {w:?}"
                );
                assert!(
                    s.weight.iter().all(|x| x.is_finite() && *x >= 0.0),
                    "{label}: sample({wi:?}) weight = {:?}",
                    s.weight
                );
                // The flag names the side wo leaves on (wo.z may round to 0
                // for a grazing exit; then there is nothing to check).
                if w.z != 0.0 && wi[2].abs() > 0.5 {
                    let above = w.z > 0.0;
                    assert_eq!(
                        s.reflection,
                        above == (wi[2] > 0.0),
                        "{label}: sample({wi:?}) = {s:?}"
                    );
                }
            }
        }
        let a = eng.albedo(wi, walks, seed, 2000 + i as u64);
        for c in 0..3 {
            let (r, t) = (a.reflected, a.transmitted);
            let sum = r.value[c] + t.value[c];
            let se = r.stderr[c] + t.stderr[c];
            assert!(
                sum.is_finite() && se.is_finite() && r.value[c] >= 0.0 && t.value[c] >= 0.0,
                "{label}: albedo({wi:?}) = {a:?}"
            );
            assert!(
                sum <= 1.0 + 4.0 * se + 1e-5,
                "{label}: albedo({wi:?}) R + T = {sum} ± {se}"
            );
        }
    }
}

fn sweep<S: Scalar>(name: &str, seed: u64) {
    let mut cases = 0;
    let start = std::time::Instant::now();
    for top in tops() {
        for medium in media() {
            for bottom in bottoms() {
                let toml = material(&top, medium, &bottom);
                let st = stack(&toml);
                // A lossless medium of depth 1e4 under an IOR-4 coat traps
                // light (total internal reflection outside a 14.5° cone):
                // 10 ms to 0.6 s per walk. See the module docs.
                let lossless_deep = medium.is_some_and(|(t, a, _)| t > 0.0 && a == 1.0);
                if lossless_deep && top.contains("ior = 4") {
                    continue;
                }
                let walks = 4;
                let t0 = std::time::Instant::now();
                check_case::<S>(&st, &format!("{name} {toml}"), walks, seed);
                let dt = t0.elapsed();
                if dt.as_millis() > 100 {
                    eprintln!("{name}: slow case ({dt:?}):\n{toml}");
                }
                cases += 1;
            }
        }
    }
    eprintln!("{name}: {cases} stacks in {:?}", start.elapsed());
}

/// The trapped case of the module docs, a few queries only.
#[test]
fn lossless_deep_medium_under_a_high_index_coat() {
    let st = stack(&material(
        r#"{ kind = "dielectric", ior = 4.0 }"#,
        Some((1e4, 1.0, 0.99)),
        r#"{ kind = "diffuse", albedo = 1.0 }"#,
    ));
    let eng = Walks::new(&st, Settings::default());
    let (wi, wo) = ([0.0, 0.0, 1.0], [0.6, 0.0, 0.8]);
    let e = eng.eval(wi, wo, 2, 1, 1);
    assert!(
        e.value.iter().chain(&e.stderr).all(|x| x.is_finite()),
        "{e:?}"
    );
    let a = eng.albedo(wo, 4, 1, 2);
    let (r, t) = (a.reflected, a.transmitted);
    for c in 0..3 {
        assert!(
            r.value[c].is_finite() && r.value[c] <= 1.0 + 4.0 * r.stderr[c] + 1e-5,
            "{a:?}"
        );
        // Lossless: every walk comes back out with weight 1.
        assert!(
            (r.value[c] - 1.0).abs() < 1e-5 && t.value[c] == 0.0,
            "{a:?}"
        );
    }
}

#[test]
fn extreme_inputs_f32() {
    sweep::<f32>("f32", 1);
}

#[test]
fn extreme_inputs_f64() {
    sweep::<f64>("f64", 2);
}

/// Two-sided opaque stacks mirror light from below; grazing and normal.
#[test]
fn extreme_inputs_two_sided() {
    for top in tops() {
        let toml = format!(
            "two_sided = true\n{}",
            material(
                &top,
                Some((1.0, 0.5, 0.99)),
                r#"{ kind = "diffuse", albedo = 1.0 }"#
            )
        );
        check_case::<f32>(&stack(&toml), &toml, 16, 3);
    }
}
