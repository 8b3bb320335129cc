//! A stack of one interface: the layered estimator must return exactly that
//! interface's BSDF (method.md §8, limits), with zero variance: no walk can
//! come back after leaving the single interface, so every contribution is the
//! deterministic first-order term.
//!
//! Two comparisons per direction pair:
//! * against `InterfaceLanes::eval` of the same interface, computed in the
//!   test: equal to f32 rounding (relative 1e-6), standard error exactly 0;
//! * against independent f64 formulas (`common::reference`: Walter et al. 2007
//!   GGX reflection and transmission with the n_b² radiance factor, complex
//!   conductor Fresnel with the IOR relative to the region above, Lambert),
//!   relative 1e-4 (the engine runs in f32).
//!
//! Directions cover both hemispheres for wi and wo (reflection and
//! transmission, light from above and from below), from near-normal to 89°.

use crate::common;
use common::reference::{rough_conductor, rough_dielectric};
use common::*;
use strata_bsdf::estimator::scalar::{Scalar, ScalarEngine};
use strata_bsdf::lane::V3;
use strata_bsdf::{LayerStack, LayeredBsdf, Settings};

/// A grid of directions on both hemispheres.
fn directions() -> Vec<[f64; 3]> {
    let mut v = Vec::new();
    for theta in [3.0, 30.0, 55.0, 80.0, 89.0] {
        for phi in [0.0, 100.0, 180.0, 250.0] {
            v.push(dir(theta, phi));
            v.push(dir(180.0 - theta, phi + 15.0));
        }
    }
    v
}

fn v3<S: Scalar>(w: [f64; 3]) -> V3<S> {
    V3::new(S::splat(w[0]), S::splat(w[1]), S::splat(w[2]))
}

/// An independent reference: `f(wi, wo)` per channel.
type Reference<'a> = dyn Fn([f64; 3], [f64; 3]) -> [f64; 3] + 'a;

/// Checks the engine against the interface's own `eval` and, where given, an
/// independent reference per channel. Returns the number of non-zero values.
fn check<S: Scalar>(st: &LayerStack, label: &str, reference: Option<&Reference>) -> usize {
    let eng = ScalarEngine::<S>::new(st, Settings::default());
    let it = st.interface_lanes::<S>(0);
    let mut nonzero = 0;
    let dirs = directions();
    for (i, &wi) in dirs.iter().enumerate() {
        for (j, &wo) in dirs.iter().enumerate() {
            let e = eng.eval(wi, wo, 8, 1, (i * 1000 + j) as u64);
            let f = it.eval(v3(wi), v3(wo));
            let lanes = [f.r.lane(0), f.g.lane(0), f.b.lane(0)];
            let r = reference.map(|r| r(wi, wo));
            for c in 0..3 {
                let what = format!("{label} wi {wi:?} wo {wo:?} ch {c}");
                assert_eq!(e.stderr[c], 0.0, "{what}: {e:?}");
                let tol = 1e-6 * lanes[c].abs() + 1e-30;
                assert!(
                    (e.value[c] - lanes[c]).abs() <= tol,
                    "{what}: engine {} vs interface {}",
                    e.value[c],
                    lanes[c]
                );
                if let Some(r) = r {
                    // f32 engines to rounding of f32; the f64 engine far tighter.
                    let rel = if std::mem::size_of::<S>() == 8 {
                        1e-9
                    } else {
                        1e-4
                    };
                    let tol = rel * r[c] + 1e-6 * rel / 1e-4;
                    assert!(
                        (e.value[c] - r[c]).abs() <= tol,
                        "{what}: engine {} vs reference {}",
                        e.value[c],
                        r[c]
                    );
                }
                if e.value[c] > 0.0 {
                    nonzero += 1;
                }
            }
        }
    }
    nonzero
}

#[test]
fn rough_dielectric_alone_is_the_interface() {
    for (n0, n1, alpha) in [(1.0, 1.5, 0.3), (1.2, 1.7, 0.08), (1.5, 1.0, 0.6)] {
        let st = stack(&format!(
            r#"
            exterior_ior = {n0}
            [[layers]]
            interface = {{ kind = "dielectric", ior = {n1}, roughness = {alpha} }}
            "#
        ));
        let reference = |a: [f64; 3], b: [f64; 3]| [rough_dielectric(alpha, n0, n1, a, b); 3];
        let label = format!("dielectric {n0}/{n1} α {alpha}");
        let nz = check::<f32>(&st, &label, Some(&reference));
        let nz64 = check::<f64>(&st, &label, Some(&reference));
        // Reflection and transmission on both sides: most pairs are non-zero.
        assert!(
            nz > 3 * 800 && nz == nz64,
            "{label}: {nz} / {nz64} non-zero values"
        );
    }
}

