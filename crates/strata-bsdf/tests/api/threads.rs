//! Every batch call runs where the BSDF's thread setting says (issue 40):
//! with `threads(1)` on the calling thread alone, with a pool of its own
//! never on rayon's current pool, and a call of at most `SERIAL_WALKS`
//! walks (a pdf batch of at most `PDF_CHUNK` queries) on the calling thread
//! whatever the setting.
//!
//! Each entry point (eval, keyed eval, sample, keyed sample, pdf, unbiased
//! pdf, albedo; on the BSDF's own parameters, its parameter sets, a
//! [`Materials`] of two shapes, per-query columns through [`PerQuery`];
//! the `Vec` batches, the slice calls and the single calls) runs under
//! [`watch`] (tests/common/threads.rs, whose doc explains the method): on
//! the test's thread, which is no rayon worker, while every worker of
//! rayon's global pool runs a thief that takes and records every job handed
//! to that pool. A call that goes parallel without a pool of its own hands
//! its jobs to that pool, where only the thieves can run them, so the set
//! of threads seen running the call is exact, not a matter of timing: with
//! `threads(1)` it must be the calling thread alone. The same batches under
//! the default setting (rayon's current pool) are seen to run jobs there,
//! where their path has parallel work: they are large enough, and the
//! watch sees it. Each test runs in a process of its own (the global pool
//! is process-wide).
//!
//! Three stacks take the three routes of a batch: walks of the
//! unidirectional estimator, of the bidirectional one, and a rough coat
//! answered without walks (its eval and sample go query by query over the
//! pool; its albedo walks).

use crate::common::batches::{Batches, Buffers, MaterialBatches, MaterialBuffers};
use crate::common::threads::{in_own_process, watch, Watched};
use crate::common::{stack, COATED_COPPER, VARNISH_OVER_SCATTERING};
use glam::Vec3;
use strata_bsdf::estimator::coat_return::RoughReturn;
use strata_bsdf::{
    AlbedoRecord, Column, Estimator, EvalRecord, LayerStack, LayeredBsdf, Materials, PerQuery,
    SampleRecord, SetPath, Vectors, VectorsMut,
};

/// A rough coat over an absorbing layer over a Lambertian base: answered
/// without walks under `Auto` (eval by its factorization, sample and pdf by
/// its walk-free sampler), its albedo by walks.
const ROUGH_COAT_ABSORBER_LAMBERTIAN: &str = r#"
[[layers]]
interface = { kind = "dielectric", ior = 1.5, roughness = 0.2 }
medium = { thickness = 0.5, sigma_t = [0.2, 0.5, 1.0], albedo = 0.0 }
[[layers]]
interface = { kind = "diffuse", albedo = 0.6 }
"#;

/// Queries of a large batch: more sample queries than `SERIAL_WALKS` (256)
/// on each of the two shapes of [`Case::materials`], more pdf queries than
/// `PDF_CHUNK` (64).
const LARGE: usize = 600;
/// Queries of a small batch: at most `SERIAL_WALKS` walks a call.
const SMALL: usize = 4;
/// Walks per eval, unbiased pdf and albedo query.
const WALKS: u64 = 32;

