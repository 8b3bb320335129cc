//! `strata demo`: the main job on built-in materials.
//!
//! For each built-in material (copies of files in `examples/materials/`,
//! embedded in the binary) it prints a table of directional albedos (R, T, with
//! standard errors) at a few incidence angles and a table of BSDF values f(wi,
//! wo) with standard errors, and writes a PNG per material into `--out`: a
//! polar plot of f·|cos θo| and a log plot of f in the plane of incidence for a
//! few incidence angles. Every estimate runs in parallel (rayon); the figures
//! are rendered in memory and written together at the end (temporary files,
//! renamed when all are written). The output directory is checked before any
//! work (created if missing, a probe file written and removed, no directory in
//! place of a figure) so that a bad `--out` fails at once; a failed or
//! interrupted run leaves no figure, temporary file or directory it created.

use crate::output::{check_target, commit, prepare_dir, stage};
use crate::plot::{luminance, luminance_stderr, render_png, Lobe, LobeFigure, LobePoint};
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use std::path::PathBuf;
use std::time::Instant;
use strata_bsdf::{Bsdf, Estimate, LayerStack, LayeredBsdf, Queries};

/// Arguments of `strata demo`.
#[derive(clap::Args)]
pub struct Args {
    /// Directory the PNG figures are written into (created if missing).
    #[arg(long, default_value = "out")]
    out: PathBuf,
    /// Walks per plotted BSDF value; the tables use 16 times as many.
    #[arg(long, default_value_t = 1024, value_parser = demo_walks)]
    samples: u64,
    /// Seed of every random stream.
    #[arg(long, default_value_t = 0)]
    seed: u64,
}

/// The built-in materials the demo shows (names in `strata_bsdf::materials`).
pub const MATERIALS: &[&str] = &[
    "clear_coat_lambertian",
    "coated_copper",
    "varnished_wood",
    "scattering_slab",
    "validation1",
];

/// Incidence angles of the albedo table (degrees).
const ALBEDO_THETAS: [f64; 4] = [0.0, 30.0, 60.0, 80.0];
/// Incidence angles of the lobe plots (degrees).
const PLOT_THETAS: [f64; 3] = [0.0, 30.0, 60.0];
/// `(theta_i, psi_o)` pairs of the BSDF table (degrees; psi as in `plot`).
const TABLE_PAIRS: [(f64, f64); 5] = [
    (30.0, -30.0),
    (30.0, 0.0),
    (30.0, 45.0),
    (60.0, -60.0),
    (60.0, -20.0),
];
/// Extra pairs for transmissive stacks: straight through, and out along -z.
const TABLE_PAIRS_T: [(f64, f64); 2] = [(30.0, -150.0), (30.0, 180.0)];
/// Table estimates use this many times `--samples` walks.
const TABLE_FACTOR: u64 = 16;

/// `--samples` of `demo`: its tables use `TABLE_FACTOR` times as many walks,
/// which must stay within the library's bound.
fn demo_walks(text: &str) -> Result<u64, String> {
    crate::common::walks_at_most(text, strata_bsdf::MAX_WALKS / TABLE_FACTOR)
}

/// `wi` at polar angle `theta` (degrees), azimuth 0.
fn wi_dir(theta_deg: f64) -> glam::Vec3 {
    let t = theta_deg.to_radians();
    glam::Vec3::new(t.sin() as f32, 0.0, t.cos() as f32)
}

/// `wo` at signed angle `psi` (degrees) in the plane of incidence.
fn wo_dir(psi_deg: f64) -> glam::Vec3 {
    let t = psi_deg.to_radians();
    glam::Vec3::new(t.sin() as f32, 0.0, t.cos() as f32)
}

/// One unit of work.
#[derive(Clone, Copy)]
enum Job {
    Albedo {
        m: usize,
        theta: f64,
    },
    Eval {
        m: usize,
        theta: f64,
        psi: f64,
        n: u64,
        table: bool,
    },
}

/// Its answer.
enum Answer {
    Albedo(strata_bsdf::Albedo),
    Eval(Estimate, f32),
}

/// Appends a line to the output buffer (a `String`: writing cannot fail).
macro_rules! outln {
    ($o:expr) => {
        $o.push('\n')
    };
    ($o:expr, $($t:tt)*) => {{
        use std::fmt::Write as _;
        let _ = writeln!($o, $($t)*);
    }};
}

/// Writes the buffer to stdout and empties it. A closed pipe only stops the
/// printing: the figures are still written.
fn emit(o: &mut String) -> Result<(), String> {
    let r = crate::common::print_out(o);
    o.clear();
    r
}

