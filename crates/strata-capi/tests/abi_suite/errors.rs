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

/// `3 n` floats at `p`, `x, y, z` per query.
fn xyz(p: *const f32) -> StrataVectors {
    StrataVectors {
        xyz: p,
        ..Default::default()
    }
}

/// `3 n` floats to write at `p`.
fn xyz_out(p: *mut f32) -> StrataVectorsOut {
    StrataVectorsOut {
        xyz: p,
        ..Default::default()
    }
}

/// The descriptor of an eval of `n` queries in the AoS layout.
fn eval_of(n: usize, wi: *const f32, wo: *const f32, f: *mut f32, se: *mut f32) -> StrataBatch {
    StrataBatch {
        n,
        wi: xyz(wi),
        wo: xyz(wo),
        f: xyz_out(f),
        stderr: xyz_out(se),
        ..Default::default()
    }
}

#[test]
fn bad_directions_name_the_query_and_argument_and_write_nothing() {
    let b = good();
    let mut wi = [0.0f32, 0.0, 1.0].repeat(5);
    let wo = [0.3f32, 0.0, 0.9].repeat(5);
    wi[3 * 3] = f32::NAN;
    let mut f = vec![-7.0f32; 15];
    let mut cut = 9u64;
    let batch = StrataBatch {
        truncated: &mut cut,
        ..eval_of(5, wi.as_ptr(), wo.as_ptr(), f.as_mut_ptr(), null_mut())
    };
    // SAFETY: 5 queries: 15 floats each.
    let s = unsafe { strata_eval(b.0, &batch) };
    assert_eq!(s, STRATA_ERR_INVALID_ARGUMENT);
    assert_eq!(
        last_error(),
        "strata_eval: query 3: wi = [NaN, 0, 1] is not a direction: components must be finite"
    );
    assert!(f.iter().all(|&x| x == -7.0), "nothing written");
    assert_eq!(cut, 9, "nothing written");

    let mut wo2 = wo.clone();
    wi[3 * 3] = 0.0;
    wo2[3..6].copy_from_slice(&[0.0, 0.0, 0.0]);
    let mut pdf = [0.0f32; 5];
    let batch = StrataBatch {
        n: 5,
        wi: xyz(wi.as_ptr()),
        wo: xyz(wo2.as_ptr()),
        pdf: pdf.as_mut_ptr(),
        ..Default::default()
    };
    // SAFETY: as above.
    let s = unsafe { strata_pdf(b.0, &batch) };
    assert_eq!(s, STRATA_ERR_INVALID_ARGUMENT);
    assert_eq!(
        last_error(),
        "strata_pdf: query 1: wo = [0, 0, 0] is not a direction: it has zero length"
    );

    wi[4 * 3 + 2] = f32::INFINITY;
    let mut out = vec![StrataSample::default(); 5];
    let batch = StrataBatch {
        n: 5,
        wi: xyz(wi.as_ptr()),
        sample: out.as_mut_ptr(),
        ..Default::default()
    };
    // SAFETY: 5 queries.
    let s = unsafe { strata_sample(b.0, &batch) };
    assert_eq!(s, STRATA_ERR_INVALID_ARGUMENT);
    assert_eq!(
        last_error(),
        "strata_sample: query 4: wi = [0, 0, inf] is not a direction: components must be finite"
    );
    assert!(out.iter().all(|s| *s == StrataSample::default()));

    let mut a = vec![StrataAlbedo::default(); 5];
    let mut batch = StrataBatch {
        n: 5,
        wi: xyz(wi.as_ptr()),
        walks: 16,
        albedo: a.as_mut_ptr(),
        ..Default::default()
    };
    // SAFETY: 5 queries.
    let s = unsafe { strata_albedo(b.0, &batch) };
    assert_eq!(s, STRATA_ERR_INVALID_ARGUMENT);
    assert!(last_error().starts_with("strata_albedo: query 4: wi = [0, 0, inf]"));
    (batch.wi, batch.walks) = (xyz(wo.as_ptr()), 0);
    // SAFETY: 5 queries.
    let s = unsafe { strata_albedo(b.0, &batch) };
    assert_eq!(s, STRATA_ERR_INVALID_ARGUMENT);
    assert_eq!(
        last_error(),
        "strata_albedo: walks = 0: at least one walk is needed"
    );

    // A good call clears the message.
    let batch = eval_of(5, wo.as_ptr(), wo.as_ptr(), f.as_mut_ptr(), null_mut());
    // SAFETY: 5 queries.
    let s = unsafe { strata_eval(b.0, &batch) };
    assert_eq!(s, STRATA_OK);
    assert_eq!(last_error(), "");
    assert!(f.iter().all(|&x| x > 0.0));
}

