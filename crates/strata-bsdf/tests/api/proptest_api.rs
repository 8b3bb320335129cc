//! Property tests of the public API against bad and extreme input (proptest).
//!
//! * Directions: arbitrary `f32` triples (NaN, infinities, zeros, denormals,
//!   huge values, ordinary values) into every query of [`LayeredBsdf`], single
//!   and batch, on both engines. A non-finite component is
//!   `QueryError::NonFinite`, a zero vector `QueryError::ZeroLength`, each
//!   naming the argument; a batch reports its first bad query by index with
//!   the same error as the single query; valid directions never give a NaN,
//!   an infinity or a negative value; light arriving at (or leaving from) the
//!   back of a one-sided opaque stack gives exact zeros; an opaque stack
//!   never transmits; a batch answers exactly what single queries answer.
//! * Materials: arbitrary descriptions (every field drawn from ordinary,
//!   extreme and invalid values) either build or fail with an error that names
//!   the field; a stack that builds answers every query with finite,
//!   non-negative numbers on both engines. Arbitrary text into the TOML, JSON
//!   and query-line parsers never panics.
//!
//! Fixed seeds (`RngSeed::Fixed`) make the runs reproducible, and no
//! regression files are written.

use crate::common::batches::Batches;
use glam::Vec3;
use proptest::prelude::*;
use proptest::test_runner::{Config, RngSeed};
use strata_bsdf::estimator::wavefront::{DefaultWide, PDF_CHUNK, SERIAL_WALKS};
use strata_bsdf::lane::Lane;
use strata_bsdf::stack::{
    Distribution, InterfaceDesc, LayerDesc, MaterialDesc, MediumDesc, PhaseDesc, RgbParam,
    Roughness, Shadowing,
};
use strata_bsdf::{Engine, LayerStack, LayeredBsdf, PdfWalks, QueryError, Settings};

fn config(cases: u32, seed: u64) -> Config {
    Config {
        cases,
        rng_seed: RngSeed::Fixed(seed),
        failure_persistence: None,
        ..Config::default()
    }
}

// ------------------------------------------------------------- directions

const SPECIAL_F32: [f32; 16] = [
    0.0,
    -0.0,
    f32::NAN,
    f32::INFINITY,
    f32::NEG_INFINITY,
    f32::MAX,
    -f32::MAX,
    f32::MIN_POSITIVE,
    1e-45,
    -1e-45,
    1e-20,
    1e20,
    1e-7,
    -1e-7,
    1.0,
    -1.0,
];

fn any_f32() -> impl Strategy<Value = f32> {
    prop_oneof![
        4 => -1.0f32..1.0,
        2 => prop::sample::select(SPECIAL_F32.to_vec()),
        1 => prop::num::f32::ANY,
    ]
}

fn any_dir() -> impl Strategy<Value = Vec3> {
    (any_f32(), any_f32(), any_f32()).prop_map(|(x, y, z)| Vec3::new(x, y, z))
}

/// What the API must say about `v`, decided here from the documented rules:
/// `Some(true)` valid, `Some(false)` an error, `None` for lengths so small that
/// either answer is allowed (below 1e-20, where normalizing is meaningless).
fn expected_validity(v: Vec3) -> Option<bool> {
    if !v.is_finite() {
        return Some(false);
    }
    let l = v.as_dvec3().length();
    if l == 0.0 {
        Some(false)
    } else if l >= 1e-20 {
        Some(true)
    } else {
        None
    }
}

fn check_error(e: &QueryError, argument: &str, v: Vec3) {
    match *e {
        QueryError::NonFinite { argument: a, .. } => {
            assert_eq!(a, argument);
            assert!(!v.is_finite(), "NonFinite for finite {v}");
        }
        QueryError::ZeroLength { argument: a, .. } => {
            assert_eq!(a, argument);
            assert!(v.is_finite(), "ZeroLength for non-finite {v}");
        }
        ref other => panic!("a bad direction gave {other:?}"),
    }
    assert!(
        e.to_string().contains(argument),
        "message names {argument}: {e}"
    );
}

/// The stacks the direction properties run on.
struct Subject {
    name: &'static str,
    transmissive: bool,
    two_sided: bool,
    bsdfs: Vec<LayeredBsdf>,
}

