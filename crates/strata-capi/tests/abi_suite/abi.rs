//! The C ABI called as C calls it: the extern functions with raw pointers.
//! Its numbers are the Rust API's, bit for bit (same material, seed, walk
//! count and keys), in both layouts; `strata eval` and `strata sample` print
//! the same numbers; bad input is a negative status and a message naming the
//! query and the argument, never a crash.

use crate::common::batches::{Batches, Buffers};
use glam::Vec3;
use std::ffi::{CStr, CString};
use std::ptr::{null, null_mut};
use strata_bsdf::{
    AlbedoRecord, Estimator, EvalRecord, LayerStack, LayeredBsdf, PdfWalks, SampleRecord,
    Transport, Vectors, VectorsMut,
};
use strata_capi::*;

use crate::batch::{aos, aos_out, soa3, soa3_out};
use crate::common::{COATED_COPPER, SCATTERING_SLAB};
/// A rough dielectric slab with glass below: transmission between exteriors
/// of different IOR, where the transport mode matters.
const GLASS: &str = crate::common::ROUGH_GLASS;

/// A BSDF made through the C ABI, freed on drop.
struct Capi(*mut StrataBsdf);

impl Capi {
    fn toml(text: &str, samples: u64, seed: u64) -> Capi {
        let c = CString::new(text).unwrap();
        let mut b = null_mut();
        // SAFETY: `c` is NUL-terminated and `b` is a writable pointer.
        let status = unsafe { strata_bsdf_from_toml(c.as_ptr(), samples, seed, &mut b) };
        assert_eq!(status, STRATA_OK, "{}", last_error());
        assert!(!b.is_null());
        Capi(b)
    }
}

