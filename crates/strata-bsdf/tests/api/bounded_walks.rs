//! Every walk ends: on a lossless slab of optical depth 10^4, whose walks
//! diffuse for up to ~10^8 events, the bidirectional estimator, the
//! unbiased pdf and the unidirectional walks answer under the default limit
//! of events, with finite values; the albedo's `R + T` is exactly the
//! fraction of walks the limit did not end. `cargo run --release -p strata-bsdf --example bounded_walks` times
//! 36 queries × 16 walks of each on one thread (docs/numerics.md).

use crate::common::batches::Batches;
use crate::common::*;
use glam::Vec3;
use strata_bsdf::{Estimator, LayeredBsdf};

const LOSSLESS_TAU_1E4: &str = include_str!("../data/lossless_slab_tau_1e4.toml");

#[test]
fn walks_on_a_lossless_slab_of_optical_depth_1e4_end() {
    let bsdf = LayeredBsdf::new(stack(LOSSLESS_TAU_1E4))
        .threads(1)
        .unwrap();
    let pairs: Vec<(Vec3, Vec3)> = (0..6)
        .map(|k| {
            let (a, b) = (0.2 + 0.2 * k as f32, 0.1 + 0.25 * k as f32);
            let side = if k % 2 == 0 { 1.0 } else { -1.0 };
            let wo = Vec3::new(-b.sin(), 0.1, side * b.cos()).normalize();
            (Vec3::new(a.sin(), 0.0, a.cos()), wo)
        })
        .collect();
    let keys: Vec<u64> = (0..pairs.len() as u64).collect();
    for estimator in [Estimator::Bidirectional, Estimator::Unidirectional] {
        let b = bsdf.clone().estimator(estimator);
        for e in b.eval_batch_keyed(&pairs, 16, &keys).unwrap() {
            assert!(
                e.value.iter().all(|v| v.is_finite() && *v >= 0.0),
                "{estimator:?}: {e:?}"
            );
        }
    }
    for p in bsdf.pdf_unbiased_batch(&pairs, 16).unwrap() {
        assert!(p.value.is_finite() && p.value >= 0.0, "{p:?}");
    }
    let (wi, n) = (pairs[0].0, 4000u64);
    let a = bsdf.albedo(wi, n).unwrap();
    let kept = n - a.reflected.truncated;
    for c in 0..3 {
        let sum = (a.reflected.value[c] + a.transmitted.value[c]) * n as f64;
        assert!(
            (sum - kept as f64).abs() < 1e-6 * n as f64,
            "{sum} of {n}, {kept} not cut"
        );
    }
}

/// The results count the walks the limit ended, exactly: on the lossless
/// slab every walk that leaves carries weight 1, so at a limit of 64 events
/// `R + T` is the fraction of walks the limit did not end. The unidirectional
/// and bidirectional evals and the unbiased pdf count theirs too, the same
/// on both engines; under the default limit, stacks of the test suite
/// count none.
#[test]
fn results_count_the_walks_the_limit_ended() {
    use strata_bsdf::Engine;
    let slab = LayeredBsdf::new(stack(LOSSLESS_TAU_1E4))
        .threads(1)
        .unwrap()
        .max_events(64);
    let (wi, wo) = (Vec3::new(0.5, 0.0, 0.866), Vec3::new(-0.3, 0.1, 0.95));
    let n = 2000u64;
    let on = |engine| slab.clone().engine(engine);
    let a = on(Engine::Wavefront).albedo(wi, n).unwrap();
    assert_eq!(a, on(Engine::Scalar).albedo(wi, n).unwrap());
    let cut = a.reflected.truncated;
    assert!(cut > 0 && cut < n, "{cut} of {n}");
    assert_eq!(a.transmitted.truncated, cut);
    for c in 0..3 {
        let kept = (a.reflected.value[c] + a.transmitted.value[c]) * n as f64;
        assert!(
            (kept - (n - cut) as f64).abs() < 1e-6 * n as f64,
            "{kept} vs {n} - {cut}"
        );
    }
    for estimator in [Estimator::Unidirectional, Estimator::Bidirectional] {
        let eval = |engine| {
            let b = on(engine).estimator(estimator);
            b.eval_batch_keyed(&[(wi, wo)], 256, &[7]).unwrap()[0]
        };
        let e = eval(Engine::Wavefront);
        assert_eq!(e, eval(Engine::Scalar), "{estimator:?}");
        assert!(
            e.truncated > 0 && e.truncated <= 256,
            "{estimator:?}: {e:?}"
        );
    }
    let p = slab.pdf_unbiased(wi, wo, 256).unwrap();
    assert!(p.truncated > 0 && p.truncated <= p.samples, "{p:?}");
    for toml in [COATED_COPPER, SCATTERING_SLAB] {
        let b = LayeredBsdf::new(stack(toml));
        let a = b.albedo(wi, 4000).unwrap();
        let e = b
            .clone()
            .estimator(Estimator::Bidirectional)
            .eval(wi, wo)
            .unwrap();
        let p = b.pdf_unbiased(wi, wo, 256).unwrap();
        let counts = [a.reflected.truncated, e.truncated, p.truncated];
        assert_eq!(counts, [0; 3]);
    }
}
