//! The stiff and extreme suite: stacks and directions where single precision
//! is most likely to fail, run on every engine against the f64 oracle.
//!
//! Each [`Case`] is one stack and one `(wi, wo)` query. [`Runner::run`] measures,
//! on the f64 scalar engine (the accuracy oracle), the f32 scalar reference and
//! the wavefront engine, each with its own seed (independent estimates):
//!
//! * `eval(wi, wo)`, and its z-scores against the f64 value;
//! * the directional albedo at `wi` from analog walks: reflected `R`,
//!   transmitted `T`, and `R + T` per walk (so its standard error is that of
//!   the sum, not a bound from the two parts), with z-scores against f64 and
//!   the z-score of any excess of `R + T` over 1 (or, for a lossless case, of
//!   any departure from 1);
//! * the walk-length distribution of the f32 reference (events per walk:
//!   interface events and medium collisions; mean, 99th percentile, maximum);
//! * time per walk of each engine (the wavefront on one thread);
//! * parity: with a shared seed, how many walks of the wavefront differ from
//!   the f32 scalar walks (both `eval` walk values and `sample` outputs);
//! * every number produced (estimates, per-walk weights and directions, the
//!   pdf) checked finite, every sampled direction checked unit and on the side
//!   its flag says.
//!
//! z-scores use the combined standard error of the two estimates plus a
//! rounding allowance [`ROUNDING`] relative to the reference, for the cases
//! whose walks are deterministic (standard error 0): single precision cannot
//! match f64 closer than that, and the allowance is far below every effect
//! the suite looks for (the f32 failures it found were 1e-3 to 1e-1).
//!
//! The module computes and formats; it never prints (`strata stress` prints,
//! `tests/reports/stress.rs` asserts).

use std::time::Instant;
use strata_bsdf::estimator::pdf::PdfKind;
use strata_bsdf::estimator::scalar::ScalarEngine;
use strata_bsdf::estimator::wavefront::{DefaultWide, Plan, Wavefront};
use strata_bsdf::estimator::{BlockReducer, Estimate, MeanVar, Settings};
use strata_bsdf::rng::{Stream, WalkRng};
use strata_bsdf::stack::{LayerStack, MaterialError};

/// Relative rounding allowance of a comparison with the f64 oracle (see the
/// module docs).
pub const ROUNDING: f64 = 1e-5;

/// Largest |z| a passing row may have. About 600 comparisons are made over
/// the suite; with fixed seeds the outcome is deterministic, and |z| > 5 has
/// probability 6e-7 per comparison for a correct engine.
pub const Z_MAX: f64 = 5.0;

/// One stiff or extreme configuration.
#[derive(Clone, Debug)]
pub struct Case {
    /// Short name (the table's first column).
    pub name: &'static str,
    /// What it stresses.
    pub stresses: &'static str,
    /// The material, as TOML.
    pub material: String,
    /// Incident direction (unit, stack frame).
    pub wi: [f64; 3],
    /// Outgoing direction of the `eval` query.
    pub wo: [f64; 3],
    /// No absorption anywhere (smooth interfaces, white media and bases): every
    /// walk must leave with weight 1, so `R + T = 1`.
    pub lossless: bool,
    /// Walks of this case cost about this many times a short walk: its walk
    /// counts are divided by it.
    pub cost: f64,
    /// A limit of events per walk other than the default
    /// (`Settings::max_events`), the same on every
    /// engine, for the lossless cases whose walk length has no useful bound
    /// (docs/numerics.md): the engines are then compared on the same capped
    /// estimate, and `1 - (R + T)` is the energy the cap lost.
    pub max_events: Option<u32>,
}

/// How many walks each engine runs per case (before division by
/// [`Case::cost`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Budget {
    /// Walks of `eval`.
    pub eval_walks: u64,
    /// Walks of the albedo.
    pub albedo_walks: u64,
    /// Walks compared one by one between the f32 engines.
    pub parity_walks: u64,
    /// Fewest walks of any estimate, whatever the cost.
    pub min_walks: u64,
    /// Leave out the cases whose [`Case::cost`] exceeds this (`None`: run all).
    pub max_cost: Option<f64>,
}

