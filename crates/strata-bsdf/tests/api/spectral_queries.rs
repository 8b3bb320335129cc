//! Spectral queries (issue 42): a query's three wavelengths in the three
//! channels, its material's spectra read at them (`SpectralColumns`, then
//! `PerQuery`). Checked against independent formulas (`common::reference`,
//! Fresnel and Beer–Lambert written in the test) at each wavelength, and for
//! a caller's RGB texture against the uplift of its triple.

use crate::common::reference::rough_conductor;
use crate::common::{dir, stack};
use strata_bsdf::stack::presets;
use strata_bsdf::stack::spectrum::rgb_at;
use strata_bsdf::stack::{SetPath, Spectrum};
use strata_bsdf::{
    Albedo, Bsdf, Column, Estimate, LayeredBsdf, PerQuery, Queries, SpectralColumns, SpectralError,
};

/// Query `k`'s eval of every pair, with its wavelengths `nm[3k..3k + 3]`.
fn evals(bsdf: &LayeredBsdf, nm: &[f32], wi: &[[f32; 3]], wo: &[[f32; 3]]) -> Vec<Estimate> {
    let s = SpectralColumns::new(bsdf, nm, &[]).expect("spectral columns");
    let per = PerQuery::new(bsdf, s.queries(), &s.columns()).expect("per-query rows");
    let mut out = vec![Estimate::default(); s.queries()];
    per.eval_into(&Queries::pairs(wi, wo), &mut |k, e| out[k] = *e)
        .expect("eval");
    out
}

/// Query `k`'s albedo from `wi[k]` at its wavelengths, with `walks` walks.
fn albedos(bsdf: &LayeredBsdf, nm: &[f32], wi: &[[f32; 3]], walks: u64) -> Vec<Albedo> {
    let s = SpectralColumns::new(bsdf, nm, &[]).expect("spectral columns");
    let per = PerQuery::new(bsdf, s.queries(), &s.columns()).expect("per-query rows");
    let mut out = vec![Albedo::default(); s.queries()];
    per.albedo_into(&Queries::directions(wi).walks(walks), &mut |k, a| {
        out[k] = *a
    })
    .expect("albedo");
    out
}

fn f32x3(d: [f64; 3]) -> [f32; 3] {
    d.map(|x| x as f32)
}

/// Gold's rough reflection at three wavelengths a query is the microfacet
/// conductor of gold's measured η and k at each (the preset's tables),
/// channel by channel, to the engine's f32 rounding.
#[test]
fn a_rough_conductor_answers_at_each_wavelength() {
    let alpha = 0.2;
    let bsdf = LayeredBsdf::new(stack(&format!(
        "[[layers]]\ninterface = {{ kind = \"conductor\", preset = \"Au\", roughness = {alpha} }}\n"
    )));
    let au = presets::preset("Au").expect("gold");
    let nm: Vec<f32> = vec![
        450.0, 550.0, 650.0, 400.0, 500.0, 700.0, 380.0, 600.0, 820.0, 520.0, 520.0, 520.0,
    ];
    let (a, b) = (dir(30.0, 0.0), dir(50.0, 160.0));
    let n = nm.len() / 3;
    let (wi, wo) = (vec![f32x3(a); n], vec![f32x3(b); n]);
    let got = evals(&bsdf, &nm, &wi, &wo);
    // The directions as the engine reads them (f32).
    let (a, b) = (wi[0].map(f64::from), wo[0].map(f64::from));
    for (k, e) in got.iter().enumerate() {
        for c in 0..3 {
            let l = f64::from(nm[3 * k + c]);
            let want = rough_conductor(alpha, au.eta().at(l), au.k().at(l), a, b);
            let rel = (e.value[c] - want).abs() / want;
            assert!(rel < 1e-4, "query {k} at {l} nm: {} vs {want}", e.value[c]);
        }
    }
    // The channels differ where the wavelengths do, as gold's colour does.
    assert!(
        got[0].value[0] < 0.6 * got[0].value[2],
        "{:?}",
        got[0].value
    );
    assert_eq!(got[3].value[0], got[3].value[2]);
}

/// Fresnel reflectance of unpolarized light from a medium of IOR 1 onto one
/// of IOR `n` at incidence cosine `cos_i`.
fn fresnel(cos_i: f64, n: f64) -> f64 {
    let sin_t2 = (1.0 - cos_i * cos_i) / (n * n);
    let cos_t = (1.0 - sin_t2).sqrt();
    let rs = (cos_i - n * cos_t) / (cos_i + n * cos_t);
    let rp = (n * cos_i - cos_t) / (n * cos_i + cos_t);
    0.5 * (rs * rs + rp * rp)
}

/// Query `k` at one wavelength `lambdas[k]`, three times.
fn thrice(lambdas: &[f32]) -> Vec<f32> {
    lambdas.iter().flat_map(|&l| [l; 3]).collect()
}

