//! Per-query parameter sets (issue 15): a query of a table of materials of
//! one shape (whose materials are parameter sets of one BSDF) answers bit
//! for bit what a BSDF built from its set's material file answers, with the same seed and key, on both engines, for every kind of
//! parameter, in batches that mix the sets; and a set's walks in such
//! batches are its own stack's, walk by walk (the scalar engine's on each
//! stack: `tests/parity/param_sets.rs`). (The physics of each set is the
//! physics of its own stack, which the other suites check: this file
//! checks that a set reaches every kernel that reads a number, and nothing
//! else.)

use crate::common;
use crate::common::batches::{Batches, MaterialBatches};
use common::sets::*;
use common::*;
use strata_bsdf::estimator::coat_lambertian::CoatLambertian;
use strata_bsdf::estimator::params::SetTable;
use strata_bsdf::estimator::wavefront::{Plan, Sets, Wavefront};
use strata_bsdf::lane::F32x8;
use strata_bsdf::{
    BatchError, Engine, Estimator, LayerStack, LayeredBsdf, Materials, QueryError, Settings,
    Transport,
};

/// Every call of a batch on a table of one shape against the same query on a BSDF
/// of its set's own stack, on each engine and estimator, in both transport
/// modes (importance runs the adjoint walks of the tilted family).
#[test]
fn a_set_answers_what_its_material_file_answers() {
    let modes = [Estimator::Auto, Estimator::Unidirectional]
        .into_iter()
        .flat_map(|e| [Transport::Radiance, Transport::Importance].map(|t| (e, t)));
    for f in families() {
        let stacks: Vec<LayerStack> = (0..SETS).map(|v| variant(&f, v)).collect();
        for engine in [Engine::Scalar, Engine::Wavefront, Engine::Auto] {
            for (estimator, transport) in modes.clone() {
                let make = |s: &LayerStack| {
                    LayeredBsdf::new(s.clone())
                        .engine(engine)
                        .estimator(estimator)
                        .transport(transport)
                        .samples(40)
                        .seed(7)
                };
                let bsdf = make(&stacks[0]);
                let sets = Materials::new(&bsdf, stacks.clone());
                let (pairs, set) = queries(23);
                let keys: Vec<u64> = (0..pairs.len() as u64).map(|k| 1000 + k).collect();
                let what = |k: usize| {
                    format!(
                        "{} {engine:?} {estimator:?} {transport:?} query {k}",
                        f.name
                    )
                };
                // eval
                let got = sets.eval_batch_keyed(&set, &pairs, 40, &keys).unwrap();
                for (k, g) in got.iter().enumerate() {
                    let own = make(&stacks[set[k] as usize]);
                    let want = own.eval_batch_keyed(&pairs[k..k + 1], 40, &keys[k..k + 1]);
                    let want = want.unwrap()[0];
                    assert_eq!(bits(g.value), bits(want.value), "eval {}", what(k));
                    assert_eq!(bits(g.stderr), bits(want.stderr), "eval {}", what(k));
                }
                // sample (and the pdf it carries)
                let wis: Vec<glam::Vec3> = pairs.iter().map(|p| p.0).collect();
                let index: Vec<u64> = (0..wis.len() as u64).collect();
                let got = sets.sample_batch_keyed(&set, &wis, &keys, &index).unwrap();
                for (k, g) in got.iter().enumerate() {
                    let own = make(&stacks[set[k] as usize]);
                    let want = own
                        .sample_batch_keyed(&wis[k..k + 1], &keys[k..k + 1], &index[k..k + 1])
                        .unwrap()[0];
                    assert_eq!(*g, want, "sample {}", what(k));
                }
                // pdf, approximate and unbiased
                let got = sets.pdf_batch(&set, &pairs).unwrap();
                let got_u = sets.pdf_unbiased_batch(&set, &pairs, 6).unwrap();
                for k in 0..pairs.len() {
                    let own = make(&stacks[set[k] as usize]);
                    let want = own.pdf_batch(&pairs[k..k + 1]).unwrap()[0];
                    assert_eq!(got[k].to_bits(), want.to_bits(), "pdf {}", what(k));
                    let want = own.pdf_unbiased_batch(&pairs[k..k + 1], 6).unwrap()[0];
                    assert_eq!(got_u[k], want, "unbiased pdf {}", what(k));
                }
                // albedo
                let got = sets.albedo_batch_keyed(&set, &wis, 24, &keys).unwrap();
                for (k, g) in got.iter().enumerate() {
                    let own = make(&stacks[set[k] as usize]);
                    let want = own
                        .albedo_batch_keyed(&wis[k..k + 1], 24, &keys[k..k + 1])
                        .unwrap()[0];
                    assert_eq!(*g, want, "albedo {}", what(k));
                }
            }
        }
    }
}