impl Drop for Capi {
    fn drop(&mut self) {
        // SAFETY: the pointer came from `strata_bsdf_from_toml` and is freed once.
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

fn rust(text: &str, samples: u64, seed: u64) -> LayeredBsdf {
    LayeredBsdf::new(LayerStack::from_toml_str(text).unwrap())
        .samples(samples)
        .seed(seed)
}

/// `n` directions spread over both hemispheres (not unit length: the ABI
/// normalizes them as the Rust API does), deterministic.
fn directions(n: usize, salt: u64, both_sides: bool) -> Vec<[f32; 3]> {
    let mut s = 0x9e37_79b9_7f4a_7c15u64 ^ salt;
    let mut next = || {
        s = s
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((s >> 40) as f32) / (1u64 << 24) as f32
    };
    (0..n)
        .map(|k| {
            let (x, y) = (2.0 * next() - 1.0, 2.0 * next() - 1.0);
            let z = 0.05 + next();
            let z = if both_sides && k % 3 == 2 { -z } else { z };
            [x, y, z]
        })
        .collect()
}

fn flat(v: &[[f32; 3]]) -> Vec<f32> {
    v.iter().flatten().copied().collect()
}

fn soa(v: &[[f32; 3]]) -> [Vec<f32>; 3] {
    [0, 1, 2].map(|c| v.iter().map(|d| d[c]).collect())
}

fn bits(v: &[f32]) -> Vec<u32> {
    v.iter().map(|x| x.to_bits()).collect()
}

/// 37 queries: not a multiple of the wavefront's 8 lanes.
const N: usize = 37;

#[test]
fn eval_is_the_rust_apis_bit_for_bit_in_both_layouts() {
    for (text, samples, seed) in [(COATED_COPPER, 64, 7), (GLASS, 1, 11), (GLASS, 200, 0)] {
        let c = Capi::toml(text, samples, seed);
        let r = rust(text, samples, seed);
        let wi = directions(N, 1, true);
        let wo = directions(N, 2, true);
        let keys: Vec<u64> = (0..N as u64).map(|k| k * 7919 + 3).collect();
        for keyed in [false, true] {
            let k = keyed.then_some(&keys[..]);
            let mut want = vec![EvalRecord::default(); N];
            r.eval_records(Vectors::Aos(&wi), Vectors::Aos(&wo), k, &mut want)
                .unwrap();
            let want_f: Vec<f32> = want.iter().flat_map(|e| e.f).collect();
            let want_se: Vec<f32> = want.iter().flat_map(|e| e.stderr).collect();
            assert!(want_f.iter().any(|&x| x > 0.0), "a nonzero BSDF");

            let (mut f, mut se) = (vec![-1.0f32; 3 * N], vec![-1.0f32; 3 * N]);
            let (wi_f, wo_f) = (flat(&wi), flat(&wo));
            let kp = if keyed { keys.as_ptr() } else { null() };
            let mut cut = u64::MAX;
            let batch = StrataBatch {
                n: N,
                wi: aos(&wi_f),
                wo: aos(&wo_f),
                keys: kp,
                f: aos_out(&mut f),
                stderr: aos_out(&mut se),
                truncated: &mut cut,
                ..Default::default()
            };
            // SAFETY: every array holds 3 N floats (N keys).
            let status = unsafe { strata_eval(c.0, &batch) };
            assert_eq!(status, STRATA_OK, "{}", last_error());
            assert_eq!(last_error(), "");
            assert_eq!(bits(&f), bits(&want_f));
            assert_eq!(bits(&se), bits(&want_se));
            assert_eq!(cut, 0, "no walk reaches the default limit");

            // Without the standard errors: the same f.
            let mut f2 = vec![0.0f32; 3 * N];
            let batch = StrataBatch {
                n: N,
                wi: aos(&wi_f),
                wo: aos(&wo_f),
                keys: kp,
                f: aos_out(&mut f2),
                ..Default::default()
            };
            // SAFETY: as above; stderr may be NULL.
            let status = unsafe { strata_eval(c.0, &batch) };
            assert_eq!(status, STRATA_OK);
            assert_eq!(bits(&f2), bits(&want_f));

            // SoA.
            let (wis, wos) = (soa(&wi), soa(&wo));
            let mut fs = [vec![0.0f32; N], vec![0.0; N], vec![0.0; N]];
            let mut ses = [vec![0.0f32; N], vec![0.0; N], vec![0.0; N]];
            let batch = StrataBatch {
                n: N,
                wi: soa3(&wis),
                wo: soa3(&wos),
                keys: kp,
                f: soa3_out(&mut fs),
                stderr: soa3_out(&mut ses),
                ..Default::default()
            };
            // SAFETY: every array holds N elements.
            let status = unsafe { strata_eval(c.0, &batch) };
            assert_eq!(status, STRATA_OK, "{}", last_error());
            for ch in 0..3 {
                let want_c: Vec<f32> = want.iter().map(|e| e.f[ch]).collect();
                let want_s: Vec<f32> = want.iter().map(|e| e.stderr[ch]).collect();
                assert_eq!(bits(&fs[ch]), bits(&want_c));
                assert_eq!(bits(&ses[ch]), bits(&want_s));
            }
        }
        // Unkeyed is the plain API's eval: keyed by the directions' bits.
        let single = r
            .eval(Vec3::from(wi[5]), Vec3::from(wo[5]))
            .unwrap()
            .value
            .map(|v| v as f32);
        let mut f = [0.0f32; 3];
        let batch = StrataBatch {
            n: 1,
            wi: aos(&wi[5]),
            wo: aos(&wo[5]),
            f: aos_out(&mut f),
            ..Default::default()
        };
        // SAFETY: one query: 3 floats each.
        let status = unsafe { strata_eval(c.0, &batch) };
        assert_eq!(status, STRATA_OK);
        assert_eq!(bits(&f), bits(&single));
    }
}

/// An eval given `pdf` (one library call, `eval_pdf_into`) answers bit for
/// bit what the eval without it and `strata_pdf` answer, and what the Rust
/// API's `eval_into` and `pdf_into` answer: in both layouts, keyed or not,
/// with or without `stderr`, under the lobe pdf and walked pdfs; its
/// `truncated` is the eval's count (a limit of events that ends walks).
#[test]
fn an_eval_with_pdf_is_eval_then_pdf_bit_for_bit() {
    let cases = [
        (COATED_COPPER, 64, 7, 0, 0),
        (GLASS, 1, 11, 4, 0),
        (SCATTERING_SLAB, 16, 4, 0, 3),
    ];
    for (text, samples, seed, pdf_samples, max_events) in cases {
        let c = Capi::toml(text, samples, seed);
        let mut r = rust(text, samples, seed);
        // SAFETY: `c.0` is a live BSDF used by this thread only.
        unsafe {
            if pdf_samples > 0 {
                assert_eq!(strata_bsdf_set_pdf_samples(c.0, pdf_samples), STRATA_OK);
                r = r.pdf_samples(pdf_samples);
            }
            if max_events > 0 {
                assert_eq!(strata_bsdf_set_max_events(c.0, max_events), STRATA_OK);
                r = r.max_events(max_events);
            }
        }
        let wi = directions(N, 31, true);
        let wo = directions(N, 32, true);
        let (wi_f, wo_f) = (flat(&wi), flat(&wo));
        let (wis, wos) = (soa(&wi), soa(&wo));
        let keys: Vec<u64> = (0..N as u64).map(|k| k * 131 + 9).collect();
        for keyed in [false, true] {
            let k = keyed.then_some(&keys[..]);
            let kp = if keyed { keys.as_ptr() } else { null() };
            // The Rust API's two calls.
            let (mut want_f, mut want_se) = (vec![[0.0f32; 3]; N], vec![[0.0f32; 3]; N]);
            let want_cut = r
                .eval_buffers(
                    Vectors::Aos(&wi),
                    Vectors::Aos(&wo),
                    k,
                    VectorsMut::Aos(&mut want_f),
                    Some(VectorsMut::Aos(&mut want_se)),
                )
                .unwrap();
            let mut want_pdf = vec![0.0f32; N];
            r.pdf_buffers(Vectors::Aos(&wi), Vectors::Aos(&wo), &mut want_pdf)
                .unwrap();
            let (want_f, want_se) = (flat(&want_f), flat(&want_se));
            assert!(want_pdf.iter().any(|&p| p > 0.0), "a nonzero pdf");
            assert_eq!(max_events > 0, want_cut > 0, "walks ended by the limit");

            // The C ABI's two calls.
            let (mut f2, mut p2) = (vec![0.0f32; 3 * N], vec![0.0f32; N]);
            let eval = StrataBatch {
                n: N,
                wi: aos(&wi_f),
                wo: aos(&wo_f),
                keys: kp,
                f: aos_out(&mut f2),
                ..Default::default()
            };
            let pdf = StrataBatch {
                n: N,
                wi: aos(&wi_f),
                wo: aos(&wo_f),
                pdf: p2.as_mut_ptr(),
                ..Default::default()
            };
            // SAFETY: every array holds 3 N floats (N keys, N pdfs).
            unsafe {
                assert_eq!(strata_eval(c.0, &eval), STRATA_OK, "{}", last_error());
                assert_eq!(strata_pdf(c.0, &pdf), STRATA_OK, "{}", last_error());
            }
            assert_eq!(bits(&f2), bits(&want_f));
            assert_eq!(bits(&p2), bits(&want_pdf));

            // One call, AoS, with and without the standard errors.
            for with_se in [true, false] {
                let (mut f, mut se, mut p) =
                    (vec![-1.0f32; 3 * N], vec![-1.0f32; 3 * N], vec![-1.0f32; N]);
                let mut cut = u64::MAX;
                let batch = StrataBatch {
                    n: N,
                    wi: aos(&wi_f),
                    wo: aos(&wo_f),
                    keys: kp,
                    f: aos_out(&mut f),
                    stderr: if with_se {
                        aos_out(&mut se)
                    } else {
                        Default::default()
                    },
                    pdf: p.as_mut_ptr(),
                    truncated: &mut cut,
                    ..Default::default()
                };
                // SAFETY: every array holds 3 N floats (N keys, N pdfs).
                let status = unsafe { strata_eval(c.0, &batch) };
                assert_eq!(status, STRATA_OK, "{}", last_error());
                assert_eq!(bits(&f), bits(&want_f), "{keyed} {with_se}");
                assert_eq!(bits(&p), bits(&want_pdf), "{keyed} {with_se}");
                if with_se {
                    assert_eq!(bits(&se), bits(&want_se));
                } else {
                    assert!(se.iter().all(|&x| x == -1.0));
                }
                assert_eq!(cut, want_cut, "the eval's count");
            }

            // One call, SoA.
            let mut fs = [vec![0.0f32; N], vec![0.0; N], vec![0.0; N]];
            let mut ses = [vec![0.0f32; N], vec![0.0; N], vec![0.0; N]];
            let mut p = vec![0.0f32; N];
            let batch = StrataBatch {
                n: N,
                wi: soa3(&wis),
                wo: soa3(&wos),
                keys: kp,
                f: soa3_out(&mut fs),
                stderr: soa3_out(&mut ses),
                pdf: p.as_mut_ptr(),
                ..Default::default()
            };
            // SAFETY: every array holds N elements.
            let status = unsafe { strata_eval(c.0, &batch) };
            assert_eq!(status, STRATA_OK, "{}", last_error());
            assert_eq!(bits(&p), bits(&want_pdf));
            let (want_fs, want_ses) = (soa(&triples(&want_f)), soa(&triples(&want_se)));
            for ch in 0..3 {
                assert_eq!(bits(&fs[ch]), bits(&want_fs[ch]));
                assert_eq!(bits(&ses[ch]), bits(&want_ses[ch]));
            }
        }
    }
}

fn triples(v: &[f32]) -> Vec<[f32; 3]> {
    v.chunks(3).map(|c| [c[0], c[1], c[2]]).collect()
}

#[test]
fn sample_is_the_rust_apis_bit_for_bit_in_both_layouts() {
    for (text, seed) in [(COATED_COPPER, 3), (GLASS, 4)] {
        let c = Capi::toml(text, 16, seed);
        let r = rust(text, 16, seed);
        let wi = directions(N, 3, true);
        let keys: Vec<u64> = (0..N as u64).map(|k| k ^ 0xabcdef).collect();
        for keyed in [false, true] {
            let k = keyed.then_some(&keys[..]);
            let mut want = vec![SampleRecord::default(); N];
            r.sample_records(Vectors::Aos(&wi), k, &mut want).unwrap();
            assert!(want.iter().any(|s| s.flags != 0 && s.pdf > 0.0));

            let wi_f = flat(&wi);
            let mut out = vec![StrataSample::default(); N];
            let kp = if keyed { keys.as_ptr() } else { null() };
            let batch = StrataBatch {
                n: N,
                wi: aos(&wi_f),
                keys: kp,
                sample: out.as_mut_ptr(),
                ..Default::default()
            };
            // SAFETY: wi holds 3 N floats, keys N, out N records.
            let status = unsafe { strata_sample(c.0, &batch) };
            assert_eq!(status, STRATA_OK, "{}", last_error());
            for (o, w) in out.iter().zip(&want) {
                assert_eq!(bits(&o.wo), bits(&w.wo));
                assert_eq!(bits(&o.weight), bits(&w.weight));
                assert_eq!(o.pdf.to_bits(), w.pdf.to_bits());
                assert_eq!(o.flags, w.flags);
            }

            // SoA.
            let wis = soa(&wi);
            let mut wo = [vec![0.0f32; N], vec![0.0; N], vec![0.0; N]];
            let mut weight = [vec![0.0f32; N], vec![0.0; N], vec![0.0; N]];
            let (mut pdf, mut flags) = (vec![0.0f32; N], vec![0u32; N]);
            let batch = StrataBatch {
                n: N,
                wi: soa3(&wis),
                keys: kp,
                sampled: soa3_out(&mut wo),
                weight: soa3_out(&mut weight),
                pdf: pdf.as_mut_ptr(),
                flags: flags.as_mut_ptr(),
                ..Default::default()
            };
            // SAFETY: every array holds N elements.
            let status = unsafe { strata_sample(c.0, &batch) };
            assert_eq!(status, STRATA_OK, "{}", last_error());
            for (i, w) in want.iter().enumerate() {
                for ch in 0..3 {
                    assert_eq!(wo[ch][i].to_bits(), w.wo[ch].to_bits());
                    assert_eq!(weight[ch][i].to_bits(), w.weight[ch].to_bits());
                }
                assert_eq!(pdf[i].to_bits(), w.pdf.to_bits());
                assert_eq!(flags[i], w.flags);
            }

            // The same through the Rust SoA slice call.
            let mut rwo = [vec![0.0f32; N], vec![0.0; N], vec![0.0; N]];
            let mut rweight = [vec![0.0f32; N], vec![0.0; N], vec![0.0; N]];
            let (mut rpdf, mut rflags) = (vec![0.0f32; N], vec![0u32; N]);
            let [a, b2, c2] = &mut rwo;
            let [d, e, f] = &mut rweight;
            r.sample_buffers(
                Vectors::Soa([&wis[0], &wis[1], &wis[2]]),
                k,
                VectorsMut::Soa([a, b2, c2]),
                VectorsMut::Soa([d, e, f]),
                &mut rpdf,
                &mut rflags,
            )
            .unwrap();
            assert_eq!(bits(&rpdf), bits(&pdf));
            assert_eq!(rflags, flags);
            assert_eq!(bits(&rwo[2]), bits(&wo[2]));
        }
    }
}

#[test]
fn the_unbiased_pdf_is_the_rust_apis() {
    let c = Capi::toml(COATED_COPPER, 16, 5);
    let r = rust(COATED_COPPER, 16, 5);
    let wi = directions(N, 6, false);
    let wo = directions(N, 7, false);
    let (wi_f, wo_f) = (flat(&wi), flat(&wo));
    let (mut pdf, mut se) = (vec![0.0f32; N], vec![0.0f32; N]);
    let mut cut = u64::MAX;
    let mut batch = StrataBatch {
        n: N,
        wi: aos(&wi_f),
        wo: aos(&wo_f),
        walks: 64,
        pdf: pdf.as_mut_ptr(),
        pdf_stderr: se.as_mut_ptr(),
        truncated: &mut cut,
        ..Default::default()
    };
    // SAFETY: wi, wo hold 3 N floats, pdf and se N each.
    let status = unsafe { strata_pdf_unbiased(c.0, &batch) };
    assert_eq!(status, STRATA_OK, "{}", last_error());
    assert_eq!(cut, 0);
    let (mut want, mut want_se) = (vec![0.0f32; N], vec![0.0f32; N]);
    r.pdf_unbiased_buffers(
        Vectors::Aos(&wi),
        Vectors::Aos(&wo),
        64,
        &mut want,
        &mut want_se,
    )
    .unwrap();
    assert_eq!(bits(&pdf), bits(&want));
    assert_eq!(bits(&se), bits(&want_se));
    assert!(pdf.iter().all(|&p| p >= 0.0 && p.is_finite()) && se.iter().any(|&s| s > 0.0));
    // No walks, and outputs that overlap, are errors naming the argument.
    batch.walks = 0;
    // SAFETY: as above.
    let status = unsafe { strata_pdf_unbiased(c.0, &batch) };
    assert_ne!(status, STRATA_OK);
    assert!(last_error().contains("walks = 0"), "{}", last_error());
    (batch.walks, batch.pdf_stderr) = (8, pdf.as_mut_ptr());
    // SAFETY: as above; one buffer as both outputs.
    let status = unsafe { strata_pdf_unbiased(c.0, &batch) };
    assert_ne!(status, STRATA_OK);
    assert!(last_error().contains("pdf_stderr"), "{}", last_error());
}

#[test]
fn a_samples_pdf_is_what_strata_pdf_gives_and_pdf_is_the_rust_apis() {
    let c = Capi::toml(COATED_COPPER, 16, 5);
    let r = rust(COATED_COPPER, 16, 5);
    let wi = directions(N, 4, false);
    let wo = directions(N, 5, false);
    let (wi_f, wo_f) = (flat(&wi), flat(&wo));
    let mut pdf = vec![0.0f32; N];
    let batch = StrataBatch {
        n: N,
        wi: aos(&wi_f),
        wo: aos(&wo_f),
        pdf: pdf.as_mut_ptr(),
        ..Default::default()
    };
    // SAFETY: wi, wo hold 3 N floats, pdf N.
    let status = unsafe { strata_pdf(c.0, &batch) };
    assert_eq!(status, STRATA_OK, "{}", last_error());
    let mut want = vec![0.0f32; N];
    r.pdf_buffers(Vectors::Aos(&wi), Vectors::Aos(&wo), &mut want)
        .unwrap();
    assert_eq!(bits(&pdf), bits(&want));
    assert!(pdf.iter().all(|&p| p > 0.0 && p.is_finite()));
    assert_eq!(
        pdf[9].to_bits(),
        r.pdf(Vec3::from(wi[9]), Vec3::from(wo[9]))
            .unwrap()
            .to_bits()
    );

    // Every sample's pdf is pdf(wi, its wo).
    let mut s = vec![StrataSample::default(); N];
    let batch = StrataBatch {
        n: N,
        wi: aos(&wi_f),
        sample: s.as_mut_ptr(),
        ..Default::default()
    };
    // SAFETY: wi holds 3 N floats, s N records.
    let status = unsafe { strata_sample(c.0, &batch) };
    assert_eq!(status, STRATA_OK);
    let mut checked = 0;
    for (k, s) in s.iter().enumerate().filter(|(_, s)| s.flags != 0) {
        let mut p = 0.0f32;
        let batch = StrataBatch {
            n: 1,
            wi: aos(&wi[k]),
            wo: aos(&s.wo),
            pdf: &mut p,
            ..Default::default()
        };
        // SAFETY: one query.
        let status = unsafe { strata_pdf(c.0, &batch) };
        assert_eq!(status, STRATA_OK);
        assert_eq!(p.to_bits(), s.pdf.to_bits(), "query {k}");
        checked += 1;
    }
    assert!(checked > N / 2, "{checked} samples not absorbed");
}

/// `strata_bsdf_set_pdf_samples` is the Rust API's `pdf_samples` (n ≥ 1)
/// and its default rule (n = 0), bit for bit, in the pdfs and in the pdfs
/// the samples carry; a fixed count differs from the default; NULL is an
/// error.
#[test]
fn pdf_samples_are_the_rust_apis() {
    let wi = directions(N, 6, false);
    let wo = directions(N, 7, false);
    let (wi_f, wo_f) = (flat(&wi), flat(&wo));
    let pdfs = |c: &Capi| {
        let mut pdf = vec![0.0f32; N];
        let batch = StrataBatch {
            n: N,
            wi: aos(&wi_f),
            wo: aos(&wo_f),
            pdf: pdf.as_mut_ptr(),
            ..Default::default()
        };
        // SAFETY: wi, wo hold 3 N floats, pdf N.
        let status = unsafe { strata_pdf(c.0, &batch) };
        assert_eq!(status, STRATA_OK, "{}", last_error());
        let mut s = vec![StrataSample::default(); N];
        let batch = StrataBatch {
            n: N,
            wi: aos(&wi_f),
            sample: s.as_mut_ptr(),
            ..Default::default()
        };
        // SAFETY: wi holds 3 N floats, s N records.
        let status = unsafe { strata_sample(c.0, &batch) };
        assert_eq!(status, STRATA_OK, "{}", last_error());
        (pdf, s.iter().map(|s| s.pdf.to_bits()).collect::<Vec<_>>())
    };
    let rust_pdfs = |r: &LayeredBsdf| {
        let mut pdf = vec![0.0f32; N];
        r.pdf_buffers(Vectors::Aos(&wi), Vectors::Aos(&wo), &mut pdf)
            .unwrap();
        let mut s = vec![SampleRecord::default(); N];
        r.sample_records(Vectors::Aos(&wi), None, &mut s).unwrap();
        (pdf, s.iter().map(|s| s.pdf.to_bits()).collect::<Vec<_>>())
    };
    let mut seen = vec![];
    for n in [STRATA_PDF_SAMPLES_RULE, 1, 3, 40] {
        let c = Capi::toml(COATED_COPPER, 16, 5);
        // SAFETY: `c.0` is a live BSDF used by this thread only. A count
        // set first must not survive the rule.
        assert_eq!(unsafe { strata_bsdf_set_pdf_samples(c.0, 7) }, STRATA_OK);
        assert_eq!(unsafe { strata_bsdf_set_pdf_samples(c.0, n) }, STRATA_OK);
        let r = match n {
            0 => rust(COATED_COPPER, 16, 5),
            n => rust(COATED_COPPER, 16, 5).pdf_samples(n),
        };
        let (pdf, carried) = pdfs(&c);
        let (want, want_carried) = rust_pdfs(&r);
        assert_eq!(bits(&pdf), bits(&want), "n = {n}");
        assert_eq!(carried, want_carried, "n = {n}");
        assert!(pdf.iter().all(|&p| p > 0.0 && p.is_finite()), "n = {n}");
        seen.push(bits(&pdf));
    }
    // The default is the lobe pdf, not a fixed count; counts differ.
    let fresh = Capi::toml(COATED_COPPER, 16, 5);
    assert_eq!(bits(&pdfs(&fresh).0), seen[0]);
    for (k, n) in [1, 3, 40].into_iter().enumerate() {
        assert_ne!(seen[0], seen[k + 1], "the rule and {n} walks");
    }
    // SAFETY: NULL is an error, not a dereference.
    assert_eq!(
        unsafe { strata_bsdf_set_pdf_samples(null_mut(), 4) },
        STRATA_ERR_NULL
    );
    assert_eq!(last_error(), "strata_bsdf_set_pdf_samples: b is NULL");

    // An adaptive rule is the Rust API's: ADAPTIVE's parameters give
    // ADAPTIVE, TIGHT's give TIGHT; none is the default (the lobe pdf).
    for (pilot, max, rel, rule) in [
        (8, 64, 0.15, PdfWalks::ADAPTIVE),
        (8, 128, 0.1, PdfWalks::TIGHT),
        (4, 24, 0.3, PdfWalks::adaptive(4, 24, 0.3)),
    ] {
        let c = Capi::toml(COATED_COPPER, 16, 5);
        // SAFETY: `c.0` is a live BSDF used by this thread only. A count
        // set first must not survive the rule.
        assert_eq!(unsafe { strata_bsdf_set_pdf_samples(c.0, 7) }, STRATA_OK);
        let status = unsafe { strata_bsdf_set_pdf_walks(c.0, pilot, max, rel) };
        assert_eq!(status, STRATA_OK, "{}", last_error());
        let (pdf, carried) = pdfs(&c);
        let (want, want_carried) = rust_pdfs(&rust(COATED_COPPER, 16, 5).pdf_walks(rule));
        assert_eq!(bits(&pdf), bits(&want), "{rule}");
        assert_eq!(carried, want_carried, "{rule}");
        assert_ne!(bits(&pdf), seen[0], "{rule}");
    }
    // A bad rule names the argument and its value and changes nothing.
    let c = Capi::toml(COATED_COPPER, 16, 5);
    // SAFETY: as above.
    assert_eq!(unsafe { strata_bsdf_set_pdf_samples(c.0, 3) }, STRATA_OK);
    for (pilot, max, rel, message) in [
        (1, 64, 0.1, "pilot = 1: expected 2 to"),
        (0, 64, 0.1, "pilot = 0"),
        (8, 4, 0.1, "max = 4: expected pilot (8) to"),
        (8, 64, 0.0, "rel_stderr = 0: expected a positive"),
        (8, 64, -0.5, "rel_stderr = -0.5"),
        (8, 64, f64::NAN, "rel_stderr = NaN"),
        (8, 64, f64::INFINITY, "rel_stderr = inf"),
    ] {
        // SAFETY: as above.
        let status = unsafe { strata_bsdf_set_pdf_walks(c.0, pilot, max, rel) };
        assert_eq!(status, STRATA_ERR_INVALID_ARGUMENT, "{message}");
        let e = last_error();
        assert!(
            e.starts_with("strata_bsdf_set_pdf_walks: ") && e.contains(message),
            "{e}"
        );
    }
    assert_eq!(bits(&pdfs(&c).0), seen[2], "a bad rule changed the BSDF");
    // SAFETY: NULL is an error, not a dereference.
    assert_eq!(
        unsafe { strata_bsdf_set_pdf_walks(null_mut(), 8, 64, 0.15) },
        STRATA_ERR_NULL
    );
    assert_eq!(last_error(), "strata_bsdf_set_pdf_walks: b is NULL");
}

#[test]
fn albedo_is_the_rust_apis_bit_for_bit() {
    let c = Capi::toml(GLASS, 16, 9);
    let r = rust(GLASS, 16, 9);
    let wi = directions(N, 6, true);
    let wi_f = flat(&wi);
    let keys: Vec<u64> = (100..100 + N as u64).collect();
    for keyed in [false, true] {
        let k = keyed.then_some(&keys[..]);
        let mut want = vec![AlbedoRecord::default(); N];
        r.albedo_records(Vectors::Aos(&wi), 300, k, &mut want)
            .unwrap();
        let mut out = vec![StrataAlbedo::default(); N];
        let kp = if keyed { keys.as_ptr() } else { null() };
        let mut cut = u64::MAX;
        let batch = StrataBatch {
            n: N,
            wi: aos(&wi_f),
            walks: 300,
            keys: kp,
            albedo: out.as_mut_ptr(),
            truncated: &mut cut,
            ..Default::default()
        };
        // SAFETY: wi holds 3 N floats, keys N, out N records.
        let status = unsafe { strata_albedo(c.0, &batch) };
        assert_eq!(status, STRATA_OK, "{}", last_error());
        assert_eq!(cut, 0);
        for ((o, w), d) in out.iter().zip(&want).zip(&wi) {
            assert_eq!(bits(&o.reflected), bits(&w.reflected));
            assert_eq!(bits(&o.transmitted), bits(&w.transmitted));
            assert_eq!(bits(&o.reflected_stderr), bits(&w.reflected_stderr));
            assert_eq!(bits(&o.transmitted_stderr), bits(&w.transmitted_stderr));
            // Glass seen from the air transmits most light.
            assert!(o.transmitted[0] > 0.0 && o.reflected[0] > 0.0, "{o:?}");
            if d[2] > 0.0 {
                assert!(o.transmitted[0] > o.reflected[0], "{o:?}");
            }
        }
    }
}

#[test]
fn importance_transport_is_the_rust_apis_and_changes_transmission_only() {
    let c = Capi::toml(GLASS, 64, 2);
    let r = rust(GLASS, 64, 2).transport(Transport::Importance);
    // SAFETY: `c.0` is a live BSDF used by this thread only.
    assert_eq!(
        unsafe { strata_bsdf_set_transport(c.0, STRATA_TRANSPORT_IMPORTANCE) },
        STRATA_OK
    );
    let wi = [[0.2f32, 0.1, 0.9], [0.2, 0.1, 0.9]];
    let wo = [[-0.3f32, 0.0, -0.8], [-0.3, 0.0, 0.8]]; // transmission, reflection
    let mut want = vec![EvalRecord::default(); 2];
    r.eval_records(Vectors::Aos(&wi), Vectors::Aos(&wo), None, &mut want)
        .unwrap();
    let mut f = [0.0f32; 6];
    let (wi_f, wo_f) = (flat(&wi), flat(&wo));
    let eval = |b: *mut StrataBsdf, f: &mut [f32; 6]| {
        let batch = StrataBatch {
            n: 2,
            wi: aos(&wi_f),
            wo: aos(&wo_f),
            f: aos_out(f),
            ..Default::default()
        };
        // SAFETY: two queries: 6 floats each.
        unsafe { strata_eval(b, &batch) }
    };
    assert_eq!(eval(c.0, &mut f), STRATA_OK);
    assert_eq!(bits(&f[..3]), bits(&want[0].f));
    assert_eq!(bits(&f[3..]), bits(&want[1].f));
    // Back to radiance: transmission from air into glass gains (1.5/1)^2.
    // SAFETY: as above.
    assert_eq!(
        unsafe { strata_bsdf_set_transport(c.0, STRATA_TRANSPORT_RADIANCE) },
        STRATA_OK
    );
    let mut g = [0.0f32; 6];
    assert_eq!(eval(c.0, &mut g), STRATA_OK);
    assert!(f[0] > 0.0);
    assert!((g[0] / f[0] - 2.25).abs() < 1e-5, "{} / {}", g[0], f[0]);
    assert_eq!(bits(&g[3..]), bits(&f[3..]), "reflection is reciprocal");
    // An unknown mode changes nothing and says so.
    // SAFETY: as above.
    assert_eq!(
        unsafe { strata_bsdf_set_transport(c.0, 2) },
        STRATA_ERR_INVALID_ARGUMENT
    );
    assert_eq!(
        last_error(),
        "strata_bsdf_set_transport: mode = 2: expected 0 (STRATA_TRANSPORT_RADIANCE) or 1 \
         (STRATA_TRANSPORT_IMPORTANCE)"
    );
    let mut h = [0.0f32; 6];
    assert_eq!(eval(c.0, &mut h), STRATA_OK);
    assert_eq!(bits(&h), bits(&g));
}

#[test]
fn json_and_path_give_the_tomls_bsdf() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples/materials/");
    let json = std::fs::read_to_string(format!("{dir}coated_copper.json")).unwrap();
    let from_toml = Capi::toml(COATED_COPPER, 32, 1);
    let mut from_json = null_mut();
    let mut from_path = null_mut();
    let (j, p) = (
        CString::new(json).unwrap(),
        CString::new(format!("{dir}coated_copper.toml")).unwrap(),
    );
    // SAFETY: NUL-terminated strings and writable out pointers.
    unsafe {
        assert_eq!(
            strata_bsdf_from_json(j.as_ptr(), 32, 1, &mut from_json),
            STRATA_OK
        );
        assert_eq!(
            strata_bsdf_from_path(p.as_ptr(), 32, 1, &mut from_path),
            STRATA_OK
        );
    }
    let (from_json, from_path) = (Capi(from_json), Capi(from_path));
    let wi = flat(&directions(9, 7, false));
    let wo = flat(&directions(9, 8, false));
    let mut results = vec![];
    for b in [&from_toml, &from_json, &from_path] {
        let mut f = vec![0.0f32; 27];
        let batch = StrataBatch {
            n: 9,
            wi: aos(&wi),
            wo: aos(&wo),
            f: aos_out(&mut f),
            ..Default::default()
        };
        // SAFETY: 9 queries: 27 floats each.
        let s = unsafe { strata_eval(b.0, &batch) };
        assert_eq!(s, STRATA_OK);
        results.push(bits(&f));
    }
    assert!(results[0].iter().any(|&x| x != 0));
    assert_eq!(results[0], results[1]);
    assert_eq!(results[0], results[2]);
}

/// The newest modification time of the files under `dir`.
fn newest(dir: &std::path::Path) -> std::time::SystemTime {
    let mut t = std::time::SystemTime::UNIX_EPOCH;
    for e in std::fs::read_dir(dir).unwrap().flatten() {
        let m = e.metadata().unwrap();
        let u = if m.is_dir() {
            newest(&e.path())
        } else {
            m.modified().unwrap()
        };
        t = t.max(u);
    }
    t
}

/// The `strata` binary of this build profile and target directory. The
/// workspace's `cargo test` (as CI runs it) has just built it; if it is
/// missing or older than the sources it is built from (this crate's tests
/// run alone), it is built here.
fn strata_cli() -> std::path::PathBuf {
    static BIN: std::sync::OnceLock<std::path::PathBuf> = std::sync::OnceLock::new();
    BIN.get_or_init(|| {
        let exe = std::env::current_exe().unwrap();
        let profile_dir = exe.parent().unwrap().parent().unwrap().to_path_buf();
        let bin = profile_dir.join("strata");
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        let sources = [
            "crates/strata-bsdf",
            "crates/strata-cli",
            "crates/strata-reports",
        ]
        .iter()
        .map(|c| newest(&root.join(c)))
        .max()
        .unwrap();
        let fresh = std::fs::metadata(&bin)
            .and_then(|m| m.modified())
            .is_ok_and(|t| t >= sources);
        if !fresh {
            let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
            let mut cmd = std::process::Command::new(cargo);
            cmd.args(["build", "--quiet", "-p", "strata-cli", "--bin", "strata"]);
            if profile_dir.file_name().unwrap() == "release" {
                cmd.arg("--release");
            }
            cmd.env("CARGO_TARGET_DIR", profile_dir.parent().unwrap());
            let status = cmd.status().unwrap();
            assert!(status.success(), "cargo build of strata-cli failed");
        }
        assert!(bin.exists(), "{} missing", bin.display());
        bin
    })
    .clone()
}

fn run_cli(args: &[&str], stdin: &str) -> String {
    use std::io::Write;
    use std::process::{Command, Stdio};
    let mut child = Command::new(strata_cli())
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child
        .stdin
        .take()
        .unwrap()
        .write_all(stdin.as_bytes())
        .unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(
        out.status.success(),
        "strata {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

/// `strata eval` keys each query by its directions, as unkeyed C calls do:
/// they give its f and stderr (printed as f64; the ABI's f32 are their
/// casts) and its pdf, exactly.
#[test]
fn unkeyed_eval_and_pdf_are_what_strata_eval_prints() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../examples/materials/coated_copper.toml"
    );
    let n = 12;
    // Unit vectors that normalization leaves as they are, printed exactly
    // (as f64): the CLI evaluates these very vectors whether it normalizes
    // the components it reads or takes them as given.
    let unit = |v: [f32; 3]| {
        let mut u = Vec3::from(v);
        for _ in 0..8 {
            let next = strata_bsdf::Direction::new("v", u).unwrap().to_vec3();
            if next == u {
                return Some(u.to_array());
            }
            u = next;
        }
        None
    };
    let fixed = |salt| -> Vec<[f32; 3]> {
        directions(4 * n, salt, false)
            .into_iter()
            .filter_map(unit)
            .take(n)
            .collect()
    };
    let (wi_cli, wo_cli) = (fixed(10), fixed(11));
    assert_eq!((wi_cli.len(), wo_cli.len()), (n, n));
    let mut input = String::new();
    for k in 0..n {
        let (a, b) = (wi_cli[k].map(f64::from), wo_cli[k].map(f64::from));
        let line = format!(
            "{{\"wi\":[{},{},{}],\"wo\":[{},{},{}]}}",
            a[0], a[1], a[2], b[0], b[1], b[2]
        );
        let (pa, pb) = strata_bsdf::query::parse_query_line(&line).unwrap();
        assert_eq!(
            (pa.to_vec3().to_array(), pb.to_vec3().to_array()),
            (wi_cli[k], wo_cli[k])
        );
        input.push_str(&line);
        input.push('\n');
    }
    let printed = run_cli(
        &[
            "eval",
            "--material",
            path,
            "--samples",
            "48",
            "--seed",
            "13",
        ],
        &input,
    );
    let lines: Vec<serde_json::Value> = printed
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), n);

    let c = Capi::toml(COATED_COPPER, 48, 13);
    let (wi_f, wo_f) = (flat(&wi_cli), flat(&wo_cli));
    let (mut f, mut se, mut pdf) = (vec![0.0f32; 3 * n], vec![0.0f32; 3 * n], vec![0.0f32; n]);
    let mut pdf2 = vec![0.0f32; n];
    let eval = StrataBatch {
        n,
        wi: aos(&wi_f),
        wo: aos(&wo_f),
        f: aos_out(&mut f),
        stderr: aos_out(&mut se),
        pdf: pdf2.as_mut_ptr(),
        ..Default::default()
    };
    let pdfs = StrataBatch {
        n,
        wi: aos(&wi_f),
        wo: aos(&wo_f),
        pdf: pdf.as_mut_ptr(),
        ..Default::default()
    };
    // SAFETY: 3 n floats each, n pdfs.
    unsafe {
        let s = strata_eval(c.0, &eval);
        assert_eq!(s, STRATA_OK, "{}", last_error());
        let s = strata_pdf(c.0, &pdfs);
        assert_eq!(s, STRATA_OK);
    }
    // An eval that asks for the pdf too gives strata_pdf's.
    assert_eq!(bits(&pdf2), bits(&pdf));
    for (k, line) in lines.iter().enumerate() {
        for ch in 0..3 {
            let cli_f = line["f"][ch].as_f64().unwrap() as f32;
            let cli_se = line["stderr"][ch].as_f64().unwrap() as f32;
            assert_eq!(f[3 * k + ch].to_bits(), cli_f.to_bits(), "query {k}");
            assert_eq!(se[3 * k + ch].to_bits(), cli_se.to_bits(), "query {k}");
        }
        assert!(f[3 * k] > 0.0);
        let cli_pdf = line["pdf"].as_f64().unwrap() as f32;
        assert_eq!(pdf[k].to_bits(), cli_pdf.to_bits(), "query {k}");
    }
    // Keyed calls draw other streams.
    let keys: Vec<u64> = (0..n as u64).collect();
    let mut g = vec![0.0f32; 3 * n];
    let batch = StrataBatch {
        n,
        wi: aos(&wi_f),
        wo: aos(&wo_f),
        keys: keys.as_ptr(),
        f: aos_out(&mut g),
        ..Default::default()
    };
    // SAFETY: 3 n floats each, n keys.
    let s = unsafe { strata_eval(c.0, &batch) };
    assert_eq!(s, STRATA_OK);
    assert_ne!(bits(&g), bits(&f));
}

