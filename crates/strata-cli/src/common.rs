//! Helpers shared by the subcommands: loading materials and parsing vectors,
//! with errors that name the flag and the value.

use std::path::Path;
use strata_bsdf::{LayerStack, LayeredBsdf};

/// Loads and validates the material file given by `--material`.
pub fn load_material(path: &Path) -> Result<LayerStack, String> {
    LayerStack::from_path(path).map_err(|e| format!("--material {}: {e}", path.display()))
}

/// Parses `x,y,z` (three finite numbers) given for `flag`.
pub fn parse_vec3(flag: &str, text: &str) -> Result<glam::Vec3, String> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    if parts.len() != 3 {
        return Err(format!(
            "{flag} {text}: expected three numbers x,y,z separated by commas, got {}",
            parts.len()
        ));
    }
    let mut v = [0.0f32; 3];
    for (slot, p) in v.iter_mut().zip(&parts) {
        let x: f32 = p
            .parse()
            .map_err(|_| format!("{flag} {text}: {p:?} is not a number"))?;
        if !x.is_finite() {
            return Err(format!("{flag} {text}: {p} is not a finite number"));
        }
        *slot = x;
    }
    Ok(glam::Vec3::from(v))
}

/// `--wavelengths`: wavelengths in nm, comma-separated, each positive and
/// finite, at least one.
#[derive(Clone, Debug)]
pub struct Wavelengths(pub Vec<f32>);

impl std::str::FromStr for Wavelengths {
    type Err = String;
    fn from_str(text: &str) -> Result<Self, String> {
        let nm = (text.split(',').map(str::trim))
            .map(|p| match p.parse::<f32>() {
                Ok(x) if x.is_finite() && x > 0.0 => Ok(x),
                _ => Err(format!("{p:?} is not a positive number of nm")),
            })
            .collect::<Result<Vec<f32>, String>>()?;
        Ok(Wavelengths(nm))
    }
}

/// The walks that answer `--wavelengths` (`bsdf` itself without it): per
/// pass, its wavelengths (three, or one where the material's IOR varies
/// with wavelength: `LayeredBsdf::wavelength_groups`) and `bsdf` at them.
pub fn spectral_passes<'b>(
    bsdf: &'b LayeredBsdf,
    nm: Option<&'b Wavelengths>,
) -> Result<Vec<SpectralPass<'b>>, String> {
    let Some(nm) = nm else {
        return Ok(vec![SpectralPass {
            nm: None,
            bsdf: std::borrow::Cow::Borrowed(bsdf),
        }]);
    };
    (bsdf.wavelength_groups(&nm.0).into_iter())
        .map(|g| {
            Ok(SpectralPass {
                nm: Some(g),
                bsdf: std::borrow::Cow::Owned(at_wavelengths(bsdf, g)?),
            })
        })
        .collect()
}

/// One pass of [`spectral_passes`].
pub struct SpectralPass<'b> {
    /// Its wavelengths (none: RGB).
    pub nm: Option<&'b [f32]>,
    /// The BSDF at them.
    pub bsdf: std::borrow::Cow<'b, LayeredBsdf>,
}

impl SpectralPass<'_> {
    /// The channels of its answers that are wanted.
    pub fn channels(&self) -> usize {
        self.nm.map_or(3, <[f32]>::len)
    }
}

/// `bsdf` at the wavelengths `nm`, an error naming the flag.
pub fn at_wavelengths(bsdf: &LayeredBsdf, nm: &[f32]) -> Result<LayeredBsdf, String> {
    bsdf.at_wavelengths(nm)
        .map_err(|e| format!("--wavelengths: {e}"))
}

/// Parses a count that must be at least 1 (clap names the flag and value).
pub fn positive(text: &str) -> Result<u64, String> {
    match text.parse::<u64>() {
        Ok(0) => Err("must be at least 1".into()),
        Ok(n) => Ok(n),
        Err(_) if text.trim_start().starts_with('-') => Err("must be at least 1".into()),
        Err(e) => Err(format!("not a whole number: {e}")),
    }
}

/// Parses `--samples`: a walk count per query, from 1 to the library's
/// `MAX_WALKS` (2^40), checked before any work is done.
pub fn walks(text: &str) -> Result<u64, String> {
    walks_at_most(text, strata_bsdf::MAX_WALKS)
}

/// A whole number from 1 to `max` walks.
pub fn walks_at_most(text: &str, max: u64) -> Result<u64, String> {
    at_most(text, max, " walks per query")
}

/// A whole number from 1 to `max` (`unit` follows `max` in the message).
fn at_most(text: &str, max: u64, unit: &str) -> Result<u64, String> {
    match positive(text)? {
        n if n <= max => Ok(n),
        _ => Err(format!("must be at most {max}{unit}")),
    }
}

/// The most threads any `--threads` may ask for: the library's bound (a
/// thread pool of more is a typo, and starting it would take the machine
/// down first).
pub const MAX_THREADS: u64 = strata_bsdf::MAX_THREADS as u64;

