//! The public API and its batches: embedding, settings, material sets and per-
//! query parameters, property tests of its contracts, and the README's example.
//!
//! One test binary per theme, so that the suite links a handful of times;
//! each file below is a module whose doc says what it checks.

#[path = "../common/mod.rs"]
mod common;

mod api_embedding;
mod bounded_walks;
mod layered_settings;
mod material_set;
mod param_sets;
mod per_query_chunks;
mod proptest_api;
mod readme_example;
mod threads;
