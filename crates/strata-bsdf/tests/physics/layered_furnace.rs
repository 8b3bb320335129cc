//! White furnace tests (method.md §8): energy conservation of `albedo`.
//!
//! * Lossless stacks with smooth interfaces (dielectrics, albedo-1 media, a
//!   white Lambertian base or a transmissive bottom) reflect and transmit all
//!   the light: R + T = 1 for every incidence from 0° to 89°, within 3 standard
//!   errors of R + T (its per-walk variance, accumulated here from
//!   the walks of `sample` (on the wavefront), which `albedo` averages; `albedo` itself
//!   is checked against 1 with the conservative σ_R + σ_T ≥ σ_{R+T}). Where
//!   every event has weight exactly 1 (grey media) the standard error is 0 and
//!   R + T must be 1 to rounding.
//! * A lone rough interface loses what the single-scattering microfacet model
//!   loses, no more: R + T equals the interface's directional albedo
//!   ∫ f(wi, wo) |cos θo| dωo computed here by quadrature of an independent
//!   GGX formula (`common::reference`), within 3 standard errors of the
//!   difference. The quadrature is jittered (one random point per cell, 8
//!   replicas) so that the lobes' cut-offs (GGX has density at the horizon, so
//!   f jumps where a half vector crosses it) give an unbiased error with its
//!   own error bar (about 1e-4, against 7e-4 for the walks).
//! * Every stack (coated conductor, scattering varnish, transmissive slab,
//!   3-interface stack, the paper's validation stack) gives R + T ≤ 1 + 3σ.
//!
//! 3σ is the issue's tolerance. About 80 of the comparisons have a non-zero
//! error bar (the chromatic stacks' 63 per-walk sums, the 19 lone
//! interfaces; the `albedo` checks use the conservative σ_R + σ_T), so a
//! correct estimator would trip one with probability ~20% for an arbitrary
//! seed. The seeds are fixed, so the test is deterministic, and the measured
//! |z| stay below 2.5; a failure must be reproduced with more samples before
//! it is believed.

use crate::common;
use common::reference::{rough_conductor, rough_dielectric, sphere_integral, Acc};
use common::*;
use strata_bsdf::{LayerStack, Settings};

/// R, T and R + T per channel from `n` walks of `sample`.
struct Energy {
    r: [Acc; 3],
    t: [Acc; 3],
    sum: [Acc; 3],
}

fn energy(eng: &Walks, wi: [f64; 3], n: u64, seed: u64, query: u64) -> Energy {
    let mut e = Energy {
        r: [Acc::default(); 3],
        t: [Acc::default(); 3],
        sum: [Acc::default(); 3],
    };
    for s in eng.samples(wi, n, seed, query) {
        let (mut r, mut t) = ([0.0; 3], [0.0; 3]);
        if let Some(s) = s {
            let w = s.weight.map(f64::from);
            // The flag and the direction must agree.
            assert_eq!(s.reflection, (s.wo.z > 0.0) == (wi[2] > 0.0), "{s:?}");
            if s.reflection {
                r = w;
            } else {
                t = w;
            }
        }
        for c in 0..3 {
            e.r[c].push(r[c]);
            e.t[c].push(t[c]);
            e.sum[c].push(r[c] + t[c]);
        }
    }
    e
}

const ANGLES: [f64; 7] = [0.0, 20.0, 45.0, 60.0, 75.0, 85.0, 89.0];

/// R + T = 1 within 3σ, from above (and from below when transmissive).
fn check_lossless(toml: &str, label: &str, n: u64) {
    let st = stack(toml);
    let eng = Walks::new(&st, Settings::default());
    let sides: &[f64] = if st.transmissive() {
        &[1.0, -1.0]
    } else {
        &[1.0]
    };
    for &side in sides {
        for (q, &theta) in ANGLES.iter().enumerate() {
            let mut wi = dir(theta, 30.0);
            wi[2] *= side;
            let e = energy(&eng, wi, n, 5, q as u64);
            let a = eng.albedo(wi, n, 6, q as u64);
            for c in 0..3 {
                let what = format!("{label}: θi {theta} side {side} ch {c}");
                assert_z(&what, e.sum[c].mean(), 1.0, e.sum[c].stderr(), 3.0, 1e-5);
                let (r, t) = (a.reflected, a.transmitted);
                assert_z(
                    &format!("{what} (albedo)"),
                    r.value[c] + t.value[c],
                    1.0,
                    r.stderr[c] + t.stderr[c],
                    3.0,
                    1e-5,
                );
                if !st.transmissive() {
                    assert_eq!(t.value[c], 0.0, "{what}: opaque stack transmits");
                }
            }
            eprintln!(
                "{label} θi {theta} side {side}: R+T = {:.5} ± {:.5}, R = {:.4}",
                e.sum[1].mean(),
                e.sum[1].stderr(),
                e.r[1].mean()
            );
        }
    }
}

