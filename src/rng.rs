//! Per-walk random streams.
//!
//! Every walk owns a `Xoshiro128++` stream (rand_xoshiro) seeded from
//! `(seed, query, sample, stream)` through SplitMix64, so a result depends only
//! on those numbers: not on the thread that ran it, the batch it was in, or the
//! engine (the wavefront's lane generator is tested bit for bit against it).

use rand_core::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro128PlusPlus;

/// Which independent stream of a walk.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
pub enum Stream {
    /// The random walk from `wi`.
    Walk = 0,
    /// The adjoint chain sampled from `wo` (next-event estimation).
    Adjoint = 1,
    /// The approximate pdf.
    Pdf = 2,
    /// The brute-force position-based baseline (`estimator::brute_force`).
    BruteForce = 3,
}

/// SplitMix64's output function: a bijective 64-bit mixer.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// The 128-bit initial state of stream `(seed, query, sample, stream)`.
pub fn seed_state(seed: u64, query: u64, sample: u64, stream: Stream) -> [u32; 4] {
    const G: u64 = 0x9e37_79b9_7f4a_7c15;
    let k = mix64(seed.wrapping_add(G));
    let k = mix64(k ^ query.wrapping_mul(G));
    let k = mix64(k ^ sample.wrapping_add(0x632b_e59b_d9b4_e019).wrapping_mul(G));
    let k = mix64(k ^ (stream as u64 + 1).wrapping_mul(0xd6e8_feb8_6659_fd93));
    let a = mix64(k.wrapping_add(G));
    let b = mix64(k.wrapping_add(G.wrapping_mul(2)));
    let s = [a as u32, (a >> 32) as u32, b as u32, (b >> 32) as u32];
    if s == [0; 4] {
        [1, 0, 0, 0]
    } else {
        s
    }
}

/// One walk's stream of uniforms in `[0, 1)`.
#[derive(Clone, Debug)]
pub struct WalkRng(Xoshiro128PlusPlus);

impl WalkRng {
    /// The stream `(seed, query, sample, stream)`.
    pub fn new(seed: u64, query: u64, sample: u64, stream: Stream) -> Self {
        let s = seed_state(seed, query, sample, stream);
        let mut bytes = [0u8; 16];
        for (i, w) in s.iter().enumerate() {
            bytes[4 * i..4 * i + 4].copy_from_slice(&w.to_le_bytes());
        }
        WalkRng(Xoshiro128PlusPlus::from_seed(bytes))
    }

    /// The next raw 32-bit output.
    #[inline]
    pub fn next_u32(&mut self) -> u32 {
        self.0.next_u32()
    }

    /// The next uniform in `[0, 1)`: the top 24 bits, exactly representable.
    #[inline]
    pub fn uniform(&mut self) -> f32 {
        to_unit(self.next_u32())
    }
}

/// Maps 32 random bits to `[0, 1)` with 24 bits of resolution.
#[inline]
pub fn to_unit(x: u32) -> f32 {
    (x >> 8) as f32 * (1.0 / 16_777_216.0)
}
