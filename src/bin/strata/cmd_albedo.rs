//! `strata albedo`: reflected and transmitted fractions for one incident direction.

use std::path::PathBuf;
use strata::{LayerStack, LayeredBsdf};

/// Arguments of `strata albedo`.
#[derive(clap::Args)]
pub struct Args {
    /// Material file (TOML, or JSON by extension).
    #[arg(long)]
    material: PathBuf,
    /// Polar angle of incidence in degrees (0 = normal; above 90 = from below).
    #[arg(long)]
    theta: f64,
    /// Azimuth of incidence in degrees.
    #[arg(long, default_value_t = 0.0)]
    phi: f64,
    /// Walks.
    #[arg(long, default_value_t = 100_000)]
    samples: u64,
    /// Seed of every random stream.
    #[arg(long, default_value_t = 0)]
    seed: u64,
}

pub fn run(args: Args) -> Result<(), String> {
    if !args.theta.is_finite() || !(0.0..=180.0).contains(&args.theta) {
        return Err(format!(
            "--theta {} must be in [0, 180] degrees",
            args.theta
        ));
    }
    if !args.phi.is_finite() {
        return Err(format!("--phi {} must be finite", args.phi));
    }
    let stack = LayerStack::from_path(&args.material).map_err(|e| e.to_string())?;
    let bsdf = LayeredBsdf::new(stack).seed(args.seed);
    let (t, p) = (args.theta.to_radians(), args.phi.to_radians());
    let wi = glam::Vec3::new(
        (t.sin() * p.cos()) as f32,
        (t.sin() * p.sin()) as f32,
        t.cos() as f32,
    );
    let a = bsdf.albedo(wi, args.samples).map_err(|e| e.to_string())?;
    println!(
        "{}",
        serde_json::json!({
            "R": a.reflected.value, "T": a.transmitted.value,
            "stderr_R": a.reflected.stderr, "stderr_T": a.transmitted.stderr
        })
    );
    Ok(())
}