/// `strata sample --count n` draws sample index k for line k, as an unkeyed
/// C sample batch of n copies of wi does.
#[test]
fn unkeyed_samples_are_what_strata_sample_prints() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../examples/materials/coated_copper.toml"
    );
    let n = 20;
    let printed = run_cli(
        &[
            "sample",
            "--material",
            path,
            "--wi",
            "0.3,0,0.9",
            "--count",
            "20",
            "--seed",
            "4",
        ],
        "",
    );
    let lines: Vec<serde_json::Value> = printed
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), n);
    // The CLI samples from the direction it parsed, as given (not
    // normalized): 0.3, 0, 0.9 in f32.
    let wi: Vec<f32> = (0..n).flat_map(|_| [0.3f32, 0.0, 0.9]).collect();
    let c = Capi::toml(COATED_COPPER, 1, 4);
    let mut s = vec![StrataSample::default(); n];
    let batch = StrataBatch {
        n,
        wi: aos(&wi),
        sample: s.as_mut_ptr(),
        ..Default::default()
    };
    // SAFETY: 3 n floats, n records.
    let status = unsafe { strata_sample(c.0, &batch) };
    assert_eq!(status, STRATA_OK);
    let mut seen = 0;
    for (k, (line, s)) in lines.iter().zip(&s).enumerate() {
        for ch in 0..3 {
            let w = line["weight"][ch].as_f64().unwrap() as f32;
            assert_eq!(s.weight[ch].to_bits(), w.to_bits(), "sample {k}");
        }
        if line["wo"].is_null() {
            assert_eq!(s.flags, 0);
        } else {
            seen += 1;
            for ch in 0..3 {
                let w = line["wo"][ch].as_f64().unwrap() as f32;
                assert_eq!(s.wo[ch].to_bits(), w.to_bits(), "sample {k}");
            }
            assert_eq!(
                s.flags & STRATA_SAMPLE_REFLECTION != 0,
                line["reflection"].as_bool().unwrap()
            );
            assert_eq!(
                s.flags & STRATA_SAMPLE_DELTA != 0,
                line["specular"].as_bool().unwrap()
            );
            // A CLI that prints the sample's pdf prints the C sample's.
            if let Some(p) = line.get("pdf") {
                assert_eq!(s.pdf.to_bits(), (p.as_f64().unwrap() as f32).to_bits());
            }
        }
    }
    assert!(seen > 0);
}

