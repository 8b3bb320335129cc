//! `strata bench`: throughput of the scalar reference and of the wavefront
//! engine on the representative stacks, as ratios measured in one run.
//!
//! Each engine runs the same eval batch (`--queries` queries over both
//! hemispheres × `--samples` walks); the engines take turns, one batch each
//! per round, until each has run for at least `--min-seconds`, and each keeps
//! its fastest run. Taking turns makes a slow phase of a shared machine hit
//! every engine alike, so the ratios hold even when single times do not. The
//! walks are the same on every engine (same seeds), so walk segments (one
//! walk advancing by one event) are counted once
//! by the wavefront engine and used for the scalar rows too; the general
//! (unspecialized) walk counts its own, since it runs more stages.

use crate::common::{load_material, print_out};
use rayon::ThreadPoolBuilder;
use std::fmt::Write as _;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};
use strata_bsdf::estimator::params::SetTable;
use strata_bsdf::estimator::scalar::ScalarEngine;
use strata_bsdf::estimator::wavefront::{Plan, Sets, Stats, Wavefront};
use strata_bsdf::lane::{F32x16, F32x8, Wide};
use strata_bsdf::stack::{InterfaceDesc, Roughness, Spectrum};
use strata_bsdf::{
    Bsdf, Engine, Estimator, EvalStart, LayerStack, LayeredBsdf, Materials, Queries, Settings,
};

/// Arguments of `strata bench`.
#[derive(clap::Args)]
pub struct Args {
    /// Print one JSON object per stack × engine × threads instead of a table.
    #[arg(long)]
    json: bool,
    /// Queries per batch (at most 1000000).
    #[arg(long, default_value_t = 48, value_parser = clap::value_parser!(u64).range(1..=MAX_QUERIES))]
    queries: u64,
    /// Walks per query.
    #[arg(long, default_value_t = 512, value_parser = crate::common::walks)]
    samples: u64,
    /// Minimum time each engine runs, in turns with the others (its fastest
    /// batch counts). At most a day.
    #[arg(long, default_value_t = 1.0)]
    min_seconds: f64,
    /// Threads of the "all threads" rows (default: every core; at most 1024).
    #[arg(long, value_parser = crate::common::threads)]
    threads: Option<u64>,
    /// Benchmark this material instead of the built-in representative stacks.
    #[arg(long)]
    material: Option<PathBuf>,
    /// Also time the bidirectional walks (scalar and wavefront rows): on the
    /// thick scattering stack they take minutes, so they are not in the
    /// default run. `--only scalar-bidir` or `wavefront-bidir` implies it.
    #[arg(long)]
    bidir: bool,
    /// Run only this engine's one-thread row (to profile it).
    #[arg(long, value_parser = ["scalar", "wavefront", "wavefront-general", "wavefront-f32x16", "scalar-bidir", "wavefront-bidir"])]
    only: Option<String>,
    /// Compare cost at equal error with another renderer's layered BxDFs, from
    /// its measured values and times (shipped with strata): `pbrt-v4`.
    #[arg(long, value_parser = ["pbrt-v4"])]
    against: Option<String>,
    /// Walks per direction pair of `--against` (pbrt-v4's data averages 10^6 calls).
    #[arg(long, default_value_t = 65536, value_parser = crate::common::walks)]
    walks: u64,
    /// Where eval starts its walks, for `--against`: the side `normal` picks
    /// (the library's default: nearer the normal, or farther from it for a
    /// reflected pair under a rough coat) or always from wi.
    #[arg(long, default_value = "normal")]
    eval_start: strata_bsdf::EvalStart,
    /// The estimator of `--against`: auto (the library's default: a closed
    /// form where the stack has one), uni (always the unidirectional walks)
    /// or bidir (always the bidirectional walks).
    #[arg(long, default_value = "auto")]
    estimator: strata_bsdf::Estimator,
    /// With `--against pbrt-v4`: one shading vertex of a path tracer (a BSDF
    /// sample, a light sample's eval and pdf, one walk each, batches of 4096
    /// on one thread) instead of many-walk evals.
    #[arg(long, requires = "against")]
    vertex: bool,
    /// Vertices per configuration, view and setting of `--vertex`.
    #[arg(long, default_value_t = 196_608, value_parser = clap::value_parser!(u64).range(4096..=100_000_000))]
    vertices: u64,
    /// Runs per pair of `--against` (the fastest counts).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=100))]
    reps: u32,
}

