//! Times the walks on a lossless slab of optical depth 10^4 (glass over a
//! white medium over air), whose walks diffuse for up to ~10^8 events, under
//! the default limit of events per walk: 36 queries × 16 walks of the
//! bidirectional estimator, the unidirectional one and the unbiased pdf, on
//! one thread, and how many walks the limit cut. `cargo run --release -p strata-bsdf --example bounded_walks
//! [max_events]`.

use glam::Vec3;
use std::time::Instant;
use strata_bsdf::{Bsdf, Estimate, Estimator, LayerStack, LayeredBsdf, PdfEstimate, Queries};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let toml = include_str!("../tests/data/lossless_slab_tau_1e4.toml");
    let mut bsdf = LayeredBsdf::new(LayerStack::from_toml_str(toml)?).threads(1)?;
    if let Some(n) = std::env::args().nth(1) {
        bsdf = bsdf.max_events(n.parse()?);
    }
    let pairs: Vec<(Vec3, Vec3)> = (0..36)
        .map(|k| {
            let (a, b) = (0.2 + 0.2 * (k / 6) as f32, 0.1 + 0.25 * (k % 6) as f32);
            let side = if k % 2 == 0 { 1.0 } else { -1.0 };
            let wo = Vec3::new(-b.sin(), 0.1, side * b.cos()).normalize();
            (Vec3::new(a.sin(), 0.0, a.cos()), wo)
        })
        .collect();
    let keys: Vec<u64> = (0..pairs.len() as u64).collect();
    println!("max_events {}", bsdf.settings().max_events);
    for estimator in [Estimator::Bidirectional, Estimator::Unidirectional] {
        let t = Instant::now();
        let (wi, wo): (Vec<Vec3>, Vec<Vec3>) = pairs.iter().copied().unzip();
        let q = Queries::pairs(&wi, &wo).keys(&keys).walks(16);
        let mut e = vec![Estimate::default(); pairs.len()];
        let b = bsdf.clone().estimator(estimator);
        b.eval_into(&q, &mut |k, x| e[k] = *x)?;
        let mean = e.iter().map(|e| e.value[0]).sum::<f64>() / e.len() as f64;
        let s = t.elapsed().as_secs_f64();
        let cut: u64 = e.iter().map(|e| e.truncated).sum();
        println!("eval {estimator:?}: {s:.2} s, mean f {mean:.4}, {cut} walks cut");
    }
    let t = Instant::now();
    let (wi, wo): (Vec<Vec3>, Vec<Vec3>) = pairs.iter().copied().unzip();
    let mut p = vec![PdfEstimate::default(); pairs.len()];
    bsdf.pdf_unbiased_into(&Queries::pairs(&wi, &wo).walks(16), &mut |k, x| p[k] = *x)?;
    let mean = p.iter().map(|p| p.value).sum::<f64>() / p.len() as f64;
    let s = t.elapsed().as_secs_f64();
    let cut: u64 = p.iter().map(|p| p.truncated).sum();
    println!("pdf_unbiased: {s:.2} s, mean pdf {mean:.4}, {cut} walks cut");
    Ok(())
}
