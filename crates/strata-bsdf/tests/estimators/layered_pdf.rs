//! The approximate pdf of `sample()` (`estimator::pdf`, method.md §6), on
//! the wavefront engine (the scalar engine's pdf walk by walk: tests/parity).
//!
//! It is an estimate of the density of `sample()`'s walks of at most
//! `APPROX_EVENTS` events (tests/estimators/pdf_density.rs checks the density walk
//! against `sample()`'s histogram), and need not integrate to 1:
//! * `sample()` itself is a defective distribution: walks can be absorbed
//!   (returning `None`) and smooth interfaces put probability into delta lobes,
//!   which have no density; only the rest can appear in a pdf;
//! * it is a Monte Carlo estimate from a few walks, so its value at one
//!   direction is noisy (its expectation is what integrates to ≤ 1);
//! * it is mixed with a uniform density, pdf = (1 − f) p + f / 4π (f is
//!   `UNIFORM_FRACTION`), so that it is positive wherever f can be (on the
//!   hemispheres light can leave through).
//!
//! Its expected integral is therefore at most (1 − f) + f = 1; the uniform
//! part alone gives f on a transmissive stack. What is checked, per stack
//! and incident direction:
//! * over a grid of directions, the pdf is finite and ≥ 0 everywhere, and > 0
//!   wherever `eval` is > 0 in some channel;
//! * its integral over the sphere (jittered quadrature, one random point per
//!   cell; standard error from pairs of neighbouring cells) is at most
//!   1 + 4σ, and at least the uniform part's, f over the sphere (f / 2 on an
//!   opaque stack, whose pdf is 0 below): exactly, since the quadrature of a
//!   constant is exact;
//! * for a lone rough interface it is exactly (1 − f) · that interface's density
//!   plus the uniform part.

use crate::common;
use crate::common::batches::Batches;
use common::reference::SplitMix;
use common::*;
use strata_bsdf::estimator::pdf::UNIFORM_FRACTION;
use strata_bsdf::lane::V3;
use strata_bsdf::{PdfKind, Settings};

const STACKS: [(&str, &str); 6] = [
    (
        "smooth coat / diffuse",
        crate::common::SMOOTH_COAT_OVER_DIFFUSE,
    ),
    ("coated conductor", COATED_COPPER),
    (
        "scattering varnish",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5, roughness = 0.3 }
        medium = { thickness = 1.0, sigma_t = 1.0, albedo = 0.9, phase = { kind = "hg", g = 0.3 } }
        [[layers]]
        interface = { kind = "diffuse", albedo = 0.5 }
        "#,
    ),
    (
        "rough slab",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5, roughness = 0.3 }
        medium = { thickness = 1.0, sigma_t = [0.5, 1.0, 2.0], albedo = 0.9 }
        [[layers]]
        interface = { kind = "dielectric", ior = 1.33, roughness = 0.2 }
        "#,
    ),
    (
        "smooth slab",
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.3 }
        medium = { thickness = 1.0, sigma_t = 1.0, albedo = 0.9, phase = { kind = "hg", g = 0.5 } }
        [[layers]]
        interface = { kind = "dielectric", ior = 1.0 }
        "#,
    ),
    ("3 interfaces", crate::common::TWO_COATS_OVER_GOLD),
];

/// Incident directions: from above, and from below for transmissive stacks.
fn incidents(transmissive: bool) -> Vec<[f64; 3]> {
    let mut v = vec![dir(0.0, 0.0), dir(45.0, 0.0), dir(80.0, 30.0)];
    if transmissive {
        v.push(dir(130.0, 0.0));
    }
    v
}

