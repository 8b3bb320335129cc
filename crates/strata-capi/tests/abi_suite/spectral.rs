//! Spectral queries through the C ABI (a batch's `wavelengths`): query
//! `k`'s three wavelengths make its answers the library's spectral
//! answers (`SpectralColumns`, then `PerQuery`) bit for bit, with the
//! batch's columns too; a bad wavelength is a status and a message naming
//! the query and the value, and nothing is written.

use std::ffi::{CStr, CString};
use std::ptr::null_mut;
use strata_bsdf::stack::SetPath;
use strata_bsdf::{
    Bsdf, Column, Estimate, LayerStack, LayeredBsdf, PerQuery, Queries, SpectralColumns,
};
use strata_capi::*;

use crate::batch::{aos, aos_out};

const COAT_ON_PAINT: &str = "[[layers]]\n\
    interface = { kind = \"dielectric\", ior = 1.5, roughness = 0.2 }\n\
    medium = { thickness = 0.3, sigma_t = { nm = [400, 700], values = [1.5, 0.2] }, albedo = 0.5 }\n\
    [[layers]]\ninterface = { kind = \"diffuse\", albedo = [0.7, 0.4, 0.2] }\n";
const SAMPLES: u64 = 16;
const SEED: u64 = 5;
const N: usize = 4;

fn capi(text: &str) -> *mut StrataBsdf {
    let c = CString::new(text).unwrap();
    let mut b = null_mut();
    // SAFETY: `c` is NUL-terminated and `b` is writable.
    let status = unsafe { strata_bsdf_from_toml(c.as_ptr(), SAMPLES, SEED, &mut b) };
    assert_eq!(status, STRATA_OK);
    b
}

fn last_error() -> String {
    // SAFETY: NUL-terminated, valid until the thread's next call.
    unsafe { CStr::from_ptr(strata_last_error()) }
        .to_string_lossy()
        .into_owned()
}

fn directions() -> (Vec<f32>, Vec<f32>) {
    let wi = (0..N).flat_map(|k| [0.1 * k as f32, 0.2, 1.0]).collect();
    let wo = (0..N).flat_map(|k| [-0.3, 0.1 * k as f32, 0.9]).collect();
    (wi, wo)
}

/// The library's spectral evals of the same queries.
fn library(nm: &[f32], columns: &[Column]) -> Vec<Estimate> {
    let bsdf = LayeredBsdf::new(LayerStack::from_toml_str(COAT_ON_PAINT).unwrap())
        .samples(SAMPLES)
        .seed(SEED);
    let s = SpectralColumns::new(&bsdf, nm, columns).unwrap();
    let per = PerQuery::new(&bsdf, N, &s.columns()).unwrap();
    let (wi, wo) = directions();
    let (wi, wo) = (
        wi.chunks(3).map(|c| [c[0], c[1], c[2]]).collect::<Vec<_>>(),
        wo,
    );
    let wo: Vec<[f32; 3]> = wo.chunks(3).map(|c| [c[0], c[1], c[2]]).collect();
    let mut out = vec![Estimate::default(); N];
    per.eval_into(&Queries::pairs(&wi[..], &wo[..]), &mut |k, e| out[k] = *e)
        .unwrap();
    out
}

#[test]
fn eval_with_wavelengths_is_the_librarys_spectral_eval() {
    let nm: Vec<f32> = vec![
        450.0, 550.0, 650.0, 400.0, 500.0, 700.0, 620.0, 620.0, 620.0, 380.0, 480.0, 580.0,
    ];
    let albedo = [
        0.9f32, 0.1, 0.3, 0.2, 0.5, 0.8, 0.4, 0.4, 0.4, 0.1, 0.6, 0.2,
    ];
    let path = CString::new("layers[1].interface.albedo").unwrap();
    for with_column in [false, true] {
        let (wi, wo) = directions();
        let mut f = vec![-1.0f32; 3 * N];
        let columns = [StrataColumn {
            path: path.as_ptr(),
            width: 3,
            values: albedo.as_ptr(),
        }];
        let batch = StrataBatch {
            n: N,
            wi: aos(&wi),
            wo: aos(&wo),
            f: aos_out(&mut f),
            wavelengths: nm.as_ptr(),
            columns: if with_column {
                columns.as_ptr()
            } else {
                std::ptr::null()
            },
            ncolumns: usize::from(with_column),
            ..Default::default()
        };
        let b = capi(COAT_ON_PAINT);
        // SAFETY: `b` is live; the batch's arrays hold `N` queries.
        let status = unsafe { strata_eval(b, &batch) };
        assert_eq!(status, STRATA_OK, "{}", last_error());
        let set: SetPath = "layers[1].interface.albedo".parse().unwrap();
        let mine = [Column {
            path: &set,
            width: 3,
            values: &albedo,
        }];
        let want = library(&nm, if with_column { &mine } else { &[] });
        for k in 0..N {
            for c in 0..3 {
                assert_eq!(
                    f[3 * k + c],
                    want[k].value[c] as f32,
                    "query {k} channel {c}"
                );
            }
        }
        // The channels follow the wavelengths: the layer absorbs blue most.
        assert!(f[2] > f[0], "{f:?}");
        // SAFETY: from `strata_bsdf_from_toml`, freed once.
        unsafe { strata_bsdf_free(b) };
    }
}

#[test]
fn a_bad_wavelength_names_the_query_and_writes_nothing() {
    let b = capi(COAT_ON_PAINT);
    let (wi, wo) = directions();
    let mut nm = [500.0f32; 3 * N];
    nm[7] = f32::NAN;
    let mut f = vec![-1.0f32; 3 * N];
    let batch = StrataBatch {
        n: N,
        wi: aos(&wi),
        wo: aos(&wo),
        f: aos_out(&mut f),
        wavelengths: nm.as_ptr(),
        ..Default::default()
    };
    // SAFETY: `b` is live; the batch's arrays hold `N` queries.
    let status = unsafe { strata_eval(b, &batch) };
    assert_eq!(status, STRATA_ERR_INVALID_ARGUMENT);
    let e = last_error();
    assert!(e.contains("wavelengths: query 2: wavelength NaN nm"), "{e}");
    assert!(f.iter().all(|&x| x == -1.0));
    // SAFETY: from `strata_bsdf_from_toml`, freed once.
    unsafe { strata_bsdf_free(b) };
    let glass = capi(
        "[[layers]]\ninterface = { kind = \"dielectric\", ior = { cauchy = [1.5, 0.005] } }\n",
    );
    let nm = [450.0f32, 550.0, 650.0].repeat(N);
    let wi = directions().0;
    let mut rec = vec![StrataAlbedo::default(); N];
    let batch = StrataBatch {
        n: N,
        wi: aos(&wi),
        walks: 8,
        albedo: rec.as_mut_ptr(),
        wavelengths: nm.as_ptr(),
        ..Default::default()
    };
    // SAFETY: `glass` is live; the batch's arrays hold `N` queries.
    let status = unsafe { strata_albedo(glass, &batch) };
    assert_eq!(status, STRATA_ERR_INVALID_ARGUMENT);
    let e = last_error();
    assert!(
        e.contains("query 0: `layers[0].interface.ior` varies with wavelength"),
        "{e}"
    );
    // SAFETY: from `strata_bsdf_from_toml`, freed once.
    unsafe { strata_bsdf_free(glass) };
}
