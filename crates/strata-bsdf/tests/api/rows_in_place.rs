//! Per-query columns written into the template's stack in place answer
//! what a material file with the row's values answers, bit for bit, where
//! the values are the file's numbers exactly (multiples of 1/64: a float
//! enters as itself, a file's decimal as its nearest double): on a coat
//! over copper, on both engines: eval, sample (with its pdf) and pdf,
//! keyed, and albedo (which walks every row). Over a Lambertian base (a rough and a smooth coat over
//! an absorber, answered without walks; the varnish, whose control variate
//! knows the paths without a collision) a row takes its own `R̄` from the
//! coat's table, within 1e-6 of the quadrature a material takes, so there
//! the answers agree to 1e-5 relative.
//! A row that changes the stack's shape runs as a material and answers the
//! same; an invalid row is the error its material file gives.

use crate::common::batches::{Batches, Buffers};
use crate::common::{COATED_COPPER, VARNISH_OVER_SCATTERING};
use glam::Vec3;
use serde_json::Value;
use strata_bsdf::stack::SetPath;
use strata_bsdf::{
    Column, Engine, LayerStack, LayeredBsdf, PerQuery, SampleRecord, Vectors, VectorsMut,
};

const ROUGH_COAT_ABSORBER: &str = r#"
[[layers]]
interface = { kind = "dielectric", ior = 1.5, roughness = 0.25 }
medium = { thickness = 0.5, sigma_t = [0.5, 1.0, 2.0], albedo = 0.0 }
[[layers]]
interface = { kind = "diffuse", albedo = 0.75 }
"#;

const SMOOTH_COAT_ABSORBER: &str = r#"
[[layers]]
interface = { kind = "dielectric", ior = 1.5 }
medium = { thickness = 0.5, sigma_t = [0.5, 1.0, 2.0], albedo = 0.0 }
[[layers]]
interface = { kind = "diffuse", albedo = 0.75 }
"#;

/// The columns of a stack: `(path, width, value of query k)`.
type Columns = Vec<(&'static str, usize, fn(usize, usize) -> f32)>;

fn sixty_fourths(k: usize, c: usize, lo: usize) -> f32 {
    (lo + (7 * k + 3 * c) % 16) as f32 / 64.0
}

fn columns_of(toml: &str) -> Columns {
    let mut c: Columns = vec![("layers[0].medium.thickness", 1, |k, c| {
        sixty_fourths(k, c, 8)
    })];
    // A grey extinction stays grey (a chromatic one would be another
    // shape).
    match toml.contains("sigma_t = [") {
        true => c.push(("layers[0].medium.sigma_t", 3, |k, c| {
            sixty_fourths(k, c, 16)
        })),
        false => c.push(("layers[0].medium.sigma_t", 1, |k, _| {
            sixty_fourths(k, 0, 16)
        })),
    }
    if toml.contains("roughness") {
        c.push(("layers[0].interface.roughness", 1, |k, c| {
            sixty_fourths(k, c, 4)
        }));
    }
    if toml.contains("diffuse") {
        c.push(("layers[1].interface.albedo", 3, |k, c| {
            sixty_fourths(k, c, 40)
        }));
    }
    c
}

/// `n` pairs of directions above the surface: a spiral of `wi`, and each
/// `wo` the `wi` five steps on.
fn pairs(n: usize) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    let wi: Vec<[f32; 3]> = (0..n)
        .map(|k| {
            let t = k as f32 * 0.7;
            let z = 0.2 + 0.75 * (t * 1.3).sin().abs();
            let r = (1.0 - z * z).sqrt();
            [r * t.cos(), r * t.sin(), z]
        })
        .collect();
    let wo = (0..n).map(|k| wi[(k + 5) % n]).collect();
    (wi, wo)
}

/// Query `k` of `v` alone.
fn one(v: &[[f32; 3]], k: usize) -> Vectors<'_> {
    Vectors::Aos(&v[k..k + 1])
}