/// Runs `strata demo`.
pub fn run(args: Args) -> Result<(), String> {
    let start = Instant::now();
    crate::plot::register_font()?;
    prepare_dir("--out", &args.out)?;
    let png_path = |name: &str| args.out.join(format!("{name}.png"));
    for name in MATERIALS {
        check_target(&png_path(name)).map_err(|e| format!("--out {}: {e}", args.out.display()))?;
    }

    let bsdfs: Vec<(String, LayeredBsdf)> = MATERIALS
        .iter()
        .map(|&name| {
            strata_bsdf::materials::builtin(name)
                .map(|s| (name.to_string(), LayeredBsdf::new(s).seed(args.seed)))
                .ok_or_else(|| format!("unknown built-in material {name}"))
        })
        .collect::<Result<_, _>>()?;

    // Every estimate the demo needs, in a fixed order.
    let n_table = args.samples.saturating_mul(TABLE_FACTOR);
    let mut jobs = Vec::new();
    for (m, (_, b)) in bsdfs.iter().enumerate() {
        for &theta in &ALBEDO_THETAS {
            jobs.push(Job::Albedo { m, theta });
        }
        let transmissive = b.stack().transmissive();
        let extra: &[(f64, f64)] = if transmissive { &TABLE_PAIRS_T } else { &[] };
        for &(theta, psi) in TABLE_PAIRS.iter().chain(extra) {
            jobs.push(Job::Eval {
                m,
                theta,
                psi,
                n: n_table,
                table: true,
            });
        }
        for &theta in &PLOT_THETAS {
            for psi in plot_angles(transmissive) {
                jobs.push(Job::Eval {
                    m,
                    theta,
                    psi,
                    n: args.samples,
                    table: false,
                });
            }
        }
    }

    let bar = ProgressBar::new(jobs.len() as u64);
    if let Ok(style) = ProgressStyle::with_template(
        "{spinner} {wide_bar} {pos}/{len} estimates, {elapsed} (about {eta} left)",
    ) {
        bar.set_style(style);
    }
    let answers: Vec<Answer> = jobs
        .par_iter()
        .enumerate()
        .map(|(q, job)| {
            let a = answer(&bsdfs, q as u64, *job, n_table);
            bar.inc(1);
            a
        })
        .collect::<Result<_, _>>()?;
    bar.finish_and_clear();
    let computed = start.elapsed();

    // Tables.
    let mut o = String::new();
    let o = &mut o;
    outln!(
        o,
        "strata demo: {} built-in materials (examples/materials/), {} walks per plotted value, \
         {} per table entry, seed {}.",
        bsdfs.len(),
        args.samples,
        n_table,
        args.seed
    );
    outln!(
        o,
        "Values are mean ± one standard error per RGB channel. Directions lie in the plane of \
         incidence: wi at polar angle θi (azimuth 0), wo at signed angle θo (+ on the side of wi, \
         − on the mirror side, |θo| > 90° is transmission). f is in 1/sr, without the cosine."
    );
    let mut figures = Vec::new();
    for (m, (name, b)) in bsdfs.iter().enumerate() {
        let pick = |j: &Job| match *j {
            Job::Albedo { m: mm, .. } | Job::Eval { m: mm, .. } => mm == m,
        };
        let mine: Vec<(&Job, &Answer)> =
            jobs.iter().zip(&answers).filter(|(j, _)| pick(j)).collect();
        let desc = b.stack().desc().description.clone().unwrap_or_default();
        outln!(o);
        outln!(o, "== {name}: {desc}");
        print_albedos(o, &mine, b.stack().transmissive());
        print_values(o, &mine);
        figures.push((
            name.clone(),
            figure(name, &desc, b.stack(), &mine, args.samples),
        ));
    }

    emit(o)?;

    // Figures: render all in memory, then write each atomically.
    let pngs: Vec<(String, Vec<u8>)> = figures
        .par_iter()
        .map(|(name, fig)| render_png(fig).map(|png| (name.clone(), png)))
        .collect::<Result<_, _>>()?;
    let out_err = |e: String| format!("--out {}: {e}", args.out.display());
    let staged = pngs
        .iter()
        .map(|(name, png)| stage(&png_path(name), png))
        .collect::<Result<Vec<_>, _>>()
        .map_err(out_err)?;
    commit(staged).map_err(out_err)?;
    outln!(o);
    for (name, _) in &pngs {
        outln!(o, "wrote {}", png_path(name).display());
    }
    emit(o)?;
    outln!(
        o,
        "estimates took {:.1} s, all done in {:.1} s on {} threads",
        computed.as_secs_f64(),
        start.elapsed().as_secs_f64(),
        rayon::current_num_threads()
    );
    emit(o)
}

/// Signed outgoing angles of the lobe plots: every degree but grazing (±90°).
fn plot_angles(transmissive: bool) -> Vec<f64> {
    let (lo, hi) = if transmissive { (-179, 180) } else { (-89, 89) };
    (lo..=hi)
        .filter(|a: &i32| a.abs() != 90)
        .map(f64::from)
        .collect()
}