/// The sets really differ: a batch of sets does not answer what the base
/// material answers (else the test above could pass with the sets ignored).
#[test]
fn sets_change_the_answers() {
    for f in families() {
        let stacks: Vec<LayerStack> = (0..SETS).map(|v| variant(&f, v)).collect();
        let bsdf = LayeredBsdf::new(stacks[0].clone()).samples(64);
        let sets = Materials::new(&bsdf, stacks.clone());
        let (pairs, _) = queries(10);
        let one = vec![1u32; pairs.len()];
        let a = bsdf.eval_batch(&pairs).unwrap();
        let b = sets.eval_batch(&one, &pairs).unwrap();
        let differ = a.iter().zip(&b).filter(|(x, y)| x.value != y.value).count();
        assert!(differ >= 5, "{}: only {differ} of 10 evals differ", f.name);
    }
}

/// Walk by walk: the wavefront's walks with per-query sets are the walks of
/// the same plan on each set's own stack (a heterogeneous batch: sets
/// interleaved, so chunks gather their lanes' numbers). The specialized
/// walks on each stack are the scalar engine's: `tests/parity/param_sets.rs`.
#[test]
fn a_set_walks_as_its_own_stack_walk_by_walk() {
    let settings = Settings::default();
    for f in families() {
        let stacks: Vec<LayerStack> = (0..SETS).map(|v| variant(&f, v)).collect();
        let mut table = SetTable::new(stacks[0].len());
        for (s, st) in stacks.iter().enumerate() {
            let cv = (s % 2 == 1)
                .then(|| CoatLambertian::unscattered(st, &settings))
                .flatten();
            table.push(st, cv, true, true);
        }
        let table = std::sync::Arc::new(table);
        let (pairs, set) = queries(17);
        let dirs = unit_dirs(&pairs);
        let keys: Vec<u64> = (0..dirs.len() as u64).collect();
        for plan in [Plan::Specialized, Plan::General] {
            let wave = Wavefront::<F32x8>::new(&stacks[0], settings, plan);
            let sets = Sets::Table(&table, &set);
            let got = wave.eval_walk_values_in(sets, &dirs, 24, 3, &keys);
            for (k, walks) in got.iter().enumerate() {
                let s = set[k] as usize;
                let cv = s % 2 == 1;
                let want = Wavefront::<F32x8>::new(&stacks[s], settings, plan)
                    .with_control_variate(cv)
                    .eval_walk_values(&dirs[k..k + 1], 24, 3, &keys[k..k + 1])
                    .remove(0);
                assert_eq!(walks.len(), want.len());
                for (w, (a, b)) in walks.iter().zip(&want).enumerate() {
                    assert_eq!(bits(*a), bits(*b), "{} {plan:?} query {k} walk {w}", f.name);
                }
            }
            // Analog walks: samples.
            let wis: Vec<[f64; 3]> = dirs.iter().map(|d| d.0).collect();
            let index: Vec<u64> = (0..wis.len() as u64).map(|k| k * 5).collect();
            let (got, _) = wave.sample_batch_in(sets, &wis, 3, &keys, &index);
            for (k, g) in got.iter().enumerate() {
                let s = &stacks[set[k] as usize];
                let w = Wavefront::<F32x8>::new(s, settings, plan);
                let (ks, ix) = (&keys[k..k + 1], &index[k..k + 1]);
                let want = w.sample_batch(&wis[k..k + 1], 3, ks, ix).0[0];
                assert_eq!(*g, want, "{} {plan:?} sample {k}", f.name);
            }
        }
    }
}

