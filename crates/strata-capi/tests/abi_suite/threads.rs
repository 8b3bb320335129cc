//! `strata_bsdf_set_threads(b, 1)` holds for every batch call (issue 40):
//! each of the C ABI's batch functions (eval, sample, pdf, unbiased pdf,
//! albedo; with and without keys and columns; AoS and SoA) on a BSDF
//! set to one thread runs on the calling thread alone. Watched as the Rust
//! API's tests/api/threads.rs watches (tests/common/threads.rs explains
//! the method): the call is made on the test's thread, which is no rayon
//! worker, while every worker of rayon's global pool runs a thief that
//! records each job handed to that pool, in a process of its own; the set
//! of threads seen running the call must be the calling thread alone. The
//! same batches on a BSDF of the default setting (rayon's global pool) are
//! seen to run jobs there: they are large enough to go parallel.

use crate::common::threads::{in_own_process, watch};
use std::ffi::{CStr, CString};
use std::ptr::{null, null_mut};
use strata_capi::*;

/// A rough coat over a scattering layer over a rough conductor: every
/// call walks.
const MATERIAL: &str = "[[layers]]\n\
    interface = { kind = \"dielectric\", ior = 1.5, roughness = 0.15 }\n\
    medium = { thickness = 0.5, sigma_t = [0.4, 0.8, 1.6], albedo = 0.6 }\n\
    [[layers]]\n\
    interface = { kind = \"conductor\", eta = [0.2, 0.9, 1.1], k = [3.9, 2.4, 2.1], roughness = 0.3 }\n";

/// Queries per batch: more sample queries than `SERIAL_WALKS` (256), more
/// pdf queries than `PDF_CHUNK` (64).
const N: usize = 600;
/// Walks per eval, unbiased pdf and albedo query.
const WALKS: u64 = 32;

struct Bsdf(*mut StrataBsdf);

impl Bsdf {
    /// The material with `threads` set (`None`: the default).
    fn new(threads: Option<usize>) -> Bsdf {
        let text = CString::new(MATERIAL).unwrap();
        let mut b = null_mut();
        // SAFETY: `text` is NUL-terminated and `b` is writable.
        let status = unsafe { strata_bsdf_from_toml(text.as_ptr(), WALKS, 5, &mut b) };
        assert_eq!(status, STRATA_OK, "{}", last_error());
        // SAFETY: `b` is live and used by this thread only.
        assert_eq!(unsafe { strata_bsdf_set_pdf_samples(b, 8) }, STRATA_OK);
        if let Some(n) = threads {
            // SAFETY: as above.
            let status = unsafe { strata_bsdf_set_threads(b, n) };
            assert_eq!(status, STRATA_OK, "{}", last_error());
        }
        Bsdf(b)
    }
}

impl Drop for Bsdf {
    fn drop(&mut self) {
        // SAFETY: from `strata_bsdf_from_toml`, freed once.
        unsafe { strata_bsdf_free(self.0) }
    }
}

fn last_error() -> String {
    // SAFETY: NUL-terminated, valid until the next call on this thread.
    unsafe { CStr::from_ptr(strata_last_error()) }
        .to_string_lossy()
        .into_owned()
}

/// The inputs of a batch: directions (AoS and SoA), keys, one column.
struct Inputs {
    wi: Vec<f32>,
    wo: Vec<f32>,
    wi_soa: [Vec<f32>; 3],
    wo_soa: [Vec<f32>; 3],
    keys: Vec<u64>,
    path: CString,
    thickness: Vec<f32>,
}

impl Inputs {
    fn new() -> Inputs {
        let dir = |k: usize, s: f32| {
            let t = k as f32 * 0.618_034 * s;
            let z = 0.1 + 0.85 * (t * 1.3).sin().abs();
            let r = (1.0 - z * z).sqrt();
            [r * t.cos(), r * t.sin(), z]
        };
        let wi: Vec<[f32; 3]> = (0..N).map(|k| dir(k, 1.0)).collect();
        let wo: Vec<[f32; 3]> = (0..N).map(|k| dir(k + 7, 2.3)).collect();
        let soa = |v: &[[f32; 3]]| [0, 1, 2].map(|i| v.iter().map(|d| d[i]).collect::<Vec<_>>());
        Inputs {
            wi: wi.concat(),
            wo: wo.concat(),
            wi_soa: soa(&wi),
            wo_soa: soa(&wo),
            keys: (0..N as u64).map(|k| k.wrapping_mul(0x9e37_79b9)).collect(),
            path: CString::new("layers[0].medium.thickness").unwrap(),
            thickness: (0..N).map(|k| 0.2 + 0.01 * (k % 50) as f32).collect(),
        }
    }

    fn column(&self) -> StrataColumn {
        StrataColumn {
            path: self.path.as_ptr(),
            width: 1,
            values: self.thickness.as_ptr(),
        }
    }
}

/// Outputs of every call, sized for [`N`] queries.
struct Outputs {
    v3: [Vec<f32>; 2],
    f: [Vec<f32>; 8],
    flags: Vec<u32>,
    samples: Vec<StrataSample>,
    albedo: Vec<StrataAlbedo>,
}

impl Outputs {
    fn new() -> Outputs {
        Outputs {
            v3: std::array::from_fn(|_| vec![0.0; 3 * N]),
            f: std::array::from_fn(|_| vec![0.0; N]),
            flags: vec![0; N],
            samples: vec![StrataSample::default(); N],
            albedo: vec![StrataAlbedo::default(); N],
        }
    }
}