/// A BSDF and what its per-query calls vary.
struct Case {
    name: &'static str,
    bsdf: LayeredBsdf,
    /// The parameter sets' stacks (the BSDF's shape).
    sets: Vec<LayerStack>,
    /// A [`Materials`]' stacks (two shapes).
    materials: Vec<LayerStack>,
    /// The per-query column's path and its values (`f(k)` for query `k`).
    column: (&'static str, fn(usize) -> f32),
}

fn cases() -> Vec<Case> {
    let varnish = |t: f32| {
        let text = VARNISH_OVER_SCATTERING.replace("thickness = 1.0", &format!("thickness = {t}"));
        stack(&text)
    };
    let coat = |albedo: f32| {
        let text = ROUGH_COAT_ABSORBER_LAMBERTIAN.replace("0.6", &format!("{albedo}"));
        stack(&text)
    };
    let walks = |estimator| {
        LayeredBsdf::new(varnish(1.0))
            .samples(WALKS)
            .pdf_samples(8)
            .seed(7)
            .estimator(estimator)
    };
    let thickness: fn(usize) -> f32 = |k| 0.5 + 0.01 * (k % 50) as f32;
    vec![
        Case {
            name: "unidirectional walks",
            bsdf: walks(Estimator::Unidirectional),
            sets: vec![varnish(0.5), varnish(1.0), varnish(2.0)],
            materials: vec![varnish(0.5), stack(COATED_COPPER), varnish(2.0)],
            column: ("layers[0].medium.thickness", thickness),
        },
        Case {
            name: "bidirectional walks",
            bsdf: walks(Estimator::Bidirectional),
            sets: vec![varnish(0.5), varnish(1.0), varnish(2.0)],
            materials: vec![varnish(0.5), stack(COATED_COPPER), varnish(2.0)],
            column: ("layers[0].medium.thickness", thickness),
        },
        Case {
            name: "rough coat without walks",
            bsdf: LayeredBsdf::new(coat(0.6))
                .samples(WALKS)
                .pdf_samples(8)
                .seed(7),
            sets: vec![coat(0.3), coat(0.6), coat(0.9)],
            materials: vec![coat(0.3), stack(COATED_COPPER), coat(0.9)],
            column: ("layers[1].interface.albedo", |k| {
                0.2 + 0.01 * (k % 70) as f32
            }),
        },
    ]
}

/// The inputs of a batch of `n` queries.
struct Inputs {
    wi: Vec<[f32; 3]>,
    wo: Vec<[f32; 3]>,
    keys: Vec<u64>,
    /// Query `k`'s parameter set, material, and index of its sample.
    set: Vec<u32>,
    material: Vec<u32>,
    index: Vec<u64>,
    column: Vec<f32>,
    /// `(wi, wo)` and `wi` as the `Vec` batches take them.
    pairs: Vec<(Vec3, Vec3)>,
    wis: Vec<Vec3>,
}

impl Inputs {
    fn new(n: usize, column: fn(usize) -> f32) -> Inputs {
        // Spread over the hemisphere; every eleventh `wo` below (transmission).
        let dir = |k: usize, s: f32| {
            let t = k as f32 * 0.618_034 * s;
            let z = 0.1 + 0.85 * (t * 1.3).sin().abs();
            let r = (1.0 - z * z).sqrt();
            [r * t.cos(), r * t.sin(), if k % 11 == 3 { -z } else { z }]
        };
        let wi: Vec<[f32; 3]> = (0..n).map(|k| dir(k, 1.0)).collect();
        let wo: Vec<[f32; 3]> = (0..n).map(|k| dir(k + 7, 2.3)).collect();
        Inputs {
            pairs: (wi.iter().zip(&wo))
                .map(|(a, b)| (Vec3::from(*a), Vec3::from(*b)))
                .collect(),
            wis: wi.iter().map(|&a| Vec3::from(a)).collect(),
            wi,
            wo,
            keys: (0..n as u64).map(|k| k.wrapping_mul(0x9e37_79b9)).collect(),
            set: (0..n as u32).map(|k| k % 3).collect(),
            // Materials 0 and 2 are of one shape, 1 of another: half each.
            material: (0..n as u32)
                .map(|k| [0, 1, 2, 1][k as usize % 4])
                .collect(),
            index: (0..n as u64).collect(),
            column: (0..n).map(column).collect(),
        }
    }
}

/// Takes a call's answers (their numbers are other modules' concern).
fn used<T>(_: T) {}

/// A named call whose answers are dropped (their numbers are other
/// modules' concern).
type Call<'a> = (&'static str, Box<dyn Fn() + Send + Sync + 'a>);

/// Every batch entry point of `b` (and its single calls) on `x`, with the
/// parameter sets, materials and column of `case`.
fn calls<'a>(
    b: &'a LayeredBsdf,
    sets: &'a Materials,
    mats: &'a Materials,
    path: &'a SetPath,
    x: &'a Inputs,
) -> Vec<Call<'a>> {
    let n = x.wi.len();
    let (pairs, wis) = (&x.pairs[..], &x.wis[..]);
    let (wi, wo) = (Vectors::Aos(&x.wi), Vectors::Aos(&x.wo));
    let keys = &x.keys[..];
    let (set, material, index) = (&x.set[..], &x.material[..], &x.index[..]);
    let samples = b.samples_per_eval();
    let column = move || {
        let c = Column {
            path,
            width: 1,
            values: &x.column,
        };
        PerQuery::new(b, n, &[c]).unwrap()
    };
    let v3 = move || vec![[0.0f32; 3]; n];
    let f32s = move || vec![0.0f32; n];
    let one = (Vec3::from(x.wi[0]), Vec3::from(x.wo[0]));
    let many = WALKS * n as u64;
    // (The slice calls that run walks return their count of truncated ones.)
    fn ok<T>(r: Result<T, strata_bsdf::BatchError>) {
        r.unwrap();
    }
    let v: Vec<Call<'a>> = vec![
        // The BSDF's own parameters: `Vec` batches.
        (
            "eval_batch",
            Box::new(move || used(b.eval_batch(pairs).unwrap())),
        ),
        (
            "eval_batch_keyed",
            Box::new(move || used(b.eval_batch_keyed(pairs, samples, keys).unwrap())),
        ),
        (
            "sample_batch",
            Box::new(move || used(b.sample_batch(wis, index).unwrap())),
        ),
        (
            "sample_batch_keyed",
            Box::new(move || used(b.sample_batch_keyed(wis, keys, index).unwrap())),
        ),
        (
            "pdf_batch",
            Box::new(move || used(b.pdf_batch(pairs).unwrap())),
        ),
        (
            "pdf_unbiased_batch",
            Box::new(move || used(b.pdf_unbiased_batch(pairs, WALKS).unwrap())),
        ),
        (
            "albedo_batch",
            Box::new(move || used(b.albedo_batch(wis, WALKS).unwrap())),
        ),
        (
            "albedo_batch_keyed",
            Box::new(move || used(b.albedo_batch_keyed(wis, WALKS, keys).unwrap())),
        ),
        // Slice calls.
        (
            "eval_into",
            Box::new(move || {
                let (mut f, mut se) = (v3(), v3());
                let out = (VectorsMut::Aos(&mut f), Some(VectorsMut::Aos(&mut se)));
                ok(b.eval_buffers(wi, wo, None, out.0, out.1))
            }),
        ),
        (
            "eval_records",
            Box::new(move || {
                let mut r = vec![EvalRecord::default(); n];
                ok(b.eval_records(wi, wo, Some(keys), &mut r))
            }),
        ),
        (
            "sample_into",
            Box::new(move || {
                let (mut o, mut w, mut p, mut fl) = (v3(), v3(), f32s(), vec![0u32; n]);
                let (o, w) = (VectorsMut::Aos(&mut o), VectorsMut::Aos(&mut w));
                ok(b.sample_buffers(wi, None, o, w, &mut p, &mut fl))
            }),
        ),
        (
            "sample_records",
            Box::new(move || {
                let mut r = vec![SampleRecord::default(); n];
                ok(b.sample_records(wi, Some(keys), &mut r))
            }),
        ),
        (
            "pdf_into",
            Box::new(move || ok(b.pdf_buffers(wi, wo, &mut f32s()))),
        ),
        (
            "pdf_unbiased_into",
            Box::new(move || ok(b.pdf_unbiased_buffers(wi, wo, WALKS, &mut f32s(), &mut f32s()))),
        ),
        (
            "albedo_records",
            Box::new(move || {
                let mut r = vec![AlbedoRecord::default(); n];
                ok(b.albedo_records(wi, WALKS, None, &mut r))
            }),
        ),
        // Single calls of as many walks as the batch.
        (
            "eval_with",
            Box::new(move || used(b.eval_with(one.0, one.1, many, 3).unwrap())),
        ),
        (
            "pdf_unbiased",
            Box::new(move || used(b.pdf_unbiased(one.0, one.1, many).unwrap())),
        ),
        (
            "albedo",
            Box::new(move || used(b.albedo(one.0, many).unwrap())),
        ),
        // Materials of one shape: the parameter sets of one BSDF.
        (
            "Materials of one shape (its sets)::eval_batch",
            Box::new(move || used(sets.eval_batch(set, pairs).unwrap())),
        ),
        (
            "Materials of one shape (its sets)::eval_batch_keyed",
            Box::new(move || used(sets.eval_batch_keyed(set, pairs, samples, keys).unwrap())),
        ),
        (
            "Materials of one shape (its sets)::sample_batch",
            Box::new(move || used(sets.sample_batch(set, wis, index).unwrap())),
        ),
        (
            "Materials of one shape (its sets)::sample_batch_keyed",
            Box::new(move || used(sets.sample_batch_keyed(set, wis, keys, index).unwrap())),
        ),
        (
            "Materials of one shape (its sets)::pdf_batch",
            Box::new(move || used(sets.pdf_batch(set, pairs).unwrap())),
        ),
        (
            "Materials of one shape (its sets)::pdf_unbiased_batch",
            Box::new(move || used(sets.pdf_unbiased_batch(set, pairs, WALKS).unwrap())),
        ),
        (
            "Materials of one shape (its sets)::albedo_batch_keyed",
            Box::new(move || used(sets.albedo_batch_keyed(set, wis, WALKS, keys).unwrap())),
        ),
        // Materials of two shapes: `Vec` batches and slice calls.
        (
            "Materials::eval_batch_keyed",
            Box::new(move || {
                used(
                    mats.eval_batch_keyed(material, pairs, samples, keys)
                        .unwrap(),
                )
            }),
        ),
        (
            "Materials::eval_batch",
            Box::new(move || used(mats.eval_batch(material, pairs).unwrap())),
        ),
        (
            "Materials::sample_batch_keyed",
            Box::new(move || used(mats.sample_batch_keyed(material, wis, keys, index).unwrap())),
        ),
        (
            "Materials::albedo_batch_keyed",
            Box::new(move || used(mats.albedo_batch_keyed(material, wis, WALKS, keys).unwrap())),
        ),
        (
            "Materials::sample_batch",
            Box::new(move || used(mats.sample_batch(material, wis, index).unwrap())),
        ),
        (
            "Materials::pdf_batch",
            Box::new(move || used(mats.pdf_batch(material, pairs).unwrap())),
        ),
        (
            "Materials::pdf_unbiased_batch",
            Box::new(move || used(mats.pdf_unbiased_batch(material, pairs, WALKS).unwrap())),
        ),
        (
            "Materials::eval_into",
            Box::new(move || {
                let mut f = v3();
                ok(mats.eval_buffers(material, wi, wo, None, VectorsMut::Aos(&mut f), None))
            }),
        ),
        (
            "Materials::sample_records",
            Box::new(move || {
                let mut r = vec![SampleRecord::default(); n];
                ok(mats.sample_records(material, wi, Some(keys), &mut r))
            }),
        ),
        (
            "Materials::sample_into",
            Box::new(move || {
                let (mut o, mut w, mut p, mut fl) = (v3(), v3(), f32s(), vec![0u32; n]);
                let (o, w) = (VectorsMut::Aos(&mut o), VectorsMut::Aos(&mut w));
                ok(mats.sample_buffers(material, wi, None, o, w, &mut p, &mut fl))
            }),
        ),
        (
            "Materials::pdf_unbiased_into",
            Box::new(move || {
                ok(mats.pdf_unbiased_buffers(material, wi, wo, WALKS, &mut f32s(), &mut f32s()))
            }),
        ),
        (
            "Materials::pdf_into",
            Box::new(move || ok(mats.pdf_buffers(material, wi, wo, &mut f32s()))),
        ),
        (
            "Materials::albedo_records",
            Box::new(move || {
                let mut r = vec![AlbedoRecord::default(); n];
                ok(mats.albedo_records(material, wi, WALKS, Some(keys), &mut r))
            }),
        ),
        // Per-query columns (what the C calls' `columns` and Python's
        // `params=` run), the answerer built inside the watch too.
        (
            "PerQuery::eval_into",
            Box::new(move || {
                let (mut f, mut se) = (v3(), v3());
                let out = (VectorsMut::Aos(&mut f), Some(VectorsMut::Aos(&mut se)));
                ok(column().eval_buffers(wi, wo, Some(keys), out.0, out.1))
            }),
        ),
        (
            "PerQuery::sample_into",
            Box::new(move || {
                let (mut o, mut w, mut p, mut fl) = (v3(), v3(), f32s(), vec![0u32; n]);
                let (o, w) = (VectorsMut::Aos(&mut o), VectorsMut::Aos(&mut w));
                ok(column().sample_buffers(wi, None, o, w, &mut p, &mut fl))
            }),
        ),
        (
            "PerQuery::sample_records",
            Box::new(move || {
                let mut r = vec![SampleRecord::default(); n];
                ok(column().sample_records(wi, Some(keys), &mut r))
            }),
        ),
        (
            "PerQuery::pdf_into",
            Box::new(move || ok(column().pdf_buffers(wi, wo, &mut f32s()))),
        ),
        (
            "PerQuery::pdf_unbiased_into",
            Box::new(move || {
                ok(column().pdf_unbiased_buffers(wi, wo, WALKS, &mut f32s(), &mut f32s()))
            }),
        ),
        (
            "PerQuery::albedo_records",
            Box::new(move || {
                let mut r = vec![AlbedoRecord::default(); n];
                ok(column().albedo_records(wi, WALKS, None, &mut r))
            }),
        ),
    ];
    v
}

