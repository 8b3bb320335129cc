//! Bad input through the C ABI: a negative status and a message that names
//! the function, the argument and the query, never a crash or a write.

use std::ffi::{CStr, CString};
use std::ptr::{null, null_mut};
use strata_capi::*;

const GOOD: &str = crate::common::COATED_COPPER;

fn last_error() -> String {
    // SAFETY: `strata_last_error` returns a NUL-terminated string valid
    // until the next call on this thread.
    unsafe { CStr::from_ptr(strata_last_error()) }
        .to_str()
        .unwrap()
        .to_owned()
}

/// Creates from TOML text: the status, the BSDF pointer (NULL on failure)
/// and the message.
fn create(text: &[u8], samples: u64) -> (i32, *mut StrataBsdf, String) {
    let c = CString::new(text).unwrap();
    let mut b = std::ptr::dangling_mut::<StrataBsdf>(); // must come back NULL on failure
                                                        // SAFETY: `c` is NUL-terminated; `b` is writable.
    let s = unsafe { strata_bsdf_from_toml(c.as_ptr(), samples, 0, &mut b) };
    (s, b, last_error())
}

/// Checks a call's status is `STRATA_ERR_NULL` with the message `want`.
fn expect_null(status: i32, want: &str) {
    assert_eq!(status, STRATA_ERR_NULL, "{want}");
    assert_eq!(last_error(), want);
}

struct Capi(*mut StrataBsdf);
impl Drop for Capi {
    fn drop(&mut self) {
        // SAFETY: from `strata_bsdf_from_toml`, freed once.
        unsafe { strata_bsdf_free(self.0) }
    }
}

fn good() -> Capi {
    let (s, b, m) = create(GOOD.as_bytes(), 8);
    assert_eq!(s, STRATA_OK, "{m}");
    Capi(b)
}

#[test]
fn material_errors_name_the_layer_field_and_value() {
    let (s, b, m) = create(
        br#"
[[layers]]
interface = { kind = "dielectric", ior = 1.5 }
medium = { thickness = -0.5, sigma_t = 1.0, albedo = 0.5 }
[[layers]]
interface = { kind = "diffuse", albedo = 0.8 }
"#,
        8,
    );
    assert_eq!(s, STRATA_ERR_MATERIAL);
    assert!(b.is_null());
    assert!(
        m.starts_with("strata_bsdf_from_toml: invalid material: layer 0: medium.thickness = -0.5"),
        "{m}"
    );

    let (s, b, m) = create(
        b"[[layers]]\ninterface = { kind = \"dielectric\", ior = \"x\" }\n",
        8,
    );
    assert_eq!(s, STRATA_ERR_MATERIAL);
    assert!(b.is_null());
    assert!(
        m.contains("invalid TOML material") && m.contains("ior"),
        "{m}"
    );

    let (s, _, m) = create(b"[[layers]\n", 8);
    assert_eq!(s, STRATA_ERR_MATERIAL);
    assert!(m.contains("line 1"), "{m}");

    let (s, _, m) = create(b"description = \"\xff\"", 8);
    assert_eq!(s, STRATA_ERR_INVALID_ARGUMENT);
    assert_eq!(
        m,
        "strata_bsdf_from_toml: toml is not UTF-8 (invalid byte at offset 15)"
    );

    for (samples, want) in [
        (0, "strata_bsdf_from_toml: samples = 0: at least one walk is needed"),
        (
            (1 << 40) + 1,
            "strata_bsdf_from_toml: samples = 1099511627777: at most 1099511627776 walks per query (2^40)",
        ),
    ] {
        let (s, b, m) = create(GOOD.as_bytes(), samples);
        assert_eq!(s, STRATA_ERR_INVALID_ARGUMENT);
        assert!(b.is_null());
        assert_eq!(m, want);
    }
    let (s, b, _) = create(GOOD.as_bytes(), 1 << 40);
    assert_eq!(s, STRATA_OK);
    Capi(b);

    let json = CString::new("{\"layers\": [").unwrap();
    let mut b = null_mut();
    // SAFETY: NUL-terminated; writable out.
    assert_eq!(
        unsafe { strata_bsdf_from_json(json.as_ptr(), 8, 0, &mut b) },
        STRATA_ERR_MATERIAL
    );
    assert!(last_error().starts_with("strata_bsdf_from_json: invalid JSON material"));

    let path = CString::new("/nonexistent/dir/m.toml").unwrap();
    // SAFETY: as above.
    assert_eq!(
        unsafe { strata_bsdf_from_path(path.as_ptr(), 8, 0, &mut b) },
        STRATA_ERR_IO
    );
    assert!(
        last_error().starts_with("strata_bsdf_from_path: cannot read /nonexistent/dir/m.toml: "),
        "{}",
        last_error()
    );
    assert!(b.is_null());

    // SAFETY: NULL pointers are reported, not read.
    unsafe {
        assert_eq!(strata_bsdf_from_toml(null(), 8, 0, &mut b), STRATA_ERR_NULL);
        assert_eq!(last_error(), "strata_bsdf_from_toml: toml is NULL");
        let c = CString::new(GOOD).unwrap();
        assert_eq!(
            strata_bsdf_from_toml(c.as_ptr(), 8, 0, null_mut()),
            STRATA_ERR_NULL
        );
        assert_eq!(last_error(), "strata_bsdf_from_toml: out is NULL");
        strata_bsdf_free(null_mut());
    }
}