fn subjects() -> Vec<Subject> {
    let mats = [
        (
            "rough coat over copper, absorbing medium (one-sided)",
            crate::common::ROUGH_COAT_ABSORBER_COPPER,
        ),
        (
            "smooth coat over a scattering medium and a Lambertian base, two-sided",
            r#"
            two_sided = true
            [[layers]]
            interface = { kind = "dielectric", ior = 1.5 }
            medium = { thickness = 1.0, sigma_t = 1.0, albedo = 0.9, phase = { kind = "hg", g = 0.5 } }
            [[layers]]
            interface = { kind = "diffuse", albedo = 0.7 }
            "#,
        ),
        (
            "transmissive scattering slab",
            r#"
            [[layers]]
            interface = { kind = "dielectric", ior = 1.4, roughness = 0.3 }
            medium = { thickness = 1.0, sigma_t = [1.0, 2.0, 3.0], albedo = 0.95 }
            [[layers]]
            interface = { kind = "dielectric", ior = 1.0, roughness = 0.2 }
            "#,
        ),
    ];
    mats.iter()
        .map(|(name, toml)| {
            let st = LayerStack::from_toml_str(toml).unwrap();
            let base = LayeredBsdf::new(st.clone()).samples(16).pdf_samples(2);
            Subject {
                name,
                transmissive: st.transmissive(),
                two_sided: st.two_sided(),
                // The pdf's pilot round too, small (2 walks, then 2 to 8).
                bsdfs: vec![
                    base.clone().engine(Engine::Scalar),
                    base.clone().engine(Engine::Wavefront),
                    base.pdf_walks(PdfWalks::adaptive(2, 8, 0.15)),
                ],
            }
        })
        .collect()
}

/// The z of `v` normalized in f64, as 0 for directions the API treats as
/// grazing (documented: |cos| below `strata_bsdf::estimator::MIN_COS`, 1e-18).
fn unit_z(v: Vec3) -> Option<f64> {
    let d = v.as_dvec3();
    let z = d.z / d.length();
    Some(if z.abs() < strata_bsdf::estimator::MIN_COS {
        0.0
    } else {
        z
    })
}

/// Whether light from `wi` can reach `wo` at all on this stack (0 otherwise),
/// from the conventions: grazing directions see nothing; an opaque stack
/// reflects only; a one-sided opaque stack only from above.
fn reachable(s: &Subject, wi: Vec3, wo: Vec3) -> Option<bool> {
    let (a, c) = (unit_z(wi)?, unit_z(wo)?);
    if a == 0.0 || c == 0.0 {
        return Some(false);
    }
    if s.transmissive {
        return Some(true);
    }
    let same_side = (a > 0.0) == (c > 0.0);
    Some(same_side && (s.two_sided || a > 0.0))
}

/// Whether light from `wi` enters the stack at all.
fn enters(s: &Subject, wi: Vec3) -> Option<bool> {
    let a = unit_z(wi)?;
    Some(a != 0.0 && (s.transmissive || s.two_sided || a > 0.0))
}

fn finite_nonneg(x: &[f64]) -> bool {
    x.iter().all(|v| v.is_finite() && *v >= 0.0)
}

proptest! {
    #![proptest_config(config(96, 0x5eed_0001))]

    #[test]
    fn eval_validates_directions_and_never_returns_nan(wi in any_dir(), wo in any_dir()) {
        for s in subjects() {
            for b in &s.bsdfs {
                let r = b.eval(wi, wo);
                match (expected_validity(wi), expected_validity(wo), &r) {
                    (Some(false), _, Err(e)) => check_error(e, "wi", wi),
                    (None, _, _) | (Some(true), None, _) | (Some(true), Some(true), Ok(_)) => {}
                    (Some(true), Some(false), Err(e)) => check_error(e, "wo", wo),
                    (a, c, r) => panic!("{}: eval({wi}, {wo}): expected {a:?}/{c:?}, got {r:?}", s.name),
                }
                if let Ok(e) = r {
                    prop_assert!(finite_nonneg(&e.value) && finite_nonneg(&e.stderr),
                        "{}: eval({wi}, {wo}) = {e:?}", s.name);
                    if reachable(&s, wi, wo) == Some(false) {
                        prop_assert_eq!(e.value, [0.0; 3], "{}: eval({}, {}) must be 0", s.name, wi, wo);
                    }
                }
            }
        }
    }

    #[test]
    fn sample_validates_and_stays_on_the_right_side(wi in any_dir(), index in 0u64..1000) {
        for s in subjects() {
            for b in &s.bsdfs {
                let r = b.sample(wi, index);
                match (expected_validity(wi), &r) {
                    (Some(false), Err(e)) => check_error(e, "wi", wi),
                    (Some(true), Ok(_)) | (None, _) => {}
                    (a, r) => panic!("{}: sample({wi}): expected {a:?}, got {r:?}", s.name),
                }
                let Ok(Some(x)) = r else { continue };
                prop_assert!(enters(&s, wi) != Some(false),
                    "{}: a sample for light that cannot enter ({})", s.name, wi);
                prop_assert!(x.wo.is_finite() && (x.wo.length() - 1.0).abs() < 1e-5,
                    "{}: wo = {}", s.name, x.wo);
                prop_assert!(x.weight.iter().all(|w| w.is_finite() && *w >= 0.0),
                    "{}: weight {:?}", s.name, x.weight);
                prop_assert_eq!(x.reflection, (x.wo.z > 0.0) == (wi.z > 0.0));
                prop_assert!(s.transmissive || x.reflection, "{}: an opaque stack transmitted", s.name);
            }
        }
    }

    #[test]
    fn pdf_and_albedo_validate_and_stay_finite(wi in any_dir(), wo in any_dir()) {
        for s in subjects() {
            for b in &s.bsdfs {
                match (expected_validity(wi), expected_validity(wo), b.pdf(wi, wo)) {
                    (Some(false), _, Err(e)) => check_error(&e, "wi", wi),
                    (None, _, _) | (Some(true), None, _) => {}
                    (Some(true), Some(false), Err(e)) => check_error(&e, "wo", wo),
                    (Some(true), Some(true), Ok(p)) => {
                        prop_assert!(p.is_finite() && p >= 0.0, "{}: pdf {}", s.name, p);
                        match reachable(&s, wi, wo) {
                            Some(true) => prop_assert!(p > 0.0, "{}: pdf 0 where f may be positive", s.name),
                            Some(false) => prop_assert_eq!(p, 0.0, "{}: pdf({}, {})", s.name, wi, wo),
                            None => {}
                        }
                    }
                    (a, c, r) => panic!("{}: pdf: expected {a:?}/{c:?}, got {r:?}", s.name),
                }
                match (expected_validity(wi), b.albedo(wi, 16)) {
                    (Some(false), Err(e)) => check_error(&e, "wi", wi),
                    (None, Err(_)) => {}
                    (Some(true) | None, Ok(al)) => {
                        for e in [al.reflected, al.transmitted] {
                            prop_assert!(finite_nonneg(&e.value) && finite_nonneg(&e.stderr),
                                "{}: albedo {:?}", s.name, e);
                        }
                        if !s.transmissive {
                            prop_assert_eq!(al.transmitted.value, [0.0; 3]);
                        }
                        if enters(&s, wi) == Some(false) {
                            prop_assert_eq!(al.reflected.value, [0.0; 3]);
                        }
                    }
                    (a, r) => panic!("{}: albedo: expected {a:?}, got {r:?}", s.name),
                }
            }
        }
    }
}

