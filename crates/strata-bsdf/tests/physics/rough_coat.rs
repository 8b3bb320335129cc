//! The factorized estimator of a rough coat over a clear or absorbing layer
//! over a Lambertian base (`estimator::rough_coat`), with which
//! `Estimator::Auto` answers such stacks' eval without walks:
//! `f = f_coat + (n0/n1)² ρ A(wi) A(wo) / (π (1 − ρ R̄))`, `A` sampled by the
//! coat's transmission, `R̄` by quadrature (`estimator::coat_return`, whose
//! own tests check it against the walks' sampler).
//!
//! * Unbiased: on ten stacks of that shape (roughness 0.01–0.8, GGX and
//!   Beckmann, correlated and separable shadowing, coat IOR 1.3–2.2, no
//!   layer, grey and chromatic absorbers up to optical depth 3, white and
//!   coloured bases, a denser and a lighter exterior, two-sided lit from
//!   below), at six direction pairs each (normal, oblique, the specular
//!   peak, grazing light, grazing view, both grazing), it agrees with the
//!   plain unidirectional walks, which know nothing of the factorization,
//!   within 4 combined standard errors per channel (independent seeds; 183
//!   comparisons, a false alarm about 1.2 % for a random seed, seeds fixed).
//! * Its standard error is the spread of independent estimates.
//! * A nearly smooth coat gives the smooth closed form.
//! * The two engines give the same bits (it runs no walk), and keys drive
//!   its streams as they drive walks'.

use crate::common;
use crate::common::batches::Batches;
use common::*;
use strata_bsdf::estimator::closed_form::SmoothCoatLambertian;
use strata_bsdf::{Engine, Estimator, LayeredBsdf, Settings};

const STACKS: &[(&str, &str)] = &[
    (
        "pbrt-v4's rough coat over a weak absorber",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5, roughness = 0.1 }
        medium = { thickness = 0.01, sigma_t = 1.0, albedo = 0.0 }
        [[layers]]
        interface = { kind = "diffuse", albedo = 0.8 }
        "#,
    ),
    (
        "α 0.01, no layer, white base",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5, roughness = 0.01 }
        [[layers]]
        interface = { kind = "diffuse", albedo = 1.0 }
        "#,
    ),
    (
        "α 0.3, IOR 2.2, chromatic absorber τ 0.1–2, coloured base",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 2.2, roughness = 0.3 }
        medium = { thickness = 1.0, sigma_t = [0.1, 0.5, 2.0], albedo = 0.0 }
        [[layers]]
        interface = { kind = "diffuse", albedo = [0.9, 0.5, 0.2] }
        "#,
    ),
    (
        "α 0.8, IOR 1.3, τ 1",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.3, roughness = 0.8 }
        medium = { thickness = 0.5, sigma_t = 2.0, albedo = 0.0 }
        [[layers]]
        interface = { kind = "diffuse", albedo = 0.7 }
        "#,
    ),
    (
        "α 0.2 Beckmann, τ 0.3",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5, roughness = 0.2, distribution = "beckmann" }
        medium = { thickness = 0.3, sigma_t = 1.0, albedo = 0.0 }
        [[layers]]
        interface = { kind = "diffuse", albedo = 0.6 }
        "#,
    ),
    (
        "α 0.25 separable, IOR 1.7",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.7, roughness = 0.25, shadowing = "separable" }
        medium = { thickness = 0.2, sigma_t = 1.0, albedo = 0.0 }
        [[layers]]
        interface = { kind = "diffuse", albedo = 0.9 }
        "#,
    ),
    (
        "α 0.15, water above (exterior IOR 1.33)",
        r#"
        exterior_ior = 1.33
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5, roughness = 0.15 }
        medium = { thickness = 0.1, sigma_t = 1.0, albedo = 0.0 }
        [[layers]]
        interface = { kind = "diffuse", albedo = 0.8 }
        "#,
    ),
    (
        "α 0.2, coat lighter than the exterior (1.3 under 1.5)",
        r#"
        exterior_ior = 1.5
        [[layers]]
        interface = { kind = "dielectric", ior = 1.3, roughness = 0.2 }
        [[layers]]
        interface = { kind = "diffuse", albedo = 0.8 }
        "#,
    ),
    (
        "α 0.1, two-sided, IOR 1.8, τ 0.05",
        r#"
        two_sided = true
        [[layers]]
        interface = { kind = "dielectric", ior = 1.8, roughness = 0.1 }
        medium = { thickness = 0.05, sigma_t = 1.0, albedo = 0.0 }
        [[layers]]
        interface = { kind = "diffuse", albedo = [0.2, 0.4, 0.8] }
        "#,
    ),
    (
        "α 0.05, thick absorber τ 3",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5, roughness = 0.05 }
        medium = { thickness = 3.0, sigma_t = 1.0, albedo = 0.0 }
        [[layers]]
        interface = { kind = "diffuse", albedo = 0.9 }
        "#,
    ),
];

