//! `strata albedo`: reflected and transmitted fractions for one incident direction.
//!
//! Output: one JSON line `{"R":[r,g,b],"T":[r,g,b],"stderr_R":[..],"stderr_T":[..]}`,
//! with `"truncated":n` when the limit of events (`--max-events`) ended `n` walks;
//! with `--wavelengths`, one value per wavelength in each array.

use crate::common::EngineArgs;
use crate::common::{load_material, spectral_passes, stdout_failure};
use std::io::Write;
use std::path::PathBuf;
use strata_bsdf::LayeredBsdf;

/// Arguments of `strata albedo`.
#[derive(clap::Args)]
pub struct Args {
    /// Material file (TOML, or JSON by extension).
    #[arg(long)]
    material: PathBuf,
    /// Polar angle of incidence in degrees (0 = normal; above 90 = from below).
    #[arg(long, allow_hyphen_values = true)]
    theta: f64,
    /// Azimuth of incidence in degrees.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    phi: f64,
    /// Walks.
    #[arg(long, default_value_t = 100_000, value_parser = crate::common::walks)]
    samples: u64,
    /// Seed of every random stream.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Wavelengths in nm, e.g. `450,550,650,700`: the material's spectra
    /// are read at each (docs/materials.md, *Spectra*), and every array has
    /// one value per wavelength.
    #[arg(long)]
    wavelengths: Option<crate::common::Wavelengths>,
    #[command(flatten)]
    engine: EngineArgs,
}

/// The unit direction at polar angle `theta_deg` and azimuth `phi_deg`.
pub fn direction(theta_deg: f64, phi_deg: f64) -> glam::Vec3 {
    let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
    glam::Vec3::new(
        (t.sin() * p.cos()) as f32,
        (t.sin() * p.sin()) as f32,
        t.cos() as f32,
    )
}

/// Runs `strata albedo`.
pub fn run(args: Args) -> Result<(), String> {
    if !args.theta.is_finite() || !(0.0..=180.0).contains(&args.theta) {
        return Err(format!(
            "--theta {}: must be in [0, 180] degrees",
            args.theta
        ));
    }
    if !args.phi.is_finite() {
        return Err(format!("--phi {}: must be finite", args.phi));
    }
    let stack = load_material(&args.material)?;
    let bsdf = args.engine.apply(LayeredBsdf::new(stack).seed(args.seed))?;
    let wi = direction(args.theta, args.phi);
    let [mut r, mut t, mut se_r, mut se_t]: [Vec<f64>; 4] = Default::default();
    let mut truncated = 0;
    for pass in spectral_passes(&bsdf, args.wavelengths.as_ref())? {
        let a = (pass.bsdf)
            .albedo(wi, args.samples)
            .map_err(|e| format!("--theta {} --phi {}: {e}", args.theta, args.phi))?;
        let c = pass.channels();
        r.extend(&a.reflected.value[..c]);
        t.extend(&a.transmitted.value[..c]);
        se_r.extend(&a.reflected.stderr[..c]);
        se_t.extend(&a.transmitted.stderr[..c]);
        truncated += a.reflected.truncated;
    }
    let mut line = serde_json::json!({ "R": r, "T": t, "stderr_R": se_r, "stderr_T": se_t });
    // Walks the limit of events ended, when some were.
    if truncated > 0 {
        line["truncated"] = truncated.into();
    }
    writeln!(std::io::stdout(), "{line}").or_else(stdout_failure)
}
