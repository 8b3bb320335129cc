//! `strata converge`: error against run time for every estimator, with a
//! reference, as CSV, markdown and a log-log plot (see `strata_reports::converge`).
//!
//! `--out` is checked before any work (created if missing, a probe file
//! written and removed, no directory in place of an output). The outputs of
//! every stack are written to temporary files as each stack is done and
//! renamed together at the end: a failed or interrupted run leaves none of
//! them (only the cached references of the stacks it finished).

use crate::common::{check_seconds, note, print_out};
use crate::output::{check_target, commit, prepare_dir, stage, write_atomic};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use plotters::prelude::*;
use std::path::PathBuf;
use std::sync::Mutex;
use std::time::Instant;
use strata_bsdf::LayerStack;
use strata_reports::converge::{
    self, cache_key, Config, EstimatorKind, Progress, QuerySet, Reference, Report,
};

/// Arguments of `strata converge`.
#[derive(clap::Args)]
pub struct Args {
    /// Material file (TOML, or JSON by extension). Not used with --suite.
    #[arg(long, required_unless_present = "suite")]
    material: Option<PathBuf>,
    /// Queries as JSON lines: {"wi":[..],"wo":[..]} for f, {"wi":[..]} for the
    /// albedo. Default: a built-in set in and off the plane of incidence.
    /// Queries no light can answer on the stack (light from behind a
    /// one-sided opaque stack, a view from the other side of an opaque one)
    /// are refused.
    #[arg(long)]
    queries: Option<PathBuf>,
    /// Seconds of doubling budgets per estimator (one thread) [default: 2,
    /// or 0.5 per stack with --suite docs]; at most a day.
    #[arg(long)]
    budget_seconds: Option<f64>,
    /// Output directory (default: out/converge, or docs/results with --suite docs).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Run a built-in suite of stacks instead of --material: `docs` (the
    /// seven stacks of docs/results.md).
    #[arg(long)]
    suite: Option<String>,
    /// Comma-separated estimators: scalar, wavefront, wavefront-mt, bidir,
    /// bidir-wavefront, bidir-wavefront-mt, brute, brute:DEG (bin
    /// half-angle). Default: scalar, wavefront, bidir, bidir-wavefront,
    /// brute.
    #[arg(long, value_delimiter = ',')]
    estimators: Option<Vec<String>>,
    /// Directory of cached references.
    #[arg(long, default_value = "out/cache")]
    cache: PathBuf,
    /// Neither read nor write cached references.
    #[arg(long)]
    no_cache: bool,
    /// Upper limit on the wall time of a long-run reference, seconds (at
    /// most a day).
    #[arg(long, default_value_t = 300.0)]
    reference_seconds: f64,
    /// Seed of the measured runs.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

/// The stacks of `--suite docs`: name, one-line description, material
/// (TOML). Each one's reference is `converge::reference_for`'s: the
/// estimator `Estimator::Auto` runs there.
pub const DOCS_SUITE: &[(&str, &str, &str)] = &[
    (
        "clear-coat",
        "smooth dielectric (IOR 1.5) over a coloured Lambertian base: closed-form reference",
        r#"
[[layers]]
interface = { kind = "dielectric", ior = 1.5 }
[[layers]]
interface = { kind = "diffuse", albedo = [0.8, 0.45, 0.2] }
"#,
    ),
    (
        "coated-conductor",
        "rough dielectric (α 0.1) over a tinted absorber (optical depth 0.1/0.25/0.5) over rough copper (α 0.2)",
        r#"
[[layers]]
interface = { kind = "dielectric", ior = 1.5, roughness = 0.1 }
medium = { thickness = 0.5, sigma_t = [0.2, 0.5, 1.0], albedo = 0.0 }
[[layers]]
interface = { kind = "conductor", preset = "Cu", roughness = 0.2 }
"#,
    ),
    (
        "scattering-varnish",
        "rough dielectric (α 0.05) over a thin forward-scattering layer (optical depth 0.6, HG g 0.6) over a wood-coloured Lambertian base",
        r#"
[[layers]]
interface = { kind = "dielectric", ior = 1.5, roughness = 0.05 }
medium = { thickness = 0.3, sigma_t = 2.0, albedo = [0.9, 0.85, 0.7], phase = { kind = "hg", g = 0.6 } }
[[layers]]
interface = { kind = "diffuse", albedo = [0.55, 0.33, 0.15] }
"#,
    ),
    (
        "thick-scattering",
        "rough dielectric (α 0.3) over a thick scattering layer (optical depth 10, albedo 0.99, HG g 0.3) over a grey Lambertian base",
        r#"
[[layers]]
interface = { kind = "dielectric", ior = 1.5, roughness = 0.3 }
medium = { thickness = 1.0, sigma_t = 10.0, albedo = 0.99, phase = { kind = "hg", g = 0.3 } }
[[layers]]
interface = { kind = "diffuse", albedo = 0.5 }
"#,
    ),
    (
        "transmissive-slab",
        "scattering slab (optical depth 0.5/1/2, albedo 0.9, HG g 0.3) between two rough dielectrics (α 0.2), air on both sides",
        r#"
[[layers]]
interface = { kind = "dielectric", ior = 1.5, roughness = 0.2 }
medium = { thickness = 1.0, sigma_t = [0.5, 1.0, 2.0], albedo = 0.9, phase = { kind = "hg", g = 0.3 } }
[[layers]]
interface = { kind = "dielectric", ior = 1.0, roughness = 0.2 }
"#,
    ),
    (
        "three-interfaces",
        "rough coat (α 0.1) over a tinted absorber, an anisotropic rough boundary (α 0.3/0.15) into a scattering film (IOR 2), rough gold (Beckmann α 0.15)",
        r#"
[[layers]]
interface = { kind = "dielectric", ior = 1.5, roughness = 0.1 }
medium = { thickness = 0.2, sigma_t = [0.5, 0.3, 0.1], albedo = 0.0 }
[[layers]]
interface = { kind = "dielectric", ior = 2.0, roughness = [0.3, 0.15] }
medium = { thickness = 0.5, sigma_t = 1.0, albedo = 0.8, phase = { kind = "isotropic" } }
[[layers]]
interface = { kind = "conductor", preset = "Au", roughness = 0.15, distribution = "beckmann" }
"#,
    ),
    (
        "near-specular",
        "near-specular coat (α 0.01) over near-specular copper (α 0.02): the unidirectional estimator is heavy-tailed here, so the reference is bidirectional",
        r#"
[[layers]]
interface = { kind = "dielectric", ior = 1.5, roughness = 0.01 }
[[layers]]
interface = { kind = "conductor", preset = "Cu", roughness = 0.02 }
"#,
    ),
];

/// Progress bars that appear only once a stage has run for a second.
struct Bars {
    state: Mutex<Option<(ProgressBar, Instant, bool)>>,
}

impl Bars {
    fn new() -> Self {
        Bars {
            state: Mutex::new(None),
        }
    }
}

impl Progress for Bars {
    fn begin(&self, label: &str, total: u64) {
        let pb = ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::hidden());
        if let Ok(style) =
            ProgressStyle::with_template("{msg:>12} [{elapsed_precise}] {wide_bar} {percent:>3}%")
        {
            pb.set_style(style);
        }
        pb.set_message(label.to_string());
        if let Ok(mut s) = self.state.lock() {
            *s = Some((pb, Instant::now(), false));
        }
    }
    fn advance(&self, n: u64) {
        if let Ok(mut s) = self.state.lock() {
            if let Some((pb, t0, shown)) = s.as_mut() {
                pb.inc(n);
                if !*shown && t0.elapsed().as_secs_f64() > 1.0 {
                    pb.set_draw_target(ProgressDrawTarget::stderr());
                    *shown = true;
                }
            }
        }
    }
    fn end(&self) {
        if let Ok(mut s) = self.state.lock() {
            if let Some((pb, _, _)) = s.take() {
                pb.finish_and_clear();
            }
        }
    }
}

