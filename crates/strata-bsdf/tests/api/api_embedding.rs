//! The API a renderer embeds: the pdf `sample` returns, the transport mode,
//! and the batch calls over flat slices.
//!
//! What checks what: `sample`'s pdf against `pdf` is an identity of the API
//! (same number, bit for bit); importance eval against an independent f64
//! formula of a rough dielectric (Walter et al. 2007, `common::reference`)
//! and against radiance eval with the directions swapped (walks started
//! from the other side) checks the adjoint's physics; the slice forms
//! against the `Vec3` batches are identities of the API on both engines.

use crate::common;
use crate::common::batches::{Batches, Buffers};

use common::{dir, reference, vec3};
use glam::Vec3;
use strata_bsdf::{
    AlbedoRecord, Engine, Estimator, EvalRecord, EvalStart, LayerStack, LayeredBsdf, SampleFlags,
    SampleRecord, Transport, Vectors, VectorsMut,
};

use crate::common::{COATED_COPPER, SCATTERING_SLAB as SLAB};

/// A rough dielectric interface alone: air above, glass below (exteriors of
/// different IOR, so the two transport modes differ in transmission).
const ROUGH_GLASS: &str = crate::common::ROUGH_GLASS;

/// A smooth coat over a scattering medium over glass: delta lobes, media
/// and transmission between different exteriors.
const COATED_SLAB: &str = r#"
    [[layers]]
    interface = { kind = "dielectric", ior = 1.5 }
    medium = { thickness = 0.5, sigma_t = [1.0, 2.0, 0.5], albedo = 0.8, phase = { kind = "hg", g = 0.3 } }
    [[layers]]
    interface = { kind = "dielectric", ior = 1.33, roughness = 0.2 }
"#;

fn bsdf(toml: &str) -> LayeredBsdf {
    LayeredBsdf::new(common::stack(toml)).samples(64).seed(11)
}

fn incident() -> Vec<Vec3> {
    let mut v = Vec::new();
    for t in [5.0, 30.0, 60.0, 85.0, 120.0, 170.0] {
        for p in [0.0, 77.0] {
            v.push(vec3(dir(t, p)));
        }
    }
    v
}

#[test]
fn sample_carries_the_pdf_that_pdf_gives() {
    for toml in [COATED_COPPER, SLAB, COATED_SLAB, ROUGH_GLASS] {
        for engine in [Engine::Scalar, Engine::Wavefront, Engine::Auto] {
            let b = bsdf(toml).engine(engine);
            let wis: Vec<Vec3> = incident().into_iter().cycle().take(96).collect();
            let index: Vec<u64> = (0..wis.len() as u64).collect();
            let samples = b.sample_batch(&wis, &index).unwrap();
            let mut exited = 0;
            for (&wi, s) in wis.iter().zip(&samples) {
                let Some(s) = s else { continue };
                exited += 1;
                let p = b.pdf(wi, s.wo).unwrap();
                assert_eq!(
                    s.pdf.to_bits(),
                    p.to_bits(),
                    "{engine:?} wi {wi} wo {}",
                    s.wo
                );
                assert!(s.pdf > 0.0 && s.pdf.is_finite());
            }
            assert!(
                exited > 20,
                "{engine:?}: only {exited} walks left the stack"
            );
            // Single samples too, and a direction given at another length.
            let s = (0..64)
                .find_map(|i| b.sample(wis[1], i).unwrap())
                .expect("a walk leaves");
            assert_eq!(s.pdf, b.pdf(wis[1], s.wo).unwrap());
            assert_eq!(s.pdf, b.pdf(wis[1] * 3.0, s.wo * 0.5).unwrap());
        }
    }
}

#[test]
fn reflection_is_the_same_in_both_modes() {
    for toml in [COATED_COPPER, COATED_SLAB] {
        let r = bsdf(toml);
        let i = bsdf(toml).transport(Transport::Importance);
        let (wi, wo) = (vec3(dir(30.0, 0.0)), vec3(dir(50.0, 140.0)));
        assert_eq!(r.eval(wi, wo).unwrap(), i.eval(wi, wo).unwrap());
        let wis = incident();
        let idx: Vec<u64> = (0..wis.len() as u64).collect();
        let (a, b) = (
            r.sample_batch(&wis, &idx).unwrap(),
            i.sample_batch(&wis, &idx).unwrap(),
        );
        for (a, b) in a.iter().zip(&b) {
            match (a, b) {
                (Some(a), Some(b)) if a.reflection => assert_eq!(a, b),
                (Some(a), Some(b)) => {
                    assert_eq!((a.wo, a.pdf), (b.wo, b.pdf));
                }
                (None, None) => {}
                _ => panic!("the modes walked differently: {a:?} {b:?}"),
            }
        }
    }
}

