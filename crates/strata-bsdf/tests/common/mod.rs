//! Helpers shared by the integration tests: stacks from TOML, directions from
//! angles, and z-score assertions whose tolerance comes from standard errors.
#![allow(dead_code)]

use strata_bsdf::estimator::wavefront::{Plan, Wavefront};
use strata_bsdf::estimator::WalkSample;
use strata_bsdf::lane::F32x8;
use strata_bsdf::{Albedo, Estimate, LayerStack, Settings};

/// The built-in coated copper (`examples/materials/coated_copper.toml`):
/// the tests' coated conductor is the material the README and the CLI name.
pub const COATED_COPPER: &str = include_str!("../../materials/coated_copper.toml");

/// The built-in scattering slab (`examples/materials/scattering_slab.toml`).
pub const SCATTERING_SLAB: &str = include_str!("../../materials/scattering_slab.toml");

/// A smooth coat over a white Lambertian base: a closed-form stack
/// (`estimator::closed_form`), lossless.
pub const SMOOTH_COAT_WHITE: &str = r#"
[[layers]]
interface = { kind = "dielectric", ior = 1.5 }
[[layers]]
interface = { kind = "diffuse", albedo = 1.0 }
"#;

/// A 2.2 coat over a coloured absorber over a Lambertian base: a
/// closed-form stack.
pub const DENSE_COAT_ABSORBER: &str = r#"
[[layers]]
interface = { kind = "dielectric", ior = 2.2 }
medium = { thickness = 0.2, sigma_t = [0.1, 0.3, 0.8], albedo = 0.0 }
[[layers]]
interface = { kind = "diffuse", albedo = 0.7 }
"#;

/// Issue 16's rough varnish over a scattering layer (HG 0.6) over a
/// Lambertian base.
pub const VARNISH_OVER_SCATTERING: &str = r#"
[[layers]]
interface = { kind = "dielectric", ior = 1.5, roughness = 0.2 }
medium = { thickness = 1.0, sigma_t = 2.0, albedo = 0.9, phase = { kind = "hg", g = 0.6 } }
[[layers]]
interface = { kind = "diffuse", albedo = 0.5 }
"#;

/// Issue 16's smooth coat over a rough inner interface over rough copper.
pub const COAT_INNER_COPPER: &str = r#"
[[layers]]
interface = { kind = "dielectric", ior = 1.5 }
[[layers]]
interface = { kind = "dielectric", ior = 1.8, roughness = 0.15 }
[[layers]]
interface = { kind = "conductor", preset = "Cu", roughness = 0.2 }
"#;

/// A smooth coat over a peaked (HG 0.8), chromatic scattering layer over a
/// Lambertian base.
pub const COAT_OVER_HG08: &str = r#"
[[layers]]
interface = { kind = "dielectric", ior = 1.6 }
medium = { thickness = 1.0, sigma_t = 4.0, albedo = [0.6, 0.95, 0.7], phase = { kind = "hg", g = 0.8 } }
[[layers]]
interface = { kind = "diffuse", albedo = 0.5 }
"#;

/// A rough dielectric interface alone (IOR 1.5, GGX α 0.3): air above, glass
/// below.
pub const ROUGH_GLASS: &str = r#"
[[layers]]
interface = { kind = "dielectric", ior = 1.5, roughness = 0.3 }
"#;

/// A rough coat (α 0.2) over a tinted absorber over smoother copper (α 0.1):
/// not the built-in coated copper (α 0.1 over 0.2, σt 0.2/0.6/1.2).
pub const ROUGH_COAT_ABSORBER_COPPER: &str = r#"
[[layers]]
interface = { kind = "dielectric", ior = 1.5, roughness = 0.2 }
medium = { thickness = 0.5, sigma_t = [0.2, 0.5, 1.0], albedo = 0.0 }
[[layers]]
interface = { kind = "conductor", preset = "Cu", roughness = 0.1 }
"#;

