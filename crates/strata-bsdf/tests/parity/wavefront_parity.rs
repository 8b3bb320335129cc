//! The wavefront engine against the scalar reference.
//!
//! * Walk by walk: for the same seeds, lane `j` of the wavefront replays
//!   scalar walk `j` (same kernels, same uniforms in the same order), so the
//!   per-walk values are compared bit for bit, every walk. Both engines use
//!   the same f32 operations, no FMA, and the same transcendental code, so no
//!   rounding difference can flip a branch. (The issue allows a tiny fraction
//!   of flipped walks; a budget of 0.1 % was tried and hid a real bug: a
//!   task's last few deferred continuations dropped, 3 walks of 3072.)
//! * Statistically: with independent seeds, the means agree within 4.5
//!   standard errors (the combined standard error of the two estimates) over
//!   every stack, query and channel.
//! * Determinism: 1, 2 and 4 threads, any wave size, any batch composition
//!   and the 16-lane width give bit-identical results.
//! * Specialization: the general walk (every stage for every walk) agrees
//!   with the specialized one within standard errors.

use crate::common;
use common::*;
use strata_bsdf::estimator::scalar::ScalarEngine;
use strata_bsdf::estimator::wavefront::{Plan, Wavefront};
use strata_bsdf::lane::{F32x16, F32x8};
use strata_bsdf::rng::{Stream, WalkRng};
use strata_bsdf::{LayerStack, PdfKind, PdfWalks, Settings};

/// Every interface kind (smooth and rough, GGX and Beckmann, isotropic and
/// anisotropic), every medium kind (clear, absorbing, scattering; grey and
/// chromatic), reflection and transmission, a two-sided opaque stack,
/// tilted shading normals, and SGGX and mixture phase functions.
const STACKS: &[(&str, &str)] = &[
    (
        "clear coat over Lambertian",
        crate::common::SMOOTH_COAT_OVER_DIFFUSE,
    ),
    (
        "rough coat over copper, tinted absorber",
        crate::common::ROUGH_COAT_ABSORBER_COPPER,
    ),
    (
        "scattering varnish, chromatic",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5, roughness = 0.1 }
        medium = { thickness = 1.0, sigma_t = [1.0, 2.0, 3.0], albedo = [0.9, 0.8, 0.7], phase = { kind = "hg", g = 0.5 } }
        [[layers]]
        interface = { kind = "diffuse", albedo = [0.6, 0.4, 0.2] }
        "#,
    ),
    (
        "transmissive slab",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.4, roughness = 0.3 }
        medium = { thickness = 1.0, sigma_t = 2.0, albedo = 0.95, phase = { kind = "hg", g = 0.3 } }
        [[layers]]
        interface = { kind = "dielectric", ior = 1.0, roughness = 0.2 }
        "#,
    ),
    (
        "smooth three-interface stack (adjoint chains)",
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
    (
        "Beckmann anisotropic, separable, over a smooth transmissive bottom",
        r#"
        exterior_ior = 1.0
        [[layers]]
        interface = { kind = "dielectric", ior = 1.6, roughness = [0.05, 0.3], distribution = "beckmann", shadowing = "separable" }
        medium = { thickness = 0.3, sigma_t = 3.0, albedo = 0.99 }
        [[layers]]
        interface = { kind = "dielectric", ior = 1.33 }
        "#,
    ),
    (
        "thick scattering layer under a rough coat, two-sided",
        r#"
        two_sided = true
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5, roughness = 0.3 }
        medium = { thickness = 10.0, sigma_t = 1.0, albedo = 0.99, phase = { kind = "hg", g = 0.2 } }
        [[layers]]
        interface = { kind = "conductor", preset = "Al", roughness = 0.4 }
        "#,
    ),
    (
        "tilted normals: smooth coat, scattering layer, rough inner interface, rough gold; two-sided",
        r#"
        two_sided = true
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5, normal = [0.2, 0.1, 1] }
        medium = { thickness = 0.5, sigma_t = [0.5, 1.0, 1.5], albedo = 0.8, phase = { kind = "hg", g = 0.4 } }
        [[layers]]
        interface = { kind = "dielectric", ior = 1.3, roughness = 0.2, normal = [-0.3, 0.0, 1] }
        [[layers]]
        interface = { kind = "conductor", preset = "Au", roughness = [0.1, 0.3], normal = [0.0, 0.25, 1] }
        "#,
    ),
    (
        "tilted normals: rough transmissive slab",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.4, roughness = 0.3, normal = [0.15, -0.1, 1] }
        medium = { thickness = 1.0, sigma_t = 1.0, albedo = 0.9 }
        [[layers]]
        interface = { kind = "dielectric", ior = 1.0, normal = [0.0, 0.3, 1] }
        "#,
    ),
    (
        "SGGX fibres (specular), chromatic, under a rough coat",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5, roughness = 0.2 }
        medium = { thickness = 1.0, sigma_t = [1.0, 2.0, 3.0], albedo = 0.9, phase = { kind = "sggx", flakes = "fiber", axis = [0.8, 0.0, 0.6], roughness = 0.3 } }
        [[layers]]
        interface = { kind = "diffuse", albedo = 0.5 }
        "#,
    ),
    (
        "SGGX diffuse surface flakes in a transmissive slab, a mixture below",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.3, roughness = 0.25 }
        medium = { thickness = 1.0, sigma_t = 1.5, albedo = 0.95, phase = { kind = "sggx", flakes = "surface", axis = [0.0, 0.6, 0.8], roughness = 0.2, scattering = "diffuse" } }
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5, roughness = 0.1 }
        medium = { thickness = 1.0, sigma_t = 1.0, albedo = 0.8, phase = { kind = "mixture", components = [{ weight = 0.8, kind = "hg", g = 0.8 }, { weight = 0.2, kind = "hg", g = -0.8 }] } }
        [[layers]]
        interface = { kind = "dielectric", ior = 1.0 }
        "#,
    ),
    (
        "absorbing SGGX layer under a smooth coat over copper",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5 }
        medium = { thickness = 1.0, sigma_t = [0.5, 1.0, 2.0], albedo = 0.0, phase = { kind = "sggx", flakes = "surface", axis = [0.6, 0.0, 0.8], roughness = 0.1 } }
        [[layers]]
        interface = { kind = "conductor", preset = "Cu", roughness = 0.2 }
        "#,
    ),
];

