//! strata against pbrt-v4's layered BxDFs, side by side: cost at equal error.
//!
//! pbrt-v4's `CoatedDiffuse` and `CoatedConductor` estimate f with one
//! stochastic walk per call. Their values (10⁶ calls per direction pair, with
//! standard errors) and their thread-CPU time per call were measured once on a
//! machine of the kind strata's are (`data/pbrt-v4/README.md` says how; the
//! files are copies, read at compile time). This module builds the same
//! configurations as strata materials, runs strata's estimator on the same
//! pairs, and compares
//!
//! * values, as z-scores (pbrt-v4 is biased in places: its depth cap of 10
//!   loses about 2 % on a smooth coat, and its rough-coat `f()` is not
//!   reciprocal at grazing light; the README of the data says so), and
//! * efficiency, `1 / (per-walk variance × time per walk)`: strata's over
//!   pbrt-v4's per pair, so a ratio of 2 means strata reaches pbrt-v4's error
//!   in half its time.

use std::time::Instant;
use strata_bsdf::{Bsdf, Engine, Estimate, Estimator, EvalStart, LayerStack, LayeredBsdf, Queries};

const VALUES: &str = include_str!("../data/pbrt-v4/values_f.csv");
/// The timing file used, and the machine it was measured on.
pub const TIMING_FILE: &str = "timing_amd_epyc_2026-12-01.csv";
const TIMING: &str = include_str!("../data/pbrt-v4/timing_amd_epyc_2026-12-01.csv");
/// Where pbrt-v4's times were measured.
pub const TIMING_MACHINE: &str = "a 2-vCPU AMD EPYC VM (thread-CPU time, otherwise idle)";

/// pbrt-v4's four wavelengths of its data, in nm: the first three are
/// strata's three channels in [`configs`].
pub const WAVELENGTHS: [f64; 4] = [545.9, 616.9, 830.0, 479.2];

/// pbrt-v4's Cu, divided by the coat's 1.5, at its four wavelengths
/// ([`WAVELENGTHS`]; the data's README gives them).
pub const CU_ETA4: [f64; 4] = [0.659210, 0.192042, 0.174942, 0.765492];
/// The imaginary part, likewise.
pub const CU_K4: [f64; 4] = [1.719525, 2.129022, 3.524815, 1.674542];

/// pbrt-v4's Cu at the first three wavelengths (strata's three channels).
const CU_ETA: [f64; 3] = [CU_ETA4[0], CU_ETA4[1], CU_ETA4[2]];
const CU_K: [f64; 3] = [CU_K4[0], CU_K4[1], CU_K4[2]];

/// One pbrt-v4 configuration and its strata twin.
#[derive(Clone, Debug)]
pub struct Config {
    /// pbrt-v4's name of it (`values_f.csv`'s `config`).
    pub name: &'static str,
    /// The same stack as a strata material.
    pub toml: String,
    /// In the efficiency target (the four coated-diffuse stacks) or reported
    /// too (coated conductors).
    pub target: bool,
}

/// The layered configurations of the data, as strata materials.
pub fn configs() -> Vec<Config> {
    let absorber = ABSORBER;
    let scatterer =
        "medium = { thickness = 0.01, sigma_t = 1.0, albedo = 0.9, phase = { kind = \"hg\", g = 0.5 } }";
    let diffuse = "interface = { kind = \"diffuse\", albedo = 0.8 }";
    let cu = |alpha: f64| {
        let eta = CU_ETA.map(|x| x * 1.5);
        let k = CU_K.map(|x| x * 1.5);
        format!(
            "interface = {{ kind = \"conductor\", eta = [{}, {}, {}], k = [{}, {}, {}], roughness = {alpha} }}",
            eta[0], eta[1], eta[2], k[0], k[1], k[2]
        )
    };
    let stack = |top: String, medium: &str, base: String| coated(&top, medium, &base);
    vec![
        Config {
            name: "coated_diffuse_smooth_alb0",
            toml: stack(coat(0.0), absorber, diffuse.into()),
            target: true,
        },
        Config {
            name: "coated_diffuse_rough_alb0",
            toml: stack(coat(0.1), absorber, diffuse.into()),
            target: true,
        },
        Config {
            name: "coated_diffuse_smooth_alb0.9_g0.5",
            toml: stack(coat(0.0), scatterer, diffuse.into()),
            target: true,
        },
        Config {
            name: "coated_diffuse_rough_alb0.9_g0.5",
            toml: stack(coat(0.1), scatterer, diffuse.into()),
            target: true,
        },
        Config {
            name: "coated_conductor_rough_cu_smooth",
            toml: stack(coat(0.1), absorber, cu(0.0)),
            target: false,
        },
        Config {
            name: "coated_conductor_rough_cu_rough0.1",
            toml: stack(coat(0.1), absorber, cu(0.1)),
            target: false,
        },
    ]
}

