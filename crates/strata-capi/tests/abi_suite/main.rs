//! The C ABI called from Rust: the functions' contracts (abi), per-query
//! columns (columns), the configuration text (config), every error path
//! (errors), calls from a thread-local destructor (thread_exit) and the
//! thread setting of every batch call (threads). One binary, so that the
//! suite links once; each module's doc says what it checks.

#[path = "../../../strata-bsdf/tests/common/mod.rs"]
mod common;

mod abi;
mod batch;
mod columns;
mod config;
mod errors;
mod spectral;
mod thread_exit;
mod threads;
