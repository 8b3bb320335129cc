//! Error against run time: how fast each estimator converges to a reference.
//!
//! For a [`QuerySet`] (queries `f(wi, wo)` and directional albedos), this
//! module
//! 1. runs every [`Estimator`] at doubling sample budgets (a [`LadderSpec`]),
//!    timing each run on one thread;
//! 2. computes a [`Reference`]: the closed form where one exists (a smooth
//!    dielectric over a Lambertian base with no attenuating medium,
//!    method.md §8), otherwise a long run of an unbiased estimator (the scalar
//!    reference by default), extended in parallel chunks until its RMS
//!    relative standard error is at least 10× below the smallest error plotted
//!    (the expected error: the larger of a run's measured error and the one
//!    its own standard errors predict, so that a lucky point does not set it);
//! 3. reports, per run, the RMS relative error over all queries and channels,
//!    the RMS of the estimator's own relative standard errors (what the error
//!    should be if the estimator is unbiased), and the efficiency
//!    `1 / (error² × time)` (per run, and for a curve `1 / mean(error² ×
//!    time)` over the upper half of its ladder); as CSV, markdown and a text
//!    summary.
//!
//! Binned estimators (the brute-force baseline) estimate the `|cos|`-weighted
//! average of `f` over a cone, not `f(wo)`: the reference also holds those bin
//! averages, so the report can show the baseline's binning floor (the RMS
//! relative difference between bin average and point value), below which its
//! error cannot fall.
//!
//! Plotting lives in the CLI (`strata converge`); nothing here writes files.
//! To add an estimator (the wavefront engine, a bidirectional one): implement
//! [`Estimator`] for it, add a variant to [`EstimatorKind`] with its arm in
//! [`EstimatorKind::build`] and [`EstimatorKind::parse`], and list it in
//! [`ESTIMATORS`] (what `strata converge --suite docs` runs).

use crate::brute_force::{Bin, BruteForce, BruteSettings};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;
use std::fmt::Write as _;
use std::time::Instant;
use strata_bsdf::estimator::scalar::ScalarEngine;
use strata_bsdf::estimator::wavefront::{Plan, Wavefront};
use strata_bsdf::estimator::{Albedo, Estimate, Settings};
use strata_bsdf::rng::{mix64, Stream, WalkRng};
use strata_bsdf::stack::{InterfaceKind, LayerStack};

/// Bump when a change makes cached references invalid.
const CACHE_VERSION: u64 = 1;

// ------------------------------------------------------------------ queries

/// One BSDF query: `f(wi, wo)`, unit directions pointing away from the surface.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FQuery {
    /// Towards the light.
    pub wi: [f64; 3],
    /// Towards the viewer.
    pub wo: [f64; 3],
}

/// What a convergence run measures: BSDF values and directional albedos.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct QuerySet {
    /// `f(wi, wo)` queries.
    pub f: Vec<FQuery>,
    /// Incident directions of the albedo queries (reflected and, for a
    /// transmissive stack, transmitted fraction).
    pub albedo: Vec<[f64; 3]>,
}

/// The unit direction at polar angle `theta_deg` from +z and azimuth `phi_deg`.
pub fn direction(theta_deg: f64, phi_deg: f64) -> [f64; 3] {
    let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
    [t.sin() * p.cos(), t.sin() * p.sin(), t.cos()]
}

/// The unit direction along `d`, as the API normalizes it
/// ([`strata_bsdf::Direction`]): any finite nonzero vector.
fn normalize(d: [f64; 3]) -> Option<[f64; 3]> {
    strata_bsdf::Direction::from_f64("direction", d)
        .ok()
        .map(|d| d.get())
}

/// Why light cannot answer the query `(wi, wo)` (`wo` `None`: an albedo
/// query) on `stack`, by the engines' own rule, or `None` if it can. Such a
/// query is zero for every estimator, so a study of it measures nothing.
pub fn unanswerable(
    stack: &LayerStack,
    wi: [f64; 3],
    wo: Option<[f64; 3]>,
) -> Option<&'static str> {
    if strata_bsdf::estimator::orient(stack, wi, wo).is_some() {
        return None;
    }
    let grazing = |d: [f64; 3]| d[2].abs() < strata_bsdf::estimator::MIN_COS;
    Some(if grazing(wi) || wo.is_some_and(grazing) {
        "a direction within cos 1e-18 of the horizon: no light enters or leaves there"
    } else if wi[2] < 0.0 && !stack.two_sided() {
        "light from below, and the stack is opaque and one-sided: it takes no light there"
    } else {
        "wo is on the other side of the surface from wi, and the stack is opaque: it sends no \
         light there"
    })
}

impl QuerySet {
    /// The built-in set: light from 30° and 60° (azimuth 0); for each, views
    /// straight above, at the mirror direction, off the plane of incidence
    /// (45°, azimuth 90°) and back towards the light (65°); for a transmissive
    /// stack also straight below, along the unscattered transmission `-wi`,
    /// and off-plane below (135°, azimuth 90°). The albedo from 10°, 30°,
    /// 60° and 80°.
    pub fn default_for(stack: &LayerStack) -> Self {
        let mut q = QuerySet::default();
        for ti in [30.0, 60.0] {
            let wi = direction(ti, 0.0);
            let mut wos = vec![(0.0, 0.0), (ti, 180.0), (45.0, 90.0), (65.0, 0.0)];
            if stack.transmissive() {
                wos.extend([(180.0, 0.0), (180.0 - ti, 180.0), (135.0, 90.0)]);
            }
            for (t, p) in wos {
                q.f.push(FQuery {
                    wi,
                    wo: direction(t, p),
                });
            }
        }
        q.albedo = [10.0, 30.0, 60.0, 80.0]
            .iter()
            .map(|&t| direction(t, 0.0))
            .collect();
        q
    }

    /// Parses JSON lines: `{"wi":[x,y,z],"wo":[x,y,z]}` is a BSDF query,
    /// `{"wi":[x,y,z]}` an albedo query. Blank lines and lines starting with
    /// `#` are skipped; directions are normalized. Errors name the line.
    pub fn parse_json_lines(text: &str) -> Result<Self, String> {
        #[derive(Deserialize)]
        #[serde(deny_unknown_fields)]
        struct Line {
            wi: [f64; 3],
            wo: Option<[f64; 3]>,
        }
        let mut q = QuerySet::default();
        for (i, line) in text.lines().enumerate() {
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let n = i + 1;
            let l: Line = serde_json::from_str(line).map_err(|e| {
                format!(
                    "line {n}: invalid query (expected {{\"wi\":[x,y,z],\"wo\":[x,y,z]}} or {{\"wi\":[x,y,z]}}): {e}"
                )
            })?;
            let dir = |name: &str, v: [f64; 3]| {
                normalize(v)
                    .filter(|d| d[2] != 0.0)
                    .ok_or_else(|| format!("line {n}: {name} = {v:?} is not a direction (finite, non-zero, not exactly grazing)"))
            };
            let wi = dir("wi", l.wi)?;
            match l.wo {
                Some(wo) => q.f.push(FQuery {
                    wi,
                    wo: dir("wo", wo)?,
                }),
                None => q.albedo.push(wi),
            }
        }
        if q.f.is_empty() && q.albedo.is_empty() {
            return Err("the query file holds no query".into());
        }
        Ok(q)
    }

    /// The distinct incident directions, in order of first appearance (BSDF
    /// queries first).
    pub fn incident(&self) -> Vec<[f64; 3]> {
        let mut v: Vec<[f64; 3]> = Vec::new();
        for w in self
            .f
            .iter()
            .map(|q| q.wi)
            .chain(self.albedo.iter().copied())
        {
            if !v.contains(&w) {
                v.push(w);
            }
        }
        v
    }
}

// ----------------------------------------------------------------- progress

/// Progress of a long computation (the CLI shows a bar; the library and the
/// tests use [`Silent`]).
pub trait Progress: Sync {
    /// A stage starts with `total` units of work.
    fn begin(&self, _label: &str, _total: u64) {}
    /// `n` more units are done.
    fn advance(&self, _n: u64) {}
    /// The stage is over.
    fn end(&self) {}
}

/// Reports nothing.
pub struct Silent;
impl Progress for Silent {}

// --------------------------------------------------------------- estimators

/// One run of an estimator at one budget.
#[derive(Clone, Debug, PartialEq)]
pub struct Run {
    /// Walks per BSDF query (position-free) or per incident direction (brute
    /// force, whose walks serve every query with that `wi` at once).
    pub samples: u64,
    /// One estimate per [`QuerySet::f`] entry.
    pub f: Vec<Estimate>,
    /// One per [`QuerySet::albedo`] entry.
    pub albedo: Vec<Albedo>,
    /// Wall time of the BSDF queries, seconds (one thread).
    pub time_f: f64,
    /// Wall time of the albedo queries, seconds (one thread). The brute force
    /// gets both from the same walks where they share an incident direction,
    /// and counts the time of those walks in full in each.
    pub time_albedo: f64,
    /// Wall time of the whole run, seconds.
    pub time: f64,
    /// Throughput lost through the sides of a finite slab, per walk (0 for
    /// position-free estimators).
    pub lost_weight: f64,
}