pub fn run(args: Args) -> Result<(), String> {
    let budget = args
        .budget_seconds
        .unwrap_or(if args.suite.is_some() { 0.5 } else { 2.0 });
    check_seconds("--budget-seconds", budget, false)?;
    check_seconds("--reference-seconds", args.reference_seconds, false)?;
    let mut cfg = Config::default();
    if let Some(list) = &args.estimators {
        cfg.estimators = list
            .iter()
            .map(|s| EstimatorKind::parse(s))
            .collect::<Result<_, _>>()?;
    }
    cfg.ladder.budget_seconds = budget;
    cfg.reference_spec.max_seconds = args.reference_seconds;
    cfg.seed = args.seed;

    let mut jobs: Vec<(String, String, LayerStack, EstimatorKind)> = Vec::new();
    let out = match args.suite.as_deref() {
        Some("docs") => {
            for (name, what, toml) in DOCS_SUITE {
                let st = LayerStack::from_toml_str(toml)
                    .map_err(|e| format!("built-in stack {name}: {e}"))?;
                let r = converge::reference_for(&st);
                jobs.push((name.to_string(), what.to_string(), st, r));
            }
            args.out
                .clone()
                .unwrap_or_else(|| PathBuf::from("docs/results"))
        }
        Some(other) => return Err(format!("--suite {other:?}: unknown suite (known: docs)")),
        None => {
            let path = args.material.as_ref().ok_or("--material is required")?;
            let st = LayerStack::from_path(path).map_err(|e| e.to_string())?;
            let name = path
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| "material".into());
            let r = converge::reference_for(&st);
            jobs.push((name, path.display().to_string(), st, r));
            args.out
                .clone()
                .unwrap_or_else(|| PathBuf::from("out/converge"))
        }
    };
    let queries = match &args.queries {
        Some(p) => {
            let text = std::fs::read_to_string(p)
                .map_err(|e| format!("--queries {}: cannot read: {e}", p.display()))?;
            let qs = QuerySet::parse_json_lines(&text)
                .map_err(|e| format!("--queries {}: {e}", p.display()))?;
            for (name, _, st, _) in &jobs {
                check_queries_see(&text, name, st)
                    .map_err(|e| format!("--queries {}: {e}", p.display()))?;
            }
            Some(qs)
        }
        None => None,
    };

    // Every output location is checked before the work.
    prepare_dir("--out", &out)?;
    let mut targets: Vec<PathBuf> = Vec::new();
    for (name, _, _, _) in &jobs {
        for suffix in [".csv", "-reference.csv", ".md", ".png"] {
            targets.push(out.join(format!("{name}{suffix}")));
        }
    }
    if args.suite.is_some() {
        targets.push(out.join("summary.md"));
    }
    for t in &targets {
        check_target(t).map_err(|e| format!("--out {}: {e}", out.display()))?;
    }
    if !args.no_cache {
        prepare_dir("--cache", &args.cache)?;
    }

    let out_err = |e: String| format!("--out {}: {e}", out.display());
    let bars = Bars::new();
    let mut summaries = Vec::new();
    let mut staged = Vec::new();
    for (name, what, st, reference) in &jobs {
        cfg.reference = *reference;
        let qs = queries.clone().unwrap_or_else(|| QuerySet::default_for(st));
        let bins = cfg.bin_half_angles(st);
        let ref_name = cfg.reference.build(st, cfg.settings).name();
        let key = cache_key(
            st,
            &qs,
            &cfg.settings,
            &bins,
            &ref_name,
            &cfg.reference_spec,
        );
        let cache_path = args.cache.join(format!("ref-{key:016x}.json"));
        let cached: Option<Reference> = if args.no_cache {
            None
        } else {
            std::fs::read_to_string(&cache_path)
                .ok()
                .and_then(|t| serde_json::from_str(&t).ok())
        };
        note(&format!("{name}: {what}"));
        let t0 = Instant::now();
        let report = converge::converge(name, st, &qs, &cfg, cached, &bars);
        if !args.no_cache && report.reference.kind != converge::ReferenceKind::Analytic {
            let text = serde_json::to_string(&report.reference)
                .map_err(|e| format!("cannot encode the reference: {e}"))?;
            write_atomic(&cache_path, text.as_bytes())
                .map_err(|e| format!("--cache {}: {e}", args.cache.display()))?;
        }
        let md = format!("### {name}\n\n{what}.\n\n{}", report.markdown());
        let png = plot(&report).map_err(|e| format!("plot of {name}: {e}"))?;
        for (suffix, bytes) in [
            (".csv", report.csv().into_bytes()),
            ("-reference.csv", report.targets_csv().into_bytes()),
            (".md", md.into_bytes()),
            (".png", png),
        ] {
            staged.push(stage(&out.join(format!("{name}{suffix}")), &bytes).map_err(out_err)?);
        }
        // A closed pipe only stops the printing: the files are still written.
        print_out(&format!(
            "{}  ({:.1} s)\n",
            report.summary(),
            t0.elapsed().as_secs_f64()
        ))?;
        summaries.push(summary_rows(&report));
    }
    if args.suite.is_some() {
        let mut md = String::from(
            "Written by `strata converge --suite docs`. Per stack and estimator: the largest budget \
             run (walks per BSDF query for position-free estimators, per incident direction for \
             the brute force), its wall time for the BSDF queries (one thread) and RMS relative \
             error; the efficiency 1 / mean(RMS relative error² × time) over the upper half of \
             the ladder, for f and for the albedo, with its ratio to the first estimator's; and \
             the binning floor of binned estimators.\n\n\
             | stack | reference | estimator | samples | time f (s) | RMS rel. error f | efficiency f | ratio | efficiency albedo | ratio | binning floor |\n\
             |---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|\n",
        );
        for rows in &summaries {
            md.push_str(rows);
        }
        staged.push(stage(&out.join("summary.md"), md.as_bytes()).map_err(out_err)?);
    }
    commit(staged).map_err(out_err)?;
    note(&format!("wrote {}", out.display()));
    Ok(())
}