/// Importance eval of a lone rough dielectric is the adjoint: the radiance
/// BSDF with the directions swapped, from an independent f64 formula.
#[test]
fn importance_eval_is_the_adjoint_of_a_rough_dielectric() {
    let r = bsdf(ROUGH_GLASS);
    let i = bsdf(ROUGH_GLASS).transport(Transport::Importance);
    let cases = [
        (dir(30.0, 0.0), dir(150.0, 180.0)),
        (dir(60.0, 20.0), dir(160.0, 190.0)),
        (dir(140.0, 0.0), dir(20.0, 170.0)),
        (dir(170.0, 40.0), dir(45.0, 200.0)),
    ];
    for (a, b) in cases {
        let (na, nb) = (
            if a[2] > 0.0 { 1.0 } else { 1.5 },
            if b[2] > 0.0 { 1.0 } else { 1.5 },
        );
        let (above, below) = (1.0, 1.5);
        // f(b → a): light from b, leaving along a.
        let adjoint = reference::rough_dielectric(0.3, above, below, b, a);
        let fi = i.eval(vec3(a), vec3(b)).unwrap();
        let fr = r.eval(vec3(a), vec3(b)).unwrap();
        for c in 0..3 {
            // One interface: eval is its closed form, so only f32 rounding differs.
            let tol = 1e-3 * adjoint + 1e-6;
            assert!(
                (fi.value[c] - adjoint).abs() <= tol,
                "importance f({a:?}, {b:?}) = {} vs adjoint {adjoint}",
                fi.value[c]
            );
            let s = (na / nb) * (na / nb);
            assert!((fi.value[c] - fr.value[c] * s).abs() <= 1e-12 * fi.value[c]);
        }
    }
}

/// Importance eval from one side against radiance eval from the other: two
/// independent sets of walks (each from its own `wi`: `EvalStart::Wi`) of a
/// stack with media, delta lobes and transmission between different
/// exteriors.
#[test]
fn importance_eval_matches_radiance_with_directions_swapped() {
    let i = bsdf(COATED_SLAB)
        .transport(Transport::Importance)
        .eval_start(EvalStart::Wi)
        .samples(1 << 16);
    let r = bsdf(COATED_SLAB).eval_start(EvalStart::Wi).samples(1 << 16);
    for (a, b) in [
        (dir(20.0, 0.0), dir(140.0, 200.0)),
        (dir(150.0, 30.0), dir(50.0, 170.0)),
        (dir(40.0, 0.0), dir(60.0, 130.0)),
    ] {
        let fi = i.eval(vec3(a), vec3(b)).unwrap();
        let fr = r.eval(vec3(b), vec3(a)).unwrap();
        for c in 0..3 {
            let se = (fi.stderr[c].powi(2) + fr.stderr[c].powi(2)).sqrt();
            common::assert_z(
                &format!("importance f({a:?},{b:?})[{c}] vs radiance f(b, a)"),
                fi.value[c],
                fr.value[c],
                se,
                4.0,
                0.0,
            );
        }
    }
}

#[test]
fn importance_albedo_scales_transmission_only() {
    let r = bsdf(COATED_SLAB);
    let i = bsdf(COATED_SLAB).transport(Transport::Importance);
    for (wi, s) in [
        (dir(30.0, 0.0), 1.0 / 1.33f64.powi(2)),
        (dir(150.0, 0.0), 1.33f64.powi(2)),
    ] {
        let (a, b) = (
            r.albedo(vec3(wi), 512).unwrap(),
            i.albedo(vec3(wi), 512).unwrap(),
        );
        assert_eq!(a.reflected, b.reflected);
        for c in 0..3 {
            let want = a.transmitted.value[c] * s;
            assert!((b.transmitted.value[c] - want).abs() <= 1e-12 * want);
            assert!(a.transmitted.value[c] > 0.0);
        }
    }
}