/// An estimator of `f` and of the albedo whose convergence is measured.
pub trait Estimator: Sync {
    /// Short identifier (CSV, file names): `scalar`, `brute-5deg`.
    fn name(&self) -> String;
    /// One line for tables and legends.
    fn description(&self) -> String;
    /// The cone half-angle (radians) when `f` is estimated by binning, which
    /// gives a bias floor; `None` for unbiased estimators.
    fn bin_half_angle(&self) -> Option<f64> {
        None
    }
    /// The first budget of a ladder.
    fn start_samples(&self) -> u64;
    /// Runs every query of `qs` with `samples` walks and seed `seed`, timing
    /// the BSDF and albedo parts.
    fn run(&self, qs: &QuerySet, samples: u64, seed: u64) -> Run;
}

/// The estimators `strata converge` knows.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum EstimatorKind {
    /// The position-free unidirectional scalar reference ([`ScalarEngine<f32>`]).
    Scalar,
    /// The position-free unidirectional estimator on the SIMD wavefront
    /// engine: on one thread (`threads: Some(1)`, for a like-for-like
    /// comparison with the scalar row) or on the current thread pool (`None`).
    /// Its walks are the scalar reference's (same seeds), so its errors are
    /// the scalar row's and only the time differs.
    Wavefront {
        /// Threads of its own pool; `None` runs on the current rayon pool.
        threads: Option<usize>,
    },
    /// The position-free bidirectional estimator (`estimator::bidir`) on
    /// the scalar engine.
    Bidirectional,
    /// The bidirectional estimator on the SIMD wavefront engine (one walk
    /// per lane): on one thread (`Some(1)`) or on the current pool (`None`).
    /// Its walks are the scalar row's.
    BidirectionalWavefront {
        /// Threads of its own pool; `None` runs on the current rayon pool.
        threads: Option<usize>,
    },
    /// The position-based baseline with cone bins of this half-angle.
    BruteForce {
        /// Half-angle of the bins, degrees.
        half_angle_deg: f64,
    },
}

/// The estimators of a default run and of `strata converge --suite docs`.
/// Add the wavefront engine here once it has an [`EstimatorKind`] variant.
pub const ESTIMATORS: &[EstimatorKind] = &[
    EstimatorKind::Scalar,
    EstimatorKind::Wavefront { threads: Some(1) },
    EstimatorKind::Bidirectional,
    EstimatorKind::BidirectionalWavefront { threads: Some(1) },
    EstimatorKind::BruteForce {
        half_angle_deg: 5.0,
    },
];

/// The estimator long-run references use (it must be unbiased; the fastest
/// one is the best choice): the wavefront engine on the current pool.
pub const REFERENCE_ESTIMATOR: EstimatorKind = EstimatorKind::Wavefront { threads: None };

/// The reference estimator for `stack`: the estimator `Estimator::Auto`
/// runs there (bidirectional on three interfaces or more and on
/// near-specular coated conductors), on the wavefront
/// engine on the current pool.
pub fn reference_for(stack: &LayerStack) -> EstimatorKind {
    if strata_bsdf::Estimator::bidirectional_pays(stack) {
        EstimatorKind::BidirectionalWavefront { threads: None }
    } else {
        REFERENCE_ESTIMATOR
    }
}

impl EstimatorKind {
    /// The estimator for `stack`.
    pub fn build(&self, stack: &LayerStack, settings: Settings) -> Box<dyn Estimator> {
        match *self {
            EstimatorKind::Scalar | EstimatorKind::Bidirectional => Box::new(ScalarEstimator {
                eng: ScalarEngine::new(stack, settings),
                bidir: *self == EstimatorKind::Bidirectional,
            }),
            EstimatorKind::Wavefront { threads }
            | EstimatorKind::BidirectionalWavefront { threads } => Box::new(WavefrontEstimator {
                wf: Wavefront::new(stack, settings, Plan::Specialized),
                pool: threads.map(|n| {
                    rayon::ThreadPoolBuilder::new()
                        .num_threads(n)
                        .build()
                        .expect("a thread pool")
                }),
                bidir: matches!(self, EstimatorKind::BidirectionalWavefront { .. }),
            }),
            EstimatorKind::BruteForce { half_angle_deg } => Box::new(BruteEstimator {
                bf: BruteForce::new(
                    stack,
                    BruteSettings {
                        half_angle: half_angle_deg.to_radians(),
                        rr_start: settings.rr_start,
                        ..BruteSettings::default()
                    },
                ),
            }),
        }
    }

    /// `scalar`, `wavefront`, `wavefront-mt`, `bidir`, `bidir-wavefront`,
    /// `bidir-wavefront-mt`, `brute` (5° bins) or `brute:DEG`.
    pub fn parse(s: &str) -> Result<Self, String> {
        let s = s.trim();
        if s == "scalar" {
            return Ok(EstimatorKind::Scalar);
        }
        if s == "wavefront" {
            return Ok(EstimatorKind::Wavefront { threads: Some(1) });
        }
        if s == "wavefront-mt" {
            return Ok(EstimatorKind::Wavefront { threads: None });
        }
        if s == "bidir" {
            return Ok(EstimatorKind::Bidirectional);
        }
        if s == "bidir-wavefront" {
            return Ok(EstimatorKind::BidirectionalWavefront { threads: Some(1) });
        }
        if s == "bidir-wavefront-mt" {
            return Ok(EstimatorKind::BidirectionalWavefront { threads: None });
        }
        if s == "brute" {
            return Ok(EstimatorKind::BruteForce {
                half_angle_deg: 5.0,
            });
        }
        if let Some(d) = s.strip_prefix("brute:") {
            let v: f64 = d.parse().map_err(|_| {
                format!("estimator {s:?}: the bin half-angle {d:?} is not a number")
            })?;
            if !(v > 0.0 && v < 90.0) {
                return Err(format!(
                    "estimator {s:?}: the bin half-angle must be in (0, 90) degrees"
                ));
            }
            return Ok(EstimatorKind::BruteForce { half_angle_deg: v });
        }
        Err(format!(
            "unknown estimator {s:?} (known: scalar, wavefront, wavefront-mt, bidir, \
             bidir-wavefront, bidir-wavefront-mt, brute, brute:DEG)"
        ))
    }
}

/// Query key offset of albedo queries, so they never share streams with BSDF
/// queries of the same index.
const ALBEDO_KEY: u64 = 1 << 40;

/// The estimator of `f` a position-free row runs (`bidir`: the
/// bidirectional one, whose albedo columns are still `sample()`'s analog
/// walks: it is an estimator of `f` only), as its description says it:
/// the kind, and a note to append.
fn direction_label(bidir: bool) -> (&'static str, &'static str) {
    if bidir {
        ("bidirectional", " (albedo: analog walks)")
    } else {
        ("unidirectional", "")
    }
}

struct ScalarEstimator {
    eng: ScalarEngine<f32>,
    bidir: bool,
}

impl Estimator for ScalarEstimator {
    fn name(&self) -> String {
        if self.bidir { "bidir" } else { "scalar" }.into()
    }
    fn description(&self) -> String {
        let (kind, note) = direction_label(self.bidir);
        format!("position-free, {kind}, scalar reference{note}")
    }
    fn start_samples(&self) -> u64 {
        if self.bidir {
            16
        } else {
            64
        }
    }
    fn run(&self, qs: &QuerySet, samples: u64, seed: u64) -> Run {
        let t = Instant::now();
        let eval = |j: usize, q: &FQuery| match self.bidir {
            true => self.eng.eval_bidir(q.wi, q.wo, samples, seed, j as u64),
            false => self.eng.eval(q.wi, q.wo, samples, seed, j as u64),
        };
        let f = qs.f.iter().enumerate().map(|(j, q)| eval(j, q)).collect();
        let time_f = t.elapsed().as_secs_f64();
        let t2 = Instant::now();
        let albedo = qs
            .albedo
            .iter()
            .enumerate()
            .map(|(j, &wi)| self.eng.albedo(wi, samples, seed, ALBEDO_KEY + j as u64))
            .collect();
        Run {
            samples,
            f,
            albedo,
            time_f,
            time_albedo: t2.elapsed().as_secs_f64(),
            time: t.elapsed().as_secs_f64(),
            lost_weight: 0.0,
        }
    }
}

struct WavefrontEstimator {
    wf: Wavefront,
    pool: Option<rayon::ThreadPool>,
    bidir: bool,
}

