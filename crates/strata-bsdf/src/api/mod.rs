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
//! * `strategy`: the choices of estimator and start side a caller makes;
//!   `plan`: the automatic ones (`Auto`), each rule with its constants,
//!   decided once per row.
//! * `queries`: one batch of queries ([`Queries`]) and the verbs that
//!   answer it ([`Bsdf`]); `batch`: those verbs for a BSDF, for
//!   [`Materials`] and for [`PerQuery`].
//! * `vectors`: the flat buffers a renderer keeps (SoA, AoS or `Vec3`), and
//!   `#[repr(C)]` records.
//! * `param_sets`, `sets`: the numbers of many stacks of one shape, which
//!   a table's rows become; `materials`: tables of materials of any shapes;
//!   `columns`: a query's own numbers by column; `spectral`: the columns
//!   of queries at wavelengths.

mod batch;
mod bsdf;
mod columns;
mod config;
mod error;
mod materials;
mod param_sets;
mod plan;
mod queries;
mod sets;
mod spectral;
mod strategy;
mod transport;
mod vectors;

pub use bsdf::{direction_key, LayeredBsdf, Sample};
pub use columns::{
    Column, ColumnsError, PerQuery, CHUNK_LAYERS, CHUNK_QUERIES, CHUNK_ROWS, MAX_MATERIAL_LAYERS,
    MAX_QUERIES,
};
pub use config::{Config, ConfigError, CONFIG_KEYS};
pub use error::{
    check_walks, BatchError, Direction, QueryError, ThreadsError, MAX_THREADS, MAX_WALKS,
};
pub use materials::Materials;
pub use plan::{
    BOOSTED_CV_MAX_DEPTH, MAX_COATED_CONDUCTOR_DEPTH, MAX_OPTICAL_DEPTH, NEAR_SPECULAR_ALPHA,
    ROUGH_CV_MIN_BASE,
};
pub use queries::{Bsdf, Queries};
pub use spectral::{SpectralColumns, SpectralError};
pub use strategy::{Engine, Estimator, EvalStart};
pub use transport::Transport;
pub use vectors::{
    AlbedoRecord, EvalBuffers, EvalRecord, SampleBuffers, SampleFlags, SampleRecord, Vectors,
    VectorsMut,
};