impl Budget {
    /// The budget of `strata stress` (under a minute on two cores).
    pub fn full() -> Self {
        Budget {
            eval_walks: 500_000,
            albedo_walks: 500_000,
            parity_walks: 4096,
            min_walks: 400,
            max_cost: None,
        }
    }
    /// The budget of the test suite (seconds).
    pub fn quick() -> Self {
        Budget {
            eval_walks: 20_000,
            albedo_walks: 20_000,
            parity_walks: 512,
            min_walks: 200,
            // The lossless cases of optical depth 1e4 and 1e5 have walks of
            // heavy-tailed length (see docs/numerics.md): minutes, not seconds.
            max_cost: Some(1000.0),
        }
    }
    /// Whether `case` runs under this budget.
    pub fn includes(&self, case: &Case) -> bool {
        self.max_cost.is_none_or(|m| case.cost <= m)
    }
    fn walks(&self, n: u64, cost: f64) -> u64 {
        ((n as f64 / cost.max(1.0)) as u64).max(self.min_walks)
    }
}

/// Walk lengths (events per walk) of the f32 reference's analog walks.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct WalkLengths {
    /// Mean.
    pub mean: f64,
    /// 99th percentile.
    pub p99: u32,
    /// Longest.
    pub max: u32,
}

/// The albedo as measured by one engine.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AlbedoRun {
    /// Reflected fraction.
    pub r: Estimate,
    /// Transmitted fraction.
    pub t: Estimate,
    /// `R + T`, per walk.
    pub sum: Estimate,
    /// Seconds per walk.
    pub sec_per_walk: f64,
}

/// `eval` as measured by one engine.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EvalRun {
    /// The estimate.
    pub f: Estimate,
    /// Seconds per walk.
    pub sec_per_walk: f64,
}

/// Everything measured on one case.
#[derive(Clone, Debug, PartialEq)]
pub struct Row {
    /// The case's name.
    pub name: &'static str,
    /// Whether the case is lossless.
    pub lossless: bool,
    /// The cap on events per walk, if any.
    pub max_events: Option<u32>,
    /// `eval` on the f64 oracle, the f32 scalar reference and the wavefront.
    pub eval: [EvalRun; 3],
    /// The albedo on the same three engines.
    pub albedo: [AlbedoRun; 3],
    /// The approximate pdf of `(wi, wo)` on the f32 scalar and wavefront engines.
    pub pdf: [f64; 2],
    /// Walk lengths of the f32 reference.
    pub lengths: WalkLengths,
    /// Walks whose wavefront result differs from the f32 scalar one (same seed).
    pub parity_differ: u64,
    /// Walks compared for parity.
    pub parity_walks: u64,
    /// Non-finite numbers seen anywhere.
    pub nonfinite: u64,
    /// Sampled directions that are not unit (|‖wo‖ - 1| > 1e-4) or lie on the
    /// wrong side for their reflection flag.
    pub bad_directions: u64,
}

/// Index of each engine in [`Row`]'s arrays.
pub const ENGINES: [&str; 3] = ["f64 scalar", "f32 scalar", "wavefront"];

/// `(x - r) / sqrt(se_x² + se_r² + (ROUNDING r)²)`: the z-score of `x` against
/// the reference `r`.
pub fn z_score(x: f64, se_x: f64, r: f64, se_r: f64) -> f64 {
    let s = (se_x * se_x + se_r * se_r + (ROUNDING * r).powi(2)).sqrt();
    if x == r {
        0.0
    } else if s > 0.0 {
        (x - r) / s
    } else {
        f64::INFINITY
    }
}

fn max_abs_z(x: &Estimate, r: &Estimate) -> f64 {
    (0..3)
        .map(|c| z_score(x.value[c], x.stderr[c], r.value[c], r.stderr[c]).abs())
        .fold(0.0, f64::max)
}

