//! Media with an SGGX or a mixture phase function, through whole walks
//! (the kernels alone: `tests/physics/phase_sggx.rs`).
//!
//! * **Direction-dependent extinction.** An absorbing SGGX layer between
//!   index-matched smooth boundaries transmits exactly
//!   `exp(−τ sqrt(ωᵀSω) / |cos θ|)`, computed here from the full 3×3 matrix
//!   in f64 (the walks have one path and no variance).
//! * **Energy.** A lossless SGGX slab between smooth dielectrics has
//!   R + T = 1 within 3 standard errors, at normal and grazing incidence,
//!   from both sides, for specular and diffuse flakes, surface flakes and
//!   fibres.
//! * **Spheres.** Roughness 1 (S = I) with specular flakes is the isotropic
//!   phase function: eval and albedo agree with an isotropic medium within
//!   4 combined standard errors (different random walks, the same BSDF).
//! * **Reciprocity.** Reflection off an SGGX stack with a tilted axis is
//!   symmetric, `f(wi, wo) = f(wo, wi)`, within 4 combined standard errors.
//! * **Mixtures.** Two lobes of the same `g` are that lobe: the same BSDF
//!   from other random numbers (the mixture's sampler and value against
//!   each other: the chi-square of `tests/physics/phase_sggx.rs`).
//!
//! Tolerances: 3 or 4 standard errors with fixed seeds; the exact
//! transmittance to 2e-6 relative (single precision through the walk).

use crate::common;
use crate::common::batches::{Batches, MaterialBatches};
use common::reference::Acc;
use common::*;
use strata_bsdf::{Materials, Settings};

fn sggx(flakes: &str, axis: [f64; 3], r: f64, scattering: &str) -> String {
    format!(
        "{{ kind = \"sggx\", flakes = \"{flakes}\", axis = [{}, {}, {}], roughness = {r}, scattering = \"{scattering}\" }}",
        axis[0], axis[1], axis[2]
    )
}

fn unit(v: [f64; 3]) -> [f64; 3] {
    let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    v.map(|x| x / l)
}

/// `sqrt(ωᵀ S ω)` from the full matrix of the flakes.
fn sigma_scale(flakes: &str, a: [f64; 3], r: f64, w: [f64; 3]) -> f64 {
    let r2 = r * r;
    let mut s = [[0.0; 3]; 3];
    for (i, row) in s.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            let id = if i == j { 1.0 } else { 0.0 };
            *x = match flakes {
                "surface" => r2 * id + (1.0 - r2) * a[i] * a[j],
                _ => id - (1.0 - r2) * a[i] * a[j],
            };
        }
    }
    let mut q = 0.0;
    for i in 0..3 {
        for j in 0..3 {
            q += w[i] * s[i][j] * w[j];
        }
    }
    q.sqrt()
}

#[test]
fn absorbing_sggx_layer_transmits_exactly() {
    let tau = 0.7;
    for (flakes, axis, r) in [
        ("surface", unit([0.3, -0.2, 1.0]), 0.2),
        ("fiber", unit([1.0, 0.5, 0.2]), 0.5),
        ("surface", [0.0, 0.0, 1.0], 0.01),
        ("fiber", [1.0, 0.0, 0.0], 0.01),
    ] {
        let toml = format!(
            "[[layers]]\ninterface = {{ kind = \"dielectric\", ior = 1.0 }}\n\
             medium = {{ thickness = 1.0, sigma_t = {tau}, albedo = 0.0, phase = {} }}\n\
             [[layers]]\ninterface = {{ kind = \"dielectric\", ior = 1.0 }}\n",
            sggx(flakes, axis, r, "specular")
        );
        let st = stack(&toml);
        let eng = Walks::new(&st, Settings::default());
        for (theta, phi) in [
            (0.0, 0.0),
            (30.0, 10.0),
            (45.0, 100.0),
            (60.0, 200.0),
            (80.0, 300.0),
        ] {
            let wi = dir(theta, phi);
            let a = eng.albedo(wi, 16, 1, 0);
            let d = wi.map(|x| -x);
            let want = (-tau * sigma_scale(flakes, axis, r, d) / wi[2]).exp();
            for c in 0..3 {
                let got = a.transmitted.value[c];
                assert!(
                    (got - want).abs() <= 2e-6 * want + 1e-9,
                    "{flakes} r {r} θ {theta} φ {phi}: T = {got}, exp(-τσ/μ) = {want}"
                );
                assert_eq!(a.transmitted.stderr[c], 0.0, "one path, no variance");
                assert_eq!(a.reflected.value[c], 0.0);
            }
        }
    }
}

