//! `strata bench --against pbrt-v4`: cost at equal error against pbrt-v4's
//! `CoatedDiffuse` and `CoatedConductor`, on its configurations and direction
//! pairs (`strata_reports::pbrt`), one thread and all threads.

use std::fmt::Write as _;
use strata_bsdf::{Engine, Estimator, EvalStart};
use strata_reports::pbrt::{self, PairResult};

/// An efficiency ratio as printed: "exact" where strata's answer has no
/// variance.
fn ratio(x: f64) -> String {
    if x.is_infinite() {
        "exact".to_string()
    } else {
        format!("{x:.2}x")
    }
}

/// The report: a summary table per thread count, then every pair.
pub fn report(
    walks: u64,
    reps: u32,
    all: usize,
    start: EvalStart,
    estimator: Estimator,
    json: bool,
) -> Result<String, String> {
    let mut o = String::new();
    let mut threads = vec![1];
    if all > 1 {
        threads.push(all);
    }
    let mut runs: Vec<(usize, pbrt::Config, Vec<PairResult>)> = Vec::new();
    for &t in &threads {
        for c in pbrt::configs() {
            crate::common::note(&format!("{} on {t} thread(s) ...", c.name));
            let r = pbrt::compare(&c, walks, t, reps, Engine::Wavefront, start, estimator)?;
            runs.push((t, c, r));
        }
    }
    if json {
        for (t, c, rs) in &runs {
            for r in rs {
                let line = serde_json::json!({
                    "config": c.name, "threads": t, "pair": r.pbrt.pair,
                    "theta_o": r.pbrt.theta_o, "theta_i": r.pbrt.theta_i,
                    "f": r.f, "se": r.se, "pbrt_f": r.pbrt.f, "pbrt_se": r.pbrt.se,
                    "us_per_walk": r.seconds_per_walk * 1e6, "exact": r.exact,
                    "pbrt_us_per_call": r.pbrt_seconds_per_call * 1e6,
                    "efficiency_ratio": r.ratio.map(|x| if x.is_finite() {
                        serde_json::json!(x)
                    } else {
                        serde_json::json!("exact")
                    }),
                });
                let _ = writeln!(o, "{line}");
            }
        }
        return Ok(o);
    }
    let _ = writeln!(
        o,
        "strata (wavefront, {walks} walks per pair, fastest of {reps} runs, eval from {start:?}, \
         estimator {estimator:?}) against pbrt-v4 \
         (values_f.csv, {}: {}).\nEfficiency = 1 / (per-walk variance x time per walk); \
         ratio = strata's / pbrt-v4's, per direction pair.\n",
        pbrt::TIMING_FILE,
        pbrt::TIMING_MACHINE
    );
    let _ = writeln!(
        o,
        "{:<36} {:>7} {:>16} {:>15} {:>8} {:>8} {:>7}",
        "configuration", "threads", "strata us/walk", "pbrt us/call", "median", "worst", "target"
    );
    for (t, c, rs) in &runs {
        let (lo, hi) = rs.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), r| {
            (lo.min(r.seconds_per_walk), hi.max(r.seconds_per_walk))
        });
        let (median, worst) = pbrt::median_and_worst(rs)
            .map_or(("-".into(), "-".into()), |(m, w)| (ratio(m), ratio(w)));
        let per_walk = if rs.iter().all(|r| r.exact) {
            "exact".to_string()
        } else {
            format!("{:.3}-{:.3}", lo * 1e6, hi * 1e6)
        };
        let _ = writeln!(
            o,
            "{:<36} {:>7} {:>16} {:>15.3} {:>8} {:>8} {:>7}",
            c.name,
            t,
            per_walk,
            rs.first().map_or(0.0, |r| r.pbrt_seconds_per_call * 1e6),
            median,
            worst,
            if c.target { "yes" } else { "no" }
        );
    }
    let _ = writeln!(
        o,
        "\nEvery pair (f at the first channel / wavelength; z = (strata - pbrt) / combined se; \
         pbrt-v4 is 2 % low on smooth coats and not reciprocal at grazing light on rough ones):\n"
    );
    let _ = writeln!(
        o,
        "{:<36} {:>7} {:>4} {:>5} {:>5} {:>22} {:>22} {:>7} {:>9}",
        "configuration",
        "threads",
        "pair",
        "θo",
        "θi",
        "strata f ± se",
        "pbrt f ± se",
        "z",
        "ratio"
    );
    for (t, c, rs) in &runs {
        for r in rs {
            let _ = writeln!(
                o,
                "{:<36} {:>7} {:>4} {:>5} {:>5} {:>22} {:>22} {:>7.2} {:>9}",
                c.name,
                t,
                r.pbrt.pair,
                r.pbrt.theta_o,
                r.pbrt.theta_i,
                format!("{:.5} ± {:.5}", r.f, r.se),
                format!("{:.5} ± {:.5}", r.pbrt.f, r.pbrt.se),
                r.z(),
                r.ratio.map_or("-".into(), ratio),
            );
        }
    }
    Ok(o)
}
