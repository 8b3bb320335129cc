//! Estimators, scalar reference against the wavefront engine, on the
//! representative stacks (`strata_bsdf::materials::REPRESENTATIVE`): the same eval
//! batch (same seeds, so the same walks) on the scalar engine, on the
//! wavefront on one thread, and on the wavefront's specialized and general
//! walks. Throughput is in queries per second. Then single `sample` and `pdf`
//! calls through the public API on each engine (time per call), and small
//! batches of them (`small`: 4 and 16 queries per call, a BSDF with a pool of
//! two threads, time per call). Then the pdf's density walks with and
//! without their medium connection (`pdf`). Last, what a renderer's path
//! vertex asks (`vertex`: a sample, then the eval and pdf of a light
//! direction, a batch of 16 vertices on one thread) with the default pdf
//! walks and with 4 fixed ones: the cost of the default's accuracy.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use glam::Vec3;
use std::hint::black_box;
use strata_bsdf::estimator::scalar::ScalarEngine;
use strata_bsdf::estimator::wavefront::{Plan, Wavefront};
use strata_bsdf::lane::F32x8;
use strata_bsdf::{Bsdf, Engine, LayeredBsdf, PdfKind, PdfWalks, Queries, Settings};

const QUERIES: usize = 16;
const SAMPLES: u64 = 256;

/// A query: `(wi, wo)`.
type Pair = ([f64; 3], [f64; 3]);

fn pairs() -> Vec<Pair> {
    let dir = |t: f64, p: f64| {
        let (t, p) = (t.to_radians(), p.to_radians());
        [t.sin() * p.cos(), t.sin() * p.sin(), t.cos()]
    };
    (0..QUERIES)
        .map(|k| {
            let u = (k as f64 + 0.5) / QUERIES as f64;
            (dir(80.0 * u, 0.0), dir(80.0 * (1.0 - u), 137.0 * k as f64))
        })
        .collect()
}

/// A one-thread pool, the batch's queries and their keys.
fn batch() -> (rayon::ThreadPool, Vec<Pair>, Vec<u64>) {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    (pool, pairs(), (0..QUERIES as u64).collect())
}

fn estimators(c: &mut Criterion) {
    let (pool, pairs, keys) = batch();
    for &name in strata_bsdf::materials::REPRESENTATIVE {
        let stack = strata_bsdf::materials::builtin(name).unwrap();
        let mut g = c.benchmark_group(format!("eval/{name}"));
        g.throughput(Throughput::Elements(QUERIES as u64));
        let sc = ScalarEngine::<f32>::new(&stack, Settings::default());
        g.bench_function(BenchmarkId::new("scalar", 1), |b| {
            b.iter(|| {
                let s: f64 = pairs
                    .iter()
                    .zip(&keys)
                    .map(|(&(wi, wo), &k)| sc.eval(wi, wo, SAMPLES, 1, k).value[0])
                    .sum();
                black_box(s)
            })
        });
        for (label, plan) in [
            ("wavefront", Plan::Specialized),
            ("wavefront-general", Plan::General),
        ] {
            let wf = Wavefront::<F32x8>::new(&stack, Settings::default(), plan);
            g.bench_function(BenchmarkId::new(label, 1), |b| {
                b.iter(|| pool.install(|| black_box(wf.eval_batch(&pairs, SAMPLES, 1, &keys).0)))
            });
        }
        g.finish();
    }
}

/// Single queries through the public API, as a renderer makes them: one
/// `sample` or one `pdf` per call, on each engine, with a one-thread pool
/// (time per call).
fn single_queries(c: &mut Criterion) {
    let wi = Vec3::new(0.3, 0.1, 0.9).normalize();
    let wo = Vec3::new(-0.2, 0.4, 0.8).normalize();
    for &name in strata_bsdf::materials::REPRESENTATIVE {
        let stack = strata_bsdf::materials::builtin(name).unwrap();
        let mut g = c.benchmark_group(format!("single/{name}"));
        for (label, bsdf) in engines(&stack, 1) {
            let mut k = 0u64;
            g.bench_function(BenchmarkId::new("sample", label), |b| {
                b.iter(|| {
                    k += 1;
                    black_box(bsdf.sample(wi, k).unwrap())
                })
            });
            g.bench_function(BenchmarkId::new("pdf", label), |b| {
                b.iter(|| black_box(bsdf.pdf(wi, wo).unwrap()))
            });
        }
        g.finish();
    }
}