/// A smooth coat (IOR 1.5) over a Lambertian base of albedo 0.8: a closed-
/// form stack.
pub const SMOOTH_COAT_OVER_DIFFUSE: &str = r#"
[[layers]]
interface = { kind = "dielectric", ior = 1.5 }
[[layers]]
interface = { kind = "diffuse", albedo = 0.8 }
"#;

/// pbrt-v4's smooth coat over a weak scatterer (τ 0.01, albedo 0.9, HG 0.5)
/// over a Lambertian base.
pub const SMOOTH_WEAK_SCATTERER: &str = r#"
[[layers]]
interface = { kind = "dielectric", ior = 1.5 }
medium = { thickness = 0.01, sigma_t = 1.0, albedo = 0.9, phase = { kind = "hg", g = 0.5 } }
[[layers]]
interface = { kind = "diffuse", albedo = 0.8 }
"#;

/// pbrt-v4's rough coat (α 0.1) over a weak scatterer (τ 0.01, albedo 0.9, HG
/// 0.5) over a Lambertian base.
pub const ROUGH_WEAK_SCATTERER: &str = r#"
[[layers]]
interface = { kind = "dielectric", ior = 1.5, roughness = 0.1 }
medium = { thickness = 0.01, sigma_t = 1.0, albedo = 0.9, phase = { kind = "hg", g = 0.5 } }
[[layers]]
interface = { kind = "diffuse", albedo = 0.8 }
"#;

/// A rough scattering coat over a smooth absorbing coat over rough gold.
pub const TWO_COATS_OVER_GOLD: &str = r#"
[[layers]]
interface = { kind = "dielectric", ior = 1.4, roughness = 0.05 }
medium = { thickness = 0.3, sigma_t = 1.0, albedo = 0.9 }
[[layers]]
interface = { kind = "dielectric", ior = 1.8 }
medium = { thickness = 1.0, sigma_t = [0.5, 1.0, 2.0], albedo = 0.0 }
[[layers]]
interface = { kind = "conductor", preset = "Au", roughness = 0.1 }
"#;

/// A transmissive slab: a rough coat over a chromatic scattering layer (HG
/// 0.5) over a rough exit into IOR 1.33.
pub const ROUGH_SCATTERING_SLAB: &str = r#"
[[layers]]
interface = { kind = "dielectric", ior = 1.5, roughness = 0.3 }
medium = { thickness = 1.0, sigma_t = [0.5, 1.0, 2.0], albedo = 0.9, phase = { kind = "hg", g = 0.5 } }
[[layers]]
interface = { kind = "dielectric", ior = 1.33, roughness = 0.2 }
"#;

/// A smooth coat (IOR 1.5) over a Lambertian base of albedo 0.7: a closed-
/// form stack.
pub const SMOOTH_COAT_OVER_GREY: &str = r#"
[[layers]]
interface = { kind = "dielectric", ior = 1.5 }
[[layers]]
interface = { kind = "diffuse", albedo = 0.7 }
"#;

/// A stack from TOML text (panics with the error: test inputs are valid).
pub fn stack(toml: &str) -> LayerStack {
    LayerStack::from_toml_str(toml).unwrap_or_else(|e| panic!("test material: {e}"))
}

/// The unit direction at polar angle `theta_deg` (from +z) and azimuth `phi_deg`.
pub fn dir(theta_deg: f64, phi_deg: f64) -> [f64; 3] {
    let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
    [t.sin() * p.cos(), t.sin() * p.sin(), t.cos()]
}

/// As a glam vector.
pub fn vec3(d: [f64; 3]) -> glam::Vec3 {
    glam::Vec3::new(d[0] as f32, d[1] as f32, d[2] as f32)
}

/// Asserts `|value - expected| <= k * stderr + abs_tol`, with a message that
/// gives the z-score. `abs_tol` covers the reference's own rounding (f32
/// arithmetic, quadrature); it must be far below the effect being tested.
#[track_caller]
pub fn assert_z(what: &str, value: f64, expected: f64, stderr: f64, k: f64, abs_tol: f64) {
    assert!(
        value.is_finite() && stderr.is_finite(),
        "{what}: non-finite estimate {value} ± {stderr}"
    );
    let err = (value - expected).abs();
    let z = if stderr > 0.0 {
        err / stderr
    } else {
        f64::INFINITY
    };
    assert!(
        err <= k * stderr + abs_tol,
        "{what}: {value} ± {stderr} vs expected {expected} (|z| = {z:.2}, allowed {k} sigma + {abs_tol})"
    );
}