/// Reflection and transmission queries, from above and (for transmissive or
/// two-sided stacks) from below.
fn queries(st: &LayerStack) -> Vec<([f64; 3], [f64; 3])> {
    let mut q = vec![
        (dir(0.0, 0.0), dir(30.0, 90.0)),
        (dir(60.0, 0.0), dir(45.0, 180.0)),
        (dir(85.0, 10.0), dir(80.0, 200.0)),
    ];
    if st.transmissive() || st.two_sided() {
        q.push((dir(30.0, 0.0), dir(150.0, 40.0)));
        q.push((dir(140.0, 0.0), dir(110.0, 220.0)));
    }
    q
}

#[test]
fn eval_walk_by_walk() {
    let n = 1024;
    for (name, toml) in STACKS {
        let st = stack(toml);
        let sc = ScalarEngine::<f32>::new(&st, Settings::default());
        let wf = Wavefront::<F32x8>::new(&st, Settings::default(), Plan::Specialized);
        let qs = queries(&st);
        let keys: Vec<u64> = (0..qs.len() as u64).map(|k| 100 + k).collect();
        let w = wf.eval_walk_values(&qs, n, 7, &keys);
        let (mut same, mut total, mut nonzero) = (0usize, 0usize, 0usize);
        for (k, &(wi, wo)) in qs.iter().enumerate() {
            let s = sc.eval_walk_values(wi, wo, n, 7, keys[k]);
            assert_eq!(s.len(), w[k].len(), "{name}: walks per query");
            for (a, b) in s.iter().zip(&w[k]) {
                assert!(
                    b.iter().all(|x| x.is_finite()),
                    "{name}: non-finite walk value"
                );
                total += 1;
                same += (a == b) as usize;
                nonzero += a.iter().any(|&x| x != 0.0) as usize;
            }
        }
        // Parity on walks that all give zero would prove little.
        assert!(
            nonzero * 20 >= total,
            "{name}: only {nonzero} of {total} walks contribute"
        );
        assert_eq!(same, total, "{name}: walks that differ");
        // The estimates, reduced in the same block order, then agree too.
        let (we, _) = wf.eval_batch(&qs, n, 7, &keys);
        for (k, &(wi, wo)) in qs.iter().enumerate() {
            let se = sc.eval(wi, wo, n, 7, keys[k]);
            assert_eq!(se, we[k], "{name}: query {k}");
        }
    }
}

