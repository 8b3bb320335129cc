//! `strata_bsdf_configure` and `strata_bsdf_config`: the library's `Config`
//! text through the C ABI. What `strata_bsdf_config` prints reads back to
//! the same configuration; a configured BSDF answers bit for bit what the
//! `strata_bsdf_set_*` calls of the same settings make; a setting it does
//! not take is an error naming the key and the value that leaves the BSDF
//! as it was; a buffer too small is an error that reports the size.

use std::ffi::{c_char, CStr, CString};
use std::ptr::{null, null_mut};
use strata_bsdf::Config;
use strata_capi::*;

use crate::batch::{aos, aos_out};
/// Transmission between exteriors of different IOR: the transport mode and
/// the estimator matter.
const GLASS: &str = crate::common::ROUGH_GLASS;
const COPPER: &str = crate::common::COATED_COPPER;

fn last_error() -> String {
    // SAFETY: `strata_last_error` returns a NUL-terminated string valid
    // until the next call on this thread.
    unsafe { CStr::from_ptr(strata_last_error()) }
        .to_str()
        .unwrap()
        .to_owned()
}

/// A BSDF made through the C ABI, freed on drop.
struct Capi(*mut StrataBsdf);

impl Capi {
    fn toml(text: &str) -> Capi {
        let c = CString::new(text).unwrap();
        let mut b = null_mut();
        // SAFETY: `c` is NUL-terminated and `b` is a writable pointer.
        let status = unsafe { strata_bsdf_from_toml(c.as_ptr(), 16, 5, &mut b) };
        assert_eq!(status, STRATA_OK, "{}", last_error());
        Capi(b)
    }

    /// `strata_bsdf_configure` with `settings` as bytes: the status.
    fn configure(&self, settings: &[u8]) -> i32 {
        let c = CString::new(settings).unwrap();
        // SAFETY: `self.0` is live and used by this thread only; `c` is
        // NUL-terminated.
        unsafe { strata_bsdf_configure(self.0, c.as_ptr()) }
    }

    /// What `strata_bsdf_config` prints (asking the size first).
    fn config(&self) -> String {
        let mut needed = 0usize;
        // SAFETY: `self.0` is live; NULL `buf` with `len` 0 asks the size.
        let status = unsafe { strata_bsdf_config(self.0, null_mut(), 0, &mut needed) };
        assert_eq!(status, STRATA_OK, "{}", last_error());
        let mut buf = vec![b'x'; needed];
        let mut again = 0usize;
        // SAFETY: `buf` is writable for `needed` bytes.
        let status =
            unsafe { strata_bsdf_config(self.0, buf.as_mut_ptr().cast(), needed, &mut again) };
        assert_eq!(status, STRATA_OK, "{}", last_error());
        assert_eq!(again, needed);
        assert_eq!(buf[needed - 1], 0, "NUL-terminated");
        CStr::from_bytes_with_nul(&buf)
            .unwrap()
            .to_str()
            .unwrap()
            .to_owned()
    }

    /// Eval's `f`, standard errors and pdf on a fixed set of pairs, and
    /// samples' records, as bits.
    fn answers(&self) -> Vec<u32> {
        const N: usize = 19;
        let dir = |k: usize, s: f32| {
            let t = k as f32 * 0.07 + s;
            let z = if k % 3 == 2 { -0.6 } else { 0.7 + t };
            [0.3 - t, 0.2 + s, z]
        };
        let wi: Vec<f32> = (0..N).flat_map(|k| dir(k, 0.0)).collect();
        let wo: Vec<f32> = (0..N).flat_map(|k| dir(N - k, 0.1)).collect();
        let (mut f, mut se, mut pdf) = (vec![0f32; 3 * N], vec![0f32; 3 * N], vec![0f32; N]);
        let batch = StrataBatch {
            n: N,
            wi: aos(&wi),
            wo: aos(&wo),
            f: aos_out(&mut f),
            stderr: aos_out(&mut se),
            pdf: pdf.as_mut_ptr(),
            ..Default::default()
        };
        // SAFETY: wi, wo, f and stderr hold 3 N floats, pdf N.
        let status = unsafe { strata_eval(self.0, &batch) };
        assert_eq!(status, STRATA_OK, "{}", last_error());
        let mut samples = vec![StrataSample::default(); N];
        let batch = StrataBatch {
            n: N,
            wi: aos(&wi),
            sample: samples.as_mut_ptr(),
            ..Default::default()
        };
        // SAFETY: wi holds 3 N floats, samples N records.
        let status = unsafe { strata_sample(self.0, &batch) };
        assert_eq!(status, STRATA_OK, "{}", last_error());
        let s = samples
            .iter()
            .flat_map(|s| s.wo.into_iter().chain(s.weight).chain([s.pdf]));
        f.into_iter()
            .chain(se)
            .chain(pdf)
            .chain(s)
            .map(f32::to_bits)
            .collect()
    }
}

