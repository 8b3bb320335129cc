//! Determinism: the same (seed, query) gives bit-identical results from every
//! estimator, whatever was computed before and on whichever engine instance;
//! a different query or seed gives a different random stream (and so a
//! different, but statistically consistent, estimate).

use crate::common;
use crate::common::batches::Batches;
use common::*;
use strata_bsdf::estimator::scalar::{Scalar, ScalarEngine};
use strata_bsdf::rng::{Stream, WalkRng};
use strata_bsdf::{LayeredBsdf, Settings};

const SLAB: &str = crate::common::ROUGH_SCATTERING_SLAB;

fn same_and_different<S: Scalar>() {
    let st = stack(SLAB);
    let a = ScalarEngine::<S>::new(&st, Settings::default());
    let b = ScalarEngine::<S>::new(&st, Settings::default());
    let (wi, wr, wt) = (dir(30.0, 0.0), dir(50.0, 120.0), dir(140.0, 200.0));
    for wo in [wr, wt] {
        // Same (seed, query): identical, on another instance and after other work.
        let e1 = a.eval(wi, wo, 2000, 7, 42);
        let _ = a.eval(wi, wo, 500, 7, 43);
        let e2 = b.eval(wi, wo, 2000, 7, 42);
        assert_eq!(e1, e2);
        assert!(e1.value[0] > 0.0 && e1.stderr[0] > 0.0);
        // A different query or seed: a different stream, a consistent value.
        for e3 in [a.eval(wi, wo, 2000, 7, 44), a.eval(wi, wo, 2000, 8, 42)] {
            for c in 0..3 {
                assert_ne!(e1.value[c], e3.value[c]);
                let z = (e1.value[c] - e3.value[c]) / e1.stderr[c].hypot(e3.stderr[c]);
                assert!(z.abs() < 5.0, "{e1:?} vs {e3:?}");
            }
        }
        // The approximate pdf (in transmission every short walk adds a
        // random term; in reflection most add nothing).
        let p1 = a.pdf(wi, wo, 8, 7, 42);
        assert_eq!(p1.to_bits(), b.pdf(wi, wo, 8, 7, 42).to_bits());
        if wo[2] < 0.0 {
            assert_ne!(p1, a.pdf(wi, wo, 8, 7, 45));
        }
    }
    // Albedo.
    let r1 = a.albedo(wi, 2000, 3, 9);
    assert_eq!(r1, b.albedo(wi, 2000, 3, 9));
    let r2 = a.albedo(wi, 2000, 3, 10);
    assert_ne!(r1.reflected.value, r2.reflected.value);
    assert_ne!(r1.transmitted.value, r2.transmitted.value);
    // Sample: the same stream gives the same walk.
    let walk = |e: &ScalarEngine<S>, q: u64| {
        (0..200)
            .map(|k| e.sample(wi, &mut WalkRng::new(5, q, k, Stream::Walk)))
            .collect::<Vec<_>>()
    };
    let s1 = walk(&a, 1);
    assert_eq!(s1, walk(&b, 1));
    let s2 = walk(&a, 2);
    let differ = s1.iter().zip(&s2).filter(|(x, y)| x != y).count();
    assert!(
        differ > 150,
        "only {differ} of 200 walks differ between queries"
    );
}

#[test]
fn scalar_engine_is_deterministic_f32() {
    same_and_different::<f32>();
}

#[test]
fn scalar_engine_is_deterministic_f64() {
    same_and_different::<f64>();
}

#[test]
fn random_streams_depend_on_every_key() {
    let draw = |seed, query, sample, stream| {
        let mut r = WalkRng::new(seed, query, sample, stream);
        (0..8).map(|_| r.next_u32()).collect::<Vec<_>>()
    };
    let base = draw(1, 2, 3, Stream::Walk);
    assert_eq!(base, draw(1, 2, 3, Stream::Walk));
    for other in [
        draw(0, 2, 3, Stream::Walk),
        draw(1, 3, 3, Stream::Walk),
        draw(1, 2, 4, Stream::Walk),
        draw(1, 2, 3, Stream::Adjoint),
        draw(1, 2, 3, Stream::Pdf),
        // Swapped keys must not collide either.
        draw(2, 1, 3, Stream::Walk),
        draw(1, 3, 2, Stream::Walk),
    ] {
        assert_ne!(base, other);
    }
}

#[test]
fn public_api_is_deterministic() {
    let make = |seed| LayeredBsdf::new(stack(SLAB)).samples(1000).seed(seed);
    let (bsdf, again, other_seed) = (make(1), make(1), make(2));
    let (wi, wo) = (vec3(dir(20.0, 0.0)), vec3(dir(60.0, 90.0)));
    let e = bsdf.eval(wi, wo).expect("valid");
    assert_eq!(e, again.eval(wi, wo).expect("valid"));
    assert_ne!(e.value, other_seed.eval(wi, wo).expect("valid").value);
    // Queries keyed by their directions: another direction, another stream.
    let wo2 = vec3(dir(60.0, 91.0));
    assert_ne!(
        strata_bsdf::api::direction_key(wi, wo),
        strata_bsdf::api::direction_key(wi, wo2)
    );
    // Explicit query keys.
    let q1 = bsdf.eval_with(wi, wo, 1000, 5).expect("valid");
    assert_eq!(q1, again.eval_with(wi, wo, 1000, 5).expect("valid"));
    assert_ne!(
        q1.value,
        bsdf.eval_with(wi, wo, 1000, 6).expect("valid").value
    );
    // pdf, albedo and sample.
    assert_eq!(bsdf.pdf(wi, wo), again.pdf(wi, wo));
    assert_eq!(bsdf.albedo(wi, 500), again.albedo(wi, 500));
    let samples = |b: &LayeredBsdf| {
        (0..50)
            .map(|k| b.sample(wi, k).expect("valid"))
            .collect::<Vec<_>>()
    };
    assert_eq!(samples(&bsdf), samples(&again));
    assert_ne!(samples(&bsdf), samples(&other_seed));
}