fn soa(v: &[[f32; 3]]) -> [Vec<f32>; 3] {
    [0, 1, 2].map(|c| v.iter().map(|x| x[c]).collect())
}

#[test]
fn slice_calls_answer_what_the_batches_answer() {
    let wis: Vec<[f32; 3]> = incident().iter().map(|v| v.to_array()).collect();
    let wos: Vec<[f32; 3]> = incident().iter().rev().map(|v| v.to_array()).collect();
    let pairs: Vec<(Vec3, Vec3)> = wis
        .iter()
        .zip(&wos)
        .map(|(&a, &b)| (Vec3::from(a), Vec3::from(b)))
        .collect();
    let n = wis.len();
    for toml in [COATED_COPPER, COATED_SLAB] {
        for engine in [Engine::Scalar, Engine::Wavefront] {
            let b = bsdf(toml).engine(engine);
            let (si, so) = (soa(&wis), soa(&wos));
            let svi = Vectors::Soa([&si[0], &si[1], &si[2]]);
            let svo = Vectors::Soa([&so[0], &so[1], &so[2]]);

            // eval: AoS, SoA and records, unkeyed and keyed.
            let want = b.eval_batch(&pairs).unwrap();
            let (mut f, mut e) = (vec![[0.0f32; 3]; n], vec![[0.0f32; 3]; n]);
            b.eval_buffers(
                Vectors::Aos(&wis),
                Vectors::Aos(&wos),
                None,
                VectorsMut::Aos(&mut f),
                Some(VectorsMut::Aos(&mut e)),
            )
            .unwrap();
            let mut fs = [vec![0.0f32; n], vec![0.0f32; n], vec![0.0f32; n]];
            {
                let [x, y, z] = &mut fs;
                b.eval_buffers(svi, svo, None, VectorsMut::Soa([x, y, z]), None)
                    .unwrap();
            }
            let mut rec = vec![EvalRecord::default(); n];
            b.eval_records(svi, Vectors::Aos(&wos), None, &mut rec)
                .unwrap();
            for k in 0..n {
                let w = want[k].value.map(|x| x as f32);
                assert_eq!(f[k], w);
                assert_eq!(e[k], want[k].stderr.map(|x| x as f32));
                assert_eq!([fs[0][k], fs[1][k], fs[2][k]], w);
                assert_eq!(rec[k].f, w);
            }
            let keys: Vec<u64> = (0..n as u64).map(|k| k * 7919 + 1).collect();
            let want = b.eval_batch_keyed(&pairs, 64, &keys).unwrap();
            b.eval_buffers(svi, svo, Some(&keys), VectorsMut::Aos(&mut f), None)
                .unwrap();
            for k in 0..n {
                assert_eq!(f[k], want[k].value.map(|x| x as f32));
            }

            // sample: unkeyed = the batch with sample index k; keyed = index 0.
            let v3: Vec<Vec3> = wis.iter().map(|&a| Vec3::from(a)).collect();
            let idx: Vec<u64> = (0..n as u64).collect();
            let want = b.sample_batch(&v3, &idx).unwrap();
            let mut recs = vec![SampleRecord::default(); n];
            b.sample_records(Vectors::Aos(&wis), None, &mut recs)
                .unwrap();
            let (mut wo, mut wt) = (vec![[9.0f32; 3]; n], vec![[9.0f32; 3]; n]);
            let (mut pdf, mut flags) = (vec![9.0f32; n], vec![9u32; n]);
            b.sample_buffers(
                svi,
                None,
                VectorsMut::Aos(&mut wo),
                VectorsMut::Aos(&mut wt),
                &mut pdf,
                &mut flags,
            )
            .unwrap();
            for k in 0..n {
                let r = recs[k];
                assert_eq!(
                    (wo[k], wt[k], pdf[k], flags[k]),
                    (r.wo, r.weight, r.pdf, r.flags)
                );
                match want[k] {
                    Some(s) => {
                        assert_eq!((r.wo, r.weight, r.pdf), (s.wo.to_array(), s.weight, s.pdf));
                        let side = if s.reflection {
                            SampleFlags::REFLECTION
                        } else {
                            SampleFlags::TRANSMISSION
                        };
                        assert_eq!(r.flags & 3, side);
                        assert_eq!(r.flags & SampleFlags::DELTA != 0, s.specular);
                    }
                    None => assert_eq!(r, SampleRecord::default()),
                }
            }
            let want = b.sample_batch_keyed(&v3, &keys, &vec![0; n]).unwrap();
            b.sample_records(Vectors::Aos(&wis), Some(&keys), &mut recs)
                .unwrap();
            for k in 0..n {
                assert_eq!(recs[k].weight, want[k].map_or([0.0; 3], |s| s.weight));
            }

            // pdf and albedo.
            let want = b.pdf_batch(&pairs).unwrap();
            let mut p = vec![0.0f32; n];
            b.pdf_buffers(svi, svo, &mut p).unwrap();
            assert_eq!(p, want);
            let want = b.albedo_batch(&v3, 256).unwrap();
            let mut a = vec![AlbedoRecord::default(); n];
            b.albedo_records(svi, 256, None, &mut a).unwrap();
            for k in 0..n {
                assert_eq!(a[k].reflected, want[k].reflected.value.map(|x| x as f32));
                assert_eq!(
                    a[k].transmitted_stderr,
                    want[k].transmitted.stderr.map(|x| x as f32)
                );
            }
        }
    }
}