#[test]
fn bad_directions_name_the_query_and_argument_and_write_nothing() {
    let b = good();
    let mut wi = [0.0f32, 0.0, 1.0].repeat(5);
    let wo = [0.3f32, 0.0, 0.9].repeat(5);
    wi[3 * 3] = f32::NAN;
    let mut f = vec![-7.0f32; 15];
    // SAFETY: 5 queries: 15 floats each.
    let s =
        unsafe { strata_eval_batch(b.0, 5, wi.as_ptr(), wo.as_ptr(), f.as_mut_ptr(), null_mut()) };
    assert_eq!(s, STRATA_ERR_INVALID_ARGUMENT);
    assert_eq!(
        last_error(),
        "strata_eval_batch: query 3: wi = [NaN, 0, 1] is not a direction: components must be finite"
    );
    assert!(f.iter().all(|&x| x == -7.0), "nothing written");

    let mut wo2 = wo.clone();
    wi[3 * 3] = 0.0;
    wo2[3..6].copy_from_slice(&[0.0, 0.0, 0.0]);
    let mut pdf = [0.0f32; 5];
    // SAFETY: as above.
    let s = unsafe { strata_pdf_batch(b.0, 5, wi.as_ptr(), wo2.as_ptr(), pdf.as_mut_ptr()) };
    assert_eq!(s, STRATA_ERR_INVALID_ARGUMENT);
    assert_eq!(
        last_error(),
        "strata_pdf_batch: query 1: wo = [0, 0, 0] is not a direction: it has zero length"
    );

    wi[4 * 3 + 2] = f32::INFINITY;
    let mut out = vec![StrataSample::default(); 5];
    // SAFETY: 5 queries.
    let s = unsafe { strata_sample_batch(b.0, 5, wi.as_ptr(), null(), out.as_mut_ptr()) };
    assert_eq!(s, STRATA_ERR_INVALID_ARGUMENT);
    assert_eq!(
        last_error(),
        "strata_sample_batch: query 4: wi = [0, 0, inf] is not a direction: components must be finite"
    );
    assert!(out.iter().all(|s| *s == StrataSample::default()));

    let mut a = vec![StrataAlbedo::default(); 5];
    // SAFETY: 5 queries.
    let s = unsafe { strata_albedo_batch(b.0, 5, wi.as_ptr(), 16, null(), a.as_mut_ptr()) };
    assert_eq!(s, STRATA_ERR_INVALID_ARGUMENT);
    assert!(last_error().starts_with("strata_albedo_batch: query 4: wi = [0, 0, inf]"));
    // SAFETY: 5 queries.
    let s = unsafe { strata_albedo_batch(b.0, 5, wo.as_ptr(), 0, null(), a.as_mut_ptr()) };
    assert_eq!(s, STRATA_ERR_INVALID_ARGUMENT);
    assert_eq!(
        last_error(),
        "strata_albedo_batch: walks = 0: at least one walk is needed"
    );

    // A good call clears the message.
    // SAFETY: 5 queries.
    let s =
        unsafe { strata_eval_batch(b.0, 5, wo.as_ptr(), wo.as_ptr(), f.as_mut_ptr(), null_mut()) };
    assert_eq!(s, STRATA_OK);
    assert_eq!(last_error(), "");
    assert!(f.iter().all(|&x| x > 0.0));
}