proptest! {
    #![proptest_config(config(48, 0x5eed_0002))]

    /// Batches: the first bad query is reported by index with the single
    /// query's error; otherwise every answer is the single query's, bit for bit.
    #[test]
    fn batches_answer_as_single_queries(
        pairs in prop::collection::vec((any_dir(), any_dir()), 0..6),
    ) {
        // Skip the ambiguous tiny lengths: the property is about the rest.
        prop_assume!(pairs.iter().all(|(a, b)| expected_validity(*a).is_some() && expected_validity(*b).is_some()));
        let wis: Vec<Vec3> = pairs.iter().map(|p| p.0).collect();
        let idx: Vec<u64> = (0..pairs.len() as u64).collect();
        for s in subjects() {
            for b in &s.bsdfs {
                let first_bad = pairs.iter().position(|(a, c)| {
                    expected_validity(*a) == Some(false) || expected_validity(*c) == Some(false)
                });
                let first_bad_wi = wis.iter().position(|a| expected_validity(*a) == Some(false));
                match (b.eval_batch(&pairs), first_bad) {
                    (Err(e), Some(k)) => {
                        prop_assert_eq!(e.index, Some(k));
                        // Debug text: the error's value may hold a NaN, which is never == itself.
                        let single = b.eval(pairs[k].0, pairs[k].1).map(|_| ());
                        prop_assert_eq!(format!("{:?}", Err::<(), QueryError>(e.error)), format!("{single:?}"));
                    }
                    (Ok(v), None) => {
                        for (k, (a, c)) in pairs.iter().enumerate() {
                            prop_assert_eq!(v[k], b.eval(*a, *c).unwrap(), "{}: eval {}", s.name, k);
                        }
                    }
                    (r, k) => panic!("{}: eval_batch: first bad {k:?}, got {r:?}", s.name),
                }
                match (b.pdf_batch(&pairs), first_bad) {
                    (Err(e), Some(k)) => prop_assert_eq!(e.index, Some(k)),
                    (Ok(v), None) => {
                        for (k, (a, c)) in pairs.iter().enumerate() {
                            prop_assert_eq!(v[k], b.pdf(*a, *c).unwrap());
                        }
                    }
                    (r, k) => panic!("{}: pdf_batch: first bad {k:?}, got {r:?}", s.name),
                }
                match (b.sample_batch(&wis, &idx), first_bad_wi) {
                    (Err(e), Some(k)) => prop_assert_eq!(e.index, Some(k)),
                    (Ok(v), None) => {
                        for (k, a) in wis.iter().enumerate() {
                            prop_assert_eq!(v[k], b.sample(*a, idx[k]).unwrap());
                        }
                    }
                    (r, k) => panic!("{}: sample_batch: first bad {k:?}, got {r:?}", s.name),
                }
                match (b.albedo_batch(&wis, 8), first_bad_wi) {
                    (Err(e), Some(k)) => prop_assert_eq!(e.index, Some(k)),
                    (Ok(v), None) => {
                        for (k, a) in wis.iter().enumerate() {
                            prop_assert_eq!(v[k], b.albedo(*a, 8).unwrap());
                        }
                    }
                    (r, k) => panic!("{}: albedo_batch: first bad {k:?}, got {r:?}", s.name),
                }
            }
        }
    }
}

