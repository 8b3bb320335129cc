//! What a spectral query costs against an RGB one, as a renderer calls:
//! one thread, batches of 4096 evals of one walk, every query its own
//! random wavelengths in 380–830 nm (three a query, and four as two
//! passes, or four passes where the IOR varies), on three stacks whose
//! spectra vary. Best of 15 batches, thread-CPU time per query.
//!
//! ```sh
//! cargo run --release -p strata-reports --example spectral_cost
//! ```

use strata_bsdf::{Bsdf, Estimate, LayerStack, LayeredBsdf, PerQuery, Queries, SpectralColumns};
use strata_reports::vertex::thread_cpu_ns;

/// Queries per batch.
const N: usize = 4096;

/// The stacks: a rough coat over a scattering layer whose extinction is a
/// spectrum, over an RGB base; over measured copper; and the first with a
/// dispersive coat.
const STACKS: [(&str, &str); 3] = [
    (
        "coat / scatterer",
        "[[layers]]\ninterface = { kind = \"dielectric\", ior = 1.5, roughness = 0.1 }\n\
         medium = { thickness = 0.5, sigma_t = { nm = [400, 700], values = [1.5, 0.4] }, albedo = 0.8 }\n\
         [[layers]]\ninterface = { kind = \"diffuse\", albedo = [0.7, 0.4, 0.2] }\n",
    ),
    (
        "coat / Cu",
        "[[layers]]\ninterface = { kind = \"dielectric\", ior = 1.5, roughness = 0.1 }\n\
         medium = { thickness = 0.01, sigma_t = 1, albedo = 0 }\n\
         [[layers]]\ninterface = { kind = \"conductor\", preset = \"Cu\", roughness = 0.1 }\n",
    ),
    (
        "dispersive coat / scatterer",
        "[[layers]]\ninterface = { kind = \"dielectric\", ior = { nd = 1.5, abbe = 30 }, roughness = 0.1 }\n\
         medium = { thickness = 0.5, sigma_t = { nm = [400, 700], values = [1.5, 0.4] }, albedo = 0.8 }\n\
         [[layers]]\ninterface = { kind = \"diffuse\", albedo = [0.7, 0.4, 0.2] }\n",
    ),
];

/// The passes of per-query columns that answer four wavelengths a query:
/// each pass's three wavelengths per query.
fn passes(bsdf: &LayeredBsdf, nm4: &[[f32; 4]]) -> Vec<Vec<f32>> {
    let groups: Vec<Vec<usize>> = match bsdf.wavelengths_per_walk() {
        3 => vec![vec![0, 1, 2], vec![3, 3, 3]],
        _ => (0..4).map(|w| vec![w; 3]).collect(),
    };
    (groups.iter())
        .map(|g| nm4.iter().flat_map(|w| g.iter().map(|&i| w[i])).collect())
        .collect()
}

fn main() -> Result<(), String> {
    let wi: Vec<[f32; 3]> = (0..N)
        .map(|k| [0.3 * (k % 7) as f32 / 7.0, 0.1, 1.0])
        .collect();
    let wo: Vec<[f32; 3]> = (0..N)
        .map(|k| [-0.2, 0.4 * (k % 5) as f32 / 5.0, 1.0])
        .collect();
    let keys: Vec<u64> = (0..N as u64).collect();
    let q = Queries::pairs(&wi[..], &wo[..]).keys(&keys);
    let mut state = 1u64;
    let mut nm = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        380.0 + 450.0 * ((state >> 40) as f32 / (1u64 << 24) as f32)
    };
    println!("| stack | RGB | 3 wavelengths | 4 wavelengths |\n|---|---:|---:|---:|");
    for (name, toml) in STACKS {
        let stack = LayerStack::from_toml_str(toml).map_err(|e| e.to_string())?;
        let bsdf = (LayeredBsdf::new(stack).samples(1).threads(1)).map_err(|e| e.to_string())?;
        let mut out = vec![Estimate::default(); N];
        // Best of 15: RGB, the first pass (three wavelengths), all passes.
        let mut best = [f64::MAX; 3];
        for _ in 0..15 {
            let t0 = thread_cpu_ns();
            (bsdf.eval_into(&q, &mut |k, e| out[k] = *e)).map_err(|e| e.to_string())?;
            best[0] = best[0].min(thread_cpu_ns() - t0);
            let nm4: Vec<[f32; 4]> = (0..N).map(|_| [nm(), nm(), nm(), nm()]).collect();
            let t0 = thread_cpu_ns();
            for (p, pass) in passes(&bsdf, &nm4).iter().enumerate() {
                let s = SpectralColumns::new(&bsdf, pass, &[]).map_err(|e| e.to_string())?;
                let rows = PerQuery::new(&bsdf, N, &s.columns()).map_err(|e| e.to_string())?;
                (rows.eval_into(&q, &mut |k, e| out[k] = *e)).map_err(|e| e.to_string())?;
                if p == 0 {
                    best[1] = best[1].min(thread_cpu_ns() - t0);
                }
            }
            best[2] = best[2].min(thread_cpu_ns() - t0);
        }
        let ns = best.map(|t| t / N as f64);
        println!(
            "| {name} | {:.0} ns | {:.0} ns ({:.2}×) | {:.0} ns ({:.2}×) |",
            ns[0],
            ns[1],
            ns[1] / ns[0],
            ns[2],
            ns[2] / ns[0]
        );
    }
    Ok(())
}