#[test]
fn slice_errors_name_the_query_and_the_field() {
    let b = bsdf(COATED_COPPER);
    let good = [[0.0f32, 0.0, 1.0]; 4];
    let mut bad = good;
    bad[2] = [f32::NAN, 0.0, 1.0];
    let mut f = [[7.0f32; 3]; 4];
    let e = b
        .eval_buffers(
            Vectors::Aos(&good),
            Vectors::Aos(&bad),
            None,
            VectorsMut::Aos(&mut f),
            None,
        )
        .unwrap_err();
    assert_eq!(e.index, Some(2));
    assert_eq!(
        e.to_string(),
        "query 2: wo = [NaN, 0, 1] is not a direction: components must be finite"
    );
    assert_eq!(f, [[7.0; 3]; 4], "nothing is written on an error");

    let zero = [[0.0f32; 3]; 4];
    let e = b
        .pdf_buffers(Vectors::Aos(&zero), Vectors::Aos(&good), &mut [0.0; 4])
        .unwrap_err();
    assert_eq!(
        e.to_string(),
        "query 0: wi = [0, 0, 0] is not a direction: it has zero length"
    );

    let (x, y) = ([0.0f32; 4], [0.0f32; 3]);
    let z = [1.0f32; 4];
    let e = b
        .sample_records(
            Vectors::Soa([&x, &y, &z]),
            None,
            &mut [SampleRecord::default(); 4],
        )
        .unwrap_err();
    assert_eq!(e.index, None);
    assert_eq!(
        e.to_string(),
        "wi.y has 3 entries for 4 queries: give one per query"
    );

    let e = b
        .eval_buffers(
            Vectors::Aos(&good),
            Vectors::Aos(&good[..3]),
            None,
            VectorsMut::Aos(&mut f),
            None,
        )
        .unwrap_err();
    assert_eq!(
        e.to_string(),
        "wo has 3 entries for 4 queries: give one per query"
    );
    let e = b
        .eval_records(
            Vectors::Aos(&good),
            Vectors::Aos(&good),
            None,
            &mut [EvalRecord::default(); 5],
        )
        .unwrap_err();
    assert_eq!(
        e.to_string(),
        "out has 5 entries for 4 queries: give one per query"
    );
    let e = b
        .sample_records(
            Vectors::Aos(&good),
            Some(&[1, 2]),
            &mut [SampleRecord::default(); 4],
        )
        .unwrap_err();
    assert_eq!(
        e.to_string(),
        "keys has 2 entries for 4 queries: give one per query"
    );
    let (mut r, mut g) = (vec![0.0f32; 4], vec![0.0f32; 2]);
    let mut bb = vec![0.0f32; 4];
    let e = b
        .eval_buffers(
            Vectors::Aos(&good),
            Vectors::Aos(&good),
            None,
            VectorsMut::Soa([&mut r, &mut g, &mut bb]),
            None,
        )
        .unwrap_err();
    assert_eq!(
        e.to_string(),
        "f.g has 2 entries for 4 queries: give one per query"
    );
    let e = b
        .albedo_records(
            Vectors::Aos(&good),
            0,
            None,
            &mut [AlbedoRecord::default(); 4],
        )
        .unwrap_err();
    assert_eq!(e.to_string(), "walks = 0: at least one walk is needed");

    // Empty batches are fine and write nothing.
    b.eval_buffers(
        Vectors::Aos(&[]),
        Vectors::Aos(&[]),
        None,
        VectorsMut::Aos(&mut []),
        None,
    )
    .unwrap();
    assert!(Vectors::from_flat(&[0.0; 4]).is_none());
    assert_eq!(
        Vectors::from_flat(&[0.0, 0.0, 1.0, 1.0, 0.0, 0.0])
            .unwrap()
            .get(1),
        Vec3::X
    );
}