impl Estimator for WavefrontEstimator {
    fn name(&self) -> String {
        let prefix = if self.bidir { "bidir-" } else { "" };
        match &self.pool {
            Some(p) if p.current_num_threads() == 1 => format!("{prefix}wavefront"),
            Some(p) => format!("{prefix}wavefront-{}t", p.current_num_threads()),
            None => format!("{prefix}wavefront-mt"),
        }
    }
    fn description(&self) -> String {
        let threads = match &self.pool {
            Some(p) => format!("{} thread(s)", p.current_num_threads()),
            None => "all threads".into(),
        };
        let (kind, note) = direction_label(self.bidir);
        format!("position-free, {kind}, SIMD wavefront, {threads}{note}")
    }
    fn start_samples(&self) -> u64 {
        if self.bidir {
            16
        } else {
            64
        }
    }
    fn run(&self, qs: &QuerySet, samples: u64, seed: u64) -> Run {
        let go = || {
            let t = Instant::now();
            let pairs: Vec<_> = qs.f.iter().map(|q| (q.wi, q.wo)).collect();
            let keys: Vec<u64> = (0..pairs.len() as u64).collect();
            let f = match self.bidir {
                true => self.wf.eval_bidir_batch(&pairs, samples, seed, &keys),
                false => self.wf.eval_batch(&pairs, samples, seed, &keys).0,
            };
            let time_f = t.elapsed().as_secs_f64();
            let t2 = Instant::now();
            let keys: Vec<u64> = (0..qs.albedo.len() as u64)
                .map(|j| ALBEDO_KEY + j)
                .collect();
            let albedo = self.wf.albedo_batch(&qs.albedo, samples, seed, &keys).0;
            Run {
                samples,
                f,
                albedo,
                time_f,
                time_albedo: t2.elapsed().as_secs_f64(),
                time: t.elapsed().as_secs_f64(),
                lost_weight: 0.0,
            }
        };
        match &self.pool {
            Some(p) => p.install(go),
            None => go(),
        }
    }
}

struct BruteEstimator {
    bf: BruteForce,
}

impl Estimator for BruteEstimator {
    fn name(&self) -> String {
        format!("brute-{}deg", self.bf.settings().half_angle.to_degrees())
    }
    fn description(&self) -> String {
        format!(
            "brute force, position-based, {}° bins",
            self.bf.settings().half_angle.to_degrees()
        )
    }
    fn bin_half_angle(&self) -> Option<f64> {
        Some(self.bf.settings().half_angle)
    }
    fn start_samples(&self) -> u64 {
        1024
    }
    fn run(&self, qs: &QuerySet, samples: u64, seed: u64) -> Run {
        let mut f = vec![zero_estimate(); qs.f.len()];
        let mut albedo = vec![
            Albedo {
                reflected: zero_estimate(),
                transmitted: zero_estimate(),
            };
            qs.albedo.len()
        ];
        let start = Instant::now();
        let mut lost = 0.0;
        let (mut time_f, mut time_albedo) = (0.0, 0.0);
        let incident = qs.incident();
        for (g, wi) in incident.iter().enumerate() {
            let t = Instant::now();
            let idx: Vec<usize> = (0..qs.f.len()).filter(|&j| qs.f[j].wi == *wi).collect();
            let wos: Vec<[f64; 3]> = idx.iter().map(|&j| qs.f[j].wo).collect();
            let r = self.bf.run(*wi, &wos, samples, seed, g as u64);
            for (k, &j) in idx.iter().enumerate() {
                f[j] = r.f[k];
            }
            let mut for_albedo = false;
            for (j, a) in qs.albedo.iter().enumerate() {
                if a == wi {
                    albedo[j] = r.albedo;
                    for_albedo = true;
                }
            }
            lost += r.lost_weight.iter().sum::<f64>() / 3.0 / incident.len() as f64;
            // The walks from one wi serve its BSDF and albedo queries alike:
            // their time counts in full for each.
            let dt = t.elapsed().as_secs_f64();
            if !idx.is_empty() {
                time_f += dt;
            }
            if for_albedo {
                time_albedo += dt;
            }
        }
        Run {
            samples,
            f,
            albedo,
            time_f,
            time_albedo,
            time: start.elapsed().as_secs_f64(),
            lost_weight: lost,
        }
    }
}

fn zero_estimate() -> Estimate {
    Estimate {
        value: [0.0; 3],
        stderr: [0.0; 3],
        samples: 0,
        truncated: 0,
    }
}

// ------------------------------------------------------------------- ladder

/// Doubling budgets for one estimator.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LadderSpec {
    /// Stop doubling once the next run would take the ladder past this many
    /// seconds (predicted as twice the last run).
    pub budget_seconds: f64,
    /// Always run at least this many budgets.
    pub min_steps: usize,
    /// Never run more than this many.
    pub max_steps: usize,
    /// First budget; `None` takes the estimator's own.
    pub start: Option<u64>,
}

impl Default for LadderSpec {
    fn default() -> Self {
        LadderSpec {
            budget_seconds: 2.0,
            min_steps: 4,
            max_steps: 24,
            start: None,
        }
    }
}

/// Runs `est` at budgets `start · 2^k`, each with its own seed (so the
/// points of a curve are independent), until the spec says stop. Runs
/// shorter than 50 ms are repeated up to four times and timed by the fastest.
pub fn ladder(
    est: &dyn Estimator,
    qs: &QuerySet,
    spec: &LadderSpec,
    seed: u64,
    progress: &dyn Progress,
) -> Vec<Run> {
    let mut runs: Vec<Run> = Vec::new();
    let mut n = spec.start.unwrap_or_else(|| est.start_samples()).max(2);
    let mut spent = 0.0;
    let units = (spec.budget_seconds * 1000.0).max(1.0) as u64;
    progress.begin(&est.name(), units);
    for k in 0..spec.max_steps {
        if k >= spec.min_steps {
            let last_total = runs.last().map_or(0.0, run_time);
            if spent + 2.0 * last_total > spec.budget_seconds {
                break;
            }
        }
        let step_seed = mix64(seed ^ mix64(k as u64 + 1));
        let mut r = est.run(qs, n, step_seed);
        // Short runs are timed again (same seed: the same result) and the
        // fastest time is kept: a loaded machine adds spikes, never removes time.
        for _ in 0..4 {
            if r.time >= 0.05 {
                break;
            }
            let again = est.run(qs, n, step_seed);
            r.time_f = r.time_f.min(again.time_f);
            r.time_albedo = r.time_albedo.min(again.time_albedo);
            r.time = r.time.min(again.time);
        }
        let dt = run_time(&r);
        spent += dt;
        progress.advance((dt * 1000.0) as u64);
        runs.push(r);
        n = n.saturating_mul(2);
    }
    progress.end();
    runs
}

fn run_time(r: &Run) -> f64 {
    r.time
}

// ---------------------------------------------------------------- reference

/// A running mean and variance per RGB channel (serializable, mergeable).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Acc {
    /// Samples merged.
    pub n: u64,
    /// Mean.
    pub mean: [f64; 3],
    /// Sum of squared deviations from the mean.
    pub m2: [f64; 3],
}

impl Acc {
    /// An exactly known value (no variance).
    pub fn exact(v: [f64; 3]) -> Self {
        Acc {
            n: 1,
            mean: v,
            m2: [0.0; 3],
        }
    }
    /// From a mean and its standard error over `e.samples` samples.
    pub fn from_estimate(e: &Estimate) -> Self {
        let n = e.samples as f64;
        Acc {
            n: e.samples,
            mean: e.value,
            m2: e.stderr.map(|s| s * s * n * (n - 1.0).max(0.0)),
        }
    }
    /// Merges another accumulator (Chan et al.).
    pub fn merge(&mut self, o: &Acc) {
        if o.n == 0 {
            return;
        }
        if self.n == 0 {
            *self = *o;
            return;
        }
        let (na, nb) = (self.n as f64, o.n as f64);
        let n = na + nb;
        for c in 0..3 {
            let d = o.mean[c] - self.mean[c];
            self.mean[c] += d * nb / n;
            self.m2[c] += o.m2[c] + d * d * na * nb / n;
        }
        self.n += o.n;
    }
    /// Standard error of the mean per channel.
    pub fn stderr(&self) -> [f64; 3] {
        if self.n < 2 {
            return [0.0; 3];
        }
        let n = self.n as f64;
        self.m2.map(|m| (m / (n - 1.0) / n).max(0.0).sqrt())
    }
}

/// A group of reference values extended chunk by chunk.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RefStream {
    /// Chunks merged so far (chunk `c` has its own seed).
    pub chunks: u64,
    /// Walks (or bin points) per target per chunk.
    pub per_chunk: u64,
    /// One accumulator per target.
    pub acc: Vec<Acc>,
}