/// R + T per walk, from `n` walks of `sample`.
fn energy(eng: &Walks, wi: [f64; 3], n: u64, query: u64) -> Acc {
    let mut acc = Acc::default();
    for s in eng.samples(wi, n, 11, query) {
        acc.push(s.map_or(0.0, |s| s.weight[1] as f64));
    }
    acc
}

#[test]
fn lossless_sggx_slab_conserves_energy() {
    for (flakes, axis, r, scattering) in [
        ("surface", unit([0.5, 0.0, 1.0]), 0.1, "specular"),
        ("fiber", unit([1.0, 1.0, 0.3]), 0.3, "specular"),
        ("surface", unit([0.0, 0.3, 1.0]), 0.5, "diffuse"),
        ("fiber", [0.0, 1.0, 0.0], 0.05, "diffuse"),
    ] {
        let toml = format!(
            "[[layers]]\ninterface = {{ kind = \"dielectric\", ior = 1.5 }}\n\
             medium = {{ thickness = 1.0, sigma_t = 2.0, albedo = 1.0, phase = {} }}\n\
             [[layers]]\ninterface = {{ kind = \"dielectric\", ior = 1.0 }}\n",
            sggx(flakes, axis, r, scattering)
        );
        let st = stack(&toml);
        let eng = Walks::new(&st, Settings::default());
        for (q, (theta, side)) in [(0.0, 1.0), (85.0, 1.0), (0.0, -1.0), (85.0, -1.0)]
            .into_iter()
            .enumerate()
        {
            let mut wi = dir(theta, 40.0);
            wi[2] *= side;
            let e = energy(&eng, wi, 4000, q as u64);
            let what = format!("{flakes} r {r} {scattering}: θi {theta} side {side}");
            assert_z(&what, e.mean(), 1.0, e.stderr(), 3.0, 1e-5);
        }
    }
}

#[test]
fn sggx_spheres_are_the_isotropic_phase() {
    let slab = |phase: &str| {
        format!(
            "[[layers]]\ninterface = {{ kind = \"dielectric\", ior = 1.4, roughness = 0.2 }}\n\
             medium = {{ thickness = 1.0, sigma_t = 1.5, albedo = 0.9, phase = {phase} }}\n\
             [[layers]]\ninterface = {{ kind = \"diffuse\", albedo = 0.4 }}\n"
        )
    };
    let iso = stack(&slab("{ kind = \"isotropic\" }"));
    let sph = stack(&slab(&sggx(
        "surface",
        unit([0.3, 0.1, 1.0]),
        1.0,
        "specular",
    )));
    let (a, b) = (
        Walks::new(&iso, Settings::default()),
        Walks::new(&sph, Settings::default()),
    );
    for (q, (wi, wo)) in [
        (dir(0.0, 0.0), dir(30.0, 90.0)),
        (dir(60.0, 0.0), dir(45.0, 180.0)),
        (dir(80.0, 30.0), dir(10.0, 0.0)),
    ]
    .into_iter()
    .enumerate()
    {
        let (x, y) = (
            a.eval(wi, wo, 20_000, 3, q as u64),
            b.eval(wi, wo, 20_000, 4, q as u64),
        );
        for c in 0..3 {
            let s = x.stderr[c].hypot(y.stderr[c]);
            assert_z(
                &format!("pair {q} ch {c}"),
                y.value[c],
                x.value[c],
                s,
                4.0,
                1e-6,
            );
        }
    }
}

