//! Math shared by every kernel: the single-precision transcendental functions
//! the lanes share, frames, warps and the grazing limit of directions.

pub mod fastmath;
mod frame;
mod grazing;
mod warp;

pub use frame::Frame;
pub use grazing::MIN_COS;
pub use warp::{sample_cosine_hemisphere, sample_uniform_sphere};