impl RefStream {
    /// Whether the stream has no targets (a query set without queries of
    /// its kind).
    pub fn is_empty(&self) -> bool {
        self.acc.is_empty()
    }

    /// RMS over targets and channels (with a non-zero mean) of the relative
    /// standard error; infinite before the first chunk, 0 without targets.
    pub fn rms_rel_stderr(&self) -> f64 {
        if self.is_empty() {
            return 0.0;
        }
        if self.chunks == 0 && self.acc.iter().all(|a| a.n == 0) {
            return f64::INFINITY;
        }
        rms(self.acc.iter().flat_map(|a| {
            let se = a.stderr();
            (0..3)
                .filter(move |&c| a.mean[c] > 0.0)
                .map(move |c| se[c] / a.mean[c])
        }))
    }
}

fn rms(it: impl Iterator<Item = f64>) -> f64 {
    let (mut s, mut n) = (0.0, 0usize);
    for x in it {
        s += x * x;
        n += 1;
    }
    if n == 0 {
        0.0
    } else {
        (s / n as f64).sqrt()
    }
}

/// Where a reference comes from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum ReferenceKind {
    /// The closed form of a smooth dielectric over a Lambertian base
    /// (method.md §8): exact, no error bar.
    Analytic,
    /// A long run of this (unbiased) estimator.
    LongRun {
        /// Its name.
        estimator: String,
    },
}

/// Reference values for every target of a [`QuerySet`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Reference {
    /// Closed form or long run.
    pub kind: ReferenceKind,
    /// `f(wi, wo)` per BSDF query.
    pub f: RefStream,
    /// Reflected then transmitted fraction, per albedo query: `2 × len` targets.
    pub albedo: RefStream,
    /// Per bin half-angle (radians): the `|cos|`-weighted average of `f` over
    /// the cone bin of each BSDF query.
    pub bins: Vec<(f64, RefStream)>,
    /// Core-seconds spent computing it.
    pub seconds: f64,
}

impl Reference {
    /// `(value, stderr)` of BSDF query `j`.
    pub fn f(&self, j: usize) -> ([f64; 3], [f64; 3]) {
        let a = &self.f.acc[j];
        (a.mean, a.stderr())
    }
    /// `(R, T)` accumulators of albedo query `j`.
    pub fn albedo(&self, j: usize) -> (&Acc, &Acc) {
        (&self.albedo.acc[2 * j], &self.albedo.acc[2 * j + 1])
    }
    /// The bin averages for half-angle `h` (radians), if computed.
    pub fn bins(&self, h: f64) -> Option<&RefStream> {
        self.bins
            .iter()
            .find(|(x, _)| (x - h).abs() < 1e-12)
            .map(|(_, s)| s)
    }
    /// A one-line description for reports.
    pub fn describe(&self) -> String {
        match &self.kind {
            ReferenceKind::Analytic => {
                "closed form (smooth dielectric over Lambertian, method.md §8), exact".into()
            }
            ReferenceKind::LongRun { estimator } => {
                // Only the kinds of query the set has.
                let (mut walks, mut errors) = (Vec::new(), Vec::new());
                for (s, query, of) in [
                    (&self.f, "BSDF query", "f"),
                    (&self.albedo, "albedo query", "the albedo"),
                ] {
                    if !s.is_empty() {
                        walks.push(format!("{} walks per {query}", s.chunks * s.per_chunk));
                        errors.push(format!("{:.2e} for {of}", s.rms_rel_stderr()));
                    }
                }
                format!(
                    "long run of the {estimator} estimator: {} (RMS relative standard error {})",
                    walks.join(", "),
                    errors.join(", ")
                )
            }
        }
    }
}

/// Unpolarized Fresnel reflectance for light in a medium of IOR `n1` meeting
/// one of IOR `n2` at incidence cosine `ci` (1 under total internal reflection).
fn fresnel(ci: f64, n1: f64, n2: f64) -> f64 {
    let ci = ci.abs().min(1.0);
    let s2t = (n1 / n2).powi(2) * (1.0 - ci * ci);
    if s2t >= 1.0 {
        return 1.0;
    }
    let ct = (1.0 - s2t).sqrt();
    let rs = (n1 * ci - n2 * ct) / (n1 * ci + n2 * ct);
    let rp = (n2 * ci - n1 * ct) / (n2 * ci + n1 * ct);
    0.5 * (rs * rs + rp * rp)
}

/// `∫ F(μ) 2μ dμ` over the hemisphere, light in `n1` meeting `n2`.
fn fresnel_average(n1: f64, n2: f64) -> f64 {
    let n = 100_000;
    (0..n)
        .map(|k| {
            let mu = (k as f64 + 0.5) / n as f64;
            fresnel(mu, n1, n2) * 2.0 * mu / n as f64
        })
        .sum()
}

/// The closed form of a smooth dielectric over a Lambertian base with no
/// attenuating medium between them (method.md §8), or `None` for any other
/// stack. `f(wi, wo) = (1 - F(θi))(1 - F(θo)) ρ / (π η² (1 - ρ F̄_in))` and
/// `R(wi) = F(θi) + (1 - F(θi)) ρ (1 - F̄_out) / (η² (1 - ρ F̄_in))`, with
/// `F̄` the cosine-weighted hemispherical Fresnel averages inside and outside.
pub struct CoatOverLambert {
    n0: f64,
    n1: f64,
    rho: [f64; 3],
    fbar_in: f64,
    fbar_out: f64,
    two_sided: bool,
}

impl CoatOverLambert {
    /// Recognizes the stack.
    pub fn new(stack: &LayerStack) -> Option<Self> {
        let ifs = stack.interfaces();
        if ifs.len() != 2
            || ifs[0].kind != InterfaceKind::Dielectric
            || !ifs[0].smooth
            || ifs[1].kind != InterfaceKind::Diffuse
            || stack.medium(0).is_some_and(|m| m.attenuates())
        {
            return None;
        }
        let (n0, n1) = (ifs[0].n_above, ifs[0].n_below);
        Some(CoatOverLambert {
            n0,
            n1,
            rho: ifs[1].albedo,
            fbar_in: fresnel_average(n1, n0),
            fbar_out: fresnel_average(n0, n1),
            two_sided: stack.two_sided(),
        })
    }

    fn orient(&self, wi: [f64; 3], wo: [f64; 3]) -> Option<(f64, f64)> {
        let (mut zi, mut zo) = (wi[2], wo[2]);
        if zi < 0.0 && self.two_sided {
            zi = -zi;
            zo = -zo;
        }
        (zi > 0.0 && zo > 0.0).then_some((zi, zo))
    }

    /// `f(wi, wo)` without the cosine (non-delta part).
    pub fn f(&self, wi: [f64; 3], wo: [f64; 3]) -> [f64; 3] {
        let Some((ci, co)) = self.orient(wi, wo) else {
            return [0.0; 3];
        };
        let eta = self.n1 / self.n0;
        let t = (1.0 - fresnel(ci, self.n0, self.n1)) * (1.0 - fresnel(co, self.n0, self.n1));
        self.rho
            .map(|r| t * r / (PI * eta * eta * (1.0 - r * self.fbar_in)))
    }

    /// Reflected fraction (including the mirror reflection) for light from `wi`.
    pub fn reflected(&self, wi: [f64; 3]) -> [f64; 3] {
        let Some((ci, _)) = self.orient(wi, [0.0, 0.0, wi[2]]) else {
            return [0.0; 3];
        };
        let eta = self.n1 / self.n0;
        let fi = fresnel(ci, self.n0, self.n1);
        self.rho.map(|r| {
            fi + (1.0 - fi) * r * (1.0 - self.fbar_out) / (eta * eta * (1.0 - r * self.fbar_in))
        })
    }