impl Row {
    /// Largest |z| of the f32 scalar (`k = 1`) or wavefront (`k = 2`) `eval`
    /// against the f64 oracle, over channels.
    pub fn eval_z(&self, k: usize) -> f64 {
        max_abs_z(&self.eval[k].f, &self.eval[0].f)
    }
    /// Largest |z| of engine `k`'s `R` and `T` against the f64 oracle.
    pub fn albedo_z(&self, k: usize) -> f64 {
        max_abs_z(&self.albedo[k].r, &self.albedo[0].r)
            .max(max_abs_z(&self.albedo[k].t, &self.albedo[0].t))
    }
    /// Engine `k`'s energy check, as a z-score over channels: of the excess
    /// of `R + T` over 1, or (lossless cases) of its departure from 1.
    pub fn energy_z(&self, k: usize) -> f64 {
        let s = &self.albedo[k].sum;
        (0..3)
            .map(|c| {
                let z = z_score(s.value[c], s.stderr[c], 1.0, 0.0);
                if self.lossless {
                    z.abs()
                } else {
                    z.max(0.0)
                }
            })
            .fold(0.0, f64::max)
    }
    /// What is wrong with this row (empty if it passes).
    pub fn failures(&self) -> Vec<String> {
        let mut f = Vec::new();
        if self.nonfinite > 0 {
            f.push(format!("{} non-finite numbers", self.nonfinite));
        }
        if self.bad_directions > 0 {
            f.push(format!("{} bad sampled directions", self.bad_directions));
        }
        // NaN fails too: a comparison that is not "within" is a failure.
        let within = |z: f64| z <= Z_MAX;
        for (k, name) in ENGINES.iter().enumerate().skip(1) {
            if !within(self.eval_z(k)) {
                f.push(format!("{name} eval |z| = {:.2}", self.eval_z(k)));
            }
            if !within(self.albedo_z(k)) {
                f.push(format!("{name} albedo |z| = {:.2}", self.albedo_z(k)));
            }
        }
        for (k, name) in ENGINES.iter().enumerate() {
            if !within(self.energy_z(k)) {
                let what = if self.lossless {
                    "R + T != 1"
                } else {
                    "R + T > 1"
                };
                f.push(format!("{name}: {what}, z = {:.2}", self.energy_z(k)));
            }
        }
        if !self.pdf.iter().all(|p| *p > 0.0) {
            f.push(format!("pdf {:?} not positive", self.pdf));
        }
        f
    }
}

/// Runs cases. Owns a one-thread pool for the wavefront engine, so that its
/// time per walk compares with the scalar engines'.
pub struct Runner {
    budget: Budget,
    settings: Settings,
    pool: rayon::ThreadPool,
}

/// Seeds: one per engine for the independent estimates, one shared for parity.
const SEED_F64: u64 = 0x64;
const SEED_F32: u64 = 0x32;
const SEED_WAVE: u64 = 0x88;
const SEED_PARITY: u64 = 0x77;
/// The query key of every case (the seeds already differ per engine).
const KEY: u64 = 5;

fn finite_est(e: &Estimate) -> u64 {
    e.value
        .iter()
        .chain(&e.stderr)
        .filter(|x| !x.is_finite())
        .count() as u64
}

/// Per-walk albedo accumulation shared by the engines.
struct AlbedoAcc {
    r: BlockReducer,
    t: BlockReducer,
    s: BlockReducer,
    nonfinite: u64,
    bad_dir: u64,
}

impl AlbedoAcc {
    fn new() -> Self {
        AlbedoAcc {
            r: BlockReducer::new(),
            t: BlockReducer::new(),
            s: BlockReducer::new(),
            nonfinite: 0,
            bad_dir: 0,
        }
    }
    fn push(&mut self, wi_up: bool, s: Option<strata_bsdf::estimator::WalkSample>) {
        let (mut xr, mut xt) = ([0.0; 3], [0.0; 3]);
        if let Some(s) = s {
            let w = s.weight.map(|x| x as f64);
            let d = s.wo.to_array();
            self.nonfinite += w
                .iter()
                .chain(&d.map(|x| x as f64))
                .filter(|x| !x.is_finite())
                .count() as u64;
            let len = (s.wo.length() as f64 - 1.0).abs();
            let side = (s.wo.z > 0.0) == wi_up;
            let unit = len <= 1e-4;
            if !unit || side != s.reflection || s.wo.z == 0.0 {
                self.bad_dir += 1;
            }
            if s.reflection {
                xr = w;
            } else {
                xt = w;
            }
        }
        self.r.push(xr);
        self.t.push(xt);
        self.s.push([0, 1, 2].map(|c| xr[c] + xt[c]));
    }
    fn finish(self, seconds: f64, n: u64) -> (AlbedoRun, u64, u64) {
        let e = |m: MeanVar| m.estimate();
        let run = AlbedoRun {
            r: e(self.r.finish()),
            t: e(self.t.finish()),
            sum: e(self.s.finish()),
            sec_per_walk: seconds / n as f64,
        };
        let nf = self.nonfinite + finite_est(&run.r) + finite_est(&run.t);
        (run, nf, self.bad_dir)
    }
}

impl Runner {
    /// A runner with `budget` and default walk settings.
    pub fn new(budget: Budget) -> Self {
        Runner {
            budget,
            settings: Settings::default(),
            pool: rayon::ThreadPoolBuilder::new()
                .num_threads(1)
                .build()
                .expect("a one-thread pool"),
        }
    }

