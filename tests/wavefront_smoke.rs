mod common;
use common::*;
use strata::estimator::scalar::ScalarEngine;
use strata::estimator::wavefront::{Plan, Wavefront};
use strata::lane::F32x8;
use strata::Settings;

const STACKS: &[(&str, &str)] = &[
    (
        "coat-lambert",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5 }
        [[layers]]
        interface = { kind = "diffuse", albedo = 0.8 }
    "#,
    ),
    (
        "rough-coat-cu-absorber",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5, roughness = 0.2 }
        medium = { thickness = 0.5, sigma_t = [0.2, 0.5, 1.0], albedo = 0.0 }
        [[layers]]
        interface = { kind = "conductor", preset = "Cu", roughness = 0.1 }
    "#,
    ),
    (
        "scatter-varnish",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5, roughness = 0.1 }
        medium = { thickness = 1.0, sigma_t = [1.0, 2.0, 3.0], albedo = [0.9, 0.8, 0.7], phase = { kind = "hg", g = 0.5 } }
        [[layers]]
        interface = { kind = "diffuse", albedo = [0.6, 0.4, 0.2] }
    "#,
    ),
    (
        "slab",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.4, roughness = 0.3 }
        medium = { thickness = 1.0, sigma_t = 2.0, albedo = 0.95, phase = { kind = "hg", g = 0.3 } }
        [[layers]]
        interface = { kind = "dielectric", ior = 1.0, roughness = 0.2 }
    "#,
    ),
    (
        "smooth-3",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5 }
        medium = { thickness = 0.5, sigma_t = 1.0, albedo = 0.9, phase = { kind = "hg", g = 0.7 } }
        [[layers]]
        interface = { kind = "dielectric", ior = 1.2 }
        medium = { thickness = 1.0, sigma_t = 2.0, albedo = 0.8 }
        [[layers]]
        interface = { kind = "conductor", preset = "Au" }
    "#,
    ),
];

#[test]
fn wavefront_matches_scalar() {
    let qs = [
        (dir(10.0, 0.0), dir(30.0, 120.0)),
        (dir(60.0, 0.0), dir(45.0, 180.0)),
        (dir(30.0, 0.0), dir(150.0, 40.0)),
    ];
    for (name, toml) in STACKS {
        let st = stack(toml);
        let sc = ScalarEngine::<f32>::new(&st, Settings::default());
        let wf = Wavefront::<F32x8>::new(&st, Settings::default(), Plan::Specialized);
        let keys: Vec<u64> = (0..qs.len() as u64).collect();
        let t0 = std::time::Instant::now();
        let (w, stats) = wf.eval_batch(&qs, 20000, 5, &keys);
        let tw = t0.elapsed();
        let t0 = std::time::Instant::now();
        for (k, &(wi, wo)) in qs.iter().enumerate() {
            let s = sc.eval(wi, wo, 20000, 5, k as u64);
            eprintln!(
                "{name} q{k}: scalar {:?} ± {:?}\n      wave   {:?} ± {:?}",
                s.value, s.stderr, w[k].value, w[k].stderr
            );
        }
        eprintln!(
            "{name}: scalar {:?} wave {:?} occupancy {:.3} segs {}",
            t0.elapsed(),
            tw,
            stats.occupancy(),
            stats.segments
        );
        let sa = sc.albedo(dir(20.0, 0.0), 50000, 3, 9);
        let (wa, _) = wf.albedo_batch(&[dir(20.0, 0.0)], 50000, 3, &[9]);
        eprintln!(
            "  albedo scalar R {:?} T {:?}\n         wave   R {:?} T {:?}",
            sa.reflected.value,
            sa.transmitted.value,
            wa[0].reflected.value,
            wa[0].transmitted.value
        );
    }
}
