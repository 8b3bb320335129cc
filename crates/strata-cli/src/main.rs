//! `strata`: the command-line tool. One file per subcommand.
//!
//! Each subcommand is a module `cmd_NAME` with `pub struct Args` (clap) and
//! `pub fn run(Args) -> Result<(), String>`. Adding one is a `mod` line and a
//! line in the `commands!` list below (with its help text as a doc comment). Every error
//! is printed to stderr as `strata: MESSAGE` with a non-zero exit status.
//! A failed or interrupted run removes its temporary files (see `output`).

mod bench_pbrt;
mod bench_vertex;
mod cmd_albedo;
mod cmd_bench;
mod cmd_converge;
mod cmd_demo;
mod cmd_eval;
mod cmd_sample;
mod cmd_stress;
mod common;
mod output;
mod plot;

use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};
use std::process::ExitCode;

/// Declares the `Command` enum and its dispatch from one list of
/// `Variant => module` entries. (The modules are declared above, outside the
/// macro, so that rustfmt reaches them.)
macro_rules! commands {
    ($($(#[$doc:meta])* $variant:ident => $module:ident,)*) => {
        /// The subcommands.
        #[derive(Subcommand)]
        enum Command {
            $($(#[$doc])* $variant($module::Args),)*
        }

        impl Command {
            fn run(self) -> Result<(), String> {
                match self {
                    $(Command::$variant(args) => $module::run(args),)*
                }
            }
        }
    };
}

commands! {
    /// Evaluate f(wi, wo): JSON lines {"wi":[..],"wo":[..]} on stdin, one JSON line per query on stdout.
    Eval => cmd_eval,
    /// Directional albedo: reflected and transmitted fractions.
    Albedo => cmd_albedo,
    /// Sample outgoing directions: one JSON line {"wo":[..],"weight":[..],..} per walk.
    Sample => cmd_sample,
    /// The main job on built-in materials: tables of albedos and BSDF values, PNG lobe plots.
    Demo => cmd_demo,
    /// Throughput of the scalar reference and the wavefront engine on the representative stacks.
    Bench => cmd_bench,
    /// Error against run time of every estimator, against a reference: CSV, markdown, PNG plot.
    Converge => cmd_converge,
    /// The stiff and extreme suite: every engine against the f64 oracle, one table row per case.
    Stress => cmd_stress,
}

/// Layered BSDFs by position-free Monte Carlo.
#[derive(Parser)]
#[command(name = "strata", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

fn main() -> ExitCode {
    // Negative numbers are values, not flags: `--count -1` reaches the
    // option's own check (and its message) instead of "unexpected argument".
    let matches = Cli::command()
        .mut_subcommands(|c| c.allow_negative_numbers(true))
        .get_matches();
    let cli = Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    let result = output::on_interrupt_clean_up().and_then(|()| cli.command.run());
    output::clean_up();
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            use std::io::Write as _;
            let _ = writeln!(std::io::stderr(), "strata: {e}");
            ExitCode::FAILURE
        }
    }
}
