//! The estimator's settings change its variance, never its expectation:
//! MIS on and off, Russian roulette from the first event or much later, and
//! its threshold,
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

/// The roulette's threshold changes who survives, not the expectation: the
/// classic rule (survival `min(1, throughput)`) and a low threshold agree.
#[test]
fn russian_roulette_threshold_does_not_bias() {
    let classic = Settings {
        rr_threshold: 1.0,
        ..Settings::default()
    };
    let low = Settings {
        rr_threshold: 0.1,
        ..Settings::default()
    };
    agree(classic, low, "rr threshold 1/0.1");
}

/// Below the threshold fewer walks end early: on a high-albedo layer one
/// walk's reflected albedo has less variance under a threshold of 0.25 than
/// under the classic rule (the lever of `Settings::rr_threshold`), and the
/// two agree.
#[test]
fn a_lower_roulette_threshold_lowers_the_variance_of_one_walk() {
    let st = stack(STACKS[0].1);
    let classic = Walks::new(
        &st,
        Settings {
            rr_threshold: 1.0,
            ..Settings::default()
        },
    );
    let low = Walks::new(
        &st,
        Settings {
            rr_threshold: 0.25,
            ..Settings::default()
        },
    );
    let wi = dir(30.0, 0.0);
    let n = 100_000;
    let a = classic.albedo(wi, n, 1, 7);
    let b = low.albedo(wi, n, 2, 7);
    let (mut va, mut vb) = (0.0, 0.0);
    for c in 0..3 {
        let (x, sx) = (a.reflected.value[c], a.reflected.stderr[c]);
        let (y, sy) = (b.reflected.value[c], b.reflected.stderr[c]);
        let z = (x - y) / sx.hypot(sy);
        assert!(z.abs() < 4.0, "ch {c}: classic {x} ± {sx}, 0.25 {y} ± {sy}");
        // The standard error of a standard error of 1e5 walks is under
        // 0.5 % of it for these bounded weights.
        assert!(
            sy < sx,
            "ch {c}: 0.25's error {sy} not below classic's {sx}"
        );
        (va, vb) = (va + sx * sx, vb + sy * sy);
    }
    // Most where the throughput stays high (the bright channel): in all,
    // a quarter less variance.
    assert!(
        vb < 0.85 * va,
        "variance {vb:.3e} under 0.25, {va:.3e} classic"
    );
}

/// `LayeredBsdf::rr_threshold` sets the walks' threshold, taken in
/// `[MIN_RR_THRESHOLD, 1]` with NaN as 1: the answers of a BSDF built with
/// those settings, bit for bit.
#[test]
fn rr_threshold_is_the_walk_setting() {
    use strata_bsdf::estimator::events::{rr_threshold, MIN_RR_THRESHOLD};
    let taken = |t: f64| {
        rr_threshold(&Settings {
            rr_threshold: t,
            ..Settings::default()
        })
    };
    assert_eq!(taken(0.3), 0.3);
    assert_eq!(taken(0.0), MIN_RR_THRESHOLD);
    assert_eq!(taken(-1.0), MIN_RR_THRESHOLD);
    assert_eq!(taken(7.0), 1.0);
    assert_eq!(taken(f64::NAN), 1.0);
    let st = stack(STACKS[0].1);
    let set = LayeredBsdf::new(st.clone()).rr_threshold(0.3).samples(64);
    let built = LayeredBsdf::with_settings(
        st,
        Settings {
            rr_threshold: 0.3,
            ..Settings::default()
        },
    )
    .samples(64);
    assert_eq!(set.settings().rr_threshold, 0.3);
    let (wi, wo) = (
        glam::Vec3::new(0.3, 0.0, 0.95),
        glam::Vec3::new(-0.2, 0.1, 0.97),
    );
    assert_eq!(set.eval(wi, wo).unwrap(), built.eval(wi, wo).unwrap());
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
