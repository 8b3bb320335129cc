//! `Config`: a BSDF's configuration as one value with one text form. What
//! it prints parses back to the same value; a setting it does not take is an
//! error naming the key and the value, and sets nothing; a BSDF given a
//! configuration answers bit for bit what the builder calls of the same
//! settings make.

use crate::common::batches::Batches;
use crate::common::{COATED_COPPER, VARNISH_OVER_SCATTERING};
use glam::Vec3;
use strata_bsdf::{
    Config, Engine, Estimator, EvalStart, LayerStack, LayeredBsdf, PdfWalks, Transport, CONFIG_KEYS,
};

fn bsdf(toml: &str) -> LayeredBsdf {
    LayeredBsdf::new(LayerStack::from_toml_str(toml).unwrap())
}

#[test]
fn what_it_prints_parses_back() {
    let default = Config::default();
    let text = default.to_string();
    let keys: Vec<&str> = text
        .split_whitespace()
        .map(|p| p.split_once('=').unwrap().0)
        .collect();
    assert_eq!(keys, CONFIG_KEYS);
    assert_eq!(text.parse::<Config>().unwrap(), default);
    assert_eq!(bsdf(COATED_COPPER).config(), default);
    for text in [
        "samples=1 pdf_walks=adaptive seed=7 transport=importance",
        "eval_start=wi estimator=bidir engine=scalar threads=1",
        "threads=3 max_events=77 rr_start=2 rr_threshold=0.25",
        "max_scatter_order=1 mis=false pdf_walks=16,128,0.1",
        "pdf_walks=12 estimator=uni engine=wavefront threads=current",
    ] {
        let c: Config = text.parse().unwrap();
        assert_eq!(c.to_string().parse::<Config>().unwrap(), c, "{text}");
        for pair in text.split_whitespace() {
            let (key, value) = pair.split_once('=').unwrap();
            assert_eq!(c.get(key).as_deref(), Some(value), "{text}");
        }
    }
    let c: Config = "estimator=unidirectional".parse().unwrap();
    assert_eq!(c.get("estimator").as_deref(), Some("uni"));
}

#[test]
fn a_setting_it_does_not_take_names_the_key_and_the_value() {
    for (text, key, value) in [
        ("samples=0", "samples", "0"),
        ("samples=many", "samples", "many"),
        ("seed=-1", "seed", "-1"),
        ("pdf_walks=sometimes", "pdf_walks", "sometimes"),
        ("transport=light", "transport", "light"),
        ("eval_start=wo", "eval_start", "wo"),
        ("estimator=best", "estimator", "best"),
        ("engine=gpu", "engine", "gpu"),
        ("threads=0", "threads", "0"),
        ("threads=100000", "threads", "100000"),
        ("max_events=0", "max_events", "0"),
        ("max_events=99999999", "max_events", "99999999"),
        ("rr_threshold=2", "rr_threshold", "2"),
        ("rr_threshold=NaN", "rr_threshold", "NaN"),
        ("max_scatter_order=some", "max_scatter_order", "some"),
        ("mis=yes", "mis", "yes"),
        ("colour=red", "colour", "red"),
        ("samples", "samples", ""),
    ] {
        let mut c: Config = "samples=5 seed=3".parse().unwrap();
        let before = c.clone();
        let e = c.apply(&format!("seed=9 {text}")).unwrap_err();
        assert_eq!((e.key.as_str(), e.value.as_str()), (key, value), "{text}");
        assert!(
            e.to_string().starts_with(&format!("{key}={value}: ")),
            "{e}"
        );
        assert_eq!(c, before, "{text}: nothing is set");
    }
}

/// The builder calls of each setting, for comparison.
fn built(b: LayeredBsdf) -> LayeredBsdf {
    b.max_events(50)
        .rr_threshold(0.25)
        .samples(3)
        .pdf_walks(PdfWalks::fixed(4))
        .seed(7)
        .transport(Transport::Importance)
        .eval_start(EvalStart::Wi)
        .estimator(Estimator::Unidirectional)
        .engine(Engine::Scalar)
        .threads(1)
        .unwrap()
}

#[test]
fn a_configured_bsdf_answers_what_the_builder_calls_make() {
    let text = "max_events=50 rr_threshold=0.25 samples=3 pdf_walks=4 seed=7 \
                transport=importance eval_start=wi estimator=uni engine=scalar threads=1";
    let c: Config = text.parse().unwrap();
    let pairs: Vec<(Vec3, Vec3)> = (0..12)
        .map(|k| {
            let t = k as f32 * 0.1;
            (
                Vec3::new(0.3 - t, 0.2, 0.8).normalize(),
                Vec3::new(-0.4, t - 0.5, 0.7).normalize(),
            )
        })
        .collect();
    for toml in [COATED_COPPER, VARNISH_OVER_SCATTERING] {
        let configured = bsdf(toml).with_config(&c).unwrap();
        let by_calls = built(bsdf(toml));
        assert_eq!(configured.config(), c);
        assert_eq!(by_calls.config(), c);
        let (a, b) = (configured.eval_batch(&pairs), by_calls.eval_batch(&pairs));
        assert_eq!(format!("{a:?}"), format!("{b:?}"));
        let (a, b) = (configured.pdf_batch(&pairs), by_calls.pdf_batch(&pairs));
        assert_eq!(format!("{a:?}"), format!("{b:?}"));
        // And back to the defaults.
        let back = configured.with_config(&Config::default()).unwrap();
        let (a, b) = (back.eval_batch(&pairs), bsdf(toml).eval_batch(&pairs));
        assert_eq!(format!("{a:?}"), format!("{b:?}"));
        assert_eq!(back.config(), Config::default());
    }
    let two = bsdf(COATED_COPPER)
        .with_config(&"threads=2".parse().unwrap())
        .unwrap();
    assert_eq!(two.config().threads, Some(2));
}