#[test]
fn null_arrays_are_errors_naming_them_unless_n_is_zero() {
    let b = good();
    let v = [0.0f32, 0.0, 1.0, 0.0, 0.0, 1.0];
    let mut f = [0.0f32; 6];
    let mut s = [StrataSample::default(); 2];
    let mut a = [StrataAlbedo::default(); 2];
    let keys = [1u64, 2];
    // SAFETY: NULL arrays are reported, not read; others hold 2 queries.
    unsafe {
        expect_null(
            strata_eval_batch(
                null(),
                2,
                v.as_ptr(),
                v.as_ptr(),
                f.as_mut_ptr(),
                null_mut(),
            ),
            "strata_eval_batch: b is NULL",
        );
        expect_null(
            strata_eval_batch(b.0, 2, null(), v.as_ptr(), f.as_mut_ptr(), null_mut()),
            "strata_eval_batch: wi is NULL (n = 2)",
        );
        expect_null(
            strata_eval_batch(b.0, 2, v.as_ptr(), null(), f.as_mut_ptr(), null_mut()),
            "strata_eval_batch: wo is NULL (n = 2)",
        );
        expect_null(
            strata_eval_batch(b.0, 2, v.as_ptr(), v.as_ptr(), null_mut(), null_mut()),
            "strata_eval_batch: f_out is NULL (n = 2)",
        );
        expect_null(
            strata_eval_batch_keyed(
                    b.0,
                    2,
                    v.as_ptr(),
                    v.as_ptr(),
                    null(),
                    f.as_mut_ptr(),
                    null_mut(),
                ),
            "strata_eval_batch_keyed: keys is NULL (n = 2): use strata_eval_batch for unkeyed queries",
        );
        expect_null(
            strata_sample_batch(b.0, 2, null(), keys.as_ptr(), s.as_mut_ptr()),
            "strata_sample_batch: wi is NULL (n = 2)",
        );
        expect_null(
            strata_sample_batch(b.0, 2, v.as_ptr(), null(), null_mut()),
            "strata_sample_batch: out is NULL (n = 2)",
        );
        expect_null(
            strata_pdf_batch(b.0, 2, v.as_ptr(), v.as_ptr(), null_mut()),
            "strata_pdf_batch: pdf_out is NULL (n = 2)",
        );
        expect_null(
            strata_albedo_batch(b.0, 2, null(), 4, null(), a.as_mut_ptr()),
            "strata_albedo_batch: wi is NULL (n = 2)",
        );
        expect_null(
            strata_bsdf_set_transport(null_mut(), 1),
            "strata_bsdf_set_transport: b is NULL",
        );
        expect_null(
            strata_bsdf_set_estimator(null_mut(), 2),
            "strata_bsdf_set_estimator: b is NULL",
        );
        expect_null(
            strata_bsdf_set_pdf_samples(null_mut(), 4),
            "strata_bsdf_set_pdf_samples: b is NULL",
        );
        expect_null(
            strata_bsdf_set_pdf_walks(null_mut(), 8, 128, 0.1),
            "strata_bsdf_set_pdf_walks: b is NULL",
        );
        let p = v.as_ptr();
        let mut x = [0.0f32; 2];
        let (fr, fg, fb) = (f.as_mut_ptr(), f.as_mut_ptr().add(2), f.as_mut_ptr().add(4));
        let status = strata_eval_batch_soa(
            b.0,
            2,
            p,
            null(),
            p,
            p,
            p,
            p,
            null(),
            fr,
            fg,
            fb,
            null_mut(),
            null_mut(),
            null_mut(),
        );
        assert_eq!(status, STRATA_ERR_NULL);
        assert_eq!(last_error(), "strata_eval_batch_soa: wi_y is NULL (n = 2)");
        let status = strata_eval_batch_soa(
            b.0,
            2,
            p,
            p,
            p,
            p,
            p,
            p,
            null(),
            fr,
            fg,
            fb,
            x.as_mut_ptr(),
            null_mut(),
            null_mut(),
        );
        assert_eq!(status, STRATA_ERR_NULL);
        assert_eq!(
            last_error(),
            "strata_eval_batch_soa: se_g is NULL but se_r is not (n = 2): pass all three or none"
        );
        let mut w = [0.0f32; 14];
        let o = w.as_mut_ptr();
        let status = strata_sample_batch_soa(
            b.0,
            2,
            p,
            p,
            p,
            null(),
            o,
            o.add(2),
            o.add(4),
            o.add(6),
            o.add(8),
            o.add(10),
            o.add(12),
            null_mut(),
        );
        assert_eq!(status, STRATA_ERR_NULL);
        assert_eq!(
            last_error(),
            "strata_sample_batch_soa: flags is NULL (n = 2)"
        );

        // n = 0: nothing to do, whatever the arrays (but b must be valid).
        assert_eq!(
            strata_eval_batch(b.0, 0, null(), null(), null_mut(), null_mut()),
            STRATA_OK
        );
        assert_eq!(
            strata_eval_batch_keyed(b.0, 0, null(), null(), null(), null_mut(), null_mut()),
            STRATA_OK
        );
        assert_eq!(
            strata_sample_batch(b.0, 0, null(), null(), null_mut()),
            STRATA_OK
        );
        assert_eq!(
            strata_pdf_batch(b.0, 0, null(), null(), null_mut()),
            STRATA_OK
        );
        assert_eq!(
            strata_albedo_batch(b.0, 0, null(), 0, null(), null_mut()),
            STRATA_OK
        );
        assert_eq!(
            strata_eval_batch_soa(
                b.0,
                0,
                null(),
                null(),
                null(),
                null(),
                null(),
                null(),
                null(),
                null_mut(),
                null_mut(),
                null_mut(),
                null_mut(),
                null_mut(),
                null_mut(),
            ),
            STRATA_OK
        );
        assert_eq!(
            strata_sample_batch_soa(
                b.0,
                0,
                null(),
                null(),
                null(),
                null(),
                null_mut(),
                null_mut(),
                null_mut(),
                null_mut(),
                null_mut(),
                null_mut(),
                null_mut(),
                null_mut(),
            ),
            STRATA_OK
        );
        assert_eq!(last_error(), "");
        assert_eq!(
            strata_eval_batch(null(), 0, null(), null(), null_mut(), null_mut()),
            STRATA_ERR_NULL
        );
        assert_eq!(last_error(), "strata_eval_batch: b is NULL");
    }
}