/// Walk by walk on the other widths (16 lanes; one lane, the engine that
/// finishes a task's last walks), and with MIS off (no path continuation,
/// nothing deferred) or a scatter-order cap and early roulette: every walk
/// of every stack is the scalar engine's.
#[test]
fn eval_walk_by_walk_on_every_width_and_setting() {
    let n = 256;
    let capped = Settings {
        max_scatter_order: Some(2),
        rr_start: 1,
        ..Settings::default()
    };
    let no_mis = Settings {
        mis: false,
        ..Settings::default()
    };
    for (name, toml) in STACKS {
        let st = stack(toml);
        let qs = queries(&st);
        let keys: Vec<u64> = (0..qs.len() as u64).map(|k| 300 + k).collect();
        let check = |label: &str, set: Settings, w: Vec<Vec<[f64; 3]>>| {
            let sc = ScalarEngine::<f32>::new(&st, set);
            let (mut total, mut nonzero) = (0usize, 0usize);
            for (k, &(wi, wo)) in qs.iter().enumerate() {
                let s = sc.eval_walk_values(wi, wo, n, 5, keys[k]);
                assert_eq!(s, w[k], "{name}, {label}: query {k}");
                total += s.len();
                nonzero += s.iter().filter(|v| v.iter().any(|&x| x != 0.0)).count();
            }
            // Identical zeros would prove nothing: most walks must contribute.
            assert!(
                nonzero * 20 >= total,
                "{name}, {label}: only {nonzero} of {total} walks contribute"
            );
        };
        let spec = Plan::Specialized;
        let def = Settings::default();
        let w16 = Wavefront::<F32x16>::new(&st, def, spec);
        check("f32x16", def, w16.eval_walk_values(&qs, n, 5, &keys));
        let w1 = Wavefront::<f32>::new(&st, def, spec);
        check("one lane", def, w1.eval_walk_values(&qs, n, 5, &keys));
        for (label, set) in [("no MIS", no_mis), ("capped", capped)] {
            let w8 = Wavefront::<F32x8>::new(&st, set, spec);
            check(label, set, w8.eval_walk_values(&qs, n, 5, &keys));
        }
    }
}