/// Configuration `name` (a coated conductor) with pbrt-v4's copper as a
/// spectrum through its values at its four wavelengths ([`WAVELENGTHS`],
/// [`CU_ETA4`], [`CU_K4`]), for spectral queries at them; `None` for the
/// others, whose numbers do not vary with wavelength.
pub fn spectral_toml(name: &str) -> Option<String> {
    let alpha = match name {
        "coated_conductor_rough_cu_smooth" => 0.0,
        "coated_conductor_rough_cu_rough0.1" => 0.1,
        _ => return None,
    };
    let mut order = [0, 1, 2, 3];
    order.sort_by(|&a, &b| WAVELENGTHS[a].total_cmp(&WAVELENGTHS[b]));
    let list = |f: &dyn Fn(usize) -> f64| {
        let v: Vec<String> = order.iter().map(|&w| f(w).to_string()).collect();
        v.join(", ")
    };
    let nm = list(&|w| WAVELENGTHS[w]);
    // strata's conductor is relative to vacuum and divided by the coat's 1.5.
    let (eta, k) = (list(&|w| CU_ETA4[w] * 1.5), list(&|w| CU_K4[w] * 1.5));
    let cu = format!(
        "interface = {{ kind = \"conductor\", eta = {{ nm = [{nm}], values = [{eta}] }}, \
         k = {{ nm = [{nm}], values = [{k}] }}, roughness = {alpha} }}"
    );
    Some(coated(&coat(0.1), ABSORBER, &cu))
}

/// pbrt-v4's dielectric coat of IOR 1.5 and roughness `alpha`.
fn coat(alpha: f64) -> String {
    format!("interface = {{ kind = \"dielectric\", ior = 1.5, roughness = {alpha} }}")
}

/// pbrt's layer of thickness 0.01 with unit extinction (optical depth
/// 0.01), absorbing.
const ABSORBER: &str = "medium = { thickness = 0.01, sigma_t = 1.0, albedo = 0.0 }";

/// A stack of `top` over `medium` over `base`.
fn coated(top: &str, medium: &str, base: &str) -> String {
    format!("[[layers]]\n{top}\n{medium}\n[[layers]]\n{base}\n")
}

/// One direction pair of pbrt-v4's data.
#[derive(Clone, Copy, Debug)]
pub struct PbrtPair {
    /// Its index in the data.
    pub pair: u32,
    /// Polar angles of the viewer and the light, in degrees.
    pub theta_o: f64,
    /// The light's polar angle.
    pub theta_i: f64,
    /// The direction to the light (strata's `wi`).
    pub wi: [f64; 3],
    /// The direction to the viewer (strata's `wo`).
    pub wo: [f64; 3],
    /// pbrt-v4's mean f at its first wavelength (strata's first channel).
    pub f: f64,
    /// Its standard error.
    pub se: f64,
    /// pbrt-v4's mean f at each of its four wavelengths
    /// ([`WAVELENGTHS`]).
    pub f4: [f64; 4],
    /// Their standard errors.
    pub se4: [f64; 4],
    /// The calls it averages.
    pub calls: f64,
}

/// pbrt-v4's pairs of configuration `name`, in order.
pub fn pairs(name: &str) -> Vec<PbrtPair> {
    let mut lines = VALUES.lines();
    let header: Vec<&str> = lines.next().unwrap_or("").split(',').collect();
    let col = |h: &str| {
        header
            .iter()
            .position(|c| *c == h)
            .expect("column of values_f.csv")
    };
    let c_cfg = col("config");
    let (c_pair, c_to, c_ti) = (col("pair"), col("theta_o_deg"), col("theta_i_deg"));
    let (c_wo, c_wi, c_n, c_f, c_se) = (
        col("wo_x"),
        col("wi_x"),
        col("n_calls"),
        col("f0"),
        col("se0"),
    );
    lines
        .map(|l| l.split(',').collect::<Vec<&str>>())
        .filter(|v| v[c_cfg] == name)
        .map(|v| {
            let num = |i: usize| v[i].parse::<f64>().expect("a number in values_f.csv");
            PbrtPair {
                pair: num(c_pair) as u32,
                theta_o: num(c_to),
                theta_i: num(c_ti),
                wo: [num(c_wo), num(c_wo + 1), num(c_wo + 2)],
                wi: [num(c_wi), num(c_wi + 1), num(c_wi + 2)],
                f: num(c_f),
                se: num(c_se),
                f4: std::array::from_fn(|w| num(c_f + w)),
                se4: std::array::from_fn(|w| num(c_se + w)),
                calls: num(c_n),
            }
        })
        .collect()
}