#[test]
fn huge_misaligned_and_overlapping_arrays_are_errors_not_crashes() {
    let b = good();
    let v = [0.0f32, 0.0, 1.0, 0.0, 0.0, 1.0];
    let mut f = [0.0f32; 6];
    // SAFETY: the calls fail on their checks before reading past 2 queries.
    unsafe {
        let s = strata_eval_batch(
            b.0,
            usize::MAX,
            null(),
            v.as_ptr(),
            f.as_mut_ptr(),
            null_mut(),
        );
        assert_eq!(s, STRATA_ERR_NULL);
        assert_eq!(
            last_error(),
            format!("strata_eval_batch: wi is NULL (n = {})", usize::MAX)
        );
        for n in [usize::MAX, usize::MAX / 3, isize::MAX as usize / 8] {
            let s = strata_eval_batch(b.0, n, v.as_ptr(), v.as_ptr(), f.as_mut_ptr(), null_mut());
            assert_eq!(s, STRATA_ERR_INVALID_ARGUMENT, "n = {n}");
            assert_eq!(
                last_error(),
                format!("strata_eval_batch: n = {n} is too large: wi would not fit in memory")
            );
        }
        let mut out = [StrataSample::default(); 1];
        let s = strata_sample_batch(b.0, usize::MAX, v.as_ptr(), null(), out.as_mut_ptr());
        assert_eq!(s, STRATA_ERR_INVALID_ARGUMENT);
        assert!(last_error().contains("is too large"));

        let bytes = [0u8; 64];
        let odd = bytes.as_ptr().add(1).cast::<f32>();
        let s = strata_eval_batch(b.0, 1, odd, v.as_ptr(), f.as_mut_ptr(), null_mut());
        assert_eq!(s, STRATA_ERR_INVALID_ARGUMENT);
        assert!(
            last_error().starts_with("strata_eval_batch: wi = 0x")
                && last_error().ends_with("is not aligned to 4 bytes"),
            "{}",
            last_error()
        );

        let mut w = [0.0f32, 0.0, 1.0, 0.0, 0.0, 1.0];
        let s = strata_eval_batch(b.0, 2, w.as_ptr(), v.as_ptr(), w.as_mut_ptr(), null_mut());
        assert_eq!(s, STRATA_ERR_INVALID_ARGUMENT);
        assert_eq!(
            last_error(),
            "strata_eval_batch: wi and f_out overlap: an output array must not share memory with another array"
        );
        let s = strata_eval_batch(
            b.0,
            2,
            v.as_ptr(),
            v.as_ptr(),
            f.as_mut_ptr(),
            f.as_mut_ptr().add(3),
        );
        assert_eq!(s, STRATA_ERR_INVALID_ARGUMENT);
        assert!(last_error().contains("f_out and stderr_out overlap"));
        // Inputs may share memory: wi = wo.
        let s = strata_eval_batch(b.0, 2, v.as_ptr(), v.as_ptr(), f.as_mut_ptr(), null_mut());
        assert_eq!(s, STRATA_OK);
        assert!(f[0] > 0.0);
    }
}