impl Drop for Capi {
    fn drop(&mut self) {
        // SAFETY: the pointer came from `strata_bsdf_from_toml` and is freed once.
        unsafe { strata_bsdf_free(self.0) }
    }
}

#[test]
fn what_config_prints_configure_reads_back() {
    let c = Capi::toml(COPPER);
    let want = Config {
        samples: 16,
        seed: 5,
        ..Config::default()
    };
    assert_eq!(c.config(), want.to_string());
    let settings = "samples=3 pdf_walks=adaptive seed=7 transport=importance eval_start=wi \
                    estimator=uni engine=scalar threads=1 max_events=50 rr_start=2 \
                    rr_threshold=0.25 max_scatter_order=4 mis=false";
    assert_eq!(
        c.configure(settings.as_bytes()),
        STRATA_OK,
        "{}",
        last_error()
    );
    assert_eq!(last_error(), "");
    let printed = c.config();
    assert_eq!(printed, settings.parse::<Config>().unwrap().to_string());
    // A key not given keeps its value.
    assert_eq!(c.configure(b"  seed=8\n\tthreads=current "), STRATA_OK);
    let mut want: Config = settings.parse().unwrap();
    (want.seed, want.threads) = (8, None);
    assert_eq!(c.config(), want.to_string());
    // Another BSDF given the printed text prints it back; the empty text
    // changes nothing.
    let d = Capi::toml(COPPER);
    assert_eq!(d.configure(c.config().as_bytes()), STRATA_OK);
    assert_eq!(d.configure(b""), STRATA_OK);
    assert_eq!(d.config(), c.config());
    assert_eq!(d.answers(), c.answers());
}

/// Calls of `strata_bsdf_set_*` on a BSDF: the lowest status.
type Setters = fn(*mut StrataBsdf) -> i32;

/// Each setting by `strata_bsdf_configure` against its `strata_bsdf_set_*`
/// call, on a stack where each of them matters.
#[test]
fn a_configured_bsdf_answers_what_the_setters_make() {
    // SAFETY (every call below): the BSDFs are live and used by this thread
    // only.
    let setters: [(&str, Setters); 4] = [
        (
            "transport=importance estimator=uni max_events=40 pdf_walks=4",
            |b| unsafe {
                let s = [
                    strata_bsdf_set_transport(b, STRATA_TRANSPORT_IMPORTANCE),
                    strata_bsdf_set_estimator(b, STRATA_ESTIMATOR_UNIDIRECTIONAL),
                    strata_bsdf_set_max_events(b, 40),
                    strata_bsdf_set_pdf_samples(b, 4),
                ];
                s.into_iter().min().unwrap()
            },
        ),
        (
            "estimator=bidir pdf_walks=8,64,0.15 threads=1",
            |b| unsafe {
                let s = [
                    strata_bsdf_set_estimator(b, STRATA_ESTIMATOR_BIDIRECTIONAL),
                    strata_bsdf_set_pdf_walks(b, 8, 64, 0.15),
                    strata_bsdf_set_threads(b, 1),
                ];
                s.into_iter().min().unwrap()
            },
        ),
        ("pdf_walks=lobes threads=2 transport=radiance", |b| unsafe {
            let s = [
                strata_bsdf_set_pdf_samples(b, 6),
                strata_bsdf_set_pdf_samples(b, STRATA_PDF_SAMPLES_RULE),
                strata_bsdf_set_threads(b, 2),
                strata_bsdf_set_transport(b, STRATA_TRANSPORT_RADIANCE),
            ];
            s.into_iter().min().unwrap()
        }),
        ("estimator=auto", |b| unsafe {
            strata_bsdf_set_estimator(b, STRATA_ESTIMATOR_AUTO)
        }),
    ];
    for toml in [GLASS, COPPER] {
        let plain = Capi::toml(toml).answers();
        for (settings, set) in setters {
            let (configured, by_setters) = (Capi::toml(toml), Capi::toml(toml));
            assert_eq!(configured.configure(settings.as_bytes()), STRATA_OK);
            assert_eq!(set(by_setters.0), STRATA_OK, "{}", last_error());
            assert_eq!(configured.config(), by_setters.config(), "{settings}");
            let answers = configured.answers();
            assert_eq!(answers, by_setters.answers(), "{settings}");
            if toml == GLASS && settings.starts_with("transport=importance") {
                assert_ne!(answers, plain, "{settings} changes the glass's answers");
            }
        }
    }
}