// -------------------------------------------------------------- materials

const SPECIAL_F64: [f64; 20] = [
    f64::NAN,
    f64::INFINITY,
    f64::NEG_INFINITY,
    0.0,
    -0.0,
    1.0,
    f64::MAX,
    f64::MIN_POSITIVE,
    5e-324,
    1e300,
    1e39,
    3.5e38,
    1e-39,
    1e-46,
    0.999,
    0.999_999_9,
    -0.999_999_9,
    1.0 - 1e-12,
    1e6,
    1e-6,
];

/// A value of a field whose ordinary range is `lo..hi`: ordinary most of the
/// time (so that most descriptions are valid and get queried), a positive
/// power of ten from 1e-50 to 1e50 often (extreme but valid for most fields),
/// and a special value (NaN, infinities, zeros, f64 extremes, values beyond
/// single precision, near-1) now and then.
fn field(lo: f64, hi: f64) -> impl Strategy<Value = f64> {
    prop_oneof![
        12 => lo..hi,
        2 => (-50i32..50).prop_map(|e| 10f64.powi(e)),
        1 => prop::sample::select(SPECIAL_F64.to_vec()),
    ]
}

/// A number, three, or now and then a tabulated spectrum (of any length,
/// in any order: the invalid ones are errors, never a panic).
fn rgb(lo: f64, hi: f64) -> impl Strategy<Value = RgbParam> {
    prop_oneof![
        6 => field(lo, hi).prop_map(RgbParam::Grey),
        6 => (field(lo, hi), field(lo, hi), field(lo, hi))
            .prop_map(|(a, b, c)| RgbParam::Rgb([a, b, c])),
        1 => (
            prop::collection::vec(field(300.0, 900.0), 0..4),
            prop::collection::vec(field(lo, hi), 0..4)
        )
            .prop_map(|(nm, values)| RgbParam::Tabulated { nm, values }),
    ]
}

/// An IOR: a number, or now and then a spectrum or a dispersion law.
fn ior() -> impl Strategy<Value = RgbParam> {
    prop_oneof![
        12 => field(1.0, 3.0).prop_map(RgbParam::Grey),
        1 => (
            prop::collection::vec(field(300.0, 900.0), 0..4),
            prop::collection::vec(field(1.0, 3.0), 0..4)
        )
            .prop_map(|(nm, values)| RgbParam::Tabulated { nm, values }),
        1 => (field(1.0, 3.0), field(-0.1, 0.1)).prop_map(|(a, b)| RgbParam::Cauchy { cauchy: [a, b] }),
        1 => (field(1.0, 3.0), field(-10.0, 100.0)).prop_map(|(nd, abbe)| RgbParam::Abbe { nd, abbe }),
    ]
}

fn any_roughness() -> impl Strategy<Value = Roughness> {
    prop_oneof![
        2 => Just(Roughness::Isotropic(0.0)),
        3 => field(0.0, 1.0).prop_map(Roughness::Isotropic),
        1 => (field(0.0, 1.0), field(0.0, 1.0)).prop_map(|(a, b)| Roughness::Anisotropic([a, b])),
    ]
}

fn any_distribution() -> impl Strategy<Value = (Distribution, Shadowing)> {
    (any::<bool>(), any::<bool>()).prop_map(|(b, s)| {
        (
            if b {
                Distribution::Beckmann
            } else {
                Distribution::Ggx
            },
            if s {
                Shadowing::Separable
            } else {
                Shadowing::Correlated
            },
        )
    })
}

/// Mostly untilted; sometimes a tilted normal, now and then one that points
/// down or has zero length (errors).
fn any_normal() -> impl Strategy<Value = Option<[f64; 3]>> {
    prop_oneof![
        4 => Just(None),
        2 => (field(-1.0, 1.0), field(-1.0, 1.0), field(-0.2, 1.0)).prop_map(|(x, y, z)| Some([x, y, z])),
    ]
}

fn dielectric() -> impl Strategy<Value = InterfaceDesc> {
    (ior(), any_roughness(), any_distribution(), any_normal()).prop_map(
        |(ior, roughness, (distribution, shadowing), normal)| InterfaceDesc::Dielectric {
            ior,
            roughness,
            distribution,
            shadowing,
            normal,
        },
    )
}

