//! Per-query columns run a chunk at a time ([`PerQuery`]) answer what the
//! unchunked path answers (one table of the rows written in place, or, for
//! columns that are not, [`Materials::per_query`] and [`Materials`]' slice
//! calls), bit for bit: eval, sample, pdf, unbiased pdf and albedo, keyed
//! and unkeyed, on both engines (and `Auto`), over batches that span
//! several chunks (the default chunk of 4096 distinct rows, and chunks of
//! 7 rows with repeated rows inside and across them).

use crate::common::batches::{Buffers, MaterialBuffers};
use crate::common::COATED_COPPER;
use strata_bsdf::{
    AlbedoRecord, Column, Engine, LayerStack, LayeredBsdf, Materials, PerQuery, SampleRecord,
    Vectors, VectorsMut, CHUNK_ROWS,
};

/// Directions of `n` queries, spread over the hemispheres (some below).
fn directions(n: usize) -> (Vec<[f32; 3]>, Vec<[f32; 3]>, Vec<u64>) {
    let dir = |k: usize, s: f32| {
        let t = k as f32 * 0.618_034 * s;
        let z = 0.1 + 0.85 * (t * 1.3).sin().abs();
        let r = (1.0 - z * z).sqrt();
        [r * t.cos(), r * t.sin(), if k % 11 == 3 { -z } else { z }]
    };
    let wi = (0..n).map(|k| dir(k, 1.0)).collect();
    let wo = (0..n).map(|k| dir(k + 7, 2.3)).collect();
    let keys = (0..n as u64)
        .map(|k| k.wrapping_mul(0x9e37_79b9_7f4a_7c15))
        .collect();
    (wi, wo, keys)
}

/// Answers of every call, as bits.
#[derive(Debug, PartialEq)]
struct Answers {
    eval: Vec<[f32; 3]>,
    eval_se: Vec<[f32; 3]>,
    eval_keyed: Vec<[f32; 3]>,
    sample: Vec<[u32; 8]>,
    sample_keyed: Vec<[u32; 8]>,
    pdf: Vec<u32>,
    pdf_unbiased: Vec<(u32, u32)>,
    albedo: Vec<[u32; 12]>,
}

fn bits3(v: &[[f32; 3]]) -> Vec<[f32; 3]> {
    v.to_vec()
}

fn sample_bits(r: &[SampleRecord]) -> Vec<[u32; 8]> {
    r.iter()
        .map(|s| {
            let b = |x: f32| x.to_bits();
            [
                b(s.wo[0]),
                b(s.wo[1]),
                b(s.wo[2]),
                b(s.weight[0]),
                b(s.weight[1]),
                b(s.weight[2]),
                b(s.pdf),
                s.flags,
            ]
        })
        .collect()
}

fn albedo_bits(r: &[AlbedoRecord]) -> Vec<[u32; 12]> {
    r.iter()
        .map(|a| {
            let v: Vec<u32> = (a.reflected.iter())
                .chain(&a.transmitted)
                .chain(&a.reflected_stderr)
                .chain(&a.transmitted_stderr)
                .map(|x| x.to_bits())
                .collect();
            v.try_into().unwrap()
        })
        .collect()
}

/// Runs every call through `run`'s target.
macro_rules! answers {
    ($t:expr, $n:expr, $wi:expr, $wo:expr, $keys:expr $(, $ids:expr)?) => {{
        let (t, n) = (&$t, $n);
        let (wi, wo) = (Vectors::Aos($wi), Vectors::Aos($wo));
        let mut f = vec![[0f32; 3]; n];
        let mut se = vec![[0f32; 3]; n];
        t.eval_buffers($($ids,)? wi, wo, None, VectorsMut::Aos(&mut f), Some(VectorsMut::Aos(&mut se)))
            .unwrap();
        let mut fk = vec![[0f32; 3]; n];
        t.eval_buffers($($ids,)? wi, wo, Some($keys), VectorsMut::Aos(&mut fk), None).unwrap();
        let mut s = vec![SampleRecord::default(); n];
        t.sample_records($($ids,)? wi, None, &mut s).unwrap();
        let mut sk = vec![SampleRecord::default(); n];
        t.sample_records($($ids,)? wi, Some($keys), &mut sk).unwrap();
        let mut p = vec![0f32; n];
        t.pdf_buffers($($ids,)? wi, wo, &mut p).unwrap();
        let (mut pu, mut pus) = (vec![0f32; n], vec![0f32; n]);
        t.pdf_unbiased_buffers($($ids,)? wi, wo, 2, &mut pu, &mut pus).unwrap();
        let mut a = vec![AlbedoRecord::default(); n];
        t.albedo_records($($ids,)? wi, 2, Some($keys), &mut a).unwrap();
        Answers {
            eval: bits3(&f),
            eval_se: bits3(&se),
            eval_keyed: bits3(&fk),
            sample: sample_bits(&s),
            sample_keyed: sample_bits(&sk),
            pdf: p.iter().map(|x| x.to_bits()).collect(),
            pdf_unbiased: pu.iter().zip(&pus).map(|(a, b)| (a.to_bits(), b.to_bits())).collect(),
            albedo: albedo_bits(&a),
        }
    }};
}

