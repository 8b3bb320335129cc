//! The wavefront against the scalar reference on the stacks of the per-query
//! parameter sets (`tests/api/param_sets.rs`, which checks that a set's
//! walks are the walks on its own stack): on each set's stack, with the
//! control variate on every other set, the specialized walks and samples
//! are the scalar engine's, bit for bit.

use crate::common;
use common::sets::*;
use strata_bsdf::estimator::scalar::ScalarEngine;
use strata_bsdf::estimator::wavefront::{Plan, Wavefront};
use strata_bsdf::lane::F32x8;
use strata_bsdf::rng::{Stream, WalkRng};
use strata_bsdf::{LayerStack, Settings};

#[test]
fn engines_agree_walk_by_walk_on_each_sets_stack() {
    let settings = Settings::default();
    let plan = Plan::Specialized;
    for f in families() {
        let stacks: Vec<LayerStack> = (0..SETS).map(|v| variant(&f, v)).collect();
        let (pairs, set) = queries(17);
        let dirs = unit_dirs(&pairs);
        let keys: Vec<u64> = (0..dirs.len() as u64).collect();
        for k in 0..dirs.len() {
            let s = set[k] as usize;
            let cv = s % 2 == 1;
            let got = Wavefront::<F32x8>::new(&stacks[s], settings, plan)
                .with_control_variate(cv)
                .eval_walk_values(&dirs[k..k + 1], 24, 3, &keys[k..k + 1])
                .remove(0);
            let want = ScalarEngine::<f32>::new(&stacks[s], settings)
                .with_control_variate(cv)
                .eval_walk_values(dirs[k].0, dirs[k].1, 24, 3, keys[k]);
            assert_eq!(got.len(), want.len());
            for (w, (a, b)) in got.iter().zip(&want).enumerate() {
                assert_eq!(bits(*a), bits(*b), "{} query {k} walk {w}", f.name);
            }
        }
        // Analog walks: samples.
        let wis: Vec<[f64; 3]> = dirs.iter().map(|d| d.0).collect();
        let index: Vec<u64> = (0..wis.len() as u64).map(|k| k * 5).collect();
        for k in 0..wis.len() {
            let s = &stacks[set[k] as usize];
            let w = Wavefront::<F32x8>::new(s, settings, plan);
            let (ks, ix) = (&keys[k..k + 1], &index[k..k + 1]);
            let got = w.sample_batch(&wis[k..k + 1], 3, ks, ix).0[0];
            let mut rng = WalkRng::new(3, keys[k], index[k], Stream::Walk);
            let want = ScalarEngine::<f32>::new(s, settings).sample(wis[k], &mut rng);
            assert_eq!(got, want, "{} sample {k}", f.name);
        }
    }
}
