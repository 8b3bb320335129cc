//! The convergence machinery (`strata_reports::converge`) on the analytic case, a
//! smooth dielectric over a Lambertian base, where the reference is exact:
//! the errors it reports must be the estimator's own standard errors (z-scores
//! over queries and budgets), and the RMS error must fall as 1/sqrt(samples).

use crate::common;
use common::*;
use strata_bsdf::Settings;
use strata_reports::converge::*;

const COAT: &str = crate::common::SMOOTH_COAT_OVER_GREY;

/// A rough coat (IOR 1.5, α 0.3) over a Lambertian base of albedo 0.6: no
/// closed form.
const ROUGH_COAT: &str = r#"
[[layers]]
interface = { kind = "dielectric", ior = 1.5, roughness = 0.3 }
[[layers]]
interface = { kind = "diffuse", albedo = 0.6 }
"#;

/// Ten BSDF queries from two incident directions, in and off the plane of
/// incidence, and the albedo from eight directions (those two among them).
fn queries() -> QuerySet {
    let mut q = QuerySet::default();
    for ti in [20.0, 55.0] {
        let wi = dir(ti, 0.0);
        for (t, p) in [
            (0.0, 0.0),
            (30.0, 180.0),
            (45.0, 90.0),
            (70.0, 0.0),
            (60.0, 250.0),
        ] {
            q.f.push(FQuery { wi, wo: dir(t, p) });
        }
    }
    for t in [0.0, 20.0, 35.0, 55.0, 65.0, 75.0, 85.0, 89.0] {
        q.albedo.push(dir(t, 0.0));
    }
    q
}

fn fixed_ladder(start: u64, steps: usize) -> LadderSpec {
    LadderSpec {
        budget_seconds: f64::INFINITY,
        min_steps: steps,
        max_steps: steps,
        start: Some(start),
    }
}

/// Every third z-score: the stack is grey, so the three channels of a target
/// are the same number.
fn channel0(z: &[f64]) -> impl Iterator<Item = f64> + '_ {
    z.iter().step_by(3).copied()
}

/// Independent check of the closed form the machinery uses as reference: the
/// Fresnel terms and hemispherical averages written out here, in the test.
#[test]
fn analytic_reference_is_the_closed_form() {
    use common::reference::fresnel;
    let avg = |n1: f64, n2: f64| {
        let n = 400_000;
        (0..n)
            .map(|k| {
                let mu = (k as f64 + 0.5) / n as f64;
                fresnel(mu, n1, n2) * 2.0 * mu / n as f64
            })
            .sum::<f64>()
    };
    let (fi, fo) = (avg(1.5, 1.0), avg(1.0, 1.5));
    let st = stack(COAT);
    let qs = queries();
    let r = analytic_reference(&st, &qs, &[]).expect("coat over Lambertian has a closed form");
    assert_eq!(r.kind, ReferenceKind::Analytic);
    for (j, q) in qs.f.iter().enumerate() {
        let want = (1.0 - fresnel(q.wi[2], 1.0, 1.5)) * (1.0 - fresnel(q.wo[2], 1.0, 1.5)) * 0.7
            / (std::f64::consts::PI * 2.25 * (1.0 - 0.7 * fi));
        let (v, s) = r.f(j);
        assert!(
            (v[0] - want).abs() < 1e-6 * want,
            "query {j}: {} vs {want}",
            v[0]
        );
        assert_eq!(s, [0.0; 3]);
    }
    for (j, wi) in qs.albedo.iter().enumerate() {
        let f = fresnel(wi[2], 1.0, 1.5);
        let want = f + (1.0 - f) * 0.7 * (1.0 - fo) / (2.25 * (1.0 - 0.7 * fi));
        let (rr, tt) = r.albedo(j);
        assert!((rr.mean[0] - want).abs() < 1e-6, "{} vs {want}", rr.mean[0]);
        assert_eq!(tt.mean, [0.0; 3]);
    }
    // Stacks without a closed form have none.
    let rough = stack(
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5, roughness = 0.1 }
        [[layers]]
        interface = { kind = "diffuse", albedo = 0.7 }
        "#,
    );
    assert!(analytic_reference(&rough, &qs, &[]).is_none());
}