#[test]
fn info_describes_the_stack() {
    let mut info = StrataStackInfo::default();
    let copper = Capi::toml(COATED_COPPER, 1, 0);
    // SAFETY: live BSDFs and a writable record.
    unsafe {
        assert_eq!(strata_bsdf_info(copper.0, &mut info), STRATA_OK);
        assert_eq!(
            info,
            StrataStackInfo {
                ior_above: 1.0,
                ior_below: 1.5,
                transmissive: 0,
                two_sided: 0,
                // A rough coat over an absorber over rough copper.
                lobes: STRATA_LOBE_GLOSSY,
            }
        );
        let glass = Capi::toml(&format!("exterior_ior = 1.33\n{GLASS}"), 1, 0);
        assert_eq!(strata_bsdf_info(glass.0, &mut info), STRATA_OK);
        assert_eq!(
            (
                info.ior_above,
                info.ior_below,
                info.transmissive,
                info.lobes
            ),
            (1.33, 1.5, 1, STRATA_LOBE_GLOSSY | STRATA_LOBE_TRANSMISSION)
        );
        let smooth = Capi::toml(crate::common::SMOOTH_COAT_WHITE, 1, 0);
        assert_eq!(strata_bsdf_info(smooth.0, &mut info), STRATA_OK);
        assert_eq!(
            info.lobes,
            STRATA_LOBE_DELTA_REFLECTION | STRATA_LOBE_DIFFUSE
        );
        let window = Capi::toml(
            "[[layers]]\ninterface = { kind = \"dielectric\", ior = 1.5 }\n",
            1,
            0,
        );
        assert_eq!(strata_bsdf_info(window.0, &mut info), STRATA_OK);
        let all_delta = STRATA_LOBE_DELTA_REFLECTION | STRATA_LOBE_DELTA_TRANSMISSION;
        assert_eq!(info.lobes, all_delta | STRATA_LOBE_TRANSMISSION);
        assert_eq!(strata_bsdf_info(glass.0, null_mut()), STRATA_ERR_NULL);
        assert_eq!(last_error(), "strata_bsdf_info: out is NULL");
        assert_eq!(strata_bsdf_info(null(), &mut info), STRATA_ERR_NULL);
    }
}

