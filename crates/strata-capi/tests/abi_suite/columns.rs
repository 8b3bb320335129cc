//! Per-query parameters through the C ABI (`StrataColumn`, a batch's
//! `columns`): query `k` of a batch with columns answers bit for bit what
//! query `k` of a batch without answers on a BSDF made from a TOML material with
//! row `k`'s values (same seed, walk count and keys), for every batch call
//! and both layouts; bad columns are a status and a message naming the
//! column or query, the path and the value, and nothing is written.

use std::ffi::{c_char, CStr, CString};
use std::ptr::{null, null_mut};
use strata_capi::*;

use crate::batch::{aos, aos_out, soa3, soa3_out};

/// The material of query `k`: a dielectric coat with an absorbing medium
/// over a rough conductor, with `k`'s thickness, `sigma_t`, conductor `eta`
/// and conductor roughness. The values are printed as the number a column
/// sets (see [`n`]).
fn material(thickness: f32, sigma_t: [f32; 3], eta: [f32; 3], roughness: f32) -> String {
    material_text(thickness, &v(sigma_t), eta, roughness)
}

/// A value as TOML, the number a column's `x` sets where its rows are
/// written in place: the float itself (its shortest decimal as a double).
fn n(x: f32) -> String {
    format!("{:e}", f64::from(x))
}

/// A value as TOML, the number a column's `x` sets where its rows are
/// materials (an IOR): the first of its correctly rounded decimals of 1 to 9
/// digits that reads back as `x`.
fn d(x: f32) -> String {
    (1..=9)
        .map(|p| format!("{:.*e}", p - 1, f64::from(x)))
        .find(|s| s.parse::<f32>() == Ok(x))
        .expect("nine digits read back as any f32")
}

/// A triple as TOML.
fn v(x: [f32; 3]) -> String {
    format!("[{}, {}, {}]", n(x[0]), n(x[1]), n(x[2]))
}

/// [`material`] with `sigma_t` as TOML text (a number or a triple).
fn material_text(thickness: f32, sigma_t: &str, eta: [f32; 3], roughness: f32) -> String {
    format!(
        "[[layers]]\n\
         interface = {{ kind = \"dielectric\", ior = 1.5, roughness = 0.15 }}\n\
         medium = {{ thickness = {}, sigma_t = {}, albedo = 0.6 }}\n\
         [[layers]]\n\
         interface = {{ kind = \"conductor\", eta = {}, k = [3.9, 2.4, 2.1], roughness = {} }}\n",
        n(thickness),
        sigma_t,
        v(eta),
        n(roughness)
    )
}

/// The template the columns vary.
fn template() -> String {
    material(0.5, [0.4, 0.8, 1.6], [0.2, 0.9, 1.1], 0.3)
}

const SAMPLES: u64 = 24;
const SEED: u64 = 77;
const WALKS: u64 = 32;
/// Queries per batch: not a multiple of the wavefront's lanes.
const N: usize = 5;

/// Per query: thickness, sigma_t, eta, roughness (non-round values).
fn rows() -> Vec<(f32, [f32; 3], [f32; 3], f32)> {
    (0..N)
        .map(|k| {
            let t = k as f32;
            (
                0.1 + 0.37 * t,
                [0.3 + 0.11 * t, 1.7 - 0.23 * t, 0.9 + 0.05 * t],
                [0.15 + 0.07 * t, 0.6 + 0.13 * t, 1.3 - 0.09 * t],
                0.05 + 0.13 * t,
            )
        })
        .collect()
}

struct Capi(*mut StrataBsdf);

impl Capi {
    fn toml(text: &str) -> Capi {
        let c = CString::new(text).unwrap();
        let mut b = null_mut();
        // SAFETY: `c` is NUL-terminated and `b` is writable.
        let status = unsafe { strata_bsdf_from_toml(c.as_ptr(), SAMPLES, SEED, &mut b) };
        assert_eq!(status, STRATA_OK, "{}", last_error());
        Capi(b)
    }
}

impl Drop for Capi {
    fn drop(&mut self) {
        // SAFETY: from `strata_bsdf_from_toml`, freed once.
        unsafe { strata_bsdf_free(self.0) }
    }
}

fn last_error() -> String {
    // SAFETY: `strata_last_error` returns a NUL-terminated string valid
    // until the next call on this thread.
    unsafe { CStr::from_ptr(strata_last_error()) }
        .to_str()
        .unwrap()
        .to_owned()
}