/// The stack on each engine, with a pool of `threads` threads.
fn engines(stack: &strata_bsdf::LayerStack, threads: usize) -> [(&'static str, LayeredBsdf); 2] {
    [("scalar", Engine::Scalar), ("wavefront", Engine::Wavefront)].map(|(label, engine)| {
        let bsdf = LayeredBsdf::new(stack.clone()).engine(engine);
        (label, bsdf.threads(threads).unwrap())
    })
}

fn small_batches(c: &mut Criterion) {
    let wo = Vec3::new(-0.2, 0.4, 0.8).normalize();
    for &name in strata_bsdf::materials::REPRESENTATIVE {
        let stack = strata_bsdf::materials::builtin(name).unwrap();
        let mut g = c.benchmark_group(format!("small/{name}"));
        for n in [4usize, 16] {
            let wis: Vec<Vec3> = (0..n)
                .map(|i| Vec3::new(0.05 * i as f32, 0.1, 0.9).normalize())
                .collect();
            let wos = vec![wo; n];
            let keys: Vec<u64> = (0..n as u64).collect();
            for (label, bsdf) in engines(&stack, 2) {
                let mut k = 0u64;
                g.bench_function(BenchmarkId::new(format!("sample{n}"), label), |b| {
                    b.iter(|| {
                        k += 1;
                        let idx = vec![k; n];
                        black_box(samples(&bsdf, &wis, &keys, &idx))
                    })
                });
                g.bench_function(BenchmarkId::new(format!("pdf{n}"), label), |b| {
                    b.iter(|| black_box(pdfs(&bsdf, &wis, &wos)))
                });
            }
        }
        g.finish();
    }
}

/// The pdf's density walks on the scattering stacks, with the medium
/// connection (the default) and without it (`Settings::mis` off), on one
/// thread: the cost side of the connection (its variance side is the
/// ignored test `pdf_density::medium_connection_variance`).
fn density_walks(c: &mut Criterion) {
    let (pool, pairs, keys) = batch();
    for name in strata_bsdf::materials::SCATTERING {
        let stack = strata_bsdf::materials::builtin(name).unwrap();
        let mut g = c.benchmark_group(format!("pdf/{name}"));
        g.throughput(Throughput::Elements(QUERIES as u64));
        for (label, mis) in [("medium-connection", true), ("walk-only", false)] {
            let settings = Settings {
                mis,
                ..Settings::default()
            };
            let wf = Wavefront::<F32x8>::new(&stack, settings, Plan::Specialized);
            g.bench_function(BenchmarkId::new(label, 1), |b| {
                b.iter(|| {
                    pool.install(|| {
                        black_box(wf.pdf_batch(&pairs, 64, 1, &keys, PdfKind::Unbiased))
                    })
                })
            });
        }
        g.finish();
    }
}

/// A batch of path vertices on the representative stacks: `sample`, then
/// `eval` and `pdf` of a light direction, through the public API on one
/// thread, with the default pdf walks ([`PdfWalks::ADAPTIVE`]), with
/// [`PdfWalks::TIGHT`] and with 4.
fn vertices(c: &mut Criterion) {
    let pairs: Vec<(Vec3, Vec3)> = pairs()
        .into_iter()
        .map(|(a, b)| {
            (
                Vec3::from(a.map(|x| x as f32)),
                Vec3::from(b.map(|x| x as f32)),
            )
        })
        .collect();
    let wis: Vec<Vec3> = pairs.iter().map(|p| p.0).collect();
    let keys: Vec<u64> = (0..QUERIES as u64).collect();
    for &name in strata_bsdf::materials::REPRESENTATIVE {
        let stack = strata_bsdf::materials::builtin(name).unwrap();
        let mut g = c.benchmark_group(format!("vertex/{name}"));
        g.throughput(Throughput::Elements(QUERIES as u64));
        let rules = [
            ("default", PdfWalks::ADAPTIVE),
            ("tight", PdfWalks::TIGHT),
            ("pdf4", 4.into()),
        ];
        for (label, walks) in rules {
            let bsdf = (LayeredBsdf::new(stack.clone()).pdf_walks(walks))
                .threads(1)
                .unwrap();
            let mut k = 0u64;
            g.bench_function(BenchmarkId::new(label, 1), |b| {
                b.iter(|| {
                    k += 1;
                    let idx = vec![k; QUERIES];
                    let s = samples(&bsdf, &wis, &keys, &idx);
                    let (wi, wo): (Vec<Vec3>, Vec<Vec3>) = pairs.iter().copied().unzip();
                    let mut f = 0.0;
                    let q = Queries::pairs(&wi, &wo);
                    bsdf.eval_into(&q, &mut |_, e| f += e.value[0]).unwrap();
                    black_box((s, f, pdfs(&bsdf, &wi, &wo)))
                })
            });
        }
        g.finish();
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10).warm_up_time(std::time::Duration::from_millis(500)).measurement_time(std::time::Duration::from_secs(3));
    targets = estimators, single_queries, small_batches, density_walks, vertices
}
criterion_main!(benches);

/// The samples of a batch (how many were not absorbed).
fn samples(bsdf: &LayeredBsdf, wis: &[Vec3], keys: &[u64], index: &[u64]) -> usize {
    let q = Queries::directions(wis).keys(keys).indices(index);
    let mut n = 0;
    bsdf.sample_into(&q, &mut |_, s| n += usize::from(s.is_some()))
        .unwrap();
    n
}

/// The sum of a batch's pdfs.
fn pdfs(bsdf: &LayeredBsdf, wi: &[Vec3], wo: &[Vec3]) -> f32 {
    let mut sum = 0.0;
    bsdf.pdf_into(&Queries::pairs(wi, wo), &mut |_, p| sum += p)
        .unwrap();
    sum
}
