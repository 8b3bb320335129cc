//! `strata`: the command-line tool. One file per subcommand.

mod cmd_albedo;
mod cmd_bench;
mod cmd_demo;
mod cmd_eval;
mod cmd_sample;
mod common;
mod output;
mod plot;

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
    /// Sample outgoing directions: one JSON line {"wo":[..],"weight":[..],..} per walk.
    Sample(cmd_sample::Args),
    /// The main job on built-in materials: tables of albedos and BSDF values, PNG lobe plots.
    Demo(cmd_demo::Args),
    /// Throughput of the scalar reference and the wavefront engine on the representative stacks.
    Bench(cmd_bench::Args),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Eval(a) => cmd_eval::run(a),
        Command::Albedo(a) => cmd_albedo::run(a),
        Command::Sample(a) => cmd_sample::run(a),
        Command::Demo(a) => cmd_demo::run(a),
        Command::Bench(a) => cmd_bench::run(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("strata: {e}");
            ExitCode::FAILURE
        }
    }
}