/// Sets of another shape are refused, naming the set and the difference;
/// a query's set index out of range names the query; sets made by a BSDF
/// of another estimator are refused.
#[test]
fn sets_that_do_not_fit_are_errors() {
    let fam = families();
    let a = variant(&fam[0], 0);
    let b = variant(&fam[1], 0);
    let bsdf = LayeredBsdf::new(a.clone());
    // Materials of two shapes are two BSDFs, each answering its own.
    assert_eq!(Materials::new(&bsdf, [a.clone(), b]).shapes(), 2);
    // A roughness of 0 makes a rough interface smooth: another shape.
    let r = |k: u64, lo: f64, hi: f64| {
        if k == 2 || k == 3 {
            0.0
        } else {
            uniform(1, k, lo, hi)
        }
    };
    let smooth = stack(&(fam[0].toml)(&r));
    assert_eq!(Materials::new(&bsdf, [a.clone(), smooth]).shapes(), 2);
    let sets = Materials::new(&bsdf, [a.clone(), a.clone()]);
    assert_eq!(sets.shapes(), 1);
    let (pairs, _) = queries(4);
    let e = sets.eval_batch(&[0, 1, 2, 0], &pairs).unwrap_err();
    assert_eq!(
        e,
        BatchError {
            index: Some(2),
            error: QueryError::NoSuchMaterial {
                value: 2,
                materials: 2
            }
        }
    );
    assert_eq!(
        e.to_string(),
        "query 2: material = 2: there are 2 materials (0 to 1)"
    );
    let e = sets.eval_batch(&[0, 1], &pairs).unwrap_err();
    assert!(
        e.to_string().contains("rows has 2 entries for 4 queries"),
        "{e}"
    );
    // Without rows a batch has a query per material: 4 queries on 2 are an
    // error naming the rows.
    let (wi, wo): (Vec<_>, Vec<_>) = pairs.iter().copied().unzip();
    let q = strata_bsdf::Queries::pairs(&wi, &wo);
    let e = strata_bsdf::Bsdf::eval_into(&sets, &q, &mut |_, _| ()).unwrap_err();
    assert_eq!(
        e.to_string(),
        "rows has 0 entries for 4 queries: give one per query"
    );
}