#[test]
fn rows_in_place_answer_their_material_files() {
    let n = 24;
    let (wi, wo) = pairs(n);
    let keys: Vec<u64> = (0..n as u64).map(|k| 77 + k).collect();
    for toml in [
        ROUGH_COAT_ABSORBER,
        SMOOTH_COAT_ABSORBER,
        COATED_COPPER,
        VARNISH_OVER_SCATTERING,
    ] {
        let columns = columns_of(toml);
        let paths: Vec<SetPath> = columns.iter().map(|c| c.0.parse().unwrap()).collect();
        let values: Vec<Vec<f32>> = (columns.iter())
            .map(|&(_, w, f)| (0..n * w).map(|i| f(i / w, i % w)).collect())
            .collect();
        let cols: Vec<Column> = (paths.iter().zip(&columns).zip(&values))
            .map(|((path, c), values)| Column {
                path,
                width: c.1,
                values,
            })
            .collect();
        assert!(cols.iter().all(|c| c.path.in_place()));
        let stack = LayerStack::from_toml_str(toml).unwrap();
        for engine in [Engine::Scalar, Engine::Wavefront] {
            let make = |s: LayerStack| LayeredBsdf::new(s).engine(engine).samples(4).seed(5);
            let template = make(stack.clone());
            let q = PerQuery::new(&template, n, &cols).unwrap();
            assert!(q.rows_in_place(), "{toml}");
            let (a, b) = (Vectors::Aos(&wi), Vectors::Aos(&wo));
            let mut f = vec![[0f32; 3]; n];
            q.eval_buffers(a, b, Some(&keys), VectorsMut::Aos(&mut f), None)
                .unwrap();
            let mut s = vec![SampleRecord::default(); n];
            q.sample_records(a, Some(&keys), &mut s).unwrap();
            let mut p = vec![0f32; n];
            q.pdf_buffers(a, b, &mut p).unwrap();
            // Albedo walks every row, those answered without walks too.
            let wis: Vec<Vec3> = wi.iter().map(|&w| Vec3::from(w)).collect();
            let albedo = q.albedo_batch_keyed(&wis, 8, &keys).unwrap();
            for k in 0..n {
                let set: Vec<(SetPath, Value)> = (paths.iter().zip(&values))
                    .zip(&columns)
                    .map(|((path, v), c)| {
                        let row: Vec<f64> = v[k * c.1..(k + 1) * c.1]
                            .iter()
                            .map(|&x| f64::from(x))
                            .collect();
                        let value = match row[..] {
                            [x] => Value::from(x),
                            _ => Value::from(row),
                        };
                        (path.clone(), value)
                    })
                    .collect();
                let own = make(stack.with_set(&set).unwrap());
                let mut want = [[0f32; 3]];
                own.eval_buffers(
                    one(&wi, k),
                    one(&wo, k),
                    Some(&keys[k..k + 1]),
                    VectorsMut::Aos(&mut want),
                    None,
                )
                .unwrap();
                let what = format!("{engine:?} query {k} of\n{toml}");
                // A coat over a Lambertian base: `R̄` from the table (see
                // the module), for the walk-free form or the control variate.
                let tabulated = toml.contains("diffuse");
                let same = |a: &[f32], b: &[f32], what: String| {
                    for (&x, &y) in a.iter().zip(b) {
                        let ok = match tabulated {
                            false => x.to_bits() == y.to_bits(),
                            true => (x - y).abs() <= 1e-5 * x.abs().max(y.abs()),
                        };
                        assert!(ok, "{x} vs {y}: {what}");
                    }
                };
                same(&f[k], &want[0], format!("eval, {what}"));
                let mut ws = [SampleRecord::default()];
                own.sample_records(one(&wi, k), Some(&keys[k..k + 1]), &mut ws)
                    .unwrap();
                let (g, w) = (&s[k], &ws[0]);
                same(&g.wo, &w.wo, format!("sample, {what}"));
                same(&g.weight, &w.weight, format!("sample weight, {what}"));
                same(&[g.pdf], &[w.pdf], format!("sample pdf, {what}"));
                assert_eq!(g.flags, w.flags, "sample flags, {what}");
                let mut wp = [0f32];
                own.pdf_buffers(one(&wi, k), one(&wo, k), &mut wp).unwrap();
                same(&p[k..k + 1], &wp, format!("pdf, {what}"));
                let wa = own
                    .albedo_batch_keyed(&wis[k..k + 1], 8, &keys[k..k + 1])
                    .unwrap()[0];
                let (g, w) = (albedo[k].reflected.value, wa.reflected.value);
                let f32s = |v: [f64; 3]| v.map(|x| x as f32);
                same(&f32s(g), &f32s(w), format!("albedo, {what}"));
            }
        }
    }
}

/// A row whose values change the stack's shape (a roughness of 0 makes the
/// coat smooth) runs as a material and answers what its file answers; an
/// invalid row is the error its file gives, naming the query.
#[test]
fn rows_that_leave_the_shape_or_are_invalid() {
    let stack = LayerStack::from_toml_str(ROUGH_COAT_ABSORBER).unwrap();
    let template = LayeredBsdf::new(stack.clone()).samples(4).seed(5);
    let path: SetPath = "layers[0].interface.roughness".parse().unwrap();
    let rough = [0.25f32, 0.0, 0.5];
    let cols = [Column {
        path: &path,
        width: 1,
        values: &rough,
    }];
    let q = PerQuery::new(&template, 3, &cols).unwrap();
    assert!(!q.rows_in_place());
    let wi = [[0.0f32, 0.6, 0.8]; 3];
    let mut f = [[0f32; 3]; 3];
    let dirs = Vectors::Aos(&wi);
    q.eval_buffers(dirs, dirs, Some(&[1, 2, 3]), VectorsMut::Aos(&mut f), None)
        .unwrap();
    let smooth = LayerStack::from_toml_str(&ROUGH_COAT_ABSORBER.replace("0.25", "0.0")).unwrap();
    let own = LayeredBsdf::new(smooth).samples(4).seed(5);
    let mut want = [[0f32; 3]];
    let one = Vectors::Aos(&wi[..1]);
    own.eval_buffers(one, one, Some(&[2]), VectorsMut::Aos(&mut want), None)
        .unwrap();
    assert_eq!(f[1], want[0]);
    assert_ne!(f[0], f[1], "the smooth row is not the rough one");

    let t: SetPath = "layers[0].medium.thickness".parse().unwrap();
    for (bad, says) in [(-0.5f32, "must be >= 0"), (f32::NAN, "not a finite number")] {
        let v = [0.5f32, 0.25, bad, 0.5];
        let cols = [Column {
            path: &t,
            width: 1,
            values: &v,
        }];
        let e = PerQuery::new(&template, 4, &cols).unwrap_err().to_string();
        assert!(e.starts_with("query 2: ") && e.contains(says), "{e}");
        assert!(e.contains("medium.thickness"), "{e}");
    }
}

