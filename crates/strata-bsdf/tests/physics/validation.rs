//! strata against references made outside it (issue 14; docs/validation.md):
//!
//! * `validation/references/iad.csv`: adding-doubling (iadpython 0.5.3) for smooth-boundary
//!   slabs, R and T at normal incidence, over optical depth × albedo × g × IOR (108 slabs);
//! * `validation/references/exact.csv`: exact solutions computed in f64 by
//!   `validation/exact.py` (Chandrasekhar's H-function, a smooth coat over an absorber over a
//!   Lambertian base, absorbing Fresnel slabs);
//! * `validation/references/mitsuba*.csv`: Mitsuba 3.9.1 volumetric path tracing of the
//!   explicit slab (albedos, and BSDF values integrated over a 4–5° cone around `wi`, which
//!   strata integrates over the same cone here, so the cone adds no bias).
//!
//! The references were generated once (validation/README.md); this test only reads them.
//! Every comparison runs twice on the wavefront engine, with seeds 1 and 2 (two independent
//! estimates; seed 1's walks are the scalar reference's, bit for bit: tests/parity), and passes when
//! |strata − reference| ≤ 4 σ + bound, σ = sqrt(σ_strata² + σ_reference²) and `bound` the
//! reference's stated deterministic error (quadrature, truncation). 788 comparisons:
//! a correct estimator trips one with probability ≈ 788 × 6.3e-5 ≈ 5 % for an arbitrary seed;
//! the seeds are fixed, so the outcome is deterministic. Each file also asserts that the mean
//! of z² (excess over the bound; a row's channels averaged, as they share walks) over its N
//! rows is at most 1 + 4 sqrt(2 m/N), m = 2 where the two runs share a noisy reference row
//! (Mitsuba), else 1: 1.27 for the 432 adding-doubling rows, 1.78 for the 52 exact ones, 2.07
//! for Mitsuba's, so a bias of about half, 0.9 or 1 standard error shared by most rows fails
//! even when no single comparison is outside 4σ.

use crate::common;
use crate::common::batches::Batches;
use common::*;
use strata_bsdf::{Engine, Estimator, LayerStack, LayeredBsdf};

const DIR: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../validation");
const K: f64 = 4.0;

/// One row of a reference CSV, by column name.
struct Row {
    cols: Vec<(String, String)>,
}

impl Row {
    fn get(&self, k: &str) -> Option<&str> {
        self.cols
            .iter()
            .find(|(c, _)| c == k)
            .map(|(_, v)| v.as_str())
    }
    fn num(&self, k: &str) -> f64 {
        let v = self.get(k).unwrap_or_else(|| panic!("column {k} missing"));
        v.parse()
            .unwrap_or_else(|e| panic!("column {k} = {v:?}: {e}"))
    }
    fn num_or(&self, k: &str, d: f64) -> f64 {
        match self.get(k) {
            Some(v) if !v.is_empty() => v.parse().unwrap_or_else(|e| panic!("{k}={v}: {e}")),
            _ => d,
        }
    }
    fn rgb(&self, prefix: &str, default: f64) -> [f64; 3] {
        [0, 1, 2].map(|c| self.num_or(&format!("{prefix}{c}"), default))
    }
}

fn read_csv(name: &str) -> Vec<Row> {
    let path = format!("{DIR}/references/{name}");
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let mut lines = text.lines();
    let header: Vec<String> = lines
        .next()
        .expect("header")
        .split(',')
        .map(str::to_owned)
        .collect();
    let rows: Vec<Row> = lines
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let vals: Vec<&str> = l.split(',').collect();
            assert_eq!(vals.len(), header.len(), "{path}: {l}");
            Row {
                cols: header
                    .iter()
                    .cloned()
                    .zip(vals.iter().map(|v| v.to_string()))
                    .collect(),
            }
        })
        .collect();
    assert!(!rows.is_empty(), "{path}: no rows");
    rows
}

fn material(file: &str) -> LayerStack {
    let path = format!("{DIR}/materials/{file}");
    LayerStack::from_path(&path).unwrap_or_else(|e| panic!("{path}: {e}"))
}

/// The two runs: the wavefront engine with two seeds, two independent
/// estimates. Seed 1's walks are the scalar reference's walk by walk, bit for
/// bit (tests/parity), so its numbers are the scalar engine's.
const RUNS: [(Engine, u64, &str); 2] = [
    (Engine::Wavefront, 1, "seed1"),
    (Engine::Wavefront, 2, "seed2"),
];