/// A fixed adjoint chain (a smooth exit over a non-smooth interface: the same
/// for every walk, computed once per query) and sampled ones: walk by walk,
/// the values are the scalar engine's, on every width. With 3 walks per
/// query, chunks of new walks mix queries whose chains are fixed with ones
/// whose chains are sampled (those chunks sample every lane's chain); with
/// 16, whole chunks have fixed chains and load their query's link (checked
/// once by a panic placed on each path).
#[test]
fn fixed_and_sampled_chains_share_chunks() {
    use strata_bsdf::estimator::events::chain_is_fixed;
    use strata_bsdf::estimator::layout::Layout;
    let fixed = |toml: &str, e: usize| {
        let st = stack(toml);
        chain_is_fixed(&st, &Layout::new(&st), e)
    };
    assert!(
        fixed(STACKS[0].1, 0),
        "clear coat: smooth exit over Lambertian"
    );
    assert!(!fixed(STACKS[1].1, 0), "rough exit");
    assert!(
        !fixed(STACKS[4].1, 0),
        "smooth exit over a smooth interface"
    );
    // Exits at the rough top (sampled chains) and the smooth bottom (fixed
    // chains) alternate.
    let (name, toml) = STACKS[5];
    assert!(!fixed(toml, 0) && fixed(toml, 1), "{name}");
    let alternate: Vec<_> = (0..60)
        .map(|k| {
            let wo = dir(10.0 + k as f64, 37.0 * k as f64);
            let wo = if k % 2 == 0 {
                wo
            } else {
                [wo[0], wo[1], -wo[2]]
            };
            (dir(5.0 + k as f64, 0.0), wo)
        })
        .collect();
    // A denser exterior: past about 53° from the normal, `wo` cannot be
    // refracted into the coat (total internal reflection), so the fixed chain
    // has no link and the walks give 0.
    let tir = r#"
        exterior_ior = 1.5
        [[layers]]
        interface = { kind = "dielectric", ior = 1.2 }
        [[layers]]
        interface = { kind = "diffuse", albedo = 0.8 }
        "#;
    assert!(fixed(tir, 0), "dense exterior");
    let steep_and_grazing: Vec<_> = (0..30)
        .map(|k| (dir(40.0, 0.0), dir(3.0 * k as f64, 100.0 + k as f64)))
        .collect();
    for (name, toml, qs) in [
        (name, toml, &alternate),
        ("dense exterior", tir, &steep_and_grazing),
    ] {
        let st = stack(toml);
        let sc = ScalarEngine::<f32>::new(&st, Settings::default());
        let keys: Vec<u64> = (0..qs.len() as u64).collect();
        for n in [3, 16] {
            let want: Vec<_> = qs
                .iter()
                .zip(&keys)
                .map(|(&(wi, wo), &key)| sc.eval_walk_values(wi, wo, n, 21, key))
                .collect();
            let settings = Settings::default();
            let x8 = Wavefront::<F32x8>::new(&st, settings, Plan::Specialized);
            let x16 = Wavefront::<F32x16>::new(&st, settings, Plan::Specialized);
            let x1 = Wavefront::<f32>::new(&st, settings, Plan::Specialized);
            assert_eq!(
                x8.eval_walk_values(qs, n, 21, &keys),
                want,
                "{name}: {n} walks, f32x8"
            );
            assert_eq!(
                x16.eval_walk_values(qs, n, 21, &keys),
                want,
                "{name}: {n} walks, f32x16"
            );
            assert_eq!(
                x1.eval_walk_values(qs, n, 21, &keys),
                want,
                "{name}: {n} walks, one lane"
            );
            // Parity on walks that all give zero would prove little: walks
            // contribute through both exits (even and odd queries) of the
            // first stack, and on the steep side of the critical angle of
            // the second.
            let contributing = |k: usize| want[k].iter().filter(|v| v[0] != 0.0).count();
            let (even, odd): (usize, usize) = (0..qs.len()).fold((0, 0), |(e, o), k| {
                let c = contributing(k);
                if k % 2 == 0 {
                    (e + c, o)
                } else {
                    (e, o + c)
                }
            });
            assert!(
                even + odd >= qs.len() * n as usize / 20,
                "{name}: {even} + {odd} contribute"
            );
            assert!(
                name == "dense exterior" || (even > 0 && odd > 0),
                "{name}: {even}, {odd}"
            );
        }
        if name == "dense exterior" {
            // Past the critical angle nothing reaches `wo`; before it, walks do.
            let past = sc.eval_walk_values(qs[25].0, qs[25].1, 64, 21, 25);
            assert!(
                past.iter().all(|v| *v == [0.0; 3]),
                "{name}: past the critical angle"
            );
            let before = sc.eval_walk_values(qs[5].0, qs[5].1, 64, 21, 5);
            assert!(
                before.iter().any(|v| v[0] > 0.0),
                "{name}: before the critical angle"
            );
        }
    }
}

