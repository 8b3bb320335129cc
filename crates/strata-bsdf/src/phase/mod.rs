//! Phase functions of the media, over lanes.

pub mod sggx;
