//! `strata bench --vertex --against pbrt-v4`: one shading vertex of a path
//! tracer (a BSDF sample, a light sample's eval and pdf, one walk each, in
//! batches on one thread) on pbrt-v4's six layered configurations at three
//! views, against pbrt-v4's `LayeredBxDF` measured the same way
//! (`strata_reports::vertex`).

use std::fmt::Write as _;
use strata_bsdf::LayeredBsdf;
use strata_reports::vertex::{self, PbrtVertex, VertexRun};

/// A setting of the library the benchmark compares: its name, how it
/// changes the renderer's BSDF, and whether every vertex has its own
/// parameters ([`vertex::Texture`]).
type Setting = (&'static str, fn(LayeredBsdf) -> LayeredBsdf, bool);

/// The library's defaults, textured, the pdf's other settings, and the
/// classic roulette ([`strata_bsdf::Settings::rr_threshold`] 1).
const SETTINGS: [Setting; 5] = [
    ("default", |b| b, false),
    ("textured", |b| b, true),
    ("pdf 1 walk", |b| b.pdf_samples(1), false),
    (
        "pdf adaptive",
        |b| b.pdf_walks(strata_bsdf::PdfWalks::ADAPTIVE),
        false,
    ),
    ("roulette 1", |b| b.rr_threshold(1.0), false),
];

/// One row: a configuration, a view, a setting.
struct Row {
    config: &'static str,
    view: f64,
    setting: &'static str,
    run: VertexRun,
    pbrt: PbrtVertex,
}

/// The report: a row per configuration, view and setting, then per setting
/// the median and the worst ratio. `vertices` per row, in batches of
/// `batch`, in `rounds` turns over the settings (a shared machine's slow
/// phases then hit every setting alike).
pub fn report(vertices: u64, batch: usize, rounds: u32, json: bool) -> Result<String, String> {
    let batches = (vertices.div_ceil(batch as u64) as u32)
        .div_ceil(rounds)
        .max(1);
    let mut rows: Vec<Row> = Vec::new();
    for c in vertex::configs() {
        let bsdfs: Vec<(&str, LayeredBsdf, bool)> = SETTINGS
            .iter()
            .map(|(name, f, t)| Ok((*name, f(vertex::renderer_bsdf(&c)?), *t)))
            .collect::<Result<_, String>>()?;
        let mut texture = vertex::Texture::new(&c);
        for view in vertex::VIEWS {
            crate::common::note(&format!("{} at {view} deg ...", c.name));
            let pbrt = vertex::pbrt_vertex(c.name, view)
                .ok_or_else(|| format!("{}: no pbrt-v4 vertex at {view} deg", c.name))?;
            let mut acc: Vec<Vec<VertexRun>> = vec![Vec::new(); bsdfs.len()];
            for r in 0..rounds {
                for (i, (_, b, textured)) in bsdfs.iter().enumerate() {
                    let seed = (r as u64) << 32 | view as u64;
                    let t = textured.then_some(&mut texture);
                    acc[i].push(vertex::run(b, view, batch, batches, seed, t)?);
                }
            }
            for ((setting, _, _), runs) in bsdfs.iter().zip(acc) {
                rows.push(Row {
                    config: c.name,
                    view,
                    setting,
                    run: pool(&runs),
                    pbrt,
                });
            }
        }
    }
    let mut o = String::new();
    if json {
        for r in &rows {
            let line = serde_json::json!({
                "config": r.config, "view_deg": r.view, "setting": r.setting,
                "vertices": r.run.vertices, "mean": r.run.mean, "stderr": r.run.stderr(),
                "variance": r.run.variance, "ns_per_vertex": r.run.ns_per_vertex,
                "pbrt_mean": r.pbrt.mean, "pbrt_variance": r.pbrt.variance,
                "pbrt_ns_per_vertex": r.pbrt.ns_per_vertex, "ns_per_call": r.run.ns_per_call, "ratio": r.run.ratio(&r.pbrt),
            });
            let _ = writeln!(o, "{line}");
        }
        return Ok(o);
    }
    let _ = writeln!(
        o,
        "One shading vertex (BSDF sample + light sample's eval and pdf; batches of {batch}, one \
         thread, one walk per eval, thread-CPU time) against pbrt-v4's LayeredBxDF \
         (data/pbrt-v4/vertex.csv). ratio = strata's efficiency / pbrt-v4's, efficiency = \
         1 / (variance x time). z = (strata - pbrt) / combined se (pbrt-v4 is biased where its \
         depth cap bites).\n"
    );
    let _ = writeln!(
        o,
        "{:<34} {:>4} {:<12} {:>9} {:>22} {:>9} {:>10} {:>10} {:>11} {:>7} {:>8}",
        "configuration",
        "view",
        "setting",
        "ns/vertex",
        "[table+]sample/eval_pdf",
        "pbrt ns",
        "variance",
        "pbrt var",
        "mean",
        "z",
        "ratio"
    );
    for r in &rows {
        let z = (r.run.mean - r.pbrt.mean) / r.run.stderr().hypot(r.pbrt.stderr);
        let _ = writeln!(
            o,
            "{:<34} {:>4} {:<12} {:>9.0} {:>22} {:>9.0} {:>10.4} {:>10.4} {:>11.5} {:>7.1} {:>7.2}x",
            r.config,
            r.view,
            r.setting,
            r.run.ns_per_vertex,
            match r.run.ns_per_call {
                [0.0, s, l] => format!("{s:.0}/{l:.0}"),
                [t, s, l] => format!("{t:.0}+{s:.0}/{l:.0}"),
            },
            r.pbrt.ns_per_vertex,
            r.run.variance,
            r.pbrt.variance,
            r.run.mean,
            z,
            r.run.ratio(&r.pbrt)
        );
    }
    let _ = writeln!(
        o,
        "\ntextured (every vertex its own thickness, absorption, coat roughness where rough, \
         base albedo where Lambertian) over untextured efficiency: {}",
        textured_ratios(&rows)
    );
    let _ = writeln!(o, "\n{:<12} {:>8} {:>8}", "setting", "median", "worst");
    for (setting, _, _) in SETTINGS {
        let mut ratios: Vec<f64> = rows
            .iter()
            .filter(|r| r.setting == setting)
            .map(|r| r.run.ratio(&r.pbrt))
            .collect();
        ratios.sort_by(f64::total_cmp);
        let n = ratios.len();
        let median = 0.5 * (ratios[(n - 1) / 2] + ratios[n / 2]);
        let _ = writeln!(o, "{:<12} {:>7.2}x {:>7.2}x", setting, median, ratios[0]);
    }
    Ok(o)
}

/// Per configuration and view, the textured row's efficiency over the
/// default's (each against its own variance and time).
fn textured_ratios(rows: &[Row]) -> String {
    let eff = |r: &Row| 1.0 / (r.run.variance * r.run.ns_per_vertex);
    let mut ratios: Vec<f64> = rows
        .iter()
        .filter(|t| t.setting == "textured")
        .filter_map(|t| {
            let own = rows
                .iter()
                .find(|r| r.setting == "default" && r.config == t.config && r.view == t.view)?;
            Some(eff(t) / eff(own))
        })
        .collect();
    ratios.sort_by(f64::total_cmp);
    match ratios.len() {
        0 => "none".into(),
        n => format!(
            "median {:.2}x, worst {:.2}x",
            0.5 * (ratios[(n - 1) / 2] + ratios[n / 2]),
            ratios[0]
        ),
    }
}

/// Rounds pooled: their means and variances weighted by their vertices,
/// their times summed.
fn pool(runs: &[VertexRun]) -> VertexRun {
    let n: f64 = runs.iter().map(|r| r.vertices as f64).sum();
    let mean = runs.iter().map(|r| r.mean * r.vertices as f64).sum::<f64>() / n;
    let ss: f64 = runs
        .iter()
        .map(|r| {
            let m = r.vertices as f64;
            r.variance * (m - 1.0) + m * (r.mean - mean) * (r.mean - mean)
        })
        .sum();
    let ns = runs
        .iter()
        .map(|r| r.ns_per_vertex * r.vertices as f64)
        .sum::<f64>()
        / n;
    let per_call = |i: usize| {
        runs.iter()
            .map(|r| r.ns_per_call[i] * r.vertices as f64)
            .sum::<f64>()
            / n
    };
    VertexRun {
        vertices: n as u64,
        mean,
        variance: ss / (n - 1.0),
        ns_per_vertex: ns,
        ns_per_call: [per_call(0), per_call(1), per_call(2)],
    }
}
