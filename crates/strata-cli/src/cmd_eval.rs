//! `strata eval`: f(wi, wo) for queries read as JSON lines on stdin.
//!
//! Input: one query per line, `{"wi":[x,y,z],"wo":[x,y,z]}` (local frame, z =
//! normal, both directions pointing away from the surface; normalized on input;
//! blank lines are skipped). Output: one line per query,
//! `{"f":[r,g,b],"stderr":[r,g,b],"pdf":p}`, `f` without the cosine; with
//! `--pdf unbiased` the line ends with `"pdf_stderr":s`, and `"truncated":n`
//! when the limit of events (`--max-events`) ended `n` of the line's walks. The first
//! bad line (malformed JSON, a missing or extra field, not three numbers, a zero
//! or non-finite direction) stops the run with an error naming its line number;
//! the answers to the lines before it have already been printed. Lines are
//! answered as they arrive: from a pipe or a terminal, the lines read so far
//! are answered (and the answers flushed) before the next is waited for;
//! from a file, in chunks. The answers are the same either way.
//!
//! Each query is keyed by its directions' bits, as the library's unkeyed
//! calls key it (and the C and Python bindings'): a line's answer depends on
//! the seed and its directions only, the same number every binding gives.
//!
//! A line may carry `"set"`, a map from a path in the material tree to a
//! value, applied to that query alone (docs/materials.md, *Per-query
//! overrides*): `{"wi":[..],"wo":[..],"set":{"layers[0].medium.thickness":0.5}}`.
//! Its answer is the one a material file with those values gives, bit for
//! bit. A set that names no field of the material, or makes a value
//! invalid, stops the run like any bad line, naming the line, the path and
//! the value.

use crate::common::{
    at_wavelengths, load_material, spectral_passes, stdout_failure, EngineArgs, SpectralPass,
};
use serde::Serialize;
use std::collections::HashMap;
use std::io::{BufRead, Write};
use std::path::PathBuf;
use strata_bsdf::query::parse_query_line_set;
use strata_bsdf::{Bsdf, Estimate, LayerStack, LayeredBsdf, Materials, PdfKind, Queries};

/// Arguments of `strata eval`.
#[derive(clap::Args)]
pub struct Args {
    /// Material file (TOML, or JSON by extension).
    #[arg(long)]
    material: PathBuf,
    /// Walks per query.
    #[arg(long, default_value_t = 4096, value_parser = crate::common::walks)]
    samples: u64,
    /// Seed of every random stream.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Estimator: auto (a closed form where the stack has one, the
    /// bidirectional walks on stacks of three interfaces or more and rough coats over smooth or near-specular conductors (without optically thick scattering layers), the
    /// unidirectional walks elsewhere), uni (always the unidirectional
    /// walks) or bidir (always the bidirectional walks).
    #[arg(long, default_value = "auto")]
    estimator: strata_bsdf::Estimator,
    /// Where the walks start: from whichever of wi and wo is nearer the
    /// normal, or farther from it for a reflected pair under a rough coat
    /// (normal, the default), or always from wi.
    #[arg(long, default_value = "normal")]
    eval_start: strata_bsdf::EvalStart,
    /// Which pdf of sample(): approx (what `strata sample` reports, the
    /// default) or unbiased (the density of sample()'s directions, with its
    /// standard error; slow).
    #[arg(long, default_value = "approx")]
    pdf: strata_bsdf::PdfKind,
    /// Density walks per pdf. For approx: the library's rule by name,
    /// `default` (a pilot of 8 walks, then 8 to 64 fresh ones for a relative
    /// standard error of 0.15, as `strata sample` runs them unless told
    /// otherwise) or `tight` (8, then 8 to 128 for 0.1: within 0.7–1.3× of
    /// the density nearly everywhere), a fixed number of walks, or an
    /// adaptive rule `PILOT,MAX,REL_STDERR`. For unbiased: a number of
    /// walks, default 4096.
    #[arg(long)]
    pdf_samples: Option<strata_bsdf::PdfWalks>,
    /// Wavelengths in nm, e.g. `450,550,650,700`: the material's spectra
    /// are read at each (docs/materials.md, *Spectra*), `f` and `stderr`
    /// have one value per wavelength, and `pdf` is the density of the first
    /// wavelength's walks. A set's RGB values are read through the uplift.
    #[arg(long)]
    wavelengths: Option<crate::common::Wavelengths>,
    #[command(flatten)]
    engine: EngineArgs,
    /// The density walks of an unbiased pdf, from `--pdf-samples` (set by
    /// `run`).
    #[arg(skip)]
    unbiased_pdf_walks: u64,
}