/// The errors reported on the exact reference are the estimator's own
/// standard errors: over 9 budgets × 10 BSDF queries (90 independent
/// z-scores) and × 8 albedo queries (72) no |z| exceeds 4.5 (a 6.8e-6
/// two-sided tail each)
/// and the mean of z² lies within 3 of its standard deviations (sqrt(2/K))
/// of 1, so a standard error off by a factor 1.5 either way fails.
#[test]
fn reported_errors_are_consistent_with_standard_errors() {
    let st = stack(COAT);
    let qs = queries();
    let r = analytic_reference(&st, &qs, &[]).unwrap();
    let est = EstimatorKind::Scalar.build(&st, Settings::default());
    let runs = ladder(est.as_ref(), &qs, &fixed_ladder(256, 9), 3, &Silent);
    assert_eq!(runs.len(), 9);
    let mut zf = Vec::new();
    let mut za = Vec::new();
    for run in &runs {
        let e = errors(&r, run);
        zf.extend(channel0(&e.z_f));
        za.extend(channel0(&e.z_albedo));
    }
    assert_eq!(zf.len(), 90);
    assert_eq!(za.len(), 72);
    for (what, z) in [("f", &zf), ("albedo", &za)] {
        let k = z.len() as f64;
        let worst = z.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let mean_z2 = z.iter().map(|x| x * x).sum::<f64>() / k;
        let tol = 3.0 * (2.0 / k).sqrt();
        eprintln!("{what}: max |z| {worst:.2}, mean z² {mean_z2:.3} (1 ± {tol:.3})");
        assert!(worst < 4.5, "{what}: max |z| = {worst}");
        assert!(
            (mean_z2 - 1.0).abs() < tol,
            "{what}: mean z² = {mean_z2}, expected 1 ± {tol}"
        );
    }
}

/// log(RMS error) against log(samples) has slope -1/2. The tolerance comes
/// from the spread of an RMS over K targets: log RMS has standard deviation
/// about 1/sqrt(2 K_eff), K_eff = (Σ s²)² / Σ s⁴ over the targets' own
/// relative standard errors s (their participation ratio); propagated
/// through the least-squares fit, that gives the slope's standard deviation,
/// and the fit must land within 4 of them of -1/2.
#[test]
fn rms_error_falls_as_one_over_sqrt_samples() {
    let st = stack(COAT);
    let qs = queries();
    let r = analytic_reference(&st, &qs, &[]).unwrap();
    let est = EstimatorKind::Scalar.build(&st, Settings::default());
    let runs = ladder(est.as_ref(), &qs, &fixed_ladder(256, 9), 11, &Silent);
    let pts: Vec<(f64, f64)> = runs
        .iter()
        .map(|run| ((run.samples as f64).ln(), errors(&r, run).rms_f.ln()))
        .collect();
    let n = pts.len() as f64;
    let mx = pts.iter().map(|p| p.0).sum::<f64>() / n;
    let my = pts.iter().map(|p| p.1).sum::<f64>() / n;
    let sxx = pts.iter().map(|p| (p.0 - mx).powi(2)).sum::<f64>();
    let slope = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum::<f64>() / sxx;
    // Participation ratio of the relative standard errors (last run).
    let last = runs.last().unwrap();
    let s2: Vec<f64> =
        qs.f.iter()
            .enumerate()
            .map(|(j, _)| (last.f[j].stderr[0] / r.f(j).0[0]).powi(2))
            .collect();
    let k_eff = s2.iter().sum::<f64>().powi(2) / s2.iter().map(|x| x * x).sum::<f64>();
    let sd = 1.0 / (2.0 * k_eff).sqrt() / sxx.sqrt();
    eprintln!("slope {slope:.3}, K_eff {k_eff:.1}, sd {sd:.3}");
    assert!(
        (slope + 0.5).abs() < 4.0 * sd,
        "slope {slope}, expected -0.5 ± {}",
        4.0 * sd
    );
    // An estimator that did not converge would have slope 0: the test can tell.
    assert!(
        4.0 * sd < 0.25,
        "tolerance {} too wide to be a test",
        4.0 * sd
    );
}

/// The brute force, compared with the bin averages of the closed form (no
/// binning bias left), has only statistical error: z-scores within 4.5 over
/// 10 queries × 4 budgets; and its binning floor is the RMS relative
/// difference between those bin averages and the point values.
#[test]
fn brute_force_matches_bin_averages_and_floor_is_the_bias() {
    let st = stack(COAT);
    let qs = queries();
    let h = 15f64.to_radians();
    let r = analytic_reference(&st, &qs, &[h]).unwrap();
    let est = EstimatorKind::BruteForce {
        half_angle_deg: 15.0,
    }
    .build(&st, Settings::default());
    assert_eq!(est.bin_half_angle(), Some(h));
    let runs = ladder(est.as_ref(), &qs, &fixed_ladder(20_000, 4), 5, &Silent);
    let mut z = Vec::new();
    for run in &runs {
        z.extend(channel0(&errors_vs_bins(&r, run, h).unwrap().z_f));
    }
    assert_eq!(z.len(), 40);
    let worst = z.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    assert!(worst < 4.5, "max |z| against the bin averages: {worst}");
    let (floor, noise) = binning_floor(&r, h).unwrap();
    let direct = (qs
        .f
        .iter()
        .enumerate()
        .map(|(j, _)| {
            let p = r.f(j).0[0];
            ((r.bins(h).unwrap().acc[j].mean[0] - p) / p).powi(2)
        })
        .sum::<f64>()
        / qs.f.len() as f64)
        .sqrt();
    assert_eq!(noise, 0.0);
    assert!(
        (floor - direct).abs() < 1e-12 * direct,
        "{floor} vs {direct}"
    );
    assert!(
        floor > 1e-4,
        "a 15° bin on this lobe has a visible bias: {floor}"
    );
}