fn conductor() -> impl Strategy<Value = InterfaceDesc> {
    let presets = prop::sample::select(vec!["Cu", "Au", "Ag", "Al", "Cr", "unobtainium"]);
    // Mostly a preset alone or eta and k; sometimes both or neither (errors).
    let spec = prop_oneof![
        3 => presets.clone().prop_map(|p| (Some(p.to_string()), None, None)),
        4 => (rgb(0.05, 3.0), rgb(0.0, 10.0)).prop_map(|(e, k)| (None, Some(e), Some(k))),
        1 => (prop::option::of(presets), prop::option::of(rgb(0.05, 3.0)), prop::option::of(rgb(0.0, 10.0)))
            .prop_map(|(p, e, k)| (p.map(String::from), e, k)),
    ];
    (spec, any_roughness(), any_distribution(), any_normal()).prop_map(
        |((preset, eta, k), roughness, (distribution, shadowing), normal)| {
            InterfaceDesc::Conductor {
                preset,
                eta,
                k,
                roughness,
                distribution,
                shadowing,
                normal,
            }
        },
    )
}

fn any_medium() -> impl Strategy<Value = Option<MediumDesc>> {
    let phase = prop_oneof![
        Just(PhaseDesc::Isotropic {}),
        field(-1.0, 1.0).prop_map(|g| PhaseDesc::Hg { g }),
        prop::sample::select(vec![0.999, -0.999, 0.999_999, -0.999_999_99, 1.0])
            .prop_map(|g| PhaseDesc::Hg { g }),
    ];
    prop::option::of(
        (field(0.0, 3.0), rgb(0.0, 5.0), rgb(0.0, 1.0), phase).prop_map(
            |(thickness, sigma_t, albedo, phase)| MediumDesc {
                thickness,
                sigma_t,
                albedo,
                phase,
            },
        ),
    )
}

/// Dielectric layers over a last layer of any kind, with media between;
/// now and then an opaque layer out of place or a medium under the last.
fn any_material() -> impl Strategy<Value = MaterialDesc> {
    let last = prop_oneof![
        2 => dielectric(),
        2 => conductor(),
        1 => (rgb(0.0, 1.0), any_normal()).prop_map(|(albedo, normal)| InterfaceDesc::Diffuse { albedo, normal }),
    ];
    let upper = prop_oneof![8 => dielectric(), 1 => conductor()];
    (
        prop_oneof![4 => Just(1.0), 1 => field(1.0, 2.0)],
        any::<bool>(),
        prop::collection::vec((upper, any_medium()), 0..3),
        last,
        prop_oneof![9 => Just(None), 1 => any_medium()],
    )
        .prop_map(|(exterior_ior, two_sided, upper, last, last_medium)| {
            let mut layers: Vec<LayerDesc> = upper
                .into_iter()
                .map(|(interface, medium)| LayerDesc { interface, medium })
                .collect();
            layers.push(LayerDesc {
                interface: last,
                medium: last_medium,
            });
            MaterialDesc {
                description: None,
                exterior_ior,
                two_sided,
                layers,
            }
        })
}

/// Directions that probe every configuration: normal, grazing (cos 1e-7),
/// both hemispheres.
fn probe_dirs() -> Vec<Vec3> {
    let g = 1e-7f32;
    vec![
        Vec3::Z,
        -Vec3::Z,
        Vec3::new(0.6, 0.0, 0.8),
        Vec3::new(-0.3, 0.5, -0.7).normalize(),
        Vec3::new(1.0, 0.0, g),
        Vec3::new(0.0, -1.0, -g),
    ]
}

proptest! {
    #![proptest_config(config(3000, 0x5eed_0003))]

    /// Any description builds or fails with an error naming its field; a stack
    /// that builds gives finite, non-negative answers on both engines.
    #[test]
    fn arbitrary_materials_build_or_fail_cleanly(desc in any_material()) {
        let st = match LayerStack::new(&desc) {
            Err(e) => {
                prop_assert!(!e.field.is_empty());
                prop_assert!(e.to_string().contains(&e.field), "{e}");
                if let Some(l) = e.layer {
                    prop_assert!(l < desc.layers.len());
                }
                return Ok(());
            }
            Ok(st) => st,
        };


        // A cap on walk length bounds the test's time (a lossless stack with
        // optical depth 1e50 has walks of unbounded expected length; the
        // stress suite measures them). Finiteness is what is tested here.
        let settings = Settings { max_events: 2_000, ..Settings::default() };
        let base = LayeredBsdf::with_settings(st, settings).samples(8).pdf_samples(2);
        let dirs = probe_dirs();
        for b in [base.clone().engine(Engine::Scalar), base.engine(Engine::Wavefront)] {
            for &wi in &dirs {
                for &wo in &dirs {
                    let e = b.eval(wi, wo).unwrap();
                    prop_assert!(finite_nonneg(&e.value) && finite_nonneg(&e.stderr),
                        "{desc:?}\neval({wi}, {wo}) = {e:?}");
                    let p = b.pdf(wi, wo).unwrap();
                    prop_assert!(p.is_finite() && p >= 0.0, "{desc:?}\npdf({wi}, {wo}) = {p}");
                }
                for k in 0..4 {
                    if let Some(x) = b.sample(wi, k).unwrap() {
                        prop_assert!(x.wo.is_finite() && (x.wo.length() - 1.0).abs() < 1e-4,
                            "{desc:?}\nsample({wi}) wo = {}", x.wo);
                        prop_assert!(x.weight.iter().all(|w| w.is_finite() && *w >= 0.0),
                            "{desc:?}\nsample({wi}) weight = {:?}", x.weight);
                    }
                }
                let a = b.albedo(wi, 8).unwrap();
                for e in [a.reflected, a.transmitted] {
                    prop_assert!(finite_nonneg(&e.value) && finite_nonneg(&e.stderr),
                        "{desc:?}\nalbedo({wi}) = {e:?}");
                }
            }
        }
    }

    /// The parsers never panic on arbitrary text (the fuzz targets in fuzz/
    /// go further).
    #[test]
    fn parsers_never_panic(s in "\\PC{0,200}") {
        let _ = LayerStack::from_toml_str(&s);
        let _ = LayerStack::from_json_str(&s);
        let _ = strata_bsdf::query::parse_query_line(&s);
    }
}