    /// The budget.
    pub fn budget(&self) -> Budget {
        self.budget
    }

    /// Runs one case.
    pub fn run(&self, case: &Case) -> Result<Row, MaterialError> {
        let stack = LayerStack::from_toml_str(&case.material)?;
        let settings = Settings {
            max_events: case.max_events.unwrap_or(self.settings.max_events),
            ..self.settings
        };
        let s64 = ScalarEngine::<f64>::new(&stack, settings);
        let s32 = ScalarEngine::<f32>::new(&stack, settings);
        let wave = Wavefront::<DefaultWide>::new(&stack, settings, Plan::Specialized);
        let (wi, wo) = (case.wi, case.wo);
        let ne = self.budget.walks(self.budget.eval_walks, case.cost);
        let na = self.budget.walks(self.budget.albedo_walks, case.cost);
        let np = self.budget.walks(self.budget.parity_walks, case.cost);
        let mut nonfinite = 0;
        let mut bad_directions = 0;

        // eval on each engine, independent seeds.
        let timed = |f: &dyn Fn() -> Estimate, n: u64| {
            let t = Instant::now();
            let e = f();
            EvalRun {
                f: e,
                sec_per_walk: t.elapsed().as_secs_f64() / n as f64,
            }
        };
        let eval = [
            timed(&|| s64.eval(wi, wo, ne, SEED_F64, KEY), ne),
            timed(&|| s32.eval(wi, wo, ne, SEED_F32, KEY), ne),
            timed(
                &|| {
                    self.pool
                        .install(|| wave.eval_batch(&[(wi, wo)], ne, SEED_WAVE, &[KEY]).0[0])
                },
                ne,
            ),
        ];
        nonfinite += eval.iter().map(|e| finite_est(&e.f)).sum::<u64>();

        // Albedo from analog walks; walk lengths from the f32 reference.
        let up = wi[2] > 0.0;
        let t = Instant::now();
        let mut acc = AlbedoAcc::new();
        for k in 0..na {
            let mut rng = WalkRng::new(SEED_F64, KEY, k, Stream::Walk);
            acc.push(up, s64.sample(wi, &mut rng));
        }
        let a64 = acc.finish(t.elapsed().as_secs_f64(), na);
        let t = Instant::now();
        let mut acc = AlbedoAcc::new();
        let mut lengths = Vec::with_capacity(na as usize);
        for k in 0..na {
            let mut rng = WalkRng::new(SEED_F32, KEY, k, Stream::Walk);
            let (s, n) = s32.sample_counted(wi, &mut rng);
            lengths.push(n);
            acc.push(up, s);
        }
        let a32 = acc.finish(t.elapsed().as_secs_f64(), na);
        let t = Instant::now();
        let wis = vec![wi; na as usize];
        let keys = vec![KEY; na as usize];
        let idx: Vec<u64> = (0..na).collect();
        let ws = self
            .pool
            .install(|| wave.sample_batch(&wis, SEED_WAVE, &keys, &idx).0);
        let mut acc = AlbedoAcc::new();
        for s in ws {
            acc.push(up, s);
        }
        let aw = acc.finish(t.elapsed().as_secs_f64(), na);
        for a in [&a64, &a32, &aw] {
            nonfinite += a.1;
            bad_directions += a.2;
        }
        lengths.sort_unstable();
        let lengths = WalkLengths {
            mean: lengths.iter().map(|&x| x as f64).sum::<f64>() / na as f64,
            p99: lengths[((na as f64 * 0.99) as usize).min(lengths.len() - 1)],
            max: *lengths.last().unwrap_or(&0),
        };

        // Parity with a shared seed: eval walk values and samples.
        let sv = s32.eval_walk_values(wi, wo, np, SEED_PARITY, KEY);
        let wv = self
            .pool
            .install(|| wave.eval_walk_values(&[(wi, wo)], np, SEED_PARITY, &[KEY]));
        let mut differ = sv.iter().zip(&wv[0]).filter(|(a, b)| a != b).count() as u64;
        nonfinite += wv[0]
            .iter()
            .flatten()
            .chain(sv.iter().flatten())
            .filter(|x| !x.is_finite())
            .count() as u64;
        let wis = vec![wi; np as usize];
        let keys = vec![KEY; np as usize];
        let idx: Vec<u64> = (0..np).collect();
        let ws = self
            .pool
            .install(|| wave.sample_batch(&wis, SEED_PARITY, &keys, &idx).0);
        for (k, w) in ws.iter().enumerate() {
            let mut rng = WalkRng::new(SEED_PARITY, KEY, k as u64, Stream::Walk);
            differ += (s32.sample(wi, &mut rng) != *w) as u64;
        }

        // The approximate pdf on both f32 engines.
        let pdf = [
            s32.pdf(wi, wo, 64, SEED_F32, KEY),
            self.pool.install(|| {
                wave.pdf_batch(&[(wi, wo)], 64, SEED_F32, &[KEY], PdfKind::Approximate)[0].value
            }),
        ];
        nonfinite += pdf.iter().filter(|p| !p.is_finite()).count() as u64;

        Ok(Row {
            name: case.name,
            lossless: case.lossless,
            max_events: case.max_events,
            eval,
            albedo: [a64.0, a32.0, aw.0],
            pdf,
            lengths,
            parity_differ: differ,
            parity_walks: 2 * np,
            nonfinite,
            bad_directions,
        })
    }
}

