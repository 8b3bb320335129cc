//! `strata bench`: throughput of the scalar reference and of the wavefront
//! engine on the representative stacks, as ratios measured in one run.
//!
//! Each measurement runs the same eval batch (`--queries` queries over both
//! hemispheres × `--samples` walks) repeatedly for at least `--min-seconds`
//! and keeps the fastest repetition, which is the least disturbed by other
//! work on a shared machine. The walks are the same on every engine (same
//! seeds), so walk segments (one walk advancing by one event) are counted once
//! by the wavefront engine and used for the scalar rows too; the general
//! (unspecialized) walk counts its own, since it runs more stages.

use rayon::ThreadPoolBuilder;
use std::path::PathBuf;
use std::time::{Duration, Instant};
use strata::estimator::scalar::ScalarEngine;
use strata::estimator::wavefront::{Plan, Stats, Wavefront};
use strata::lane::{F32x16, F32x8, Wide};
use strata::{LayerStack, Settings};

/// Arguments of `strata bench`.
#[derive(clap::Args)]
pub struct Args {
    /// Print one JSON object per stack × engine × threads instead of a table.
    #[arg(long)]
    json: bool,
    /// Queries per batch.
    #[arg(long, default_value_t = 48, value_parser = clap::value_parser!(u64).range(1..))]
    queries: u64,
    /// Walks per query.
    #[arg(long, default_value_t = 512, value_parser = crate::common::positive)]
    samples: u64,
    /// Minimum time spent on each measurement (the fastest repetition counts).
    #[arg(long, default_value_t = 1.0)]
    min_seconds: f64,
    /// Threads of the "all threads" rows (default: every core).
    #[arg(long)]
    threads: Option<usize>,
    /// Benchmark this material instead of the built-in representative stacks.
    #[arg(long)]
    material: Option<PathBuf>,
}

/// One row of the table.
struct Row {
    stack: String,
    engine: &'static str,
    threads: usize,
    queries_per_s: f64,
    segments_per_s: f64,
    occupancy: Option<f64>,
}

/// Runs `f` until `min` has elapsed (at least twice, after one warm-up) and
/// returns the fastest run's time and its result.
fn fastest<R>(min: Duration, mut f: impl FnMut() -> R) -> (Duration, R) {
    let mut r = f();
    let mut best = Duration::MAX;
    let start = Instant::now();
    let mut reps = 0;
    while reps < 2 || start.elapsed() < min {
        let t = Instant::now();
        r = f();
        best = best.min(t.elapsed());
        reps += 1;
    }
    (best, r)
}

/// The batch: incidence and exit directions spread over the hemispheres
/// (transmission too, for a transmissive stack).
fn batch(stack: &LayerStack, n: usize) -> Vec<([f64; 3], [f64; 3])> {
    let dir = |t: f64, p: f64| {
        let (t, p) = (t.to_radians(), p.to_radians());
        [t.sin() * p.cos(), t.sin() * p.sin(), t.cos()]
    };
    (0..n)
        .map(|k| {
            let u = (k as f64 + 0.5) / n as f64;
            let ti = 85.0 * u;
            let mut to = 85.0 * ((k * 7 % n) as f64 + 0.5) / n as f64;
            if stack.transmissive() && k % 3 == 2 {
                to = 180.0 - to;
            }
            (dir(ti, 0.0), dir(to, 360.0 * u * 3.0))
        })
        .collect()
}

fn measure_wave<W: Wide>(
    stack: &LayerStack,
    plan: Plan,
    pairs: &[([f64; 3], [f64; 3])],
    args: &Args,
    threads: usize,
) -> Result<(Duration, Stats), String> {
    let wf = Wavefront::<W>::new(stack, Settings::default(), plan);
    let keys: Vec<u64> = (0..pairs.len() as u64).collect();
    let pool = ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| format!("cannot start {threads} threads: {e}"))?;
    let min = Duration::from_secs_f64(args.min_seconds);
    Ok(pool.install(|| fastest(min, || wf.eval_batch(pairs, args.samples, 1, &keys).1)))
}