#[test]
fn transport_names_parse() {
    assert_eq!("importance".parse::<Transport>(), Ok(Transport::Importance));
    assert_eq!("radiance".parse::<Transport>(), Ok(Transport::Radiance));
    assert!("light"
        .parse::<Transport>()
        .unwrap_err()
        .contains("\"light\""));
    assert_eq!(Transport::default(), Transport::Radiance);
    let _ = LayerStack::from_toml_str(SLAB).unwrap();
}

/// `EvalStart::Normal` starts a reflected pair from the direction nearer the
/// normal under a smooth coat, and from the one farther from it under a
/// rough coat: its walks are, bit for bit, `EvalStart::Wi`'s from that
/// side (with the query's key), in either order of the pair.
#[test]
fn normal_start_is_the_grazing_side_under_a_rough_coat() {
    let stack = |coat: &str| {
        format!(
            "[[layers]]\ninterface = {{ kind = \"dielectric\", ior = 1.5{coat} }}\n\
             medium = {{ thickness = 0.01, sigma_t = 1.0, albedo = 0.0 }}\n\
             [[layers]]\ninterface = {{ kind = \"conductor\", preset = \"Cu\", roughness = 0.1 }}\n"
        )
    };
    let (grazing, steep) = (vec3(dir(75.0, 0.0)), vec3(dir(40.0, 180.0)));
    for (coat, start) in [("", steep), (", roughness = 0.1", grazing)] {
        let toml = stack(coat);
        let walks = |s| {
            bsdf(&toml)
                .estimator(Estimator::Unidirectional)
                .eval_start(s)
        };
        let (normal, from_wi) = (walks(EvalStart::Normal), walks(EvalStart::Wi));
        for (a, b) in [(grazing, steep), (steep, grazing)] {
            let x = normal.eval_with(a, b, 64, 9).unwrap();
            let (from, to) = if a == start { (a, b) } else { (b, a) };
            let y = from_wi.eval_with(from, to, 64, 9).unwrap();
            assert!(x.value[0] > 0.0, "{coat}: {x:?}");
            assert_eq!(x.value, y.value, "coat{coat}: from {from:?}");
        }
    }
}