#[test]
fn pdf_is_finite_and_positive_where_eval_is() {
    for (label, toml) in STACKS {
        let st = stack(toml);
        let eng = Walks::new(&st, Settings::default());
        for (q, wi) in incidents(st.transmissive()).into_iter().enumerate() {
            let (mut positive_f, mut checked) = (0, 0);
            // θ from 2.5° to 177.5°, avoiding exactly grazing directions; one
            // batch of pdfs (4 walks) and one of evals (32 walks).
            let grid: Vec<(f64, usize, [f64; 3])> = (0..18)
                .flat_map(|i| {
                    let theta = 2.5 + 10.0 * i as f64;
                    (0..24).map(move |j| (theta, 15 * j + 7, dir(theta, (15 * j + 7) as f64)))
                })
                .collect();
            let wos: Vec<[f64; 3]> = grid.iter().map(|g| g.2).collect();
            let keys: Vec<u64> = (0..grid.len()).map(|k| (q * 1000 + k) as u64).collect();
            let ps = pdfs(&eng, wi, &wos, 4, 1, &keys);
            let pairs: Vec<_> = wos.iter().map(|&wo| (wi, wo)).collect();
            let fs = eng.0.eval_batch(&pairs, 32, 2, &keys).0;
            for (((theta, phi, _), p), f) in grid.iter().zip(ps).zip(fs) {
                let what = format!("{label} wi {wi:?} wo θ {theta} φ {phi}");
                assert!(p.is_finite() && p >= 0.0, "{what}: pdf {p}");
                checked += 1;
                if f.value.iter().any(|&v| v > 0.0) {
                    positive_f += 1;
                    assert!(p > 0.0, "{what}: pdf 0 where f = {:?}", f.value);
                    assert!(
                        p >= 0.999 * UNIFORM_FRACTION / (4.0 * std::f64::consts::PI),
                        "{what}: pdf {p} below the uniform floor"
                    );
                }
            }
            // The implication must have been exercised on most of the grid.
            assert!(
                positive_f * 3 > checked,
                "{label}: f > 0 at {positive_f}/{checked}"
            );
        }
    }
}

/// ∫ pdf dω over the sphere by jittered quadrature in (cos θ, φ): one point
/// per cell of `n_mu × 2 n_mu` per hemisphere, the k-th point keyed k;
/// returns the estimate and its standard error from the squared differences
/// of neighbouring cells. `pdfs` answers every point at once (a batch).
fn pdf_integral(
    pdfs: impl Fn(&[[f64; 3]], &[u64]) -> Vec<f64>,
    n_mu: usize,
    seed: u64,
) -> (f64, f64) {
    let n_phi = 2 * n_mu;
    let cell = (1.0 / n_mu as f64) * (2.0 * std::f64::consts::PI / n_phi as f64);
    let mut rng = SplitMix(seed);
    let mut points = Vec::new();
    for sign in [1.0, -1.0] {
        for i in 0..n_mu {
            for j in 0..n_phi {
                let mu = (i as f64 + rng.next_f64()) / n_mu as f64;
                let phi = j as f64 + rng.next_f64();
                let phi = phi / n_phi as f64 * 2.0 * std::f64::consts::PI;
                let s = (1.0 - mu * mu).max(0.0).sqrt();
                points.push([s * phi.cos(), s * phi.sin(), sign * mu]);
            }
        }
    }
    let keys: Vec<u64> = (0..points.len() as u64).collect();
    let v = pdfs(&points, &keys);
    let (mut sum, mut pairs) = (0.0, 0.0);
    for pair in v.chunks(2) {
        let (a, b) = (pair[0] * cell, pair[1] * cell);
        sum += a + b;
        pairs += (a - b).powi(2);
    }
    (sum, pairs.sqrt())
}

/// The approximate pdf of `(wi, wo)` for every `wo`, `walks` density walks
/// each with seed `seed` and query `keys[k]`, as one wavefront batch: the
/// scalar engine's `pdf` walk by walk (tests/parity).
fn pdfs(
    eng: &Walks,
    wi: [f64; 3],
    wos: &[[f64; 3]],
    walks: u64,
    seed: u64,
    keys: &[u64],
) -> Vec<f64> {
    let pairs: Vec<_> = wos.iter().map(|&wo| (wi, wo)).collect();
    (eng.0
        .pdf_batch(&pairs, walks, seed, keys, PdfKind::Approximate))
    .iter()
    .map(|p| p.value)
    .collect()
}

