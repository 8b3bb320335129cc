//! The bidirectional walks of the wavefront against the scalar reference's,
//! walk by walk, bit for bit, on the stacks and direction pairs of
//! `tests/estimators/bidirectional.rs`.

use crate::common;
use common::bidir::{pairs, STACKS, TILTED};
use common::*;
use strata_bsdf::estimator::scalar::ScalarEngine;
use strata_bsdf::estimator::wavefront::{Plan, Wavefront};
use strata_bsdf::lane::F32x8;
use strata_bsdf::Settings;

/// Walk-by-walk parity of the two engines' bidirectional walks (the same
/// lane code on one lane and on eight; this checks the scheduling, not the
/// physics: on the stacks with scattering layers or three interfaces the
/// wavefront regroups traced walks by their subpath lengths before
/// connecting them, and refills a lane as soon as its subpath ends: 300
/// walks make a full unit and a partial one, and 5 walks leave lanes
/// without a walk), and equal estimates from the wavefront's parallel
/// blocks.
#[test]
fn wavefront_replays_the_scalar_walks() {
    for (name, toml) in STACKS.iter().chain(TILTED) {
        let st = stack(toml);
        let eng = ScalarEngine::<f32>::new(&st, Settings::default());
        let wave = Wavefront::<F32x8>::new(&st, Settings::default(), Plan::Specialized);
        let ps = pairs(st.transmissive());
        for (q, &(wi, wo)) in ps.iter().enumerate() {
            for walks in [300, 5] {
                let a = eng.eval_bidir_walk_values(wi, wo, walks, 5, q as u64);
                let b = wave.eval_bidir_walk_values(wi, wo, walks, 5, q as u64);
                assert_eq!(a.len(), b.len());
                for (k, (x, y)) in a.iter().zip(&b).enumerate() {
                    assert_eq!(x, y, "{name}, pair {q}, walk {k} of {walks}");
                    assert!(
                        x.iter().all(|v| v.is_finite() && *v >= 0.0),
                        "{name}: {x:?}"
                    );
                }
            }
        }
        let keys: Vec<u64> = (0..ps.len() as u64).collect();
        let batch = wave.eval_bidir_batch(&ps, 600, 9, &keys);
        for (q, &(wi, wo)) in ps.iter().enumerate() {
            assert_eq!(
                batch[q],
                eng.eval_bidir(wi, wo, 600, 9, q as u64),
                "{name}, pair {q}"
            );
        }
    }
}