/// Walks from the side `EvalStart::Normal` picks (the default) against walks
/// from `wi`: independent estimates of the same f, on every example
/// material and two transmissive stacks with different exteriors (where the
/// η² relation carries the value across), at pairs in both orders (in one
/// of which the start differs).
#[test]
fn eval_from_the_side_normal_picks_is_unbiased() {
    let dirs = std::fs::read_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/materials")).unwrap();
    let mut stacks: Vec<(String, String)> = dirs
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .map(|p| {
            (
                p.display().to_string(),
                std::fs::read_to_string(&p).unwrap(),
            )
        })
        .collect();
    stacks.sort();
    assert!(stacks.len() >= 7, "{} example materials", stacks.len());
    stacks.push(("coated slab".into(), COATED_SLAB.into()));
    stacks.push(("rough glass".into(), ROUGH_GLASS.into()));
    let mut compared = 0;
    for (name, toml) in &stacks {
        let walks = |s| {
            bsdf(toml)
                .samples(1 << 14)
                .estimator(Estimator::Unidirectional)
                .eval_start(s)
        };
        let (normal, from_wi) = (walks(EvalStart::Normal), walks(EvalStart::Wi));
        let st = common::stack(toml);
        let mut pairs = vec![
            (dir(85.0, 0.0), dir(0.0, 0.0)),
            (dir(70.0, 20.0), dir(30.0, 200.0)),
        ];
        if st.transmissive() {
            pairs.push((dir(80.0, 0.0), dir(170.0, 160.0)));
            pairs.push((dir(100.0, 10.0), dir(20.0, 190.0)));
        }
        // Each pair in both orders: in one of them the two starts differ
        // (the nearer side under a smooth entrance, the farther under a
        // rough one, for reflected pairs).
        let pairs: Vec<_> = pairs
            .into_iter()
            .flat_map(|(a, b)| [(a, b), (b, a)])
            .collect();
        for (k, &(a, b)) in pairs.iter().enumerate() {
            let (x, y) = (
                normal.eval(vec3(a), vec3(b)).unwrap(),
                from_wi.eval(vec3(a), vec3(b)).unwrap(),
            );
            // A tilted stack is not reciprocal: its walks start at wi
            // whatever the rule says (method.md §9).
            let tilted = (0..st.len()).any(|i| st.interface(i).tilted());
            if tilted {
                assert_eq!(x, y, "{name}: a tilted stack starts at wi");
                continue;
            }
            if k % 2 == 1 && y.value != [0.0; 3] {
                let (c, d) = pairs[k - 1];
                let same = normal.eval(vec3(c), vec3(d)).unwrap()
                    == from_wi.eval(vec3(c), vec3(d)).unwrap();
                assert!(
                    !(same && x == y),
                    "{name}: the two starts ran the same walks in both orders"
                );
            }
            for c in 0..3 {
                let se = (x.stderr[c].powi(2) + y.stderr[c].powi(2)).sqrt();
                common::assert_z(
                    &format!("{name} f({a:?}, {b:?})[{c}] from the normal side vs from wi"),
                    x.value[c],
                    y.value[c],
                    se,
                    4.0,
                    1e-6 * y.value[c].abs(),
                );
                compared += (y.value[c] > 0.0) as u32;
            }
        }
    }
    assert!(compared > 60, "only {compared} nonzero values compared");
    // A lone rough dielectric's eval is its closed form either way: the
    // value carried across by the η² relation equals the formula.
    let b = bsdf(ROUGH_GLASS);
    for (a, c) in [
        (dir(80.0, 0.0), dir(135.0, 180.0)),
        (dir(150.0, 0.0), dir(20.0, 180.0)),
    ] {
        assert!(c[2].abs() > a[2].abs(), "the walks start from wo");
        let f = b.eval(vec3(a), vec3(c)).unwrap().value[0];
        let want = reference::rough_dielectric(0.3, 1.0, 1.5, a, c);
        assert!(
            want > 0.0 && (f - want).abs() <= 1e-3 * want,
            "f = {f}, formula {want}"
        );
    }
}