/// Per-query arguments of a keyed batch must have one entry per query, and a
/// walk count must be from 1 to `MAX_WALKS`: errors naming the argument on
/// both engines, pointing at no query (never a panic, never a silently
/// shorter or wrapped-around answer).
#[test]
fn keyed_batches_check_their_lengths_and_counts() {
    let stack = strata_bsdf::materials::builtin("coated_copper").expect("built-in");
    let pairs = [
        (Vec3::Z, Vec3::new(0.3, 0.0, 0.9)),
        (Vec3::new(0.2, 0.1, 0.9), Vec3::Z),
    ];
    let wis = [Vec3::Z, Vec3::new(0.2, 0.1, 0.9)];
    for engine in [Engine::Auto, Engine::Scalar, Engine::Wavefront] {
        let b = LayeredBsdf::new(stack.clone()).engine(engine);
        let e = b
            .eval_batch_keyed(&pairs, 16, &[1])
            .expect_err("one key for two");
        assert_eq!(e.index, None, "{engine:?}");
        assert_eq!(
            e.to_string(),
            "keys has 1 entries for 2 queries: give one per query"
        );
        let e = b
            .sample_batch_keyed(&wis, &[1, 2], &[0])
            .expect_err("short index");
        assert!(e.to_string().contains("indices"), "{e}");
        let e = b
            .albedo_batch_keyed(&wis, 16, &[1, 2, 3])
            .expect_err("long keys");
        assert_eq!(e.index, None, "{engine:?}");
        assert!(matches!(
            b.eval_with(Vec3::Z, Vec3::Z, 0, 0),
            Err(QueryError::NoSamples { .. })
        ));
        // Too many walks: the wavefront's unit count once wrapped around to
        // zero here (256 queries × u64::MAX walks) and answered from no walk.
        let many = vec![pairs[0]; 256];
        let keys: Vec<u64> = (0..256).collect();
        for n in [strata_bsdf::MAX_WALKS + 1, u64::MAX] {
            let e = b.eval_batch_keyed(&many, n, &keys).expect_err("too many");
            assert_eq!(e.index, None);
            assert_eq!(
                e.error,
                QueryError::TooManySamples {
                    argument: "walks",
                    value: n
                }
            );
            assert!(e.to_string().contains(&format!("walks = {n}")), "{e}");
            let e = b
                .albedo_batch_keyed(&wis, n, &[1, 2])
                .expect_err("too many");
            assert!(e.to_string().starts_with(&format!("walks = {n}")), "{e}");
            assert!(matches!(
                b.eval_with(Vec3::Z, Vec3::Z, n, 0),
                Err(QueryError::TooManySamples { .. })
            ));
        }
        // An empty batch with a bad count names the count, not a query.
        let e = b.eval_batch_keyed(&[], 0, &[]).expect_err("no walks");
        assert_eq!(
            (e.index, e.to_string()),
            (None, "walks = 0: at least one walk is needed".into())
        );
        assert!(matches!(
            b.albedo(Vec3::Z, 0),
            Err(QueryError::NoSamples { .. })
        ));
        assert!(b.eval_batch_keyed(&pairs, 0, &[1, 2]).is_err());
        assert_eq!(
            b.eval_batch_keyed(&pairs, 16, &[1, 2])
                .expect("valid")
                .len(),
            2
        );
    }
}