/// Density walks per unbiased pdf unless `--pdf-samples` says otherwise.
const UNBIASED_PDF_SAMPLES: u64 = 4096;

impl Args {
    /// The density walks of an unbiased pdf: `--pdf-samples` must be a
    /// number of them.
    fn unbiased_walks(&self) -> Result<u64, String> {
        match (self.pdf, self.pdf_samples) {
            (PdfKind::Unbiased, Some(walks)) if walks.pilot() > 0 => Err(format!(
                "--pdf-samples {walks}: --pdf unbiased takes a number of walks"
            )),
            (_, Some(walks)) => Ok(walks.max()),
            (_, None) => Ok(UNBIASED_PDF_SAMPLES),
        }
    }
}

/// The most queries evaluated together (the wavefront engine batches them).
const CHUNK: usize = 1024;

/// One output line (fields in this order).
#[derive(Serialize)]
struct Answer {
    f: Vec<f64>,
    stderr: Vec<f64>,
    pdf: f32,
    #[serde(skip_serializing_if = "Option::is_none")]
    pdf_stderr: Option<f32>,
    /// Walks of `f` (and of an unbiased pdf) that the limit of events
    /// ended; present only when some were.
    #[serde(skip_serializing_if = "is_zero")]
    truncated: u64,
}

fn is_zero(n: &u64) -> bool {
    *n == 0
}

/// Runs `strata eval`.
pub fn run(mut args: Args) -> Result<(), String> {
    let stack = load_material(&args.material)?;
    let mut bsdf = LayeredBsdf::new(stack.clone());
    if let (PdfKind::Approximate, Some(walks)) = (args.pdf, args.pdf_samples) {
        bsdf = bsdf.pdf_walks(walks);
    }
    // A rule where a number is needed is an error before any output.
    args.unbiased_pdf_walks = args.unbiased_walks()?;
    let bsdf = bsdf
        .samples(args.samples)
        .seed(args.seed)
        .estimator(args.estimator)
        .eval_start(args.eval_start);
    let bsdf = args.engine.apply(bsdf)?;
    // `--config` may have set the walks per query.
    args.samples = bsdf.samples_per_eval();
    // The material at each pass of `--wavelengths`, made once.
    let passes = spectral_passes(&bsdf, args.wavelengths.as_ref())?;
    let stdin = std::io::stdin();
    // From a file, lines are read in chunks of CHUNK. From anything else (a
    // pipe, a terminal) the lines that have arrived are answered, and the
    // answers flushed, before waiting for more: a program that writes one
    // query and waits for its answer gets it.
    let from_file = is_regular_file(&stdin);
    let mut input = std::io::BufReader::with_capacity(1 << 16, stdin.lock());
    let stdout = std::io::stdout();
    let mut out = std::io::BufWriter::new(stdout.lock());
    // Each query is keyed by its directions, so its answer depends only on
    // the seed and the directions (not on the engine, the chunking or its
    // line).
    let mut pairs = Vec::with_capacity(CHUNK);
    let mut lines_of = Vec::with_capacity(CHUNK);
    let mut chunk_sets = Variants::new(stack);
    let mut line = String::new();
    let mut line_no = 0;
    loop {
        let mut failure = None;
        let mut end = false;
        loop {
            line.clear();
            match input.read_line(&mut line) {
                Ok(0) => {
                    end = true;
                    break;
                }
                Ok(_) => line_no += 1,
                Err(e) => {
                    let e = format!("stdin line {}: cannot read: {e}", line_no + 1);
                    failure = Some(e);
                    break;
                }
            }
            let l = line.trim_end_matches('\n').trim_end_matches('\r');
            if !l.trim().is_empty() {
                let parsed = parse_query_line_set(l)
                    .map_err(|e| e.to_string())
                    .and_then(|(wi, wo, set)| Ok((wi, wo, chunk_sets.add(&set)?)));
                match parsed {
                    Ok((wi, wo, m)) => {
                        pairs.push((wi, wo));
                        lines_of.push(line_no);
                        chunk_sets.material.push(m);
                    }
                    Err(e) => {
                        failure = Some(format!("stdin line {line_no}: {e}"));
                        break;
                    }
                }
            }
            if pairs.len() == CHUNK || (!from_file && input.buffer().is_empty()) {
                break;
            }
        }
        let chunk = (&pairs[..], &chunk_sets, &lines_of[..]);
        if let Err(e) = answer(&bsdf, &passes, &args, chunk, &mut out) {
            return e;
        }
        pairs.clear();
        lines_of.clear();
        chunk_sets.clear();
        if let Some(e) = failure {
            // The answers before the bad line are out; then the error.
            out.flush().or_else(stdout_failure)?;
            return Err(e);
        }
        if end || !from_file {
            out.flush().or_else(stdout_failure)?;
        }
        if end {
            return Ok(());
        }
    }
}