/// `strata_bsdf_is_exact` is the Rust API's `sample_is_exact`: the closed
/// form under `Auto` on a smooth coat over a Lambertian base, walks under
/// the unidirectional estimator and on other stacks; NULLs are errors.
#[test]
fn exactness_is_the_rust_apis() {
    let clear = include_str!("../../../../examples/materials/clear_coat_lambertian.toml");
    let mut exact = 7u32;
    // SAFETY: live BSDFs used by this thread only, and a writable word.
    unsafe {
        let c = Capi::toml(clear, 16, 0);
        assert!(rust(clear, 16, 0).sample_is_exact());
        assert_eq!(strata_bsdf_is_exact(c.0, &mut exact), STRATA_OK);
        assert_eq!(exact, 1);
        let code = STRATA_ESTIMATOR_UNIDIRECTIONAL;
        assert_eq!(strata_bsdf_set_estimator(c.0, code), STRATA_OK);
        assert_eq!(strata_bsdf_is_exact(c.0, &mut exact), STRATA_OK);
        assert_eq!(exact, 0);
        let copper = Capi::toml(COATED_COPPER, 16, 0);
        assert!(!rust(COATED_COPPER, 16, 0).sample_is_exact());
        exact = 7;
        assert_eq!(strata_bsdf_is_exact(copper.0, &mut exact), STRATA_OK);
        assert_eq!(exact, 0);
        assert_eq!(strata_bsdf_is_exact(copper.0, null_mut()), STRATA_ERR_NULL);
        assert_eq!(last_error(), "strata_bsdf_is_exact: out is NULL");
        assert_eq!(strata_bsdf_is_exact(null(), &mut exact), STRATA_ERR_NULL);
    }
}