/// A long-run reference (forced on the analytic stack) reaches its targets,
/// agrees with the closed form and its bin averages within 4.5 standard
/// errors, and does not depend on the number of threads.
#[test]
fn long_run_reference_agrees_with_the_closed_form() {
    let st = stack(COAT);
    let qs = queries();
    let h = 10f64.to_radians();
    let exact = analytic_reference(&st, &qs, &[h]).unwrap();
    let est = EstimatorKind::Scalar.build(&st, Settings::default());
    let spec = ReferenceSpec {
        seed: 42,
        chunk_samples: 2048,
        bin_points: 2048,
        max_seconds: 60.0,
    };
    let targets = Targets {
        f: 0.01,
        albedo: 0.002,
        bins: 0.02,
    };
    let build = || {
        let mut r = empty_reference(est.as_ref(), &qs, &[h], &spec);
        let ok = extend_reference(&mut r, est.as_ref(), &qs, targets, &spec, &Silent);
        assert!(ok, "the reference did not reach its targets");
        r
    };
    let r = build();
    assert!(r.f.rms_rel_stderr() <= targets.f);
    assert!(r.albedo.rms_rel_stderr() <= targets.albedo);
    for (what, got, want) in [
        ("f", &r.f, &exact.f),
        ("albedo", &r.albedo, &exact.albedo),
        (
            "bins",
            &r.bins(h).unwrap().clone(),
            &exact.bins(h).unwrap().clone(),
        ),
    ] {
        for (j, (a, b)) in got.acc.iter().zip(&want.acc).enumerate() {
            for c in 0..3 {
                assert_z(
                    &format!("{what} target {j} channel {c}"),
                    a.mean[c],
                    b.mean[c],
                    a.stderr()[c],
                    4.5,
                    1e-9,
                );
            }
        }
    }
    // The same reference whatever the thread count.
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(build);
    assert_eq!((&r.f, &r.albedo, &r.bins), (&one.f, &one.albedo, &one.bins));
}

/// The whole study on a stack with no closed form: the reference's error bar
/// ends up at least 10× below the smallest error plotted, and the outputs
/// hold every run.
#[test]
fn study_keeps_the_reference_ten_times_below_the_errors() {
    let st = stack(ROUGH_COAT);
    let qs = queries();
    let cfg = Config {
        estimators: vec![EstimatorKind::Scalar],
        ladder: fixed_ladder(64, 5),
        ..Config::default()
    };
    let rep = converge("rough-coat", &st, &qs, &cfg, None, &Silent);
    assert!(rep.reference_converged);
    let (mf, ma) = rep.reference_margin(true);
    assert!(mf >= 10.0 && ma >= 10.0, "margins {mf} {ma}");
    let csv = rep.csv();
    assert_eq!(csv.lines().count(), 1 + 5);
    assert!(csv
        .lines()
        .nth(1)
        .unwrap()
        .starts_with("rough-coat,scalar,64,"));
    assert_eq!(rep.targets_csv().lines().count(), 1 + 3 * (10 + 2 * 8));
    assert!(rep.markdown().contains("| scalar | 1024 |"));
    // A cached reference is reused as it is when precise enough.
    let again = converge(
        "rough-coat",
        &st,
        &qs,
        &cfg,
        Some(rep.reference.clone()),
        &Silent,
    );
    assert_eq!(again.reference, rep.reference);
}

