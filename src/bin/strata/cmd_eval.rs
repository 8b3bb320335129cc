//! `strata eval`: f(wi, wo) for queries read as JSON lines on stdin.

use serde::Deserialize;
use std::io::{BufRead, Write};
use std::path::PathBuf;
use strata::{LayerStack, LayeredBsdf};

/// Arguments of `strata eval`.
#[derive(clap::Args)]
pub struct Args {
    /// Material file (TOML, or JSON by extension).
    #[arg(long)]
    material: PathBuf,
    /// Walks per query.
    #[arg(long, default_value_t = 4096)]
    samples: u64,
    /// Seed of every random stream.
    #[arg(long, default_value_t = 0)]
    seed: u64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Query {
    wi: [f32; 3],
    wo: [f32; 3],
}

pub fn run(args: Args) -> Result<(), String> {
    let stack = LayerStack::from_path(&args.material).map_err(|e| e.to_string())?;
    let bsdf = LayeredBsdf::new(stack).seed(args.seed);
    let stdin = std::io::stdin();
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    for (i, line) in stdin.lock().lines().enumerate() {
        let line_no = i + 1;
        let line = line.map_err(|e| format!("stdin line {line_no}: {e}"))?;
        if line.trim().is_empty() {
            continue;
        }
        let q: Query = serde_json::from_str(&line)
            .map_err(|e| format!("stdin line {line_no}: invalid query: {e}"))?;
        let (wi, wo) = (glam::Vec3::from(q.wi), glam::Vec3::from(q.wo));
        let e = bsdf
            .eval_with(wi, wo, args.samples, i as u64)
            .map_err(|e| format!("stdin line {line_no}: {e}"))?;
        let p = bsdf
            .pdf(wi, wo)
            .map_err(|e| format!("stdin line {line_no}: {e}"))?;
        writeln!(
            out,
            "{}",
            serde_json::json!({"f": e.value, "stderr": e.stderr, "pdf": p})
        )
        .map_err(|e| format!("stdout: {e}"))?;
    }
    Ok(())
}