/// `same_shape_at` compares only what a write can change (a medium's kind and
/// greyness, an interface's smoothness): on writes that keep and that change
/// the shape, of every in-place field, it says what the whole comparison says.
#[test]
fn same_shape_at_agrees_with_the_whole_comparison() {
    let stacks = [
        LayerStack::from_toml_str(VARNISH_OVER_SCATTERING).unwrap(),
        LayerStack::from_toml_str(ROUGH_COAT_ABSORBER).unwrap(),
        LayerStack::from_toml_str(SMOOTH_COAT_ABSORBER).unwrap(),
        LayerStack::from_toml_str(COATED_COPPER).unwrap(),
    ];
    let writes: [(&str, &[&[f64]]); 7] = [
        ("layers[0].medium.thickness", &[&[0.0], &[0.25], &[1.0]]),
        (
            "layers[0].medium.sigma_t",
            &[&[0.0], &[0.5], &[0.5, 1.0, 2.0], &[0.0, 0.0, 0.0]],
        ),
        (
            "layers[0].medium.albedo",
            &[&[0.0], &[0.5], &[0.5, 0.0, 0.9]],
        ),
        ("layers[0].interface.roughness", &[&[0.0], &[0.1], &[0.25]]),
        ("layers[1].interface.albedo", &[&[0.0], &[0.5, 0.6, 0.7]]),
        ("layers[1].interface.eta", &[&[0.2, 0.9, 1.1]]),
        ("layers[1].interface.k", &[&[0.0], &[3.0, 2.5, 2.0]]),
    ];
    let (mut same, mut differ) = (0, 0);
    for stack in &stacks {
        for (path, values) in writes {
            let path: SetPath = path.parse().unwrap();
            // The stack has the field (0.5 is a valid value of every one).
            let has = stack.desc().clone().apply_set(&path, &Value::from(0.5));
            if !path.in_place() || has.is_err() {
                continue;
            }
            for v in values {
                let mut row = stack.clone();
                if row.write(&path, v).is_err() || row.check_depths().is_err() {
                    continue;
                }
                let whole = row.same_shape(stack);
                assert_eq!(row.same_shape_at(stack, &[&path]), whole, "{path} = {v:?}");
                if whole {
                    same += 1;
                } else {
                    differ += 1;
                }
            }
        }
    }
    assert!(
        same > 10 && differ > 5,
        "{same} writes keep the shape, {differ} change it"
    );
}

/// A thread keeps its last table and reuses it for the same template and
/// columns (a renderer's three calls at a batch of vertices): the answers
/// are those of a table built afresh, for the same columns and for any
/// others (other values, another template, another estimator) in any order.
#[test]
fn a_kept_table_answers_only_for_its_own_columns() {
    let path: SetPath = "layers[0].medium.thickness".parse().unwrap();
    let (a, b) = ([0.25f32, 0.5, 1.0], [0.25f32, 0.5, 1.5]);
    let wi = [[0.0f32, 0.6, 0.8]; 3];
    let eval = |bsdf: &LayeredBsdf, v: &[f32]| {
        let cols = [Column {
            path: &path,
            width: 1,
            values: v,
        }];
        let q = PerQuery::new(bsdf, 3, &cols).unwrap();
        assert!(q.rows_in_place());
        let mut f = [[0f32; 3]; 3];
        let d = Vectors::Aos(&wi);
        q.eval_buffers(d, d, Some(&[1, 2, 3]), VectorsMut::Aos(&mut f), None)
            .unwrap();
        f
    };
    let coat = LayeredBsdf::new(LayerStack::from_toml_str(COATED_COPPER).unwrap()).seed(9);
    let other = LayeredBsdf::new(LayerStack::from_toml_str(ROUGH_COAT_ABSORBER).unwrap()).seed(9);
    let uni = coat
        .clone()
        .estimator(strata_bsdf::Estimator::Unidirectional);
    let first = eval(&coat, &a);
    let (with_b, on_other, with_uni) = (eval(&coat, &b), eval(&other, &a), eval(&uni, &a));
    assert_eq!(first[..2], with_b[..2], "rows 0 and 1 are the same");
    assert_ne!(first[2], with_b[2], "row 2 is not");
    assert_ne!(first, on_other);
    assert_eq!(eval(&coat, &a), first);
    // Fresh threads build every table anew: the same numbers.
    let fresh = |bsdf: LayeredBsdf, v: [f32; 3]| {
        std::thread::scope(|s| s.spawn(|| eval(&bsdf, &v)).join().unwrap())
    };
    assert_eq!(fresh(coat.clone(), b), with_b);
    assert_eq!(fresh(other.clone(), a), on_other);
    assert_eq!(fresh(uni.clone(), a), with_uni);
}

