//! Every walk ends: on a lossless slab of optical depth 10^4, whose walks
//! diffuse for up to ~10^8 events, the bidirectional estimator, the
//! unbiased pdf and the unidirectional walks answer under the default limit
//! of events, with finite values and the energy of the slab (`R + T` at most
//! 1). `cargo run --release -p strata-bsdf --example bounded_walks` times
//! 36 queries × 16 walks of each on one thread (docs/numerics.md).

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
    let wi = pairs[0].0;
    let a = bsdf.albedo(wi, 4000).unwrap();
    for c in 0..3 {
        let sum = a.reflected.value[c] + a.transmitted.value[c];
        let se = a.reflected.stderr[c].hypot(a.transmitted.stderr[c]);
        assert!(sum <= 1.0 + 5.0 * se && sum > 0.9, "R + T = {sum} ± {se}");
    }
}