#[test]
fn pdf_integrates_to_at_most_one() {
    for (s, (label, toml)) in STACKS.into_iter().enumerate() {
        let st = stack(toml);
        let eng = Walks::new(&st, Settings::default());
        for (q, wi) in incidents(st.transmissive()).into_iter().enumerate() {
            let (total, se) = pdf_integral(
                |wos, keys| pdfs(&eng, wi, wos, 32, 3, keys),
                80,
                (s * 10 + q) as u64,
            );
            eprintln!("{label} wi {wi:?}: ∫ pdf = {total:.4} ± {se:.4}");
            // 1e-9: rounding of the sum when the pdf is the uniform part alone.
            let sides = if st.transmissive() { 1.0 } else { 0.5 };
            assert!(
                total >= sides * UNIFORM_FRACTION - 1e-9 && total <= 1.0 + 4.0 * se,
                "{label} wi {wi:?}: ∫ pdf = {total} ± {se}"
            );
            // The three interfaces at grazing light set the bound: a few
            // walks carry their density, σ ≈ 0.05 at 80 or 96 cells a side.
            assert!(
                se < 0.06,
                "{label} wi {wi:?}: imprecise ∫ pdf = {total} ± {se}"
            );
        }
    }
}

#[test]
fn pdf_of_a_lone_rough_interface_is_its_density() {
    let st = stack(
        r#"
        exterior_ior = 1.1
        [[layers]]
        interface = { kind = "dielectric", ior = 1.6, roughness = 0.25 }
        "#,
    );
    let eng = Walks::new(&st, Settings::default());
    let it = st.interface_lanes::<f32>(0);
    let v = |w: [f64; 3]| V3::new(w[0] as f32, w[1] as f32, w[2] as f32);
    let uniform = UNIFORM_FRACTION / (4.0 * std::f64::consts::PI);
    let mut informative = 0;
    // The exits of the k-th point, keyed k, in one batch per incidence.
    let wos: Vec<[f64; 3]> = (0..12)
        .flat_map(|i| (0..8).map(move |j| dir(5.0 + 15.0 * i as f64, 45.0 * j as f64 + 3.0)))
        .collect();
    let keys: Vec<u64> = (0..wos.len() as u64).collect();
    for wi in [dir(20.0, 0.0), dir(70.0, 0.0), dir(160.0, 0.0)] {
        for (&wo, p) in wos.iter().zip(pdfs(&eng, wi, &wos, 4, 1, &keys)) {
            let pi = it.pdf(v(wi), v(wo), false) as f64;
            let expect = (1.0 - UNIFORM_FRACTION) * pi + uniform;
            assert!(
                (p - expect).abs() <= 1e-5 * expect,
                "wi {wi:?} wo {wo:?}: pdf {p} vs {expect}"
            );
            if pi > 0.1 {
                informative += 1;
            }
        }
    }
    assert!(
        informative > 10,
        "only {informative} directions inside the lobes"
    );
}

/// A rough coat over a smooth transmissive bottom: the walk's density through
/// the stack is picked up at the entrance (the vertex across the exit layer
/// is the entrance itself in a transmission query), so the pdf must carry
/// the transmitted lobe, not just the uniform floor. The floor alone would
/// integrate to 0.05 over the lower hemisphere; the stack transmits about
/// 0.9, nearly all of it straight through the smooth bottom. The approximate
/// pdf puts 0.87 (from above) and 0.77 (from below) there, ± 0.01: the bound
/// 0.7 fails a pdf that loses a fifth of the transmitted lobe.
#[test]
fn pdf_sees_transmission_through_a_smooth_exit() {
    let st = stack(
        r#"
        [[layers]]
        interface = { kind = "dielectric", ior = 1.5, roughness = 0.3 }
        [[layers]]
        interface = { kind = "dielectric", ior = 1.0 }
        "#,
    );
    let eng = Walks::new(&st, Settings::default());
    for (q, wi) in [dir(17.0, 0.0), dir(160.0, 40.0)].into_iter().enumerate() {
        let below = |w: [f64; 3]| (w[2] < 0.0) == (wi[2] > 0.0);
        let (t, se) = pdf_integral(
            |wos, keys| {
                let p = pdfs(&eng, wi, wos, 32, 3, keys);
                (wos.iter().zip(p))
                    .map(|(wo, p)| if below(*wo) { p } else { 0.0 })
                    .collect()
            },
            60,
            100 + q as u64,
        );
        eprintln!("wi {wi:?}: ∫ pdf over the transmission side = {t:.4} ± {se:.4}");
        assert!(t > 0.7 && t <= 1.0 + 4.0 * se, "wi {wi:?}: {t} ± {se}");
    }
}

