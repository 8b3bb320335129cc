//! Calls from a thread-local destructor, as a renderer's per-thread cache
//! makes them when its thread exits: strata's own thread-locals may be gone
//! by then. Each call answers as on a live thread, or fails with a status
//! and a message; none panics (a caught panic once came back as
//! `STRATA_ERR_PANIC` with an empty message).

use std::cell::RefCell;
use std::ffi::{CStr, CString};
use std::ptr::null_mut;
use std::sync::Mutex;
use strata_capi::*;

const COAT: &str = r#"
[[layers]]
interface = { kind = "dielectric", ior = 1.5, roughness = 0.1 }
medium = { thickness = 0.5, sigma_t = [0.2, 0.6, 1.2], albedo = 0.5 }
[[layers]]
interface = { kind = "conductor", preset = "Cu", roughness = 0.2 }
"#;

/// Queries per batch: more than a wavefront's lanes, so that `Auto` runs
/// the wavefront (whose buffers are thread-locals) as well as the scalar
/// engine.
const N: usize = 40;

/// What one round of calls gave: per call, its name, status and message,
/// and the numbers it wrote (as bits).
type Round = Vec<(&'static str, i32, String, Vec<u32>)>;

fn last_error() -> String {
    // SAFETY: `strata_last_error` returns a NUL-terminated string that
    // stays valid until the next strata call on this thread.
    unsafe { CStr::from_ptr(strata_last_error()) }
        .to_string_lossy()
        .into_owned()
}

fn directions() -> (Vec<f32>, Vec<f32>) {
    let mut wi = Vec::new();
    let mut wo = Vec::new();
    for k in 0..N {
        let t = k as f32 / N as f32;
        wi.extend([0.6 * t, 0.1, 1.0]);
        wo.extend([-0.3, 0.5 * t, 0.8]);
    }
    (wi, wo)
}

/// Creates a BSDF, runs eval, sample, pdf and albedo batches (one query
/// and `N`), a call with a NaN direction and a material with an error, and
/// frees the BSDF.
fn round() -> Round {
    let mut r: Round = Vec::new();
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    let text = CString::new(COAT).unwrap();
    let mut b = null_mut();
    // SAFETY: `text` is NUL-terminated; `b` is writable.
    let s = unsafe { strata_bsdf_from_toml(text.as_ptr(), 16, 7, &mut b) };
    r.push(("from_toml", s, last_error(), vec![]));
    if s != STRATA_OK {
        return r;
    }
    let (wi, wo) = directions();
    for n in [1, N] {
        let mut f = vec![0f32; 3 * n];
        let base = StrataBatch {
            n,
            wi: StrataVectors {
                xyz: wi.as_ptr(),
                ..Default::default()
            },
            ..Default::default()
        };
        let pairs = StrataBatch {
            wo: StrataVectors {
                xyz: wo.as_ptr(),
                ..Default::default()
            },
            ..base
        };
        let batch = StrataBatch {
            f: StrataVectorsOut {
                xyz: f.as_mut_ptr(),
                ..Default::default()
            },
            ..pairs
        };
        // SAFETY: the arrays hold 3 n floats; `b` is live.
        let s = unsafe { strata_eval(b, &batch) };
        r.push(("eval", s, last_error(), bits(&f)));
        let mut out = vec![StrataSample::default(); n];
        let batch = StrataBatch {
            sample: out.as_mut_ptr(),
            ..base
        };
        // SAFETY: `wi` holds 3 n floats, `out` n records.
        let s = unsafe { strata_sample(b, &batch) };
        let v: Vec<f32> = out
            .iter()
            .flat_map(|s| [s.wo[0], s.weight[0], s.pdf])
            .collect();
        r.push(("sample", s, last_error(), bits(&v)));
        let mut p = vec![0f32; n];
        let batch = StrataBatch {
            pdf: p.as_mut_ptr(),
            ..pairs
        };
        // SAFETY: `wi`, `wo` hold 3 n floats, `p` n.
        let s = unsafe { strata_pdf(b, &batch) };
        r.push(("pdf", s, last_error(), bits(&p)));
        let mut a = vec![StrataAlbedo::default(); n];
        let batch = StrataBatch {
            walks: 64,
            albedo: a.as_mut_ptr(),
            ..base
        };
        // SAFETY: `wi` holds 3 n floats, `a` n records.
        let s = unsafe { strata_albedo(b, &batch) };
        let v: Vec<f32> = a.iter().flat_map(|a| a.reflected).collect();
        r.push(("albedo", s, last_error(), bits(&v)));
    }
    let bad = [0.0, f32::NAN, 1.0];
    let mut f = [0f32; 3];
    let batch = StrataBatch {
        n: 1,
        wi: StrataVectors {
            xyz: bad.as_ptr(),
            ..Default::default()
        },
        wo: StrataVectors {
            xyz: wo.as_ptr(),
            ..Default::default()
        },
        f: StrataVectorsOut {
            xyz: f.as_mut_ptr(),
            ..Default::default()
        },
        ..Default::default()
    };
    // SAFETY: each array holds 3 floats.
    let s = unsafe { strata_eval(b, &batch) };
    r.push(("eval NaN", s, last_error(), vec![]));
    // SAFETY: from `strata_bsdf_from_toml`, freed once.
    unsafe { strata_bsdf_free(b) };
    let text =
        CString::new("[[layers]]\ninterface = { kind = \"diffuse\", albedo = 2 }\n").unwrap();
    let mut b = null_mut();
    // SAFETY: `text` is NUL-terminated; `b` is writable.
    let s = unsafe { strata_bsdf_from_toml(text.as_ptr(), 16, 7, &mut b) };
    r.push(("bad material", s, last_error(), vec![]));
    r
}

/// The rounds the destructors ran.
static FROM_DESTRUCTORS: Mutex<Vec<Round>> = Mutex::new(Vec::new());

/// Runs a round when dropped.
struct AtExit;

impl Drop for AtExit {
    fn drop(&mut self) {
        let r = round();
        FROM_DESTRUCTORS.lock().unwrap().push(r);
    }
}

thread_local! {
    static AT_EXIT: RefCell<Option<AtExit>> = const { RefCell::new(None) };
}

#[test]
fn calls_from_a_thread_local_destructor_answer_or_say_why() {
    let want = std::thread::spawn(round).join().unwrap();
    for (name, s, m, _) in &want {
        match *name {
            "eval NaN" => assert_eq!(*s, STRATA_ERR_INVALID_ARGUMENT, "{m}"),
            "bad material" => assert_eq!(*s, STRATA_ERR_MATERIAL, "{m}"),
            _ => assert_eq!(*s, STRATA_OK, "{name}: {m}"),
        }
    }
    // A thread whose destructor runs after strata's own thread-locals are
    // gone (registered before them, so destroyed after them), and one whose
    // first strata call is made from the destructor.
    std::thread::spawn(|| {
        AT_EXIT.with(|a| *a.borrow_mut() = Some(AtExit));
        let _ = round();
    })
    .join()
    .unwrap();
    std::thread::spawn(|| AT_EXIT.with(|a| *a.borrow_mut() = Some(AtExit)))
        .join()
        .unwrap();
    let got = std::mem::take(&mut *FROM_DESTRUCTORS.lock().unwrap());
    assert_eq!(got.len(), 2, "both destructors ran");
    for (case, r) in got.iter().enumerate() {
        assert_eq!(r.len(), want.len(), "case {case}: {r:?}");
        for ((name, s, m, v), (_, ws, wm, wv)) in r.iter().zip(&want) {
            assert_ne!(*s, STRATA_ERR_PANIC, "case {case}, {name}: panicked: {m:?}");
            assert_eq!((*s, m), (*ws, wm), "case {case}, {name}");
            assert_eq!(v, wv, "case {case}, {name}: other numbers");
        }
    }
}