/// Parses `--max-events`: a whole number in 1..=2^24, the library's
/// largest limit of events per walk.
pub fn max_events(text: &str) -> Result<u64, String> {
    at_most(text, MAX_EVENTS_LIMIT, " events per walk")
}

/// The largest `--max-events`.
const MAX_EVENTS_LIMIT: u64 = strata_bsdf::estimator::events::MAX_CAP as u64;

/// Parses `--threads`: a whole number in 1..=MAX_THREADS.
pub fn threads(text: &str) -> Result<u64, String> {
    at_most(text, MAX_THREADS, " threads")
}

/// The longest time any `--...-seconds` option may ask for: a day.
pub const MAX_SECONDS: f64 = 86_400.0;

/// Checks a time in seconds given for `flag`: finite, at most
/// `MAX_SECONDS`, and positive (or, if `zero_ok`, non-negative).
pub fn check_seconds(flag: &str, s: f64, zero_ok: bool) -> Result<(), String> {
    let low_ok = if zero_ok { s >= 0.0 } else { s > 0.0 };
    if !(low_ok && s <= MAX_SECONDS) {
        let low = if zero_ok { ">= 0" } else { "> 0" };
        return Err(format!(
            "{flag} {s}: must be a number of seconds {low} and at most {MAX_SECONDS} (a day)"
        ));
    }
    Ok(())
}

/// Prints `text` to stdout and flushes it; a closed pipe is not an error
/// (see `stdout_failure`).
pub fn print_out(text: &str) -> Result<(), String> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    out.write_all(text.as_bytes())
        .and_then(|()| out.flush())
        .or_else(stdout_failure)
}

/// Prints a progress note to stderr (never fails: a closed stderr only
/// silences it).
pub fn note(text: &str) {
    use std::io::Write;
    let _ = writeln!(std::io::stderr(), "{text}");
}

/// What a failed write to stdout means: a closed pipe (`strata ... | head`)
/// means the reader has what it wants, so the command stops quietly
/// (`Ok(())`); any other failure is an error.
pub fn stdout_failure(e: std::io::Error) -> Result<(), String> {
    if e.kind() == std::io::ErrorKind::BrokenPipe {
        Ok(())
    } else {
        Err(format!("cannot write to stdout: {e}"))
    }
}

/// The engine flags shared by `eval`, `albedo` and `sample`.
#[derive(clap::Args, Clone, Debug)]
pub struct EngineArgs {
    /// Engine: the SIMD wavefront (default), the scalar reference, or auto
    /// (the scalar engine for calls of fewer walks than the wavefront has
    /// lanes). All give the same results for the same seed.
    #[arg(long, default_value = "wavefront")]
    pub engine: strata_bsdf::Engine,
    /// Threads for the wavefront engine (default: every core). Results do not
    /// depend on it. At most 1024.
    #[arg(long, value_parser = threads)]
    pub threads: Option<u64>,
    /// What flows from wi to wo: radiance (wi points to the light; the
    /// default) or importance (wi points to the viewer: the adjoint BSDF).
    /// They differ only for transmission between exteriors of different IOR.
    #[arg(long, default_value = "radiance")]
    pub transport: strata_bsdf::Transport,
    /// The limit of events (interface events and collisions) per walk, at
    /// most 2^24: a walk that reaches it ends there (default 2^20, more than
    /// five times the longest walk of `strata stress`; a bidirectional
    /// walk's subpaths end at its square root).
    #[arg(long, value_parser = max_events)]
    pub max_events: Option<u64>,
    /// Any of the BSDF's settings as `key=value` pairs separated by spaces,
    /// the library's configuration text, as C's `strata_bsdf_configure` and
    /// Python's `Bsdf.configure` read it: samples, pdf_walks, seed,
    /// transport, eval_start, estimator, engine, threads, max_events,
    /// rr_start, rr_threshold, max_scatter_order, mis (e.g. `--config
    /// "transport=importance rr_threshold=0.1"`). Applied after the other
    /// flags, so it overrides them.
    #[arg(long, value_name = "SETTINGS")]
    pub config: Option<String>,
}

impl EngineArgs {
    /// Applies the flags to a BSDF, `--config` last.
    pub fn apply(
        &self,
        bsdf: strata_bsdf::LayeredBsdf,
    ) -> Result<strata_bsdf::LayeredBsdf, String> {
        let mut bsdf = bsdf.engine(self.engine).transport(self.transport);
        if let Some(n) = self.max_events {
            bsdf = bsdf.max_events(n as u32);
        }
        if let Some(n) = self.threads {
            bsdf = bsdf
                .threads(n as usize)
                .map_err(|e| format!("--threads {n}: {e}"))?;
        }
        let Some(text) = &self.config else {
            return Ok(bsdf);
        };
        let mut config = bsdf.config();
        config.apply(text).map_err(|e| format!("--config: {e}"))?;
        bsdf.with_config(&config).map_err(|e| {
            let threads = config.get("threads").unwrap_or_default();
            format!("--config: threads={threads}: {e}")
        })
    }
}