    /// The `|cos|`-weighted average of `f` over a cone bin, by a 200 × 200
    /// midpoint rule in the cone's polar coordinates.
    pub fn bin_average(&self, wi: [f64; 3], bin: &Bin) -> [f64; 3] {
        let (nr, np) = (200, 200);
        let h = bin.half_angle();
        let a = bin.axis();
        let helper = if a[0].abs() < 0.6 {
            [1.0, 0.0, 0.0]
        } else {
            [0.0, 1.0, 0.0]
        };
        let t = unit(cross(helper, a));
        let b = cross(a, t);
        let mut s = [0.0; 3];
        for i in 0..nr {
            let rho = (i as f64 + 0.5) * h / nr as f64;
            let (sr, cr) = rho.sin_cos();
            for k in 0..np {
                let psi = (k as f64 + 0.5) * 2.0 * PI / np as f64;
                let (sp, cp) = psi.sin_cos();
                let w = [0, 1, 2].map(|c| cr * a[c] + sr * (cp * t[c] + sp * b[c]));
                if !bin.contains(w) {
                    continue;
                }
                let f = self.f(wi, w);
                let dw = sr * (h / nr as f64) * (2.0 * PI / np as f64);
                for c in 0..3 {
                    s[c] += f[c] * w[2].abs() * dw;
                }
            }
        }
        s.map(|x| x / bin.measure())
    }
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn unit(a: [f64; 3]) -> [f64; 3] {
    normalize(a).unwrap_or([0.0, 0.0, 1.0])
}

/// The exact reference when the stack has a closed form.
pub fn analytic_reference(stack: &LayerStack, qs: &QuerySet, bins: &[f64]) -> Option<Reference> {
    let cf = CoatOverLambert::new(stack)?;
    let exact = |acc: Vec<Acc>| RefStream {
        chunks: 0,
        per_chunk: 0,
        acc,
    };
    Some(Reference {
        kind: ReferenceKind::Analytic,
        f: exact(qs.f.iter().map(|q| Acc::exact(cf.f(q.wi, q.wo))).collect()),
        albedo: exact(
            qs.albedo
                .iter()
                .flat_map(|&wi| [Acc::exact(cf.reflected(wi)), Acc::exact([0.0; 3])])
                .collect(),
        ),
        bins: bins
            .iter()
            .map(|&h| {
                let acc =
                    qs.f.iter()
                        .map(|q| Acc::exact(cf.bin_average(q.wi, &Bin::new(q.wo, h))))
                        .collect();
                (h, exact(acc))
            })
            .collect(),
        seconds: 0.0,
    })
}

/// How a long-run reference is extended.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReferenceSpec {
    /// Seed of the reference's streams (distinct from the runs measured).
    pub seed: u64,
    /// Walks per BSDF or albedo query per chunk.
    pub chunk_samples: u64,
    /// Directions per bin per chunk for the bin averages.
    pub bin_points: u64,
    /// Stop extending after this many wall-clock seconds, even if the target
    /// precision is not reached (the report then says so).
    pub max_seconds: f64,
}

impl Default for ReferenceSpec {
    fn default() -> Self {
        ReferenceSpec {
            seed: 0x5eed_0f7e_f00d,
            chunk_samples: 4096,
            bin_points: 4096,
            max_seconds: 300.0,
        }
    }
}

/// An empty long-run reference for `qs`, to be extended.
pub fn empty_reference(
    est: &dyn Estimator,
    qs: &QuerySet,
    bins: &[f64],
    spec: &ReferenceSpec,
) -> Reference {
    let stream = |n: usize, per: u64| RefStream {
        chunks: 0,
        per_chunk: per,
        acc: vec![Acc::default(); n],
    };
    Reference {
        kind: ReferenceKind::LongRun {
            estimator: est.name(),
        },
        f: stream(qs.f.len(), spec.chunk_samples),
        albedo: stream(2 * qs.albedo.len(), spec.chunk_samples),
        bins: bins
            .iter()
            .map(|&h| (h, stream(qs.f.len(), spec.bin_points)))
            .collect(),
        seconds: 0.0,
    }
}

/// Precision targets (RMS relative standard error) of a reference.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Targets {
    /// For the BSDF values.
    pub f: f64,
    /// For the albedos.
    pub albedo: f64,
    /// For the bin averages (relaxed to 5 % of the binning floor when that
    /// is larger: they only serve to draw the floor).
    pub bins: f64,
}

/// One chunk of a stream: estimates for all its targets.
fn chunk_estimates(
    est: &dyn Estimator,
    qs: &QuerySet,
    which: usize,
    r: &Reference,
    chunk: u64,
    spec: &ReferenceSpec,
) -> Vec<Estimate> {
    let seed = mix64(spec.seed ^ mix64((which as u64) << 48 ^ chunk));
    match which {
        0 => {
            let q = QuerySet {
                f: qs.f.clone(),
                albedo: vec![],
            };
            est.run(&q, r.f.per_chunk, seed).f
        }
        1 => {
            let q = QuerySet {
                f: vec![],
                albedo: qs.albedo.clone(),
            };
            est.run(&q, r.albedo.per_chunk, seed)
                .albedo
                .into_iter()
                .flat_map(|a| [a.reflected, a.transmitted])
                .collect()
        }
        _ => {
            // Bin averages: directions uniform in each cone, one walk each;
            // E[f |cos| 1_bin] · (cone solid angle) / ∫_bin |cos| is the average.
            let (h, s) = &r.bins[which - 2];
            let per = s.per_chunk;
            let mut pts = Vec::new();
            let mut owner = Vec::new();
            let mut outside = vec![0u64; qs.f.len()];
            for (j, q) in qs.f.iter().enumerate() {
                let bin = Bin::new(q.wo, *h);
                for k in 0..per {
                    let mut rng = WalkRng::new(seed, j as u64, k, Stream::Pdf);
                    let w = bin.sample_cone(rng.uniform() as f64, rng.uniform() as f64);
                    if bin.contains(w) {
                        pts.push(FQuery { wi: q.wi, wo: w });
                        owner.push((j, bin));
                    } else {
                        outside[j] += 1;
                    }
                }
            }
            let q = QuerySet {
                f: pts,
                albedo: vec![],
            };
            let run = est.run(&q, 1, mix64(seed ^ 0xb1b1));
            let mut acc = vec![strata_bsdf::estimator::MeanVar::new(); qs.f.len()];
            for ((j, bin), (e, p)) in owner.iter().zip(run.f.iter().zip(&q.f)) {
                let s = bin.cone_solid_angle() / bin.measure() * p.wo[2].abs();
                acc[*j].push(e.value.map(|v| v * s));
            }
            for (j, n) in outside.iter().enumerate() {
                for _ in 0..*n {
                    acc[j].push([0.0; 3]);
                }
            }
            acc.iter().map(|a| a.estimate()).collect()
        }
    }
}

/// Extends a long-run reference in parallel chunks (rayon) until each stream
/// meets its target or `spec.max_seconds` pass. Returns whether every target
/// was met. Deterministic whatever the thread count: chunk `c` of a stream
/// always has the same seed, the number of chunks depends only on the
/// targets and the estimates, and chunks merge in order.
pub fn extend_reference(
    r: &mut Reference,
    est: &dyn Estimator,
    qs: &QuerySet,
    targets: Targets,
    spec: &ReferenceSpec,
    progress: &dyn Progress,
) -> bool {
    if r.kind == ReferenceKind::Analytic {
        return true;
    }
    let start = Instant::now();
    // The first round's chunks per stream, and the least a later round adds.
    const PILOT: u64 = 4;
    let nstreams = 2 + r.bins.len();
    // Bin averages only serve the binning floor: they need a precision small
    // against the floor itself, or against twice the f target if finer.
    let target_of = |r: &Reference, w: usize| match w {
        0 => targets.f,
        1 => targets.albedo,
        _ => {
            let floor = if r.f.chunks > 0 && r.bins[w - 2].1.chunks > 0 {
                binning_floor(r, r.bins[w - 2].0).map_or(0.0, |f| f.0)
            } else {
                0.0
            };
            targets.bins.max(0.05 * floor)
        }
    };
    let stream = |r: &Reference, w: usize| -> RefStream {
        match w {
            0 => r.f.clone(),
            1 => r.albedo.clone(),
            _ => r.bins[w - 2].1.clone(),
        }
    };
    let empty = |w: usize| match w {
        0 => qs.f.is_empty(),
        1 => qs.albedo.is_empty(),
        _ => qs.f.is_empty(),
    };
    loop {
        // Chunks each stream still needs, predicted from 1/sqrt(n).
        let mut plan = Vec::new();
        for w in 0..nstreams {
            let s = stream(r, w);
            let e = s.rms_rel_stderr();
            let t = target_of(r, w);
            if empty(w) || e <= t || e == 0.0 {
                continue;
            }
            let need = if s.chunks == 0 {
                PILOT
            } else {
                let total = (s.chunks as f64 * (e / t).powi(2) * 1.1).ceil() as u64;
                (total.saturating_sub(s.chunks)).clamp(PILOT, 4 * s.chunks.max(PILOT))
            };
            plan.push((w, s.chunks, need));
        }
        if plan.is_empty() {
            return true;
        }
        if start.elapsed().as_secs_f64() > spec.max_seconds {
            return false;
        }
        let total: u64 = plan.iter().map(|p| p.2).sum();
        progress.begin("reference", total);
        let jobs: Vec<(usize, u64)> = plan
            .iter()
            .flat_map(|&(w, c0, n)| (c0..c0 + n).map(move |c| (w, c)))
            .collect();
        let t0 = Instant::now();
        let snapshot = r.clone();
        let results: Vec<((usize, u64), Vec<Estimate>)> = jobs
            .par_iter()
            .map(|&(w, c)| {
                let e = chunk_estimates(est, qs, w, &snapshot, c, spec);
                progress.advance(1);
                ((w, c), e)
            })
            .collect();
        progress.end();
        r.seconds += t0.elapsed().as_secs_f64() * rayon::current_num_threads() as f64;
        for ((w, _), es) in results {
            let s = match w {
                0 => &mut r.f,
                1 => &mut r.albedo,
                _ => &mut r.bins[w - 2].1,
            };
            for (a, e) in s.acc.iter_mut().zip(&es) {
                a.merge(&Acc::from_estimate(e));
            }
            s.chunks += 1;
        }
    }
}