/// Whether standard input is a regular file (which never makes a reader
/// wait for lines that have not been written yet).
fn is_regular_file(stdin: &std::io::Stdin) -> bool {
    #[cfg(unix)]
    let handle = std::os::fd::AsFd::as_fd(stdin).try_clone_to_owned();
    #[cfg(windows)]
    let handle = std::os::windows::io::AsHandle::as_handle(stdin).try_clone_to_owned();
    #[cfg(any(unix, windows))]
    return handle
        .map(std::fs::File::from)
        .and_then(|f| f.metadata())
        .is_ok_and(|m| m.is_file());
    #[cfg(not(any(unix, windows)))]
    {
        let _ = stdin;
        false
    }
}

/// Evaluates a chunk (its pairs, sets and line numbers) in each pass of
/// wavelengths and prints one line per query. `Err(result)` ends the run
/// with `result` (a failure, or a quiet stop on a closed pipe).
fn answer(
    bsdf: &LayeredBsdf,
    passes: &[SpectralPass],
    args: &Args,
    (pairs, sets, lines_of): (&[(glam::Vec3, glam::Vec3)], &Variants, &[usize]),
    out: &mut impl Write,
) -> Result<(), Result<(), String>> {
    if pairs.is_empty() {
        return Ok(());
    }
    let mut lines: Vec<Answer> = Vec::new();
    for (p, pass) in passes.iter().enumerate() {
        let got = if sets.stacks.len() > 1 {
            // Some lines set values of their own: one batch over the
            // materials, each at the pass's wavelengths.
            let at = |st: &LayerStack| match pass.nm {
                None => Ok(st.clone()),
                Some(nm) => {
                    at_wavelengths(&bsdf.with_stack(st.clone()), nm).map(|b| b.stack().clone())
                }
            };
            let stacks = sets.stacks.iter().map(at).collect::<Result<Vec<_>, _>>();
            let mats = Materials::new(&pass.bsdf, stacks.map_err(Err)?);
            answer_with(
                &mats,
                Some(&sets.material[..]),
                args,
                pairs,
                lines_of,
                p == 0,
            )?
        } else {
            answer_with(pass.bsdf.as_ref(), None, args, pairs, lines_of, p == 0)?
        };
        let channels = pass.channels();
        if p == 0 {
            lines = got;
            for l in &mut lines {
                l.f.truncate(channels);
                l.stderr.truncate(channels);
            }
        } else {
            for (l, g) in lines.iter_mut().zip(got) {
                l.f.extend(&g.f[..channels]);
                l.stderr.extend(&g.stderr[..channels]);
                l.truncated += g.truncated;
            }
        }
    }
    for line in &lines {
        let line = serde_json::to_string(line).map_err(|e| Err(format!("cannot format: {e}")))?;
        writeln!(out, "{line}").map_err(stdout_failure)?;
    }
    Ok(())
}