fn answer(
    bsdfs: &[(String, LayeredBsdf)],
    q: u64,
    job: Job,
    n_table: u64,
) -> Result<Answer, String> {
    match job {
        Job::Albedo { m, theta } => {
            let (name, b) = &bsdfs[m];
            b.albedo(wi_dir(theta), n_table)
                .map(Answer::Albedo)
                .map_err(|e| format!("{name}: {e}"))
        }
        Job::Eval {
            m, theta, psi, n, ..
        } => {
            let (name, b) = &bsdfs[m];
            let (wi, wo) = (wi_dir(theta), wo_dir(psi));
            let (wis, wos, keys) = ([wi], [wo], [q]);
            let batch = Queries::pairs(&wis[..], &wos[..]).keys(&keys).walks(n);
            let mut e = Estimate::default();
            (b.eval_into(&batch, &mut |_, x| e = *x)).map_err(|e| format!("{name}: {e}"))?;
            let p = b.pdf(wi, wo).map_err(|e| format!("{name}: {e}"))?;
            Ok(Answer::Eval(e, p))
        }
    }
}

/// `value ± error` with two significant digits of the error.
fn pm(v: f64, e: f64) -> String {
    let d = if e > 0.0 && e.is_finite() {
        (1.0 - e.log10().floor()).clamp(0.0, 7.0) as usize
    } else {
        4
    };
    format!("{v:.d$}±{e:.d$}")
}

fn print_albedos(o: &mut String, mine: &[(&Job, &Answer)], transmissive: bool) {
    let mut head = format!(
        "  {:>4}  {:>16} {:>16} {:>16}",
        "θi", "R red", "R green", "R blue"
    );
    if transmissive {
        head += &format!("  {:>16} {:>16} {:>16}", "T red", "T green", "T blue");
    }
    outln!(
        o,
        "  Directional albedo: R reflected, T transmitted{}",
        if transmissive {
            ""
        } else {
            " (opaque stack: T = 0)"
        }
    );
    outln!(o, "{head}");
    for (j, a) in mine {
        if let (Job::Albedo { theta, .. }, Answer::Albedo(a)) = (j, a) {
            let r = &a.reflected;
            let mut line = format!(
                "  {:>3}°  {:>16} {:>16} {:>16}",
                theta,
                pm(r.value[0], r.stderr[0]),
                pm(r.value[1], r.stderr[1]),
                pm(r.value[2], r.stderr[2])
            );
            if transmissive {
                let t = &a.transmitted;
                line += &format!(
                    "  {:>16} {:>16} {:>16}",
                    pm(t.value[0], t.stderr[0]),
                    pm(t.value[1], t.stderr[1]),
                    pm(t.value[2], t.stderr[2])
                );
            }
            outln!(o, "{line}");
        }
    }
}

fn print_values(o: &mut String, mine: &[(&Job, &Answer)]) {
    outln!(
        o,
        "  BSDF values f(wi, wo) in 1/sr, and the approximate pdf of sample()"
    );
    outln!(
        o,
        "  {:>4} {:>5}  {:>18} {:>18} {:>18}  {:>9}",
        "θi",
        "θo",
        "f red",
        "f green",
        "f blue",
        "pdf"
    );
    for (j, a) in mine {
        if let (
            Job::Eval {
                theta,
                psi,
                table: true,
                ..
            },
            Answer::Eval(e, p),
        ) = (j, a)
        {
            outln!(
                o,
                "  {:>3}° {:>4}°  {:>18} {:>18} {:>18}  {:>9.4}",
                theta,
                psi,
                pm(e.value[0], e.stderr[0]),
                pm(e.value[1], e.stderr[1]),
                pm(e.value[2], e.stderr[2]),
                p
            );
        }
    }
}

fn figure(
    name: &str,
    desc: &str,
    stack: &LayerStack,
    mine: &[(&Job, &Answer)],
    n_plot: u64,
) -> LobeFigure {
    let smooth = stack.interfaces().iter().any(|i| i.smooth);
    let mut subtitle = format!("built-in material {name}; {n_plot} walks per point; colours: incidence angle θi (wi in the plane of incidence)");
    if smooth {
        subtitle +=
            "; mirror (delta) lobes of smooth interfaces are not part of f and are not drawn";
    }
    let lobes = PLOT_THETAS
        .iter()
        .map(|&t| Lobe {
            theta_i_deg: t,
            points: mine
                .iter()
                .filter_map(|(j, a)| match (j, a) {
                    (
                        Job::Eval {
                            theta,
                            psi,
                            table: false,
                            ..
                        },
                        Answer::Eval(e, _),
                    ) if *theta == t => Some(LobePoint {
                        psi_deg: *psi,
                        f: luminance(e.value),
                        err: luminance_stderr(e.stderr),
                    }),
                    _ => None,
                })
                .collect(),
        })
        .collect();
    LobeFigure {
        title: desc.to_string(),
        subtitle,
        transmissive: stack.transmissive(),
        lobes,
    }
}