/// `strata_bsdf_eval_without_walks` is the Rust API's
/// `eval_without_walks`: the closed form and a rough coat's factorization
/// under `Auto`, walks under the unidirectional estimator and on other
/// stacks; NULLs are errors; eval through C is the Rust eval bit for bit.
#[test]
fn eval_without_walks_is_the_rust_apis() {
    let clear = include_str!("../../../../examples/materials/clear_coat_lambertian.toml");
    let rough = r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5, roughness = 0.2 }
        medium = { thickness = 0.1, sigma_t = 1.0, albedo = 0.0 }
        [[layers]]
        interface = { kind = "diffuse", albedo = 0.6 }
    "#;
    let mut without = 7u32;
    // SAFETY: live BSDFs used by this thread only, and writable memory.
    unsafe {
        for (toml, want) in [(clear, 1), (rough, 1), (COATED_COPPER, 0)] {
            let c = Capi::toml(toml, 16, 0);
            assert_eq!(rust(toml, 16, 0).eval_without_walks(), want == 1);
            assert_eq!(strata_bsdf_eval_without_walks(c.0, &mut without), STRATA_OK);
            assert_eq!(without, want);
            // Sampled without walks too, with an exact pdf.
            let mut exact = 7u32;
            assert_eq!(strata_bsdf_is_exact(c.0, &mut exact), STRATA_OK);
            assert_eq!(exact, want);
            let code = STRATA_ESTIMATOR_UNIDIRECTIONAL;
            assert_eq!(strata_bsdf_set_estimator(c.0, code), STRATA_OK);
            assert_eq!(strata_bsdf_eval_without_walks(c.0, &mut without), STRATA_OK);
            assert_eq!(without, 0);
        }
        let c = Capi::toml(rough, 16, 0);
        let (wi, wo) = ([0.3f32, 0.1, 0.9], [-0.5f32, 0.2, 0.8]);
        let (mut f, mut se) = ([0f32; 3], [0f32; 3]);
        let batch = StrataBatch {
            n: 1,
            wi: aos(&wi),
            wo: aos(&wo),
            f: aos_out(&mut f),
            stderr: aos_out(&mut se),
            ..Default::default()
        };
        let code = strata_eval(c.0, &batch);
        assert_eq!(code, STRATA_OK);
        let want = rust(rough, 16, 0)
            .eval(glam::Vec3::from(wi), glam::Vec3::from(wo))
            .unwrap();
        assert_eq!(f, want.value.map(|x| x as f32));
        assert!(se.iter().all(|&s| s > 0.0), "sampled, not exact");
        assert_eq!(
            strata_bsdf_eval_without_walks(c.0, null_mut()),
            STRATA_ERR_NULL
        );
        assert_eq!(last_error(), "strata_bsdf_eval_without_walks: out is NULL");
        assert_eq!(
            strata_bsdf_eval_without_walks(null(), &mut without),
            STRATA_ERR_NULL
        );
    }
}