/// The columns' storage: paths and values kept alive for the pointers.
struct Owned {
    paths: Vec<CString>,
    values: Vec<Vec<f32>>,
    widths: Vec<usize>,
}

impl Owned {
    fn new(columns: &[(&str, usize, Vec<f32>)]) -> Owned {
        Owned {
            paths: columns.iter().map(|c| CString::new(c.0).unwrap()).collect(),
            widths: columns.iter().map(|c| c.1).collect(),
            values: columns.iter().map(|c| c.2.clone()).collect(),
        }
    }
    fn columns(&self) -> Vec<StrataColumn> {
        (0..self.paths.len())
            .map(|i| StrataColumn {
                path: self.paths[i].as_ptr(),
                width: self.widths[i],
                values: self.values[i].as_ptr(),
            })
            .collect()
    }
}

/// The four columns of `rows()`.
fn textured() -> Owned {
    let r = rows();
    Owned::new(&[
        (
            "layers[0].medium.thickness",
            1,
            r.iter().map(|q| q.0).collect(),
        ),
        (
            "layers[0].medium.sigma_t",
            3,
            r.iter().flat_map(|q| q.1).collect(),
        ),
        (
            "layers[1].interface.eta",
            3,
            r.iter().flat_map(|q| q.2).collect(),
        ),
        (
            "layers[1].interface.roughness",
            1,
            r.iter().map(|q| q.3).collect(),
        ),
    ])
}

fn directions(salt: u32) -> (Vec<f32>, Vec<f32>) {
    let d = |k: usize, s: u32| {
        let a = (k as f32 + 1.0) * 0.7 + s as f32;
        [0.6 * a.cos(), 0.6 * a.sin(), 0.5 + 0.1 * k as f32]
    };
    let wi = (0..N).flat_map(|k| d(k, salt)).collect();
    let wo = (0..N).flat_map(|k| d(k, salt + 3)).collect();
    (wi, wo)
}

/// Every batch call's answers, per call and per query (as bits): without
/// columns when `cols` is `None`, with them otherwise.
fn answers(b: &Capi, cols: Option<&[StrataColumn]>) -> Vec<(&'static str, Vec<Vec<u32>>)> {
    let (wi, wo) = directions(1);
    let keys: Vec<u64> = (0..N as u64).map(|k| 1000 + 17 * k).collect();
    let (cp, nc) = cols.map_or((null(), 0), |c| (c.as_ptr(), c.len()));
    let mut out = Vec::new();
    let per = |v: Vec<u32>, w: usize| v.chunks(w).map(|c| c.to_vec()).collect::<Vec<_>>();
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    let ok = |s: i32| assert_eq!(s, STRATA_OK, "{}", last_error());
    let base = StrataBatch {
        n: N,
        wi: aos(&wi),
        columns: cp,
        ncolumns: nc,
        ..Default::default()
    };

    for keyed in [false, true] {
        let (mut f, mut se) = (vec![-1.0f32; 3 * N], vec![-1.0f32; 3 * N]);
        let kp = if keyed { keys.as_ptr() } else { null() };
        let batch = StrataBatch {
            wo: aos(&wo),
            keys: kp,
            f: aos_out(&mut f),
            stderr: aos_out(&mut se),
            ..base
        };
        // SAFETY: wi, wo, f, se hold 3 N floats, keys N, the columns N rows.
        ok(unsafe { strata_eval(b.0, &batch) });
        out.push((if keyed { "eval keyed" } else { "eval" }, per(bits(&f), 3)));
        out.push((
            if keyed { "eval keyed se" } else { "eval se" },
            per(bits(&se), 3),
        ));

        let mut s = vec![StrataSample::default(); N];
        let batch = StrataBatch {
            keys: kp,
            sample: s.as_mut_ptr(),
            ..base
        };
        // SAFETY: wi holds 3 N floats, keys N, s N records.
        ok(unsafe { strata_sample(b.0, &batch) });
        let s = s
            .iter()
            .map(|s| {
                let mut v = bits(&s.wo);
                v.extend(bits(&s.weight));
                v.extend([s.pdf.to_bits(), s.flags]);
                v
            })
            .collect();
        out.push((if keyed { "sample keyed" } else { "sample" }, s));

        let mut a = vec![StrataAlbedo::default(); N];
        let batch = StrataBatch {
            keys: kp,
            walks: WALKS,
            albedo: a.as_mut_ptr(),
            ..base
        };
        // SAFETY: wi holds 3 N floats, keys N, a N records.
        ok(unsafe { strata_albedo(b.0, &batch) });
        let a = a
            .iter()
            .map(|a| {
                let mut v = bits(&a.reflected);
                v.extend(bits(&a.transmitted));
                v.extend(bits(&a.reflected_stderr));
                v.extend(bits(&a.transmitted_stderr));
                v
            })
            .collect();
        out.push((if keyed { "albedo keyed" } else { "albedo" }, a));
    }

    let mut pdf = vec![-1.0f32; N];
    let batch = StrataBatch {
        wo: aos(&wo),
        pdf: pdf.as_mut_ptr(),
        ..base
    };
    // SAFETY: wi, wo hold 3 N floats, pdf N.
    ok(unsafe { strata_pdf(b.0, &batch) });
    out.push(("pdf", per(bits(&pdf), 1)));

    let (mut p, mut se) = (vec![-1.0f32; N], vec![-1.0f32; N]);
    let batch = StrataBatch {
        wo: aos(&wo),
        walks: WALKS,
        pdf: p.as_mut_ptr(),
        pdf_stderr: se.as_mut_ptr(),
        ..base
    };
    // SAFETY: wi, wo hold 3 N floats, p and se N.
    ok(unsafe { strata_pdf_unbiased(b.0, &batch) });
    out.push(("pdf unbiased", per(bits(&p), 1)));
    out.push(("pdf unbiased se", per(bits(&se), 1)));
    out
}