/// The closed form `Estimator::Auto` gives a smooth coat over a clear or
/// absorbing layer over a Lambertian base, against the unidirectional walks
/// (which it replaces): chromatic absorbers, another exterior, a coat less
/// dense than the exterior, light from below a two-sided stack.
#[test]
fn closed_form_agrees_with_the_walks() {
    let stacks = [
        "[[layers]]\ninterface = { kind = \"dielectric\", ior = 1.5 }\n\
         medium = { thickness = 0.01, sigma_t = 1.0, albedo = 0.0 }\n\
         [[layers]]\ninterface = { kind = \"diffuse\", albedo = 0.8 }\n",
        "[[layers]]\ninterface = { kind = \"dielectric\", ior = 1.7 }\n\
         medium = { thickness = 0.4, sigma_t = [0.2, 1.0, 3.0], albedo = 0.0 }\n\
         [[layers]]\ninterface = { kind = \"diffuse\", albedo = [0.9, 0.5, 0.2] }\n",
        "exterior_ior = 1.33\n[[layers]]\ninterface = { kind = \"dielectric\", ior = 1.5 }\n\
         [[layers]]\ninterface = { kind = \"diffuse\", albedo = 1.0 }\n",
        "exterior_ior = 1.6\n[[layers]]\ninterface = { kind = \"dielectric\", ior = 1.2 }\n\
         medium = { thickness = 1.0, sigma_t = 0.3, albedo = 0.0 }\n\
         [[layers]]\ninterface = { kind = \"diffuse\", albedo = 0.6 }\n",
        "exterior_ior = 1.6\n[[layers]]\ninterface = { kind = \"dielectric\", ior = 1.2 }\n\
         [[layers]]\ninterface = { kind = \"diffuse\", albedo = 0.9 }\n",
        "two_sided = true\n[[layers]]\ninterface = { kind = \"dielectric\", ior = 1.5 }\n\
         [[layers]]\ninterface = { kind = \"diffuse\", albedo = 0.7 }\n",
    ];
    let pairs = [
        (dir(0.0, 0.0), dir(0.0, 0.0)),
        (dir(30.0, 0.0), dir(60.0, 120.0)),
        (dir(85.0, 0.0), dir(10.0, 200.0)),
        (dir(70.0, 30.0), dir(88.0, 10.0)),
    ];
    let mut compared = 0;
    for toml in stacks {
        let exact = bsdf(toml);
        assert!(exact.eval_is_exact(), "{toml}");
        let walks = bsdf(toml)
            .estimator(Estimator::Unidirectional)
            .samples(1 << 17);
        let mut ps = pairs.to_vec();
        if common::stack(toml).two_sided() {
            ps.push((dir(150.0, 0.0), dir(120.0, 90.0)));
        }
        for (a, b) in ps {
            let x = exact.eval(vec3(a), vec3(b)).unwrap();
            let y = walks.eval(vec3(a), vec3(b)).unwrap();
            assert_eq!(x.stderr, [0.0; 3]);
            assert!(x.value.iter().all(|v| v.is_finite()), "{toml}: {x:?}");
            for c in 0..3 {
                if x.value[c] == 0.0 {
                    // Total reflection from outside (a coat less dense than
                    // the exterior): no walk enters either.
                    assert_eq!(y.value[c], 0.0, "{toml}: f({a:?}, {b:?})");
                    continue;
                }
                common::assert_z(
                    &format!("{toml} f({a:?}, {b:?})[{c}]: closed form vs walks"),
                    x.value[c],
                    y.value[c],
                    y.stderr[c],
                    4.0,
                    2e-6 * x.value[c],
                );
                compared += 1;
            }
        }
    }
    assert!(compared >= 54, "{compared} nonzero values compared");
    // Where light cannot leave (below a one-sided opaque stack): zero.
    let b = bsdf(stacks[0]);
    assert_eq!(
        b.eval(vec3(dir(30.0, 0.0)), vec3(dir(120.0, 0.0)))
            .unwrap()
            .value,
        [0.0; 3]
    );
    // A scattering layer or a rough coat has no closed form: walks answer.
    for toml in [SLAB, COATED_COPPER, COATED_SLAB] {
        assert!(!bsdf(toml).eval_is_exact());
        let e = bsdf(toml)
            .eval(vec3(dir(30.0, 0.0)), vec3(dir(40.0, 180.0)))
            .unwrap();
        assert!(e.stderr.iter().any(|&s| s > 0.0), "{toml}: {e:?}");
    }
}

/// The API's choices (walks from the side nearer the normal, the transport
/// factor) are made the same way on both engines: a transmissive stack with
/// different exteriors, in both modes, at pairs that swap and pairs that do
/// not, answers bit for bit the same on the scalar engine (query by query)
/// and on the wavefront (one batch).
#[test]
fn both_engines_answer_the_same_with_swaps_and_importance() {
    let pairs: Vec<(Vec3, Vec3)> = [
        (dir(80.0, 0.0), dir(135.0, 180.0)),
        (dir(150.0, 0.0), dir(20.0, 180.0)),
        (dir(20.0, 0.0), dir(70.0, 100.0)),
        (dir(60.0, 30.0), dir(10.0, 200.0)),
        (dir(100.0, 0.0), dir(170.0, 40.0)),
    ]
    .iter()
    .map(|&(a, b)| (vec3(a), vec3(b)))
    .collect();
    for transport in [Transport::Radiance, Transport::Importance] {
        for toml in [COATED_SLAB, ROUGH_GLASS] {
            let b = |e| bsdf(toml).transport(transport).engine(e).samples(256);
            let s = b(Engine::Scalar).eval_batch(&pairs).unwrap();
            let w = b(Engine::Wavefront).eval_batch(&pairs).unwrap();
            assert_eq!(s, w, "{transport:?} {toml}");
            assert!(s.iter().any(|e| e.value[0] > 0.0));
        }
    }
}
