//! `strata`: the command-line tool. One file per subcommand.

mod cmd_albedo;
mod cmd_eval;
mod cmd_stress;
mod output;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

/// Layered BSDFs by position-free Monte Carlo.
#[derive(Parser)]
#[command(name = "strata", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Evaluate f(wi, wo): JSON lines {"wi":[..],"wo":[..]} on stdin, one JSON line per query on stdout.
    Eval(cmd_eval::Args),
    /// Directional albedo: reflected and transmitted fractions.
    Albedo(cmd_albedo::Args),
    /// The stiff and extreme suite: every engine against the f64 oracle, one table row per case.
    Stress(cmd_stress::Args),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Eval(a) => cmd_eval::run(a),
        Command::Albedo(a) => cmd_albedo::run(a),
        Command::Stress(a) => cmd_stress::run(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("strata: {e}");
            ExitCode::FAILURE
        }
    }
}