#[test]
fn columns_answer_what_toml_materials_with_those_values_answer() {
    let cols = textured();
    let b = Capi::toml(&template());
    let got = answers(&b, Some(&cols.columns()));
    let plain = answers(&b, None);
    for (k, row) in rows().into_iter().enumerate() {
        let own = Capi::toml(&material(row.0, row.1, row.2, row.3));
        let want = answers(&own, None);
        for ((name, g), (_, w)) in got.iter().zip(&want) {
            assert_eq!(g[k], w[k], "{name}, query {k}");
        }
    }
    // The columns are used: the template's own answers differ (but the
    // default pdf's, the lobe pdf, which reads only the entry interface, and
    // the columns set the layer and the base).
    for ((name, g), (_, p)) in got.iter().zip(&plain) {
        if *name != "pdf" {
            assert_ne!(g, p, "{name}: the columns changed nothing");
        }
    }
    // A thicker absorbing coat reflects less: query 4 (thickest) below
    // query 0 in the red channel's albedo (a check on the direction of the
    // effect, not only on its presence).
    let albedo = &got.iter().find(|(n, _)| *n == "albedo").unwrap().1;
    let red = |k: usize| f32::from_bits(albedo[k][0]);
    assert!(red(4) < red(0), "{} vs {}", red(4), red(0));
}

#[test]
fn a_number_for_a_triple_field_is_one_grey_value() {
    let grey = [0.7f32, 1.3, 2.1, 0.2, 3.3];
    let cols = Owned::new(&[("layers[0].medium.sigma_t", 1, grey.to_vec())]);
    let b = Capi::toml(&template());
    let got = answers(&b, Some(&cols.columns()));
    for (k, &g) in grey.iter().enumerate() {
        let own = Capi::toml(&material_text(0.5, &n(g), [0.2, 0.9, 1.1], 0.3));
        let want = answers(&own, None);
        for ((name, g), (_, w)) in got.iter().zip(&want) {
            assert_eq!(g[k], w[k], "{name}, query {k}");
        }
    }
}

#[test]
fn the_bsdfs_transport_mode_holds_for_every_query() {
    // A rough glass slab: transmission between exteriors of different IOR,
    // where importance transport differs from radiance.
    let glass = |ior: f32| {
        format!(
            "[[layers]]\ninterface = {{ kind = \"dielectric\", ior = {}, roughness = 0.3 }}\n",
            d(ior)
        )
    };
    let importance = |text: &str| {
        let b = Capi::toml(text);
        // SAFETY: `b.0` is live and used by this thread only.
        let status = unsafe { strata_bsdf_set_transport(b.0, STRATA_TRANSPORT_IMPORTANCE) };
        assert_eq!(status, STRATA_OK, "{}", last_error());
        b
    };
    let iors = [1.2f32, 1.45, 1.7, 2.0, 1.33];
    let cols = Owned::new(&[("layers[0].interface.ior", 1, iors.to_vec())]);
    let b = importance(&glass(1.5));
    let got = answers(&b, Some(&cols.columns()));
    let radiance = answers(&Capi::toml(&glass(1.5)), Some(&cols.columns()));
    assert_ne!(got, radiance, "the transport mode changed nothing");
    for (k, &ior) in iors.iter().enumerate() {
        let want = answers(&importance(&glass(ior)), None);
        for ((name, g), (_, w)) in got.iter().zip(&want) {
            assert_eq!(g[k], w[k], "{name}, query {k}");
        }
    }
}