/// The largest `--queries`: the batch and the engines' per-query state stay
/// small (tens of megabytes).
const MAX_QUERIES: u64 = 1_000_000;

/// One row of the table.
struct Row {
    stack: String,
    engine: &'static str,
    threads: usize,
    queries_per_s: f64,
    segments_per_s: Option<f64>,
    occupancy: Option<f64>,
}

/// One engine configuration of a stack: runs the batch once per call and
/// keeps its fastest time.
struct Measurement<'a> {
    engine: &'static str,
    threads: usize,
    /// Runs the batch; the wavefront engines return their counters.
    run: Box<dyn FnMut() -> Option<Stats> + 'a>,
    best: Duration,
    spent: Duration,
    reps: u32,
    stats: Option<Stats>,
}

impl<'a> Measurement<'a> {
    fn new(engine: &'static str, threads: usize, run: impl FnMut() -> Option<Stats> + 'a) -> Self {
        Measurement {
            engine,
            threads,
            run: Box::new(run),
            best: Duration::MAX,
            spent: Duration::ZERO,
            reps: 0,
            stats: None,
        }
    }

    fn once(&mut self) {
        let t = Instant::now();
        let st = (self.run)();
        let e = t.elapsed();
        self.best = self.best.min(e);
        self.spent += e;
        self.reps += 1;
        self.stats = st.or(self.stats);
    }
}

/// Runs the measurements in turn, one batch each per round (after one
/// warm-up round), each until it has run at least three times and for at
/// least `min`: a slow phase of a shared machine then hits every engine
/// alike, and each keeps its fastest run. A measurement that is done sits
/// out the later rounds, so a fast one does not make a slow one run for as
/// many rounds as it needs.
fn interleaved(ms: &mut [Measurement], min: Duration) {
    ms.iter_mut().for_each(|m| {
        (m.run)();
    });
    let done = |m: &Measurement| m.reps >= 3 && m.spent >= min;
    while ms.iter().any(|m| !done(m)) {
        ms.iter_mut()
            .filter(|m| !done(m))
            .for_each(Measurement::once);
    }
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

/// A wavefront measurement: `W` lanes, `plan`, on a pool of `threads`.
fn wave<'a, W: Wide>(
    engine: &'static str,
    stack: &LayerStack,
    plan: Plan,
    pairs: &'a [([f64; 3], [f64; 3])],
    keys: &'a [u64],
    samples: u64,
    threads: usize,
) -> Result<Measurement<'a>, String> {
    let wf = Wavefront::<W>::new(stack, Settings::default(), plan);
    let pool = pool(threads)?;
    Ok(Measurement::new(engine, threads, move || {
        Some(pool.install(|| wf.eval_batch(pairs, samples, 1, keys).1))
    }))
}

