//! Tilted shading normals per interface (method.md §9, "Tilted normals").
//!
//! The model: a tilted interface scatters in its shading frame, `f(a → b)`
//! being the frame's `f(a' → b') |b'.z| / |b.z|`, and an event whose arrival
//! or departure lies on the other side of the shading normal than of the
//! slab's normal carries no light. What must hold, and is checked here:
//!
//! * a lone tilted interface is its rotated BSDF: the engine's eval equals an
//!   independent f64 GGX formula (`common::reference`) at the directions
//!   expressed in the shading frame, times `|wo'.z| / |wo.z|`, and 0 exactly
//!   where the model says; its albedo equals the quadrature of that formula
//!   over the directions the model lets through (4σ);
//! * a slab whose interfaces all share one tilt, with clear layers, is the
//!   untilted slab turned by the tilt, wherever no event meets the other side
//!   of the shading normal: a lossless smooth slab reflects `2r / (1 + r)` and
//!   transmits the rest, R + T = 1 to rounding (furnace), and a smooth coat
//!   over a rough bottom gives the untilted slab's f at the turned
//!   directions, times `|wo'.z| / |wo.z|` (4 combined σ), which makes
//!   `f(wi, wo) |wo.z| / |wo'.z|` reciprocal (checked with walks from both
//!   sides, whose next-event chains differ);
//! * the importance mode's adjoint walks from `wi` agree with radiance walks
//!   from `wo` (`f*(wi → wo) = f(wo → wi)`) where `f` is not reciprocal;
//! * zero tilt is bit-identical to none; a two-sided opaque stack lit from
//!   below answers what its top answers for the negated directions; bad
//!   normals are errors naming the layer, field and value.
//!
//! Walk-by-walk parity of the engines on tilted stacks is in
//! `wavefront_parity.rs`, `sample()` against eval in
//! `layered_sample_vs_eval.rs`, and the sampler's histogram against the
//! unbiased pdf in `pdf_density.rs`; the kernels lane by lane, with untilted
//! lanes inside tilted vectors, in `kernel_parity.rs`.

use crate::common;
use crate::common::batches::{Batches, MaterialBatches};
use common::reference::{fresnel, rough_dielectric, sphere_integral};
use common::*;
use strata_bsdf::{Estimator, LayerStack, LayeredBsdf, Materials, Transport};