/// Fails, naming the line, on a query of `text` (the query file, already
/// parsed) that the stack `name` cannot answer (`converge::unanswerable`):
/// a grazing direction, light from behind a one-sided opaque stack, or a
/// view from the other side of an opaque one. It is zero for every
/// estimator: the reference would have no error to be measured against, and
/// its error bar would be infinite.
fn check_queries_see(text: &str, name: &str, st: &LayerStack) -> Result<(), String> {
    for (i, line) in text.lines().enumerate() {
        let t = line.trim();
        if t.is_empty() || t.starts_with('#') {
            continue;
        }
        let q = QuerySet::parse_json_lines(t).map_err(|e| format!("line {}: {e}", i + 1))?;
        let queries =
            (q.f.iter().map(|f| (f.wi, Some(f.wo)))).chain(q.albedo.iter().map(|&wi| (wi, None)));
        for (wi, wo) in queries {
            let Some(why) = converge::unanswerable(st, wi, wo) else {
                continue;
            };
            return Err(format!(
                "line {} ({t}): stack {name} cannot answer it: {why}",
                i + 1
            ));
        }
    }
    Ok(())
}

/// The rows of the suite's summary table for one stack.
fn summary_rows(report: &Report) -> String {
    let (hf, ha) = report.has_queries();
    let reference = match report.reference.kind {
        converge::ReferenceKind::Analytic => "closed form".to_string(),
        converge::ReferenceKind::LongRun { ref estimator } => {
            let bar = |has: bool, s: &converge::RefStream| {
                if has {
                    format!("±{:.1e}", s.rms_rel_stderr())
                } else {
                    "–".into()
                }
            };
            let (f, a) = (
                bar(hf, &report.reference.f),
                bar(ha, &report.reference.albedo),
            );
            format!("{estimator}, {f} (f), {a} (albedo)")
        }
    };
    let effs: Vec<(f64, f64)> = report.series.iter().map(|s| s.efficiency()).collect();
    let base = effs.first().copied().unwrap_or((0.0, 0.0));
    let mut out = String::new();
    for (s, &(ef, ea)) in report.series.iter().zip(&effs) {
        let (Some(r), Some(e)) = (s.runs.last(), s.errors.last()) else {
            continue;
        };
        let floor = report
            .floor(s)
            .map_or("–".to_string(), |f| format!("{:.2e}", f.0));
        let f = converge::cells(
            hf,
            "–",
            [
                format!("{:.3}", r.time_f),
                format!("{:.2e}", e.rms_f),
                format!("{ef:.3e}"),
                converge::fmt_ratio(ef, base.0),
            ],
        );
        let a = converge::cells(
            ha,
            "–",
            [format!("{ea:.3e}"), converge::fmt_ratio(ea, base.1)],
        );
        out.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} | {} |\n",
            report.name,
            reference,
            s.name,
            r.samples,
            f.join(" | "),
            a.join(" | "),
            floor
        ));
    }
    out
}