/// The lobe pdf (the default, `PdfWalks::LOBES`) is a density: on every
/// stack and incidence it integrates to at most 1, and to at least its
/// uniform part; on an opaque stack away from grazing, as `sample()`'s
/// density, to about the albedo (within a factor 2: its cosine lobe is
/// weighted by a closed-form estimate of what the stack returns). (At
/// most 1.005: the body's weight `1 − F(cos θi)` is the flat surface's
/// Fresnel term, and a rough entry's reflection lobe carries its
/// microfacets' mean, a few thousandths more on the rough slab from below.)
#[test]
fn lobe_pdf_integrates_to_at_most_one() {
    for (s, (label, toml)) in STACKS.into_iter().enumerate() {
        let st = stack(toml);
        let opaque = !st.transmissive();
        let b = strata_bsdf::LayeredBsdf::new(st.clone());
        assert!(
            b.pdf_walks_value().is_lobes(),
            "the default is the lobe pdf"
        );
        for (q, wi) in incidents(st.transmissive()).into_iter().enumerate() {
            let v = |w: [f64; 3]| glam::Vec3::new(w[0] as f32, w[1] as f32, w[2] as f32);
            let pdfs = |wos: &[[f64; 3]], _: &[u64]| {
                let pairs: Vec<_> = wos.iter().map(|&wo| (v(wi), v(wo))).collect();
                let p = b.pdf_batch(&pairs).unwrap();
                p.into_iter().map(f64::from).collect()
            };
            let (total, se) = pdf_integral(pdfs, 80, (s * 10 + q) as u64);
            eprintln!("{label} wi {wi:?}: ∫ lobe pdf = {total:.4} ± {se:.4}");
            let sides = if st.transmissive() { 1.0 } else { 0.5 };
            assert!(
                total >= sides * UNIFORM_FRACTION - 1e-9 && total <= 1.005 + 4.0 * se,
                "{label} wi {wi:?}: ∫ lobe pdf = {total} ± {se}"
            );
            if opaque && wi[2] > 0.5 {
                // As sample()'s density, to about the albedo.
                let a = b.albedo(v(wi), 20_000).unwrap().reflected.value;
                let albedo = (a[0] + a[1] + a[2]) / 3.0;
                let want = (1.0 - UNIFORM_FRACTION) * albedo + 0.5 * UNIFORM_FRACTION;
                eprintln!(
                    "  albedo {albedo:.4}: ∫ lobe pdf / that {:.3}",
                    total / want
                );
                assert!(
                    (0.5..=2.0).contains(&(total / want)),
                    "{label} wi {wi:?}: ∫ lobe pdf = {total}, albedo {albedo}"
                );
            }
        }
    }
}

/// On a lone interface the lobe pdf is the interface's own density, mixed
/// with the uniform part: the density of `sample()`, exactly.
#[test]
fn lobe_pdf_of_a_lone_rough_interface_is_its_density() {
    let st = stack(
        r#"
        exterior_ior = 1.1
        [[layers]]
        interface = { kind = "dielectric", ior = 1.6, roughness = 0.25 }
        "#,
    );
    let b = strata_bsdf::LayeredBsdf::new(st.clone());
    let it = st.interface_lanes::<f32>(0);
    let v = |w: [f64; 3]| V3::new(w[0] as f32, w[1] as f32, w[2] as f32);
    let g = |w: [f64; 3]| glam::Vec3::new(w[0] as f32, w[1] as f32, w[2] as f32);
    let uniform = UNIFORM_FRACTION / (4.0 * std::f64::consts::PI);
    let mut informative = 0;
    for wi in [dir(20.0, 0.0), dir(70.0, 0.0), dir(160.0, 0.0)] {
        for i in 0..12 {
            for j in 0..8 {
                let wo = dir(5.0 + 15.0 * i as f64, 45.0 * j as f64 + 3.0);
                let p = b.pdf(g(wi), g(wo)).unwrap() as f64;
                let pi = it.pdf(v(wi), v(wo), false) as f64;
                let expect = (1.0 - UNIFORM_FRACTION) * pi + uniform;
                assert!(
                    (p - expect).abs() <= 1e-5 * expect,
                    "wi {wi:?} wo {wo:?}: lobe pdf {p} vs {expect}"
                );
                informative += usize::from(pi > 0.1);
            }
        }
    }
    assert!(
        informative > 10,
        "only {informative} directions inside the lobes"
    );
}