fn unit(v: [f64; 3]) -> [f64; 3] {
    let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    v.map(|x| x / l)
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// An orthonormal frame around `n` (any: the tests' roughness is
/// isotropic), as a map of world directions into it.
fn to_frame(n: [f64; 3]) -> impl Fn([f64; 3]) -> [f64; 3] {
    let t = unit(cross([0.0, 1.0, 0.0], n));
    let b = cross(n, t);
    move |w| [dot(w, t), dot(w, b), dot(w, n)]
}

/// The inverse of [`to_frame`].
fn from_frame(n: [f64; 3]) -> impl Fn([f64; 3]) -> [f64; 3] {
    let t = unit(cross([0.0, 1.0, 0.0], n));
    let b = cross(n, t);
    move |l| std::array::from_fn(|i| t[i] * l[0] + b[i] * l[1] + n[i] * l[2])
}

fn bsdf(toml: &str, samples: u64) -> LayeredBsdf {
    LayeredBsdf::new(stack(toml)).samples(samples).seed(11)
}

const TILT: [f64; 3] = [0.3, -0.2, 1.0];

#[test]
fn a_lone_tilted_interface_is_its_rotated_bsdf() {
    let n = unit(TILT);
    let toml = format!(
        "[[layers]]\ninterface = {{ kind = \"dielectric\", ior = 1.5, roughness = 0.3, \
         normal = [{}, {}, {}] }}",
        TILT[0], TILT[1], TILT[2]
    );
    let b = bsdf(&toml, 4);
    let local = to_frame(n);
    let (mut nonzero, mut zero) = (0, 0);
    for ti in [5.0, 35.0, 70.0, 88.0, 130.0, 170.0] {
        for pi in [0.0, 120.0, 240.0] {
            let wi = dir(ti, pi);
            for to in [10.0, 45.0, 80.0, 100.0, 150.0] {
                for po in [30.0, 200.0] {
                    let wo = dir(to, po);
                    let (a, c) = (local(wi), local(wo));
                    // Too near the shading horizon for f32 to decide the side.
                    if a[2].abs() < 1e-3 || c[2].abs() < 1e-3 {
                        continue;
                    }
                    let open = a[2] * wi[2] > 0.0 && c[2] * wo[2] > 0.0;
                    let expected = if open {
                        rough_dielectric(0.3, 1.0, 1.5, a, c) * c[2].abs() / wo[2].abs()
                    } else {
                        0.0
                    };
                    let e = b.eval(vec3(wi), vec3(wo)).unwrap();
                    let what = format!("wi {wi:?} wo {wo:?}");
                    assert_eq!(e.stderr[0], 0.0, "{what}: one interface, no walk returns");
                    let tol = 2e-4 * expected + 1e-6;
                    assert!(
                        (e.value[0] - expected).abs() <= tol,
                        "{what}: {} vs rotated reference {expected}",
                        e.value[0]
                    );
                    if expected > 0.0 {
                        nonzero += 1;
                    } else if !open {
                        zero += 1;
                    }
                }
            }
        }
    }
    assert!(
        nonzero > 60 && zero > 10,
        "{nonzero} values, {zero} closed pairs"
    );

    // Its albedo: what the model lets through, by quadrature of the reference.
    for ti in [20.0, 60.0] {
        let wi = dir(ti, 40.0);
        let a = local(wi);
        let through = |w: [f64; 3], reflected: bool| {
            let c = local(w);
            let open = c[2] * w[2] > 0.0 && (w[2] > 0.0) == reflected;
            if open {
                rough_dielectric(0.3, 1.0, 1.5, a, c) * c[2].abs() / w[2].abs()
            } else {
                0.0
            }
        };
        let (r_ref, r_err) = sphere_integral(96, 8, 5, |w| through(w, true));
        let (t_ref, t_err) = sphere_integral(96, 8, 6, |w| through(w, false));
        let al = b.albedo(vec3(wi), 400_000).unwrap();
        let (r, t) = (al.reflected, al.transmitted);
        let what = format!("albedo at {ti}°");
        let sr = (r.stderr[0].powi(2) + r_err * r_err).sqrt();
        let st = (t.stderr[0].powi(2) + t_err * t_err).sqrt();
        assert_z(&format!("{what} R"), r.value[0], r_ref, sr, 4.0, 1e-5);
        assert_z(&format!("{what} T"), t.value[0], t_ref, st, 4.0, 1e-5);
        assert!(r.value[0] + t.value[0] < 1.0, "{what}: R + T");
    }
}

/// A two-interface slab, both interfaces tilted by `n` (`None`: untilted).
fn slab(n: Option<[f64; 3]>, bottom_roughness: f64) -> String {
    let normal = n.map_or(String::new(), |n| {
        format!(", normal = [{}, {}, {}]", n[0], n[1], n[2])
    });
    format!(
        "[[layers]]\ninterface = {{ kind = \"dielectric\", ior = 1.5{normal} }}\n\
         [[layers]]\ninterface = {{ kind = \"dielectric\", ior = 1.0, \
         roughness = {bottom_roughness}{normal} }}\n"
    )
}

#[test]
fn a_lossless_slab_tilted_as_one_is_the_turned_slab() {
    let n = unit(TILT);
    let b = bsdf(&slab(Some(TILT), 0.0), 1);
    let world = from_frame(n);
    for (ti, pi) in [(0.0, 0.0), (30.0, 60.0), (50.0, 200.0)] {
        // Incidence given in the shading frame; every direction of these
        // walks stays within 50° + the tilt (34°) of the slab's normal.
        let wi = world(dir(ti, pi));
        let r = fresnel(dir(ti, pi)[2], 1.0, 1.5);
        let al = b.albedo(vec3(wi), 100_000).unwrap();
        let (rr, tt) = (al.reflected, al.transmitted);
        let what = format!("{ti}° in the shading frame");
        assert!(
            (rr.value[0] + tt.value[0] - 1.0).abs() < 1e-5,
            "{what}: R + T = {} (every walk leaves with weight 1)",
            rr.value[0] + tt.value[0]
        );
        assert_z(
            &what,
            rr.value[0],
            2.0 * r / (1.0 + r),
            rr.stderr[0],
            4.0,
            1e-6,
        );
    }
}

#[test]
fn a_coat_over_a_rough_bottom_tilted_as_one_is_the_turned_slab() {
    // A small tilt: light trapped by total internal reflection drifts in
    // angle until it escapes, and the part that first reaches the wedge
    // between the two horizons is lost (the model's leak, which grows with
    // the tilt; at this one it is below the error bars, asserted below).
    let tilt = [0.1, -0.05, 1.0];
    let n = unit(tilt);
    let tilted = bsdf(&slab(Some(tilt), 0.1), 40_000);
    let flat = bsdf(&slab(None, 0.1), 40_000);
    let lost = |b: &LayeredBsdf, wi: [f64; 3]| {
        let al = b.albedo(vec3(wi), 400_000).unwrap();
        let (r, t) = (al.reflected, al.transmitted);
        (1.0 - r.value[0] - t.value[0], r.stderr[0] + t.stderr[0])
    };
    let (lt, et) = lost(&tilted, from_frame(n)(dir(20.0, 0.0)));
    let (lf, ef) = lost(&flat, dir(20.0, 0.0));
    // What a lossless slab loses is the microfacet model's single-scattering
    // loss, the same with the tilt within error: the leak is not seen.
    assert!(
        (lt - lf).abs() <= 4.0 * (et + ef) && lt > 0.0,
        "lost: tilted {lt:e} ± {et:e}, untilted {lf:e} ± {ef:e}"
    );
    let (local, world) = (to_frame(n), from_frame(n));
    let z = |x: f64, y: f64| (x - y).abs();
    let mut compared = 0;
    for (wi_l, wo_l) in [
        (dir(20.0, 0.0), dir(25.0, 160.0)),
        (dir(35.0, 90.0), dir(15.0, 250.0)),
        (dir(10.0, 0.0), dir(170.0, 0.0)),
        (dir(30.0, 45.0), dir(160.0, 200.0)),
    ] {
        let (wi, wo) = (world(wi_l), world(wo_l));
        let ft = tilted.eval(vec3(wi), vec3(wo)).unwrap();
        let ff = flat.eval(vec3(wi_l), vec3(wo_l)).unwrap();
        let c = wo_l[2].abs() / wo[2].abs();
        let (v, e) = (ft.value[0] / c, ft.stderr[0] / c);
        let s = (e * e + ff.stderr[0].powi(2)).sqrt();
        let what = format!("wi' {wi_l:?} wo' {wo_l:?}");
        assert!(ff.value[0] > 10.0 * ff.stderr[0], "{what}: {ff:?}");
        assert!(
            z(v, ff.value[0]) <= 4.0 * s,
            "{what}: tilted {v} ± {e} vs turned {} ± {}",
            ff.value[0],
            ff.stderr[0]
        );
        // Reciprocity of f |wo.z| / |wo'.z|: walks from the other side.
        if (wi[2] > 0.0) == (wo[2] > 0.0) {
            let back = tilted.eval(vec3(wo), vec3(wi)).unwrap();
            let cb = local(wi)[2].abs() / wi[2].abs();
            let (vb, eb) = (back.value[0] / cb, back.stderr[0] / cb);
            let s = (e * e + eb * eb).sqrt();
            assert!(
                z(v, vb) <= 4.0 * s,
                "{what}: from wi {v} ± {e}, from wo {vb} ± {eb}"
            );
        }
        compared += 1;
    }
    assert_eq!(compared, 4);
}

const VARNISH: &str = "
    [[layers]]
    interface = { kind = \"dielectric\", ior = 1.5, roughness = 0.2 NORMAL0 }
    medium = { thickness = 0.5, sigma_t = [0.5, 1.0, 2.0], albedo = 0.7 }
    [[layers]]
    interface = { kind = \"conductor\", preset = \"Au\", roughness = 0.3 NORMAL1 }
";

fn varnish(n0: &str, n1: &str) -> String {
    VARNISH.replace("NORMAL0", n0).replace("NORMAL1", n1)
}

#[test]
fn zero_tilt_is_bit_identical_to_none() {
    let none = varnish("", "");
    for z in [", normal = [0, 0, 1]", ", normal = [0, 0, 2.5]"] {
        let given = varnish(z, z);
        let (s0, s1) = (stack(&none), stack(&given));
        assert_eq!(s0.interfaces(), s1.interfaces(), "{z}: the same interfaces");
        assert!(!stack(&given).shape().tilted());
        let (a, b) = (bsdf(&none, 64), bsdf(&given, 64));
        let (wi, wo) = (vec3(dir(30.0, 10.0)), vec3(dir(50.0, 200.0)));
        assert_eq!(a.eval(wi, wo).unwrap(), b.eval(wi, wo).unwrap());
        assert_eq!(a.sample(wi, 3).unwrap(), b.sample(wi, 3).unwrap());
        assert_eq!(a.pdf(wi, wo).unwrap(), b.pdf(wi, wo).unwrap());
    }
    // A tilt on one interface makes the shape tilted; the other stays flat.
    let one = stack(&varnish(", normal = [0.1, 0, 1]", ""));
    let shape = one.shape();
    assert!(shape.tilted() && shape.interfaces[0].tilted && !shape.interfaces[1].tilted);
    assert!(stack(&none).shape().difference(&shape).is_some());
}

#[test]
fn importance_mode_of_a_tilted_stack_is_its_adjoint() {
    // Importance walks from wi follow the adjoint kernels (Veach's factor at
    // every tilted event, the chains without it); radiance walks from wo
    // follow the forward ones. f*(wi → wo) = f(wo → wi) must hold between
    // the two, while f itself is not reciprocal.
    let toml = varnish(", normal = [0.2, 0.1, 1]", ", normal = [-0.3, 0, 1]");
    let radiance = bsdf(&toml, 60_000);
    let importance = bsdf(&toml, 60_000).transport(Transport::Importance);
    let mut asymmetric = 0;
    for (wi, wo) in [
        (dir(10.0, 10.0), dir(60.0, 200.0)),
        (dir(70.0, 0.0), dir(30.0, 90.0)),
        (dir(40.0, 120.0), dir(50.0, 300.0)),
    ] {
        let (wi, wo) = (vec3(wi), vec3(wo));
        let adj = importance.eval(wi, wo).unwrap();
        let back = radiance.eval(wo, wi).unwrap();
        let fwd = radiance.eval(wi, wo).unwrap();
        for c in 0..3 {
            let s = (adj.stderr[c].powi(2) + back.stderr[c].powi(2)).sqrt();
            let what = format!("wi {wi} wo {wo} ch {c}");
            assert!(adj.value[c] > 10.0 * adj.stderr[c], "{what}: {adj:?}");
            assert_z(&what, adj.value[c], back.value[c], s, 4.0, 0.0);
            let s = (adj.stderr[c].powi(2) + fwd.stderr[c].powi(2)).sqrt();
            asymmetric += ((adj.value[c] - fwd.value[c]).abs() > 6.0 * s) as usize;
        }
        // Sample, pdf and albedo answer in importance mode too.
        assert!(importance.sample(wi, 0).is_ok() && importance.pdf(wi, wo).unwrap() > 0.0);
    }
    assert!(
        asymmetric >= 3,
        "f is not reciprocal on a tilted stack: {asymmetric}"
    );
    // A table of materials answers in its template's mode.
    let pair = [(vec3(dir(10.0, 0.0)), vec3(dir(20.0, 0.0)))];
    let table = Materials::new(&importance, [stack(&toml)]);
    let want = importance.eval_batch(&pair).unwrap();
    assert_eq!(table.eval_batch(&[0], &pair).unwrap(), want);
    // The closed form and the control variate do not apply to tilted stacks.
    let coat =
        "[[layers]]\ninterface = { kind = \"dielectric\", ior = 1.5, normal = [0.2, 0, 1] }\n\
                medium = { thickness = 1, sigma_t = 0.3 }\n\
                [[layers]]\ninterface = { kind = \"diffuse\", albedo = 0.8 }\n";
    let auto = bsdf(coat, 256).estimator(Estimator::Auto);
    let e = auto
        .eval(vec3(dir(20.0, 10.0)), vec3(dir(60.0, 200.0)))
        .unwrap();
    assert!(e.stderr[0] > 0.0, "walks, not the closed form: {e:?}");
}

#[test]
fn a_two_sided_tilted_stack_lit_from_below_negates_the_directions() {
    let toml = format!(
        "two_sided = true\n{}",
        varnish(", normal = [0.2, 0.1, 1]", ", normal = [-0.3, 0, 1]")
    );
    let b = bsdf(&toml, 128);
    let neg = |w: glam::Vec3| -w;
    let (wi, wo) = (vec3(dir(150.0, 10.0)), vec3(dir(120.0, 230.0)));
    let below = b.eval_batch_keyed(&[(wi, wo)], 128, &[9]).unwrap()[0];
    let above = (b.eval_batch_keyed(&[(neg(wi), neg(wo))], 128, &[9])).unwrap()[0];
    assert_eq!(below.value, above.value);
    assert!(below.value[0] > 0.0);
    let key = [strata_bsdf::api::direction_key(wi, wi)];
    let mut sampled = 0;
    for i in 0..16 {
        let s = b.sample(wi, i).unwrap();
        let t = b.sample_batch_keyed(&[neg(wi)], &key, &[i]).unwrap()[0];
        assert_eq!(
            s.map(|s| (neg(s.wo), s.weight)),
            t.map(|t| (t.wo, t.weight))
        );
        sampled += s.is_some() as usize;
    }
    assert!(sampled > 4, "{sampled} of 16 walks left the stack");
}

#[test]
fn bad_normals_are_errors_naming_the_layer_field_and_value() {
    for (n, says) in [
        ("[0, 0, -1]", "z > 0"),
        ("[1, 0, 0]", "z > 0"),
        ("[0, 0, 0]", "zero length"),
        ("[0, 0]", "normal = [0, 0]"),
    ] {
        let toml = varnish("", &format!(", normal = {n}"));
        let e = LayerStack::from_toml_str(&toml).unwrap_err().to_string();
        assert!(e.contains(says), "{n}: {e}");
        // A parse error gives the line; a validation error the layer.
        assert!(
            e.contains("line 6") || e.contains("layer 1: interface.normal"),
            "{n}: {e}"
        );
    }
    let e = stack(&varnish("", ""))
        .with_set(&[(
            "layers[0].interface.normal".parse().unwrap(),
            serde_json::json!([0.0, 0.0, -2.0]),
        )])
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("layers[0].interface.normal") && e.contains("z > 0"),
        "{e}"
    );
}