#[test]
fn query_files_and_cache_keys() {
    let q = QuerySet::parse_json_lines(
        "# comment\n{\"wi\":[0,0,2],\"wo\":[1,0,1]}\n\n{\"wi\":[0.5,0,1]}\n",
    )
    .unwrap();
    assert_eq!(q.f.len(), 1);
    assert_eq!(q.albedo.len(), 1);
    assert!((q.f[0].wo[0] - 0.5f64.sqrt()).abs() < 1e-12);
    let e = QuerySet::parse_json_lines("{\"wi\":[0,0,1]}\n{\"wi\":[0,0,0]}").unwrap_err();
    assert!(e.contains("line 2") && e.contains("wi"), "{e}");
    let e = QuerySet::parse_json_lines("{\"wi\":[0,0,1],\"w\":1}").unwrap_err();
    assert!(e.contains("line 1"), "{e}");
    assert!(QuerySet::parse_json_lines("\n").is_err());

    let a = stack(COAT);
    let b = stack(&COAT.replace("0.7", "0.6"));
    let s = Settings::default();
    let spec = ReferenceSpec::default();
    let k = |st, q: &QuerySet| cache_key(st, q, &s, &[0.1], "scalar", &spec);
    let qa = QuerySet::default_for(&a);
    assert_eq!(k(&a, &qa), k(&a, &qa));
    assert_ne!(k(&a, &qa), k(&b, &qa));
    assert_ne!(k(&a, &qa), k(&a, &q));
    // Transmissive stacks get transmission queries by default.
    let slab = stack(
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5, roughness = 0.2 }
        [[layers]]
        interface = { kind = "dielectric", ior = 1.0, roughness = 0.2 }
        "#,
    );
    assert!(QuerySet::default_for(&slab).f.iter().any(|q| q.wo[2] < 0.0));
    assert!(qa.f.iter().all(|q| q.wo[2] > 0.0));
    // The reference survives a JSON round trip (the on-disk cache).
    let r = analytic_reference(&a, &qa, &[0.1]).unwrap();
    // (serde_json's default float parser may round the last bit.)
    let back: Reference = serde_json::from_str(&serde_json::to_string(&r).unwrap()).unwrap();
    assert_eq!(back.kind, r.kind);
    for (x, y) in back
        .f
        .acc
        .iter()
        .zip(&r.f.acc)
        .chain(back.bins[0].1.acc.iter().zip(&r.bins[0].1.acc))
    {
        for c in 0..3 {
            assert!((x.mean[c] - y.mean[c]).abs() <= 1e-15 * y.mean[c].abs());
        }
    }
}

/// A query set with one kind of query only: the other kind's columns are
/// empty (CSV) or "–" (markdown, summary), never `inf` or `NaN` made of no
/// query, and the reference is described by the kind it has.
#[test]
fn one_kind_of_query_leaves_the_other_blank() {
    let st = stack(ROUGH_COAT);
    let cfg = Config {
        estimators: vec![EstimatorKind::Scalar],
        ladder: fixed_ladder(64, 3),
        ..Config::default()
    };
    let all = queries();
    let only_f = QuerySet {
        f: all.f.clone(),
        ..QuerySet::default()
    };
    let only_albedo = QuerySet {
        albedo: all.albedo.clone(),
        ..QuerySet::default()
    };
    for (qs, f_blank) in [(only_f, false), (only_albedo, true)] {
        let rep = converge("one-kind", &st, &qs, &cfg, None, &Silent);
        let text = [rep.csv(), rep.markdown(), rep.summary()].concat();
        for bad in ["inf", "NaN"] {
            assert!(!text.contains(bad), "{bad} in:\n{text}");
        }
        // Every run's row of the markdown table has four "–" cells.
        let md = rep.markdown();
        let rows: Vec<&str> = md.lines().filter(|l| l.starts_with("| scalar |")).collect();
        assert_eq!(rows.len(), 3, "{md}");
        assert!(rows.iter().all(|r| r.matches(" – |").count() == 4), "{md}");
        let csv = rep.csv();
        assert_eq!(csv.lines().count(), 1 + 3, "{csv}");
        for line in csv.lines().skip(1) {
            let row: Vec<&str> = line.split(',').collect();
            // time, error, own error and efficiency of f (3..7), of the
            // albedo (7..11), the reference's error bars (12, 13).
            let (blank, full) = if f_blank {
                (3..7, 7..11)
            } else {
                (7..11, 3..7)
            };
            assert!(row[blank].iter().all(|c| c.is_empty()), "{row:?}");
            assert!(
                row[full].iter().all(|c| c.parse::<f64>().is_ok()),
                "{row:?}"
            );
            let bars = (row[12].is_empty(), row[13].is_empty());
            assert_eq!(bars, (f_blank, !f_blank), "{row:?}");
        }
        let described = rep.reference.describe();
        assert_eq!(described.contains("albedo"), f_blank, "{described}");
        assert_eq!(described.contains("BSDF query"), !f_blank, "{described}");
    }
}