#[test]
fn no_columns_is_the_call_without_columns() {
    let b = Capi::toml(&template());
    let none: [StrataColumn; 0] = [];
    assert_eq!(answers(&b, Some(&none)), answers(&b, None));
}

#[test]
fn the_soa_column_calls_give_the_aos_numbers() {
    let cols = textured();
    let cols = cols.columns();
    let b = Capi::toml(&template());
    let (wi, wo) = directions(2);
    let soa = |v: &[f32]| [0, 1, 2].map(|c| (0..N).map(|k| v[3 * k + c]).collect::<Vec<f32>>());
    let (wis, wos) = (soa(&wi), soa(&wo));
    let keys: Vec<u64> = (0..N as u64).map(|k| 5 + k).collect();
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    for keyed in [false, true] {
        let kp = if keyed { keys.as_ptr() } else { null() };
        let base = StrataBatch {
            n: N,
            keys: kp,
            columns: cols.as_ptr(),
            ncolumns: cols.len(),
            ..Default::default()
        };
        let (mut f, mut se) = (vec![0.0f32; 3 * N], vec![0.0f32; 3 * N]);
        let batch = StrataBatch {
            wi: aos(&wi),
            wo: aos(&wo),
            f: aos_out(&mut f),
            stderr: aos_out(&mut se),
            ..base
        };
        // SAFETY: every array holds 3 N floats (N keys); the columns N rows.
        let status = unsafe { strata_eval(b.0, &batch) };
        assert_eq!(status, STRATA_OK, "{}", last_error());
        let mut fs = [vec![0.0f32; N], vec![0.0; N], vec![0.0; N]];
        let mut ses = [vec![0.0f32; N], vec![0.0; N], vec![0.0; N]];
        let batch = StrataBatch {
            wi: soa3(&wis),
            wo: soa3(&wos),
            f: soa3_out(&mut fs),
            stderr: soa3_out(&mut ses),
            ..base
        };
        // SAFETY: every array holds N elements; the columns N rows.
        let status = unsafe { strata_eval(b.0, &batch) };
        assert_eq!(status, STRATA_OK, "{}", last_error());
        assert!(f.iter().any(|&x| x > 0.0));
        for ch in 0..3 {
            assert_eq!(bits(&fs[ch]), bits(&soa(&f)[ch]), "eval keyed={keyed}");
            assert_eq!(bits(&ses[ch]), bits(&soa(&se)[ch]), "stderr keyed={keyed}");
        }

        let mut s = vec![StrataSample::default(); N];
        let batch = StrataBatch {
            wi: aos(&wi),
            sample: s.as_mut_ptr(),
            ..base
        };
        // SAFETY: wi holds 3 N floats, keys N, s N records.
        let status = unsafe { strata_sample(b.0, &batch) };
        assert_eq!(status, STRATA_OK, "{}", last_error());
        let mut wo_s = [vec![0.0f32; N], vec![0.0; N], vec![0.0; N]];
        let mut weight = [vec![0.0f32; N], vec![0.0; N], vec![0.0; N]];
        let (mut pdf, mut flags) = (vec![0.0f32; N], vec![0u32; N]);
        let batch = StrataBatch {
            wi: soa3(&wis),
            sampled: soa3_out(&mut wo_s),
            weight: soa3_out(&mut weight),
            pdf: pdf.as_mut_ptr(),
            flags: flags.as_mut_ptr(),
            ..base
        };
        // SAFETY: every array holds N elements; the columns N rows.
        let status = unsafe { strata_sample(b.0, &batch) };
        assert_eq!(status, STRATA_OK, "{}", last_error());
        assert!(s.iter().any(|s| s.flags != 0));
        for (k, s) in s.iter().enumerate() {
            for ch in 0..3 {
                assert_eq!(wo_s[ch][k].to_bits(), s.wo[ch].to_bits());
                assert_eq!(weight[ch][k].to_bits(), s.weight[ch].to_bits());
            }
            assert_eq!(pdf[k].to_bits(), s.pdf.to_bits());
            assert_eq!(flags[k], s.flags);
        }
    }
}

