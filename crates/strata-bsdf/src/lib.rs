//! # strata
//!
//! Layered BSDFs by position-free Monte Carlo (Guo, Hašan and Zhao, "Position-Free
//! Monte Carlo Simulation for Arbitrary Layered BSDFs", SIGGRAPH Asia 2018).
//!
//! A layered material is a stack of interfaces (dielectric, conductor, diffuse;
//! rough or smooth) with homogeneous media between them. Because the slab is
//! laterally infinite, light transport inside it depends on depth and direction
//! only, and the BSDF is an integral over random walks in (depth, direction).
//! strata evaluates that integral, samples it and estimates its pdf, for any
//! stack, with no precomputation.
//!
//! ```
//! use strata_bsdf::{LayeredBsdf, LayerStack};
//! let stack = LayerStack::from_toml_str(r#"
//!     [[layers]]
//!     interface = { kind = "dielectric", ior = 1.5, roughness = 0.1 }
//!     medium = { thickness = 0.5, sigma_t = [0.2, 0.6, 1.2], albedo = 0.0 }
//!     [[layers]]
//!     interface = { kind = "conductor", preset = "Cu", roughness = 0.2 }
//! "#).unwrap();
//! let bsdf = LayeredBsdf::new(stack);
//! let wi = glam::Vec3::new(0.3, 0.0, 0.95).normalize();
//! let wo = glam::Vec3::new(-0.3, 0.1, 0.9).normalize();
//! let f = bsdf.eval(wi, wo).unwrap();          // f(wi, wo) without the cosine
//! assert!(f.value.iter().all(|v| v.is_finite() && *v >= 0.0));
//! ```
//!
//! ## Conventions
//! * Local frame: `z` is the normal of the stack's top, pointing into the
//!   exterior above. `wi` (towards the light) and `wo` (towards the viewer) both
//!   point away from the surface; reflection has `wi.z` and `wo.z` of equal sign.
//! * `eval` returns `f` in 1/sr **without** the cosine; delta lobes are never
//!   returned by `eval`, only produced by `sample`.
//! * Radiance transport: for transmission `f(wi, wo) / n_o² = f(wo, wi) / n_i²`.
//! * `sample(wi)` returns `wo` and the weight `f |cos θo| / p(wo)`, an unbiased
//!   walk throughput. `pdf` is a fast approximation (see [`estimator::pdf`]).
//!
//! ## Determinism
//! Every walk draws from its own stream seeded by `(seed, query, sample)`, so
//! results do not depend on threads or batching.
//!
//! ## What is stable
//! The semver surface is what these docs show: [`LayeredBsdf`] and the
//! records it returns ([`api`]), the material model ([`stack`]), the built-in
//! materials ([`materials`]) and query-line parsing ([`query`]). The modules
//! that implement the method are public only for the workspace's harnesses,
//! tests and benches; they are hidden here and may change in any release.
//! Read them in the source, in the order of the method: `lane`, `math` and
//! `rng`; `fresnel`, `microfacet`, `interface`; `medium` and `phase`; `stack`;
//! `estimator`; `api` (docs/architecture.md has the map: no file names a file
//! that names it back, which `tests/api/module_tree.rs` checks).

#![warn(missing_docs)]

pub mod api;
#[doc(hidden)]
pub mod estimator;
#[doc(hidden)]
pub mod fresnel;
#[doc(hidden)]
pub mod interface;
#[doc(hidden)]
pub mod lane;
pub mod materials;
#[doc(hidden)]
pub mod math;
#[doc(hidden)]
pub mod medium;
#[doc(hidden)]
pub mod microfacet;
#[doc(hidden)]
pub mod phase;
mod pool;
pub mod query;
#[doc(hidden)]
pub mod rng;
pub mod stack;

pub use api::{
    check_walks, AlbedoRecord, BatchError, Bsdf, Column, ColumnsError, Config, ConfigError,
    Direction, Engine, Estimator, EvalBuffers, EvalRecord, EvalStart, LayeredBsdf, Materials,
    PerQuery, Queries, QueryError, Sample, SampleBuffers, SampleFlags, SampleRecord,
    SpectralColumns, SpectralError, ThreadsError, Transport, Vectors, VectorsMut, CONFIG_KEYS,
    MAX_QUERIES, MAX_THREADS, MAX_WALKS,
};
pub use api::{CHUNK_LAYERS, CHUNK_QUERIES, CHUNK_ROWS, MAX_MATERIAL_LAYERS};
pub use estimator::pdf::{PdfEstimate, PdfKind, PdfWalks};
pub use estimator::{Albedo, Estimate, Settings};
pub use stack::{LayerStack, MaterialDesc, MaterialError, SetError, SetPath, Shape, StackError};