/// The unit direction at polar angle `theta_deg` and azimuth `phi_deg`.
pub fn dir(theta_deg: f64, phi_deg: f64) -> [f64; 3] {
    let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
    [t.sin() * p.cos(), t.sin() * p.sin(), t.cos()]
}

/// The unit direction with `z = cos` (sign included) at azimuth `phi_deg`,
/// computed without losing a tiny `cos` to rounding.
pub fn dir_cos(cos: f64, phi_deg: f64) -> [f64; 3] {
    let s = ((1.0 - cos) * (1.0 + cos)).sqrt();
    let p = phi_deg.to_radians();
    [s * p.cos(), s * p.sin(), cos]
}

/// A smooth or rough coat of IOR `ior` over a medium and a base (TOML).
fn coat(ior: f64, alpha: f64, medium: &str, base: &str) -> String {
    let medium = if medium.is_empty() {
        String::new()
    } else {
        format!("medium = {{ {medium} }}\n")
    };
    format!(
        "[[layers]]\ninterface = {{ kind = \"dielectric\", ior = {ior}, roughness = {alpha} }}\n{medium}[[layers]]\ninterface = {{ {base} }}\n"
    )
}

const WHITE: &str = "kind = \"diffuse\", albedo = 1.0";
const GREY: &str = "kind = \"diffuse\", albedo = 0.8";
const MEDIUM: &str =
    "thickness = 1.0, sigma_t = 1.0, albedo = 0.9, phase = { kind = \"hg\", g = 0.3 }";