/// An eval given `pdf` with columns (one library call, `PerQuery`'s
/// `eval_pdf_into`) answers bit for bit what the eval without it and
/// `strata_pdf` answer with the same columns, in both layouts, keyed or
/// not: rows written in place (`textured`) and rows that are materials (an
/// IOR column as well).
#[test]
fn an_eval_with_pdf_is_eval_then_pdf_with_columns() {
    let r = rows();
    let mut with_ior: Vec<(&str, usize, Vec<f32>)> = vec![(
        "layers[0].interface.ior",
        1,
        (0..N).map(|k| 1.3 + 0.07 * k as f32).collect(),
    )];
    with_ior.push((
        "layers[1].interface.roughness",
        1,
        r.iter().map(|q| q.3).collect(),
    ));
    let b = Capi::toml(&template());
    let (wi, wo) = directions(4);
    let soa = |v: &[f32]| [0, 1, 2].map(|c| (0..N).map(|k| v[3 * k + c]).collect::<Vec<f32>>());
    let (wis, wos) = (soa(&wi), soa(&wo));
    let keys: Vec<u64> = (0..N as u64).map(|k| 40 + 3 * k).collect();
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    let ok = |s: i32| assert_eq!(s, STRATA_OK, "{}", last_error());
    for owned in [textured(), Owned::new(&with_ior)] {
        let cols = owned.columns();
        for keyed in [false, true] {
            let base = StrataBatch {
                n: N,
                keys: if keyed { keys.as_ptr() } else { null() },
                columns: cols.as_ptr(),
                ncolumns: cols.len(),
                ..Default::default()
            };
            // The two calls.
            let (mut f, mut se, mut pdf) =
                (vec![0.0f32; 3 * N], vec![0.0f32; 3 * N], vec![0.0f32; N]);
            let eval = StrataBatch {
                wi: aos(&wi),
                wo: aos(&wo),
                f: aos_out(&mut f),
                stderr: aos_out(&mut se),
                ..base
            };
            let pdfs = StrataBatch {
                wi: aos(&wi),
                wo: aos(&wo),
                pdf: pdf.as_mut_ptr(),
                keys: null(),
                ..base
            };
            // SAFETY: every array holds 3 N floats (N keys, N pdfs); the
            // columns N rows.
            unsafe {
                ok(strata_eval(b.0, &eval));
                ok(strata_pdf(b.0, &pdfs));
            }
            assert!(f.iter().any(|&x| x > 0.0) && pdf.iter().any(|&p| p > 0.0));

            // One call, AoS.
            let (mut f1, mut se1, mut p1) =
                (vec![-1.0f32; 3 * N], vec![-1.0f32; 3 * N], vec![-1.0f32; N]);
            let batch = StrataBatch {
                wi: aos(&wi),
                wo: aos(&wo),
                f: aos_out(&mut f1),
                stderr: aos_out(&mut se1),
                pdf: p1.as_mut_ptr(),
                ..base
            };
            // SAFETY: as above.
            ok(unsafe { strata_eval(b.0, &batch) });
            assert_eq!(bits(&f1), bits(&f), "f keyed={keyed}");
            assert_eq!(bits(&se1), bits(&se), "stderr keyed={keyed}");
            assert_eq!(bits(&p1), bits(&pdf), "pdf keyed={keyed}");

            // One call, SoA.
            let mut fs = [vec![0.0f32; N], vec![0.0; N], vec![0.0; N]];
            let mut ses = [vec![0.0f32; N], vec![0.0; N], vec![0.0; N]];
            let mut ps = vec![0.0f32; N];
            let batch = StrataBatch {
                wi: soa3(&wis),
                wo: soa3(&wos),
                f: soa3_out(&mut fs),
                stderr: soa3_out(&mut ses),
                pdf: ps.as_mut_ptr(),
                ..base
            };
            // SAFETY: every array holds N elements; the columns N rows.
            ok(unsafe { strata_eval(b.0, &batch) });
            assert_eq!(bits(&ps), bits(&pdf));
            for ch in 0..3 {
                assert_eq!(bits(&fs[ch]), bits(&soa(&f)[ch]));
                assert_eq!(bits(&ses[ch]), bits(&soa(&se)[ch]));
            }
        }
    }
}