static FONT: &[u8] = include_bytes!("../../../assets/DejaVuSans.ttf");

const COLOURS: [RGBColor; 6] = [
    RGBColor(0, 90, 181),
    RGBColor(220, 50, 32),
    RGBColor(0, 140, 70),
    RGBColor(150, 60, 170),
    RGBColor(230, 140, 0),
    RGBColor(90, 90, 90),
];

/// The log-log plot: RMS relative error against time, f solid, albedo
/// dashed; the reference's error bar (grey), binning floors (dotted), and a
/// 1/sqrt(time) guide. Rendered in memory, returned as PNG.
fn plot(report: &Report) -> Result<Vec<u8>, String> {
    plotters::style::register_font("sans-serif", FontStyle::Normal, FONT)
        .map_err(|_| "cannot load the bundled font".to_string())?;
    let (w, h) = (960, 640);
    let mut rgb = vec![0u8; (w * h * 3) as usize];
    (|| -> Result<(), Box<dyn std::error::Error>> {
        let root = BitMapBackend::with_buffer(&mut rgb, (w, h)).into_drawing_area();
        draw(report, &root)?;
        root.present()?;
        Ok(())
    })()
    .map_err(|e| format!("cannot draw: {e}"))?;
    crate::plot::encode_png(&rgb, w, h)
}

