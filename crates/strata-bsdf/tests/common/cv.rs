//! The control variate's direction pairs and stacks without scattering
//! (tests/estimators/layered_control_variate.rs, and the engines' parity on
//! them in tests/parity/control_variate.rs).

use strata_bsdf::api::Direction;

use super::{dir, vec3};

/// Direction pairs (θi, φi, θo, φo) in degrees, above the coat: normal,
/// oblique, grazing light with a view from the normal and the swap, both
/// grazing.
pub const PAIRS: [(f64, f64, f64, f64); 5] = [
    (0.0, 0.0, 0.0, 0.0),
    (30.0, 0.0, 45.0, 180.0),
    (89.0, 0.0, 0.0, 0.0),
    (0.0, 0.0, 89.0, 0.0),
    (80.0, 10.0, 75.0, 200.0),
];

/// A direction as the API hands it to the engines.
pub fn as_api(w: [f64; 3]) -> [f64; 3] {
    Direction::new("w", vec3(w)).unwrap().get()
}

/// [`PAIRS`] as the API hands them to the engines.
pub fn api_pairs() -> Vec<([f64; 3], [f64; 3])> {
    PAIRS
        .iter()
        .map(|&(ti, pi, to, po)| (as_api(dir(ti, pi)), as_api(dir(to, po))))
        .collect()
}

/// Stacks of the control variate's shape whose medium only absorbs: no walk
/// collides. Two smooth coats (a closed form) and a rough one (the
/// factorization, `estimator::rough_coat`).
pub const WITHOUT_SCATTERING: [&str; 3] = [
    r#"
    [[layers]]
    interface = { kind = "dielectric", ior = 1.5 }
    medium = { thickness = 0.01, sigma_t = 1.0, albedo = 0.0 }
    [[layers]]
    interface = { kind = "diffuse", albedo = 0.8 }
    "#,
    r#"
    [[layers]]
    interface = { kind = "dielectric", ior = 1.9 }
    medium = { thickness = 0.7, sigma_t = [0.5, 1.0, 3.0], albedo = 0.0, phase = { kind = "hg", g = 0.5 } }
    [[layers]]
    interface = { kind = "diffuse", albedo = [0.9, 0.5, 0.1] }
    "#,
    r#"
    [[layers]]
    interface = { kind = "dielectric", ior = 1.7, roughness = 0.2 }
    medium = { thickness = 0.4, sigma_t = [0.5, 1.0, 3.0], albedo = 0.0 }
    [[layers]]
    interface = { kind = "diffuse", albedo = [0.9, 0.5, 0.1] }
    "#,
];