/// Runs `strata_eval` on 3 queries with `cols`: the status and the
/// message, checking that `f` was not written.
fn eval_with(b: &Capi, cols: *const StrataColumn, ncolumns: usize) -> (i32, String) {
    let (wi, wo) = directions(3);
    let mut f = vec![-7.0f32; 3 * 3];
    let batch = StrataBatch {
        n: 3,
        wi: aos(&wi),
        wo: aos(&wo),
        columns: cols,
        ncolumns,
        f: aos_out(&mut f),
        ..Default::default()
    };
    // SAFETY: wi, wo, f hold at least 9 floats; `cols` is the test's.
    let status = unsafe { strata_eval(b.0, &batch) };
    if status != STRATA_OK {
        assert!(f.iter().all(|&x| x == -7.0), "f written on an error");
    }
    (status, last_error())
}

fn one(path: *const c_char, width: usize, values: *const f32) -> [StrataColumn; 1] {
    [StrataColumn {
        path,
        width,
        values,
    }]
}

fn contains_all(m: &str, parts: &[&str]) {
    for p in parts {
        assert!(m.contains(p), "{p:?} not in {m:?}");
    }
}

#[test]
fn bad_columns_are_errors_naming_the_column_query_path_and_value() {
    let b = Capi::toml(&template());
    let thickness = CString::new("layers[0].medium.thickness").unwrap();
    let good = [0.2f32, 0.3, 0.4];

    let (s, m) = eval_with(&b, null(), 2);
    assert_eq!(s, STRATA_ERR_NULL);
    assert_eq!(m, "strata_eval: columns is NULL (ncolumns = 2)");

    let c = [
        one(thickness.as_ptr(), 1, good.as_ptr())[0],
        one(null(), 1, good.as_ptr())[0],
    ];
    let (s, m) = eval_with(&b, c.as_ptr(), 2);
    assert_eq!(s, STRATA_ERR_NULL);
    assert_eq!(m, "strata_eval: columns[1].path is NULL");

    let c = one(thickness.as_ptr(), 1, null());
    let (s, m) = eval_with(&b, c.as_ptr(), 1);
    assert_eq!(s, STRATA_ERR_NULL);
    assert_eq!(m, "strata_eval: columns[0].values is NULL (n = 3)");

    let c = one(thickness.as_ptr(), 2, good.as_ptr());
    let (s, m) = eval_with(&b, c.as_ptr(), 1);
    assert_eq!(s, STRATA_ERR_INVALID_ARGUMENT);
    contains_all(&m, &["columns[0].width = 2", "layers[0].medium.thickness"]);

    let bad_utf8 = CString::new(&b"layers[0].medium.thick\xffness"[..]).unwrap();
    let c = one(bad_utf8.as_ptr(), 1, good.as_ptr());
    let (s, m) = eval_with(&b, c.as_ptr(), 1);
    assert_eq!(s, STRATA_ERR_INVALID_ARGUMENT);
    contains_all(&m, &["columns[0].path is not UTF-8"]);

    for (path, want) in [
        ("layers[0].interface.kind", "is not a numeric parameter"),
        ("layers[0].medium.thicknes", "unknown medium field"),
    ] {
        let p = CString::new(path).unwrap();
        let c = one(p.as_ptr(), 1, good.as_ptr());
        let (s, m) = eval_with(&b, c.as_ptr(), 1);
        assert_eq!(s, STRATA_ERR_INVALID_ARGUMENT, "{m}");
        contains_all(&m, &["columns[0]", path, want]);
    }

    // A path the material does not have: the column's fault, named as the
    // argument, not by its first query.
    let eta0 = CString::new("layers[0].interface.eta").unwrap();
    let c = one(eta0.as_ptr(), 1, good.as_ptr());
    let (s, m) = eval_with(&b, c.as_ptr(), 1);
    assert_eq!(s, STRATA_ERR_INVALID_ARGUMENT, "{m}");
    contains_all(&m, &["columns[0] (`layers[0].interface.eta`, width 1)"]);
    assert!(!m.contains("query"), "{m}");

    // An invalid value at query 2: the query, the path, the value, and
    // the layer and field of the invalid material.
    let bad = [0.2f32, 0.3, -0.5];
    let c = one(thickness.as_ptr(), 1, bad.as_ptr());
    let (s, m) = eval_with(&b, c.as_ptr(), 1);
    assert_eq!(s, STRATA_ERR_MATERIAL, "{m}");
    contains_all(
        &m,
        &[
            "query 2",
            "`layers[0].medium.thickness` = -0.5",
            "layer 0: medium.thickness",
        ],
    );

    // NaN at query 1, in the second column (a triple).
    let sigma = CString::new("layers[0].medium.sigma_t").unwrap();
    let triples = [1.0f32, 1.0, 1.0, 1.0, f32::NAN, 1.0, 1.0, 1.0, 1.0];
    let c = [
        one(thickness.as_ptr(), 1, good.as_ptr())[0],
        one(sigma.as_ptr(), 3, triples.as_ptr())[0],
    ];
    let (s, m) = eval_with(&b, c.as_ptr(), 2);
    assert_eq!(s, STRATA_ERR_INVALID_ARGUMENT, "{m}");
    contains_all(&m, &["query 1", "layers[0].medium.sigma_t", "NaN"]);

    // A triple where the field takes one or two numbers: the column's
    // width is at fault, whatever its values.
    let rough = CString::new("layers[1].interface.roughness").unwrap();
    let c = one(rough.as_ptr(), 3, triples.as_ptr());
    let (s, m) = eval_with(&b, c.as_ptr(), 1);
    assert_eq!(s, STRATA_ERR_INVALID_ARGUMENT, "{m}");
    contains_all(
        &m,
        &["columns[0] (`layers[1].interface.roughness`, width 3)"],
    );
    assert!(!m.contains("query"), "{m}");

    // The same path twice: the second is at fault.
    let c = [
        one(thickness.as_ptr(), 1, good.as_ptr())[0],
        one(thickness.as_ptr(), 1, good.as_ptr())[0],
    ];
    let (s, m) = eval_with(&b, c.as_ptr(), 2);
    assert_eq!(s, STRATA_ERR_INVALID_ARGUMENT, "{m}");
    contains_all(
        &m,
        &[
            "columns[1] (`layers[0].medium.thickness`, width 1)",
            "given twice",
        ],
    );
}

