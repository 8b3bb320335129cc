//! strata's criterion benchmarks, kept out of the library crate so that
//! `cargo test` does not build criterion. The benchmarks are in `benches/`:
//! `cargo bench -p strata-benches --bench kernels` (the lane kernels) and
//! `--bench estimators` (the engines, single calls, the pdf's walks, a
//! renderer's path vertex).
