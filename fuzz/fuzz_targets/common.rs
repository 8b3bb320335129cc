//! What every material target checks once a material has parsed: the stack
//! answers queries with finite, non-negative numbers on both engines.

use strata_bsdf::{Engine, LayerStack, LayeredBsdf, Settings};

pub fn exercise(st: LayerStack) {
    // A walk-length cap bounds the fuzzer's time on lossless stacks of huge
    // optical depth (their walks are long by physics, not by a bug).
    let settings = Settings {
        max_depth: Some(256),
        ..Settings::default()
    };
    let base = LayeredBsdf::with_settings(st, settings)
        .samples(4)
        .pdf_samples(1);
    let dirs = [
        glam::Vec3::Z,
        -glam::Vec3::Z,
        glam::Vec3::new(0.6, 0.0, 0.8),
        glam::Vec3::new(0.0, -0.8, -0.6),
        glam::Vec3::new(1.0, 0.0, 1e-7),
    ];
    for b in [base.clone().engine(Engine::Scalar), base.engine(Engine::Wavefront)] {
        for &wi in &dirs {
            for &wo in &dirs {
                let e = b.eval(wi, wo).expect("valid directions");
                assert!(
                    e.value.iter().chain(&e.stderr).all(|x| x.is_finite() && *x >= 0.0),
                    "eval({wi}, {wo}) = {e:?}"
                );
                let p = b.pdf(wi, wo).expect("valid directions");
                assert!(p.is_finite() && p >= 0.0, "pdf({wi}, {wo}) = {p}");
            }
            if let Some(s) = b.sample(wi, 0).expect("valid direction") {
                assert!(s.wo.is_finite() && s.weight.iter().all(|w| w.is_finite() && *w >= 0.0));
            }
        }
    }
}