/// `Engine::Auto`, the default, takes the scalar engine for calls of fewer
/// walks (queries × walks per query) than the wavefront has lanes, and for a
/// single pdf, and the wavefront for the rest. (Which engine answered is not
/// visible in the answers, which agree; the rule is checked on `resolve`.)
#[test]
fn auto_engine_picks_by_walks_per_call() {
    assert_eq!(Engine::default(), Engine::Auto);
    assert_eq!("auto".parse::<Engine>(), Ok(Engine::Auto));
    assert!("simd"
        .parse::<Engine>()
        .unwrap_err()
        .contains("auto, scalar or wavefront"));
    let lanes = <DefaultWide as Lane>::LANES as u64;
    for (queries, walks, want) in [
        (1, 1, Engine::Scalar),
        (1, lanes - 1, Engine::Scalar),
        (lanes as usize - 1, 1, Engine::Scalar),
        (1, lanes, Engine::Wavefront),
        (2, lanes / 2, Engine::Wavefront),
        (1, 256, Engine::Wavefront),
        (usize::MAX, u64::MAX, Engine::Wavefront),
    ] {
        assert_eq!(
            Engine::Auto.resolve(queries, walks),
            want,
            "{queries} x {walks}"
        );
        assert_eq!(Engine::Scalar.resolve(queries, walks), Engine::Scalar);
        assert_eq!(Engine::Wavefront.resolve(queries, walks), Engine::Wavefront);
    }
    let stack = strata_bsdf::materials::builtin("three_interfaces").expect("built-in");
    let auto = LayeredBsdf::new(stack).samples(64).seed(5);
    let scalar = auto.clone().engine(Engine::Scalar);
    let wave = auto.clone().engine(Engine::Wavefront);
    let wis: Vec<Vec3> = (0..12)
        .map(|i| Vec3::new(0.07 * i as f32, -0.03 * i as f32, 1.0).normalize())
        .collect();
    let wo = Vec3::new(-0.4, 0.2, 0.8).normalize();
    let pairs: Vec<(Vec3, Vec3)> = wis.iter().map(|&w| (w, wo)).collect();
    let mut exited = 0;
    for (i, &wi) in wis.iter().enumerate() {
        let s = auto.sample(wi, i as u64).expect("valid");
        assert_eq!(s, scalar.sample(wi, i as u64).expect("valid"));
        exited += s.is_some() as usize;
        assert_eq!(auto.pdf(wi, wo), scalar.pdf(wi, wo));
        // An eval of 64 walks fills the lanes.
        assert_eq!(auto.eval(wi, wo), wave.eval(wi, wo));
    }
    assert!(
        exited > 0,
        "no sample left the stack: the comparison saw nothing"
    );
    let keys: Vec<u64> = (0..wis.len() as u64).collect();
    assert_eq!(
        auto.sample_batch_keyed(&wis, &keys, &keys),
        wave.sample_batch_keyed(&wis, &keys, &keys)
    );
    assert_eq!(auto.pdf_batch(&pairs), wave.pdf_batch(&pairs));
}

/// A call of at most `SERIAL_WALKS` walks (or `PDF_CHUNK` pdf queries) runs
/// on the calling thread, a larger one on the BSDF's pool. A batch just past
/// the limit (the pool) answers exactly what the same queries answer in
/// batches within it (the calling thread), with one thread and with three.
#[test]
fn batches_past_the_calling_thread_limit_answer_as_smaller_ones() {
    let stack = strata_bsdf::materials::builtin("scattering_slab").expect("built-in");
    let s = SERIAL_WALKS as usize;
    let pairs: Vec<(Vec3, Vec3)> = (0..s + 1)
        .map(|i| {
            let t = i as f32 / s as f32;
            (
                Vec3::new(t, 0.2, 1.0).normalize(),
                Vec3::new(-0.3, t, -0.9).normalize(),
            )
        })
        .collect();
    let wis: Vec<Vec3> = pairs.iter().map(|p| p.0).collect();
    let keys: Vec<u64> = (0..pairs.len() as u64).collect();
    for threads in [1, 3] {
        let b = LayeredBsdf::new(stack.clone())
            .engine(Engine::Wavefront)
            .threads(threads)
            .expect("pool");
        // Eval, 64 walks per query: 5 queries are 320 walks (the pool), 4 are
        // 256 (the calling thread).
        let n = s / 64 + 1;
        let big = b
            .eval_batch_keyed(&pairs[..n], 64, &keys[..n])
            .expect("valid");
        let mut parts = b
            .eval_batch_keyed(&pairs[..n - 1], 64, &keys[..n - 1])
            .expect("valid");
        parts.extend(
            b.eval_batch_keyed(&pairs[n - 1..n], 64, &keys[n - 1..n])
                .expect("valid"),
        );
        assert_eq!(big, parts, "eval, {threads} threads");
        // Sample, one walk per query: s + 1 queries against s and 1.
        let big = b.sample_batch_keyed(&wis, &keys, &keys).expect("valid");
        let mut parts = b
            .sample_batch_keyed(&wis[..s], &keys[..s], &keys[..s])
            .expect("valid");
        parts.extend(
            b.sample_batch_keyed(&wis[s..], &keys[s..], &keys[s..])
                .expect("valid"),
        );
        assert_eq!(big, parts, "sample, {threads} threads");
        assert!(big.iter().filter(|x| x.is_some()).count() > s / 2);
        // Pdf: PDF_CHUNK + 1 queries against PDF_CHUNK and 1.
        let m = PDF_CHUNK + 1;
        let big = b.pdf_batch(&pairs[..m]).expect("valid");
        let mut parts = b.pdf_batch(&pairs[..m - 1]).expect("valid");
        parts.extend(b.pdf_batch(&pairs[m - 1..m]).expect("valid"));
        assert_eq!(big, parts, "pdf, {threads} threads");
    }
}