#[test]
fn reflection_off_sggx_is_reciprocal() {
    for scattering in ["specular", "diffuse"] {
        let toml = format!(
            "[[layers]]\ninterface = {{ kind = \"dielectric\", ior = 1.5, roughness = 0.3 }}\n\
             medium = {{ thickness = 1.0, sigma_t = 2.0, albedo = 0.9, phase = {} }}\n\
             [[layers]]\ninterface = {{ kind = \"diffuse\", albedo = 0.5 }}\n",
            sggx("fiber", unit([1.0, 0.2, 1.0]), 0.3, scattering)
        );
        let st = stack(&toml);
        let eng = Walks::new(&st, Settings::default());
        for (q, (wi, wo)) in [
            (dir(20.0, 0.0), dir(50.0, 120.0)),
            (dir(70.0, 45.0), dir(30.0, 270.0)),
            (dir(5.0, 10.0), dir(80.0, 200.0)),
        ]
        .into_iter()
        .enumerate()
        {
            let x = eng.eval(wi, wo, 30_000, 5, q as u64);
            let y = eng.eval(wo, wi, 30_000, 6, q as u64);
            for c in 0..3 {
                let s = x.stderr[c].hypot(y.stderr[c]);
                let what = format!("{scattering} pair {q} ch {c}");
                assert_z(&what, x.value[c], y.value[c], s, 4.0, 1e-6);
            }
        }
    }
}

#[test]
fn a_mixture_of_equal_lobes_is_the_lobe() {
    let slab = |phase: &str| {
        format!(
            "[[layers]]\ninterface = {{ kind = \"dielectric\", ior = 1.5 }}\n\
             medium = {{ thickness = 1.0, sigma_t = 3.0, albedo = 0.95, phase = {phase} }}\n\
             [[layers]]\ninterface = {{ kind = \"diffuse\", albedo = 0.5 }}\n"
        )
    };
    let one = stack(&slab("{ kind = \"hg\", g = 0.6 }"));
    let two = stack(&slab(
        "{ kind = \"mixture\", components = [{ weight = 0.25, kind = \"hg\", g = 0.6 }, \
         { weight = 0.75, kind = \"hg\", g = 0.6 }] }",
    ));
    let (a, b) = (
        Walks::new(&one, Settings::default()),
        Walks::new(&two, Settings::default()),
    );
    let (wi, wo) = (dir(30.0, 0.0), dir(40.0, 160.0));
    let (x, y) = (a.eval(wi, wo, 20_000, 7, 0), b.eval(wi, wo, 20_000, 8, 0));
    for c in 0..3 {
        let s = x.stderr[c].hypot(y.stderr[c]);
        assert_z(&format!("ch {c}"), y.value[c], x.value[c], s, 4.0, 1e-6);
    }
}

/// Bad phase values are errors that name the layer, the field and the value.
#[test]
fn bad_phase_values_are_errors_naming_layer_and_field() {
    let material = |phase: &str| {
        format!(
            "[[layers]]\ninterface = {{ kind = \"dielectric\", ior = 1.5 }}\n\
             [[layers]]\ninterface = {{ kind = \"dielectric\", ior = 1.3 }}\n\
             medium = {{ thickness = 1.0, sigma_t = 1.0, phase = {phase} }}\n\
             [[layers]]\ninterface = {{ kind = \"diffuse\", albedo = 0.5 }}\n"
        )
    };
    let hg = |w: f64, g: f64| format!("{{ weight = {w}, kind = \"hg\", g = {g} }}");
    for (phase, want) in [
        (
            sggx("surface", [1.0, 1.0, 0.0], 0.5, "specular"),
            "layer 1: medium.phase.axis = [1, 1, 0]: must be a unit vector",
        ),
        (
            sggx("fiber", [0.0, 0.0, 1.0], 0.0, "specular"),
            "layer 1: medium.phase.roughness = 0: must be in [0.0001, 1]",
        ),
        (
            sggx("fiber", [0.0, 0.0, 1.0], 1.5, "diffuse"),
            "layer 1: medium.phase.roughness = 1.5",
        ),
        (
            "{ kind = \"sggx\", flakes = \"surface\", axis = [0, 0, 1], roughness = nan }".into(),
            "layer 1: medium.phase.roughness = NaN: must be a finite number",
        ),
        (
            format!("{{ kind = \"mixture\", components = [{}, {}] }}", hg(0.5, 0.3), hg(0.4, 0.1)),
            "layer 1: medium.phase.components[..].weight = 0.9: the weights must sum to 1",
        ),
        (
            format!("{{ kind = \"mixture\", components = [{}, {}] }}", hg(0.0, 0.3), hg(1.0, 0.1)),
            "layer 1: medium.phase.components[0].weight = 0: must be in (0, 1]",
        ),
        (
            format!("{{ kind = \"mixture\", components = [{}, {}] }}", hg(0.5, 0.3), hg(0.5, 1.0)),
            "layer 1: medium.phase.components[1].g = 1: must be in (-1, 1)",
        ),
        (
            "{ kind = \"mixture\", components = [{ weight = 1.0, kind = \"hg\" }] }".into(),
            "layer 1: medium.phase.components[0].g: an hg lobe needs `g`",
        ),
        (
            "{ kind = \"mixture\", components = [{ weight = 1.0, kind = \"isotropic\", g = 0.2 }] }"
                .into(),
            "layer 1: medium.phase.components[0].g = 0.2: an isotropic lobe has no `g`",
        ),
        (
            "{ kind = \"mixture\", components = [] }".into(),
            "layer 1: medium.phase.components = 0: a mixture needs 1 to 4 components",
        ),
    ] {
        let e = strata_bsdf::LayerStack::from_toml_str(&material(&phase))
            .expect_err(&phase)
            .to_string();
        assert!(e.contains(want), "{phase}: {e}");
    }
    // Unknown fields and kinds are parse errors, not silently ignored.
    for phase in [
        "{ kind = \"sggx\", flakes = \"plates\", axis = [0, 0, 1], roughness = 0.5 }",
        "{ kind = \"sggx\", flakes = \"fiber\", axis = [0, 0, 1], roughness = 0.5, g = 0.1 }",
    ] {
        assert!(
            strata_bsdf::LayerStack::from_toml_str(&material(phase)).is_err(),
            "{phase}"
        );
    }
}