/// `eval_pdf_into` answers, bit for bit, what `eval_into` and `pdf_into`
/// answer for the same pairs: on the BSDF's own parameters and on
/// per-query rows (written in place, and as materials where a column is an
/// IOR), over a walked stack, a walk-free one and one whose control
/// variate walks. A direction that is not one is the error the two calls
/// give, and nothing is written.
#[test]
fn eval_pdf_is_eval_and_pdf() {
    let n = 9;
    let wi: Vec<[f32; 3]> = (0..n)
        .map(|k| [0.1 * k as f32 - 0.4, 0.3, 0.5 + 0.05 * k as f32])
        .collect();
    let wo: Vec<[f32; 3]> = (0..n)
        .map(|k| [0.2 - 0.05 * k as f32, -0.4, 0.6 + 0.1 * (k % 3) as f32])
        .collect();
    let keys: Vec<u64> = (0..n as u64).map(|k| 7 * k + 1).collect();
    let (a, b) = (Vectors::Aos(&wi), Vectors::Aos(&wo));
    type Answer = (Vec<[f32; 3]>, Vec<[f32; 3]>, Vec<f32>);
    let apart = |eval: &dyn Fn(VectorsMut, VectorsMut), pdf: &dyn Fn(&mut [f32])| -> Answer {
        let (mut f, mut e, mut p) = (vec![[0f32; 3]; n], vec![[0f32; 3]; n], vec![0f32; n]);
        eval(VectorsMut::Aos(&mut f), VectorsMut::Aos(&mut e));
        pdf(&mut p);
        (f, e, p)
    };
    let together = |call: &dyn Fn(VectorsMut, VectorsMut, &mut [f32])| -> Answer {
        let (mut f, mut e, mut p) = (vec![[0f32; 3]; n], vec![[0f32; 3]; n], vec![0f32; n]);
        call(VectorsMut::Aos(&mut f), VectorsMut::Aos(&mut e), &mut p);
        (f, e, p)
    };
    let thickness: SetPath = "layers[0].medium.thickness".parse().unwrap();
    let ior: SetPath = "exterior_ior".parse().unwrap();
    let depths: Vec<f32> = (0..n).map(|k| sixty_fourths(k, 0, 8)).collect();
    let iors: Vec<f32> = (0..n).map(|k| 1.0 + sixty_fourths(k, 0, 0)).collect();
    for toml in [COATED_COPPER, SMOOTH_COAT_ABSORBER, VARNISH_OVER_SCATTERING] {
        let bsdf = LayeredBsdf::new(LayerStack::from_toml_str(toml).unwrap())
            .samples(2)
            .seed(3);
        let k = Some(&keys[..]);
        let own_apart = apart(
            &|f, e| {
                bsdf.eval_buffers(a, b, k, f, Some(e)).unwrap();
            },
            &|p| bsdf.pdf_buffers(a, b, p).unwrap(),
        );
        let own = together(&|f, e, p| {
            bsdf.eval_pdf_buffers(a, b, k, f, Some(e), p).unwrap();
        });
        assert_eq!(own, own_apart, "{toml}");
        for (path, values) in [(&thickness, &depths), (&ior, &iors)] {
            let cols = [Column {
                path,
                width: 1,
                values,
            }];
            let q = PerQuery::new(&bsdf, n, &cols).unwrap();
            assert_eq!(q.rows_in_place(), path == &thickness);
            let rows_apart = apart(
                &|f, e| {
                    q.eval_buffers(a, b, k, f, Some(e)).unwrap();
                },
                &|p| q.pdf_buffers(a, b, p).unwrap(),
            );
            let rows = together(&|f, e, p| {
                q.eval_pdf_buffers(a, b, k, f, Some(e), p).unwrap();
            });
            assert_eq!(rows, rows_apart, "{path} of {toml}");
            assert!(rows.2.iter().all(|p| p.is_finite() && *p >= 0.0));
        }
        // A NaN direction: the calls' error, nothing written.
        let mut bad = wo.clone();
        bad[4] = [f32::NAN, 0.0, 1.0];
        let c = Vectors::Aos(&bad);
        let (mut f, mut p) = (vec![[-1f32; 3]; n], vec![-1f32; n]);
        let e = bsdf
            .eval_pdf_buffers(a, c, k, VectorsMut::Aos(&mut f), None, &mut p)
            .unwrap_err();
        let alone = bsdf.pdf_buffers(a, c, &mut vec![0.0; n]).unwrap_err();
        assert_eq!((e.index, e.to_string()), (alone.index, alone.to_string()));
        assert!(f.iter().all(|v| *v == [-1.0; 3]) && p.iter().all(|x| *x == -1.0));
    }
}