/// Collects comparisons; fails at the end with every failure listed.
#[derive(Default)]
struct Tally {
    /// Per reference row (channels averaged: they share walks, so they are not independent).
    z2: Vec<f64>,
    /// z² of the current row's channels.
    row: Vec<f64>,
    failures: Vec<String>,
    worst: f64,
    /// Every comparison as a CSV line, written out when `STRATA_VALIDATION_OUT` names a
    /// directory (validation/table.py makes docs/validation.md's table from it).
    lines: Vec<String>,
}

impl Tally {
    /// `key` identifies the comparison for the table (run, case, quantity, angles, channel).
    #[allow(clippy::too_many_arguments)]
    fn check(&mut self, key: &str, what: &str, s: f64, s_err: f64, r: f64, r_err: f64, bound: f64) {
        assert!(
            s.is_finite() && s_err.is_finite(),
            "{what}: non-finite {s} ± {s_err}"
        );
        let sigma = (s_err * s_err + r_err * r_err).sqrt();
        let excess = ((s - r).abs() - bound).max(0.0);
        if sigma == 0.0 && bound == 0.0 {
            // An exact zero on both sides (a channel with no light) says nothing.
            assert_eq!(s, r, "{what}");
            return;
        }
        let z = if sigma > 0.0 {
            excess / sigma
        } else if excess > 0.0 {
            f64::INFINITY
        } else {
            0.0
        };
        self.lines.push(format!(
            "{key},{s:e},{s_err:e},{r:e},{r_err:e},{bound:e},{:.3}",
            (s - r) / sigma.max(f64::MIN_POSITIVE)
        ));
        self.row.push(z * z);
        self.worst = self.worst.max(z);
        if excess > K * sigma {
            self.failures.push(format!(
                "{what}: strata {s:.6} ± {s_err:.2e}, reference {r:.6} ± {r_err:.2e} (bound {bound:.1e}): |z| = {z:.2}"
            ));
        }
    }

    /// Closes a reference row: its channels' mean z² is one sample of the file's mean.
    fn end_row(&mut self) {
        if !self.row.is_empty() {
            self.z2
                .push(self.row.iter().sum::<f64>() / self.row.len() as f64);
            self.row.clear();
        }
    }

    /// `shared`: how many rows may share one reference error (2 where both runs are compared
    /// with the same noisy reference row, 1 for deterministic references).
    fn finish(mut self, name: &str, shared: f64, min_rows: usize) {
        self.end_row();
        if let Ok(dir) = std::env::var("STRATA_VALIDATION_OUT") {
            let path = format!("{dir}/{name}.strata.csv");
            let text = format!(
                "run,case,quantity,theta_i,theta_o,phi_o,channel,strata,strata_sigma,reference,reference_sigma,bound,z\n{}\n",
                self.lines.join("\n")
            );
            std::fs::write(&path, text).unwrap_or_else(|e| panic!("{path}: {e}"));
        }
        let n = self.z2.len();
        let comparisons = self.lines.len();
        let mean = self.z2.iter().sum::<f64>() / n as f64;
        eprintln!(
            "{name}: {comparisons} comparisons in {n} rows, mean z² {mean:.3}, worst |z| {:.2}",
            self.worst
        );
        assert!(
            self.failures.is_empty(),
            "{name}: {} of {comparisons} comparisons outside {K} sigma:\n{}",
            self.failures.len(),
            self.failures.join("\n")
        );
        assert!(n >= min_rows, "{name}: only {n} rows");
        // z² has mean 1 and variance 2 per independent comparison; a row's channels may be
        // fully correlated, so its mean z² has variance at most 2, and the file's mean at most
        // 2 shared / n: allow 4 of those standard deviations.
        let max = 1.0 + 4.0 * (2.0 * shared / n as f64).sqrt();
        assert!(
            mean <= max,
            "{name}: mean z² = {mean:.3} over {n} rows (a correct estimator: 1, allowed {max:.2})"
        );
    }
}