#[test]
fn smooth_coat_over_white_lambertian_is_lossless() {
    check_lossless(crate::common::SMOOTH_COAT_WHITE, "coat 1.5 / white", 20_000);
    // Strong total internal reflection and a scattering layer: long walks.
    check_lossless(
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 4.0 }
        medium = { thickness = 1.0, sigma_t = 0.5, albedo = 1.0, phase = { kind = "hg", g = 0.8 } }
        [[layers]]
        interface = { kind = "diffuse", albedo = 1.0 }
        "#,
        "coat 4 / medium / white",
        5_000,
    );
}

#[test]
fn scattering_slab_between_smooth_dielectrics_is_lossless() {
    // Exterior 1 above, 1.33 below; grey medium: every walk has weight 1.
    check_lossless(
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5 }
        medium = { thickness = 2.0, sigma_t = 1.0, albedo = 1.0, phase = { kind = "hg", g = 0.5 } }
        [[layers]]
        interface = { kind = "dielectric", ior = 1.33 }
        "#,
        "slab 1.5 | 1.33",
        20_000,
    );
    // Chromatic extinction: the hero-channel weights vary per walk, so this
    // one has a real error bar. Exterior 1.33 above a lower IOR (total internal
    // reflection from outside), 2.4 below.
    check_lossless(
        r#"
        exterior_ior = 1.33
        [[layers]]
        interface = { kind = "dielectric", ior = 1.0 }
        medium = { thickness = 1.0, sigma_t = [0.3, 1.5, 4.0], albedo = 1.0 }
        [[layers]]
        interface = { kind = "dielectric", ior = 2.4 }
        "#,
        "chromatic slab 1.33 | 1.0 | 2.4",
        40_000,
    );
}

#[test]
fn multilayer_lossless_stack() {
    check_lossless(
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5 }
        medium = { thickness = 1.0, sigma_t = [0.5, 2.0, 5.0], albedo = 1.0 }
        [[layers]]
        interface = { kind = "dielectric", ior = 1.2 }
        medium = { thickness = 0.5, sigma_t = 1.0, albedo = 1.0, phase = { kind = "hg", g = -0.3 } }
        [[layers]]
        interface = { kind = "dielectric", ior = 1.8 }
        [[layers]]
        interface = { kind = "diffuse", albedo = 1.0 }
        "#,
        "3 dielectrics / white",
        20_000,
    );
}

/// The directional albedo ∫ f(wi, wo) |cos θo| dωo of one interface over the
/// sphere, by jittered quadrature, with its standard error.
fn quadrature_albedo(f: &dyn Fn([f64; 3]) -> f64, seed: u64) -> (f64, f64) {
    sphere_integral(250, 8, seed, f)
}

#[test]
fn lone_rough_interface_loses_only_its_own_energy() {
    for (n0, n1, alpha) in [(1.0, 1.5, 0.3), (1.2, 1.0, 0.6)] {
        let st = stack(&format!(
            r#"
            exterior_ior = {n0}
            [[layers]]
            interface = {{ kind = "dielectric", ior = {n1}, roughness = {alpha} }}
            "#
        ));
        let eng = Walks::new(&st, Settings::default());
        for side in [1.0, -1.0] {
            for (q, theta) in [0.0, 40.0, 70.0, 89.0].into_iter().enumerate() {
                let mut wi = dir(theta, 0.0);
                wi[2] *= side;
                let (expect, se) =
                    quadrature_albedo(&|wo| rough_dielectric(alpha, n0, n1, wi, wo), q as u64);
                let e = energy(&eng, wi, 200_000, 7, q as u64);
                let what = format!("dielectric {n0}/{n1} α {alpha} θi {theta} side {side}");
                let (m, s) = (e.sum[0].mean(), e.sum[0].stderr());
                eprintln!("{what}: R+T = {m:.5} ± {s:.5}, quadrature {expect:.5} ± {se:.5}");
                assert!(expect < 0.995, "{what}: the interface must lose energy");
                assert_z(&what, m, expect, s.hypot(se), 3.0, 0.0);
            }
        }
    }
    // A rough conductor with Fresnel ≈ 1 (huge k): the loss is the GGX
    // shadowing alone.
    let (alpha, eta, k) = (0.3, 1.0, 1e4);
    let st = stack(&format!(
        "[[layers]]\ninterface = {{ kind = \"conductor\", eta = {eta}, k = {k}, roughness = {alpha} }}\n"
    ));
    let eng = Walks::new(&st, Settings::default());
    for (q, theta) in [0.0, 60.0, 85.0].into_iter().enumerate() {
        let wi = dir(theta, 0.0);
        let (expect, se) =
            quadrature_albedo(&|wo| rough_conductor(alpha, eta, k, wi, wo), 100 + q as u64);
        let e = energy(&eng, wi, 200_000, 8, q as u64);
        let what = format!("conductor F≈1 α {alpha} θi {theta}");
        let (m, s) = (e.sum[0].mean(), e.sum[0].stderr());
        eprintln!("{what}: R = {m:.5} ± {s:.5}, quadrature {expect:.5} ± {se:.5}");
        assert_z(&what, m, expect, s.hypot(se), 3.0, 0.0);
    }
}