/// An SGGX roughness and axis set per query: a query answers, bit for bit,
/// what a BSDF built from its set's material answers (the phase rows reach
/// the same kernels), and a set is the stack of the file with its values.
#[test]
fn sggx_parameters_per_query_are_their_materials() {
    use serde_json::json;
    use strata_bsdf::stack::SetPath;
    use strata_bsdf::LayeredBsdf;
    let base = stack(
        "[[layers]]\ninterface = { kind = \"dielectric\", ior = 1.5, roughness = 0.2 }\n\
         medium = { thickness = 1.0, sigma_t = 2.0, albedo = 0.9, phase = { kind = \"sggx\", flakes = \"fiber\", axis = [1, 0, 0], roughness = 0.3 } }\n\
         [[layers]]\ninterface = { kind = \"diffuse\", albedo = 0.5 }\n",
    );
    let set = |r: f64, a: [f64; 3]| {
        let entries: Vec<(SetPath, serde_json::Value)> = vec![
            (
                "layers[0].medium.phase.roughness".parse().unwrap(),
                json!(r),
            ),
            ("layers[0].medium.phase.axis".parse().unwrap(), json!(a)),
        ];
        base.with_set(&entries).unwrap()
    };
    let variants = [
        set(0.3, [1.0, 0.0, 0.0]),
        set(0.05, [0.0, 0.6, 0.8]),
        set(0.9, [0.0, 0.0, 1.0]),
    ];
    let file = stack(
        "[[layers]]\ninterface = { kind = \"dielectric\", ior = 1.5, roughness = 0.2 }\n\
         medium = { thickness = 1.0, sigma_t = 2.0, albedo = 0.9, phase = { kind = \"sggx\", flakes = \"fiber\", axis = [0, 0.6, 0.8], roughness = 0.05 } }\n\
         [[layers]]\ninterface = { kind = \"diffuse\", albedo = 0.5 }\n",
    );
    assert!(variants[1] == file, "a set is the file with its values");
    let bsdf = LayeredBsdf::new(base.clone()).samples(64).seed(3);
    let sets = Materials::new(&bsdf, variants.clone());
    let pairs: Vec<_> = [(20.0, 40.0), (60.0, 10.0), (5.0, 80.0), (45.0, 45.0)]
        .iter()
        .map(|&(a, b)| (vec3(dir(a, 0.0)), vec3(dir(b, 120.0))))
        .collect();
    let which = [0u32, 1, 2, 1];
    let got = sets.eval_batch(&which, &pairs).unwrap();
    for (q, &s) in which.iter().enumerate() {
        let own = LayeredBsdf::new(variants[s as usize].clone())
            .samples(64)
            .seed(3);
        let want = own.eval_batch(&pairs).unwrap();
        assert_eq!(got[q], want[q], "query {q}, set {s}");
    }
    let plain = bsdf.eval_batch(&pairs).unwrap();
    assert_eq!(got[0], plain[0], "set 0 is the base material");
    assert_ne!(got[1], plain[1], "the sets change the answers");
}