pub mod batches;
pub mod bidir;
pub mod chi2;
pub mod cv;
pub mod reference;
pub mod sets;
pub mod threads;

/// A unit direction uniformly distributed in the cone of half-angle `delta`
/// around `axis`, from two uniforms of `u`.
pub fn in_cone(axis: [f64; 3], delta: f64, u: &mut reference::SplitMix) -> [f64; 3] {
    let cos_t = 1.0 - u.next_f64() * (1.0 - delta.cos());
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    let phi = 2.0 * std::f64::consts::PI * u.next_f64();
    // an orthonormal basis around the axis
    let a = if axis[2].abs() < 0.9 {
        [0.0, 0.0, 1.0]
    } else {
        [1.0, 0.0, 0.0]
    };
    let cross = |p: [f64; 3], q: [f64; 3]| {
        [
            p[1] * q[2] - p[2] * q[1],
            p[2] * q[0] - p[0] * q[2],
            p[0] * q[1] - p[1] * q[0],
        ]
    };
    let norm = |p: [f64; 3]| {
        let l = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
        [p[0] / l, p[1] / l, p[2] / l]
    };
    let t = norm(cross(a, axis));
    let b = cross(axis, t);
    [0, 1, 2].map(|i| sin_t * phi.cos() * t[i] + sin_t * phi.sin() * b[i] + cos_t * axis[i])
}

/// The wavefront engine behind the scalar engine's one-query calls: the same
/// numbers, bit for bit (the engines replay each other walk by walk:
/// tests/parity), at a fraction of the time. Statistical tests run on it;
/// the scalar reference is checked against it in tests/parity alone.
#[derive(Clone)]
pub struct Walks(pub Wavefront<F32x8>);

impl Walks {
    /// The specialized wavefront walks of `stack` under `settings`.
    pub fn new(stack: &LayerStack, settings: Settings) -> Self {
        Walks(Wavefront::new(stack, settings, Plan::Specialized))
    }

    /// With the control variate of `Estimator::Auto` on or off.
    pub fn with_control_variate(self, on: bool) -> Self {
        Walks(self.0.with_control_variate(on))
    }

    /// Whether the control variate is on.
    pub fn control_variate(&self) -> bool {
        self.0.control_variate()
    }

    /// `ScalarEngine::eval`: `n` unidirectional walks of query `query`.
    pub fn eval(&self, wi: [f64; 3], wo: [f64; 3], n: u64, seed: u64, query: u64) -> Estimate {
        self.0.eval_batch(&[(wi, wo)], n, seed, &[query]).0[0]
    }

    /// `ScalarEngine::eval_bidir`: `n` bidirectional walks of query `query`.
    pub fn eval_bidir(
        &self,
        wi: [f64; 3],
        wo: [f64; 3],
        n: u64,
        seed: u64,
        query: u64,
    ) -> Estimate {
        self.0.eval_bidir_batch(&[(wi, wo)], n, seed, &[query])[0]
    }

    /// `ScalarEngine::sample` `n` times: walk `k` draws from the stream
    /// `(seed, query, k)`, as `WalkRng::new(seed, query, k, Stream::Walk)`.
    pub fn samples(&self, wi: [f64; 3], n: u64, seed: u64, query: u64) -> Vec<Option<WalkSample>> {
        let wis = vec![wi; n as usize];
        let keys = vec![query; n as usize];
        let index: Vec<u64> = (0..n).collect();
        self.0.sample_batch(&wis, seed, &keys, &index).0
    }

    /// `ScalarEngine::albedo`: `n` walks from `wi`.
    pub fn albedo(&self, wi: [f64; 3], n: u64, seed: u64, query: u64) -> Albedo {
        self.0.albedo_batch(&[wi], n, seed, &[query]).0[0]
    }
}