/// The suite.
pub fn cases() -> Vec<Case> {
    let c = |name, stresses, material: String, wi, wo, lossless, cost| Case {
        name,
        stresses,
        material,
        wi,
        wo,
        lossless,
        cost,
        max_events: None,
    };
    let capped = |case: Case, cap: u32| Case {
        max_events: Some(cap),
        lossless: false,
        ..case
    };
    let grazing = 1e-7;
    let slab = |top: &str, medium: &str, bottom: &str| {
        format!(
            "[[layers]]\ninterface = {{ {top} }}\nmedium = {{ {medium} }}\n[[layers]]\ninterface = {{ {bottom} }}\n"
        )
    };
    vec![
        // ---- geometry
        c(
            "grazing-in-smooth",
            "incidence at cos 1e-7 on a smooth coat (1 - F tiny)",
            coat(1.5, 0.0, "", GREY),
            dir_cos(grazing, 0.0),
            dir(30.0, 180.0),
            false,
            1.0,
        ),
        c(
            "grazing-out-smooth",
            "exit at cos 1e-7 through a smooth coat",
            coat(1.5, 0.0, "", GREY),
            dir(30.0, 0.0),
            dir_cos(grazing, 180.0),
            false,
            1.0,
        ),
        c(
            "grazing-in-rough",
            "incidence at cos 1e-7 on a rough coat over a scattering medium",
            coat(1.5, 0.3, MEDIUM, GREY),
            dir_cos(grazing, 0.0),
            dir(60.0, 90.0),
            false,
            2.0,
        ),
        c(
            "grazing-out-rough",
            "exit at cos 1e-7 through a rough coat over a scattering medium",
            coat(1.5, 0.3, MEDIUM, GREY),
            dir(60.0, 0.0),
            dir_cos(grazing, 90.0),
            false,
            2.0,
        ),
        c(
            "grazing-slab-transmit",
            "cos 1e-7 incidence, transmission through a rough slab",
            slab(
                "kind = \"dielectric\", ior = 1.4, roughness = 0.2",
                "thickness = 1.0, sigma_t = 1.0, albedo = 0.95",
                "kind = \"dielectric\", ior = 1.0, roughness = 0.2",
            ),
            dir_cos(grazing, 0.0),
            dir(140.0, 180.0),
            false,
            2.0,
        ),
        c(
            "normal-smooth-medium",
            "exactly normal wi = wo = +z through a smooth coat and an HG medium",
            coat(
                1.5,
                0.0,
                "thickness = 0.5, sigma_t = 2.0, albedo = 0.9, phase = { kind = \"hg\", g = 0.5 }",
                GREY,
            ),
            [0.0, 0.0, 1.0],
            [0.0, 0.0, 1.0],
            false,
            2.0,
        ),
        c(
            "normal-rough-transmit",
            "exactly normal wi = +z, wo = -z through a rough slab",
            slab(
                "kind = \"dielectric\", ior = 1.5, roughness = 0.1",
                "thickness = 1.0, sigma_t = 1.0, albedo = 0.8",
                "kind = \"dielectric\", ior = 1.0, roughness = 0.1",
            ),
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
            false,
            2.0,
        ),
        // ---- anisotropic media
        c(
            "sggx-flat-flakes",
            "very flat SGGX surface flakes (roughness 0.01, tilted axis) under a rough coat",
            coat(
                1.5,
                0.2,
                "thickness = 1.0, sigma_t = 2.0, albedo = 0.95, phase = { kind = \"sggx\", flakes = \"surface\", axis = [0.6, 0.0, 0.8], roughness = 0.01 }",
                GREY,
            ),
            dir(30.0, 0.0),
            dir(40.0, 180.0),
            false,
            2.0,
        ),
        c(
            "sggx-fibres",
            "fibre-like SGGX medium (roughness 0.01 along x), diffuse flakes, transmissive",
            slab(
                "kind = \"dielectric\", ior = 1.4, roughness = 0.2",
                "thickness = 1.0, sigma_t = 2.0, albedo = 0.9, phase = { kind = \"sggx\", flakes = \"fiber\", axis = [1.0, 0.0, 0.0], roughness = 0.01, scattering = \"diffuse\" }",
                "kind = \"dielectric\", ior = 1.0, roughness = 0.2",
            ),
            dir(50.0, 90.0),
            dir(150.0, 0.0),
            false,
            2.0,
        ),
        // ---- roughness
        c(
            "alpha-1e-3-coat",
            "near-specular coat (alpha 1e-3) over a Lambertian base",
            coat(1.5, 1e-3, "", GREY),
            dir(40.0, 0.0),
            dir(20.0, 90.0),
            false,
            1.0,
        ),
        c(
            "alpha-1e-4-mirror",
            "alpha 1e-4 coat over alpha 1e-4 copper, wo 5e-5 rad off the mirror",
            "[[layers]]\ninterface = { kind = \"dielectric\", ior = 1.5, roughness = 1e-4 }\n\
             [[layers]]\ninterface = { kind = \"conductor\", preset = \"Cu\", roughness = 1e-4 }\n"
                .into(),
            dir(30.0, 0.0),
            dir(30.0 + 0.003, 180.0),
            false,
            1.0,
        ),
        c(
            "alpha-1e-4-slab",
            "alpha 1e-4 slab, transmission 5e-5 rad off the straight-through direction",
            slab(
                "kind = \"dielectric\", ior = 1.5, roughness = 1e-4",
                "thickness = 1.0, sigma_t = 0.5, albedo = 0.0",
                "kind = \"dielectric\", ior = 1.0, roughness = 1e-4",
            ),
            dir(20.0, 0.0),
            dir(160.0 - 0.003, 180.0),
            false,
            1.0,
        ),
        c(
            "alpha-1-white",
            "very rough coat (alpha 1) over a white base",
            coat(1.5, 1.0, "", WHITE),
            dir(60.0, 0.0),
            dir(45.0, 120.0),
            false,
            2.0,
        ),
        c(
            "alpha-1-slab",
            "very rough slab (alpha 1) with a white medium, transmission",
            slab(
                "kind = \"dielectric\", ior = 1.5, roughness = 1.0",
                "thickness = 1.0, sigma_t = 1.0, albedo = 1.0",
                "kind = \"dielectric\", ior = 1.0, roughness = 1.0",
            ),
            dir(30.0, 0.0),
            dir(120.0, 90.0),
            false,
            3.0,
        ),
        // ---- indices of refraction
        c(
            "ior-1.0-matched",
            "index-matched boundary (invisible) over an HG medium",
            coat(
                1.0,
                0.2,
                "thickness = 1.0, sigma_t = 1.0, albedo = 0.9, phase = { kind = \"hg\", g = 0.3 }",
                "kind = \"diffuse\", albedo = 0.5",
            ),
            dir(50.0, 0.0),
            dir(60.0, 150.0),
            false,
            2.0,
        ),
        c(
            "ior-1.0001-rough",
            "nearly matched rough boundaries (eta 1.0001, alpha 0.2): needle lobes",
            slab(
                "kind = \"dielectric\", ior = 1.0001, roughness = 0.2",
                "thickness = 1.0, sigma_t = 1.0, albedo = 1.0, phase = { kind = \"hg\", g = 0.3 }",
                "kind = \"dielectric\", ior = 1.0, roughness = 0.2",
            ),
            dir(50.0, 0.0),
            dir(60.0, 150.0),
            false,
            2.0,
        ),
        c(
            "ior-4-tir-smooth",
            "smooth IOR 4 coat over a white base: light trapped by TIR, lossless",
            coat(4.0, 0.0, "", WHITE),
            dir(45.0, 0.0),
            dir(10.0, 90.0),
            true,
            8.0,
        ),
        c(
            "ior-4-tir-rough",
            "rough IOR 4 coat over a white medium and white base",
            coat(
                4.0,
                0.3,
                "thickness = 1.0, sigma_t = 1.0, albedo = 1.0",
                WHITE,
            ),
            dir(45.0, 0.0),
            dir(10.0, 90.0),
            false,
            10.0,
        ),
        c(
            "ior-4-tir-slab",
            "IOR 4 slab with a white medium between smooth faces: lossless, R + T = 1",
            slab(
                "kind = \"dielectric\", ior = 4.0",
                "thickness = 1.0, sigma_t = 1.0, albedo = 1.0",
                "kind = \"dielectric\", ior = 1.0",
            ),
            dir(70.0, 0.0),
            dir(150.0, 30.0),
            true,
            10.0,
        ),
        // ---- optical depth
        c(
            "tau-1e3-a0.999",
            "optical depth 1e3, albedo 0.999, under a smooth coat on a white base",
            coat(1.5, 0.0, "thickness = 1.0, sigma_t = 1e3, albedo = 0.999", WHITE),
            dir(30.0, 0.0),
            dir(50.0, 90.0),
            false,
            40.0,
        ),
        c(
            "tau-1e5-a0.999",
            "optical depth 1e5, albedo 0.999, chromatic sigma_t",
            coat(
                1.5,
                0.0,
                "thickness = 1.0, sigma_t = [1e5, 3e4, 1e4], albedo = 0.999",
                WHITE,
            ),
            dir(30.0, 0.0),
            dir(50.0, 90.0),
            false,
            40.0,
        ),
        c(
            "tau-1e3-a1",
            "optical depth 1e3, albedo 1, transmissive slab: lossless",
            slab(
                "kind = \"dielectric\", ior = 1.5",
                "thickness = 1.0, sigma_t = 1e3, albedo = 1.0",
                "kind = \"dielectric\", ior = 1.0",
            ),
            dir(30.0, 0.0),
            dir(50.0, 90.0),
            true,
            1000.0,
        ),
        capped(
            c(
                "tau-1e4-a1",
                "optical depth 1e4, albedo 1, on a white base: lossless, walks capped at 1e7 events",
                coat(1.0, 0.0, "thickness = 1e4, sigma_t = 1.0, albedo = 1.0", WHITE),
                dir(30.0, 0.0),
                dir(50.0, 90.0),
                true,
                10_000.0,
            ),
            10_000_000,
        ),
        capped(
            c(
                "tau-1e5-a1",
                "optical depth 1e5, albedo 1, HG 0.8, on a white base: lossless, walks capped at 1e6 events",
                coat(
                    1.5,
                    0.0,
                    "thickness = 1.0, sigma_t = 1e5, albedo = 1.0, phase = { kind = \"hg\", g = 0.8 }",
                    WHITE,
                ),
                dir(30.0, 0.0),
                dir(50.0, 90.0),
                true,
                10_000.0,
            ),
            1_000_000,
        ),
        c(
            "tau-1e-6",
            "optical depth 1e-6 (chromatic up to 1) between a rough coat and a base",
            coat(
                1.5,
                0.2,
                "thickness = 1.0, sigma_t = [1e-6, 1e-3, 1.0], albedo = 0.9",
                GREY,
            ),
            dir(40.0, 0.0),
            dir(30.0, 90.0),
            false,
            1.0,
        ),
        // ---- phase functions
        c(
            "g+0.999",
            "forward-peaked HG (g = 0.999), thick enough to scatter often",
            coat(
                1.5,
                0.0,
                "thickness = 1.0, sigma_t = 10.0, albedo = 0.95, phase = { kind = \"hg\", g = 0.999 }",
                GREY,
            ),
            dir(30.0, 0.0),
            dir(40.0, 90.0),
            false,
            4.0,
        ),
        c(
            "g-0.999",
            "back-peaked HG (g = -0.999)",
            coat(
                1.5,
                0.0,
                "thickness = 1.0, sigma_t = 2.0, albedo = 0.95, phase = { kind = \"hg\", g = -0.999 }",
                GREY,
            ),
            dir(30.0, 0.0),
            dir(40.0, 90.0),
            false,
            4.0,
        ),
        // ---- conductors
        c(
            "conductor-k0",
            "conductor with k = 0 (eta = the coat's index in green: R = 0 there)",
            coat(
                1.5,
                0.2,
                "thickness = 0.5, sigma_t = 0.5, albedo = 0.5",
                "kind = \"conductor\", eta = [0.75, 1.5, 3.0], k = 0.0, roughness = 0.2",
            ),
            dir(40.0, 0.0),
            dir(30.0, 90.0),
            false,
            2.0,
        ),
        c(
            "conductor-huge-k",
            "conductor with k = 1e2, 1e4, 1e6 (R -> 1)",
            coat(
                1.5,
                0.1,
                "",
                "kind = \"conductor\", eta = 0.2, k = [1e2, 1e4, 1e6], roughness = 0.3",
            ),
            dir(40.0, 0.0),
            dir(30.0, 90.0),
            false,
            2.0,
        ),
        // ---- albedo extremes
        c(
            "albedo-0",
            "pure absorber (albedo 0, chromatic) over a black base",
            coat(
                1.5,
                0.2,
                "thickness = 1.0, sigma_t = [0.5, 1.0, 2.0], albedo = 0.0",
                "kind = \"diffuse\", albedo = 0.0",
            ),
            dir(40.0, 0.0),
            dir(30.0, 90.0),
            false,
            1.0,
        ),
        c(
            "albedo-1",
            "white HG medium over a white base under a smooth coat: lossless",
            coat(
                1.5,
                0.0,
                "thickness = 2.0, sigma_t = 1.0, albedo = 1.0, phase = { kind = \"hg\", g = 0.5 }",
                WHITE,
            ),
            dir(40.0, 0.0),
            dir(30.0, 90.0),
            true,
            10.0,
        ),
    ]
}