/// The materials of a chunk: the file's (0) and each distinct set's.
struct Variants {
    stacks: Vec<LayerStack>,
    /// Each distinct set (its entries, in words) and its material.
    seen: HashMap<String, u32>,
    /// Each query's material.
    material: Vec<u32>,
}

impl Variants {
    fn new(base: LayerStack) -> Self {
        Variants {
            stacks: vec![base],
            seen: HashMap::new(),
            material: Vec::new(),
        }
    }

    /// The material of a line with `set` (0: none), added if new.
    fn add(&mut self, set: &strata_bsdf::query::QuerySet) -> Result<u32, String> {
        if set.is_empty() {
            return Ok(0);
        }
        let key: Vec<String> = (set.entries().iter())
            .map(|(p, v)| format!("{p}={v}"))
            .collect();
        let key = key.join(";");
        if let Some(&m) = self.seen.get(&key) {
            return Ok(m);
        }
        let st = set.apply(&self.stacks[0]).map_err(|e| e.to_string())?;
        let m = self.stacks.len() as u32;
        self.stacks.push(st);
        self.seen.insert(key, m);
        Ok(m)
    }

    fn clear(&mut self) {
        self.stacks.truncate(1);
        self.seen.clear();
        self.material.clear();
    }
}

/// The answers of [`answer`] on the file's material alone, or on materials
/// with each line's row; their pdfs only `with_pdf` (a later pass of
/// wavelengths takes the first's).
fn answer_with(
    answers: &dyn Bsdf,
    rows: Option<&[u32]>,
    args: &Args,
    pairs: &[(glam::Vec3, glam::Vec3)],
    lines_of: &[usize],
    with_pdf: bool,
) -> Result<Vec<Answer>, Result<(), String>> {
    // Directions were validated when parsed, so the batch cannot fail on them.
    let fail = |e: strata_bsdf::BatchError| {
        Err(match e.index {
            Some(i) => format!("stdin line {}: {}", lines_of[i], e.error),
            None => format!("--{}", e.error),
        })
    };
    let (wi, wo): (Vec<glam::Vec3>, Vec<glam::Vec3>) = pairs.iter().copied().unzip();
    let q = Queries {
        rows,
        ..Queries::pairs(&wi, &wo).walks(args.samples)
    };
    let mut f = vec![Estimate::default(); pairs.len()];
    answers.eval_into(&q, &mut |k, e| f[k] = *e).map_err(fail)?;
    let mut p = vec![(0.0, None, 0); pairs.len()];
    match args.pdf {
        _ if !with_pdf => Ok(()),
        PdfKind::Approximate => answers.pdf_into(&q, &mut |k, x| p[k] = (x, None, 0)),
        PdfKind::Unbiased => {
            let q = q.walks(args.unbiased_pdf_walks);
            answers
                .pdf_unbiased_into(&q, &mut |k, e| {
                    p[k] = (e.value as f32, Some(e.stderr as f32), e.truncated)
                })
                .map(|_| ())
        }
    }
    .map_err(fail)?;
    Ok((f.iter().zip(p))
        .map(|(e, (pdf, pdf_stderr, pdf_cut))| Answer {
            f: e.value.to_vec(),
            stderr: e.stderr.to_vec(),
            pdf,
            pdf_stderr,
            truncated: e.truncated + pdf_cut,
        })
        .collect())
}