/// `A + B / λ²`, λ in µm.
fn cauchy(a: f64, b: f64, nm: f32) -> f64 {
    let um = f64::from(nm) * 1e-3;
    a + b / (um * um)
}

/// A smooth interface whose IOR follows Cauchy's law reflects, at 45°, the
/// Fresnel reflectance of its IOR at each of four wavelengths (one a query;
/// a walk refracts at one IOR): within 4 standard errors of 10⁷ walks each
/// (about 7e-5). The walks share their random numbers across wavelengths, so
/// the reflectances' order, which differs by 30 standard errors from 400 to
/// 700 nm, is resolved too.
#[test]
fn a_cauchy_interface_reflects_fresnel_at_each_wavelength() {
    let (a, b) = (1.5046, 0.0042);
    let bsdf = LayeredBsdf::new(stack(&format!(
        "[[layers]]\ninterface = {{ kind = \"dielectric\", ior = {{ cauchy = [{a}, {b}] }} }}\n"
    )));
    let lambdas = [400.0f32, 480.0, 560.0, 700.0];
    let wi = vec![f32x3(dir(45.0, 0.0)); lambdas.len()];
    let got = albedos(&bsdf, &thrice(&lambdas), &wi, 10_000_000);
    let cos = f64::from(wi[0][2]);
    for (k, al) in got.iter().enumerate() {
        let want = fresnel(cos, cauchy(a, b, lambdas[k]));
        let (r, se) = (al.reflected.value, al.reflected.stderr);
        assert!(se[0] > 0.0 && se[0] < 1e-4, "{se:?}");
        assert!(
            (r[0] - want).abs() < 4.0 * se[0],
            "{} nm: {r:?} ± {se:?} vs Fresnel {want}",
            lambdas[k]
        );
        assert!(r.iter().all(|&x| x == r[0]), "{r:?}");
        assert!((al.reflected.value[0] + al.transmitted.value[0] - 1.0).abs() < 1e-12);
    }
    for w in got.windows(2) {
        assert!(w[0].reflected.value[0] > w[1].reflected.value[0]);
    }
}

/// An index-matched absorbing layer whose `sigma_t` is a tabulated spectrum
/// transmits `exp(−σt(λ) d / cos θ)` at each wavelength of a query, three
/// different ones at once (its IOR does not vary), exactly: a layer that
/// does not scatter is crossed with its transmittance as the weight.
#[test]
fn an_absorbing_layer_transmits_beer_lambert_at_each_wavelength() {
    let d = 0.7;
    let sigma_t = Spectrum::Tabulated {
        nm: vec![400.0, 550.0, 700.0],
        values: vec![2.0, 0.5, 1.25],
    };
    let bsdf = LayeredBsdf::new(stack(&format!(
        "[[layers]]\ninterface = {{ kind = \"dielectric\", ior = 1.0 }}\n\
         medium = {{ thickness = {d}, sigma_t = {{ nm = [400, 550, 700], values = [2, 0.5, 1.25] }}, albedo = 0 }}\n\
         [[layers]]\ninterface = {{ kind = \"dielectric\", ior = 1.0 }}\n"
    )));
    let nm = [430.0f32, 550.0, 610.0, 380.0, 475.0, 800.0];
    let wi = vec![f32x3(dir(20.0, 0.0)), f32x3(dir(60.0, 90.0))];
    let got = albedos(&bsdf, &nm, &wi, 64);
    for (k, al) in got.iter().enumerate() {
        let cos = f64::from(wi[k][2]);
        for c in 0..3 {
            let s = f64::from(sigma_t.at(f64::from(nm[3 * k + c])) as f32);
            let want = (-s * d / cos).exp();
            let t = al.transmitted.value[c];
            assert_eq!(al.transmitted.stderr[c], 0.0, "{al:?}");
            assert!(
                (t - want).abs() < 1e-5 * want,
                "query {k} channel {c}: {t} vs {want}"
            );
            assert_eq!(al.reflected.value[c], 0.0);
        }
    }
}