/// pbrt-v4's time per `f()` call of configuration `name`, in seconds: the
/// median over the timing file's rounds of each round's median.
pub fn pbrt_seconds_per_call(name: &str) -> Option<f64> {
    let mut lines = TIMING.lines();
    let header: Vec<&str> = lines.next()?.split(',').collect();
    let col = |h: &str| header.iter().position(|c| *c == h);
    let (c_cfg, c_op, c_ns) = (col("config")?, col("op")?, col("median_ns_per_call")?);
    let mut ns: Vec<f64> = lines
        .map(|l| l.split(',').collect::<Vec<&str>>())
        .filter(|v| v[c_cfg] == name && v[c_op] == "f")
        .filter_map(|v| v[c_ns].parse().ok())
        .collect();
    if ns.is_empty() {
        return None;
    }
    ns.sort_by(f64::total_cmp);
    Some(ns[ns.len() / 2] * 1e-9)
}

/// One pair compared.
#[derive(Clone, Copy, Debug)]
pub struct PairResult {
    /// pbrt-v4's pair.
    pub pbrt: PbrtPair,
    /// strata's f (first channel) and its standard error.
    pub f: f64,
    /// Its standard error.
    pub se: f64,
    /// strata's wall time per walk, in seconds (per query when `exact`).
    pub seconds_per_walk: f64,
    /// strata answered by a closed form (standard error 0, no walk).
    pub exact: bool,
    /// pbrt-v4's time per call, in seconds.
    pub pbrt_seconds_per_call: f64,
    /// strata's efficiency over pbrt-v4's: infinite where strata's answer
    /// is exact, `None` where pbrt-v4's variance is 0 (a lone interface).
    pub ratio: Option<f64>,
}

impl PairResult {
    /// (strata − pbrt-v4) over the combined standard error.
    pub fn z(&self) -> f64 {
        (self.f - self.pbrt.f) / (self.se * self.se + self.pbrt.se * self.pbrt.se).sqrt()
    }
}

/// Runs strata's eval on every pair of `config`: `walks` walks per pair on
/// `threads` threads, `reps` runs with different query keys; the time is
/// the fastest run's (a shared machine's slow phases only lengthen runs)
/// and the variance the first run's.
pub fn compare(
    config: &Config,
    walks: u64,
    threads: usize,
    reps: u32,
    engine: Engine,
    start: EvalStart,
    estimator: Estimator,
) -> Result<Vec<PairResult>, String> {
    let stack =
        LayerStack::from_toml_str(&config.toml).map_err(|e| format!("{}: {e}", config.name))?;
    let pbrt_t = pbrt_seconds_per_call(config.name)
        .ok_or_else(|| format!("{}: no pbrt-v4 timing in {TIMING_FILE}", config.name))?;
    let bsdf = LayeredBsdf::new(stack)
        .samples(walks)
        .engine(engine)
        .eval_start(start)
        .estimator(estimator)
        .threads(threads)
        .map_err(|e| e.to_string())?;
    let mut out = Vec::new();
    for p in pairs(config.name) {
        let v = |d: [f64; 3]| glam::Vec3::new(d[0] as f32, d[1] as f32, d[2] as f32);
        let (wi, wo) = (v(p.wi), v(p.wo));
        let mut best = f64::INFINITY;
        let mut est = None;
        for r in 0..reps.max(1) {
            let key = strata_bsdf::api::direction_key(wi, wo) ^ r as u64;
            let (wis, wos, keys) = ([wi], [wo], [key]);
            let q = Queries::pairs(&wis[..], &wos[..]).keys(&keys).walks(walks);
            let mut e = Estimate::default();
            let t = Instant::now();
            (bsdf.eval_into(&q, &mut |_, x| e = *x)).map_err(|e| e.to_string())?;
            best = best.min(t.elapsed().as_secs_f64());
            est.get_or_insert(e);
        }
        let e = est.expect("at least one run");
        let exact = bsdf.eval_is_exact();
        let seconds_per_walk = if exact { best } else { best / walks as f64 };
        let var_s = e.stderr[0] * e.stderr[0] * walks as f64;
        let var_p = p.se * p.se * p.calls;
        let ratio = match (exact, var_s > 0.0 && var_p > 0.0) {
            (true, _) if var_p > 0.0 => Some(f64::INFINITY),
            (false, true) => Some((var_p * pbrt_t) / (var_s * seconds_per_walk)),
            _ => None,
        };
        out.push(PairResult {
            pbrt: p,
            f: e.value[0],
            se: e.stderr[0],
            seconds_per_walk,
            exact,
            pbrt_seconds_per_call: pbrt_t,
            ratio,
        });
    }
    Ok(out)
}

/// The median and the smallest of the pairs' efficiency ratios.
pub fn median_and_worst(results: &[PairResult]) -> Option<(f64, f64)> {
    let mut r: Vec<f64> = results.iter().filter_map(|r| r.ratio).collect();
    if r.is_empty() {
        return None;
    }
    r.sort_by(f64::total_cmp);
    let n = r.len();
    let median = if n % 2 == 1 {
        r[n / 2]
    } else {
        0.5 * (r[n / 2 - 1] + r[n / 2])
    };
    Some((median, r[0]))
}