/// strata's value for a reference row: (value, stderr) per channel.
fn strata_value(bsdf: &LayeredBsdf, row: &Row, walks: u64, cone_dirs: usize) -> [(f64, f64); 3] {
    let (ti, pi) = (row.num("theta_i"), row.num_or("phi_i", 0.0));
    let wi = dir(ti, pi);
    match row.get("quantity").unwrap() {
        q @ ("R" | "T") => {
            let a = bsdf.albedo(vec3(wi), walks).expect("albedo");
            let e = if q == "R" { a.reflected } else { a.transmitted };
            [0, 1, 2].map(|c| (e.value[c], e.stderr[c]))
        }
        "f" => {
            let wo = dir(row.num("theta_o"), row.num("phi_o"));
            let e = bsdf.eval(vec3(wi), vec3(wo)).expect("eval");
            [0, 1, 2].map(|c| (e.value[c], e.stderr[c]))
        }
        "cone" => {
            // I = ∫_cone f(w, wo) |cos θ_w| dω: Ω × the mean of f |cos| over uniform directions
            // in the cone; its error from the spread of the per-direction estimates.
            let wo = dir(row.num("theta_o"), row.num("phi_o"));
            let delta = row.num("delta_deg").to_radians();
            let omega = 2.0 * std::f64::consts::PI * (1.0 - delta.cos());
            let mut u = reference::SplitMix(0x5EED ^ bsdf.seed_value());
            let dirs: Vec<[f64; 3]> = (0..cone_dirs).map(|_| in_cone(wi, delta, &mut u)).collect();
            let pairs: Vec<_> = dirs.iter().map(|w| (vec3(*w), vec3(wo))).collect();
            let keys: Vec<u64> = (0..cone_dirs as u64).collect();
            let per_dir = (walks / cone_dirs as u64).max(1);
            let est = bsdf
                .eval_batch_keyed(&pairs, per_dir, &keys)
                .expect("eval batch");
            [0, 1, 2].map(|c| {
                let v: Vec<f64> = est
                    .iter()
                    .zip(&dirs)
                    .map(|(e, w)| omega * e.value[c] * w[2].abs())
                    .collect();
                let m = v.iter().sum::<f64>() / v.len() as f64;
                let var = v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (v.len() - 1) as f64;
                (m, (var / v.len() as f64).sqrt())
            })
        }
        other => panic!("unknown quantity {other}"),
    }
}

/// Compares every row of a point-reference file (exact.csv, mitsuba.csv).
fn point_file(name: &str, walks: u64, cone_dirs: usize) {
    let rows = read_csv(name);
    let mut tally = Tally::default();
    for (engine, seed, label) in RUNS {
        let mut cache: Option<(String, LayeredBsdf)> = None;
        for row in &rows {
            let mat = row.get("material").unwrap().to_owned();
            if cache.as_ref().map(|(m, _)| m != &mat).unwrap_or(true) {
                // The walks are what this suite validates: a closed form
                // (`Estimator::Auto`) is checked on its own below.
                let b = LayeredBsdf::new(material(&mat))
                    .engine(engine)
                    .seed(seed)
                    .samples(walks)
                    .estimator(Estimator::Unidirectional);
                cache = Some((mat.clone(), b));
            }
            let bsdf = &cache.as_ref().unwrap().1;
            let s = strata_value(bsdf, row, walks, cone_dirs);
            let (r, rs, rb) = (
                row.rgb("ref", 0.0),
                row.rgb("sigma", 0.0),
                row.rgb("bound", 0.0),
            );
            // A grey stack's channels are the same walks and the same reference: compare one.
            let grey = s.iter().all(|x| *x == s[0]) && r.iter().all(|x| *x == r[0]);
            for c in 0..if grey { 1 } else { 3 } {
                let ch = if grey {
                    "grey".to_owned()
                } else {
                    c.to_string()
                };
                let what = format!(
                    "{label} {} {} θi {} θo {} φo {} ch {ch}",
                    row.get("case").unwrap(),
                    row.get("quantity").unwrap(),
                    row.get("theta_i").unwrap(),
                    row.get("theta_o").unwrap_or(""),
                    row.get("phi_o").unwrap_or(""),
                );
                let key = format!(
                    "{label},{},{},{},{},{},{ch}",
                    row.get("case").unwrap(),
                    row.get("quantity").unwrap(),
                    row.get("theta_i").unwrap(),
                    row.get("theta_o").unwrap_or(""),
                    row.get("phi_o").unwrap_or(""),
                );
                tally.check(&key, &what, s[c].0, s[c].1, r[c], rs[c], rb[c]);
            }
            tally.end_row();
        }
    }
    let shared = if rows
        .iter()
        .any(|r| r.rgb("sigma", 0.0).iter().any(|&x| x > 0.0))
    {
        2.0
    } else {
        1.0
    };
    tally.finish(name, shared, rows.len());
}

