//! The cost per query of the C ABI: 4096 calls of n = 1 against one call of
//! n = 4096 (on one thread, `strata_bsdf_set_threads(b, 1)`, and on the
//! default pool of one thread per core), for eval (1 and 64 walks) and
//! sample, on examples/materials/coated_copper.toml; then a renderer's
//! vertex on pbrt-v4's six layered configurations with the material's own
//! values and with every query's own (`StrataBatch::columns`). Calls the
//! extern "C" functions, as a C program does. Not a test: run it and read
//! the tables.
//!
//! ```text
//! cargo run --release -p strata-capi --example batch_cost
//! ```
//! Optional argument: the seconds to spend per cell (default 1).

use std::ffi::CString;
use std::ptr::{null, null_mut};
use std::time::{Duration, Instant};
use strata_capi::*;

const N: usize = 4096;

/// `3 n` floats, `x, y, z` per query.
fn xyz(v: &[f32]) -> StrataVectors {
    StrataVectors {
        xyz: v.as_ptr(),
        ..Default::default()
    }
}

/// An eval of `n` queries from `wi`, `wo` into `f` (AoS), with `columns`.
fn eval_of(
    n: usize,
    wi: &[f32],
    wo: &[f32],
    f: &mut [f32],
    columns: &[StrataColumn],
) -> StrataBatch {
    StrataBatch {
        n,
        wi: xyz(wi),
        wo: xyz(wo),
        columns: if columns.is_empty() {
            null()
        } else {
            columns.as_ptr()
        },
        ncolumns: columns.len(),
        f: StrataVectorsOut {
            xyz: f.as_mut_ptr(),
            ..Default::default()
        },
        ..Default::default()
    }
}

/// One sample per query of `wi` into `s`, with `columns`.
fn sample_of(wi: &[f32], s: &mut [StrataSample], columns: &[StrataColumn]) -> StrataBatch {
    StrataBatch {
        n: s.len(),
        wi: xyz(wi),
        columns: if columns.is_empty() {
            null()
        } else {
            columns.as_ptr()
        },
        ncolumns: columns.len(),
        sample: s.as_mut_ptr(),
        ..Default::default()
    }
}

/// Nanoseconds per query of `run` (which answers `N` queries), the best of
/// repetitions over `budget`.
fn per_query(budget: Duration, mut run: impl FnMut()) -> f64 {
    best_per_query(budget, || {
        let t = Instant::now();
        run();
        t.elapsed().as_secs_f64()
    })
}

/// [`per_query`] for a `run` that times itself (in seconds), leaving out
/// what it prepares.
fn best_per_query(budget: Duration, mut run: impl FnMut() -> f64) -> f64 {
    run(); // warm up
    let start = Instant::now();
    let mut best = f64::INFINITY;
    while start.elapsed() < budget {
        best = best.min(run());
    }
    best * 1e9 / N as f64
}

/// A BSDF with `samples` walks per eval; on a pool of `threads` threads of
/// its own, or the default pool.
fn create(path: &str, samples: u64, threads: Option<usize>) -> *mut StrataBsdf {
    let p = CString::new(path).unwrap();
    let mut b = null_mut();
    // SAFETY: NUL-terminated path; writable out pointer; `b` is used by this
    // thread only.
    unsafe {
        assert_eq!(
            strata_bsdf_from_path(p.as_ptr(), samples, 1, &mut b),
            STRATA_OK
        );
        if let Some(t) = threads {
            assert_eq!(strata_bsdf_set_threads(b, t), STRATA_OK);
        }
    }
    b
}

