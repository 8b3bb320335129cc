//! Families of materials for the per-query parameter sets
//! (tests/api/param_sets.rs, and the engines' parity on them in
//! tests/parity/param_sets.rs): variant `v` of a family draws every number
//! of one shape of stack from its own stream.

use strata_bsdf::rng::mix64;
use strata_bsdf::LayerStack;

use super::{dir, stack, vec3};

/// A uniform number in `[lo, hi)` from a counter (no state to thread).
pub fn uniform(seed: u64, k: u64, lo: f64, hi: f64) -> f64 {
    let u = (mix64(seed.wrapping_mul(0x9e37_79b9) ^ k) >> 11) as f64 / (1u64 << 53) as f64;
    lo + (hi - lo) * u
}

/// A family of materials of one shape: variant `v` draws every number of
/// the material from its own stream (variant 0 is the base).
pub struct Family {
    pub name: &'static str,
    pub toml: fn(&dyn Fn(u64, f64, f64) -> f64) -> String,
}

/// The families: every kind of parameter, the shapes `Auto` answers without
/// walks or with the control variate, three interfaces and tilted normals.
pub fn families() -> Vec<Family> {
    vec![
        // Every kind of number: exterior IOR, a rough anisotropic coat, a
        // chromatic scattering HG layer, a rough conductor with eta and k.
        Family {
            name: "rough coat / chromatic HG layer / rough conductor",
            toml: |r| {
                format!(
                    "exterior_ior = {}\n\
                     [[layers]]\n\
                     interface = {{ kind = \"dielectric\", ior = {}, roughness = [{}, {}] }}\n\
                     medium = {{ thickness = {}, sigma_t = [{}, {}, {}], albedo = [{}, {}, {}], phase = {{ kind = \"hg\", g = {} }} }}\n\
                     [[layers]]\n\
                     interface = {{ kind = \"conductor\", eta = [{}, {}, {}], k = [{}, {}, {}], roughness = {} }}\n",
                    r(0, 1.0, 1.3),
                    r(1, 1.4, 1.9),
                    r(2, 0.05, 0.5),
                    r(3, 0.05, 0.5),
                    r(4, 0.2, 2.0),
                    r(5, 0.5, 1.0),
                    r(6, 1.1, 2.0),
                    r(7, 2.1, 3.0),
                    r(8, 0.3, 0.95),
                    r(9, 0.3, 0.95),
                    r(10, 0.3, 0.95),
                    r(11, -0.7, 0.8),
                    r(12, 0.2, 1.5),
                    r(13, 0.2, 1.5),
                    r(14, 0.2, 1.5),
                    r(15, 1.0, 4.0),
                    r(16, 1.0, 4.0),
                    r(17, 1.0, 4.0),
                    r(18, 0.05, 0.6),
                )
            },
        },
        // The closed form's shape (Auto answers exactly), with its numbers.
        Family {
            name: "smooth coat / absorber / Lambertian",
            toml: |r| {
                format!(
                    "[[layers]]\n\
                     interface = {{ kind = \"dielectric\", ior = {} }}\n\
                     medium = {{ thickness = {}, sigma_t = [{}, {}, {}], albedo = 0 }}\n\
                     [[layers]]\n\
                     interface = {{ kind = \"diffuse\", albedo = [{}, {}, {}] }}\n",
                    r(0, 1.3, 2.0),
                    r(1, 0.1, 1.0),
                    r(2, 0.1, 0.5),
                    r(3, 0.6, 1.0),
                    r(4, 1.1, 2.0),
                    r(5, 0.2, 0.9),
                    r(6, 0.2, 0.9),
                    r(7, 0.2, 0.9),
                )
            },
        },
        // The control variate's shape: smooth coat over a weak grey
        // scatterer over Lambertian; some sets use it, some not.
        Family {
            name: "smooth coat / grey scatterer / Lambertian",
            toml: |r| {
                format!(
                    "[[layers]]\n\
                     interface = {{ kind = \"dielectric\", ior = {} }}\n\
                     medium = {{ thickness = {}, sigma_t = {}, albedo = {}, phase = {{ kind = \"hg\", g = {} }} }}\n\
                     [[layers]]\n\
                     interface = {{ kind = \"diffuse\", albedo = {} }}\n",
                    r(0, 1.3, 1.8),
                    r(1, 0.05, 1.0),
                    r(2, 0.05, 1.0),
                    r(3, 0.05, 0.9),
                    r(4, -0.5, 0.9),
                    r(5, 0.3, 0.95),
                )
            },
        },
        // The rough coat's factorization (Auto answers without walks), each
        // set with its own coat and layer, so its own integral R̄.
        Family {
            name: "rough coat / absorber / Lambertian",
            toml: |r| {
                format!(
                    "[[layers]]\n\
                     interface = {{ kind = \"dielectric\", ior = {}, roughness = {} }}\n\
                     medium = {{ thickness = {}, sigma_t = [{}, {}, {}], albedo = 0 }}\n\
                     [[layers]]\n\
                     interface = {{ kind = \"diffuse\", albedo = [{}, {}, {}] }}\n",
                    r(0, 1.3, 2.0),
                    r(1, 0.05, 0.6),
                    r(2, 0.1, 1.0),
                    r(3, 0.1, 0.5),
                    r(4, 0.6, 1.0),
                    r(5, 1.1, 2.0),
                    r(6, 0.2, 0.9),
                    r(7, 0.2, 0.9),
                    r(8, 0.2, 0.9),
                )
            },
        },
        // The rough coat's control variate: some sets in the rule (a weak
        // scatterer over a bright base), some not.
        Family {
            name: "rough coat / weak grey scatterer / Lambertian",
            toml: |r| {
                format!(
                    "[[layers]]\n\
                     interface = {{ kind = \"dielectric\", ior = {}, roughness = {} }}\n\
                     medium = {{ thickness = {}, sigma_t = 1.0, albedo = {}, phase = {{ kind = \"hg\", g = {} }} }}\n\
                     [[layers]]\n\
                     interface = {{ kind = \"diffuse\", albedo = {} }}\n",
                    r(0, 1.3, 1.8),
                    r(1, 0.05, 0.5),
                    r(2, 0.005, 0.1),
                    r(3, 0.3, 0.95),
                    r(4, -0.5, 0.9),
                    r(5, 0.3, 0.95),
                )
            },
        },
        // Transmissive, three interfaces, a smooth exit below (chains through
        // delta interfaces) and different exteriors.
        Family {
            name: "rough slab / smooth clear layer / smooth bottom",
            toml: |r| {
                format!(
                    "exterior_ior = {}\n\
                     [[layers]]\n\
                     interface = {{ kind = \"dielectric\", ior = {}, roughness = {} }}\n\
                     medium = {{ thickness = {}, sigma_t = {}, albedo = {} }}\n\
                     [[layers]]\n\
                     interface = {{ kind = \"dielectric\", ior = {} }}\n\
                     [[layers]]\n\
                     interface = {{ kind = \"dielectric\", ior = {} }}\n",
                    r(0, 1.0, 1.2),
                    r(1, 1.3, 1.7),
                    r(2, 0.1, 0.6),
                    r(3, 0.3, 2.0),
                    r(4, 0.3, 2.0),
                    r(5, 0.5, 0.99),
                    r(6, 1.8, 2.2),
                    r(7, 1.0, 1.25),
                )
            },
        },
        // A normal per interface (a normal map per layer): every interface
        // tilted, each set its own way, through a smooth chain.
        Family {
            name: "tilted normals: rough coat / scatterer / smooth inner / rough conductor",
            toml: |r| {
                format!(
                    "[[layers]]\n\
                     interface = {{ kind = \"dielectric\", ior = {}, roughness = {}, normal = [{}, {}, 1] }}\n\
                     medium = {{ thickness = {}, sigma_t = {}, albedo = {} }}\n\
                     [[layers]]\n\
                     interface = {{ kind = \"dielectric\", ior = {}, normal = [{}, {}, 1] }}\n\
                     [[layers]]\n\
                     interface = {{ kind = \"conductor\", preset = \"Cu\", roughness = {}, normal = [{}, {}, 1] }}\n",
                    r(0, 1.3, 1.7),
                    r(1, 0.1, 0.5),
                    r(2, 0.05, 0.3),
                    r(3, -0.3, -0.05),
                    r(4, 0.3, 2.0),
                    r(5, 0.3, 2.0),
                    r(6, 0.5, 0.95),
                    r(7, 1.1, 1.4),
                    r(8, -0.3, -0.05),
                    r(9, 0.05, 0.3),
                    r(10, 0.1, 0.5),
                    r(11, 0.05, 0.3),
                    r(12, 0.05, 0.3),
                )
            },
        },
    ]
}

