//! Per-walk random streams.
//!
//! Every walk owns a `Xoshiro128++` stream (rand_xoshiro) seeded from
//! `(seed, query, sample, stream)` through SplitMix64, so a result depends only
//! on those numbers: not on the thread that ran it, the batch it was in, or the
//! engine (the wavefront's lane generator is tested bit for bit against it).

use crate::lane::{to_unit, Wide, LANE_IDS, MAX_LANES};
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
    /// The bidirectional estimator's walks (both subpaths and their
    /// connections).
    Bidir = 4,
    /// The factorized estimator of a rough coat over a Lambertian base
    /// (`estimator::rough_coat`): its samples of the coat's transmission.
    Coat = 5,
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
    seed_state_from(query_prefix(seed, query), sample, stream)
}

const G: u64 = 0x9e37_79b9_7f4a_7c15;

/// The part of the seeding hash that depends on `(seed, query)` only, so a
/// batch computes it once per query.
pub fn query_prefix(seed: u64, query: u64) -> u64 {
    let k = mix64(seed.wrapping_add(G));
    mix64(k ^ query.wrapping_mul(G))
}

/// [`seed_state`] from a [`query_prefix`].
#[cfg_attr(feature = "profiling", inline(never))]
pub fn seed_state_from(prefix: u64, sample: u64, stream: Stream) -> [u32; 4] {
    let k = mix64(prefix ^ sample.wrapping_add(0x632b_e59b_d9b4_e019).wrapping_mul(G));
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
        Self::from_prefix(query_prefix(seed, query), sample, stream)
    }

    /// The same stream from a [`query_prefix`], which a loop over one
    /// query's walks computes once.
    #[cfg_attr(feature = "profiling", inline(never))]
    pub fn from_prefix(prefix: u64, sample: u64, stream: Stream) -> Self {
        let s = seed_state_from(prefix, sample, stream);
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

/// One step of Xoshiro128++ on a raw state: the next output, exactly what
/// rand_xoshiro's generator gives from the same state (tested). For code that
/// keeps a walk's state in its own storage (the wavefront engine).
#[inline]
pub fn xoshiro_step(s: &mut [u32; 4]) -> u32 {
    let out = s[0].wrapping_add(s[3]).rotate_left(7).wrapping_add(s[0]);
    let t = s[1] << 9;
    s[2] ^= s[0];
    s[3] ^= s[1];
    s[1] ^= s[2];
    s[0] ^= s[3];
    s[2] ^= t;
    s[3] = s[3].rotate_left(11);
    out
}

/// Xoshiro128++ on SIMD lanes: lane `j` runs the stream of one walk, bit for
/// bit the same numbers as [`WalkRng`] made from the same state (tested).
#[derive(Clone, Copy)]
pub struct LaneRng<W: Wide> {
    s: [W::Bits; 4],
}

impl<W: Wide> LaneRng<W> {
    /// Loads the states of walks `idx` from four state columns.
    #[inline]
    pub fn gather(cols: &[Vec<u32>; 4], idx: &[u32]) -> Self {
        LaneRng {
            s: std::array::from_fn(|k| W::gather_bits(&cols[k], idx)),
        }
    }

    /// Lane `j` starts from state `state(j)`.
    #[inline]
    pub fn from_states(state: impl Fn(usize) -> [u32; 4]) -> Self {
        let mut cols = [[0u32; MAX_LANES]; 4];
        for j in 0..W::LANES {
            for (col, v) in cols.iter_mut().zip(state(j)) {
                col[j] = v;
            }
        }
        LaneRng {
            s: std::array::from_fn(|k| W::gather_bits(&cols[k], &LANE_IDS[..W::LANES])),
        }
    }

    /// Stores the states back where `m` is set.
    #[inline]
    pub fn scatter(&self, cols: &mut [Vec<u32>; 4], idx: &[u32], m: W::Mask) {
        for (k, col) in cols.iter_mut().enumerate() {
            W::scatter_bits(self.s[k], col, idx, m);
        }
    }

    /// From the four state words of every lane.
    #[inline]
    pub fn from_bits(s: [W::Bits; 4]) -> Self {
        LaneRng { s }
    }

    /// The four state words of every lane.
    #[inline]
    pub fn to_bits(&self) -> [W::Bits; 4] {
        self.s
    }

    /// The state of lane `j`.
    #[inline]
    pub fn lane_state(&self, j: usize) -> [u32; 4] {
        std::array::from_fn(|k| W::bits_lane(self.s[k], j))
    }

    /// The next uniform in `[0, 1)` of every lane in `m`; other lanes keep
    /// their state (they draw nothing) and get an unspecified value in `[0, 1)`.
    #[inline]
    pub fn uniform(&mut self, m: W::Mask) -> W {
        let [s0, s1, s2, s3] = self.s;
        let sum = s0 + s3;
        let out = ((sum << 7) | (sum >> 25)) + s0;
        let t = s1 << 9;
        let n2 = s2 ^ s0;
        let n3 = s3 ^ s1;
        let n1 = s1 ^ n2;
        let n0 = s0 ^ n3;
        let n2 = n2 ^ t;
        let n3 = (n3 << 11) | (n3 >> 21);
        let next = [n0, n1, n2, n3];
        for (s, n) in self.s.iter_mut().zip(next) {
            *s = W::select_bits(m, n, *s);
        }
        W::bits_to_unit(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lane::{F32x16, F32x8, LaneMask};

    fn lanes_match_scalar<W: Wide>() {
        let n = W::LANES;
        let cols: [Vec<u32>; 4] = std::array::from_fn(|k| {
            (0..n as u64)
                .map(|q| seed_state(7, q, 3, Stream::Walk)[k])
                .collect()
        });
        let idx: Vec<u32> = (0..n as u32).collect();
        let mut lanes = LaneRng::<W>::gather(&cols, &idx);
        let mut scalars: Vec<WalkRng> = (0..n as u64)
            .map(|q| WalkRng::new(7, q, 3, Stream::Walk))
            .collect();
        // Lanes draw on a changing subset; a lane that skips a draw must not advance.
        for step in 0..200u32 {
            let bits = 0x9e37_79b9u32.rotate_left(step) | 1;
            let m = W::mask_from_bitmask(bits);
            let u = lanes.uniform(m);
            for (j, r) in scalars.iter_mut().enumerate() {
                if m.lane(j) {
                    assert_eq!(u.lane(j) as f32, r.uniform(), "step {step} lane {j}");
                }
            }
        }
    }

    #[test]
    fn lane_rng_is_rand_xoshiro_bit_for_bit() {
        lanes_match_scalar::<F32x8>();
        lanes_match_scalar::<F32x16>();
    }

    #[test]
    fn scalar_step_is_rand_xoshiro_bit_for_bit() {
        let mut s = seed_state(3, 4, 5, Stream::Adjoint);
        let mut r = WalkRng::new(3, 4, 5, Stream::Adjoint);
        for _ in 0..1000 {
            assert_eq!(xoshiro_step(&mut s), r.next_u32());
        }
    }

    /// A stream made from a query's prefix is the stream `(seed, query,
    /// sample, stream)` of [`seed_state`], and its first output is the one
    /// the seeding has always given (values from commit 23a6ef1, before
    /// `from_prefix` existed): a change to the seeding changes every result.
    #[test]
    fn from_prefix_is_the_seeded_stream() {
        let p = query_prefix(9, 4);
        for (k, stream, first) in [
            (0, Stream::Walk, 2_089_177_970),
            (7, Stream::Adjoint, 1_255_247_153),
            (1 << 40, Stream::Pdf, 1_799_945_480),
        ] {
            let mut s = seed_state(9, 4, k, stream);
            let mut r = WalkRng::from_prefix(p, k, stream);
            let out: Vec<u32> = (0..8).map(|_| r.next_u32()).collect();
            assert_eq!(out[0], first);
            assert_eq!(
                out,
                (0..8).map(|_| xoshiro_step(&mut s)).collect::<Vec<_>>()
            );
        }
    }

    #[test]
    fn streams_differ_by_every_key() {
        let base = seed_state(1, 2, 3, Stream::Walk);
        assert_ne!(base, seed_state(0, 2, 3, Stream::Walk));
        assert_ne!(base, seed_state(1, 0, 3, Stream::Walk));
        assert_ne!(base, seed_state(1, 2, 0, Stream::Walk));
        assert_ne!(base, seed_state(1, 2, 3, Stream::Adjoint));
    }
}