#[test]
fn the_estimator_is_the_rust_apis() {
    // Three interfaces: `Auto` runs the bidirectional estimator there.
    let three = r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5, roughness = 0.2 }
        [[layers]]
        interface = { kind = "dielectric", ior = 1.8, roughness = 0.3 }
        [[layers]]
        interface = { kind = "diffuse", albedo = 0.7 }
    "#;
    let wi = [[0.2f32, 0.1, 0.9], [0.5, 0.0, 0.6]];
    let wo = [[-0.3f32, 0.0, 0.8], [0.0, 0.4, 0.7]];
    for (code, est) in [
        (STRATA_ESTIMATOR_AUTO, Estimator::Auto),
        (STRATA_ESTIMATOR_UNIDIRECTIONAL, Estimator::Unidirectional),
        (STRATA_ESTIMATOR_BIDIRECTIONAL, Estimator::Bidirectional),
    ] {
        let c = Capi::toml(three, 64, 3);
        // SAFETY: `c.0` is a live BSDF used by this thread only.
        assert_eq!(unsafe { strata_bsdf_set_estimator(c.0, code) }, STRATA_OK);
        let r = rust(three, 64, 3).estimator(est);
        let mut want = vec![EvalRecord::default(); 2];
        r.eval_records(Vectors::Aos(&wi), Vectors::Aos(&wo), None, &mut want)
            .unwrap();
        let mut f = [0.0f32; 6];
        let (wi_f, wo_f) = (flat(&wi), flat(&wo));
        let batch = StrataBatch {
            n: 2,
            wi: aos(&wi_f),
            wo: aos(&wo_f),
            f: aos_out(&mut f),
            ..Default::default()
        };
        // SAFETY: two queries: 6 floats each.
        let status = unsafe { strata_eval(c.0, &batch) };
        assert_eq!(status, STRATA_OK);
        assert_eq!(bits(&f[..3]), bits(&want[0].f), "{est:?}");
        assert_eq!(bits(&f[3..]), bits(&want[1].f), "{est:?}");
    }
    let c = Capi::toml(three, 64, 3);
    // SAFETY: as above.
    assert_eq!(
        unsafe { strata_bsdf_set_estimator(c.0, 3) },
        STRATA_ERR_INVALID_ARGUMENT
    );
    assert_eq!(
        last_error(),
        "strata_bsdf_set_estimator: estimator = 3: expected 0 (STRATA_ESTIMATOR_AUTO), 1 \
         (STRATA_ESTIMATOR_UNIDIRECTIONAL) or 2 (STRATA_ESTIMATOR_BIDIRECTIONAL)"
    );
}

/// `strata_bsdf_set_max_events` is the Rust API's `max_events`: the same
/// albedos bit for bit (and, at 3 events, less reflected light than the
/// default's on a scattering slab); a limit outside 1..=2^24 is an error
/// naming it that leaves the BSDF as it was.
#[test]
fn max_events_is_the_rust_apis() {
    let albedo = |c: &Capi| {
        let wi = flat(&directions(N, 3, false));
        let mut out = vec![StrataAlbedo::default(); N];
        let batch = StrataBatch {
            n: N,
            wi: aos(&wi),
            walks: 400,
            albedo: out.as_mut_ptr(),
            ..Default::default()
        };
        // SAFETY: wi holds 3 N floats, out N records.
        let status = unsafe { strata_albedo(c.0, &batch) };
        assert_eq!(status, STRATA_OK, "{}", last_error());
        out.iter().map(|a| a.reflected[0]).collect::<Vec<f32>>()
    };
    let want = |n: u32| {
        let wi = directions(N, 3, false);
        let mut w = vec![AlbedoRecord::default(); N];
        let r = rust(SCATTERING_SLAB, 16, 4).max_events(n);
        r.albedo_records(Vectors::Aos(&wi), 400, None, &mut w)
            .unwrap();
        w.iter().map(|a| a.reflected[0]).collect::<Vec<f32>>()
    };
    let c = Capi::toml(SCATTERING_SLAB, 16, 4);
    let full = albedo(&c);
    // SAFETY: `c.0` is a live BSDF used by this thread only.
    assert_eq!(unsafe { strata_bsdf_set_max_events(c.0, 3) }, STRATA_OK);
    let three = albedo(&c);
    assert_eq!(bits(&three), bits(&want(3)));
    assert_eq!(bits(&full), bits(&want(1 << 20)));
    let (sum3, sum) = (three.iter().sum::<f32>(), full.iter().sum::<f32>());
    assert!(sum3 < sum, "3 events {sum3}, default {sum}");
    for (n, message) in [(0, "n = 0: "), ((1 << 24) + 1, "n = 16777217: ")] {
        // SAFETY: as above.
        let status = unsafe { strata_bsdf_set_max_events(c.0, n) };
        assert_eq!(status, STRATA_ERR_INVALID_ARGUMENT);
        let e = last_error();
        assert!(
            e.starts_with("strata_bsdf_set_max_events: ") && e.contains(message),
            "{e}"
        );
    }
    assert_eq!(
        bits(&albedo(&c)),
        bits(&three),
        "a bad limit changed the BSDF"
    );
    // SAFETY: NULL is an error, not a dereference.
    assert_eq!(
        unsafe { strata_bsdf_set_max_events(null_mut(), 3) },
        STRATA_ERR_NULL
    );
    assert_eq!(last_error(), "strata_bsdf_set_max_events: b is NULL");
}

