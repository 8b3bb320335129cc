//! Reciprocity (method.md §2): reflection is symmetric, f(wi, wo) = f(wo, wi);
//! transmission obeys the radiance-transport relation
//! f(wi, wo) / n_o² = f(wo, wi) / n_i², with n_i and n_o the IORs of the
//! exteriors on the sides of wi and wo.
//!
//! The unidirectional estimator is not symmetric in its arguments (it walks
//! from wi and connects to wo), so the two sides of each relation are
//! independent estimates by different paths: a strong check of the
//! next-event, MIS and η² bookkeeping. Each comparison is
//! z = (a - b) / √(σa² + σb²) with |z| < 4: about 170 comparisons, a
//! false-alarm probability of about 1% for a random seed (seeds fixed). Every
//! estimate must also be precise (relative standard error < 10%), so that the
//! n² factor of transmission (1.77 below) is far outside the tolerance.

use crate::common;
use common::*;
use strata_bsdf::Settings;

/// Direction pairs (θ1, φ1, θ2, φ2) in degrees, both above.
const PAIRS: [(f64, f64, f64, f64); 6] = [
    (10.0, 0.0, 50.0, 120.0),
    (30.0, 0.0, 30.0, 180.0),
    (60.0, 0.0, 20.0, 90.0),
    (75.0, 40.0, 45.0, 200.0),
    (80.0, 0.0, 70.0, 170.0),
    (0.0, 0.0, 65.0, 300.0),
];

const N: u64 = 40_000;

/// Compares per channel; returns false when both sides are exactly zero
/// (e.g. total internal reflection forbids the pair both ways).
fn compare(label: &str, what: &str, a: [f64; 3], sa: [f64; 3], b: [f64; 3], sb: [f64; 3]) -> bool {
    if a == [0.0; 3] && b == [0.0; 3] && sa == [0.0; 3] && sb == [0.0; 3] {
        eprintln!("{label} {what}: zero both ways");
        return false;
    }
    for c in 0..3 {
        let s = sa[c].hypot(sb[c]);
        let z = (a[c] - b[c]) / s;
        eprintln!(
            "{label} {what} ch {c}: {:.5e} vs {:.5e} (z = {z:+.2})",
            a[c], b[c]
        );
        assert!(
            a[c] > 0.0 && b[c] > 0.0,
            "{label} {what} ch {c}: zero value"
        );
        assert!(
            sa[c] < 0.1 * a[c] && sb[c] < 0.1 * b[c],
            "{label} {what} ch {c}: imprecise {a:?} ± {sa:?}, {b:?} ± {sb:?}"
        );
        assert!(
            z.abs() < 4.0,
            "{label} {what} ch {c}: {} ± {} vs {} ± {} (|z| = {:.2})",
            a[c],
            sa[c],
            b[c],
            sb[c],
            z.abs()
        );
    }
    true
}

fn check_reflection(label: &str, toml: &str, from_below: bool, seed: u64) {
    check_reflection_with(label, toml, from_below, seed, false);
}

/// [`check_reflection`], with the control variate of `Estimator::Auto` on
/// (`cv`) or off.
fn check_reflection_with(label: &str, toml: &str, from_below: bool, seed: u64, cv: bool) {
    let st = stack(toml);
    let eng = Walks::new(&st, Settings::default()).with_control_variate(cv);
    assert_eq!(eng.control_variate(), cv, "{label}");
    let flip = |mut w: [f64; 3]| {
        if from_below {
            w[2] = -w[2];
        }
        w
    };
    for (q, &(t1, p1, t2, p2)) in PAIRS.iter().enumerate() {
        let (w1, w2) = (flip(dir(t1, p1)), flip(dir(t2, p2)));
        let a = eng.eval(w1, w2, N, seed, 2 * q as u64);
        let b = eng.eval(w2, w1, N, seed, 2 * q as u64 + 1);
        let what = format!("reflection ({t1}, {p1}) ↔ ({t2}, {p2}) below {from_below}");
        assert!(compare(label, &what, a.value, a.stderr, b.value, b.stderr));
    }
}

#[test]
fn reflection_is_symmetric_on_rough_and_scattering_stacks() {
    check_reflection(
        "coated conductor",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5, roughness = 0.2 }
        medium = { thickness = 0.5, sigma_t = [0.2, 0.5, 1.0], albedo = 0.0 }
        [[layers]]
        interface = { kind = "conductor", preset = "Cu", roughness = 0.3 }
        "#,
        false,
        1,
    );
    check_reflection(
        "scattering varnish",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5, roughness = 0.3 }
        medium = { thickness = 1.0, sigma_t = [1.0, 2.0, 0.5], albedo = [0.9, 0.8, 0.7], phase = { kind = "hg", g = 0.4 } }
        [[layers]]
        interface = { kind = "diffuse", albedo = [0.6, 0.4, 0.2] }
        "#,
        false,
        2,
    );
    check_reflection(
        "smooth coat over a scattering layer",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.4 }
        medium = { thickness = 1.0, sigma_t = 2.0, albedo = 0.9, phase = { kind = "hg", g = -0.3 } }
        [[layers]]
        interface = { kind = "conductor", preset = "Au", roughness = 0.2 }
        "#,
        false,
        3,
    );
    check_reflection(
        "3 interfaces",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.4, roughness = 0.1 }
        medium = { thickness = 0.3, sigma_t = 1.0, albedo = 0.9 }
        [[layers]]
        interface = { kind = "dielectric", ior = 1.8, roughness = 0.3 }
        medium = { thickness = 1.0, sigma_t = [0.2, 0.4, 0.8], albedo = 0.0 }
        [[layers]]
        interface = { kind = "conductor", preset = "Au", roughness = 0.3 }
        "#,
        false,
        4,
    );
}