/// A lossless dispersive slab (a smooth coat whose IOR follows the Abbe
/// form, a non-absorbing scattering layer, a smooth exit) conserves energy
/// at each of four wavelengths, `R + T = 1` within 3 standard errors (the
/// walks conserve it walk by walk: what this checks is that no wavelength's
/// row makes the slab lossy), and its reflectance at each wavelength is, within
/// 4 standard errors, that of the same slab written with the IOR's value
/// there as a number (another path: a material file, no spectral column).
#[test]
fn a_lossless_dispersive_slab_conserves_energy_at_each_wavelength() {
    let slab = |ior: &str| {
        format!(
            "[[layers]]\ninterface = {{ kind = \"dielectric\", ior = {ior} }}\n\
             medium = {{ thickness = 1, sigma_t = 1, albedo = 1, phase = {{ kind = \"hg\", g = 0.5 }} }}\n\
             [[layers]]\ninterface = {{ kind = \"dielectric\", ior = 1.0 }}\n"
        )
    };
    let (nd, abbe) = (1.5168, 30.0);
    let bsdf = LayeredBsdf::new(stack(&slab(&format!("{{ nd = {nd}, abbe = {abbe} }}"))));
    let lambdas = [420.0f32, 500.0, 587.56, 690.0];
    let wi = vec![f32x3(dir(35.0, 0.0)); lambdas.len()];
    let walks = 100_000;
    let got = albedos(&bsdf, &thrice(&lambdas), &wi, walks);
    let law = strata_bsdf::stack::spectrum::abbe_to_cauchy(nd, abbe);
    for (k, al) in got.iter().enumerate() {
        let (r, t) = (al.reflected, al.transmitted);
        let sum = r.value[0] + t.value[0];
        let se = r.stderr[0] + t.stderr[0];
        assert!(
            (sum - 1.0).abs() <= 3.0 * se + 1e-9,
            "{} nm: R + T = {sum} ± {se}",
            lambdas[k]
        );
        // The same slab with the IOR at this wavelength as a number.
        let n = cauchy(law[0], law[1], lambdas[k]) as f32;
        let file = LayeredBsdf::new(stack(&slab(&format!("{:e}", f64::from(n)))));
        let want = albedos(&file, &[500.0; 3], &wi[..1], walks)[0].reflected;
        let sigma = (r.stderr[0].powi(2) + want.stderr[0].powi(2)).sqrt();
        assert!(
            (r.value[0] - want.value[0]).abs() < 4.0 * sigma,
            "{} nm: R {} vs the file's {} ± {sigma}",
            lambdas[k],
            r.value[0],
            want.value[0]
        );
    }
    // Dispersion shows: the blue row reflects more than the red one, by
    // more than 2 standard errors of the difference taken as independent
    // (the rows share their random numbers, which only narrows it).
    let (b, r) = (got[0].reflected, got[3].reflected);
    let d = b.value[0] - r.value[0];
    let sigma = (b.stderr[0].powi(2) + r.stderr[0].powi(2)).sqrt();
    assert!(d > 2.0 * sigma, "R(420 nm) − R(690 nm) = {d} ± {sigma}");
}

/// The caller's columns keep their indices among the spectral ones: an
/// error about a column names the caller's.
#[test]
fn a_callers_column_keeps_its_index() {
    let gold = LayeredBsdf::new(stack(
        "[[layers]]\ninterface = { kind = \"conductor\", preset = \"Au\", roughness = 0.2 }\n",
    ));
    let rough: SetPath = "layers[0].interface.roughness".parse().unwrap();
    let v = [0.1f32, 0.2];
    let columns = [Column {
        path: &rough,
        width: 1,
        values: &v,
    }];
    let s = SpectralColumns::new(&gold, &[500.0; 6], &columns).unwrap();
    let paths: Vec<String> = s.columns().iter().map(|c| c.path.to_string()).collect();
    assert_eq!(
        paths,
        [
            "layers[0].interface.roughness",
            "layers[0].interface.eta",
            "layers[0].interface.k"
        ]
    );
}

/// A caller's texture of a coloured field (an RGB albedo per query) is read
/// at each query's wavelengths through the uplift of its triple, as a
/// material file's RGB value is: a Lambertian base answers `ρ(λ) / π`.
#[test]
fn an_rgb_texture_is_read_at_the_wavelengths() {
    let bsdf = LayeredBsdf::new(stack(
        "[[layers]]\ninterface = { kind = \"diffuse\", albedo = 0.5 }\n",
    ));
    let path: SetPath = "layers[0].interface.albedo".parse().unwrap();
    let rgb = [0.8f32, 0.3, 0.1, 0.2, 0.6, 0.9];
    let nm = [450.0f32, 550.0, 650.0, 700.0, 520.0, 430.0];
    let columns = [Column {
        path: &path,
        width: 3,
        values: &rgb,
    }];
    let s = SpectralColumns::new(&bsdf, &nm, &columns).unwrap();
    let per = PerQuery::new(&bsdf, 2, &s.columns()).unwrap();
    let (a, b) = (f32x3(dir(10.0, 0.0)), f32x3(dir(40.0, 0.0)));
    let mut got = [Estimate::default(); 2];
    per.eval_into(&Queries::pairs(&[a, a][..], &[b, b][..]), &mut |k, e| {
        got[k] = *e
    })
    .unwrap();
    for k in 0..2 {
        let triple = [0, 1, 2].map(|c| f64::from(rgb[3 * k + c]));
        for c in 0..3 {
            let rho = rgb_at(triple, f64::from(nm[3 * k + c]));
            let want = f64::from(rho as f32) / std::f64::consts::PI;
            assert!(
                (got[k].value[c] - want).abs() < 1e-6 * want,
                "query {k} channel {c}: {} vs {want}",
                got[k].value[c]
            );
        }
    }
    // Red reflects most at 650 nm and least at 450 nm.
    assert!(
        got[0].value[2] > 2.0 * got[0].value[0],
        "{:?}",
        got[0].value
    );
}