#[test]
fn the_last_error_is_per_thread() {
    let b = good();
    // SAFETY: NULL wi is reported, not read.
    let s = unsafe { strata_eval_batch(b.0, 1, null(), null(), null_mut(), null_mut()) };
    assert_eq!(s, STRATA_ERR_NULL);
    let here = last_error();
    assert_eq!(here, "strata_eval_batch: wi is NULL (n = 1)");
    std::thread::spawn(|| {
        assert_eq!(last_error(), "");
        // SAFETY: a NULL BSDF is reported, not read.
        let s = unsafe { strata_pdf_batch(null(), 1, null(), null(), null_mut()) };
        assert_eq!(s, STRATA_ERR_NULL);
        assert_eq!(last_error(), "strata_pdf_batch: b is NULL");
    })
    .join()
    .unwrap();
    assert_eq!(last_error(), here);
}

#[test]
fn one_bsdf_is_shared_by_threads_with_the_same_answers() {
    let b = good();
    let wi: Vec<f32> = (0..64)
        .flat_map(|k| [k as f32 / 64.0 - 0.5, 0.1, 1.0])
        .collect();
    let wo: Vec<f32> = (0..64)
        .flat_map(|k| [0.4 - k as f32 / 80.0, -0.2, 1.0])
        .collect();
    let run = |p: usize| {
        let b = p as *const StrataBsdf;
        let mut f = vec![0.0f32; 192];
        // SAFETY: 64 queries; the BSDF outlives the threads (joined below).
        let s = unsafe {
            strata_eval_batch(b, 64, wi.as_ptr(), wo.as_ptr(), f.as_mut_ptr(), null_mut())
        };
        assert_eq!(s, STRATA_OK);
        f.iter().map(|x| x.to_bits()).collect::<Vec<u32>>()
    };
    let p = b.0 as usize;
    let results: Vec<Vec<u32>> = std::thread::scope(|sc| {
        let hs: Vec<_> = (0..4).map(|_| sc.spawn(|| run(p))).collect();
        hs.into_iter().map(|h| h.join().unwrap()).collect()
    });
    assert!(results[0].iter().any(|&x| x != 0));
    for r in &results[1..] {
        assert_eq!(r, &results[0]);
    }
}

#[test]
fn the_version_is_the_crates() {
    // SAFETY: a static NUL-terminated string.
    let v = unsafe { CStr::from_ptr(strata_version()) };
    assert_eq!(v.to_str().unwrap(), env!("CARGO_PKG_VERSION"));
    assert!(!v.to_str().unwrap().is_empty());
}

#[test]
fn a_pool_of_its_own_changes_no_result() {
    let shared = good();
    let own = good();
    let wi: Vec<f32> = (0..300)
        .flat_map(|k| [k as f32 / 300.0 - 0.5, 0.2, 0.9])
        .collect();
    let wo: Vec<f32> = (0..300)
        .flat_map(|k| [0.1, k as f32 / 400.0 - 0.3, 0.8])
        .collect();
    // SAFETY: `own.0` is live and used by this thread only; 300 queries.
    unsafe {
        assert_eq!(strata_bsdf_set_threads(own.0, 3), STRATA_OK);
        assert_eq!(
            strata_bsdf_set_threads(own.0, 2000),
            STRATA_ERR_INVALID_ARGUMENT
        );
        assert_eq!(
            last_error(),
            "strata_bsdf_set_threads: threads = 2000: at most 1024 (0 means one per core)"
        );
        assert_eq!(strata_bsdf_set_threads(null_mut(), 1), STRATA_ERR_NULL);
        assert_eq!(last_error(), "strata_bsdf_set_threads: b is NULL");
        let (mut f, mut g) = (vec![0.0f32; 900], vec![0.0f32; 900]);
        for (b, out) in [(&shared, &mut f), (&own, &mut g)] {
            let s = strata_eval_batch(
                b.0,
                300,
                wi.as_ptr(),
                wo.as_ptr(),
                out.as_mut_ptr(),
                null_mut(),
            );
            assert_eq!(s, STRATA_OK);
        }
        assert!(f.iter().all(|&x| x > 0.0));
        assert_eq!(
            f.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
            g.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
        );
    }
}