#[test]
fn a_setting_it_does_not_take_names_key_and_value_and_changes_nothing() {
    let c = Capi::toml(GLASS);
    assert_eq!(
        c.configure(b"transport=importance max_events=99"),
        STRATA_OK
    );
    let (text, answers) = (c.config(), c.answers());
    let unchanged = |what: &str| {
        assert_eq!(c.config(), text, "{what}");
        assert_eq!(c.answers(), answers, "{what}");
    };
    for (settings, message) in [
        (
            "rr_threshold=2",
            "rr_threshold=2: expected a number from 0.001 to 1",
        ),
        (
            "seed=9 transport=radiance samples=0",
            "samples=0: expected a whole number from 1 to 1099511627776",
        ),
        (
            "colour=red",
            "colour=red: unknown setting (known: samples, ",
        ),
        ("estimator=best", "estimator=best: "),
        ("threads=0", "threads=0: "),
        ("pdf_walks=1,2", "pdf_walks=1,2: "),
        ("seed=1 mis", "mis=: expected key=value"),
    ] {
        assert_eq!(
            c.configure(settings.as_bytes()),
            STRATA_ERR_INVALID_ARGUMENT,
            "{settings}"
        );
        let e = last_error();
        let want = format!("strata_bsdf_configure: {message}");
        assert!(e.starts_with(&want), "{settings}: {e}");
        unchanged(settings);
    }
    // Text that is not UTF-8.
    assert_eq!(c.configure(b"seed=1 \xff"), STRATA_ERR_INVALID_ARGUMENT);
    assert_eq!(
        last_error(),
        "strata_bsdf_configure: settings is not UTF-8 (invalid byte at offset 7)"
    );
    unchanged("not UTF-8");
    // NULL arguments.
    // SAFETY: NULL is an error, not a dereference.
    let status = unsafe { strata_bsdf_configure(c.0, null()) };
    assert_eq!(status, STRATA_ERR_NULL);
    assert_eq!(last_error(), "strata_bsdf_configure: settings is NULL");
    unchanged("NULL settings");
    let s = CString::new("seed=1").unwrap();
    // SAFETY: as above.
    let status = unsafe { strata_bsdf_configure(null_mut(), s.as_ptr()) };
    assert_eq!(status, STRATA_ERR_NULL);
    assert_eq!(last_error(), "strata_bsdf_configure: b is NULL");
    let mut needed = 7usize;
    // SAFETY: as above.
    let status = unsafe { strata_bsdf_config(null(), null_mut(), 0, &mut needed) };
    assert_eq!(status, STRATA_ERR_NULL);
    assert_eq!(last_error(), "strata_bsdf_config: b is NULL");
    assert_eq!(needed, 7, "nothing written");
}

#[test]
fn a_buffer_too_small_is_an_error_that_reports_the_size() {
    let c = Capi::toml(COPPER);
    let text = c.config();
    let size = text.len() + 1;
    let mut buf = vec![b'x' as c_char; size + 4];
    let mut needed = 0usize;
    for len in [1, size - 1] {
        buf.fill(b'x' as c_char);
        // SAFETY: `buf` is writable for `len` ≤ its length bytes.
        let status = unsafe { strata_bsdf_config(c.0, buf.as_mut_ptr(), len, &mut needed) };
        assert_eq!(status, STRATA_ERR_INVALID_ARGUMENT);
        assert_eq!(
            last_error(),
            format!("strata_bsdf_config: len = {len} is too small: the configuration takes {size} bytes")
        );
        assert_eq!(needed, size);
        assert_eq!(buf[0], 0, "the empty string");
        assert!(
            buf[1..].iter().all(|&b| b == b'x' as c_char),
            "no byte past it"
        );
    }
    // `len` 0 with a buffer: nothing written at all.
    buf.fill(b'x' as c_char);
    // SAFETY: nothing is written for `len` 0.
    let status = unsafe { strata_bsdf_config(c.0, buf.as_mut_ptr(), 0, null_mut()) };
    assert_eq!(status, STRATA_ERR_INVALID_ARGUMENT);
    assert!(buf.iter().all(|&b| b == b'x' as c_char));
    // NULL `buf` with a length.
    // SAFETY: NULL is an error, not a dereference.
    let status = unsafe { strata_bsdf_config(c.0, null_mut(), 8, &mut needed) };
    assert_eq!(status, STRATA_ERR_NULL);
    assert_eq!(last_error(), "strata_bsdf_config: buf is NULL (len = 8)");
    // Exactly the size, with `needed` NULL.
    buf.fill(b'x' as c_char);
    // SAFETY: `buf` is writable for `size` bytes.
    let status = unsafe { strata_bsdf_config(c.0, buf.as_mut_ptr(), size, null_mut()) };
    assert_eq!(status, STRATA_OK, "{}", last_error());
    // SAFETY: the call wrote a NUL-terminated string into `buf`.
    let got = unsafe { CStr::from_ptr(buf.as_ptr()) }.to_str().unwrap();
    assert_eq!(got, text);
    assert_eq!(buf[size], b'x' as c_char, "no byte past the NUL");
}
