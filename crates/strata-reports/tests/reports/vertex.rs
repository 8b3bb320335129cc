//! The renderer's vertex benchmark (`strata_reports::vertex`) as a test:
//! its estimator's mean, made of `sample`, `eval` and `pdf` at one walk each
//! with the library's default (lobe) pdf, against other calls of the
//! library: the reflected albedo (the sky) plus a quadrature over the sun of
//! many-walk evals (closed forms where the stack has them). MIS weights that
//! sum to one keep the vertex unbiased whatever the pdf; this checks that
//! they do, and that `sample`'s pdf is `pdf`'s.

use strata_bsdf::{Bsdf, Queries, SampleBuffers, Vectors, VectorsMut};
use strata_reports::vertex;

/// The vertex mean agrees with the albedo plus the sun's integral within
/// four combined standard errors, on a closed-form stack, a walked
/// scattering stack and a walked coated conductor (at views where f is
/// smooth over the sun, so the 8 × 8 midpoint rule is far below the noise).
#[test]
fn the_vertex_mean_is_the_sky_plus_the_sun() {
    let cases = [
        ("coated_diffuse_smooth_alb0", 45.0),
        ("coated_diffuse_rough_alb0.9_g0.5", 45.0),
        ("coated_conductor_rough_cu_rough0.1", 10.0),
    ];
    for (name, view) in cases {
        let c = vertex::configs()
            .into_iter()
            .find(|c| c.name == name)
            .expect("a configuration of the benchmark");
        let bsdf = vertex::renderer_bsdf(&c).expect("the configuration builds");
        let run = vertex::run(&bsdf, view, 4096, 8, 11, None).expect("the vertex runs");
        let (want, want_se) = vertex::expected(&bsdf, view, 1 << 14, 8).expect("references");
        let se = run.stderr().hypot(want_se);
        let z = (run.mean - want) / se;
        println!(
            "{name} at {view}: vertex {:.5} ± {:.5}, albedo + sun {want:.5} ± {want_se:.5}, z {z:.2}",
            run.mean,
            run.stderr()
        );
        assert!(
            se > 0.0 && se < 0.02 * want,
            "{name}: se {se} too loose a check"
        );
        assert!(z.abs() < 4.0, "{name} at {view}: z = {z:.2}");
    }
}

/// Under the default pdf, every sample carries exactly the number `pdf`
/// gives for its direction, and it is positive and finite.
#[test]
fn a_sample_carries_the_pdf_of_its_direction() {
    for c in vertex::configs() {
        let bsdf = vertex::renderer_bsdf(&c).expect("the configuration builds");
        let n = 512;
        let wi: Vec<f32> = (0..n)
            .flat_map(|k| vertex::view(10.0 + 70.0 * k as f64 / n as f64).map(|x| x as f32))
            .collect();
        let keys: Vec<u64> = (0..n as u64).collect();
        let (mut wo, mut weight) = (vec![0.0f32; 3 * n], vec![0.0f32; 3 * n]);
        let (mut pdf, mut flags) = (vec![0.0f32; n], vec![0u32; n]);
        let mut out = SampleBuffers {
            wo: VectorsMut::from_flat(&mut wo).unwrap(),
            weight: VectorsMut::from_flat(&mut weight).unwrap(),
            pdf: &mut pdf,
            flags: &mut flags,
        };
        let q = Queries::directions(Vectors::from_flat(&wi).unwrap()).keys(&keys);
        bsdf.sample_into(&q, &mut |k, s| out.put(k, s)).unwrap();
        // The pdf of every sampled direction, in one batch.
        let sampled: Vec<usize> = (0..n).filter(|&k| flags[k] != 0).collect();
        let pick = |v: &[f32]| -> Vec<f32> {
            sampled
                .iter()
                .flat_map(|&k| v[3 * k..3 * k + 3].to_vec())
                .collect()
        };
        let (wi_s, wo_s) = (pick(&wi), pick(&wo));
        let mut again = vec![0.0f32; sampled.len()];
        let q = Queries::pairs(
            Vectors::from_flat(&wi_s).unwrap(),
            Vectors::from_flat(&wo_s).unwrap(),
        );
        (bsdf.pdf_into(&q, &mut |k, p| again[k] = p)).unwrap_or_else(|e| panic!("{}: {e}", c.name));
        for (j, &k) in sampled.iter().enumerate() {
            assert!(
                pdf[k].is_finite() && pdf[k] > 0.0,
                "{}: pdf {}",
                c.name,
                pdf[k]
            );
            assert_eq!(pdf[k].to_bits(), again[j].to_bits(), "{} query {k}", c.name);
        }
        let sampled = sampled.len();
        assert!(sampled > n / 2, "{}: {sampled} samples of {n}", c.name);
    }
}
