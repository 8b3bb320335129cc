//! The command-line tool run as a user runs it (cli), its input: streamed
//! lines, JSON and TOML errors (cli_input), its behaviour under abuse:
//! signals, full disks, bad input (cli_robustness), and its convergence
//! report (cli_converge). One binary, so that the suite links once.

mod cli_common;
#[path = "../../../strata-bsdf/tests/common/mod.rs"]
mod common;

mod cli;
mod cli_converge;
mod cli_input;
mod cli_robustness;
mod cli_spectral;