/// Columns that cannot make materials are errors, never panics: a query
/// count past what materials can be numbered by, a length that is not
/// width × queries; and a fault of the whole column (a path the material
/// lacks, a path twice, a width its field refuses) is its own error
/// (`ColumnsError::Column`, which the C and Python bindings name the column
/// by), found before any row, so in an empty batch too; one query's invalid
/// values are that query's.
#[test]
fn bad_columns_are_errors_and_name_their_column() {
    use strata_bsdf::{Column, ColumnsError, MAX_QUERIES};
    let bsdf = LayeredBsdf::new(stack(
        "[[layers]]\ninterface = { kind = \"dielectric\", ior = 1.5 }\n\
         medium = { thickness = 1, sigma_t = 0.5 }\n\
         [[layers]]\ninterface = { kind = \"diffuse\", albedo = 0.8 }\n",
    ));
    let e = Materials::per_query(&bsdf, usize::MAX, &[]).unwrap_err();
    assert_eq!(
        e,
        ColumnsError::TooManyQueries {
            queries: usize::MAX
        }
    );
    assert!(e.to_string().contains(&MAX_QUERIES.to_string()), "{e}");
    assert_eq!(Materials::identity(3), [0, 1, 2]);
    let thickness = "layers[0].medium.thickness".parse().unwrap();
    let two = [1.0f32, 2.0];
    let col = |path, width, values| Column {
        path,
        width,
        values,
    };
    // Far fewer values than width × queries (a product that is checked).
    let e = Materials::per_query(&bsdf, MAX_QUERIES, &[col(&thickness, 3, &two)]);
    assert!(matches!(e, Err(ColumnsError::Length { .. })));
    // A query's invalid value: its own fault, no column at fault.
    let bad = [0.5f32, -1.0];
    let e = Materials::per_query(&bsdf, 2, &[col(&thickness, 1, &bad)]).unwrap_err();
    assert!(matches!(e, ColumnsError::Query { query: 1, .. }), "{e}");
    // The value as the caller wrote it: -0.1, not its widening to f64
    // (-0.10000000149011612).
    let bad = [0.5f32, -0.1];
    let e = Materials::per_query(&bsdf, 2, &[col(&thickness, 1, &bad)]).unwrap_err();
    let m = e.to_string();
    assert!(
        m.contains("` = -0.1: invalid material") && m.contains("thickness = -0.1: must be"),
        "{m}"
    );
    let column = |e: ColumnsError| match e {
        ColumnsError::Column { column, error } => (column, error.to_string()),
        e => panic!("not a column's fault: {e}"),
    };
    // A path the material does not have, after a good column; in an empty
    // batch too.
    let eta = "layers[1].interface.eta".parse().unwrap();
    let cols = [col(&thickness, 1, &two), col(&eta, 1, &two)];
    let (i, m) = column(Materials::per_query(&bsdf, 2, &cols).unwrap_err());
    assert!(
        i == 1 && m.contains("diffuse, which has no `eta`"),
        "{i} {m}"
    );
    let empty = [col(&thickness, 1, &[]), col(&eta, 1, &[])];
    assert_eq!(
        column(Materials::per_query(&bsdf, 0, &empty).unwrap_err()).0,
        1
    );
    // A triple for a field of one number: the width's fault.
    let six = [1.0f32; 6];
    let (i, m) = column(Materials::per_query(&bsdf, 2, &[col(&thickness, 3, &six)]).unwrap_err());
    assert!(i == 0 && m.contains("layers[0].medium.thickness"), "{m}");
    // The same path twice: the second.
    let cols = [col(&thickness, 1, &two), col(&thickness, 1, &two)];
    let (i, m) = column(Materials::per_query(&bsdf, 2, &cols).unwrap_err());
    assert!(i == 1 && m.contains("given twice"), "{i} {m}");
    // Good columns in an empty batch: no materials, no error.
    assert_eq!(
        Materials::per_query(&bsdf, 0, &[col(&thickness, 1, &[])])
            .unwrap()
            .len(),
        0
    );
}

/// A column's float sets its shortest correctly rounded decimal, ties to
/// even: 0.181640625 (an exact half-float, halfway between 0.18164062 and
/// 0.18164063) is a material file's 0.18164062, as C's `%.8g` and Python's
/// `'%.8g'` print it, and not the 0.18164063 of Rust's `Display`. Where the
/// column's value is the template's own, the rough coat over a Lambertian
/// base keeps the template's walk-free form (`Estimator::Auto`), so its
/// answers are the file's bit for bit; a column read as another number
/// would be walked instead.
#[test]
fn a_column_sets_its_correctly_rounded_decimal() {
    use strata_bsdf::Column;
    let template = LayeredBsdf::new(stack(
        "[[layers]]\ninterface = { kind = \"dielectric\", ior = 1.5, roughness = 0.18164062 }\n\
         medium = { thickness = 0.1, sigma_t = 1.0, albedo = 0.0 }\n\
         [[layers]]\ninterface = { kind = \"diffuse\", albedo = 0.8 }\n",
    ))
    .samples(32)
    .seed(5);
    assert!(template.eval_without_walks());
    let path = "layers[0].interface.roughness".parse().unwrap();
    let n = 8;
    let tie = vec![0.181_640_63f32; n];
    assert_eq!(f64::from(tie[0]), 0.181_640_625, "the tie itself, exactly");
    let column = Column {
        path: &path,
        width: 1,
        values: &tie,
    };
    let m = Materials::per_query(&template, n, &[column]).unwrap();
    let ids = Materials::identity(n);
    let (pairs, _) = queries(n);
    assert_eq!(
        m.eval_batch(&ids, &pairs).unwrap(),
        template.eval_batch(&pairs).unwrap()
    );
    assert_eq!(
        m.pdf_unbiased_batch(&ids, &pairs, 16).unwrap(),
        template.pdf_unbiased_batch(&pairs, 16).unwrap()
    );
}