type Area<'a> = DrawingArea<BitMapBackend<'a>, plotters::coord::Shift>;

fn draw(report: &Report, root: &Area) -> Result<(), Box<dyn std::error::Error>> {
    root.fill(&WHITE)?;
    let mut pts: Vec<(f64, f64)> = Vec::new();
    for s in &report.series {
        for (r, e) in s.runs.iter().zip(&s.errors) {
            pts.push((r.time_f, e.rms_f));
            pts.push((r.time_albedo, e.rms_albedo));
        }
    }
    let floors: Vec<(usize, f64)> = report
        .series
        .iter()
        .enumerate()
        .filter_map(|(i, s)| report.floor(s).map(|f| (i, f.0)))
        .filter(|(_, f)| *f > 0.0)
        .collect();
    let (rf, ra) = (
        report.reference.f.rms_rel_stderr(),
        report.reference.albedo.rms_rel_stderr(),
    );
    let exact = report.reference.kind == converge::ReferenceKind::Analytic;
    let good = |x: f64| x.is_finite() && x > 0.0;
    let xs: Vec<f64> = pts.iter().map(|p| p.0).filter(|&x| good(x)).collect();
    let mut ys: Vec<f64> = pts.iter().map(|p| p.1).filter(|&y| good(y)).collect();
    ys.extend(floors.iter().map(|f| f.1));
    if !exact {
        ys.extend([rf, ra].into_iter().filter(|&y| good(y)));
    }
    let (x0, x1) = bounds(&xs);
    let (y0, y1) = bounds(&ys);
    let title = format!("{}: RMS relative error against time", report.name);
    let mut chart = ChartBuilder::on(root)
        .caption(&title, ("sans-serif", 24))
        .margin(16)
        .x_label_area_size(48)
        .y_label_area_size(72)
        .build_cartesian_2d(
            (x0 / 1.5..x1 * 1.5).log_scale(),
            (y0 / 1.5..y1 * 1.5).log_scale(),
        )?;
    chart
        .configure_mesh()
        .x_desc("wall time (s, one thread)")
        .y_desc("RMS relative error")
        .label_style(("sans-serif", 15))
        .axis_desc_style(("sans-serif", 17))
        .x_label_formatter(&|x| format!("{x:.0e}"))
        .y_label_formatter(&|y| format!("{y:.0e}"))
        .draw()?;
    let (lo, hi) = (x0 / 1.5, x1 * 1.5);
    for (i, s) in report.series.iter().enumerate() {
        let c = COLOURS[i % COLOURS.len()];
        let f: Vec<(f64, f64)> = s
            .runs
            .iter()
            .zip(&s.errors)
            .map(|(r, e)| (r.time_f, e.rms_f))
            .filter(|p| good(p.0) && good(p.1))
            .collect();
        let a: Vec<(f64, f64)> = s
            .runs
            .iter()
            .zip(&s.errors)
            .map(|(r, e)| (r.time_albedo, e.rms_albedo))
            .filter(|p| good(p.0) && good(p.1))
            .collect();
        chart
            .draw_series(LineSeries::new(f.clone(), c.stroke_width(2)))?
            .label(format!("{}: f", s.description))
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(2)));
        chart.draw_series(f.iter().map(|&p| Circle::new(p, 4, c.filled())))?;
        chart
            .draw_series(DashedLineSeries::new(a.clone(), 6, 4, c.stroke_width(1)))?
            .label(format!("{}: albedo", s.description))
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(1)));
        chart.draw_series(
            a.iter()
                .map(|&p| TriangleMarker::new(p, 4, c.stroke_width(1))),
        )?;
    }
    for &(i, fl) in &floors {
        let c = COLOURS[i % COLOURS.len()];
        let name = report.series[i].name.clone();
        chart
            .draw_series(DashedLineSeries::new(
                vec![(lo, fl), (hi, fl)],
                2,
                5,
                c.stroke_width(2),
            ))?
            .label(format!("{name}: binning floor"))
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(1)));
    }
    let grey = RGBColor(150, 150, 150);
    if !exact {
        for (v, what) in [(rf, "f"), (ra, "albedo")] {
            if good(v) {
                chart
                    .draw_series(DashedLineSeries::new(
                        vec![(lo, v), (hi, v)],
                        3,
                        3,
                        grey.stroke_width(1),
                    ))?
                    .label(format!("reference's own error bar ({what})"))
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 20, y)], grey.stroke_width(1))
                    });
            }
        }
    }
    // A 1/sqrt(t) guide through the first estimator's first f point.
    if let Some((t, e)) = report
        .series
        .first()
        .and_then(|s| Some((s.runs.first()?.time_f, s.errors.first()?.rms_f)))
        .filter(|&(t, e)| good(t) && good(e))
    {
        let light = RGBColor(200, 200, 200);
        let guide: Vec<(f64, f64)> = [lo, hi].iter().map(|&x| (x, e * (t / x).sqrt())).collect();
        chart
            .draw_series(LineSeries::new(guide, light.stroke_width(1)))?
            .label("∝ 1/sqrt(time)")
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], light.stroke_width(1))
            });
    }
    chart
        .configure_series_labels()
        .label_font(("sans-serif", 14))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::LowerLeft)
        .draw()?;
    Ok(())
}

fn bounds(v: &[f64]) -> (f64, f64) {
    let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = v.iter().copied().fold(0.0, f64::max);
    if lo.is_finite() && hi > 0.0 {
        (lo, hi.max(lo * 10.0))
    } else {
        (1e-3, 1.0)
    }
}