/// An eval given `pdf` fails as the eval without it fails, with the same
/// message, and writes neither `f`, `stderr`, `pdf` nor `truncated`: a NaN
/// or zero direction (with and without columns), a NULL array, a pdf that
/// is misaligned or overlaps `f`.
#[test]
fn an_eval_with_pdf_fails_as_eval_and_writes_nothing() {
    let b = good();
    let mut wi = [0.0f32, 0.0, 1.0].repeat(5);
    let mut wo = [0.3f32, 0.0, 0.9].repeat(5);
    let (mut f, mut se, mut pdf) = (vec![-7.0f32; 15], vec![-7.0f32; 15], vec![-7.0f32; 5]);
    let mut cut = 9u64;
    let thickness = CString::new("layers[0].medium.thickness").unwrap();
    let values = [0.1f32, 0.2, 0.3, 0.4, 0.5];
    let column = [StrataColumn {
        path: thickness.as_ptr(),
        width: 1,
        values: values.as_ptr(),
    }];
    let untouched = |f: &[f32], se: &[f32], pdf: &[f32], cut: u64| {
        assert!(
            f.iter().chain(se).chain(pdf).all(|&x| x == -7.0),
            "nothing written"
        );
        assert_eq!(cut, 9, "nothing written");
    };
    // The message of the eval without pdf, then the eval with it: the same
    // status and message, nothing written.
    let both = |batch: StrataBatch, pdf: *mut f32, status: i32, want: &str| {
        // SAFETY: the batches hold 5 queries' arrays (or fail before reading).
        let plain = unsafe { strata_eval(b.0, &batch) };
        assert_eq!((plain, last_error()), (status, want.to_owned()));
        let with_pdf = StrataBatch { pdf, ..batch };
        // SAFETY: as above; `pdf` holds 5 floats.
        let s = unsafe { strata_eval(b.0, &with_pdf) };
        assert_eq!((s, last_error()), (status, want.to_owned()));
    };
    wi[3 * 3] = f32::NAN;
    for cols in [false, true] {
        let batch = StrataBatch {
            truncated: &mut cut,
            columns: if cols { column.as_ptr() } else { null() },
            ncolumns: usize::from(cols),
            ..eval_of(5, wi.as_ptr(), wo.as_ptr(), f.as_mut_ptr(), se.as_mut_ptr())
        };
        both(
            batch,
            pdf.as_mut_ptr(),
            STRATA_ERR_INVALID_ARGUMENT,
            "strata_eval: query 3: wi = [NaN, 0, 1] is not a direction: components must be finite",
        );
        untouched(&f, &se, &pdf, cut);
    }
    wi[3 * 3] = 0.0;
    wo[3..6].copy_from_slice(&[0.0, 0.0, 0.0]);
    let batch = StrataBatch {
        truncated: &mut cut,
        ..eval_of(5, wi.as_ptr(), wo.as_ptr(), f.as_mut_ptr(), se.as_mut_ptr())
    };
    both(
        batch,
        pdf.as_mut_ptr(),
        STRATA_ERR_INVALID_ARGUMENT,
        "strata_eval: query 1: wo = [0, 0, 0] is not a direction: it has zero length",
    );
    untouched(&f, &se, &pdf, cut);
    wo[3..6].copy_from_slice(&[0.3, 0.0, 0.9]);

    let good_batch = StrataBatch {
        truncated: &mut cut,
        ..eval_of(5, wi.as_ptr(), wo.as_ptr(), f.as_mut_ptr(), se.as_mut_ptr())
    };
    let p = pdf.as_mut_ptr();
    let none = StrataVectors::default();
    both(
        StrataBatch {
            wo: none,
            ..good_batch
        },
        p,
        STRATA_ERR_NULL,
        "strata_eval: wo is NULL (n = 5): set wo.xyz, or wo.x, .y and .z",
    );
    both(
        StrataBatch {
            f: StrataVectorsOut::default(),
            ..good_batch
        },
        p,
        STRATA_ERR_NULL,
        "strata_eval: f is NULL (n = 5): set f.xyz, or f.x, .y and .z",
    );
    // SAFETY: NULL is reported, not read.
    let s = unsafe {
        strata_eval(
            null(),
            &StrataBatch {
                pdf: p,
                ..good_batch
            },
        )
    };
    assert_eq!(
        (s, last_error()),
        (STRATA_ERR_NULL, "strata_eval: b is NULL".to_owned())
    );
    untouched(&f, &se, &pdf, cut);

    // The pdf array itself: misaligned, overlapping f.
    let mut bytes = [0u32; 8];
    let odd = bytes
        .as_mut_ptr()
        .cast::<u8>()
        .wrapping_add(1)
        .cast::<f32>();
    let batch = StrataBatch {
        pdf: odd,
        ..good_batch
    };
    // SAFETY: the call fails on the alignment before writing.
    let s = unsafe { strata_eval(b.0, &batch) };
    assert_eq!(s, STRATA_ERR_INVALID_ARGUMENT);
    let e = last_error();
    assert!(
        e.starts_with("strata_eval: pdf = 0x") && e.ends_with("is not aligned to 4 bytes"),
        "{e}"
    );
    let batch = StrataBatch {
        pdf: f.as_mut_ptr().wrapping_add(10),
        ..good_batch
    };
    // SAFETY: the call fails on the overlap before writing.
    let s = unsafe { strata_eval(b.0, &batch) };
    assert_eq!(s, STRATA_ERR_INVALID_ARGUMENT);
    assert!(
        last_error().contains("f.xyz and pdf overlap"),
        "{}",
        last_error()
    );
    untouched(&f, &se, &pdf, cut);
    assert!(bytes.iter().all(|&x| x == 0));

    // And the good call writes all three.
    // SAFETY: every array holds 5 queries'.
    let s = unsafe {
        strata_eval(
            b.0,
            &StrataBatch {
                pdf: p,
                ..good_batch
            },
        )
    };
    assert_eq!(s, STRATA_OK, "{}", last_error());
    assert!(f.iter().chain(&pdf).all(|&x| x > 0.0) && cut == 0);
}