#[test]
fn eval_means_agree_with_independent_seeds() {
    let n = 20_000;
    for (name, toml) in STACKS {
        let st = stack(toml);
        let sc = ScalarEngine::<f32>::new(&st, Settings::default());
        let wf = Wavefront::<F32x8>::new(&st, Settings::default(), Plan::Specialized);
        let qs = queries(&st);
        let keys: Vec<u64> = (0..qs.len() as u64).collect();
        let (we, _) = wf.eval_batch(&qs, n, 1, &keys);
        for (k, &(wi, wo)) in qs.iter().enumerate() {
            let se = sc.eval(wi, wo, n, 2, keys[k]);
            for c in 0..3 {
                let sigma = (se.stderr[c].powi(2) + we[k].stderr[c].powi(2)).sqrt();
                assert_z(
                    &format!("{name}: query {k} channel {c}"),
                    we[k].value[c],
                    se.value[c],
                    sigma,
                    4.5,
                    1e-7,
                );
            }
        }
    }
}

#[test]
fn sample_albedo_and_pdf_match_the_scalar_engine() {
    let mut counts = [0; 2];
    for (name, toml) in STACKS {
        let st = stack(toml);
        let sc = ScalarEngine::<f32>::new(&st, Settings::default());
        let wf = Wavefront::<F32x8>::new(&st, Settings::default(), Plan::Specialized);
        // Sample: one walk per query, every walk compared. Every third query
        // comes from below, so on a transmissive stack the new walks of one
        // chunk enter at both outer interfaces (not every other one: tasks
        // take every n-th query, and n is even).
        let wis: Vec<[f64; 3]> = (0..2000)
            .map(|k| {
                let d = dir((k % 89) as f64, (k * 37 % 360) as f64);
                [d[0], d[1], if k % 3 == 1 { -d[2] } else { d[2] }]
            })
            .collect();
        let keys: Vec<u64> = (0..wis.len() as u64).collect();
        let idx: Vec<u64> = keys.iter().map(|k| k * 3 + 1).collect();
        let (ws, _) = wf.sample_batch(&wis, 9, &keys, &idx);
        let mut differ = 0;
        for (k, &wi) in wis.iter().enumerate() {
            let mut rng = WalkRng::new(9, keys[k], idx[k], Stream::Walk);
            let s = sc.sample(wi, &mut rng);
            differ += (s != ws[k]) as usize;
        }
        assert_eq!(differ, 0, "{name}: of {} samples", wis.len());
        // Albedo and pdf.
        let w = [dir(20.0, 0.0), dir(75.0, 30.0)];
        let (wa, _) = wf.albedo_batch(&w, 5000, 3, &[5, 6]);
        for (k, &wi) in w.iter().enumerate() {
            let sa = sc.albedo(wi, 5000, 3, 5 + k as u64);
            assert_eq!(sa, wa[k], "{name}: albedo {k}");
        }
        let qs = queries(&st);
        let keys: Vec<u64> = (0..qs.len() as u64).collect();
        // Both pdfs: the same density walks, lane by lane, and the same
        // pilot rounds (the default approximate pdf's).
        let pdfs = [
            (PdfKind::Approximate, PdfWalks::fixed(8)),
            (PdfKind::Approximate, PdfWalks::ADAPTIVE),
            (PdfKind::Unbiased, PdfWalks::fixed(37)),
        ];
        for (kind, walks) in pdfs {
            let wp = wf.pdf_batch(&qs, walks, 4, &keys, kind);
            for (k, &(wi, wo)) in qs.iter().enumerate() {
                let sp = sc.pdf_estimate(wi, wo, walks, 4, keys[k], kind);
                assert_eq!(sp, wp[k], "{name}: {kind:?} {walks:?} pdf {k}");
            }
            if walks == PdfWalks::ADAPTIVE {
                // The pilot's walks and at least as many fresh ones.
                let fewest = 2 * walks.pilot();
                for e in wp.iter().filter(|e| e.samples > 0) {
                    assert!(e.samples >= fewest, "{name}: {e:?}");
                    counts[(e.samples > fewest) as usize] += 1;
                }
            }
        }
    }
    // The pilots chose: some queries ran the fewest walks, some more.
    assert!(
        counts[0] > 0 && counts[1] > 0,
        "fewest walks, more: {counts:?}"
    );
}