#[test]
fn every_columns_call_checks_its_columns_before_anything_runs() {
    let b = Capi::toml(&template());
    let thickness = CString::new("layers[0].medium.thickness").unwrap();
    let bad = [0.2f32, -1.0, 0.4];
    let c = one(thickness.as_ptr(), 1, bad.as_ptr());
    let (wi, wo) = directions(4);
    let (wp, op, cp) = (wi.as_ptr(), wo.as_ptr(), c.as_ptr());
    let keys = [1u64, 2, 3];
    // Outputs: 16 distinct float arrays of 9, 3 sample and 3 albedo records
    // and 3 flags, all filled with a sentinel.
    let mut o = vec![[-7.0f32; 9]; 16];
    let mut s = [StrataSample {
        pdf: -7.0,
        ..Default::default()
    }; 3];
    let mut a = [StrataAlbedo {
        reflected: [-7.0; 3],
        ..Default::default()
    }; 3];
    let mut flags = [7u32; 3];
    let p: Vec<*mut f32> = o.iter_mut().map(|x| x.as_mut_ptr()).collect();
    // SAFETY: every array holds 3 queries (9 floats for 3-vectors); the
    // SoA components are thirds of wi and wo; the outputs are distinct.
    let rec = |name: &'static str, status: i32| (name, status, last_error());
    let v3 = |p: *mut f32| StrataVectorsOut {
        xyz: p,
        ..Default::default()
    };
    let c3 = |x: *mut f32, y: *mut f32, z: *mut f32| StrataVectorsOut {
        x,
        y,
        z,
        ..Default::default()
    };
    let base = StrataBatch {
        n: 3,
        wi: StrataVectors {
            xyz: wp,
            ..Default::default()
        },
        columns: cp,
        ncolumns: 1,
        ..Default::default()
    };
    let pairs = StrataBatch {
        wo: StrataVectors {
            xyz: op,
            ..Default::default()
        },
        ..base
    };
    let mut cut = 7u64;
    let calls: Vec<(&str, i32, String)> = unsafe {
        let (wy, wz, oy, oz) = (wp.add(3), wp.add(6), op.add(3), op.add(6));
        let wi_soa = StrataVectors {
            x: wp,
            y: wy,
            z: wz,
            ..Default::default()
        };
        let wo_soa = StrataVectors {
            x: op,
            y: oy,
            z: oz,
            ..Default::default()
        };
        vec![
            rec(
                "strata_eval",
                strata_eval(
                    b.0,
                    &StrataBatch {
                        f: v3(p[0]),
                        stderr: v3(p[1]),
                        truncated: &mut cut,
                        ..pairs
                    },
                ),
            ),
            rec(
                "strata_eval",
                strata_eval(
                    b.0,
                    &StrataBatch {
                        keys: keys.as_ptr(),
                        f: v3(p[0]),
                        stderr: v3(p[1]),
                        ..pairs
                    },
                ),
            ),
            rec(
                "strata_eval",
                strata_eval(
                    b.0,
                    &StrataBatch {
                        wi: wi_soa,
                        wo: wo_soa,
                        f: c3(p[2], p[3], p[4]),
                        stderr: c3(p[5], p[6], p[7]),
                        ..base
                    },
                ),
            ),
            rec(
                "strata_sample",
                strata_sample(
                    b.0,
                    &StrataBatch {
                        sample: s.as_mut_ptr(),
                        ..base
                    },
                ),
            ),
            rec(
                "strata_sample",
                strata_sample(
                    b.0,
                    &StrataBatch {
                        wi: wi_soa,
                        keys: keys.as_ptr(),
                        sampled: c3(p[8], p[9], p[10]),
                        weight: c3(p[11], p[12], p[13]),
                        pdf: p[14],
                        flags: flags.as_mut_ptr(),
                        ..base
                    },
                ),
            ),
            rec(
                "strata_pdf",
                strata_pdf(
                    b.0,
                    &StrataBatch {
                        pdf: p[15],
                        ..pairs
                    },
                ),
            ),
            rec(
                "strata_pdf_unbiased",
                strata_pdf_unbiased(
                    b.0,
                    &StrataBatch {
                        walks: 8,
                        pdf: p[14],
                        pdf_stderr: p[15],
                        truncated: &mut cut,
                        ..pairs
                    },
                ),
            ),
            rec(
                "strata_albedo",
                strata_albedo(
                    b.0,
                    &StrataBatch {
                        walks: 8,
                        albedo: a.as_mut_ptr(),
                        truncated: &mut cut,
                        ..base
                    },
                ),
            ),
        ]
    };
    assert_eq!(cut, 7, "truncated was written");
    assert_eq!(calls.len(), 8);
    for (name, status, m) in calls {
        assert_eq!(status, STRATA_ERR_MATERIAL, "{name}: {m}");
        contains_all(
            &m,
            &[
                &format!("{name}: columns: query 1"),
                "`layers[0].medium.thickness` = -1",
                "layer 0: medium.thickness",
            ],
        );
    }
    assert!(
        o.iter().flatten().all(|&x| x == -7.0),
        "an output was written"
    );
    assert!(s.iter().all(|s| s.pdf == -7.0));
    assert!(a.iter().all(|a| a.reflected == [-7.0; 3]));
    assert_eq!(flags, [7; 3]);
}