/// A thread pool larger than `MAX_THREADS` is an error naming the count
/// (100 000 threads once took minutes to spawn); up to it, a pool is built.
#[test]
fn thread_pools_are_bounded() {
    let stack = strata_bsdf::materials::builtin("coated_copper").expect("built-in");
    let e = LayeredBsdf::new(stack.clone())
        .threads(strata_bsdf::MAX_THREADS + 1)
        .expect_err("too many");
    assert_eq!(
        e.to_string(),
        "threads = 1025: at most 1024 (0 means one per core)"
    );
    assert!(LayeredBsdf::new(stack.clone()).threads(0).is_ok());
    assert!(LayeredBsdf::new(stack.clone())
        .threads(strata_bsdf::MAX_THREADS)
        .is_ok());
    assert!(LayeredBsdf::new(stack).threads(2).is_ok());
}

/// Any finite nonzero vector is a direction, however large or small its
/// components (1e200 squared overflowed f64 and was called zero length).
#[test]
fn directions_normalize_without_overflow() {
    use strata_bsdf::Direction;
    for (v, want) in [
        ([0.0, 0.0, 1e200], [0.0, 0.0, 1.0]),
        ([1e-200, 0.0, 1e-200], [0.5f64.sqrt(), 0.0, 0.5f64.sqrt()]),
        ([3e307, 4e307, 0.0], [0.6, 0.8, 0.0]),
        ([-5e-324, 0.0, 0.0], [-1.0, 0.0, 0.0]),
    ] {
        let d = Direction::from_f64("wi", v).expect("a direction").get();
        for c in 0..3 {
            assert!((d[c] - want[c]).abs() < 1e-15, "{v:?} -> {d:?}");
        }
    }
    assert!(matches!(
        Direction::from_f64("wo", [0.0, -0.0, 0.0]),
        Err(QueryError::ZeroLength { argument: "wo", .. })
    ));
    assert!(matches!(
        Direction::from_f64("wi", [1e308, f64::INFINITY, 0.0]),
        Err(QueryError::NonFinite { argument: "wi", .. })
    ));
}

/// `pdf_samples(0)` means one walk, as `samples(0)` does: a pdf is never
/// silently the top interface's term alone.
#[test]
fn pdf_samples_are_at_least_one() {
    let stack = strata_bsdf::materials::builtin("coated_copper").expect("built-in");
    let (wi, wo) = (Vec3::new(0.3, 0.0, 0.95), Vec3::new(-0.2, 0.1, 0.97));
    for engine in [Engine::Scalar, Engine::Wavefront] {
        let b = LayeredBsdf::new(stack.clone()).engine(engine);
        let zero = b.clone().pdf_samples(0).pdf(wi, wo).expect("pdf");
        let one = b.clone().pdf_samples(1).pdf(wi, wo).expect("pdf");
        assert_eq!(zero, one, "{engine:?}");
        // The setting is honoured at all: more walks give another estimate.
        let many = b.pdf_samples(64).pdf(wi, wo).expect("pdf");
        assert_ne!(one, many, "{engine:?}");
    }
}

/// A query no light can answer (from below a one-sided opaque stack) is
/// zeros with the requested walk count, on both engines, without running
/// the walks: 2^40 of them answer at once (they took O(n) before).
#[test]
fn trivially_zero_queries_cost_nothing() {
    let stack = strata_bsdf::materials::builtin("coated_copper").expect("built-in");
    let (below, up) = (Vec3::new(0.1, 0.0, -0.9), Vec3::new(0.0, 0.2, 0.9));
    let n = strata_bsdf::MAX_WALKS;
    for engine in [Engine::Scalar, Engine::Wavefront] {
        let b = LayeredBsdf::new(stack.clone()).engine(engine);
        let e = b.eval_with(below, up, n, 7).expect("valid");
        assert_eq!((e.value, e.stderr, e.samples), ([0.0; 3], [0.0; 3], n));
        let a = b.albedo(below, n).expect("valid");
        for x in [a.reflected, a.transmitted] {
            assert_eq!((x.value, x.stderr, x.samples), ([0.0; 3], [0.0; 3], n));
        }
    }
}