/// A table kept for the same columns under another configuration is not
/// reused where the rows' shape is not the template's (a grey extinction
/// given per query as RGB, which answers on a BSDF of the rows' shape with
/// the template's configuration): each call answers with its own
/// template's seed and walks, as a table built afresh does.
#[test]
fn a_kept_table_of_another_shape_answers_with_its_templates_configuration() {
    let path: SetPath = "layers[0].medium.sigma_t".parse().unwrap();
    let sigma: Vec<f32> = (0..9).map(|k| sixty_fourths(k / 3, k % 3, 16)).collect();
    let wi = [[0.0f32, 0.6, 0.8]; 3];
    let eval = |bsdf: &LayeredBsdf| {
        let cols = [Column {
            path: &path,
            width: 3,
            values: &sigma,
        }];
        let q = PerQuery::new(bsdf, 3, &cols).unwrap();
        assert!(q.rows_in_place());
        let mut f = [[0f32; 3]; 3];
        let d = Vectors::Aos(&wi);
        q.eval_buffers(d, d, Some(&[1, 2, 3]), VectorsMut::Aos(&mut f), None)
            .unwrap();
        f
    };
    let grey = LayerStack::from_toml_str(VARNISH_OVER_SCATTERING).unwrap();
    let (one, other) = (
        LayeredBsdf::new(grey.clone()).seed(9).samples(4),
        LayeredBsdf::new(grey).seed(10).samples(4),
    );
    let fresh = |bsdf: &LayeredBsdf| std::thread::scope(|s| s.spawn(|| eval(bsdf)).join().unwrap());
    let (first, second) = (eval(&one), eval(&other));
    assert_ne!(first, second, "the seeds differ");
    assert_eq!(first, fresh(&one));
    assert_eq!(second, fresh(&other));
    assert_eq!(eval(&one), first);
}

/// A row whose extinction is grey, among rows whose extinction is not (a
/// texture's grey texels, a spectrum that is flat beyond its table at a
/// query's three wavelengths), runs in place on the chromatic shape: a
/// chromatic row answers its material file bit for bit, and a grey one
/// within 4 standard errors of its file (a chromatic walk has its
/// expectation, not its bits), whichever row comes first. A chromatic row
/// on a grey shape would not run: `runs_on_at` says so.
#[test]
fn grey_rows_run_in_place_on_a_chromatic_shape() {
    const CHROMATIC: &str = "[[layers]]\n\
        interface = { kind = \"dielectric\", ior = 1.5, roughness = 0.2 }\n\
        medium = { thickness = 0.5, sigma_t = [0.5, 1.0, 2.0], albedo = 0.8 }\n\
        [[layers]]\ninterface = { kind = \"diffuse\", albedo = 0.7 }\n";
    let walks = 20_000;
    let template = LayeredBsdf::new(LayerStack::from_toml_str(CHROMATIC).unwrap())
        .samples(walks)
        .seed(3);
    let path: SetPath = "layers[0].medium.sigma_t".parse().unwrap();
    let rows: [[f32; 3]; 3] = [[1.0, 1.0, 1.0], [0.25, 0.75, 1.5], [2.0, 2.0, 2.0]];
    for order in [[0, 1, 2], [1, 2, 0]] {
        let values: Vec<f32> = order.iter().flat_map(|&r| rows[r]).collect();
        let cols = [Column {
            path: &path,
            width: 3,
            values: &values,
        }];
        let q = PerQuery::new(&template, 3, &cols).unwrap();
        assert!(q.rows_in_place(), "order {order:?}");
        let wi = [[0.3f32, 0.1, 0.9]; 3];
        let wo = [[-0.2f32, 0.3, 0.8]; 3];
        let keys = [11u64, 12, 13];
        let mut f = [[0f32; 3]; 3];
        let mut se = [[0f32; 3]; 3];
        let (a, b) = (Vectors::Aos(&wi), Vectors::Aos(&wo));
        q.eval_buffers(
            a,
            b,
            Some(&keys),
            VectorsMut::Aos(&mut f),
            Some(VectorsMut::Aos(&mut se)),
        )
        .unwrap();
        // The engines agree bit for bit: a grey row takes its greyness (its
        // flights, and the control variate's boost under a smooth coat,
        // which the grey rows' own rule turns on) from the shape.
        let smooth = CHROMATIC.replace(", roughness = 0.2", "");
        for toml in [CHROMATIC, smooth.as_str()] {
            let st = LayerStack::from_toml_str(toml).unwrap();
            let [mut fw, mut fs] = [[[0f32; 3]; 3]; 2];
            for (engine, out) in [(Engine::Wavefront, &mut fw), (Engine::Scalar, &mut fs)] {
                let t = LayeredBsdf::new(st.clone())
                    .samples(64)
                    .seed(3)
                    .engine(engine);
                let q = PerQuery::new(&t, 3, &cols).unwrap();
                q.eval_buffers(a, b, Some(&keys), VectorsMut::Aos(out), None)
                    .unwrap();
            }
            assert_eq!(fs, fw, "the engines, order {order:?}\n{toml}");
        }
        for (k, &r) in order.iter().enumerate() {
            let file =
                CHROMATIC.replace("[0.5, 1.0, 2.0]", &format!("{:?}", rows[r].map(f64::from)));
            let own = LayeredBsdf::new(LayerStack::from_toml_str(&file).unwrap())
                .samples(walks)
                .seed(3);
            let mut want = [[0f32; 3]];
            let mut want_se = [[0f32; 3]];
            let (a, b) = (Vectors::Aos(&wi[..1]), Vectors::Aos(&wo[..1]));
            let out = VectorsMut::Aos(&mut want);
            own.eval_buffers(
                a,
                b,
                Some(&keys[k..k + 1]),
                out,
                Some(VectorsMut::Aos(&mut want_se)),
            )
            .unwrap();
            if r == 1 {
                assert_eq!(f[k], want[0], "the chromatic row, at {k}");
                continue;
            }
            for c in 0..3 {
                let sigma = (se[k][c].powi(2) + want_se[0][c].powi(2)).sqrt();
                assert!(
                    (f[k][c] - want[0][c]).abs() < 4.0 * sigma,
                    "grey row {r} at {k}, channel {c}: {} vs its file's {} ± {sigma}",
                    f[k][c],
                    want[0][c]
                );
            }
        }
    }
    // A chromatic row on a grey shape does not run on it.
    let grey = LayerStack::from_toml_str(&CHROMATIC.replace("[0.5, 1.0, 2.0]", "1.0")).unwrap();
    let mut row = grey.clone();
    row.write(&path, &[0.5, 1.0, 2.0]).unwrap();
    assert!(!row.runs_on_at(&grey, &[&path]) && grey.runs_on_at(&row, &[&path]));
    assert!(!row.runs_on(&grey) && grey.runs_on(&row));
}