fn bench_stack(
    name: &str,
    stack: &LayerStack,
    args: &Args,
    all: usize,
) -> Result<Vec<Row>, String> {
    let pairs = batch(stack, args.queries as usize);
    let q = pairs.len() as f64;
    let min = Duration::from_secs_f64(args.min_seconds);
    let sc = ScalarEngine::<f32>::new(stack, Settings::default());
    let (ts, _) = fastest(min, || {
        pairs
            .iter()
            .enumerate()
            .map(|(k, &(wi, wo))| sc.eval(wi, wo, args.samples, 1, k as u64).value[0])
            .sum::<f64>()
    });
    let mut rows = Vec::new();
    let mut row = |engine, threads, t: Duration, st: &Stats, occupancy: bool| {
        rows.push(Row {
            stack: name.to_string(),
            engine,
            threads,
            queries_per_s: q / t.as_secs_f64(),
            segments_per_s: st.segments as f64 / t.as_secs_f64(),
            occupancy: occupancy.then(|| st.occupancy()),
        });
    };
    let (t1, st) = measure_wave::<F32x8>(stack, Plan::Specialized, &pairs, args, 1)?;
    row("scalar", 1, ts, &st, false);
    row("wavefront", 1, t1, &st, true);
    if all > 1 {
        let (tn, stn) = measure_wave::<F32x8>(stack, Plan::Specialized, &pairs, args, all)?;
        row("wavefront", all, tn, &stn, true);
    }
    let (tg, stg) = measure_wave::<F32x8>(stack, Plan::General, &pairs, args, 1)?;
    row("wavefront-general", 1, tg, &stg, true);
    let (t16, st16) = measure_wave::<F32x16>(stack, Plan::Specialized, &pairs, args, 1)?;
    row("wavefront-f32x16", 1, t16, &st16, true);
    Ok(rows)
}

pub fn run(args: Args) -> Result<(), String> {
    if !(args.min_seconds.is_finite() && args.min_seconds >= 0.0) {
        return Err(format!("--min-seconds {} must be >= 0", args.min_seconds));
    }
    let all = match args.threads {
        Some(0) => return Err("--threads 0: need at least one thread".into()),
        Some(n) => n,
        None => std::thread::available_parallelism().map_or(1, |n| n.get()),
    };
    let stacks: Vec<(String, LayerStack)> = match &args.material {
        Some(p) => vec![(
            p.display().to_string(),
            LayerStack::from_path(p).map_err(|e| e.to_string())?,
        )],
        None => strata::materials::REPRESENTATIVE
            .iter()
            .map(|&name| {
                let st = strata::materials::builtin(name).expect("built-in materials are valid");
                (name.to_string(), st)
            })
            .collect(),
    };
    let mut rows = Vec::new();
    for (name, st) in &stacks {
        if !args.json {
            eprintln!("benchmarking {name} ...");
        }
        rows.extend(bench_stack(name, st, &args, all)?);
    }
    if args.json {
        for r in &rows {
            println!(
                "{}",
                serde_json::json!({
                    "stack": r.stack, "engine": r.engine, "threads": r.threads,
                    "queries_per_s": r.queries_per_s, "segments_per_s": r.segments_per_s,
                    "occupancy": r.occupancy,
                })
            );
        }
        return Ok(());
    }
    print_table(&rows, &args);
    Ok(())
}

fn print_table(rows: &[Row], args: &Args) {
    println!(
        "eval batches: {} queries x {} walks; fastest of repeated runs (>= {} s each)\n",
        args.queries, args.samples, args.min_seconds
    );
    println!(
        "{:<24} {:<18} {:>7} {:>11} {:>12} {:>9} {:>9}",
        "stack", "engine", "threads", "queries/s", "Msegments/s", "occupancy", "x scalar"
    );
    let mut last = "";
    let mut scalar = 0.0;
    for r in rows {
        let name = if r.stack != last {
            r.stack.as_str()
        } else {
            ""
        };
        if r.engine == "scalar" {
            scalar = r.queries_per_s;
        }
        println!(
            "{:<24} {:<18} {:>7} {:>11.1} {:>12.2} {:>9} {:>9.2}",
            name,
            r.engine,
            r.threads,
            r.queries_per_s,
            r.segments_per_s / 1e6,
            r.occupancy.map_or("-".into(), |o| format!("{:.3}", o)),
            r.queries_per_s / scalar
        );
        last = &r.stack;
    }
}
