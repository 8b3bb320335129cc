//! Built-in materials: the files of `examples/materials/`, embedded.
//!
//! They are the demo's defaults, the benchmarks' representative stacks and
//! the convergence reports' suite, so every figure in `docs/` names a file a
//! user can open, edit and pass back with `--material`.
//!
//! ```
//! let stack = strata_bsdf::materials::builtin("coated_copper").unwrap();
//! assert_eq!(stack.len(), 2);
//! ```

use crate::stack::LayerStack;

/// Every built-in material: `(name, TOML text)`; the name is the file stem.
pub const BUILTIN: &[(&str, &str)] = &[
    (
        "clear_coat_lambertian",
        include_str!("../materials/clear_coat_lambertian.toml"),
    ),
    (
        "coated_copper",
        include_str!("../materials/coated_copper.toml"),
    ),
    (
        "varnished_wood",
        include_str!("../materials/varnished_wood.toml"),
    ),
    (
        "thick_scattering",
        include_str!("../materials/thick_scattering.toml"),
    ),
    (
        "scattering_slab",
        include_str!("../materials/scattering_slab.toml"),
    ),
    (
        "three_interfaces",
        include_str!("../materials/three_interfaces.toml"),
    ),
    ("validation1", include_str!("../materials/validation1.toml")),
    (
        "fibers_under_coat",
        include_str!("../materials/fibers_under_coat.toml"),
    ),
    ("jade", include_str!("../materials/jade.toml")),
];

/// The performance benchmarks' representative stacks: clear coat over
/// Lambertian; rough coat over copper with a tinted absorber; a thick
/// scattering medium under a rough coat; a transmissive scattering slab; a
/// three-interface stack.
pub const REPRESENTATIVE: &[&str] = &[
    "clear_coat_lambertian",
    "coated_copper",
    "thick_scattering",
    "scattering_slab",
    "three_interfaces",
];

/// The built-in stacks with a scattering medium whose phase function has a
/// closed form of the angle alone (Henyey–Greenstein or a mixture), from
/// least to most peaked: where the pdf's density walks may connect media
/// (`crates/strata-benches/benches/estimators.rs` times them).
pub const SCATTERING: &[&str] = &[
    "varnished_wood",
    "thick_scattering",
    "validation1",
    "scattering_slab",
    "jade",
];

/// The TOML text of a built-in material.
pub fn text(name: &str) -> Option<&'static str> {
    BUILTIN.iter().find(|(n, _)| *n == name).map(|&(_, t)| t)
}

/// A built-in material, built (`None` for an unknown name).
pub fn builtin(name: &str) -> Option<LayerStack> {
    text(name).map(|t| LayerStack::from_toml_str(t).expect("built-in materials are valid"))
}

#[cfg(test)]
mod tests {
    #[test]
    fn every_builtin_builds_and_the_representative_ones_exist() {
        for (name, _) in super::BUILTIN {
            assert!(super::builtin(name).is_some(), "{name}");
        }
        for name in super::REPRESENTATIVE.iter().chain(super::SCATTERING) {
            assert!(super::text(name).is_some(), "{name}");
        }
        assert!(super::builtin("nonexistent").is_none());
    }
}