/// A stable 64-bit FNV-1a hash.
fn fnv1a(bytes: &[u8]) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    for b in bytes {
        h ^= *b as u64;
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    h
}

/// The key of a cached reference: a hash of the material description, the
/// queries, the walk settings, the bin half-angles, the reference estimator
/// and its spec (not its precision: a cached reference is extended when more
/// precision is needed).
pub fn cache_key(
    stack: &LayerStack,
    qs: &QuerySet,
    settings: &Settings,
    bins: &[f64],
    reference: &str,
    spec: &ReferenceSpec,
) -> u64 {
    let text = serde_json::json!({
        "version": CACHE_VERSION,
        "material": stack.desc(),
        "queries": qs,
        "settings": format!("{settings:?}"),
        "bins": bins,
        "reference": reference,
        "seed": spec.seed,
        "chunk_samples": spec.chunk_samples,
        "bin_points": spec.bin_points,
    })
    .to_string();
    fnv1a(text.as_bytes())
}

// ------------------------------------------------------------------- errors

/// The errors of one run against the reference.
#[derive(Clone, Debug, PartialEq)]
pub struct RunErrors {
    /// RMS relative error of the BSDF values (over queries and channels).
    pub rms_f: f64,
    /// RMS of the run's own relative standard errors for them.
    pub own_f: f64,
    /// RMS relative error of the albedos.
    pub rms_albedo: f64,
    /// RMS of the run's own relative standard errors for them.
    pub own_albedo: f64,
    /// `(estimate - reference) / sqrt(stderr² + reference stderr²)` per BSDF
    /// target (query × channel with a non-zero reference).
    pub z_f: Vec<f64>,
    /// The same for the albedo targets.
    pub z_albedo: Vec<f64>,
}

fn rel_errors(
    est: impl Iterator<Item = ([f64; 3], [f64; 3])>,
    reference: impl Iterator<Item = ([f64; 3], [f64; 3])>,
) -> (f64, f64, Vec<f64>) {
    let (mut e2, mut s2, mut n) = (0.0, 0.0, 0usize);
    let mut z = Vec::new();
    for ((v, s), (rv, rs)) in est.zip(reference) {
        for c in 0..3 {
            if rv[c] <= 0.0 {
                continue;
            }
            let d = v[c] - rv[c];
            e2 += (d / rv[c]).powi(2);
            s2 += (s[c] / rv[c]).powi(2);
            n += 1;
            let sd = (s[c] * s[c] + rs[c] * rs[c]).sqrt();
            z.push(if sd > 0.0 {
                d / sd
            } else if d == 0.0 {
                0.0
            } else {
                f64::INFINITY.copysign(d)
            });
        }
    }
    let k = n.max(1) as f64;
    ((e2 / k).sqrt(), (s2 / k).sqrt(), z)
}

/// The errors of `run` against `r` (point values: the binning bias counts).
pub fn errors(r: &Reference, run: &Run) -> RunErrors {
    let (rms_f, own_f, z_f) = rel_errors(
        run.f.iter().map(|e| (e.value, e.stderr)),
        r.f.acc.iter().map(|a| (a.mean, a.stderr())),
    );
    let (rms_albedo, own_albedo, z_albedo) = rel_errors(
        run.albedo
            .iter()
            .flat_map(|a| [a.reflected, a.transmitted])
            .map(|e| (e.value, e.stderr)),
        r.albedo.acc.iter().map(|a| (a.mean, a.stderr())),
    );
    RunErrors {
        rms_f,
        own_f,
        rms_albedo,
        own_albedo,
        z_f,
        z_albedo,
    }
}

/// The errors of a binned estimator's run against the bin averages (no
/// binning bias: what is left is statistical).
pub fn errors_vs_bins(r: &Reference, run: &Run, half_angle: f64) -> Option<RunErrors> {
    let b = r.bins(half_angle)?;
    let (rms_f, own_f, z_f) = rel_errors(
        run.f.iter().map(|e| (e.value, e.stderr)),
        b.acc.iter().map(|a| (a.mean, a.stderr())),
    );
    Some(RunErrors {
        rms_f,
        own_f,
        rms_albedo: 0.0,
        own_albedo: 0.0,
        z_f,
        z_albedo: vec![],
    })
}

/// The binning floor of bins of `half_angle`: the RMS relative difference
/// between bin average and point value over the BSDF targets, with the noise
/// of both removed (`sqrt(max(0, mean(d²) - mean(var d)))`), and that noise's
/// RMS (the floor is not resolved below it).
pub fn binning_floor(r: &Reference, half_angle: f64) -> Option<(f64, f64)> {
    let b = r.bins(half_angle)?;
    let (mut d2, mut v2, mut n) = (0.0, 0.0, 0usize);
    for (p, a) in r.f.acc.iter().zip(&b.acc) {
        let (sp, sa) = (p.stderr(), a.stderr());
        for c in 0..3 {
            if p.mean[c] <= 0.0 {
                continue;
            }
            d2 += ((a.mean[c] - p.mean[c]) / p.mean[c]).powi(2);
            v2 += (sp[c].powi(2) + sa[c].powi(2)) / p.mean[c].powi(2);
            n += 1;
        }
    }
    let k = n.max(1) as f64;
    Some((((d2 - v2) / k).max(0.0).sqrt(), (v2 / k).sqrt()))
}

// ------------------------------------------------------------------- report

/// The measured curve of one estimator.
#[derive(Clone, Debug)]
pub struct Series {
    /// [`Estimator::name`].
    pub name: String,
    /// [`Estimator::description`].
    pub description: String,
    /// Bin half-angle of a binned estimator.
    pub bin_half_angle: Option<f64>,
    /// The runs, by increasing budget.
    pub runs: Vec<Run>,
    /// Their errors against the reference.
    pub errors: Vec<RunErrors>,
}

/// Everything a convergence study measured.
#[derive(Clone, Debug)]
pub struct Report {
    /// A name for the stack (file stem or suite entry).
    pub name: String,
    /// The queries.
    pub queries: QuerySet,
    /// The reference.
    pub reference: Reference,
    /// Whether the reference met its precision target.
    pub reference_converged: bool,
    /// One curve per estimator.
    pub series: Vec<Series>,
}

/// What to run.
#[derive(Clone, Debug)]
pub struct Config {
    /// The estimators to measure.
    pub estimators: Vec<EstimatorKind>,
    /// The estimator of long-run references.
    pub reference: EstimatorKind,
    /// Walk settings.
    pub settings: Settings,
    /// Budgets of each estimator's ladder.
    pub ladder: LadderSpec,
    /// How references are extended.
    pub reference_spec: ReferenceSpec,
    /// The reference's standard error must be this many times below the
    /// smallest error plotted (10).
    pub reference_margin: f64,
    /// Seed of the measured runs.
    pub seed: u64,
}

impl Default for Config {
    fn default() -> Self {
        Config {
            estimators: ESTIMATORS.to_vec(),
            reference: REFERENCE_ESTIMATOR,
            settings: Settings::default(),
            ladder: LadderSpec::default(),
            reference_spec: ReferenceSpec::default(),
            reference_margin: 10.0,
            seed: 1,
        }
    }
}

impl Config {
    /// The bin half-angles (radians) of the binned estimators.
    pub fn bin_half_angles(&self, stack: &LayerStack) -> Vec<f64> {
        let mut v: Vec<f64> = Vec::new();
        for k in &self.estimators {
            if let Some(h) = k.build(stack, self.settings).bin_half_angle() {
                if !v.iter().any(|x| (x - h).abs() < 1e-12) {
                    v.push(h);
                }
            }
        }
        v
    }
}

/// Smallest RMS relative error of a curve, over its runs, for `f` and the albedo.
///
/// With `expected`, a run's error is the larger of its measured error and
/// the error its own standard errors predict: a point whose measured error
/// fell low by chance does not set the reference's precision (the reference
/// matters through its share of a point's *expected* squared error, which a
/// 10× margin keeps under 1 %).
fn smallest_errors(series: &[Series], expected: bool) -> (f64, f64) {
    let mut m = (f64::INFINITY, f64::INFINITY);
    for s in series {
        for e in &s.errors {
            let (f, a) = if expected {
                (e.rms_f.max(e.own_f), e.rms_albedo.max(e.own_albedo))
            } else {
                (e.rms_f, e.rms_albedo)
            };
            if f > 0.0 {
                m.0 = m.0.min(f);
            }
            if a > 0.0 {
                m.1 = m.1.min(a);
            }
        }
    }
    m
}