/// Two tilted rough dielectrics over a conductor given by its numbers: an
/// IOR written at either dielectric moves the next interface's IOR above,
/// the conductor's relative constants, and which interface is index-matched.
const TWO_COATS_OVER_METAL: &str = r#"
[[layers]]
interface = { kind = "dielectric", ior = 1.5, roughness = 0.2, normal = [0.2, 0.0, 1.0] }
medium = { thickness = 0.5, sigma_t = 0.5, albedo = 0.5 }
[[layers]]
interface = { kind = "dielectric", ior = 1.25, roughness = 0.3, normal = [0.0, 0.3, 1.0] }
medium = { thickness = 0.25, sigma_t = [0.2, 0.4, 0.6], albedo = 0.0 }
[[layers]]
interface = { kind = "conductor", eta = [0.2, 0.9, 1.1], k = [3.9, 2.4, 2.2], roughness = 0.1 }
"#;

/// An IOR written in place derives what `LayerStack::new` derives from the
/// file with that IOR, bit for bit: the next interface's IOR above, a
/// conductor's constants relative to it, and index matching (a matched
/// dielectric is smooth and untilted; one that stops matching takes its
/// description's roughness and normal back). Its shape comparison agrees
/// with the whole one.
#[test]
fn an_ior_written_in_place_is_its_files_stack() {
    let cases: [(&str, &str, &[f64]); 3] = [
        (
            TWO_COATS_OVER_METAL,
            "layers[0].interface.ior",
            &[1.0, 1.25, 1.75, 1.5],
        ),
        (
            TWO_COATS_OVER_METAL,
            "layers[1].interface.ior",
            &[1.5, 1.0, 2.0, 1.25],
        ),
        (
            COATED_COPPER,
            "layers[0].interface.ior",
            &[1.0, 1.3, 2.5, 1.5],
        ),
    ];
    let (mut same, mut differ) = (0, 0);
    for (toml, path, values) in cases {
        let stack = LayerStack::from_toml_str(toml).unwrap();
        let path: SetPath = path.parse().unwrap();
        assert!(path.in_place() && path.writes_ior());
        // Written one after another: matched, unmatched again, and back to
        // the file's own value.
        let mut row = stack.clone();
        for &v in values {
            row.write(&path, &[v]).unwrap();
            let file = stack.with_set(&[(path.clone(), Value::from(v))]).unwrap();
            for i in 0..file.len() {
                assert_eq!(
                    row.interface(i),
                    file.interface(i),
                    "{path} = {v}, interface {i}"
                );
            }
            let whole = row.same_shape(&stack);
            assert_eq!(row.same_shape_at(&stack, &[&path]), whole, "{path} = {v}");
            match whole {
                true => same += 1,
                false => differ += 1,
            }
        }
        assert!(row.same_shape(&stack));
        for i in 0..stack.len() {
            assert_eq!(row.interface(i), stack.interface(i));
        }
    }
    assert!(
        same >= 6 && differ >= 4,
        "{same} keep the shape, {differ} change it"
    );
    let e = LayerStack::from_toml_str(COATED_COPPER)
        .unwrap()
        .write(&"layers[0].interface.ior".parse().unwrap(), &[-1.0])
        .unwrap_err()
        .to_string();
    assert!(e.contains("interface.ior") && e.contains("-1"), "{e}");
}