/// Stacks like the examples: R + T ≤ 1 + 3σ at every incidence.
#[test]
fn every_stack_conserves_energy() {
    let stacks = [
        ("coated conductor", COATED_COPPER),
        (
            "scattering varnish",
            r#"
            [[layers]]
            interface = { kind = "dielectric", ior = 1.5, roughness = 0.15 }
            medium = { thickness = 1.0, sigma_t = 1.0, albedo = [0.9, 0.8, 0.7], phase = { kind = "hg", g = 0.3 } }
            [[layers]]
            interface = { kind = "diffuse", albedo = [0.6, 0.4, 0.2] }
            "#,
        ),
        (
            "transmissive slab",
            r#"
            [[layers]]
            interface = { kind = "dielectric", ior = 1.5, roughness = 0.2 }
            medium = { thickness = 1.0, sigma_t = [1.0, 2.0, 3.0], albedo = 0.95, phase = { kind = "hg", g = 0.6 } }
            [[layers]]
            interface = { kind = "dielectric", ior = 1.0, roughness = 0.3 }
            "#,
        ),
        (
            "3 interfaces",
            r#"
            [[layers]]
            interface = { kind = "dielectric", ior = 1.4, roughness = 0.05 }
            medium = { thickness = 0.3, sigma_t = 1.0, albedo = 0.9 }
            [[layers]]
            interface = { kind = "dielectric", ior = 1.8, roughness = 0.3 }
            medium = { thickness = 1.0, sigma_t = [0.5, 1.0, 2.0], albedo = 0.0 }
            [[layers]]
            interface = { kind = "conductor", preset = "Au", roughness = 0.1 }
            "#,
        ),
        (
            "validation 1 (paper Fig. 2)",
            r#"
            [[layers]]
            interface = { kind = "dielectric", ior = 1.5, roughness = 0.05 }
            medium = { thickness = 1.0, sigma_t = 1.0, albedo = [0.5, 0.7, 0.95], phase = { kind = "hg", g = 0.5 } }
            [[layers]]
            interface = { kind = "conductor", preset = "Cu", roughness = 0.05 }
            "#,
        ),
        (
            "rough lossless",
            r#"
            [[layers]]
            interface = { kind = "dielectric", ior = 1.5, roughness = 0.5 }
            medium = { thickness = 1.0, sigma_t = 2.0, albedo = 1.0 }
            [[layers]]
            interface = { kind = "diffuse", albedo = 1.0 }
            "#,
        ),
    ];
    for (label, toml) in stacks {
        let st: LayerStack = stack(toml);
        let eng = Walks::new(&st, Settings::default());
        let sides: &[f64] = if st.transmissive() {
            &[1.0, -1.0]
        } else {
            &[1.0]
        };
        for &side in sides {
            for (q, &theta) in ANGLES.iter().enumerate() {
                let mut wi = dir(theta, 45.0);
                wi[2] *= side;
                let e = energy(&eng, wi, 20_000, 9, q as u64);
                for c in 0..3 {
                    let (m, s) = (e.sum[c].mean(), e.sum[c].stderr());
                    assert!(
                        m.is_finite() && m <= 1.0 + 3.0 * s + 1e-5,
                        "{label} θi {theta} side {side} ch {c}: R + T = {m} ± {s}"
                    );
                }
                eprintln!(
                    "{label} θi {theta} side {side}: R+T = {:.4} ± {:.4}",
                    e.sum[1].mean(),
                    e.sum[1].stderr()
                );
            }
        }
    }
}