/// Runs a whole study on `stack`: the ladders, then the reference (the
/// closed form, or `cached` extended as needed, or a new long run), then the
/// errors. The returned report holds the reference to cache.
pub fn converge(
    name: &str,
    stack: &LayerStack,
    qs: &QuerySet,
    cfg: &Config,
    cached: Option<Reference>,
    progress: &dyn Progress,
) -> Report {
    let bins = cfg.bin_half_angles(stack);
    let mut series = Vec::new();
    for (i, kind) in cfg.estimators.iter().enumerate() {
        let est = kind.build(stack, cfg.settings);
        let runs = ladder(
            est.as_ref(),
            qs,
            &cfg.ladder,
            mix64(cfg.seed ^ mix64(i as u64 + 17)),
            progress,
        );
        series.push(Series {
            name: est.name(),
            description: est.description(),
            bin_half_angle: est.bin_half_angle(),
            runs,
            errors: vec![],
        });
    }
    let ref_est = cfg.reference.build(stack, cfg.settings);
    let mut reference = analytic_reference(stack, qs, &bins).unwrap_or_else(|| {
        cached
            .filter(|r| {
                r.f.acc.len() == qs.f.len()
                    && r.albedo.acc.len() == 2 * qs.albedo.len()
                    && bins.iter().all(|&h| r.bins(h).is_some())
            })
            .unwrap_or_else(|| empty_reference(ref_est.as_ref(), qs, &bins, &cfg.reference_spec))
    });
    // The smallest errors the unbiased curves will show, predicted from their
    // own standard errors (relative to their own values), set the first
    // target; the measured errors of every curve then check it.
    let predicted = |pick: &dyn Fn(&Run) -> Vec<(f64, f64)>| {
        series
            .iter()
            .filter(|s| s.bin_half_angle.is_none())
            .flat_map(|s| s.runs.iter())
            .map(|r| {
                rms(pick(r)
                    .into_iter()
                    .filter(|(v, _)| *v > 0.0)
                    .map(|(v, s)| s / v))
            })
            .filter(|&x| x > 0.0)
            .fold(f64::INFINITY, f64::min)
    };
    let pf = predicted(&|r: &Run| {
        r.f.iter()
            .flat_map(|e| (0..3).map(move |c| (e.value[c], e.stderr[c])))
            .collect()
    });
    let pa = predicted(&|r: &Run| {
        r.albedo
            .iter()
            .flat_map(|a| [a.reflected, a.transmitted])
            .flat_map(|e| (0..3).map(move |c| (e.value[c], e.stderr[c])))
            .collect()
    });
    let m = cfg.reference_margin;
    let mut targets = Targets {
        f: pf / (1.2 * m),
        albedo: pa / (1.2 * m),
        bins: 0.0,
    };
    let floor_target = |t: &Targets| t.f * 2.0;
    targets.bins = floor_target(&targets);
    let mut converged = true;
    for _round in 0..4 {
        converged = extend_reference(
            &mut reference,
            ref_est.as_ref(),
            qs,
            targets,
            &cfg.reference_spec,
            progress,
        );
        for s in series.iter_mut() {
            s.errors = s.runs.iter().map(|r| errors(&reference, r)).collect();
        }
        if reference.kind == ReferenceKind::Analytic || !converged {
            break;
        }
        // Check the margin against the errors of every curve.
        let (ef, ea) = smallest_errors(&series, true);
        let (rf, ra) = (
            reference.f.rms_rel_stderr(),
            reference.albedo.rms_rel_stderr(),
        );
        if rf * m <= ef && ra * m <= ea {
            break;
        }
        targets.f = targets.f.min(ef / (1.2 * m));
        targets.albedo = targets.albedo.min(ea / (1.2 * m));
        targets.bins = floor_target(&targets);
    }
    Report {
        name: name.to_string(),
        queries: qs.clone(),
        reference,
        reference_converged: converged,
        series,
    }
}

/// Efficiency `1 / (error² × time)`, or 0 when undefined.
pub fn efficiency(err: f64, time: f64) -> f64 {
    if err > 0.0 && time > 0.0 {
        1.0 / (err * err * time)
    } else {
        0.0
    }
}

impl Report {
    /// Whether the query set has BSDF queries and albedo queries.
    pub fn has_queries(&self) -> (bool, bool) {
        (!self.queries.f.is_empty(), !self.queries.albedo.is_empty())
    }

    /// A run's time, RMS relative error, own relative standard error and
    /// efficiency, for f and then for the albedo, each formatted by
    /// `fmt(column, value)` (column 0 to 3); `absent` for a kind of query the
    /// set does not have, never a number made of no query.
    fn run_cells(
        &self,
        r: &Run,
        e: &RunErrors,
        absent: &str,
        fmt: impl Fn(usize, f64) -> String,
    ) -> [String; 8] {
        let (hf, ha) = self.has_queries();
        let f = [r.time_f, e.rms_f, e.own_f, efficiency(e.rms_f, r.time_f)];
        let a = [
            r.time_albedo,
            e.rms_albedo,
            e.own_albedo,
            efficiency(e.rms_albedo, r.time_albedo),
        ];
        std::array::from_fn(|i| {
            let (has, v) = if i < 4 { (hf, f[i]) } else { (ha, a[i - 4]) };
            if has {
                fmt(i % 4, v)
            } else {
                absent.to_string()
            }
        })
    }

    /// How far below the smallest plotted errors the reference's own RMS
    /// relative standard error lies: `(f, albedo)` ratios (infinite when
    /// exact). With `expected`, each run's error is the larger of its measured
    /// one and the one its own standard errors predict (the criterion the
    /// reference is extended to meet: at least 10); without, the measured one.
    pub fn reference_margin(&self, expected: bool) -> (f64, f64) {
        let (ef, ea) = smallest_errors(&self.series, expected);
        let ratio = |e: f64, r: f64| if r > 0.0 { e / r } else { f64::INFINITY };
        (
            ratio(ef, self.reference.f.rms_rel_stderr()),
            ratio(ea, self.reference.albedo.rms_rel_stderr()),
        )
    }

    /// The binning floor of a series (for binned estimators).
    pub fn floor(&self, s: &Series) -> Option<(f64, f64)> {
        binning_floor(&self.reference, s.bin_half_angle?)
    }

    /// One row per run: budget, times, errors (measured and predicted by the
    /// estimator's own standard errors), efficiencies, the reference's error
    /// bar, and for binned estimators the binning floor and lost throughput.
    pub fn csv(&self) -> String {
        let mut out = String::from(
            "stack,estimator,samples,time_f_s,rms_rel_err_f,own_rel_stderr_f,efficiency_f,\
             time_albedo_s,rms_rel_err_albedo,own_rel_stderr_albedo,efficiency_albedo,\
             reference,ref_rel_stderr_f,ref_rel_stderr_albedo,binning_floor_f,binning_floor_noise,\
             lost_weight\n",
        );
        let kind = match self.reference.kind {
            ReferenceKind::Analytic => "analytic".to_string(),
            ReferenceKind::LongRun { ref estimator } => format!("long-run:{estimator}"),
        };
        let (rf, ra) = (
            self.reference.f.rms_rel_stderr(),
            self.reference.albedo.rms_rel_stderr(),
        );
        let (rf, ra) = (
            if self.reference.kind == ReferenceKind::Analytic {
                0.0
            } else {
                rf
            },
            if self.reference.kind == ReferenceKind::Analytic {
                0.0
            } else {
                ra
            },
        );
        for s in &self.series {
            let (fl, fln) = self.floor(s).unwrap_or((f64::NAN, f64::NAN));
            for (r, e) in s.runs.iter().zip(&s.errors) {
                // A kind of query the set does not have leaves its fields empty.
                let (hf, ha) = self.has_queries();
                let cols = self.run_cells(r, e, "", |_, x| format!("{x:.6e}"));
                let bar = |has: bool, x: f64| {
                    if has {
                        format!("{x:.3e}")
                    } else {
                        String::new()
                    }
                };
                let (rf, ra) = (bar(hf, rf), bar(ha, ra));
                let _ = writeln!(
                    out,
                    "{},{},{},{},{},{},{},{},{},{:.3e}",
                    self.name,
                    s.name,
                    r.samples,
                    cols.join(","),
                    kind,
                    rf,
                    ra,
                    if fl.is_nan() {
                        String::new()
                    } else {
                        format!("{fl:.4e}")
                    },
                    if fln.is_nan() {
                        String::new()
                    } else {
                        format!("{fln:.3e}")
                    },
                    r.lost_weight
                );
            }
        }
        out
    }