/// Per-query IORs (a dispersive coat at each query's wavelength) are
/// written in place and answer what the material file with the row's values
/// answers, bit for bit, on both engines: eval (keyed), sample and pdf. The
/// conductor's `eta` column comes first and still stands (rows write IORs
/// first); a row whose IOR matches the exterior's makes another shape and
/// runs as a material, answering the same.
#[test]
fn ior_columns_answer_their_material_files() {
    let n = 16;
    let (wi, wo) = pairs(n);
    let keys: Vec<u64> = (0..n as u64).map(|k| 5 + 3 * k).collect();
    let stack = LayerStack::from_toml_str(TWO_COATS_OVER_METAL).unwrap();
    let eta: SetPath = "layers[2].interface.eta".parse().unwrap();
    let ior: SetPath = "layers[0].interface.ior".parse().unwrap();
    let etas: Vec<f32> = (0..3 * n)
        .map(|i| sixty_fourths(i / 3, i % 3, 10))
        .collect();
    for matched in [false, true] {
        // IORs in [1.125, 1.73] (exact in binary), and one of 1 when matched.
        let iors: Vec<f32> = (0..n)
            .map(|k| match matched && k == 5 {
                true => 1.0,
                false => (72 + (5 * k) % 40) as f32 / 64.0,
            })
            .collect();
        let cols = [
            Column {
                path: &eta,
                width: 3,
                values: &etas,
            },
            Column {
                path: &ior,
                width: 1,
                values: &iors,
            },
        ];
        for engine in [Engine::Scalar, Engine::Wavefront] {
            let make = |s: LayerStack| LayeredBsdf::new(s).engine(engine).samples(2).seed(9);
            let template = make(stack.clone());
            let q = PerQuery::new(&template, n, &cols).unwrap();
            assert_eq!(q.rows_in_place(), !matched);
            let (a, b) = (Vectors::Aos(&wi), Vectors::Aos(&wo));
            let mut f = vec![[0f32; 3]; n];
            q.eval_buffers(a, b, Some(&keys), VectorsMut::Aos(&mut f), None)
                .unwrap();
            let mut s = vec![SampleRecord::default(); n];
            q.sample_records(a, Some(&keys), &mut s).unwrap();
            let mut p = vec![0f32; n];
            q.pdf_buffers(a, b, &mut p).unwrap();
            for k in 0..n {
                let e: Vec<f64> = etas[3 * k..3 * k + 3].iter().map(|&x| x.into()).collect();
                let set = [
                    (eta.clone(), Value::from(e)),
                    (ior.clone(), Value::from(f64::from(iors[k]))),
                ];
                let own = make(stack.with_set(&set).unwrap());
                let what = format!("{engine:?}, matched {matched}, query {k}");
                let mut want = [[0f32; 3]];
                own.eval_buffers(
                    one(&wi, k),
                    one(&wo, k),
                    Some(&keys[k..k + 1]),
                    VectorsMut::Aos(&mut want),
                    None,
                )
                .unwrap();
                assert_eq!(
                    f[k].map(f32::to_bits),
                    want[0].map(f32::to_bits),
                    "eval, {what}"
                );
                let mut ws = [SampleRecord::default()];
                own.sample_records(one(&wi, k), Some(&keys[k..k + 1]), &mut ws)
                    .unwrap();
                assert_eq!(
                    s[k].wo.map(f32::to_bits),
                    ws[0].wo.map(f32::to_bits),
                    "sample, {what}"
                );
                assert_eq!(
                    s[k].weight.map(f32::to_bits),
                    ws[0].weight.map(f32::to_bits),
                    "{what}"
                );
                assert_eq!(
                    s[k].pdf.to_bits(),
                    ws[0].pdf.to_bits(),
                    "sample pdf, {what}"
                );
                let mut wp = [0f32];
                own.pdf_buffers(one(&wi, k), one(&wo, k), &mut wp).unwrap();
                assert_eq!(p[k].to_bits(), wp[0].to_bits(), "pdf, {what}");
            }
        }
    }
}

/// A coat over a Lambertian base answered without walks (a closed form)
/// takes a table of `R̄` per IOR: rows whose IOR is their own are walked
/// instead, in place. Their eval agrees with each row's material file (the
/// closed form, exact) within 4 standard errors of the walks.
#[test]
fn ior_rows_of_a_walk_free_coat_are_walked() {
    let n = 8;
    let ior: SetPath = "layers[0].interface.ior".parse().unwrap();
    let iors: Vec<f32> = (0..n).map(|k| (80 + 6 * k) as f32 / 64.0).collect();
    let cols = [Column {
        path: &ior,
        width: 1,
        values: &iors,
    }];
    let wi: Vec<[f32; 3]> = (0..n).map(|k| [0.1 * k as f32, 0.0, 1.0]).collect();
    let wo: Vec<[f32; 3]> = (0..n).map(|k| [0.0, -0.08 * k as f32, 1.0]).collect();
    for toml in [SMOOTH_COAT_ABSORBER, ROUGH_COAT_ABSORBER] {
        let stack = LayerStack::from_toml_str(toml).unwrap();
        // (Enough walks that their standard error is itself well estimated:
        // a walk's rare long paths carry much of the rough coat's value.)
        let template = LayeredBsdf::new(stack.clone()).samples(200_000).seed(3);
        assert!(template.eval_without_walks());
        let q = PerQuery::new(&template, n, &cols).unwrap();
        assert!(q.rows_in_place());
        let (a, b) = (Vectors::Aos(&wi), Vectors::Aos(&wo));
        let (mut f, mut se) = (vec![[0f32; 3]; n], vec![[0f32; 3]; n]);
        q.eval_buffers(
            a,
            b,
            None,
            VectorsMut::Aos(&mut f),
            Some(VectorsMut::Aos(&mut se)),
        )
        .unwrap();
        for k in 0..n {
            let set = [(ior.clone(), Value::from(f64::from(iors[k])))];
            // (A rough coat's walk-free eval estimates its first-order
            // term: with as many samples, and its own standard error.)
            let own = LayeredBsdf::new(stack.with_set(&set).unwrap())
                .samples(200_000)
                .seed(4);
            let (mut want, mut want_se) = ([[0f32; 3]], [[0f32; 3]]);
            let (a, b) = (one(&wi, k), one(&wo, k));
            own.eval_buffers(
                a,
                b,
                None,
                VectorsMut::Aos(&mut want),
                Some(VectorsMut::Aos(&mut want_se)),
            )
            .unwrap();
            for c in 0..3 {
                assert!(se[k][c] > 0.0, "walked: query {k}");
                let z = (f[k][c] - want[0][c]) / se[k][c].hypot(want_se[0][c]);
                assert!(
                    z.abs() < 4.0,
                    "query {k} channel {c}: {} vs {} (z {z})",
                    f[k][c],
                    want[0][c]
                );
            }
        }
    }
}

