//! The C ABI called from Rust: the functions' contracts (abi), per-query
//! columns (columns) and every error path (errors). One binary, so that the
//! suite links once; each module's doc says what it checks.

mod abi;
mod columns;
mod errors;