/// Direction pairs (θi, φi, θo, φo) in degrees, above the coat.
const PAIRS: [(f64, f64, f64, f64); 6] = [
    (0.0, 0.0, 0.0, 0.0),
    (30.0, 0.0, 45.0, 180.0),
    (40.0, 0.0, 40.0, 180.0),
    (85.0, 0.0, 0.0, 0.0),
    (0.0, 0.0, 85.0, 0.0),
    (80.0, 10.0, 75.0, 200.0),
];

fn pairs(two_sided: bool) -> Vec<(glam::Vec3, glam::Vec3)> {
    let mut p: Vec<_> = PAIRS
        .iter()
        .map(|&(ti, pi, to, po)| (vec3(dir(ti, pi)), vec3(dir(to, po))))
        .collect();
    if two_sided {
        // Lit from below: the stack is mirrored.
        let below = |w: [f64; 3]| vec3([w[0], w[1], -w[2]]);
        p.push((below(dir(20.0, 0.0)), below(dir(70.0, 90.0))));
    }
    p
}

#[test]
fn the_factorization_agrees_with_the_walks() {
    for (s, (name, toml)) in STACKS.iter().enumerate() {
        let st = stack(toml);
        let auto = LayeredBsdf::new(st.clone()).seed(100 + s as u64);
        assert!(
            auto.eval_without_walks() && !auto.eval_is_exact(),
            "{name}: not the factorization's shape"
        );
        let plain = LayeredBsdf::new(st.clone())
            .estimator(Estimator::Unidirectional)
            .engine(Engine::Wavefront)
            .seed(200 + s as u64);
        assert!(!plain.eval_without_walks());
        let p = pairs(st.two_sided());
        let keys: Vec<u64> = (0..p.len() as u64).collect();
        let a = plain.eval_batch_keyed(&p, 1 << 18, &keys).unwrap();
        let b = auto.eval_batch_keyed(&p, 1 << 14, &keys).unwrap();
        for (q, (a, b)) in a.iter().zip(&b).enumerate() {
            for c in 0..3 {
                let what = format!("{name}, pair {q}, channel {c}");
                let se = a.stderr[c].hypot(b.stderr[c]);
                let z = (b.value[c] - a.value[c]) / se;
                eprintln!(
                    "{what}: factorized {:.5e} ± {:.1e}, walks {:.5e} ± {:.1e} (z {z:+.2})",
                    b.value[c], b.stderr[c], a.value[c], a.stderr[c]
                );
                assert!(
                    a.stderr[c] < 0.03 * a.value[c],
                    "{what}: imprecise walks {} ± {}",
                    a.value[c],
                    a.stderr[c]
                );
                assert!(z.abs() < 4.0, "{what}: |z| = {:.2}", z.abs());
            }
        }
    }
}