#[test]
fn a_column_may_not_overlap_an_output_and_n_zero_does_nothing() {
    let b = Capi::toml(&template());
    let thickness = CString::new("layers[0].medium.thickness").unwrap();
    let (wi, wo) = directions(5);
    let mut f = [0.3f32; 9];
    let c = one(thickness.as_ptr(), 1, f.as_ptr());
    let mut batch = StrataBatch {
        n: 3,
        wi: aos(&wi),
        wo: aos(&wo),
        columns: c.as_ptr(),
        ncolumns: 1,
        f: aos_out(&mut f),
        ..Default::default()
    };
    // SAFETY: wi, wo, f hold 9 floats; the column's values are f's first 3
    // (an overlap the call refuses before making any slice of them).
    let status = unsafe { strata_eval(b.0, &batch) };
    assert_eq!(status, STRATA_ERR_INVALID_ARGUMENT);
    contains_all(&last_error(), &["f.xyz and columns[0].values overlap"]);
    assert_eq!(f, [0.3; 9]);

    // A batch too large to address: an error, not an overflow.
    let c = one(thickness.as_ptr(), 3, f.as_ptr());
    (batch.n, batch.columns) = (usize::MAX / 2, c.as_ptr());
    // SAFETY: the call fails on the columns' length before reading anything.
    let status = unsafe { strata_eval(b.0, &batch) };
    assert_eq!(status, STRATA_ERR_INVALID_ARGUMENT);
    contains_all(&last_error(), &["too large", "columns[0].values"]);

    // n = 0: nothing is read, whatever the columns.
    let c = one(null(), 5, null());
    let batch = StrataBatch {
        columns: c.as_ptr(),
        ncolumns: 1,
        ..Default::default()
    };
    // SAFETY: n = 0: no array is read.
    let status = unsafe { strata_eval(b.0, &batch) };
    assert_eq!(status, STRATA_OK, "{}", last_error());
    assert_eq!(last_error(), "");
}