/// A heterogeneous batch: materials of five shapes (five of each) in one
/// call, queries interleaved; each answers what its material alone answers
/// with the template's configuration.
#[test]
fn a_mixed_batch_answers_what_each_material_answers() {
    let stacks: Vec<LayerStack> = (families().iter())
        .flat_map(|f| (0..SETS).map(move |v| variant(f, v)))
        .collect();
    for engine in [Engine::Scalar, Engine::Wavefront] {
        let template = LayeredBsdf::new(stacks[0].clone())
            .engine(engine)
            .samples(32)
            .seed(11);
        let mats = Materials::new(&template, stacks.clone());
        let shapes = families().len();
        let m = shapes * SETS as usize;
        assert_eq!((mats.len(), mats.shapes()), (m, shapes));
        let (pairs, _) = queries(41);
        let material: Vec<u32> = (0..pairs.len() as u32).map(|k| k * 7 % m as u32).collect();
        let own = |k: usize| template.with_stack(stacks[material[k] as usize].clone());
        let eval = mats.eval_batch(&material, &pairs).unwrap();
        let wis: Vec<glam::Vec3> = pairs.iter().map(|p| p.0).collect();
        let index: Vec<u64> = (0..wis.len() as u64).collect();
        let samples = mats.sample_batch(&material, &wis, &index).unwrap();
        let pdf = mats.pdf_batch(&material, &pairs).unwrap();
        let keys: Vec<u64> = (0..wis.len() as u64).map(|k| k ^ 0xabc).collect();
        let albedo = mats.albedo_batch_keyed(&material, &wis, 16, &keys).unwrap();
        for k in 0..pairs.len() {
            let b = own(k);
            let what = format!("{engine:?} query {k} (material {})", material[k]);
            let e = b.eval_batch(&pairs[k..k + 1]).unwrap()[0];
            assert_eq!(bits(eval[k].value), bits(e.value), "eval {what}");
            let s = b.sample_batch(&wis[k..k + 1], &index[k..k + 1]).unwrap()[0];
            assert_eq!(samples[k], s, "sample {what}");
            let p = b.pdf_batch(&pairs[k..k + 1]).unwrap()[0];
            assert_eq!(pdf[k].to_bits(), p.to_bits(), "pdf {what}");
            let a = b
                .albedo_batch_keyed(&wis[k..k + 1], 16, &keys[k..k + 1])
                .unwrap()[0];
            assert_eq!(albedo[k], a, "albedo {what}");
        }
        // An index past the materials names the query.
        let mut bad = material.clone();
        bad[9] = m as u32;
        let e = mats.eval_batch(&bad, &pairs).unwrap_err();
        assert_eq!(e.index, Some(9));
        assert_eq!(
            e.to_string(),
            format!(
                "query 9: material = {m}: there are {m} materials (0 to {})",
                m - 1
            )
        );
        // A bad direction is named by its index in the whole batch.
        let mut p2 = pairs.clone();
        p2[13].1 = glam::Vec3::new(f32::NAN, 0.0, 1.0);
        let e = mats.eval_batch(&material, &p2).unwrap_err();
        assert_eq!(e.index, Some(13), "{e}");
    }
}