#[test]
fn results_do_not_depend_on_threads_wave_size_batching_or_width() {
    let (_, toml) = STACKS[2];
    let st = stack(toml);
    let wf = Wavefront::<F32x8>::new(&st, Settings::default(), Plan::Specialized);
    let qs: Vec<_> = (0..40)
        .map(|k| {
            (
                dir(k as f64 * 2.0, 0.0),
                dir(80.0 - k as f64, 90.0 + k as f64),
            )
        })
        .collect();
    let keys: Vec<u64> = (0..qs.len() as u64).collect();
    let run = |threads: usize, wf: &Wavefront<F32x8>| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| wf.eval_batch(&qs, 1500, 11, &keys).0)
    };
    let one = run(1, &wf);
    assert_eq!(one, run(2, &wf), "2 threads");
    assert_eq!(one, run(4, &wf), "4 threads");
    let small = wf.clone().with_slots(8);
    assert_eq!(one, run(2, &small), "a wave of 8 slots");
    // A query alone gives what it gives in the batch.
    let (alone, _) = wf.eval_batch(&qs[17..18], 1500, 11, &keys[17..18]);
    assert_eq!(alone[0], one[17], "a query alone");
    // Sixteen lanes replay the same walks.
    let wide = Wavefront::<F32x16>::new(&st, Settings::default(), Plan::Specialized);
    assert_eq!(one, wide.eval_batch(&qs, 1500, 11, &keys).0, "f32x16");
    let w = [dir(10.0, 0.0), dir(50.0, 0.0)];
    assert_eq!(
        wf.albedo_batch(&w, 4000, 2, &[1, 2]).0,
        wide.albedo_batch(&w, 4000, 2, &[1, 2]).0,
        "f32x16 albedo"
    );
}

#[test]
fn general_walk_agrees_with_specialized() {
    let n = 20_000;
    for (name, toml) in STACKS {
        let st = stack(toml);
        let spec = Wavefront::<F32x8>::new(&st, Settings::default(), Plan::Specialized);
        let gen = Wavefront::<F32x8>::new(&st, Settings::default(), Plan::General);
        let qs = queries(&st);
        let keys: Vec<u64> = (0..qs.len() as u64).collect();
        let (a, _) = spec.eval_batch(&qs, n, 1, &keys);
        let (b, _) = gen.eval_batch(&qs, n, 2, &keys);
        for k in 0..qs.len() {
            for c in 0..3 {
                let sigma = (a[k].stderr[c].powi(2) + b[k].stderr[c].powi(2)).sqrt();
                assert_z(
                    &format!("{name}: general vs specialized, query {k} channel {c}"),
                    b[k].value[c],
                    a[k].value[c],
                    sigma,
                    4.5,
                    1e-7,
                );
            }
        }
        let w = [dir(30.0, 0.0)];
        let (ra, _) = spec.albedo_batch(&w, n, 3, &[0]);
        let (rb, _) = gen.albedo_batch(&w, n, 4, &[0]);
        for c in 0..3 {
            let (x, y) = (ra[0].reflected, rb[0].reflected);
            let sigma = (x.stderr[c].powi(2) + y.stderr[c].powi(2)).sqrt();
            assert_z(
                &format!("{name}: albedo R"),
                y.value[c],
                x.value[c],
                sigma,
                4.5,
                1e-7,
            );
        }
    }
}