fn main() {
    let budget = Duration::from_secs_f64(
        std::env::args()
            .nth(1)
            .map_or(1.0, |s| s.parse().expect("seconds")),
    );
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../examples/materials/coated_copper.toml"
    );
    // N query pairs over the upper hemisphere.
    let dir = |k: usize, a: f32| {
        let t = (k as f32 + 0.5) / N as f32;
        let phi = a + std::f32::consts::TAU * t * 37.0;
        let s = (0.95 * t).sqrt();
        [s * phi.cos(), s * phi.sin(), (1.0 - s * s).sqrt()]
    };
    let wi: Vec<f32> = (0..N).flat_map(|k| dir(k, 0.0)).collect();
    let wo: Vec<f32> = (0..N).flat_map(|k| dir(N - 1 - k, 1.0)).collect();
    let mut f = vec![0.0f32; 3 * N];
    let mut s = vec![StrataSample::default(); N];

    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    println!(
        "| call | n = 1 calls | one call of n = {N}, 1 thread | ratio | one call of n = {N}, {cores} threads | ratio |"
    );
    println!("|---|---|---|---|---|---|");
    let row = |name: &str, single: f64, one: f64, pool: f64| {
        println!(
            "| {name} | {single:.0} ns | {one:.0} ns | {:.1}× | {pool:.0} ns | {:.1}× |",
            single / one,
            single / pool
        );
    };
    for samples in [1u64, 64] {
        let mut cells = vec![];
        for threads in [Some(1), None] {
            let b = create(path, samples, threads);
            // Both closures: every array holds N queries; query k's
            // arrays start at 3 k.
            if threads.is_some() {
                cells.push(per_query(budget, || {
                    for k in 0..N {
                        let batch = eval_of(1, &wi[3 * k..], &wo[3 * k..], &mut f[3 * k..], &[]);
                        // SAFETY: N queries (query k at 3 k); a live BSDF.
                        let st = unsafe { strata_eval(b, &batch) };
                        assert_eq!(st, STRATA_OK);
                    }
                }));
            }
            cells.push(per_query(budget, || {
                let batch = eval_of(N, &wi, &wo, &mut f, &[]);
                // SAFETY: N queries (query k at 3 k); a live BSDF.
                let st = unsafe { strata_eval(b, &batch) };
                assert_eq!(st, STRATA_OK);
            }));
            // SAFETY: from `create`, freed once.
            unsafe { strata_bsdf_free(b) };
        }
        row(
            &format!("`strata_eval`, samples {samples}"),
            cells[0],
            cells[1],
            cells[2],
        );
    }
    let mut cells = vec![];
    for threads in [Some(1), None] {
        let b = create(path, 1, threads);
        // Both closures: as above.
        if threads.is_some() {
            cells.push(per_query(budget, || {
                for k in 0..N {
                    let batch = sample_of(&wi[3 * k..], &mut s[k..k + 1], &[]);
                    // SAFETY: N queries (query k at 3 k); a live BSDF.
                    let st = unsafe { strata_sample(b, &batch) };
                    assert_eq!(st, STRATA_OK);
                }
            }));
        }
        cells.push(per_query(budget, || {
            let batch = sample_of(&wi, &mut s, &[]);
            // SAFETY: N queries (query k at 3 k); a live BSDF.
            let st = unsafe { strata_sample(b, &batch) };
            assert_eq!(st, STRATA_OK);
        }));
        // SAFETY: from `create`, freed once.
        unsafe { strata_bsdf_free(b) };
    }
    row(
        "`strata_sample` (with its pdf)",
        cells[0],
        cells[1],
        cells[2],
    );
    columns_cost(budget, &wi, &wo);
}

/// The cost of per-query values as a renderer's textures give them, on
/// pbrt-v4's six layered configurations (`strata_reports::pbrt::configs`):
/// a vertex's two calls of n = N on one thread, one walk per eval, in
/// importance mode (a sample, then an eval with its pdf at a second
/// direction), with the material's own values against a column per
/// parameter (`strata_reports::vertex::Texture`: the coat's thickness, its
/// absorption, its roughness where rough, the base's albedo where
/// Lambertian), every query its own values, drawn afresh (untimed) before
/// every repetition as a texture lookup would give them.
fn columns_cost(budget: Duration, wi: &[f32], wo: &[f32]) {
    let mut f = vec![0.0f32; 3 * N];
    let mut pdf = vec![0.0f32; N];
    let mut s = vec![StrataSample::default(); N];
    println!();
    println!(
        "| one vertex (sample, eval with pdf), n = {N}, 1 thread, 1 walk | own values | per-query values | ratio |"
    );
    println!("|---|---|---|---|");
    for c in strata_reports::pbrt::configs() {
        let toml = CString::new(c.toml.as_str()).unwrap();
        let mut b = null_mut();
        // SAFETY: a NUL-terminated TOML text; a writable out pointer; `b` is
        // used by this thread only.
        unsafe {
            assert_eq!(
                strata_bsdf_from_toml(toml.as_ptr(), 1, 1, &mut b),
                STRATA_OK
            );
            assert_eq!(strata_bsdf_set_threads(b, 1), STRATA_OK);
            let t = STRATA_TRANSPORT_IMPORTANCE;
            assert_eq!(strata_bsdf_set_transport(b, t), STRATA_OK);
        }
        let mut texture = strata_reports::vertex::Texture::new(&c);
        let paths: Vec<CString> = (texture.paths().into_iter())
            .map(|p| CString::new(p).unwrap())
            .collect();
        let mut rng = 1u64;
        let mut cell = |textured: bool| {
            best_per_query(budget, || {
                // Fresh values for every repetition, untimed.
                texture.draw(N, &mut rng);
                let cols: Vec<StrataColumn> = match textured {
                    false => vec![],
                    true => (paths.iter().zip(texture.columns()))
                        .map(|(p, c)| StrataColumn {
                            path: p.as_ptr(),
                            width: c.width,
                            values: c.values.as_ptr(),
                        })
                        .collect(),
                };
                let t = Instant::now();
                let smp = sample_of(wi, &mut s, &cols);
                let mut light = eval_of(N, wi, wo, &mut f, &cols);
                light.pdf = pdf.as_mut_ptr();
                // SAFETY: N queries in every array, N rows per column; a live
                // BSDF.
                unsafe {
                    assert_eq!(strata_sample(b, &smp), STRATA_OK);
                    assert_eq!(strata_eval(b, &light), STRATA_OK);
                }
                t.elapsed().as_secs_f64()
            })
        };
        let (own, per) = (cell(false), cell(true));
        println!(
            "| {} | {own:.0} ns | {per:.0} ns | {:.2}× |",
            c.name,
            per / own
        );
        // SAFETY: from `strata_bsdf_from_toml`, freed once.
        unsafe { strata_bsdf_free(b) };
    }
}
