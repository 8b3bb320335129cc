//! The SIMD wavefront engine: many walks advance together in lanes.
//!
//! The same estimators as the scalar reference (sample, unidirectional eval,
//! approximate pdf, albedo), over batches of queries:
//!
//! * **Waves.** A wave holds a fixed number of walk slots whose state lives in
//!   structure-of-arrays columns ([`walks::Walks`]). Each round, every live walk
//!   advances by one event. Walks wait in queues by where they are:
//!   at interface `i`, or inside scattering layer `l`. A queue is processed in
//!   chunks of `W::LANES` walks, gathered into lanes, run through the shared
//!   event kernels ([`crate::estimator::events`], `interface`, `medium`) and
//!   scattered back. Every lane of a chunk sits at the same interface or layer,
//!   so the chunk's physics parameters are splatted constants.
//! * **Stream compaction.** Terminated walks leave their slot; the next round
//!   refills free slots with new walks (the next sample of the same query, or
//!   the next query), so queues stay full whatever the walk-length spread.
//!   [`Stats::occupancy`] measures the fraction of busy lanes.
//! * **Masks.** Partial chunks and finished lanes are masked; every kernel
//!   feeds inactive lanes safe values, so no lane produces a NaN.
//! * **Determinism.** Lane `j` draws from walk `j`'s own stream, seeded from
//!   `(seed, query, sample)` exactly as in the scalar engine, and consumes the
//!   same uniforms in the same order, so a walk gives the same value on either
//!   engine, bit for bit (tested on every walk). Results are
//!   reduced per query in the canonical block order
//!   ([`crate::estimator::BlockReducer`]), so they do not depend on the thread
//!   count, the batch composition or the wave size.
//! * **Threads.** A batch is cut into tasks of whole blocks, dealt in turn so
//!   that tasks cost alike whatever the order of the queries; rayon runs the
//!   tasks. Each task owns its wave: no shared mutable state, and memory
//!   bounded by the wave and task sizes. Which blocks share a task does not
//!   change any result. A serial call (one thread) runs its tasks in order
//!   on the calling thread.
//! * **Memory.** A thread keeps its waves, its tasks' queues and its calls'
//!   query columns and reducers between calls (grow-only, cleared per call),
//!   so that the `*_each` calls of a warm thread allocate nothing when they
//!   run serially (`tests/alloc_free.rs`). A call that finds its thread's
//!   buffers in use (re-entered) runs on fresh ones.
//! * **Pay for what the stack uses** ([`Plan`]): clear and absorbing layers are
//!   crossed inside the interface stage (transmittance, never free flight),
//!   grey media skip spectral MIS, smooth interfaces skip microfacet code, and
//!   an interface runs only its own kind's code. [`Plan::General`] turns all of
//!   that off (every layer runs free flight, every interface all code paths):
//!   the unspecialized walk the benchmarks compare against.

//!
//! The files: `engine` (the engine's state, a call's queries), `walks` (a
//! wave's walk records), `stages` (a wave's stages and rounds), `deferred`
//! (the eval connections a round defers), `buffers` (what a thread keeps
//! between calls), `batch` (the batch calls over tasks and threads),
//! `bidir` (the bidirectional estimator's batches).

mod batch;
mod bidir;
mod buffers;
mod deferred;
mod engine;
mod stages;
pub mod walks;

pub use crate::lane::DefaultWide;
pub use batch::{PDF_CHUNK, SERIAL_WALKS};
pub(crate) use buffers::with_kept;
pub use engine::{Plan, Sets, Stats, Wavefront};
