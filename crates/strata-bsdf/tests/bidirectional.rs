//! The bidirectional estimator against the unidirectional one (method.md
//! §4): two estimators with different strategies, different random streams
//! and different subpaths. They share the interface and phase kernels (whose
//! own physics `kernels_chi2.rs` and `kernels_closed_forms.rs` test) but not
//! the path sampling, connections or weights, so agreement checks that the
//! bidirectional walk's measure, eye-side light-sense values and MIS
//! weights are right. The clear coat's closed form checks both against an
//! exact value.

mod common;
use common::*;
use strata_bsdf::estimator::scalar::ScalarEngine;
use strata_bsdf::Settings;

/// Stacks covering the issue's cases: smooth and rough interfaces, thick
/// scattering, transmission, three interfaces, a conductor base.
pub const STACKS: &[(&str, &str)] = &[
    (
        "smooth coat over Lambertian",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5 }
        [[layers]]
        interface = { kind = "diffuse", albedo = 0.8 }
        "#,
    ),
    (
        "rough coat over rough copper",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5, roughness = 0.3 }
        medium = { thickness = 0.5, sigma_t = [0.2, 0.5, 1.0], albedo = 0.0 }
        [[layers]]
        interface = { kind = "conductor", preset = "Cu", roughness = 0.2 }
        "#,
    ),
    (
        "smooth coat over rough copper",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5 }
        [[layers]]
        interface = { kind = "conductor", preset = "Cu", roughness = 0.3 }
        "#,
    ),
    (
        "rough coat, weak scatterer, Lambertian",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5, roughness = 0.1 }
        medium = { thickness = 0.1, sigma_t = 1.0, albedo = 0.9, phase = { kind = "hg", g = 0.5 } }
        [[layers]]
        interface = { kind = "diffuse", albedo = 0.8 }
        "#,
    ),
    (
        "thick scattering (τ 4, g 0.6, chromatic) under a smooth coat",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.4 }
        medium = { thickness = 1.0, sigma_t = [3.0, 4.0, 5.0], albedo = 0.95, phase = { kind = "hg", g = 0.6 } }
        [[layers]]
        interface = { kind = "diffuse", albedo = 0.5 }
        "#,
    ),
    (
        "transmissive rough slab, scattering",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.33, roughness = 0.2 }
        medium = { thickness = 1.0, sigma_t = 2.0, albedo = 0.95, phase = { kind = "hg", g = 0.7 } }
        [[layers]]
        interface = { kind = "dielectric", ior = 1.0, roughness = 0.2 }
        "#,
    ),
    (
        "transmissive smooth-over-rough slab into a denser exterior",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5 }
        medium = { thickness = 0.5, sigma_t = 1.0, albedo = 0.8 }
        [[layers]]
        interface = { kind = "dielectric", ior = 1.3, roughness = 0.3 }
        "#,
    ),
    (
        "three interfaces: rough coat, absorber, anisotropic boundary, scattering film, rough gold",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5, roughness = 0.1 }
        medium = { thickness = 0.2, sigma_t = [0.5, 0.3, 0.1], albedo = 0.0 }
        [[layers]]
        interface = { kind = "dielectric", ior = 2.0, roughness = [0.3, 0.15] }
        medium = { thickness = 0.5, sigma_t = 1.0, albedo = 0.8, phase = { kind = "isotropic" } }
        [[layers]]
        interface = { kind = "conductor", preset = "Au", roughness = 0.15, distribution = "beckmann" }
        "#,
    ),
    (
        "SGGX fibres under a smooth coat",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5 }
        medium = { thickness = 0.5, sigma_t = 2.0, albedo = 0.9, phase = { kind = "sggx", flakes = "fiber", axis = [1.0, 0.0, 0.0], roughness = 0.3, scattering = "specular" } }
        [[layers]]
        interface = { kind = "diffuse", albedo = 0.5 }
        "#,
    ),
];

/// Direction pairs: near normal, oblique, grazing, reflection and (for
/// transmissive stacks) transmission.
fn pairs(transmissive: bool) -> Vec<([f64; 3], [f64; 3])> {
    let mut p = vec![
        (dir(10.0, 0.0), dir(30.0, 180.0)),
        (dir(45.0, 0.0), dir(45.0, 180.0)),
        (dir(70.0, 0.0), dir(20.0, 90.0)),
        (dir(85.0, 0.0), dir(60.0, 200.0)),
    ];
    if transmissive {
        let down = |d: [f64; 3]| [d[0], d[1], -d[2]];
        p.push((dir(20.0, 0.0), down(dir(30.0, 180.0))));
        p.push((dir(60.0, 0.0), down(dir(10.0, 45.0))));
    }
    p
}

#[test]
fn bidirectional_agrees_with_unidirectional() {
    let mut worst = 0.0f64;
    for (name, toml) in STACKS {
        let st = stack(toml);
        let eng = ScalarEngine::<f32>::new(&st, Settings::default());
        let transmissive = st.transmissive();
        for (q, (wi, wo)) in pairs(transmissive).into_iter().enumerate() {
            let u = eng.eval(wi, wo, 40_000, 11, q as u64);
            let b = eng.eval_bidir(wi, wo, 40_000, 12, q as u64);
            for c in 0..3 {
                let se = (u.stderr[c].powi(2) + b.stderr[c].powi(2)).sqrt();
                let z = (u.value[c] - b.value[c]).abs() / se.max(1e-30);
                worst = worst.max(z);
                eprintln!(
                    "{name} q{q} c{c}: uni {:.5} ± {:.5}  bidir {:.5} ± {:.5}  z {z:.2}",
                    u.value[c], u.stderr[c], b.value[c], b.stderr[c]
                );
                assert_z(
                    &format!("{name}, pair {q}, channel {c}"),
                    b.value[c],
                    u.value[c],
                    se,
                    4.0,
                    1e-7,
                );
            }
        }
    }
    eprintln!("worst |z| = {worst:.2}");
}
