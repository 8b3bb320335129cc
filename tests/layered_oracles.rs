//! The layered estimators against closed forms (method.md §8).

mod common;
use common::*;
use strata::estimator::scalar::ScalarEngine;
use strata::Settings;

/// Unpolarized Fresnel reflectance, written independently of the crate:
/// light in a medium of IOR `n1` hitting one of IOR `n2` at cosine `ci`.
fn fresnel(ci: f64, n1: f64, n2: f64) -> f64 {
    let s2t = (n1 / n2).powi(2) * (1.0 - ci * ci);
    if s2t >= 1.0 {
        return 1.0;
    }
    let ct = (1.0 - s2t).sqrt();
    let rs = (n1 * ci - n2 * ct) / (n1 * ci + n2 * ct);
    let rp = (n2 * ci - n1 * ct) / (n2 * ci + n1 * ct);
    0.5 * (rs * rs + rp * rp)
}

/// Cosine-weighted hemispherical average of the internal reflectance.
fn fbar_inside(eta: f64) -> f64 {
    let n = 200_000;
    let mut s = 0.0;
    for k in 0..n {
        // ∫ F(μ) 2μ dμ over μ in (0,1), midpoint rule.
        let mu = (k as f64 + 0.5) / n as f64;
        s += fresnel(mu, eta, 1.0) * 2.0 * mu / n as f64;
    }
    s
}

#[test]
fn smooth_coat_over_lambertian_matches_closed_form() {
    for (eta, rho) in [(1.5, 0.8), (1.33, 0.5), (2.0, 1.0)] {
        let st = stack(&format!(
            r#"
            [[layers]]
            interface = {{ kind = "dielectric", ior = {eta} }}
            [[layers]]
            interface = {{ kind = "diffuse", albedo = {rho} }}
            "#
        ));
        let eng = ScalarEngine::<f32>::new(&st, Settings::default());
        let fb = fbar_inside(eta);
        for (ti, to, po) in [(0.0, 30.0, 90.0), (45.0, 60.0, 180.0), (80.0, 10.0, 0.0)] {
            let wi = dir(ti, 0.0);
            let wo = dir(to, po);
            let exact = (1.0 - fresnel(wi[2], 1.0, eta)) * (1.0 - fresnel(wo[2], 1.0, eta)) * rho
                / (std::f64::consts::PI * eta * eta * (1.0 - rho * fb));
            let e = eng.eval(wi, wo, 400_000, 1, 7 + (ti as u64) * 1000 + to as u64);
            for c in 0..3 {
                assert_z(
                    &format!("eta {eta} rho {rho} θi {ti} θo {to} ch {c}"),
                    e.value[c],
                    exact,
                    e.stderr[c],
                    4.0,
                    1e-5 * exact,
                );
            }
            eprintln!(
                "eta {eta} rho {rho} {ti} {to}: {} ± {} vs {exact}",
                e.value[0], e.stderr[0]
            );
        }
    }
}
