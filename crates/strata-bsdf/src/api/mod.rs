//! The public API: [`LayeredBsdf`], with eval, sample, pdf and albedo.
//!
//! Directions cross the boundary as `glam::Vec3` in the local frame (z = normal
//! of the stack's top; both directions pointing away from the surface). They
//! are normalized on the way in; a NaN, infinite or zero-length direction is a
//! [`QueryError`] naming the argument and its value, never a panic and never a
//! silent NaN.
//!
//! * `bsdf`: [`LayeredBsdf`] and its single and batch queries (the core
//!   the other files' batch forms call).
//! * `config`: how a BSDF answers apart from its stack, as one value with
//!   one text form.
//! * `error`: what can be wrong with a query, and which one.
//! * `transport`: radiance or importance, for light that crosses the stack.
//! * `strategy`: which estimator answers `eval`, and from which side.
//! * `param_sets`, `sets`: per-query parameter sets, and the batch calls
//!   that take them; `materials`: batches that mix shapes; `columns`: a
//!   query's own numbers by column.
//! * [`slices`]: the batch forms over flat slices a renderer keeps (SoA or
//!   AoS), writing into the caller's buffers, and `#[repr(C)]` records.

mod bsdf;
mod columns;
mod config;
mod error;
mod materials;
mod param_sets;
mod sets;
pub mod slices;
mod strategy;
mod transport;

pub use bsdf::{direction_key, Engine, LayeredBsdf, Sample};
pub use columns::{
    Column, ColumnsError, PerQuery, CHUNK_LAYERS, CHUNK_QUERIES, CHUNK_ROWS, MAX_MATERIAL_LAYERS,
    MAX_QUERIES,
};
pub use config::{Config, ConfigError, CONFIG_KEYS};
pub use error::{
    check_walks, BatchError, Direction, QueryError, ThreadsError, MAX_THREADS, MAX_WALKS,
};
pub use materials::Materials;
pub use param_sets::{ParamSets, SetsError};
pub use slices::{AlbedoRecord, EvalRecord, SampleFlags, SampleRecord, Vectors, VectorsMut};
pub use strategy::{Estimator, EvalStart, MAX_OPTICAL_DEPTH, NEAR_SPECULAR_ALPHA};
pub use transport::Transport;
