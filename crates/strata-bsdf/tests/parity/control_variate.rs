//! The wavefront against the scalar reference with the control variate, at
//! what `tests/estimators/layered_control_variate.rs` checks on the
//! wavefront: the walks and estimates of the two engines are equal, bit for
//! bit. (Every walk on every width and setting: `wavefront_parity.rs`.)

use crate::common;
use common::cv::{api_pairs, as_api, WITHOUT_SCATTERING};
use common::*;
use strata_bsdf::estimator::coat_lambertian::CoatLambertian;
use strata_bsdf::estimator::scalar::ScalarEngine;
use strata_bsdf::estimator::wavefront::{Plan, Wavefront};
use strata_bsdf::lane::F32x8;
use strata_bsdf::Settings;

/// No scattering: with the control variate every scalar walk scores exactly
/// 0, as every wavefront walk, and the estimates are equal.
#[test]
fn without_scattering_the_engines_agree() {
    for toml in WITHOUT_SCATTERING {
        let st = stack(toml);
        let set = Settings::default();
        let coat = CoatLambertian::of(&st, &set).expect("a walk-free form");
        let sc = ScalarEngine::<f32>::new(&st, set).with_cv(Some(coat.clone()));
        let wf = Wavefront::<F32x8>::new(&st, set, Plan::Specialized).with_cv(Some(coat.clone()));
        let pairs = api_pairs();
        let keys: Vec<u64> = (0..pairs.len() as u64).collect();
        let n = 4096;
        let walks = wf.eval_walk_values(&pairs, n, 5, &keys);
        let (we, _) = wf.eval_batch(&pairs, n, 5, &keys);
        for (q, &(wi, wo)) in pairs.iter().enumerate() {
            let sv = sc.eval_walk_values(wi, wo, n, 5, keys[q]);
            assert!(sv.iter().all(|v| *v == [0.0; 3]), "scalar walks");
            assert_eq!(sv, walks[q], "pair {q}: walks");
            let se = sc.eval(wi, wo, n, 5, keys[q]);
            assert_eq!(se, we[q], "pair {q}: engines");
        }
    }
}

/// The engines' estimates that `Auto` and `Unidirectional` give through the
/// API (`auto_uses_the_control_variate_and_unidirectional_does_not`): with
/// and without the control variate, the scalar engine's is the wavefront's.
#[test]
fn auto_and_unidirectional_estimates_agree() {
    let st = stack(SMOOTH_WEAK_SCATTERER);
    let set = Settings::default();
    let (wi, wo) = (as_api(dir(30.0, 0.0)), as_api(dir(60.0, 120.0)));
    let (n, key) = (2048, 77);
    for cv in [true, false] {
        let sc = ScalarEngine::<f32>::new(&st, set).with_control_variate(cv);
        let wf = Walks::new(&st, set).with_control_variate(cv);
        assert_eq!(sc.control_variate(), cv);
        assert_eq!(
            sc.eval(wi, wo, n, 0, key),
            wf.eval(wi, wo, n, 0, key),
            "control variate {cv}"
        );
    }
}