/// An IOR a rounding from its neighbour's (a texture's `1.45f32` beside a
/// file's 1.45) makes the interface between them invisible, in place as in
/// the material file: the walks hold IORs in single precision, where the two
/// are one. The row answers what the file with the decimal answers, but for
/// the IOR's last bits.
#[test]
fn an_ior_a_rounding_from_its_neighbours_matches_it() {
    let toml = TWO_COATS_OVER_METAL
        .replace("ior = 1.5,", "ior = 1.3,")
        .replace("ior = 1.25,", "ior = 1.45,");
    let stack = LayerStack::from_toml_str(&toml).unwrap();
    assert!(!stack.interface(1).smooth);
    let ior: SetPath = "layers[0].interface.ior".parse().unwrap();
    let mut row = stack.clone();
    row.write(&ior, &[f64::from(1.45f32)]).unwrap();
    let file = stack.with_set(&[(ior.clone(), Value::from(1.45))]).unwrap();
    assert!(file.interface(1).smooth && row.interface(1).smooth);
    assert_eq!(row.interface_shape(1), file.interface_shape(1));
    assert_eq!(row.interface(1).normal, [0.0, 0.0, 1.0]);
    let n = 8;
    let (wi, wo) = pairs(n);
    let iors = vec![1.45f32; n];
    let cols = [Column {
        path: &ior,
        width: 1,
        values: &iors,
    }];
    let template = LayeredBsdf::new(stack).samples(64).seed(2);
    let q = PerQuery::new(&template, n, &cols).unwrap();
    let (a, b) = (Vectors::Aos(&wi), Vectors::Aos(&wo));
    let mut f = vec![[0f32; 3]; n];
    q.eval_buffers(a, b, None, VectorsMut::Aos(&mut f), None)
        .unwrap();
    let own = LayeredBsdf::new(file).samples(64).seed(2);
    let mut want = vec![[0f32; 3]; n];
    own.eval_buffers(a, b, None, VectorsMut::Aos(&mut want), None)
        .unwrap();
    for k in 0..n {
        for c in 0..3 {
            let (x, y) = (f[k][c], want[k][c]);
            assert!(
                (x - y).abs() <= 1e-4 * y.abs().max(1e-6),
                "query {k}: {x} vs {y}"
            );
        }
    }
}

/// The bottom interface's IOR is the exterior's below, which the transport
/// mode's η² reads from the BSDF's own stack: such a column runs as a
/// material per row, and a transmitted pair in importance mode answers what
/// its file answers, bit for bit.
#[test]
fn the_bottom_interfaces_ior_runs_as_a_material() {
    let glass = "[[layers]]\ninterface = { kind = \"dielectric\", ior = 1.5, roughness = 0.3 }\n";
    let stack = LayerStack::from_toml_str(glass).unwrap();
    let ior: SetPath = "layers[0].interface.ior".parse().unwrap();
    let iors = [1.25f32, 1.75];
    let cols = [Column {
        path: &ior,
        width: 1,
        values: &iors,
    }];
    let make = |s: LayerStack| {
        LayeredBsdf::new(s)
            .transport(strata_bsdf::Transport::Importance)
            .samples(4)
            .seed(1)
    };
    let template = make(stack.clone());
    let q = PerQuery::new(&template, 2, &cols).unwrap();
    assert!(!q.rows_in_place());
    let wi = [[0.3f32, 0.0, 0.9]; 2];
    let wo = [[-0.2f32, 0.1, -0.9]; 2];
    let (a, b) = (Vectors::Aos(&wi), Vectors::Aos(&wo));
    let mut f = [[0f32; 3]; 2];
    q.eval_buffers(a, b, Some(&[3, 4]), VectorsMut::Aos(&mut f), None)
        .unwrap();
    for k in 0..2 {
        let set = [(ior.clone(), Value::from(f64::from(iors[k])))];
        let own = make(stack.with_set(&set).unwrap());
        let mut want = [[0f32; 3]];
        let keys = [3 + k as u64];
        own.eval_buffers(
            one(&wi, k),
            one(&wo, k),
            Some(&keys),
            VectorsMut::Aos(&mut want),
            None,
        )
        .unwrap();
        assert!(want[0][0] > 0.0);
        assert_eq!(f[k], want[0], "query {k}");
    }
}