const SLAB: &str = crate::common::ROUGH_SCATTERING_SLAB;

#[test]
fn reflection_is_symmetric_on_both_sides_of_a_transmissive_slab() {
    check_reflection("rough slab", SLAB, false, 5);
    check_reflection("rough slab", SLAB, true, 6);
}

/// f(wi, wo) / n_o² = f(wo, wi) / n_i² for wi above and wo below.
fn check_transmission(label: &str, toml: &str, seed: u64) {
    let st = stack(toml);
    let (n_above, n_below) = (st.exterior_above(), st.exterior_below());
    assert!(
        (n_above - n_below).abs() > 0.2,
        "{label}: the test needs different exteriors"
    );
    let eng = Walks::new(&st, Settings::default());
    let mut nonzero = 0;
    for (q, &(t1, p1, t2, p2)) in PAIRS.iter().enumerate() {
        let w1 = dir(t1, p1);
        let mut w2 = dir(t2, p2);
        w2[2] = -w2[2];
        // Light from above to below: n_i = n_above, n_o = n_below.
        let a = eng.eval(w1, w2, N, seed, 2 * q as u64);
        let b = eng.eval(w2, w1, N, seed, 2 * q as u64 + 1);
        let (ka, kb) = (1.0 / (n_below * n_below), 1.0 / (n_above * n_above));
        let what = format!("transmission ({t1}, {p1}) ↔ ({t2}, {p2}) scaled by n²");
        nonzero += usize::from(compare(
            label,
            &what,
            a.value.map(|v| v * ka),
            a.stderr.map(|v| v * ka),
            b.value.map(|v| v * kb),
            b.stderr.map(|v| v * kb),
        ));
    }
    assert!(nonzero >= 3, "{label}: only {nonzero} informative pairs");
}

#[test]
fn transmission_obeys_the_eta_squared_relation() {
    // Exterior 1.0 above, 1.33 below.
    check_transmission("rough slab 1 | 1.33", SLAB, 7);
    // A smooth entrance on one side and a rough one on the other, exterior
    // 1.6 above and 1.0 below.
    check_transmission(
        "smooth/rough slab 1.6 | 1.0",
        r#"
        exterior_ior = 1.6
        [[layers]]
        interface = { kind = "dielectric", ior = 1.8 }
        medium = { thickness = 0.5, sigma_t = 1.0, albedo = [0.95, 0.7, 0.4] }
        [[layers]]
        interface = { kind = "dielectric", ior = 1.0, roughness = 0.4 }
        "#,
        8,
    );
    // Total internal reflection at the top for exterior angles beyond 54.3°
    // forbids some pairs both ways (f = 0 on both sides, checked).
    check_transmission(
        "smooth/rough slab 1.6 | 1.3 | 1.0",
        r#"
        exterior_ior = 1.6
        [[layers]]
        interface = { kind = "dielectric", ior = 1.3 }
        medium = { thickness = 0.5, sigma_t = 1.0, albedo = [0.95, 0.7, 0.4] }
        [[layers]]
        interface = { kind = "dielectric", ior = 1.0, roughness = 0.4 }
        "#,
        10,
    );
    // Both interfaces smooth: only scattered light has a non-delta part.
    check_transmission(
        "smooth slab 1 | 1.5",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.2 }
        medium = { thickness = 1.0, sigma_t = 1.5, albedo = 0.8, phase = { kind = "hg", g = 0.3 } }
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5 }
        "#,
        9,
    );
}

/// The control variate (a smooth coat over a scattering layer over a
/// Lambertian base: the paths without a collision exactly, walks for the
/// rest) keeps reflection symmetric: its exact part is, and the walks'
/// part is the plain estimator's over the paths with a collision.
#[test]
fn reflection_is_symmetric_with_the_control_variate() {
    check_reflection_with(
        "weak scatterer under a smooth coat",
        crate::common::SMOOTH_WEAK_SCATTERER,
        false,
        11,
        true,
    );
    let chromatic = r#"
        two_sided = true
        [[layers]]
        interface = { kind = "dielectric", ior = 1.8 }
        medium = { thickness = 0.3, sigma_t = [0.1, 1.0, 3.0], albedo = [0.5, 0.9, 1.0], phase = { kind = "hg", g = -0.4 } }
        [[layers]]
        interface = { kind = "diffuse", albedo = [0.9, 0.6, 0.3] }
        "#;
    check_reflection_with("chromatic, two-sided", chromatic, false, 12, true);
    check_reflection_with("chromatic, two-sided", chromatic, true, 13, true);
}