#[test]
fn chunked_per_query_calls_answer_the_unchunked_numbers() {
    let stack = LayerStack::from_toml_str(COATED_COPPER).unwrap();
    // Distinct rows beyond two default chunks; then rows that repeat.
    let n = 2 * CHUNK_ROWS + 1500;
    let thickness: Vec<f32> = (0..n).map(|k| 0.05 + k as f32 * 1e-4).collect();
    let roughness: Vec<f32> = (0..n).map(|k| 0.05 + (k % 5) as f32 * 0.05).collect();
    // An IOR is not written in place: its rows are materials.
    let ior: Vec<f32> = (0..n).map(|k| 1.4 + (k % 9) as f32 * 0.02).collect();
    let t_path = "layers[0].medium.thickness".parse().unwrap();
    let r_path = "layers[0].interface.roughness".parse().unwrap();
    let i_path = "layers[0].interface.ior".parse().unwrap();
    let (wi, wo, keys) = directions(n);
    let col = |path, values| {
        [Column {
            path,
            width: 1,
            values,
        }]
    };
    for engine in [Engine::Scalar, Engine::Wavefront, Engine::Auto] {
        let template = LayeredBsdf::new(stack.clone())
            .engine(engine)
            .samples(1)
            .seed(3);
        let (distinct, repeated) = (col(&t_path, &thickness), col(&r_path, &roughness));
        let materials = col(&i_path, &ior);
        for (columns, rows) in [
            (&distinct, None),
            (&repeated, Some(7)),
            (&distinct, Some(7)),
            (&materials, None),
            (&materials, Some(7)),
        ] {
            // The whole batch in one chunk: rows in place as one table, or
            // the materials of `Materials::per_query`.
            let whole = if columns[0].path.in_place() {
                let q = PerQuery::new(&template, n, columns).unwrap();
                answers!(q.with_chunk_rows(n), n, &wi, &wo, &keys)
            } else {
                let m = Materials::per_query(&template, n, columns).unwrap();
                answers!(m, n, &wi, &wo, &keys, &Materials::identity(n))
            };
            let mut q = PerQuery::new(&template, n, columns).unwrap();
            assert_eq!(q.chunk_rows(), CHUNK_ROWS, "two layers: the default chunk");
            if let Some(r) = rows {
                q = q.with_chunk_rows(r);
            }
            let chunked = answers!(q, n, &wi, &wo, &keys);
            assert!(whole == chunked, "{engine:?}, chunks of {:?} rows", rows);
        }
    }
}

/// A row that makes an invalid material is found before anything runs, in
/// any chunk; arguments are checked before the first chunk writes.
#[test]
fn chunked_per_query_checks_everything_first() {
    let template = LayeredBsdf::new(LayerStack::from_toml_str(COATED_COPPER).unwrap()).samples(1);
    let n = CHUNK_ROWS + 10;
    let thickness: Vec<f32> = (0..n).map(|k| 0.05 + k as f32 * 1e-4).collect();
    let mut bad = thickness.clone();
    bad[n - 2] = -1.0;
    let path = "layers[0].medium.thickness".parse().unwrap();
    let col = |v| {
        [Column {
            path: &path,
            width: 1,
            values: v,
        }]
    };
    let e = PerQuery::new(&template, n, &col(&bad)).unwrap_err();
    assert!(
        e.to_string().starts_with(&format!("query {}: ", n - 2)),
        "{e}"
    );
    let q = PerQuery::new(&template, n, &col(&thickness)).unwrap();
    let (mut wi, wo, _) = directions(n);
    wi[n - 1] = [f32::NAN, 0.0, 1.0];
    let mut f = vec![[7f32; 3]; n];
    let e = q
        .eval_buffers(
            Vectors::Aos(&wi),
            Vectors::Aos(&wo),
            None,
            VectorsMut::Aos(&mut f),
            None,
        )
        .unwrap_err();
    assert_eq!(e.index, Some(n - 1));
    assert!(f.iter().all(|v| *v == [7.0; 3]), "nothing written");
    let e = q
        .eval_buffers(
            Vectors::Aos(&wi[1..]),
            Vectors::Aos(&wo[1..]),
            None,
            VectorsMut::Aos(&mut f[1..]),
            None,
        )
        .unwrap_err();
    assert!(e.to_string().contains("wi"), "{e}");
}