/// Runs every call of `case` on `b` over `n` queries under the watch, and
/// hands each call's name and report to `check`.
fn each_call(case: &Case, b: &LayeredBsdf, n: usize, mut check: impl FnMut(&str, &Watched<()>)) {
    let sets = Materials::new(b, case.sets.clone());
    let mats = Materials::new(b, case.materials.clone());
    let path: SetPath = case.column.0.parse().unwrap();
    let x = Inputs::new(n, case.column.1);
    for (name, call) in calls(b, &sets, &mats, &path, &x) {
        check(name, &watch(&*call));
    }
}

/// Every failure of a test, listed at its end.
#[track_caller]
fn none(failures: Vec<String>) {
    assert!(
        failures.is_empty(),
        "{} calls:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// `what` if the call ran anywhere but on the calling thread.
fn off_caller(what: String, w: &Watched<()>) -> Option<String> {
    (!w.on_caller_only()).then(|| {
        let (jobs, others) = (w.jobs_elsewhere(), w.others.len());
        format!("{what}: {jobs} jobs on {others} threads other than the caller's")
    })
}

#[test]
fn one_thread_runs_every_batch_on_the_calling_thread() {
    in_own_process(
        "threads::one_thread_runs_every_batch_on_the_calling_thread",
        || {
            let mut failures = Vec::new();
            for case in cases() {
                let b = case.bsdf.clone().threads(1).unwrap();
                each_call(&case, &b, LARGE, |name, w| {
                    let what = format!("{} / threads(1) / {LARGE} queries / {name}", case.name);
                    failures.extend(off_caller(what, w));
                });
            }
            none(failures);
        },
    );
}

/// The batches above are large enough to go parallel, and the watch sees
/// it: under the default setting (rayon's current pool, here the global
/// one) each call whose path has parallel work runs jobs on the pool.
#[test]
fn the_same_batches_go_parallel_on_the_current_pool() {
    // Calls that run query by query on the calling thread whatever the
    // setting: a walk-free stack's pdfs (its sampler's density, of its own
    // or of its sets; of `Materials` of two shapes, the walks' shape's go
    // parallel) and its single eval (one
    // query's factorization), and a single pdf (one query's density walks
    // share a chunk).
    let serial = |case: &str, name: &str| {
        let walk_free = case == "rough coat without walks";
        (walk_free && name.contains("pdf") && !name.starts_with("Materials::"))
            || (walk_free && name == "eval_with")
            || name == "pdf_unbiased"
    };
    in_own_process(
        "threads::the_same_batches_go_parallel_on_the_current_pool",
        || {
            let mut failures = Vec::new();
            for case in cases() {
                each_call(&case, &case.bsdf, LARGE, |name, w| {
                    if !serial(case.name, name) && w.jobs_elsewhere() == 0 {
                        let what = format!("{} / default / {LARGE} queries / {name}", case.name);
                        failures.push(format!("{what}: no job on the pool"));
                    }
                });
            }
            none(failures);
        },
    );
}

#[test]
fn a_pool_of_its_own_leaves_the_current_pool_idle() {
    in_own_process(
        "threads::a_pool_of_its_own_leaves_the_current_pool_idle",
        || {
            let mut failures = Vec::new();
            for case in cases() {
                let b = case.bsdf.clone().threads(2).unwrap();
                for n in [LARGE, SMALL] {
                    each_call(&case, &b, n, |name, w| {
                        if !w.others.is_empty() {
                            failures.push(format!(
                            "{} / threads(2) / {n} queries / {name}: {} jobs on the current pool",
                            case.name,
                            w.jobs_elsewhere(),
                        ));
                        }
                    });
                }
            }
            none(failures);
        },
    );
}

#[test]
fn small_batches_run_on_the_calling_thread_whatever_the_setting() {
    let test = "threads::small_batches_run_on_the_calling_thread_whatever_the_setting";
    in_own_process(test, || {
        let mut failures = Vec::new();
        for case in cases() {
            for (setting, b) in [
                ("default", case.bsdf.clone()),
                ("threads(2)", case.bsdf.clone().threads(2).unwrap()),
            ] {
                each_call(&case, &b, SMALL, |name, w| {
                    let what = format!("{} / {setting} / {SMALL} queries / {name}", case.name);
                    failures.extend(off_caller(what, w));
                });
            }
        }
        none(failures);
    });
}

/// A rough coat's table of `R̄` (what per-query coat depths and roughnesses
/// read, built on a process's first such call, on threads of its own) is
/// built on as many threads as the call runs on: the calling thread alone
/// with `threads(1)`, three with a pool of three. Each setting and verb in
/// a process of its own, so that the verb's call builds the table (eval
/// and sample read it; a pdf does not).
fn rough_table_built_on(test: &str, threads: usize) {
    in_own_process(test, || {
        let bsdf = LayeredBsdf::new(stack(ROUGH_COAT_ABSORBER_LAMBERTIAN))
            .samples(1)
            .threads(threads)
            .unwrap();
        let inputs = Inputs::new(LARGE, |k| 0.1 + 0.01 * k as f32);
        let path = SetPath::parse("layers[0].medium.thickness").unwrap();
        let column = Column {
            path: &path,
            width: 1,
            values: &inputs.column,
        };
        let rows = PerQuery::new(&bsdf, LARGE, std::slice::from_ref(&column)).unwrap();
        assert!(rows.rows_in_place());
        let (wi, wo) = (Vectors::Aos(&inputs.wi), Vectors::Aos(&inputs.wo));
        let verb = test.rsplit('_').next().unwrap();
        match verb {
            "eval" => {
                let mut f = vec![[0.0; 3]; LARGE];
                let f = VectorsMut::Aos(&mut f);
                rows.eval_buffers(wi, wo, Some(&inputs.keys), f, None)
                    .unwrap();
            }
            "sample" => {
                let mut r = vec![SampleRecord::default(); LARGE];
                rows.sample_records(wi, Some(&inputs.keys), &mut r).unwrap();
            }
            _ => panic!("no verb {verb}"),
        }
        // The coat: IOR 1.5 over vacuum, GGX, height-correlated (the
        // defaults); the call above built its table.
        let table = RoughReturn::for_coat(1.5, false, false);
        assert_eq!(table.built_on(), threads, "threads({threads}), {verb}");
    });
}

#[test]
fn one_thread_builds_a_rough_table_on_the_calling_thread_in_eval() {
    let test = "threads::one_thread_builds_a_rough_table_on_the_calling_thread_in_eval";
    rough_table_built_on(test, 1);
}

#[test]
fn one_thread_builds_a_rough_table_on_the_calling_thread_in_sample() {
    let test = "threads::one_thread_builds_a_rough_table_on_the_calling_thread_in_sample";
    rough_table_built_on(test, 1);
}

#[test]
fn a_pool_of_three_builds_a_rough_table_on_three_threads_in_eval() {
    let test = "threads::a_pool_of_three_builds_a_rough_table_on_three_threads_in_eval";
    rough_table_built_on(test, 3);
}
