//! The bidirectional estimator's test stacks and direction pairs
//! (tests/estimators/bidirectional.rs, and the engines' parity on them in
//! tests/parity/bidirectional.rs).

use super::dir;

/// Stacks covering the issue's cases: smooth and rough interfaces, thick
/// scattering, transmission, three interfaces, a conductor base.
pub const STACKS: &[(&str, &str)] = &[
    (
        "smooth coat over Lambertian",
        super::SMOOTH_COAT_OVER_DIFFUSE,
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
    (
        "diffuse SGGX flakes (surface) under a rough coat",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5, roughness = 0.2 }
        medium = { thickness = 0.5, sigma_t = 2.0, albedo = 0.9, phase = { kind = "sggx", flakes = "surface", axis = [0.0, 0.0, 1.0], roughness = 0.2, scattering = "diffuse" } }
        [[layers]]
        interface = { kind = "diffuse", albedo = 0.5 }
        "#,
    ),
];

/// Stacks with tilted shading normals (not reciprocal): a transmissive slab
/// with a scattering layer, and an opaque coat over gold.
pub const TILTED: &[(&str, &str)] = &[
    (
        "tilted coat and base, scattering between",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5, roughness = 0.2, normal = [0.2, 0.1, 1.0] }
        medium = { thickness = 0.3, sigma_t = 1.0, albedo = 0.8, phase = { kind = "hg", g = 0.3 } }
        [[layers]]
        interface = { kind = "dielectric", ior = 1.3, roughness = 0.3, normal = [-0.3, 0.0, 1.0] }
        "#,
    ),
    (
        "tilted smooth coat over a smooth gold base",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5, normal = [0.15, 0.0, 1.0] }
        medium = { thickness = 0.2, sigma_t = 1.0, albedo = 0.5 }
        [[layers]]
        interface = { kind = "conductor", preset = "Au" }
        "#,
    ),
];

/// Direction pairs: near normal, oblique, grazing, reflection and (for
/// transmissive stacks) transmission.
pub fn pairs(transmissive: bool) -> Vec<([f64; 3], [f64; 3])> {
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
