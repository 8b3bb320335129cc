//! `strata sample`: outgoing directions drawn by the analog random walk.
//!
//! One JSON line per walk: `{"wo":[x,y,z],"weight":[r,g,b],"reflection":b,"specular":b}`.
//! An absorbed walk (or light arriving where the stack sees nothing) prints
//! `{"wo":null,"weight":[0.0,0.0,0.0],"reflection":null,"specular":null}`, so the
//! mean of `weight` over all lines is an unbiased estimate of the albedo R + T.
//! If stdout is closed early (`| head`), the command stops quietly.

use crate::common::{at_wavelengths, load_material, parse_vec3, stdout_failure, EngineArgs};
use serde::Serialize;
use std::io::Write;
use std::path::PathBuf;
use strata_bsdf::{Bsdf, LayeredBsdf, Queries};

/// Arguments of `strata sample`.
#[derive(clap::Args)]
pub struct Args {
    /// Material file (TOML, or JSON by extension).
    #[arg(long)]
    material: PathBuf,
    /// Incident direction x,y,z (towards the light, local frame, z = normal;
    /// normalized on input). Write `--wi=-0.5,0,1` or `--wi -0.5,0,1`.
    #[arg(long, allow_hyphen_values = true)]
    wi: String,
    /// Number of walks (one output line each), at least 1.
    #[arg(long, value_parser = crate::common::positive)]
    count: u64,
    /// Seed of every random stream.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Values of the material to set for these walks: a JSON object from a
    /// path in the material tree to a value, as a line of `strata eval`
    /// carries (docs/materials.md), e.g. `{"layers[0].medium.thickness":0.5}`.
    #[arg(long)]
    set: Option<String>,
    /// Density walks of the pdf each line carries, as `strata eval
    /// --pdf-samples` takes them for approx: `default` (the library's rule),
    /// `tight`, a fixed number, or `PILOT,MAX,REL_STDERR`.
    #[arg(long)]
    pdf_samples: Option<strata_bsdf::PdfWalks>,
    /// Wavelengths in nm of every walk, one to three (one where the
    /// material's IOR varies with wavelength), e.g. `450,550,650`: the
    /// material's spectra are read at each (docs/materials.md, *Spectra*)
    /// and `weight` has one value per wavelength.
    #[arg(long)]
    wavelengths: Option<crate::common::Wavelengths>,
    #[command(flatten)]
    engine: EngineArgs,
}

/// Walks sampled together (the wavefront engine batches them).
const CHUNK: u64 = 1 << 16;

/// One output line (fields in this order).
#[derive(Serialize)]
struct Line {
    wo: Option<[f32; 3]>,
    weight: Vec<f32>,
    /// The pdf `strata eval` reports for `(wi, wo)`; null if absorbed.
    pdf: Option<f32>,
    reflection: Option<bool>,
    specular: Option<bool>,
}

/// Runs `strata sample`.
pub fn run(args: Args) -> Result<(), String> {
    let wi = parse_vec3("--wi", &args.wi)?;
    let mut stack = load_material(&args.material)?;
    if let Some(set) = &args.set {
        use strata_bsdf::query::{parse_set, QueryParseError};
        let q = parse_set(set).map_err(|e| match e {
            QueryParseError::Malformed(m) => format!("--set {set}: not JSON: {m}"),
            QueryParseError::Set(e) => format!("--set: {e}"),
            e => format!("--set: {e}"),
        })?;
        stack = q.apply(&stack).map_err(|e| format!("--set: {e}"))?;
    }
    let walks = args.pdf_samples.unwrap_or_default();
    let bsdf = LayeredBsdf::new(stack).seed(args.seed).pdf_walks(walks);
    let mut bsdf = args.engine.apply(bsdf)?;
    let channels = match &args.wavelengths {
        None => 3,
        Some(nm) => {
            // One walk draws one direction: one pass of wavelengths.
            let per_walk = bsdf.wavelengths_per_walk();
            if nm.0.len() > per_walk {
                return Err(format!(
                    "--wavelengths: {} wavelengths; a walk carries at most {per_walk} on this \
                     material (one where its IOR varies with wavelength)",
                    nm.0.len()
                ));
            }
            bsdf = at_wavelengths(&bsdf, &nm.0)?;
            nm.0.len()
        }
    };
    // Validate the direction once, naming the flag.
    strata_bsdf::Direction::new("wi", wi).map_err(|e| format!("--wi {}: {e}", args.wi))?;
    let stdout = std::io::stdout();
    let mut out = std::io::BufWriter::new(stdout.lock());
    let mut first = 0;
    while first < args.count {
        let n = CHUNK.min(args.count - first);
        let (index, wis): (Vec<u64>, Vec<_>) = (first..first + n).map(|k| (k, wi)).unzip();
        let mut samples = vec![None; n as usize];
        let q = Queries::directions(&wis).indices(&index);
        (bsdf.sample_into(&q, &mut |k, s| samples[k] = s.copied()))
            .map_err(|e| format!("--wi {}: {}", args.wi, e.error))?;
        first += n;
        for s in samples {
            let line = match s {
                Some(s) => Line {
                    wo: Some(s.wo.to_array()),
                    weight: s.weight[..channels].to_vec(),
                    pdf: Some(s.pdf),
                    reflection: Some(s.reflection),
                    specular: Some(s.specular),
                },
                None => Line {
                    wo: None,
                    weight: vec![0.0; channels],
                    pdf: None,
                    reflection: None,
                    specular: None,
                },
            };
            let line = serde_json::to_string(&line).map_err(|e| format!("cannot format: {e}"))?;
            if let Err(e) = writeln!(out, "{line}") {
                return stdout_failure(e);
            }
        }
    }
    out.flush().or_else(stdout_failure)
}
