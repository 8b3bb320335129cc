//! The public API and its batches: embedding, settings, material sets and per-
//! query parameters, property tests of its contracts, the README's example,
//! and the library's one-way module tree.
//!
//! One test binary per theme, so that the suite links a handful of times;
//! each file below is a module whose doc says what it checks.

#[path = "../common/mod.rs"]
mod common;

mod api_embedding;
mod bounded_walks;
mod config;
mod layered_settings;
mod material_set;
mod material_spectra;
mod module_tree;
mod param_sets;
mod per_query_chunks;
mod proptest_api;
mod readme_example;
mod rows_in_place;
mod spectral_queries;
mod threads;