#[test]
fn exact_solutions() {
    point_file("exact.csv", 400_000, 0);
}

/// The library's closed form of a smooth coat over an absorbing layer over a
/// Lambertian base (`Estimator::Auto`, standard error 0) against the suite's
/// own exact solution (numpy, f64, `validation/exact.py`): equal to 1e-6
/// relative plus the reference's bound. (The directions cross the API as
/// f32: at 80° their rounding alone moves the Fresnel factors by 2e-8.)
#[test]
fn closed_form_against_the_exact_solution() {
    let rows = read_csv("exact.csv");
    let mut compared = 0;
    for row in rows.iter().filter(|r| r.get("quantity") == Some("f")) {
        let mat = row.get("material").unwrap();
        let bsdf = LayeredBsdf::new(material(mat));
        let s = strata_value(&bsdf, row, 1, 1);
        let (r, rb) = (row.rgb("ref", 0.0), row.rgb("bound", 0.0));
        if s.iter().any(|x| x.1 > 0.0) {
            continue; // no closed form: the walks answered (checked above)
        }
        for c in 0..3 {
            let tol = rb[c] + 1e-6 * r[c].abs();
            assert!(
                (s[c].0 - r[c]).abs() <= tol,
                "{mat} θi {} θo {} ch {c}: closed form {} vs exact {} (tolerance {tol:e})",
                row.num("theta_i"),
                row.num("theta_o"),
                s[c].0,
                r[c]
            );
            compared += 1;
        }
    }
    assert!(
        compared >= 12,
        "only {compared} closed-form values compared"
    );
}

/// The factorization of a rough coat over a Lambertian base
/// (`estimator::rough_coat`, `Estimator::Auto`, no walks) against Mitsuba's
/// explicit slab of `rough_coat_lambertian.toml`: the cone-integrated BSDF
/// rows, within 4 combined standard errors (both seeds), on
/// the same cone directions as the walks above.
#[test]
fn rough_factorization_against_mitsuba() {
    let rows = read_csv("mitsuba.csv");
    let mut compared = 0;
    for (engine, seed, label) in RUNS {
        let bsdf = LayeredBsdf::new(material("rough_coat_lambertian.toml"))
            .engine(engine)
            .seed(seed);
        assert!(bsdf.eval_without_walks());
        let of_it = |r: &&Row| {
            r.get("material") == Some("rough_coat_lambertian.toml")
                && r.get("quantity") == Some("cone")
        };
        for row in rows.iter().filter(of_it) {
            let s = strata_value(&bsdf, row, 1 << 20, 512);
            let (r, rs) = (row.rgb("ref", 0.0), row.rgb("sigma", 0.0));
            for c in 0..3 {
                let z = (s[c].0 - r[c]) / s[c].1.hypot(rs[c]);
                eprintln!(
                    "{label} θi {} ch {c}: factorized {:.6e} ± {:.1e}, Mitsuba {:.6e} ± {:.1e}, z {z:+.2}",
                    row.num("theta_i"),
                    s[c].0,
                    s[c].1,
                    r[c],
                    rs[c]
                );
                assert!(
                    z.abs() <= K,
                    "{label} θi {} ch {c}: z = {z}",
                    row.num("theta_i")
                );
                compared += 1;
            }
        }
    }
    assert!(compared >= 18, "only {compared} values compared");
}