/// Query `k`'s own variant of `stack`: every rough interface's roughness,
/// every layer's thickness and single-scattering albedo and every diffuse
/// albedo scaled by its own factor (0.7–1.3, 0.5–1.5, 0.8–1, 0.8–1); the
/// stack itself where a variant would change the shape.
fn varied(stack: &LayerStack, k: u64) -> LayerStack {
    let u = |i: u64| {
        let x = strata_bsdf::rng::mix64(k.wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ i);
        (x >> 11) as f64 / (1u64 << 53) as f64
    };
    let scale = |r: &Spectrum, f: f64| match r {
        Spectrum::Grey(v) => Spectrum::Grey(v * f),
        Spectrum::Rgb(a) => Spectrum::Rgb(a.map(|v| v * f)),
        Spectrum::Tabulated { nm, values } => Spectrum::Tabulated {
            nm: nm.clone(),
            values: values.iter().map(|v| v * f).collect(),
        },
        // IOR laws: no albedo has one.
        other => other.clone(),
    };
    let mut desc = stack.desc().clone();
    for (i, layer) in desc.layers.iter_mut().enumerate() {
        let i = 4 * i as u64;
        match &mut layer.interface {
            InterfaceDesc::Dielectric { roughness, .. }
            | InterfaceDesc::Conductor { roughness, .. } => {
                let f = 0.7 + 0.6 * u(i);
                *roughness = match *roughness {
                    Roughness::Isotropic(a) => Roughness::Isotropic(a * f),
                    Roughness::Anisotropic(a) => Roughness::Anisotropic(a.map(|x| x * f)),
                };
            }
            InterfaceDesc::Diffuse { albedo, .. } => *albedo = scale(albedo, 0.8 + 0.2 * u(i)),
        }
        if let Some(m) = &mut layer.medium {
            m.thickness *= 0.5 + u(i + 1);
            m.albedo = scale(&m.albedo, 0.8 + 0.2 * u(i + 2));
        }
    }
    match LayerStack::new(&desc) {
        Ok(v) if v.shape() == stack.shape() => v,
        _ => stack.clone(),
    }
}

/// The wavefront measurement where every query has its own parameters
/// ([`varied`]), on a pool of `threads`.
fn wave_varying<'a>(
    table: &'a Arc<SetTable>,
    set: &'a [u32],
    stack: &LayerStack,
    pairs: &'a [([f64; 3], [f64; 3])],
    keys: &'a [u64],
    samples: u64,
    threads: usize,
) -> Result<Measurement<'a>, String> {
    let wf = Wavefront::<F32x8>::new(stack, Settings::default(), Plan::Specialized);
    let pool = pool(threads)?;
    Ok(Measurement::new("wavefront-varying", threads, move || {
        let sets = Sets::Table(table, set);
        Some(pool.install(|| wf.eval_batch_in(sets, pairs, samples, 1, keys).1))
    }))
}

fn pool(threads: usize) -> Result<rayon::ThreadPool, String> {
    ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| format!("cannot start {threads} threads: {e}"))
}

