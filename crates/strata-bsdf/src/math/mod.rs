//! Math shared by every kernel: the single-precision transcendental functions
//! the lanes share, frames and warps.

pub mod fastmath;
mod frame;
mod warp;

pub use frame::Frame;
pub use warp::{sample_cosine_hemisphere, sample_uniform_sphere};