/// The suite's table in Markdown, one row per case.
pub fn format_table(rows: &[Row]) -> String {
    let mut s = String::new();
    s.push_str(
        "| case | f (f64) ± se | z f32 | z wf | R+T (f64) ± se | z f32 | z wf | z R+T | events mean / p99 / max | µs/walk f64 / f32 / wf | parity | ok |\n",
    );
    s.push_str("|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for r in rows {
        let e = &r.eval[0].f;
        let a = &r.albedo[0].sum;
        let mean = |x: &[f64; 3]| (x[0] + x[1] + x[2]) / 3.0;
        let energy = (0..3).map(|k| r.energy_z(k)).fold(0.0, f64::max);
        let us = |k: usize| r.eval[k].sec_per_walk * 1e6;
        let fails = r.failures();
        s.push_str(&format!(
            "| {} | {:.4e} ± {:.1e} | {:.2} | {:.2} | {:.5} ± {:.1e} | {:.2} | {:.2} | {:.2} | {:.1} / {} / {} | {:.2} / {:.2} / {:.2} | {}/{} | {} |\n",
            match r.max_events {
                Some(k) => format!("{} (cap {k:.0e})", r.name),
                None => r.name.to_string(),
            },
            mean(&e.value),
            mean(&e.stderr),
            r.eval_z(1),
            r.eval_z(2),
            mean(&a.value),
            mean(&a.stderr),
            r.albedo_z(1),
            r.albedo_z(2),
            energy,
            r.lengths.mean,
            r.lengths.p99,
            r.lengths.max,
            us(0),
            us(1),
            us(2),
            r.parity_walks - r.parity_differ,
            r.parity_walks,
            if fails.is_empty() { "yes".to_string() } else { fails.join("; ") },
        ));
    }
    s
}