fn bench_stack(
    name: &str,
    stack: &LayerStack,
    args: &Args,
    all: usize,
) -> Result<Vec<Row>, String> {
    let pairs = batch(stack, args.queries as usize);
    let keys: Vec<u64> = (0..pairs.len() as u64).collect();
    let q = pairs.len() as f64;
    let n = args.samples;
    let sc = ScalarEngine::<f32>::new(stack, Settings::default());
    let mut table = SetTable::new(stack.len());
    for k in 0..pairs.len() as u64 {
        table.push(&varied(stack, k), None, true, true);
    }
    let table = Arc::new(table);
    let set: Vec<u32> = (0..pairs.len() as u32).collect();
    let mut ms = vec![
        Measurement::new("scalar", 1, || {
            let s: f64 = pairs
                .iter()
                .enumerate()
                .map(|(k, &(wi, wo))| sc.eval(wi, wo, n, 1, k as u64).value[0])
                .sum();
            std::hint::black_box(s);
            None
        }),
        wave::<F32x8>("wavefront", stack, Plan::Specialized, &pairs, &keys, n, 1)?,
    ];
    ms.push(wave_varying(&table, &set, stack, &pairs, &keys, n, 1)?);
    if all > 1 {
        ms.push(wave::<F32x8>(
            "wavefront",
            stack,
            Plan::Specialized,
            &pairs,
            &keys,
            n,
            all,
        )?);
        ms.push(wave_varying(&table, &set, stack, &pairs, &keys, n, all)?);
    }
    ms.push(wave::<F32x8>(
        "wavefront-general",
        stack,
        Plan::General,
        &pairs,
        &keys,
        n,
        1,
    )?);
    ms.push(wave::<F32x16>(
        "wavefront-f32x16",
        stack,
        Plan::Specialized,
        &pairs,
        &keys,
        n,
        1,
    )?);
    let only_bidir = args.only.as_deref().is_some_and(|o| o.ends_with("-bidir"));
    if stack.len() >= 2 && (args.bidir || only_bidir) {
        // The bidirectional walks, whose connections make them costlier.
        ms.push(Measurement::new("scalar-bidir", 1, || {
            let s: f64 = (pairs.iter().enumerate())
                .map(|(k, &(wi, wo))| sc.eval_bidir(wi, wo, n, 1, k as u64).value[0])
                .sum();
            std::hint::black_box(s);
            None
        }));
        let wf = Wavefront::<F32x8>::new(stack, Settings::default(), Plan::Specialized);
        let (one, pairs, keys) = (pool(1)?, &pairs, &keys);
        ms.push(Measurement::new("wavefront-bidir", 1, move || {
            let e = one.install(|| wf.eval_bidir_batch(pairs, n, 1, keys));
            std::hint::black_box(e.len());
            None
        }));
    }
    if let Some(only) = &args.only {
        ms.retain(|m| m.engine == only && m.threads == 1);
        if ms.is_empty() {
            return Err(format!(
                "--only {only}: {name} has one interface, no bidirectional walks to time"
            ));
        }
    }
    interleaved(&mut ms, Duration::from_secs_f64(args.min_seconds));
    // The scalar engine runs the same walks as the specialized wavefront: it
    // takes that row's segment count (unknown if it ran alone; the
    // bidirectional walks' segments are not counted).
    let walks = ms
        .iter()
        .find(|m| m.engine == "wavefront")
        .and_then(|m| m.stats);
    Ok(ms
        .iter()
        .map(|m| {
            let t = m.best.as_secs_f64();
            Row {
                stack: name.to_string(),
                engine: m.engine,
                threads: m.threads,
                queries_per_s: q / t,
                segments_per_s: if m.engine.ends_with("-bidir") {
                    None
                } else {
                    m.stats.or(walks).map(|st| st.segments as f64 / t)
                },
                occupancy: m.stats.map(|s| s.occupancy()),
            }
        })
        .collect())
}

/// The batch of every stack's queries at once, interleaved (query `k` on
/// stack `k % stacks`), through [`Materials`] with the wavefront rows' walks
/// (the wavefront engine, unidirectional walks from `wi`), one thread and
/// all threads; and the cost of building a parameter set.
fn bench_mixed(
    stacks: &[(String, LayerStack)],
    args: &Args,
    all: usize,
) -> Result<Vec<Row>, String> {
    let m = stacks.len();
    let per: Vec<Vec<([f64; 3], [f64; 3])>> = (stacks.iter())
        .map(|(_, st)| batch(st, args.queries as usize))
        .collect();
    let v = |d: [f64; 3]| glam::Vec3::new(d[0] as f32, d[1] as f32, d[2] as f32);
    let (mut pairs, mut material) = (Vec::new(), Vec::new());
    for k in 0..args.queries as usize {
        for (s, p) in per.iter().enumerate() {
            pairs.push((v(p[k].0), v(p[k].1)));
            material.push(s as u32);
        }
    }
    let keys: Vec<u64> = (0..pairs.len() as u64).collect();
    let (wi, wo): (Vec<glam::Vec3>, Vec<glam::Vec3>) = pairs.iter().copied().unzip();
    let name = format!("mixed ({m} shapes)");
    let mut ms = Vec::new();
    let mut threads = vec![1];
    if all > 1 {
        threads.push(all);
    }
    for t in threads {
        let template = LayeredBsdf::new(stacks[0].1.clone())
            .engine(Engine::Wavefront)
            .estimator(Estimator::Unidirectional)
            .eval_start(EvalStart::Wi)
            .threads(t)
            .map_err(|e| e.to_string())?;
        let mats = Materials::new(&template, stacks.iter().map(|(_, st)| st.clone()));
        let q = Queries::pairs(&wi, &wo)
            .keys(&keys)
            .rows(&material)
            .walks(args.samples);
        ms.push(Measurement::new("wavefront-mixed", t, move || {
            let mut sum = 0.0;
            let e = mats.eval_into(&q, &mut |_, e| sum += e.value[0]);
            std::hint::black_box((e.is_ok(), sum));
            None
        }));
    }
    interleaved(&mut ms, Duration::from_secs_f64(args.min_seconds));
    let q = pairs.len() as f64;
    Ok(ms
        .iter()
        .map(|x| Row {
            stack: name.clone(),
            engine: x.engine,
            threads: x.threads,
            queries_per_s: q / x.best.as_secs_f64(),
            segments_per_s: None,
            occupancy: None,
        })
        .collect())
}

