//! Engine parity: the kernels on SIMD lanes against the same kernels on f32,
//! lane by lane, and the wavefront engine against the scalar reference, walk by
//! walk, bit for bit; the only tests that CI also runs on baseline x86-64,
//! where SIMD lanes are emulated differently.
//!
//! One test binary per theme, so that the suite links a handful of times;
//! each file below is a module whose doc says what it checks.

#[path = "../common/mod.rs"]
mod common;

mod bidirectional;
mod control_variate;
mod fingerprint;
mod kernel_parity;
mod layered_determinism;
mod param_sets;
mod wavefront_parity;
