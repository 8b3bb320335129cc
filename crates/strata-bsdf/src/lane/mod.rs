//! Lanes: the one abstraction the physics is written against.
//!
//! Every kernel in strata (Fresnel, microfacets, phase functions, free flight)
//! is written once, generic over [`Lane`]. Three instances exist:
//!
//! * `f32`: the scalar reference;
//! * [`F32x8`]: eight walks at once on `wide::f32x8` (the wavefront engine);
//! * `f64`: the accuracy oracle for the stability checks.
//!
//! `f32` and [`F32x8`] share the same transcendental functions
//! ([`crate::math::fastmath`]) and never fuse multiply-adds, so a kernel gives
//! bit-identical results in both: lane `i` of the wavefront replays scalar walk `i`.
//!
//! The trait is deliberately small: arithmetic, `sqrt`, `exp`, `ln`, a sine and
//! cosine of turns, comparisons to a mask, and `select`. Kernels narrow masks
//! monotonically and feed inactive lanes safe values before `sqrt`, `ln` or a
//! division, so no lane ever produces a NaN, even one that is thrown away.
//!
//! The traits are in `traits`, their scalar instances (`f32`, `f64`) in
//! `scalar`, the SIMD ones in `simd`; `V3` and `Rgb` are built on them.

mod rgb;
mod scalar;
mod simd;
pub(crate) mod traits;
mod v3;

pub use rgb::Rgb;
pub use simd::{
    load16, to_unit, BitLanes, DefaultWide, F32x16, F32x8, Wide, LANE_IDS, M16, M8, MAX_LANES,
};
pub use traits::{Lane, LaneBits, LaneMask};
pub use v3::V3;