/// Time to build one parameter set: `LayerStack::new` of a variant's
/// description and its row of [`Materials`] (of one shape), per set, from
/// a thousand sets of `stack`.
fn set_build_cost(stack: &LayerStack) -> (f64, f64) {
    let n = 1000u64;
    let descs: Vec<_> = (0..n).map(|k| varied(stack, k).desc().clone()).collect();
    let t = Instant::now();
    let stacks: Vec<LayerStack> = (descs.iter())
        .map(|d| LayerStack::new(d).expect("a variant is valid"))
        .collect();
    let validate = t.elapsed().as_secs_f64() / n as f64;
    let bsdf = LayeredBsdf::new(stack.clone());
    let t = Instant::now();
    let sets = Materials::new(&bsdf, stacks);
    assert_eq!(sets.shapes(), 1, "variants keep the shape");
    std::hint::black_box(sets.len());
    (validate, t.elapsed().as_secs_f64() / n as f64)
}

pub fn run(args: Args) -> Result<(), String> {
    crate::common::check_seconds("--min-seconds", args.min_seconds, true)?;
    let all = match args.threads {
        Some(n) => n as usize,
        None => std::thread::available_parallelism().map_or(1, |n| n.get()),
    };
    if args.vertex {
        let text = crate::bench_vertex::report(args.vertices, 4096, 3, args.json)?;
        return print_out(&text);
    }
    if args.against.is_some() {
        let text = crate::bench_pbrt::report(
            args.walks,
            args.reps,
            all,
            args.eval_start,
            args.estimator,
            args.json,
        )?;
        return print_out(&text);
    }
    let stacks: Vec<(String, LayerStack)> = match &args.material {
        Some(p) => vec![(p.display().to_string(), load_material(p)?)],
        None => strata_bsdf::materials::REPRESENTATIVE
            .iter()
            .map(|&name| {
                let st =
                    strata_bsdf::materials::builtin(name).expect("built-in materials are valid");
                (name.to_string(), st)
            })
            .collect(),
    };
    let mut rows = Vec::new();
    for (name, st) in &stacks {
        if !args.json {
            crate::common::note(&format!("benchmarking {name} ..."));
        }
        rows.extend(bench_stack(name, st, &args, all)?);
    }
    if stacks.len() > 1 && args.only.is_none() {
        if !args.json {
            crate::common::note("benchmarking a batch that mixes them ...");
        }
        rows.extend(bench_mixed(&stacks, &args, all)?);
    }
    let mut text = String::new();
    if args.json {
        for r in &rows {
            let line = serde_json::json!({
                "stack": r.stack, "engine": r.engine, "threads": r.threads,
                "queries_per_s": r.queries_per_s, "segments_per_s": r.segments_per_s,
                "occupancy": r.occupancy,
            });
            let _ = writeln!(text, "{line}");
        }
    } else {
        table(&mut text, &rows, &args);
        summary(&mut text, &rows);
        let _ = writeln!(text, "\nbuilding a parameter set (per set, 1000 variants):");
        for (name, st) in &stacks {
            let (validate, add) = set_build_cost(st);
            let _ = writeln!(
                text,
                "  {name:<24} LayerStack::new {:.2} us, a set (a row of Materials) {:.2} us",
                validate * 1e6,
                add * 1e6
            );
        }
    }
    print_out(&text)
}