#[test]
fn rough_conductor_alone_is_the_interface() {
    // A preset, and explicit values under an exterior of IOR 1.3: the complex
    // IOR is relative to the region above.
    let cu = strata_bsdf::stack::presets::conductor("Cu").expect("preset");
    for (n0, eta, k, alpha) in [
        (1.0, cu.0, cu.1, 0.25),
        (1.3, [0.2, 1.1, 1.6], [3.9, 2.4, 0.0], 0.5),
    ] {
        let desc = if n0 == 1.0 {
            r#"{ kind = "conductor", preset = "Cu", roughness = 0.25 }"#.to_string()
        } else {
            format!(r#"{{ kind = "conductor", eta = {eta:?}, k = {k:?}, roughness = {alpha} }}"#)
        };
        let st = stack(&format!(
            "exterior_ior = {n0}\n[[layers]]\ninterface = {desc}\n"
        ));
        let reference = |a: [f64; 3], b: [f64; 3]| {
            [0, 1, 2].map(|c| rough_conductor(alpha, eta[c] / n0, k[c] / n0, a, b))
        };
        let label = format!("conductor n0 {n0} α {alpha}");
        let nz = check::<f32>(&st, &label, Some(&reference));
        check::<f64>(&st, &label, Some(&reference));
        // Only light from above, reflected: a quarter of the pairs.
        assert!(nz > 3 * 350, "{label}: {nz} non-zero values");
    }
}

#[test]
fn diffuse_alone_is_the_interface() {
    let st = stack(
        r#"
        [[layers]]
        interface = { kind = "diffuse", albedo = [0.2, 0.5, 0.9] }
        "#,
    );
    let reference = |a: [f64; 3], b: [f64; 3]| {
        let up = a[2] > 0.0 && b[2] > 0.0;
        [0.2, 0.5, 0.9].map(|r| if up { r / std::f64::consts::PI } else { 0.0 })
    };
    let nz = check::<f32>(&st, "diffuse", Some(&reference));
    assert_eq!(nz, 3 * 400);
}

/// Interfaces the independent reference does not cover: anisotropic GGX,
/// Beckmann, separable shadowing. The engine must still return the interface.
#[test]
fn other_microfacet_models_alone_are_the_interface() {
    for iface in [
        r#"{ kind = "dielectric", ior = 1.45, roughness = [0.1, 0.4] }"#,
        r#"{ kind = "dielectric", ior = 1.45, roughness = 0.3, distribution = "beckmann" }"#,
        r#"{ kind = "dielectric", ior = 2.0, roughness = 0.2, shadowing = "separable" }"#,
        r#"{ kind = "conductor", preset = "Au", roughness = [0.5, 0.05] }"#,
        r#"{ kind = "conductor", preset = "Al", roughness = 0.2, distribution = "beckmann" }"#,
    ] {
        let st = stack(&format!("[[layers]]\ninterface = {iface}\n"));
        let nz = check::<f32>(&st, iface, None);
        assert!(nz > 3 * 300, "{iface}: {nz} non-zero values");
    }
}

/// Smooth interfaces are pure delta lobes, which `eval` never returns.
#[test]
fn smooth_interface_alone_evaluates_to_zero() {
    for iface in [
        r#"{ kind = "dielectric", ior = 1.5 }"#,
        r#"{ kind = "conductor", preset = "Cu" }"#,
    ] {
        let st = stack(&format!("[[layers]]\ninterface = {iface}\n"));
        let nz = check::<f32>(&st, iface, Some(&|_, _| [0.0; 3]));
        assert_eq!(nz, 0);
    }
}

/// An opaque one-sided interface sees nothing from below; a two-sided one
/// mirrors both directions so its top faces the light.
#[test]
fn opaque_interface_from_below() {
    let one = stack(
        "[[layers]]\ninterface = { kind = \"conductor\", preset = \"Cu\", roughness = 0.3 }\n",
    );
    let two = stack(
        "two_sided = true\n[[layers]]\ninterface = { kind = \"conductor\", preset = \"Cu\", roughness = 0.3 }\n",
    );
    let e1 = Walks::new(&one, Settings::default());
    let e2 = Walks::new(&two, Settings::default());
    let mirror = |w: [f64; 3]| [w[0], w[1], -w[2]];
    let (wi, wo) = (dir(150.0, 0.0), dir(120.0, 200.0));
    assert_eq!(e1.eval(wi, wo, 8, 1, 1).value, [0.0; 3]);
    let below = e2.eval(wi, wo, 8, 1, 1);
    let above = e2.eval(mirror(wi), mirror(wo), 8, 1, 1);
    assert!(above.value[0] > 0.0);
    assert_eq!(below.value, above.value);
    // And through the public API.
    let bsdf = LayeredBsdf::new(two);
    let api = bsdf.eval(vec3(wi), vec3(wo)).expect("valid directions");
    for c in 0..3 {
        assert!((api.value[c] - above.value[c]).abs() <= 1e-5 * above.value[c]);
    }
}