/// Every batch function of the C ABI, in each form of its descriptor:
/// AoS or SoA, with or without keys, with or without a column.
const CALLS: &[&str] = &[
    "strata_eval",
    "strata_eval keys",
    "strata_eval columns",
    "strata_eval keys columns",
    "strata_eval pdf truncated",
    "strata_eval soa keys",
    "strata_eval soa columns",
    "strata_sample",
    "strata_sample keys columns",
    "strata_sample soa keys",
    "strata_sample soa columns",
    "strata_pdf",
    "strata_pdf columns",
    "strata_pdf_unbiased",
    "strata_pdf_unbiased columns",
    "strata_albedo keys",
    "strata_albedo columns",
];

/// Runs the batch function of the form `name` on `b` with `x`'s inputs
/// into `o`; returns its status.
fn call(name: &str, b: &Bsdf, x: &Inputs, o: &mut Outputs) -> i32 {
    let b = b.0 as *const StrataBsdf;
    let col = [x.column()];
    let has = |word: &str| name.split(' ').any(|w| w == word);
    let soa = has("soa");
    let in3 = |aos: &Vec<f32>, c: &[Vec<f32>; 3]| match soa {
        false => StrataVectors {
            xyz: aos.as_ptr(),
            ..Default::default()
        },
        true => StrataVectors {
            x: c[0].as_ptr(),
            y: c[1].as_ptr(),
            z: c[2].as_ptr(),
            ..Default::default()
        },
    };
    let [v0, v1] = &mut o.v3;
    let (v0, v1) = (v0.as_mut_ptr(), v1.as_mut_ptr());
    let [f0, f1, f2, f3, f4, f5, f6, f7] = &mut o.f;
    let [f0, f1, f2, f3, f4, f5, f6, f7] = [f0, f1, f2, f3, f4, f5, f6, f7].map(|f| f.as_mut_ptr());
    let out3 = |aos: *mut f32, [x, y, z]: [*mut f32; 3]| match soa {
        false => StrataVectorsOut {
            xyz: aos,
            ..Default::default()
        },
        true => StrataVectorsOut {
            x,
            y,
            z,
            ..Default::default()
        },
    };
    let mut cut = 0u64;
    let verb = name.split(' ').next().unwrap();
    let pairs = verb != "strata_sample" && verb != "strata_albedo";
    let batch = StrataBatch {
        n: N,
        wi: in3(&x.wi, &x.wi_soa),
        wo: if pairs {
            in3(&x.wo, &x.wo_soa)
        } else {
            StrataVectors::default()
        },
        keys: if has("keys") { x.keys.as_ptr() } else { null() },
        columns: if has("columns") { col.as_ptr() } else { null() },
        ncolumns: has("columns") as usize,
        truncated: if has("truncated") {
            &mut cut
        } else {
            null_mut()
        },
        ..Default::default()
    };
    // SAFETY: every input holds `N` queries' worth, every output is sized
    // for `N` queries and overlaps nothing, the column holds `N` values,
    // and `b` is live.
    unsafe {
        match verb {
            "strata_eval" => strata_eval(
                b,
                &StrataBatch {
                    f: out3(v0, [f0, f1, f2]),
                    stderr: out3(v1, [f3, f4, f5]),
                    pdf: if has("pdf") { f7 } else { null_mut() },
                    ..batch
                },
            ),
            "strata_sample" if soa => strata_sample(
                b,
                &StrataBatch {
                    sampled: out3(v0, [f0, f1, f2]),
                    weight: out3(v1, [f3, f4, f5]),
                    pdf: f6,
                    flags: o.flags.as_mut_ptr(),
                    ..batch
                },
            ),
            "strata_sample" => strata_sample(
                b,
                &StrataBatch {
                    sample: o.samples.as_mut_ptr(),
                    ..batch
                },
            ),
            "strata_pdf" => strata_pdf(b, &StrataBatch { pdf: f7, ..batch }),
            "strata_pdf_unbiased" => strata_pdf_unbiased(
                b,
                &StrataBatch {
                    walks: WALKS,
                    pdf: f6,
                    pdf_stderr: f7,
                    ..batch
                },
            ),
            "strata_albedo" => strata_albedo(
                b,
                &StrataBatch {
                    walks: WALKS,
                    albedo: o.albedo.as_mut_ptr(),
                    ..batch
                },
            ),
            _ => unreachable!("{name}"),
        }
    }
}

/// Runs every batch function on `b` under the watch; hands `check` each
/// one's name and whether it ran on the calling thread alone (with the
/// jobs that ran elsewhere).
fn each_call(b: &Bsdf, mut check: impl FnMut(&str, bool, usize)) {
    let x = Inputs::new();
    let mut o = Outputs::new();
    for name in CALLS {
        let w = watch(|| call(name, b, &x, &mut o));
        assert_eq!(w.value, STRATA_OK, "{name}: {}", last_error());
        check(name, w.on_caller_only(), w.jobs_elsewhere());
    }
}

#[test]
fn set_threads_1_runs_every_batch_on_the_calling_thread() {
    in_own_process(
        "threads::set_threads_1_runs_every_batch_on_the_calling_thread",
        || {
            let b = Bsdf::new(Some(1));
            let mut failures = Vec::new();
            each_call(&b, |name, alone, jobs| {
                if !alone {
                    failures.push(format!("{name}: {jobs} jobs on other threads"));
                }
            });
            assert!(failures.is_empty(), "{}", failures.join("\n"));
        },
    );
}

/// The batches above are large enough to go parallel, and the watch sees
/// it: by default each runs jobs on rayon's global pool.
#[test]
fn the_same_batches_go_parallel_by_default() {
    in_own_process("threads::the_same_batches_go_parallel_by_default", || {
        let b = Bsdf::new(None);
        let mut failures = Vec::new();
        each_call(&b, |name, _, jobs| {
            if jobs == 0 {
                failures.push(format!("{name}: no job on the pool"));
            }
        });
        assert!(failures.is_empty(), "{}", failures.join("\n"));
    });
}