/// The standard error it reports is the spread of independent estimates
/// (its samples are independent, within a query and across keys): 1000
/// estimates of 64 samples each, the sample deviation of their values
/// against the root mean square of the reported standard errors, within
/// 15 % (the deviation of 1000 values is itself uncertain by a few per
/// cent: rare samples that the coat lets through at no direction, zeros,
/// make the samples' distribution skewed).
#[test]
fn its_standard_error_is_the_spread_of_estimates() {
    let bsdf = LayeredBsdf::new(stack(STACKS[0].1));
    for &(ti, pi, to, po) in &[(30.0, 0.0, 45.0, 180.0), (85.0, 0.0, 0.0, 0.0)] {
        let (wi, wo) = (vec3(dir(ti, pi)), vec3(dir(to, po)));
        let m = 1000;
        let est: Vec<_> = (0..m)
            .map(|k| bsdf.eval_with(wi, wo, 64, k).unwrap())
            .collect();
        let mean = est.iter().map(|e| e.value[0]).sum::<f64>() / m as f64;
        let var = est.iter().map(|e| (e.value[0] - mean).powi(2)).sum::<f64>() / (m - 1) as f64;
        let se2 = est.iter().map(|e| e.stderr[0].powi(2)).sum::<f64>() / m as f64;
        let se = se2.sqrt();
        let ratio = var.sqrt() / se;
        eprintln!(
            "θi {ti} θo {to}: spread {:.3e}, stderr {se:.3e}, ratio {ratio:.3}",
            var.sqrt()
        );
        assert!((0.85..1.15).contains(&ratio), "θi {ti}: ratio {ratio}");
    }
}

/// With roughness 0.001 the coat is nearly a mirror: off the specular
/// direction its value is the smooth closed form's, within 0.2 % (what the
/// roughness itself moves; 4 standard errors besides).
#[test]
fn a_nearly_smooth_coat_gives_the_closed_form() {
    let toml = |alpha: &str| {
        format!(
            "[[layers]]\ninterface = {{ kind = \"dielectric\", ior = 1.6{alpha} }}\n\
             medium = {{ thickness = 0.4, sigma_t = [0.2, 0.6, 1.0], albedo = 0.0 }}\n\
             [[layers]]\ninterface = {{ kind = \"diffuse\", albedo = [0.9, 0.6, 0.3] }}\n"
        )
    };
    let smooth = SmoothCoatLambertian::of(&stack(&toml("")), &Settings::default()).unwrap();
    let rough = LayeredBsdf::new(stack(&toml(", roughness = 0.001"))).samples(1 << 14);
    for &(ti, pi, to, po) in &[
        (30.0, 0.0, 45.0, 180.0),
        (60.0, 0.0, 20.0, 90.0),
        (0.0, 0.0, 70.0, 0.0),
    ] {
        let (wi, wo) = (dir(ti, pi), dir(to, po));
        let want = smooth.eval(wi, wo);
        let got = rough.eval(vec3(wi), vec3(wo)).unwrap();
        for (c, want) in want.into_iter().enumerate() {
            let (v, se) = (got.value[c], got.stderr[c]);
            let tol = 2e-3 * want + 4.0 * se;
            assert!(
                (v - want).abs() < tol,
                "θi {ti} θo {to} channel {c}: {v} ± {se} against {want}"
            );
        }
    }
}

/// It runs no walk, so the engine changes nothing (both route it to the
/// same code: this checks the routing, and a large batch's parallel path
/// against single queries); a key gives the same answer whatever the batch,
/// and different keys give different noise.
#[test]
fn engines_and_keys() {
    let st = stack(STACKS[2].1);
    let p = pairs(false);
    let keys: Vec<u64> = (0..p.len() as u64).map(|k| 7 * k + 1).collect();
    let scalar = LayeredBsdf::new(st.clone())
        .engine(Engine::Scalar)
        .samples(300);
    let wave = LayeredBsdf::new(st.clone())
        .engine(Engine::Wavefront)
        .samples(300);
    let a = scalar.eval_batch_keyed(&p, 300, &keys).unwrap();
    let b = wave.eval_batch_keyed(&p, 300, &keys).unwrap();
    assert_eq!(a, b);
    for (k, e) in a.iter().enumerate() {
        let one = wave.eval_with(p[k].0, p[k].1, 300, keys[k]).unwrap();
        assert_eq!(*e, one, "pair {k}");
        let other = wave.eval_with(p[k].0, p[k].1, 300, keys[k] + 1).unwrap();
        assert_ne!(e.value, other.value, "pair {k}");
        assert!(
            e.stderr.iter().all(|&s| s > 0.0),
            "pair {k}: a sampled estimate"
        );
    }
}