/// The walk-free sampler of a rough coat over a Lambertian base
/// (`RoughCoatLambertian::sample`, `Estimator::Auto`): the mean of its
/// weights is the directional albedo, against Mitsuba's explicit slab of
/// `rough_coat_lambertian.toml` (its two albedo rows, three channels, both
/// two seeds), within 4 combined standard errors.
#[test]
fn rough_sampler_against_mitsuba() {
    let rows = read_csv("mitsuba.csv");
    let mut compared = 0;
    for (engine, seed, label) in RUNS {
        let bsdf = LayeredBsdf::new(material("rough_coat_lambertian.toml"))
            .engine(engine)
            .seed(seed);
        assert!(bsdf.sample_is_exact());
        let of_it = |r: &&Row| {
            r.get("material") == Some("rough_coat_lambertian.toml")
                && r.get("quantity") == Some("R")
        };
        for row in rows.iter().filter(of_it) {
            let wi = vec3(dir(row.num("theta_i"), row.num_or("phi_i", 0.0)));
            let n = 400_000;
            let idx: Vec<u64> = (0..n).collect();
            let s = bsdf
                .sample_batch_keyed(&vec![wi; n as usize], &vec![1; n as usize], &idx)
                .unwrap();
            let (r, rs) = (row.rgb("ref", 0.0), row.rgb("sigma", 0.0));
            for c in 0..3 {
                let w: Vec<f64> = s
                    .iter()
                    .map(|x| x.map_or(0.0, |x| x.weight[c] as f64))
                    .collect();
                let mean = w.iter().sum::<f64>() / n as f64;
                let var = w.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / (n - 1) as f64;
                let z = (mean - r[c]) / (var / n as f64 + rs[c] * rs[c]).sqrt();
                eprintln!(
                    "{label} R(θi {}) ch {c}: mean weight {mean:.6}, Mitsuba {:.6} ± {:.1e}, z {z:+.2}",
                    row.num("theta_i"),
                    r[c],
                    rs[c]
                );
                assert!(
                    z.abs() <= K,
                    "{label} θi {} ch {c}: z = {z}",
                    row.num("theta_i")
                );
                compared += 1;
            }
        }
    }
    assert!(compared >= 12, "only {compared} values compared");
}

#[test]
fn mitsuba_explicit_slab() {
    point_file("mitsuba.csv", 1 << 20, 512);
}

/// The paper's Fig. 2 "Validation 1" stack (Beckmann), its own file (a separate run).
#[test]
fn mitsuba_paper_validation1() {
    point_file("mitsuba_validation1.csv", 1 << 20, 512);
}

/// The transmissive slab lit from below (θi > 90°), its own file (a separate run).
#[test]
fn mitsuba_from_below() {
    point_file("mitsuba_below.csv", 1 << 20, 512);
}

/// A slab between air above and glass (1.5) below: transmitted radiance carries the n²
/// factor; its own file (a separate run).
#[test]
fn mitsuba_exteriors_of_different_ior() {
    point_file("mitsuba_glass.csv", 1 << 20, 512);
}

/// A scattering slab between smooth boundaries at oblique incidence; its own file.
#[test]
fn mitsuba_smooth_slab_oblique() {
    point_file("mitsuba_smooth.csv", 1 << 20, 512);
}

#[test]
fn iadpython_adding_doubling() {
    let rows = read_csv("iad.csv");
    let mut tally = Tally::default();
    for (engine, seed, label) in RUNS {
        for row in &rows {
            let (n, tau, a, g) = (
                row.num("ior"),
                row.num("tau"),
                row.num("albedo"),
                row.num("g"),
            );
            let st = stack(&format!(
                r#"
                [[layers]]
                interface = {{ kind = "dielectric", ior = {n} }}
                medium = {{ thickness = 1.0, sigma_t = {tau}, albedo = {a}, phase = {{ kind = "hg", g = {g} }} }}
                [[layers]]
                interface = {{ kind = "dielectric", ior = 1.0 }}
                "#
            ));
            let bsdf = LayeredBsdf::new(st).engine(engine).seed(seed);
            let al = bsdf.albedo(vec3(dir(0.0, 0.0)), 200_000).expect("albedo");
            let what = format!("{label} n {n} τ {tau} a {a} g {g}");
            // Grey slab: the three channels are the same walks; compare one.
            let case = format!("iad n={n} tau={tau} a={a} g={g}");
            tally.check(
                &format!("{label},{case},R,0,,,grey"),
                &format!("{what} R"),
                al.reflected.value[0],
                al.reflected.stderr[0],
                row.num("R"),
                0.0,
                row.num("quad_err_R"),
            );
            tally.end_row();
            tally.check(
                &format!("{label},{case},T,0,,,grey"),
                &format!("{what} T"),
                al.transmitted.value[0],
                al.transmitted.stderr[0],
                row.num("T"),
                0.0,
                row.num("quad_err_T"),
            );
            tally.end_row();
        }
    }
    tally.finish("iad.csv", 1.0, 4 * rows.len());
}