/// A lossless slab of optical depth 10^4, whose walks diffuse for up to
/// ~10^8 events (crates/strata-bsdf/tests/api/bounded_walks.rs).
const LOSSLESS_TAU_1E4: &str =
    include_str!("../../../strata-bsdf/tests/data/lossless_slab_tau_1e4.toml");

/// `truncated` is the number of walks the limit of events ended in the
/// call: under a limit of 64 events on the lossless slab, the sum of the
/// Rust API's `Estimate::truncated` (eval, in both layouts and with
/// per-query columns), `PdfEstimate::truncated` (the unbiased pdf) and the
/// albedos' counts, with the same numbers bit for bit; 0 when no walk
/// reaches the limit (the ordinary stacks of the tests above) and for an
/// empty batch.
#[test]
fn truncated_is_the_rust_apis_count_of_the_walks_the_limit_ended() {
    let (samples, seed, n) = (256, 5, 6);
    let c = Capi::toml(LOSSLESS_TAU_1E4, samples, seed);
    // SAFETY: `c.0` is a live BSDF used by this thread only.
    assert_eq!(unsafe { strata_bsdf_set_max_events(c.0, 64) }, STRATA_OK);
    let r = rust(LOSSLESS_TAU_1E4, samples, seed).max_events(64);
    let wi = directions(n, 21, true);
    let wo = directions(n, 22, true);
    let (wi_f, wo_f) = (flat(&wi), flat(&wo));
    let keys: Vec<u64> = (0..n as u64).map(|k| 3 * k + 1).collect();
    let pairs: Vec<(Vec3, Vec3)> = (0..n).map(|k| (wi[k].into(), wo[k].into())).collect();

    // Eval: AoS, SoA, and with a column of the material's own thickness
    // (one material per query, the same numbers).
    let est = r.eval_batch_keyed(&pairs, samples, &keys).unwrap();
    let want: u64 = est.iter().map(|e| e.truncated).sum();
    assert!(want > 0 && want < n as u64 * samples, "{want}");
    let want_f: Vec<f32> = est.iter().flat_map(|e| e.value.map(|v| v as f32)).collect();
    let thickness = vec![1.0f32; n];
    let path = CString::new("layers[0].medium.thickness").unwrap();
    let column = StrataColumn {
        path: path.as_ptr(),
        width: 1,
        values: thickness.as_ptr(),
    };
    let (wis, wos) = (soa(&wi), soa(&wo));
    for (layout, ncolumns) in [("aos", 0), ("soa", 0), ("aos", 1)] {
        let mut f = vec![0.0f32; 3 * n];
        let mut cut = u64::MAX;
        let (wi_v, wo_v) = match layout {
            "aos" => (aos(&wi_f), aos(&wo_f)),
            _ => (soa3(&wis), soa3(&wos)),
        };
        let batch = StrataBatch {
            n,
            wi: wi_v,
            wo: wo_v,
            keys: keys.as_ptr(),
            columns: if ncolumns > 0 { &column } else { null() },
            ncolumns,
            f: aos_out(&mut f),
            truncated: &mut cut,
            ..Default::default()
        };
        // SAFETY: every array holds n queries' values; one column of n.
        let status = unsafe { strata_eval(c.0, &batch) };
        assert_eq!(status, STRATA_OK, "{}", last_error());
        assert_eq!(cut, want, "{layout}, {ncolumns} columns");
        assert_eq!(bits(&f), bits(&want_f), "{layout}, {ncolumns} columns");
    }

    // The unbiased pdf.
    let walks = 128;
    let est = r.pdf_unbiased_batch(&pairs, walks).unwrap();
    let want: u64 = est.iter().map(|e| e.truncated).sum();
    assert!(want > 0, "{est:?}");
    let (mut pdf, mut se, mut cut) = (vec![0.0f32; n], vec![0.0f32; n], u64::MAX);
    let batch = StrataBatch {
        n,
        wi: aos(&wi_f),
        wo: aos(&wo_f),
        walks,
        pdf: pdf.as_mut_ptr(),
        pdf_stderr: se.as_mut_ptr(),
        truncated: &mut cut,
        ..Default::default()
    };
    // SAFETY: every array holds n queries' values.
    let status = unsafe { strata_pdf_unbiased(c.0, &batch) };
    assert_eq!(status, STRATA_OK, "{}", last_error());
    assert_eq!(cut, want);
    let want_pdf: Vec<f32> = est.iter().map(|e| e.value as f32).collect();
    assert_eq!(bits(&pdf), bits(&want_pdf));

    // The albedo: each walk counted once, though it feeds R and T.
    let wis_v: Vec<Vec3> = wi.iter().map(|&w| w.into()).collect();
    let albedos = r.albedo_batch_keyed(&wis_v, 500, &keys).unwrap();
    let want: u64 = albedos.iter().map(|a| a.reflected.truncated).sum();
    assert!(want > 0 && want < 500 * n as u64, "{want}");
    let (mut out, mut cut) = (vec![StrataAlbedo::default(); n], u64::MAX);
    let batch = StrataBatch {
        n,
        wi: aos(&wi_f),
        walks: 500,
        keys: keys.as_ptr(),
        albedo: out.as_mut_ptr(),
        truncated: &mut cut,
        ..Default::default()
    };
    // SAFETY: every array holds n queries' values.
    let status = unsafe { strata_albedo(c.0, &batch) };
    assert_eq!(status, STRATA_OK, "{}", last_error());
    assert_eq!(cut, want);
    let r0: Vec<f32> = out.iter().map(|a| a.reflected[0]).collect();
    let want_r0: Vec<f32> = albedos
        .iter()
        .map(|a| a.reflected.value[0] as f32)
        .collect();
    assert_eq!(bits(&r0), bits(&want_r0));

    // An empty batch writes 0; a failed one writes nothing.
    let mut cut = u64::MAX;
    let empty = StrataBatch {
        truncated: &mut cut,
        ..Default::default()
    };
    // SAFETY: n = 0: no array is read.
    assert_eq!(unsafe { strata_eval(c.0, &empty) }, STRATA_OK);
    assert_eq!(cut, 0);
    let mut cut = 7u64;
    let bad = [f32::NAN, 0.0, 1.0];
    let mut f = [0.0f32; 3];
    let batch = StrataBatch {
        n: 1,
        wi: aos(&bad),
        wo: aos(&bad),
        f: aos_out(&mut f),
        truncated: &mut cut,
        ..Default::default()
    };
    // SAFETY: one query.
    assert_eq!(
        unsafe { strata_eval(c.0, &batch) },
        STRATA_ERR_INVALID_ARGUMENT
    );
    assert_eq!(cut, 7);
}