/// Variant `v` of a family, as a material file would give it.
pub fn variant(f: &Family, v: u64) -> LayerStack {
    let r = move |k: u64, lo: f64, hi: f64| uniform(v + 1, k, lo, hi);
    stack(&(f.toml)(&r))
}

/// The variants of a family that the tests use.
pub const SETS: u64 = 5;

/// Queries: reflection and transmission, near-normal and grazing, each
/// with its set (sets interleaved, so chunks mix them).
pub fn queries(n: usize) -> (Vec<(glam::Vec3, glam::Vec3)>, Vec<u32>) {
    let pairs = (0..n)
        .map(|k| {
            let ti = [5.0, 35.0, 65.0, 85.0, 150.0][k % 5];
            let to = [10.0, 50.0, 80.0, 120.0, 170.0, 30.0, 60.0][k % 7];
            (
                vec3(dir(ti, 10.0 * k as f64)),
                vec3(dir(to, 200.0 + 7.0 * k as f64)),
            )
        })
        .collect();
    let set = (0..n).map(|k| (k as u64 * 3 % SETS) as u32).collect();
    (pairs, set)
}

/// The directions of [`queries`]' pairs, normalized in f64.
pub fn unit_dirs(pairs: &[(glam::Vec3, glam::Vec3)]) -> Vec<([f64; 3], [f64; 3])> {
    (pairs.iter())
        .map(|(a, b)| {
            (
                a.as_dvec3().normalize().to_array(),
                b.as_dvec3().normalize().to_array(),
            )
        })
        .collect()
}

/// The bits of an RGB value.
pub fn bits(v: [f64; 3]) -> [u64; 3] {
    v.map(f64::to_bits)
}