/// Per-query columns over a rough coat over a Lambertian base: a column of
/// the base's albedo keeps the coat and the layer of the template, whose
/// integral `R̄` every query shares, and each query answers bit for bit what
/// its material file answers (without walks); a roughness column would need
/// an integral per distinct value, so the queries whose roughness is not the
/// template's are answered by the plain walks: bit for bit what their
/// material file answers under `Estimator::Unidirectional`. The rule is the
/// query's own value against the template's, whatever the batch's first
/// query is.
#[test]
fn per_query_columns_share_the_rough_coats_integral_or_walk() {
    use strata_bsdf::Column;
    let base = stack(
        "[[layers]]\n\
         interface = { kind = \"dielectric\", ior = 1.5, roughness = 0.2 }\n\
         medium = { thickness = 0.1, sigma_t = 1.0, albedo = 0.0 }\n\
         [[layers]]\n\
         interface = { kind = \"diffuse\", albedo = 0.8 }\n",
    );
    let template = LayeredBsdf::new(base.clone()).samples(32).seed(3);
    // Enough queries for the wavefront (a batch of more walks than lanes),
    // the six values in turn.
    let n = 24;
    let (pairs, _) = queries(n);
    let keys: Vec<u64> = (0..n as u64).collect();
    for (path, values, template_value) in [
        (
            "layers[1].interface.albedo",
            [0.2, 0.4, 0.5, 0.6, 0.8, 0.9],
            None,
        ),
        (
            "layers[0].interface.roughness",
            [0.3, 0.2, 0.1, 0.4, 0.2, 0.6],
            Some(0.2),
        ),
    ] {
        let p = path.parse().unwrap();
        let values: Vec<f64> = (0..n).map(|k| values[k % 6]).collect();
        let column_values: Vec<f32> = values.iter().map(|&x| x as f32).collect();
        let column = Column {
            path: &p,
            width: 1,
            values: &column_values,
        };
        let m = Materials::per_query(&template, n, &[column]).unwrap();
        let ids = Materials::identity(n);
        let got = m.eval_batch_keyed(&ids, &pairs, 32, &keys).unwrap();
        let wis: Vec<_> = pairs.iter().map(|p| p.0).collect();
        let idx: Vec<u64> = (0..n as u64).collect();
        let s = m.sample_batch_keyed(&ids, &wis, &keys, &idx).unwrap();
        let p_all = m.pdf_batch(&ids, &pairs).unwrap();
        let u = m.pdf_unbiased_batch(&ids, &pairs, 8).unwrap();
        for k in 0..n {
            // The column's f32 is the decimal a material file gives.
            let st = base.with_set(&[(p.clone(), values[k].into())]);
            let own = LayeredBsdf::new(st.unwrap()).samples(32).seed(3);
            let walked = template_value.is_some_and(|t| values[k] != t);
            assert!(own.eval_without_walks());
            let own = if walked {
                own.estimator(Estimator::Unidirectional)
            } else {
                own
            };
            let want = own.eval_batch_keyed(&pairs[k..k + 1], 32, &keys[k..k + 1]);
            assert_eq!(got[k], want.unwrap()[0], "{path}, query {k}");
            // sample and pdf too, in a batch that mixes walk-free and walked
            // queries: each its material file's, bit for bit.
            let want = own.sample_batch_keyed(&wis[k..k + 1], &keys[k..k + 1], &idx[k..k + 1]);
            assert_eq!(s[k], want.unwrap()[0], "{path}, sample {k}");
            assert_eq!(own.sample_is_exact(), !walked, "{path}, query {k}");
            let want = own.pdf_batch(&pairs[k..k + 1]).unwrap()[0];
            assert_eq!(p_all[k].to_bits(), want.to_bits(), "{path}, pdf {k}");
            let want = own.pdf_unbiased_batch(&pairs[k..k + 1], 8).unwrap()[0];
            assert_eq!(u[k], want, "{path}, unbiased pdf {k}");
        }
    }
}