    /// One row per reference target: the query, channel, reference value and
    /// error bar, and the bin averages.
    pub fn targets_csv(&self) -> String {
        let mut out =
            String::from("kind,wi_x,wi_y,wi_z,wo_x,wo_y,wo_z,channel,reference,ref_stderr");
        for (h, _) in &self.reference.bins {
            let _ = write!(out, ",bin_{0:.3}deg,bin_{0:.3}deg_stderr", h.to_degrees());
        }
        out.push('\n');
        for (j, q) in self.queries.f.iter().enumerate() {
            let (v, s) = self.reference.f(j);
            for c in 0..3 {
                let _ = write!(
                    out,
                    "f,{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{c},{:.6e},{:.3e}",
                    q.wi[0], q.wi[1], q.wi[2], q.wo[0], q.wo[1], q.wo[2], v[c], s[c]
                );
                for (_, b) in &self.reference.bins {
                    let a = &b.acc[j];
                    let _ = write!(out, ",{:.6e},{:.3e}", a.mean[c], a.stderr()[c]);
                }
                out.push('\n');
            }
        }
        for (j, wi) in self.queries.albedo.iter().enumerate() {
            let (r, t) = self.reference.albedo(j);
            for (k, a) in [("R", r), ("T", t)] {
                for c in 0..3 {
                    let _ = write!(
                        out,
                        "{k},{:.6},{:.6},{:.6},,,,{c},{:.6e},{:.3e}",
                        wi[0],
                        wi[1],
                        wi[2],
                        a.mean[c],
                        a.stderr()[c]
                    );
                    for _ in &self.reference.bins {
                        out.push_str(",,");
                    }
                    out.push('\n');
                }
            }
        }
        out
    }

    /// Each estimator at its largest budget: `(series, run, errors)`.
    pub fn last_points(&self) -> Vec<(&Series, &Run, &RunErrors)> {
        self.series
            .iter()
            .filter_map(|s| Some((s, s.runs.last()?, s.errors.last()?)))
            .collect()
    }

    /// A markdown table of every run, with the reference and floors stated.
    pub fn markdown(&self) -> String {
        let mut out = String::new();
        let _ = writeln!(out, "Reference: {}.", self.reference.describe());
        let (mf, ma) = self.reference_margin(true);
        let (nf, na) = self.reference_margin(false);
        if self.reference.kind == ReferenceKind::Analytic {
            let _ = writeln!(out, "The reference is exact: it has no error bar.");
        } else {
            let late = if self.reference_converged {
                ""
            } else {
                "; the reference hit its time limit before its target"
            };
            let (mf, ma, nf, na) = (
                fmt_margin(mf),
                fmt_margin(ma),
                fmt_margin(nf),
                fmt_margin(na),
            );
            let below = "Its RMS relative standard error is";
            let _ = match self.has_queries() {
                (true, true) => writeln!(
                    out,
                    "{below} {mf} below the smallest expected error plotted for f and {ma} for the \
                     albedo (measured errors: {nf} and {na}){late}."
                ),
                (true, false) => writeln!(
                    out,
                    "{below} {mf} below the smallest expected error plotted for f (measured error: \
                     {nf}){late}."
                ),
                (false, _) => writeln!(
                    out,
                    "{below} {ma} below the smallest expected error plotted for the albedo \
                     (measured error: {na}){late}."
                ),
            };
        }
        for s in &self.series {
            if let Some((fl, noise)) = self.floor(s) {
                let _ = writeln!(
                    out,
                    "Binning floor of {} (RMS relative difference between the {:.1}° bin averages and f): {:.2e} (noise {:.1e}).",
                    s.name,
                    s.bin_half_angle.unwrap_or(0.0).to_degrees(),
                    fl,
                    noise
                );
            }
        }
        out.push('\n');
        out.push_str("| estimator | samples | time f (s) | RMS rel. error f | own stderr f | efficiency f | time albedo (s) | RMS rel. error albedo | own stderr albedo | efficiency albedo |\n");
        out.push_str("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
        for s in &self.series {
            for (r, e) in s.runs.iter().zip(&s.errors) {
                let cols = self.run_cells(r, e, "–", |k, x| match k {
                    0 => format!("{x:.3}"),
                    3 => format!("{x:.3e}"),
                    _ => format!("{x:.2e}"),
                });
                let _ = writeln!(out, "| {} | {} | {} |", s.name, r.samples, cols.join(" | "));
            }
        }
        out
    }

    /// Efficiencies at each estimator's largest budget and their ratios to
    /// the first estimator's.
    pub fn summary(&self) -> String {
        let mut out = String::new();
        let _ = writeln!(
            out,
            "{}: reference = {}",
            self.name,
            self.reference.describe()
        );
        let effs: Vec<(f64, f64)> = self.series.iter().map(Series::efficiency).collect();
        let base = effs.first().copied().unwrap_or((0.0, 0.0));
        let (hf, ha) = self.has_queries();
        let _ = writeln!(
            out,
            "  {:<14} {:>9} {:>8} {:>9} {:>9} {:>10} {:>8} {:>10} {:>10} {:>8}",
            "estimator",
            "samples",
            "time f",
            "err f",
            "own f",
            "eff f",
            "ratio",
            "err alb.",
            "eff alb.",
            "ratio"
        );
        for (s, &(ef, ea)) in self.series.iter().zip(&effs) {
            let (Some(r), Some(e)) = (s.runs.last(), s.errors.last()) else {
                continue;
            };
            let f = cells(
                hf,
                "–",
                [
                    format!("{:.3}", r.time_f),
                    format!("{:.2e}", e.rms_f),
                    format!("{:.2e}", e.own_f),
                    format!("{ef:.3e}"),
                    fmt_ratio(ef, base.0),
                ],
            );
            let a = cells(
                ha,
                "–",
                [
                    format!("{:.2e}", e.rms_albedo),
                    format!("{ea:.3e}"),
                    fmt_ratio(ea, base.1),
                ],
            );
            let _ = writeln!(
                out,
                "  {:<14} {:>9} {:>8} {:>9} {:>9} {:>10} {:>8} {:>10} {:>10} {:>8}",
                s.name, r.samples, f[0], f[1], f[2], f[3], f[4], a[0], a[1], a[2]
            );
        }
        let _ = writeln!(
            out,
            "  (samples, times and errors at the largest budget; eff = 1/mean(err² × time) over the upper half of the ladder; ratio to {})",
            self.series.first().map_or("-", |s| s.name.as_str())
        );
        for s in &self.series {
            if let Some((fl, _)) = self.floor(s) {
                let _ = writeln!(out, "  {} binning floor (RMS rel.): {:.3e}", s.name, fl);
            }
        }
        out
    }
}

impl Series {
    /// The efficiency of the curve for `f` and for the albedo:
    /// `1 / mean(error² × time)` over the upper half of the ladder (at least
    /// its last three runs). For an unbiased estimator `error² × time` is
    /// constant up to noise, so this fits `error = c / sqrt(time)` with the
    /// slope fixed and is far less noisy than one run's value (a squared RMS
    /// error over a few targets scatters like a chi-square with few degrees of
    /// freedom); for a biased one (the brute force on its floor) it averages
    /// where the curve flattens.
    pub fn efficiency(&self) -> (f64, f64) {
        let n = self.runs.len().min(self.errors.len());
        let k = (n / 2).max(3).min(n);
        let inv_mean = |v: Vec<f64>| {
            let v: Vec<f64> = v.into_iter().filter(|x| x.is_finite()).collect();
            let m = v.iter().sum::<f64>() / v.len().max(1) as f64;
            if m > 0.0 {
                1.0 / m
            } else {
                0.0
            }
        };
        let pts = self.runs[n - k..n].iter().zip(&self.errors[n - k..n]);
        (
            inv_mean(
                pts.clone()
                    .map(|(r, e)| e.rms_f.powi(2) * r.time_f)
                    .collect(),
            ),
            inv_mean(
                pts.map(|(r, e)| e.rms_albedo.powi(2) * r.time_albedo)
                    .collect(),
            ),
        )
    }
}

/// `values`, or as many `absent` where the query set has no query of their
/// kind (`present` false): never a number made of no query.
pub fn cells<const N: usize>(present: bool, absent: &str, values: [String; N]) -> [String; N] {
    if present {
        values
    } else {
        std::array::from_fn(|_| absent.to_string())
    }
}

/// `a / b` to three decimals, or "–" where `b` is not positive (a ratio to
/// an efficiency of 0 is undefined, not NaN).
pub fn fmt_ratio(a: f64, b: f64) -> String {
    if b > 0.0 {
        format!("{:.3}", a / b)
    } else {
        "–".into()
    }
}

fn fmt_margin(m: f64) -> String {
    if m.is_infinite() {
        "infinitely".into()
    } else {
        format!("{m:.1}×")
    }
}
