//! The comparison with pbrt-v4 (`strata_reports::pbrt`): its data parse as
//! described, its configurations are the stacks the data's README names, and
//! the one value known exactly (a smooth coat over an absorber over a
//! Lambertian base at normal incidence and exit: 0.18721, the README's
//! closed form, where pbrt-v4's depth cap gives 0.18348) comes out.

use strata_bsdf::{Engine, Estimator, EvalStart};
use strata_reports::pbrt;

#[test]
fn data_parse_and_configurations_build() {
    let configs = pbrt::configs();
    assert_eq!(configs.len(), 6);
    assert_eq!(configs.iter().filter(|c| c.target).count(), 4);
    for c in &configs {
        strata_bsdf::LayerStack::from_toml_str(&c.toml)
            .unwrap_or_else(|e| panic!("{}: {e}", c.name));
        let p = pbrt::pairs(c.name);
        assert_eq!(p.len(), 21, "{}", c.name);
        for (k, q) in p.iter().enumerate() {
            assert_eq!(q.pair as usize, k);
            assert!(
                q.f > 0.0 && q.se > 0.0 && q.calls == 1e6,
                "{} pair {k}: {q:?}",
                c.name
            );
            let n = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            assert!((n(q.wi) - 1.0).abs() < 1e-6 && (n(q.wo) - 1.0).abs() < 1e-6);
        }
        let t = pbrt::pbrt_seconds_per_call(c.name).expect("a timing");
        assert!(t > 5e-8 && t < 5e-6, "{}: {t} s per call", c.name);
    }
    assert!(pbrt::pairs("no such configuration").is_empty());
}

#[test]
fn the_smooth_coat_is_exact_and_the_walks_agree() {
    let c = &pbrt::configs()[0];
    assert_eq!(c.name, "coated_diffuse_smooth_alb0");
    let exact = pbrt::compare(
        c,
        64,
        1,
        1,
        Engine::Scalar,
        EvalStart::Normal,
        Estimator::Auto,
    )
    .unwrap();
    assert!(exact
        .iter()
        .all(|r| r.exact && r.ratio == Some(f64::INFINITY)));
    assert!((exact[0].f - 0.18721).abs() < 1e-5, "f = {}", exact[0].f);
    // pbrt-v4's depth cap: about 2 % low.
    let low = 1.0 - exact[0].pbrt.f / exact[0].f;
    assert!(low > 0.015 && low < 0.025, "pbrt-v4 is {low} low");
    let walks = pbrt::compare(
        c,
        1 << 15,
        1,
        1,
        Engine::Wavefront,
        EvalStart::Normal,
        Estimator::Unidirectional,
    )
    .unwrap();
    for (x, w) in exact.iter().zip(&walks) {
        assert!(!w.exact && w.se > 0.0);
        let z = (w.f - x.f) / w.se;
        assert!(
            z.abs() < 4.5,
            "pair {}: walks {} ± {} vs exact {}",
            x.pbrt.pair,
            w.f,
            w.se,
            x.f
        );
        let r = w.ratio.expect("a ratio");
        assert!(r.is_finite() && r > 0.0);
    }
    // median_and_worst against the ratios sorted here: 21 pairs, the 11th.
    let mut r: Vec<f64> = walks.iter().map(|w| w.ratio.unwrap()).collect();
    r.sort_by(f64::total_cmp);
    assert_eq!(pbrt::median_and_worst(&walks), Some((r[10], r[0])));
}