/// A BSDF whose own stack has no walk-free form (an anisotropic rough coat
/// over a Lambertian base) still answers a set that has one (an isotropic
/// coat) without walks, as that set's material file does; a batch of
/// materials answers each whatever their order; per-query columns over such
/// a template are walked (the template has no integral to share), row by
/// row whatever the order of the rows.
#[test]
fn a_set_has_its_own_walk_free_form_whatever_the_bsdf_or_the_order() {
    use strata_bsdf::Column;
    let coat = |rough: &str| {
        stack(&format!(
            "[[layers]]\ninterface = {{ kind = \"dielectric\", ior = 1.5, roughness = {rough} }}\n\
             medium = {{ thickness = 0.2, sigma_t = 1.0, albedo = 0.0 }}\n\
             [[layers]]\ninterface = {{ kind = \"diffuse\", albedo = 0.7 }}\n"
        ))
    };
    let (aniso, iso) = (coat("[0.1, 0.3]"), coat("0.2"));
    let make = |s: &LayerStack| LayeredBsdf::new(s.clone()).samples(32).seed(9);
    assert!(!make(&aniso).eval_without_walks() && make(&iso).eval_without_walks());
    let (pairs, _) = queries(12);
    let keys: Vec<u64> = (0..12).collect();
    let want: Vec<_> = (0..12)
        .map(|k| {
            make(&iso)
                .eval_batch_keyed(&pairs[k..k + 1], 32, &keys[k..k + 1])
                .unwrap()[0]
        })
        .collect();
    // Materials in either order: with the anisotropic first, the isotropic
    // is a parameter set of its BSDF.
    for order in [[aniso.clone(), iso.clone()], [iso.clone(), aniso.clone()]] {
        let m = Materials::new(&make(&aniso), order.clone());
        let which = if order[0].interface(0).alpha[0] == 0.2 {
            0
        } else {
            1
        };
        let got = m.eval_batch_keyed(&[which; 12], &pairs, 32, &keys).unwrap();
        assert_eq!(got, want, "iso material at {which}");
    }
    // Per-query columns over the anisotropic template: walked, row by row.
    let p: strata_bsdf::SetPath = "layers[0].interface.roughness".parse().unwrap();
    for values in [[0.2f32, 0.3, 0.2], [0.3, 0.2, 0.2]] {
        let column: Vec<f32> = (0..12).map(|k| values[k % 3]).collect();
        let col = Column {
            path: &p,
            width: 1,
            values: &column,
        };
        let m = Materials::per_query(&make(&aniso), 12, &[col]).unwrap();
        let got = m
            .eval_batch_keyed(&Materials::identity(12), &pairs, 32, &keys)
            .unwrap();
        for k in 0..12 {
            let st = aniso
                .with_set(&[(p.clone(), (column[k] as f64).into())])
                .unwrap();
            let own = make(&st).estimator(Estimator::Unidirectional);
            let w = own
                .eval_batch_keyed(&pairs[k..k + 1], 32, &keys[k..k + 1])
                .unwrap()[0];
            assert_eq!(got[k], w, "rows {values:?}, query {k}");
        }
    }
}

/// `Materials::per_query` holds at most `MAX_MATERIAL_LAYERS` layers' worth
/// of materials: one distinct row more is an error naming the rows and the
/// layers (it points to `PerQuery`, which takes the same batch).
#[test]
fn per_query_materials_are_bounded() {
    use strata_bsdf::{Column, ColumnsError, PerQuery, MAX_MATERIAL_LAYERS};
    let bsdf = LayeredBsdf::new(stack(COATED_COPPER));
    assert_eq!(bsdf.stack().len(), 2);
    let rows = MAX_MATERIAL_LAYERS / 2 + 1;
    let thickness: Vec<f32> = (0..rows).map(|k| 0.1 + k as f32 * 1e-5).collect();
    let path = "layers[0].medium.thickness".parse().unwrap();
    let columns = [Column {
        path: &path,
        width: 1,
        values: &thickness,
    }];
    let e = Materials::per_query(&bsdf, rows, &columns).unwrap_err();
    assert_eq!(e, ColumnsError::TooManyRows { rows, layers: 2 });
    assert!(e.to_string().contains("PerQuery"), "{e}");
    assert!(PerQuery::new(&bsdf, rows, &columns).is_ok());
}