/// The ratios issue 15 asks for: each `wavefront-varying` row against the
/// uniform `wavefront` row of its stack and threads, and each
/// `wavefront-mixed` row against the throughput its stacks' uniform rows
/// predict for the same mix (equal numbers of queries of each: the
/// harmonic mean of their rates) and against their arithmetic mean.
fn summary(o: &mut String, rows: &[Row]) {
    let rate = |stack: &str, engine: &str, t: usize| {
        (rows.iter())
            .find(|r| r.stack == stack && r.engine == engine && r.threads == t)
            .map(|r| r.queries_per_s)
    };
    let _ = writeln!(o);
    for r in rows.iter().filter(|r| r.engine == "wavefront-varying") {
        if let Some(u) = rate(&r.stack, "wavefront", r.threads) {
            let _ = writeln!(
                o,
                "{:<24} varying / uniform, {} thread(s): {:.2}",
                r.stack,
                r.threads,
                r.queries_per_s / u
            );
        }
    }
    for r in rows.iter().filter(|r| r.engine == "wavefront-mixed") {
        let uniform: Vec<f64> = (rows.iter())
            .filter(|u| u.engine == "wavefront" && u.threads == r.threads)
            .map(|u| u.queries_per_s)
            .collect();
        if uniform.is_empty() {
            continue;
        }
        let k = uniform.len() as f64;
        let harmonic = k / uniform.iter().map(|x| 1.0 / x).sum::<f64>();
        let mean = uniform.iter().sum::<f64>() / k;
        let _ = writeln!(
            o,
            "{:<24} mixed, {} thread(s): {:.2} x the uniform rows' rate for this mix, {:.2} x their mean",
            r.stack,
            r.threads,
            r.queries_per_s / harmonic,
            r.queries_per_s / mean
        );
    }
}

/// The table of `rows`, appended to `o`.
fn table(o: &mut String, rows: &[Row], args: &Args) {
    let _ = writeln!(
        o,
        "eval batches: {} queries x {} walks; engines in turns, fastest run of each (>= {} s each)\n",
        args.queries, args.samples, args.min_seconds
    );
    let _ = writeln!(
        o,
        "{:<24} {:<18} {:>7} {:>11} {:>12} {:>9} {:>9}",
        "stack", "engine", "threads", "queries/s", "Msegments/s", "occupancy", "x scalar"
    );
    let mut last = "";
    // The scalar engine's rate with the unidirectional and the
    // bidirectional walks: each row is against the one of its walks.
    let (mut scalar, mut scalar_bidir) = (None, None);
    for r in rows {
        let name = if r.stack != last {
            (scalar, scalar_bidir) = (None, None);
            r.stack.as_str()
        } else {
            ""
        };
        match r.engine {
            "scalar" => scalar = Some(r.queries_per_s),
            "scalar-bidir" => scalar_bidir = Some(r.queries_per_s),
            _ => {}
        }
        let scalar = if r.engine.ends_with("-bidir") {
            scalar_bidir
        } else {
            scalar
        };
        let dash = |x: Option<f64>, f: fn(f64) -> String| x.map_or("-".into(), f);
        let _ = writeln!(
            o,
            "{:<24} {:<18} {:>7} {:>11.1} {:>12} {:>9} {:>9}",
            name,
            r.engine,
            r.threads,
            r.queries_per_s,
            dash(r.segments_per_s, |s| format!("{:.2}", s / 1e6)),
            dash(r.occupancy, |o| format!("{o:.3}")),
            dash(scalar.map(|s| r.queries_per_s / s), |x| format!("{x:.2}")),
        );
        last = &r.stack;
    }
}