/// The control variate of `Estimator::Auto` (a smooth or rough coat over a
/// scattering layer over a Lambertian base: walks leave out the paths
/// without a collision, and the estimate adds them, exactly or from the
/// rough coat's factorized samples): every walk on every width and setting
/// is the scalar engine's, and so are the estimates with that part. On the
/// thin layers most walks never collide and score 0; the thicker ones keep
/// most walks contributing.
#[test]
fn eval_walk_by_walk_with_the_control_variate() {
    let stacks = [
        ("thin (τ 0.01)", crate::common::SMOOTH_WEAK_SCATTERER, 100),
        (
            "chromatic, two-sided",
            r#"
            two_sided = true
            [[layers]]
            interface = { kind = "dielectric", ior = 1.7 }
            medium = { thickness = 1.0, sigma_t = [0.5, 1.0, 2.0], albedo = [0.2, 0.6, 1.0], phase = { kind = "hg", g = 0.3 } }
            [[layers]]
            interface = { kind = "diffuse", albedo = [0.9, 0.5, 0.2] }
            "#,
            20,
        ),
        (
            "thick grey",
            r#"
            [[layers]]
            interface = { kind = "dielectric", ior = 2.2 }
            medium = { thickness = 2.0, sigma_t = 1.0, albedo = 0.95, phase = { kind = "hg", g = -0.5 } }
            [[layers]]
            interface = { kind = "diffuse", albedo = 0.6 }
            "#,
            20,
        ),
        (
            "rough coat, thin (τ 0.01)",
            crate::common::ROUGH_WEAK_SCATTERER,
            100,
        ),
        (
            "rough Beckmann coat, chromatic, two-sided",
            r#"
            two_sided = true
            [[layers]]
            interface = { kind = "dielectric", ior = 1.7, roughness = 0.3, distribution = "beckmann" }
            medium = { thickness = 1.0, sigma_t = [0.5, 1.0, 2.0], albedo = [0.2, 0.6, 1.0], phase = { kind = "hg", g = 0.3 } }
            [[layers]]
            interface = { kind = "diffuse", albedo = [0.9, 0.5, 0.2] }
            "#,
            20,
        ),
    ];
    let n = 512;
    let capped = Settings {
        max_scatter_order: Some(2),
        rr_start: 1,
        ..Settings::default()
    };
    let no_mis = Settings {
        mis: false,
        ..Settings::default()
    };
    for (name, toml, share) in stacks {
        let st = stack(toml);
        let qs = queries(&st);
        let keys: Vec<u64> = (0..qs.len() as u64).map(|k| 500 + k).collect();
        for (label, set) in [
            ("default", Settings::default()),
            ("no MIS", no_mis),
            ("capped", capped),
        ] {
            let sc = ScalarEngine::<f32>::new(&st, set).with_control_variate(true);
            assert!(sc.control_variate(), "{name}");
            let spec = Plan::Specialized;
            let w8 = Wavefront::<F32x8>::new(&st, set, spec).with_control_variate(true);
            let w16 = Wavefront::<F32x16>::new(&st, set, spec).with_control_variate(true);
            let w1 = Wavefront::<f32>::new(&st, set, spec).with_control_variate(true);
            let plain = ScalarEngine::<f32>::new(&st, set);
            for (width, w) in [
                ("f32x8", w8.eval_walk_values(&qs, n, 9, &keys)),
                ("f32x16", w16.eval_walk_values(&qs, n, 9, &keys)),
                ("one lane", w1.eval_walk_values(&qs, n, 9, &keys)),
            ] {
                let (mut total, mut nonzero, mut dropped) = (0usize, 0usize, 0usize);
                for (k, &(wi, wo)) in qs.iter().enumerate() {
                    let s = sc.eval_walk_values(wi, wo, n, 9, keys[k]);
                    assert_eq!(s, w[k], "{name}, {label}, {width}: query {k}");
                    let p = plain.eval_walk_values(wi, wo, n, 9, keys[k]);
                    total += s.len();
                    nonzero += s.iter().filter(|v| v.iter().any(|&x| x != 0.0)).count();
                    dropped += s.iter().zip(&p).filter(|(a, b)| a != b).count();
                }
                assert!(
                    nonzero * share >= total,
                    "{name}, {label}, {width}: only {nonzero} of {total} walks contribute"
                );
                // The control variate changed something (it is on).
                assert!(dropped > 0, "{name}, {label}, {width}");
            }
            let (we, _) = w8.eval_batch(&qs, n, 9, &keys);
            for (k, &(wi, wo)) in qs.iter().enumerate() {
                assert_eq!(
                    sc.eval(wi, wo, n, 9, keys[k]),
                    we[k],
                    "{name}, {label}: {k}"
                );
            }
        }
    }
}
