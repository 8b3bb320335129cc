//! Warps from the unit square to directions.

use crate::lane::{Lane, V3};

/// Cosine-weighted direction on the +z hemisphere (Malley's method); density `z / π`.
#[inline]
pub fn sample_cosine_hemisphere<L: Lane>(u1: L, u2: L) -> V3<L> {
    let r = u1.sqrt();
    let (s, c) = u2.sin_cos_turns();
    V3::new(r * c, r * s, (L::one() - u1).safe_sqrt())
}

/// Uniform direction on the sphere; density `1 / 4π`.
#[inline]
pub fn sample_uniform_sphere<L: Lane>(u1: L, u2: L) -> V3<L> {
    let z = L::one() - L::splat(2.0) * u1;
    let r = (L::one() - z * z).safe_sqrt();
    let (s, c) = u2.sin_cos_turns();
    V3::new(r * c, r * s, z)
}
