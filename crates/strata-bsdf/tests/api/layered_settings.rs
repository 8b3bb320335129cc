//! The estimator's settings change its variance, never its expectation:
//! MIS on and off, and Russian roulette from the first event or much later,
//! estimate the same f (|z| < 4 on the difference of independent estimates).
//! A depth cap is the one biased option: it can only lose energy.
//!
//! With MIS off, next-event estimation takes every connection to a rough exit
//! and path continuation only those through delta vertices; with MIS on both
//! strategies contribute with power-heuristic weights. A missing or double
//! counted strategy shows up as a difference of the size of that strategy's
//! share, far above the error bars here (relative standard errors ~1%).

use crate::common;
use common::*;
use strata_bsdf::{LayeredBsdf, Settings};

const STACKS: [(&str, &str); 3] = [
    (
        "scattering varnish",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5, roughness = 0.3 }
        medium = { thickness = 1.0, sigma_t = [1.0, 2.0, 0.5], albedo = 0.9, phase = { kind = "hg", g = 0.5 } }
        [[layers]]
        interface = { kind = "diffuse", albedo = [0.6, 0.4, 0.2] }
        "#,
    ),
    (
        "rough slab",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5, roughness = 0.2 }
        medium = { thickness = 0.5, sigma_t = 1.0, albedo = 0.95 }
        [[layers]]
        interface = { kind = "dielectric", ior = 1.2, roughness = 0.5 }
        "#,
    ),
    (
        "3 interfaces",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.4, roughness = 0.4 }
        medium = { thickness = 0.3, sigma_t = 1.0, albedo = 0.9 }
        [[layers]]
        interface = { kind = "dielectric", ior = 1.8, roughness = 0.2 }
        [[layers]]
        interface = { kind = "conductor", preset = "Cu", roughness = 0.3 }
        "#,
    ),
];

/// (θi, φi, θo, φo): reflection and (for the slab) transmission.
const PAIRS: [(f64, f64, f64, f64); 4] = [
    (20.0, 0.0, 40.0, 180.0),
    (60.0, 0.0, 10.0, 90.0),
    (0.0, 0.0, 150.0, 0.0),
    (70.0, 0.0, 120.0, 200.0),
];

fn agree(a: Settings, b: Settings, what: &str) {
    for (s, (label, toml)) in STACKS.into_iter().enumerate() {
        let st = stack(toml);
        let (ea, eb) = (Walks::new(&st, a), Walks::new(&st, b));
        for (q, &(ti, pi, to, po)) in PAIRS.iter().enumerate() {
            if to > 90.0 && !st.transmissive() {
                continue;
            }
            let (wi, wo) = (dir(ti, pi), dir(to, po));
            let key = (s * 10 + q) as u64;
            let x = ea.eval(wi, wo, 30_000, 1, key);
            let y = eb.eval(wi, wo, 30_000, 2, key);
            for c in 0..3 {
                let z = (x.value[c] - y.value[c]) / x.stderr[c].hypot(y.stderr[c]);
                eprintln!(
                    "{what} {label} {ti}->{to} ch {c}: {:.5e} vs {:.5e} (z {z:+.2})",
                    x.value[c], y.value[c]
                );
                assert!(
                    x.value[c] > 0.0 && x.stderr[c] < 0.05 * x.value[c],
                    "{label}: {x:?}"
                );
                assert!(
                    z.abs() < 4.0,
                    "{what} {label} {ti}->{to} ch {c}: {x:?} vs {y:?} (|z| = {:.2})",
                    z.abs()
                );
            }
        }
    }
}

#[test]
fn mis_on_and_off_agree() {
    let on = Settings::default();
    let off = Settings { mis: false, ..on };
    agree(on, off, "mis on/off");
}

#[test]
fn russian_roulette_start_does_not_bias() {
    let early = Settings {
        rr_start: 0,
        ..Settings::default()
    };
    let late = Settings {
        rr_start: 64,
        ..Settings::default()
    };
    agree(early, late, "rr 0/64");
}

/// A depth cap only removes paths: the capped albedo is at most the uncapped
/// one, and strictly lower on a stack with long paths.
#[test]
fn depth_cap_only_loses_energy() {
    let st = stack(STACKS[0].1);
    let full = Walks::new(&st, Settings::default());
    let capped = Walks::new(
        &st,
        Settings {
            max_events: 3,
            ..Settings::default()
        },
    );
    let wi = dir(30.0, 0.0);
    let a = full.albedo(wi, 50_000, 1, 1);
    let b = capped.albedo(wi, 50_000, 2, 1);
    for c in 0..3 {
        let (x, sx) = (a.reflected.value[c], a.reflected.stderr[c]);
        let (y, sy) = (b.reflected.value[c], b.reflected.stderr[c]);
        let z = (x - y) / sx.hypot(sy);
        assert!(z > 5.0, "ch {c}: capped {y} ± {sy} not below {x} ± {sx}");
    }
}

/// `LayeredBsdf::max_events` sets the walks' limit: the answers of a BSDF
/// built with those settings, bit for bit, and limits outside `1..=2^24`
/// are taken at the nearest end.
#[test]
fn max_events_is_the_walk_setting() {
    use strata_bsdf::estimator::events::{MAX_CAP, MAX_EVENTS};
    let st = stack(STACKS[0].1);
    let set = LayeredBsdf::new(st.clone()).max_events(3);
    let built = LayeredBsdf::with_settings(
        st.clone(),
        Settings {
            max_events: 3,
            ..Settings::default()
        },
    );
    assert_eq!(
        LayeredBsdf::new(st.clone()).settings().max_events,
        MAX_EVENTS
    );
    assert_eq!(set.settings().max_events, 3);
    let wi = glam::Vec3::from(dir(30.0, 0.0).map(|x| x as f32));
    let (a, b) = (
        set.albedo(wi, 20_000).unwrap(),
        built.albedo(wi, 20_000).unwrap(),
    );
    assert_eq!(a, b);
    let full = LayeredBsdf::new(st.clone()).albedo(wi, 20_000).unwrap();
    let (x, sx) = (full.reflected.value[0], full.reflected.stderr[0]);
    let (y, sy) = (a.reflected.value[0], a.reflected.stderr[0]);
    assert!(
        (x - y) / sx.hypot(sy) > 5.0,
        "3 events {y} ± {sy}, default {x} ± {sx}"
    );
    let ends = [(0, 1), (u32::MAX, MAX_CAP)];
    for (n, taken) in ends {
        let b = LayeredBsdf::new(st.clone()).max_events(n);
        assert_eq!(b.settings().max_events, taken, "max_events({n})");
    }
}
