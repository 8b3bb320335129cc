//! A digest of strata's answers on every built-in material: eval on both
//! engines and both estimators, sample with its pdf, the approximate and
//! unbiased pdfs, and the albedo, for a fixed set of directions.
//!
//! The test asserts that the two engines' digests are equal on every
//! material (walk-by-walk parity through the public API). With
//! `STRATA_FINGERPRINT=FILE` it also writes the digests, a line per material:
//! two builds that write the same lines give the same answers bit for bit.
//! CI compares the repository's AVX2 build with baseline x86-64 this way
//! (.ci/run), since results must not depend on the target
//! (docs/architecture.md).

use crate::common::batches::Batches;
use glam::Vec3;
use strata_bsdf::{Engine, Estimator, LayeredBsdf};

/// FNV-1a over the bits of every number fed to it.
struct Digest(u64);

impl Digest {
    fn bits(&mut self, b: u64) {
        for byte in b.to_le_bytes() {
            self.0 = (self.0 ^ byte as u64).wrapping_mul(0x0100_0000_01b3);
        }
    }
    fn f64s(&mut self, v: &[f64]) {
        v.iter().for_each(|x| self.bits(x.to_bits()));
    }
    fn f32s(&mut self, v: &[f32]) {
        v.iter().for_each(|x| self.bits(x.to_bits() as u64));
    }
}

/// Directions over both hemispheres, grazing ones included.
fn directions() -> Vec<Vec3> {
    let mut d = Vec::new();
    for (i, theta) in [0.0f32, 17.0, 45.0, 71.0, 89.0, 120.0, 165.0]
        .iter()
        .enumerate()
    {
        let (t, p) = (theta.to_radians(), (40.0 * i as f32 + 5.0).to_radians());
        d.push(Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos()));
    }
    d
}

#[test]
fn every_builtin_material_answers_alike_on_both_engines() {
    let mut lines = Vec::new();
    let dirs = directions();
    let pairs: Vec<(Vec3, Vec3)> = dirs
        .iter()
        .flat_map(|&a| dirs.iter().map(move |&b| (a, b)))
        .collect();
    let index: Vec<u64> = (0..dirs.len() as u64).collect();
    for &(name, _) in strata_bsdf::materials::BUILTIN {
        let stack = strata_bsdf::materials::builtin(name).expect("built-in materials are valid");
        let base = LayeredBsdf::new(stack).seed(5).samples(64);
        let mut line = String::from(name);
        let mut engines = Vec::new();
        let runs = [
            ("scalar-uni", Engine::Scalar, Estimator::Unidirectional),
            (
                "wavefront-uni",
                Engine::Wavefront,
                Estimator::Unidirectional,
            ),
            ("scalar-bidir", Engine::Scalar, Estimator::Bidirectional),
            (
                "wavefront-bidir",
                Engine::Wavefront,
                Estimator::Bidirectional,
            ),
            ("auto", Engine::Auto, Estimator::Auto),
        ];
        for (label, engine, estimator) in runs {
            let b = base.clone().engine(engine).estimator(estimator);
            let mut h = Digest(0xcbf2_9ce4_8422_2325);
            for e in b.eval_batch(&pairs).expect("valid directions") {
                h.f64s(&e.value);
                h.f64s(&e.stderr);
            }
            line += &format!(" {label}:{:016x}", h.0);
            engines.push(h.0);
        }
        assert_eq!(
            engines[0], engines[1],
            "{name}: unidirectional eval, scalar ≠ wavefront"
        );
        assert_eq!(
            engines[2], engines[3],
            "{name}: bidirectional eval, scalar ≠ wavefront"
        );
        let b = base.clone();
        let mut h = Digest(0xcbf2_9ce4_8422_2325);
        for s in b.sample_batch(&dirs, &index).expect("valid directions") {
            match s {
                Some(s) => {
                    h.f32s(&s.wo.to_array());
                    h.f32s(&s.weight);
                    h.f32s(&[s.pdf]);
                }
                None => h.bits(u64::MAX),
            }
        }
        h.f32s(&b.pdf_batch(&pairs).expect("valid directions"));
        for p in b.pdf_unbiased_batch(&pairs, 16).expect("valid directions") {
            h.f64s(&[p.value, p.stderr]);
        }
        for a in b.albedo_batch(&dirs, 256).expect("valid directions") {
            h.f64s(&a.reflected.value);
            h.f64s(&a.transmitted.value);
        }
        line += &format!(" sample-pdf-albedo:{:016x}", h.0);
        lines.push(line);
    }
    if let Some(path) = std::env::var_os("STRATA_FINGERPRINT") {
        let text = lines.join("\n") + "\n";
        std::fs::write(&path, text).unwrap_or_else(|e| panic!("{path:?}: {e}"));
    }
}