/// Bad wavelengths and columns are errors naming the query and the value;
/// different wavelengths in one query of a dispersive stack name its IOR.
#[test]
fn bad_wavelengths_are_errors_naming_the_query() {
    let bsdf = LayeredBsdf::new(stack(
        "[[layers]]\ninterface = { kind = \"dielectric\", ior = { cauchy = [1.5, 0.004] }, roughness = 0.1 }\n",
    ));
    let err = |nm: &[f32]| SpectralColumns::new(&bsdf, nm, &[]).unwrap_err();
    assert_eq!(err(&[500.0; 4]), SpectralError::Length { len: 4 });
    let e = err(&[500.0, 500.0, 500.0, 600.0, f32::NAN, 600.0]);
    assert!(
        matches!(e, SpectralError::Wavelength { query: 1, value } if value.is_nan()),
        "{e:?}"
    );
    assert_eq!(
        err(&[-450.0, 500.0, 600.0]),
        SpectralError::Wavelength {
            query: 0,
            value: -450.0
        }
    );
    let e = err(&[500.0, 500.0, 500.0, 450.0, 550.0, 650.0]);
    assert!(
        e.to_string()
            .starts_with("query 1: `layers[0].interface.ior` varies with wavelength"),
        "{e}"
    );
    let path: SetPath = "layers[0].interface.roughness".parse().unwrap();
    let short = [0.1f32];
    let columns = [Column {
        path: &path,
        width: 1,
        values: &short,
    }];
    let e = SpectralColumns::new(&bsdf, &[500.0; 6], &columns).unwrap_err();
    assert!(e.to_string().contains("1 values for 2 queries"), "{e}");
    // A caller's IOR column replaces the law, and any wavelengths then go.
    let ior = [1.4f32, 1.6];
    let path: SetPath = "layers[0].interface.ior".parse().unwrap();
    let columns = [Column {
        path: &path,
        width: 1,
        values: &ior,
    }];
    let nm = [450.0, 550.0, 650.0, 400.0, 500.0, 600.0];
    assert!(SpectralColumns::new(&bsdf, &nm, &columns).is_ok());
}

/// A batch whose queries share their wavelengths takes one material at them
/// (`at_wavelengths`, one to three, the spare channels repeating the last):
/// it answers what the per-query form answers; walks split wavelengths
/// three at a time, or one at a time where the IOR varies.
#[test]
fn a_batch_at_shared_wavelengths_takes_one_material() {
    let gold = LayeredBsdf::new(stack(
        "[[layers]]\ninterface = { kind = \"conductor\", preset = \"Au\", roughness = 0.3 }\n",
    ));
    let (a, b) = (f32x3(dir(20.0, 0.0)), f32x3(dir(35.0, 120.0)));
    let nm = [430.0f32, 510.0, 640.0];
    let per_query = evals(&gold, &nm, &[a], &[b])[0].value;
    let one = gold.at_wavelengths(&nm).unwrap();
    let mut got = [Estimate::default()];
    one.eval_into(&Queries::pairs(&[a][..], &[b][..]), &mut |k, e| got[k] = *e)
        .unwrap();
    for (x, y) in got[0].value.iter().zip(per_query) {
        assert!((x - y).abs() < 1e-6 * y, "{x} vs {y}");
    }
    let padded = gold.at_wavelengths(&[430.0, 510.0]).unwrap();
    assert_eq!(
        padded.stack().interface(0).eta[2],
        gold.at_wavelengths(&[510.0])
            .unwrap()
            .stack()
            .interface(0)
            .eta[0]
    );
    assert!(matches!(
        gold.at_wavelengths(&[]),
        Err(SpectralError::Length { len: 0 })
    ));
    assert!(matches!(
        gold.at_wavelengths(&[500.0; 4]),
        Err(SpectralError::Length { len: 4 })
    ));
    let four = [400.0, 500.0, 600.0, 700.0];
    assert_eq!(gold.wavelength_groups(&four), [&four[..3], &four[3..]]);
    let glass = LayeredBsdf::new(stack(
        "[[layers]]\ninterface = { kind = \"dielectric\", ior = { nd = 1.5, abbe = 40 } }\n",
    ));
    assert_eq!(glass.wavelength_groups(&four).len(), 4);
    assert_eq!(
        (gold.wavelengths_per_walk(), glass.wavelengths_per_walk()),
        (3, 1)
    );
}
