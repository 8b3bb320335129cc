//! `strata eval`: f(wi, wo) for queries read as JSON lines on stdin.
//!
//! Input: one query per line, `{"wi":[x,y,z],"wo":[x,y,z]}` (local frame, z =
//! normal, both directions pointing away from the surface; normalized on input;
//! blank lines are skipped). Output: one line per query,
//! `{"f":[r,g,b],"stderr":[r,g,b],"pdf":p}`, `f` without the cosine. The first
//! bad line (malformed JSON, a missing or extra field, not three numbers, a zero
//! or non-finite direction) stops the run with an error naming its line number;
//! the answers to the lines before it have already been printed.

use crate::common::{load_material, stdout_failure};
use serde::Serialize;
use std::io::{BufRead, Write};
use std::path::PathBuf;
use strata::query::parse_query_line;
use strata::LayeredBsdf;

/// Arguments of `strata eval`.
#[derive(clap::Args)]
pub struct Args {
    /// Material file (TOML, or JSON by extension).
    #[arg(long)]
    material: PathBuf,
    /// Walks per query.
    #[arg(long, default_value_t = 4096, value_parser = crate::common::positive)]
    samples: u64,
    /// Seed of every random stream.
    #[arg(long, default_value_t = 0)]
    seed: u64,
}

/// One output line (fields in this order).
#[derive(Serialize)]
struct Answer {
    f: [f64; 3],
    stderr: [f64; 3],
    pdf: f32,
}

/// Runs `strata eval`.
pub fn run(args: Args) -> Result<(), String> {
    let stack = load_material(&args.material)?;
    let bsdf = LayeredBsdf::new(stack).seed(args.seed);
    let stdin = std::io::stdin();
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    for (i, line) in stdin.lock().lines().enumerate() {
        let line_no = i + 1;
        let line = line.map_err(|e| format!("stdin line {line_no}: cannot read: {e}"))?;
        if line.trim().is_empty() {
            continue;
        }
        let (wi, wo) = parse_query_line(&line).map_err(|e| format!("stdin line {line_no}: {e}"))?;
        let (wi, wo) = (wi.to_vec3(), wo.to_vec3());
        // The query key is the line index, so a query's answer depends only on
        // the seed and where it stands in the input.
        let e = bsdf
            .eval_with(wi, wo, args.samples, i as u64)
            .map_err(|e| format!("stdin line {line_no}: {e}"))?;
        let p = bsdf
            .pdf(wi, wo)
            .map_err(|e| format!("stdin line {line_no}: {e}"))?;
        let answer = Answer {
            f: e.value,
            stderr: e.stderr,
            pdf: p,
        };
        let answer = serde_json::to_string(&answer).map_err(|e| format!("cannot format: {e}"))?;
        if let Err(e) = writeln!(out, "{answer}") {
            return stdout_failure(e);
        }
    }
    Ok(())
}