#[test]
fn null_arrays_are_errors_naming_them_unless_n_is_zero() {
    let b = good();
    let v = [0.0f32, 0.0, 1.0, 0.0, 0.0, 1.0];
    let mut f = [0.0f32; 6];
    let mut s = [StrataSample::default(); 2];
    let mut a = [StrataAlbedo::default(); 2];
    let keys = [1u64, 2];
    let (p, fp) = (v.as_ptr(), f.as_mut_ptr());
    let eval = eval_of(2, p, p, fp, null_mut());
    let sample = StrataBatch {
        n: 2,
        wi: xyz(p),
        keys: keys.as_ptr(),
        sample: s.as_mut_ptr(),
        ..Default::default()
    };
    let pdf = StrataBatch {
        n: 2,
        wi: xyz(p),
        wo: xyz(p),
        ..Default::default()
    };
    let albedo = StrataBatch {
        n: 2,
        wi: xyz(p),
        walks: 4,
        albedo: a.as_mut_ptr(),
        ..Default::default()
    };
    let none = StrataVectors::default();
    let mut q = [0.0f32; 2];
    // SAFETY: NULL arrays are reported, not read; others hold 2 queries.
    unsafe {
        expect_null(strata_eval(null(), &eval), "strata_eval: b is NULL");
        // A NULL descriptor, for every call.
        expect_null(strata_eval(b.0, null()), "strata_eval: batch is NULL");
        expect_null(strata_sample(b.0, null()), "strata_sample: batch is NULL");
        expect_null(strata_pdf(b.0, null()), "strata_pdf: batch is NULL");
        expect_null(
            strata_pdf_unbiased(b.0, null()),
            "strata_pdf_unbiased: batch is NULL",
        );
        expect_null(strata_albedo(b.0, null()), "strata_albedo: batch is NULL");
        expect_null(
            strata_eval(b.0, &StrataBatch { wi: none, ..eval }),
            "strata_eval: wi is NULL (n = 2): set wi.xyz, or wi.x, .y and .z",
        );
        expect_null(
            strata_eval(b.0, &StrataBatch { wo: none, ..eval }),
            "strata_eval: wo is NULL (n = 2): set wo.xyz, or wo.x, .y and .z",
        );
        expect_null(
            strata_eval(
                b.0,
                &StrataBatch {
                    f: StrataVectorsOut::default(),
                    ..eval
                },
            ),
            "strata_eval: f is NULL (n = 2): set f.xyz, or f.x, .y and .z",
        );
        expect_null(
            strata_sample(b.0, &StrataBatch { wi: none, ..sample }),
            "strata_sample: wi is NULL (n = 2): set wi.xyz, or wi.x, .y and .z",
        );
        expect_null(
            strata_sample(
                b.0,
                &StrataBatch {
                    sample: null_mut(),
                    ..sample
                },
            ),
            "strata_sample: sample is NULL (n = 2): pass records in sample, or sampled, \
             weight, pdf and flags",
        );
        expect_null(strata_pdf(b.0, &pdf), "strata_pdf: pdf is NULL (n = 2)");
        expect_null(
            strata_albedo(b.0, &StrataBatch { wi: none, ..albedo }),
            "strata_albedo: wi is NULL (n = 2): set wi.xyz, or wi.x, .y and .z",
        );
        let unbiased = StrataBatch {
            walks: 4,
            pdf: q.as_mut_ptr(),
            ..pdf
        };
        expect_null(
            strata_pdf_unbiased(b.0, &unbiased),
            "strata_pdf_unbiased: pdf_stderr is NULL (n = 2)",
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
        let mut x = [0.0f32; 2];
        let (fr, fg, fb) = (fp, fp.add(2), fp.add(4));
        let f_soa = StrataVectorsOut {
            x: fr,
            y: fg,
            z: fb,
            ..Default::default()
        };
        let soa = StrataBatch {
            n: 2,
            wi: StrataVectors {
                x: p,
                y: null(),
                z: p,
                ..Default::default()
            },
            wo: StrataVectors {
                x: p,
                y: p,
                z: p,
                ..Default::default()
            },
            f: f_soa,
            ..Default::default()
        };
        let status = strata_eval(b.0, &soa);
        assert_eq!(status, STRATA_ERR_NULL);
        assert_eq!(
            last_error(),
            "strata_eval: wi.y is NULL but wi.x is not (n = 2): pass all three or none"
        );
        let status = strata_eval(
            b.0,
            &StrataBatch {
                wi: soa.wo,
                stderr: StrataVectorsOut {
                    x: x.as_mut_ptr(),
                    ..Default::default()
                },
                ..soa
            },
        );
        assert_eq!(status, STRATA_ERR_NULL);
        assert_eq!(
            last_error(),
            "strata_eval: stderr.y is NULL but stderr.x is not (n = 2): pass all three or none"
        );
        let mut w = [0.0f32; 14];
        let o = w.as_mut_ptr();
        let sample_soa = StrataBatch {
            n: 2,
            wi: soa.wo,
            sampled: StrataVectorsOut {
                x: o,
                y: o.add(2),
                z: o.add(4),
                ..Default::default()
            },
            weight: StrataVectorsOut {
                x: o.add(6),
                y: o.add(8),
                z: o.add(10),
                ..Default::default()
            },
            pdf: o.add(12),
            ..Default::default()
        };
        let status = strata_sample(b.0, &sample_soa);
        assert_eq!(status, STRATA_ERR_NULL);
        assert_eq!(last_error(), "strata_sample: flags is NULL (n = 2)");

        // n = 0: nothing to do, whatever the arrays (but b and the
        // descriptor must be valid).
        let empty = StrataBatch::default();
        assert_eq!(strata_eval(b.0, &empty), STRATA_OK);
        let keyed = StrataBatch {
            keys: null(),
            ..empty
        };
        assert_eq!(strata_eval(b.0, &keyed), STRATA_OK);
        assert_eq!(strata_sample(b.0, &empty), STRATA_OK);
        assert_eq!(strata_pdf(b.0, &empty), STRATA_OK);
        assert_eq!(strata_albedo(b.0, &empty), STRATA_OK);
        assert_eq!(strata_pdf_unbiased(b.0, &empty), STRATA_OK);
        assert_eq!(last_error(), "");
        assert_eq!(strata_eval(null(), &empty), STRATA_ERR_NULL);
        assert_eq!(last_error(), "strata_eval: b is NULL");
    }
}

/// A field the call does not read is an error naming it, so that nothing
/// passed is silently ignored; so is a vector field given in both layouts,
/// and a sample batch given both records and components.
#[test]
fn fields_a_call_does_not_take_are_errors_naming_them() {
    let b = good();
    let v = [0.0f32, 0.0, 1.0, 0.3, 0.0, 0.9];
    let (mut f, mut pdf, mut flags) = ([0.0f32; 6], [0.0f32; 2], [0u32; 2]);
    let mut out = [StrataSample::default(); 2];
    let mut cut = 5u64;
    let keys = [1u64, 2];
    let pdfs = StrataBatch {
        n: 2,
        wi: xyz(v.as_ptr()),
        wo: xyz(v.as_ptr()),
        pdf: pdf.as_mut_ptr(),
        ..Default::default()
    };
    // SAFETY: every array holds 2 queries; the calls fail on their checks.
    unsafe {
        for (batch, want) in [
            (
                StrataBatch {
                    keys: keys.as_ptr(),
                    ..pdfs
                },
                "strata_pdf: keys is not NULL, but this call does not take it: set it to NULL",
            ),
            (
                StrataBatch {
                    truncated: &mut cut,
                    ..pdfs
                },
                "strata_pdf: truncated is not NULL, but this call does not take it: set it to NULL",
            ),
            (
                StrataBatch { walks: 8, ..pdfs },
                "strata_pdf: walks = 8, but this call takes no walk count: set it to 0",
            ),
        ] {
            assert_eq!(strata_pdf(b.0, &batch), STRATA_ERR_INVALID_ARGUMENT);
            assert_eq!(last_error(), want);
        }
        let eval = StrataBatch {
            walks: 3,
            ..eval_of(2, v.as_ptr(), v.as_ptr(), f.as_mut_ptr(), null_mut())
        };
        assert_eq!(strata_eval(b.0, &eval), STRATA_ERR_INVALID_ARGUMENT);
        assert_eq!(
            last_error(),
            "strata_eval: walks = 3, but this call takes no walk count: set it to 0"
        );
        let sample = StrataBatch {
            n: 2,
            wi: xyz(v.as_ptr()),
            sample: out.as_mut_ptr(),
            truncated: &mut cut,
            ..Default::default()
        };
        assert_eq!(strata_sample(b.0, &sample), STRATA_ERR_INVALID_ARGUMENT);
        assert_eq!(
            last_error(),
            "strata_sample: truncated is not NULL, but this call does not take it: set it to NULL"
        );
        let both = StrataBatch {
            truncated: null_mut(),
            flags: flags.as_mut_ptr(),
            ..sample
        };
        assert_eq!(strata_sample(b.0, &both), STRATA_ERR_INVALID_ARGUMENT);
        assert_eq!(
            last_error(),
            "strata_sample: sample and sampled, weight, pdf or flags are set: \
             pass the records or the components"
        );
        let layouts = StrataBatch {
            wi: StrataVectors {
                xyz: v.as_ptr(),
                x: v.as_ptr(),
                y: v.as_ptr(),
                z: v.as_ptr(),
            },
            ..pdfs
        };
        assert_eq!(strata_pdf(b.0, &layouts), STRATA_ERR_INVALID_ARGUMENT);
        assert_eq!(
            last_error(),
            "strata_pdf: wi.xyz and wi.x, .y, .z are both set: pass one layout"
        );
        // Nothing was written.
        assert_eq!(cut, 5);
        assert!(out.iter().all(|s| *s == StrataSample::default()));
        assert_eq!(pdf, [0.0; 2]);
    }
}

#[test]
fn huge_misaligned_and_overlapping_arrays_are_errors_not_crashes() {
    let b = good();
    let v = [0.0f32, 0.0, 1.0, 0.0, 0.0, 1.0];
    let mut f = [0.0f32; 6];
    let (p, fp) = (v.as_ptr(), f.as_mut_ptr());
    // SAFETY: the calls fail on their checks before reading past 2 queries.
    unsafe {
        let s = strata_eval(b.0, &eval_of(usize::MAX, null(), p, fp, null_mut()));
        assert_eq!(s, STRATA_ERR_NULL);
        assert_eq!(
            last_error(),
            format!(
                "strata_eval: wi is NULL (n = {}): set wi.xyz, or wi.x, .y and .z",
                usize::MAX
            )
        );
        for n in [usize::MAX, usize::MAX / 3, isize::MAX as usize / 8] {
            let s = strata_eval(b.0, &eval_of(n, p, p, fp, null_mut()));
            assert_eq!(s, STRATA_ERR_INVALID_ARGUMENT, "n = {n}");
            assert_eq!(
                last_error(),
                format!("strata_eval: n = {n} is too large: wi.xyz would not fit in memory")
            );
        }
        let mut out = [StrataSample::default(); 1];
        let sample = StrataBatch {
            n: usize::MAX,
            wi: xyz(p),
            sample: out.as_mut_ptr(),
            ..Default::default()
        };
        let s = strata_sample(b.0, &sample);
        assert_eq!(s, STRATA_ERR_INVALID_ARGUMENT);
        assert!(last_error().contains("is too large"));

        let bytes = [0u8; 64];
        let odd = bytes.as_ptr().add(1).cast::<f32>();
        let s = strata_eval(b.0, &eval_of(1, odd, p, fp, null_mut()));
        assert_eq!(s, STRATA_ERR_INVALID_ARGUMENT);
        assert!(
            last_error().starts_with("strata_eval: wi.xyz = 0x")
                && last_error().ends_with("is not aligned to 4 bytes"),
            "{}",
            last_error()
        );
        let mut cut = 0u64;
        let odd_count = bytes.as_ptr().add(1).cast::<u64>().cast_mut();
        let s = strata_eval(
            b.0,
            &StrataBatch {
                truncated: odd_count,
                ..eval_of(2, p, p, fp, null_mut())
            },
        );
        assert_eq!(s, STRATA_ERR_INVALID_ARGUMENT);
        assert!(
            last_error().starts_with("strata_eval: truncated = 0x")
                && last_error().ends_with("is not aligned to 8 bytes"),
            "{}",
            last_error()
        );

        let mut w = [0.0f32, 0.0, 1.0, 0.0, 0.0, 1.0];
        let s = strata_eval(b.0, &eval_of(2, w.as_ptr(), p, w.as_mut_ptr(), null_mut()));
        assert_eq!(s, STRATA_ERR_INVALID_ARGUMENT);
        assert_eq!(
            last_error(),
            "strata_eval: wi.xyz and f.xyz overlap: an output array must not share memory with another array"
        );
        let s = strata_eval(b.0, &eval_of(2, p, p, fp, fp.add(3)));
        assert_eq!(s, STRATA_ERR_INVALID_ARGUMENT);
        assert!(last_error().contains("f.xyz and stderr.xyz overlap"));
        // (An output of u64s, so that `truncated` is aligned inside it.)
        let mut g = [0u64; 3];
        let gp = g.as_mut_ptr();
        let s = strata_eval(
            b.0,
            &StrataBatch {
                truncated: gp,
                ..eval_of(2, p, p, gp.cast(), null_mut())
            },
        );
        assert_eq!(s, STRATA_ERR_INVALID_ARGUMENT);
        assert!(
            last_error().contains("f.xyz and truncated overlap"),
            "{}",
            last_error()
        );
        // Inputs may share memory: wi = wo.
        let s = strata_eval(
            b.0,
            &StrataBatch {
                truncated: &mut cut,
                ..eval_of(2, p, p, fp, null_mut())
            },
        );
        assert_eq!(s, STRATA_OK);
        assert!(f[0] > 0.0);
    }
}

#[test]
fn the_last_error_is_per_thread() {
    let b = good();
    let batch = eval_of(1, null(), null(), null_mut(), null_mut());
    // SAFETY: NULL wi is reported, not read.
    let s = unsafe { strata_eval(b.0, &batch) };
    assert_eq!(s, STRATA_ERR_NULL);
    let here = last_error();
    assert_eq!(
        here,
        "strata_eval: wi is NULL (n = 1): set wi.xyz, or wi.x, .y and .z"
    );
    std::thread::spawn(|| {
        assert_eq!(last_error(), "");
        let batch = StrataBatch {
            n: 1,
            ..Default::default()
        };
        // SAFETY: a NULL BSDF is reported, not read.
        let s = unsafe { strata_pdf(null(), &batch) };
        assert_eq!(s, STRATA_ERR_NULL);
        assert_eq!(last_error(), "strata_pdf: b is NULL");
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
        let batch = eval_of(64, wi.as_ptr(), wo.as_ptr(), f.as_mut_ptr(), null_mut());
        // SAFETY: 64 queries; the BSDF outlives the threads (joined below).
        let s = unsafe { strata_eval(b, &batch) };
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
            let batch = eval_of(300, wi.as_ptr(), wo.as_ptr(), out.as_mut_ptr(), null_mut());
            let s = strata_eval(b.0, &batch);
            assert_eq!(s, STRATA_OK);
        }
        assert!(f.iter().all(|&x| x > 0.0));
        assert_eq!(
            f.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
            g.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
        );
    }
}
