//! The SIMD instances of [`Lane`]: [`F32x8`] on `wide::f32x8` (the wavefront
//! engine's default) and [`F32x16`] on `wide::f32x16` (measured beside it).
//!
//! This file and `crate::rng`'s lane generator are the only places that touch
//! `wide`. With `-C target-cpu=x86-64-v3` (AVX2 + FMA) an `F32x8` is one 256-bit
//! register; on baseline x86-64 `wide` runs it as two SSE halves, with identical
//! results. An `F32x16` is one AVX-512 register with `-C target-cpu=native` on a
//! CPU that has it, and two AVX2 halves otherwise.
//!
//! Both widths implement [`Wide`]: what the wavefront engine needs beyond the
//! arithmetic of [`Lane`] (gathers and scatters of walk columns, and the 32-bit
//! integer lanes of the random number generator).

use super::traits::{Lane, LaneBits, LaneMask};
use std::ops::{
    Add, AddAssign, BitAnd, BitOr, BitXor, Div, DivAssign, Mul, MulAssign, Neg, Not, Shl, Shr, Sub,
    SubAssign,
};

/// The lane type of the wavefront engine (and of the closed forms it
/// samples over lanes): the one place the width is set.
pub type DefaultWide = F32x8;

/// The widest lane type's lane count ([`F32x16`]): per-chunk index arrays
/// are this long.
pub const MAX_LANES: usize = 16;

/// `LANE_IDS[j] == j`: the index list under which lane `j` reads or writes
/// row `j` of a small per-chunk table (with [`Wide::load8`], [`Wide::store8`],
/// [`Wide::gather_bits`]).
pub const LANE_IDS: [u32; MAX_LANES] = {
    let mut a = [0u32; MAX_LANES];
    let mut j = 0;
    while j < MAX_LANES {
        a[j] = j as u32;
        j += 1;
    }
    a
};

/// Unsigned 32-bit integer lanes: the state of the lane random number generator.
pub trait BitLanes:
    Copy
    + Send
    + Sync
    + Add<Output = Self>
    + BitXor<Output = Self>
    + BitOr<Output = Self>
    + Shl<u32, Output = Self>
    + Shr<u32, Output = Self>
{
}

/// A SIMD lane type the wavefront engine runs on.
pub trait Wide: Lane + LaneBits {
    /// 32-bit unsigned integers, one per lane.
    type Bits: BitLanes;
    /// Loads `col[idx[j]]` into lane `j` (`idx.len() == LANES`).
    fn gather(col: &[f32], idx: &[u32]) -> Self;
    /// Stores lane `j` into `col[idx[j]]` where `m` is set.
    fn scatter(self, col: &mut [f32], idx: &[u32], m: Self::Mask);
    /// Loads `col[idx[j]]` into integer lane `j`.
    fn gather_bits(col: &[u32], idx: &[u32]) -> Self::Bits;
    /// Stores integer lane `j` into `col[idx[j]]` where `m` is set.
    fn scatter_bits(b: Self::Bits, col: &mut [u32], idx: &[u32], m: Self::Mask);
    /// Integer lane `j`.
    fn bits_lane(b: Self::Bits, j: usize) -> u32;
    /// `t` where `m` is set, `f` elsewhere.
    fn select_bits(m: Self::Mask, t: Self::Bits, f: Self::Bits) -> Self::Bits;
    /// `(b >> 8) · 2⁻²⁴`: the uniform in `[0, 1)` that [`to_unit`] makes.
    fn bits_to_unit(b: Self::Bits) -> Self;
    /// One bit per lane, lane 0 in bit 0.
    fn bitmask(m: Self::Mask) -> u32;
    /// The mask with lane `j` set where bit `j` of `bits` is.
    fn mask_from_bitmask(bits: u32) -> Self::Mask;
    /// The bits of each lane as an integer lane.
    fn to_bit_lanes(self) -> Self::Bits;
    /// Integer lanes reinterpreted as floats.
    fn from_bit_lanes(b: Self::Bits) -> Self;
    /// Loads fields `first..first + 8` of records `recs[idx[j]]` (one record
    /// per lane) and transposes them: element `k` holds field `first + k` of
    /// every lane's record.
    fn load8<const R: usize>(recs: &[[f32; R]], idx: &[u32], first: usize) -> [Self; 8];
    /// The inverse of [`Wide::load8`]: stores fields `first..first + 8` of
    /// every lane's record, the last lane first (where `idx` repeats an index,
    /// the lowest lane's record is the one that stays).
    fn store8<const R: usize>(vals: [Self; 8], recs: &mut [[f32; R]], idx: &[u32], first: usize);
}

/// Fields `first..first + 16` of records `recs[idx[j]]` in lanes (two
/// [`Wide::load8`]s): a chain link's twelve fields and what follows them.
#[inline(always)]
pub fn load16<W: Wide, const R: usize>(recs: &[[f32; R]], idx: &[u32], first: usize) -> [W; 16] {
    let (lo, hi) = (W::load8(recs, idx, first), W::load8(recs, idx, first + 8));
    std::array::from_fn(|k| if k < 8 { lo[k] } else { hi[k - 8] })
}

/// Eight rows of eight floats, transposed.
#[inline]
fn transpose8(rows: [wide::f32x8; 8]) -> [wide::f32x8; 8] {
    wide::f32x8::transpose(rows)
}

/// Checks that `idx[..8]` are records of `recs` and that fields
/// `first..first + 8` exist, once for the eight rows of a block.
#[inline(always)]
fn check8<const R: usize>(n: usize, idx: &[u32], first: usize) -> &[u32; 8] {
    let idx: &[u32; 8] = idx[..8].try_into().expect("eight lanes");
    assert!(first + 8 <= R, "fields {first}..{} of {R}", first + 8);
    assert!(
        idx.iter().all(|&i| (i as usize) < n),
        "record index out of range"
    );
    idx
}

/// Loads an 8×8 block: rows are records `idx[j]`, columns fields `first..first + 8`.
#[inline(always)]
fn rows8<const R: usize>(recs: &[[f32; R]], idx: &[u32], first: usize) -> [wide::f32x8; 8] {
    let idx = check8::<R>(recs.len(), idx, first);
    let base = recs.as_ptr() as *const f32;
    std::array::from_fn(|j| {
        // SAFETY: check8 showed idx[j] < recs.len() and first + 8 <= R, so the
        // eight floats at recs[idx[j]][first..] lie inside `recs`; an [f32; 8]
        // read needs no more than f32 alignment. (Measured: the bounds-checked
        // slice version made loading a chunk several times slower.)
        let row = unsafe {
            base.add(idx[j] as usize * R + first)
                .cast::<[f32; 8]>()
                .read()
        };
        wide::f32x8::from(row)
    })
}

/// Stores an 8×8 block, the last row first (see [`Wide::store8`]).
#[inline(always)]
fn put_rows8<const R: usize>(
    rows: [wide::f32x8; 8],
    recs: &mut [[f32; R]],
    idx: &[u32],
    first: usize,
) {
    let idx = check8::<R>(recs.len(), idx, first);
    let base = recs.as_mut_ptr() as *mut f32;
    for j in (0..8).rev() {
        // SAFETY: as in rows8, the eight floats written lie inside `recs`.
        unsafe {
            base.add(idx[j] as usize * R + first)
                .cast::<[f32; 8]>()
                .write(rows[j].to_array())
        };
    }
}

/// The result of a blend, hidden from the optimizer.
///
/// On AVX builds without AVX-512, LLVM turns "blend a new value into one just
/// loaded from memory, store the blend back" (a masked update of a walk's
/// field) into a masked store, `vmaskmovps`, which is slow on AMD Zen and
/// would slow every stack's walks (docs/performance.md). An empty `asm!`
/// block between the blend and its uses keeps the blend a blend; it emits no
/// instruction. With AVX-512 the masked store is a fast `vmovups {k}`, and on
/// other targets there is none, so there this is the identity.
#[inline(always)]
fn opaque<T: wide::bytemuck::Pod>(x: T) -> T {
    #[cfg(all(
        target_arch = "x86_64",
        target_feature = "avx",
        not(target_feature = "avx512f")
    ))]
    {
        use std::arch::x86_64::__m256;
        use wide::bytemuck::cast;
        #[inline(always)]
        fn hide(mut r: __m256) -> __m256 {
            // SAFETY: the template is an assembler comment: no instruction is
            // emitted, no memory is touched; the register is only declared
            // read and written.
            unsafe {
                std::arch::asm!("/* {0} */", inout(ymm_reg) r, options(pure, nomem, nostack, preserves_flags));
            }
            r
        }
        match size_of::<T>() {
            32 => cast(hide(cast(x))),
            64 => cast(cast::<T, [__m256; 2]>(x).map(hide)),
            _ => x,
        }
    }
    #[cfg(not(all(
        target_arch = "x86_64",
        target_feature = "avx",
        not(target_feature = "avx512f")
    )))]
    {
        x
    }
}

macro_rules! wide_lane {
    (
        $(#[$doc:meta])* $name:ident,
        $(#[$mdoc:meta])* $mask:ident,
        $f:ident, $u:ident, $i:ident, $n:literal, $from_i:ident
    ) => {
        $(#[$doc])*
        #[derive(Clone, Copy, Debug, Default, PartialEq)]
        #[repr(transparent)]
        pub struct $name(pub wide::$f);

        $(#[$mdoc])*
        #[derive(Clone, Copy, Debug)]
        #[repr(transparent)]
        pub struct $mask(pub wide::$f);

        impl $name {
            /// Lanes as an array.
            #[inline]
            pub fn to_array(self) -> [f32; $n] {
                self.0.to_array()
            }
            /// From an array of lanes.
            #[inline]
            pub fn from_array(a: [f32; $n]) -> Self {
                $name(wide::$f::from(a))
            }
            /// The raw bits of each lane.
            #[inline]
            pub fn to_bits(self) -> wide::$u {
                self.0.to_bits()
            }
            /// From raw bits per lane.
            #[inline]
            pub fn from_bits(b: wide::$u) -> Self {
                $name(wide::$f::from_bits(b))
            }
        }

        impl $mask {
            /// One bit per lane, lane 0 in bit 0.
            #[inline]
            pub fn bitmask(self) -> u32 {
                self.0.to_bitmask()
            }
            /// From one bool per lane.
            #[inline]
            pub fn from_bools(b: [bool; $n]) -> Self {
                let t = f32::from_bits(u32::MAX);
                $mask(wide::$f::from(b.map(|x| if x { t } else { 0.0 })))
            }
        }

        impl BitAnd for $mask {
            type Output = $mask;
            #[inline]
            fn bitand(self, o: $mask) -> $mask {
                $mask(self.0 & o.0)
            }
        }
        impl BitOr for $mask {
            type Output = $mask;
            #[inline]
            fn bitor(self, o: $mask) -> $mask {
                $mask(self.0 | o.0)
            }
        }
        impl BitXor for $mask {
            type Output = $mask;
            #[inline]
            fn bitxor(self, o: $mask) -> $mask {
                $mask(self.0 ^ o.0)
            }
        }
        impl Not for $mask {
            type Output = $mask;
            #[inline]
            fn not(self) -> $mask {
                $mask(!self.0)
            }
        }

        impl LaneMask for $mask {
            #[inline]
            fn splat(b: bool) -> Self {
                $mask(wide::$f::splat(if b { f32::from_bits(u32::MAX) } else { 0.0 }))
            }
            #[inline]
            fn from_fn(f: impl FnMut(usize) -> bool) -> Self {
                $mask::from_bools(std::array::from_fn(f))
            }
            #[inline]
            fn any(self) -> bool {
                self.0.any()
            }
            #[inline]
            fn all(self) -> bool {
                self.0.all()
            }
            #[inline]
            fn lane(self, i: usize) -> bool {
                self.0.to_bitmask() & (1 << i) != 0
            }
        }

        wide_lane!(@binop $name, Add, add, AddAssign, add_assign, +);
        wide_lane!(@binop $name, Sub, sub, SubAssign, sub_assign, -);
        wide_lane!(@binop $name, Mul, mul, MulAssign, mul_assign, *);
        wide_lane!(@binop $name, Div, div, DivAssign, div_assign, /);

        impl Neg for $name {
            type Output = $name;
            #[inline]
            fn neg(self) -> $name {
                $name(-self.0)
            }
        }

        impl Lane for $name {
            type Mask = $mask;
            const LANES: usize = $n;
            #[inline]
            fn splat(v: f64) -> Self {
                $name(wide::$f::splat(v as f32))
            }
            #[inline]
            fn from_fn(mut f: impl FnMut(usize) -> f64) -> Self {
                $name(wide::$f::from(std::array::from_fn::<f32, $n, _>(|i| f(i) as f32)))
            }
            #[inline]
            fn lane(self, i: usize) -> f64 {
                self.0.to_array()[i] as f64
            }
            #[inline]
            fn sqrt(self) -> Self {
                $name(self.0.sqrt())
            }
            #[inline]
            fn abs(self) -> Self {
                $name(self.0.abs())
            }
            #[inline]
            fn min(self, o: Self) -> Self {
                // `if self < o { self } else { o }`, the scalar instance's definition.
                $name(self.0.simd_lt(o.0).select(self.0, o.0))
            }
            #[inline]
            fn max(self, o: Self) -> Self {
                $name(self.0.simd_gt(o.0).select(self.0, o.0))
            }
            #[inline]
            fn floor(self) -> Self {
                $name(self.0.floor())
            }
            #[inline]
            fn exp(self) -> Self {
                crate::math::fastmath::exp(self)
            }
            #[inline]
            fn exp_m1(self) -> Self {
                crate::math::fastmath::exp_m1(self)
            }
            #[inline]
            fn ln(self) -> Self {
                crate::math::fastmath::ln(self)
            }
            #[inline]
            fn sin_cos_turns(self) -> (Self, Self) {
                crate::math::fastmath::sin_cos_turns(self)
            }
            #[inline]
            fn lt(self, o: Self) -> $mask {
                $mask(self.0.simd_lt(o.0))
            }
            #[inline]
            fn le(self, o: Self) -> $mask {
                $mask(self.0.simd_le(o.0))
            }
            #[inline]
            fn gt(self, o: Self) -> $mask {
                $mask(self.0.simd_gt(o.0))
            }
            #[inline]
            fn ge(self, o: Self) -> $mask {
                $mask(self.0.simd_ge(o.0))
            }
            #[inline]
            fn eq(self, o: Self) -> $mask {
                $mask(self.0.simd_eq(o.0))
            }
            #[inline]
            fn is_finite(self) -> $mask {
                $mask(self.0.is_finite())
            }
            #[inline]
            fn select(m: $mask, t: Self, f: Self) -> Self {
                $name(opaque(m.0.select(t.0, f.0)))
            }
        }

        impl LaneBits for $name {
            #[inline]
            fn pow2i(n: Self) -> Self {
                let i: wide::$i = (n.0 + wide::$f::splat(127.0)).round_int();
                let u: wide::$u = wide::bytemuck::cast(i);
                $name(wide::$f::from_bits(u << 23))
            }
            #[inline]
            fn frexp(self) -> (Self, Self) {
                let b = self.0.to_bits();
                let e: wide::$i = wide::bytemuck::cast((b >> 23) & wide::$u::splat(0xff));
                let m = (b & wide::$u::splat(0x807f_ffff)) | wide::$u::splat(0x3f00_0000);
                (
                    $name(wide::$f::from_bits(m)),
                    $name(wide::$f::$from_i(e) - wide::$f::splat(126.0)),
                )
            }
        }

        impl BitLanes for wide::$u {}

        impl Wide for $name {
            type Bits = wide::$u;
            #[inline]
            fn gather(col: &[f32], idx: &[u32]) -> Self {
                $name(wide::$f::from(std::array::from_fn::<f32, $n, _>(|j| {
                    col[idx[j] as usize]
                })))
            }
            #[inline]
            fn scatter(self, col: &mut [f32], idx: &[u32], m: $mask) {
                let a = self.0.to_array();
                let bits = m.bitmask();
                for j in 0..$n {
                    if bits & (1 << j) != 0 {
                        col[idx[j] as usize] = a[j];
                    }
                }
            }
            #[inline]
            fn gather_bits(col: &[u32], idx: &[u32]) -> wide::$u {
                wide::$u::from(std::array::from_fn::<u32, $n, _>(|j| col[idx[j] as usize]))
            }
            #[inline]
            fn scatter_bits(b: wide::$u, col: &mut [u32], idx: &[u32], m: $mask) {
                let a = b.to_array();
                let bits = m.bitmask();
                for j in 0..$n {
                    if bits & (1 << j) != 0 {
                        col[idx[j] as usize] = a[j];
                    }
                }
            }
            #[inline]
            fn bits_lane(b: wide::$u, j: usize) -> u32 {
                b.to_array()[j]
            }
            #[inline]
            fn select_bits(m: $mask, t: wide::$u, f: wide::$u) -> wide::$u {
                let m: wide::$u = m.0.to_bits();
                opaque((t & m) | (f & !m))
            }
            #[inline]
            fn bits_to_unit(b: wide::$u) -> Self {
                // Below 2^24, so the signed conversion is exact.
                let i: wide::$i = wide::bytemuck::cast(b >> 8);
                $name(wide::$f::$from_i(i) * wide::$f::splat(1.0 / 16_777_216.0))
            }
            #[inline]
            fn bitmask(m: $mask) -> u32 {
                m.bitmask()
            }
            #[inline]
            fn mask_from_bitmask(bits: u32) -> $mask {
                // Lane j tests bit j: a splat, an and and a compare (building
                // the mask from bools took a chain of lane inserts).
                let lane_bit = wide::$u::from(std::array::from_fn::<u32, $n, _>(|j| 1 << j));
                let set = (wide::$u::splat(bits) & lane_bit).simd_eq(lane_bit);
                $mask(wide::$f::from_bits(set))
            }
            #[inline]
            fn to_bit_lanes(self) -> wide::$u {
                self.0.to_bits()
            }
            #[inline]
            fn from_bit_lanes(b: wide::$u) -> Self {
                $name(wide::$f::from_bits(b))
            }
            #[inline(always)]
            fn load8<const R: usize>(recs: &[[f32; R]], idx: &[u32], first: usize) -> [Self; 8] {
                $name::load8_impl(recs, idx, first)
            }
            #[inline(always)]
            fn store8<const R: usize>(vals: [Self; 8], recs: &mut [[f32; R]], idx: &[u32], first: usize) {
                $name::store8_impl(vals, recs, idx, first)
            }
        }
    };
    (@binop $name:ident, $tr:ident, $f:ident, $atr:ident, $af:ident, $op:tt) => {
        impl $tr for $name {
            type Output = $name;
            #[inline]
            fn $f(self, o: $name) -> $name {
                $name(self.0 $op o.0)
            }
        }
        impl $atr for $name {
            #[inline]
            fn $af(&mut self, o: $name) {
                self.0 = self.0 $op o.0;
            }
        }
    };
}

wide_lane!(
    /// Eight f32 lanes.
    F32x8,
    /// Eight boolean lanes (all bits set or all clear, as `wide` expects).
    M8,
    f32x8, u32x8, i32x8, 8, from_i32x8
);

wide_lane!(
    /// Sixteen f32 lanes.
    F32x16,
    /// Sixteen boolean lanes.
    M16,
    f32x16, u32x16, i32x16, 16, from_i32x16
);

// Per-chunk index arrays hold `MAX_LANES` lanes.
const _: () = assert!(F32x8::LANES <= MAX_LANES && F32x16::LANES <= MAX_LANES);

impl F32x8 {
    #[inline(always)]
    fn load8_impl<const R: usize>(recs: &[[f32; R]], idx: &[u32], first: usize) -> [Self; 8] {
        transpose8(rows8(recs, idx, first)).map(F32x8)
    }
    #[inline(always)]
    fn store8_impl<const R: usize>(
        vals: [Self; 8],
        recs: &mut [[f32; R]],
        idx: &[u32],
        first: usize,
    ) {
        put_rows8(transpose8(vals.map(|v| v.0)), recs, idx, first);
    }
}

impl F32x16 {
    // Two 8×8 transposes, one per half of the lanes.
    #[inline(always)]
    fn load8_impl<const R: usize>(recs: &[[f32; R]], idx: &[u32], first: usize) -> [Self; 8] {
        let lo = transpose8(rows8(recs, &idx[..8], first));
        let hi = transpose8(rows8(recs, &idx[8..16], first));
        std::array::from_fn(|k| {
            let mut a = [0.0f32; 16];
            a[..8].copy_from_slice(&lo[k].to_array());
            a[8..].copy_from_slice(&hi[k].to_array());
            F32x16::from_array(a)
        })
    }
    #[inline(always)]
    fn store8_impl<const R: usize>(
        vals: [Self; 8],
        recs: &mut [[f32; R]],
        idx: &[u32],
        first: usize,
    ) {
        let lanes = vals.map(|v| v.to_array());
        for h in (0..2).rev() {
            let rows = transpose8(std::array::from_fn(|k| {
                let l = &lanes[k][8 * h..8 * h + 8];
                wide::f32x8::from(<[f32; 8]>::try_from(l).expect("8 lanes"))
            }));
            put_rows8(rows, recs, &idx[8 * h..8 * h + 8], first);
        }
    }
}

/// Wrapping 32-bit unsigned integer: the random state of a one-lane "chunk".
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct U32(pub u32);

impl Add for U32 {
    type Output = U32;
    #[inline]
    fn add(self, o: U32) -> U32 {
        U32(self.0.wrapping_add(o.0))
    }
}
impl BitXor for U32 {
    type Output = U32;
    #[inline]
    fn bitxor(self, o: U32) -> U32 {
        U32(self.0 ^ o.0)
    }
}
impl BitOr for U32 {
    type Output = U32;
    #[inline]
    fn bitor(self, o: U32) -> U32 {
        U32(self.0 | o.0)
    }
}
impl Shl<u32> for U32 {
    type Output = U32;
    #[inline]
    fn shl(self, k: u32) -> U32 {
        U32(self.0.wrapping_shl(k))
    }
}
impl Shr<u32> for U32 {
    type Output = U32;
    #[inline]
    fn shr(self, k: u32) -> U32 {
        U32(self.0.wrapping_shr(k))
    }
}
impl BitLanes for U32 {}

/// Maps 32 random bits to `[0, 1)` with 24 bits of resolution: the uniform
/// of the scalar walks' streams (`crate::rng`), which [`Wide::bits_to_unit`]
/// makes per lane.
#[inline]
pub fn to_unit(x: u32) -> f32 {
    (x >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// One lane: the wavefront engine finishes the last, longest walks of a task
/// on it, where a lone walk would leave seven of eight SIMD lanes idle. The
/// same kernels and stages run, so its walks are bit for bit those of the
/// other widths and of the scalar reference.
impl Wide for f32 {
    type Bits = U32;
    #[inline]
    fn gather(col: &[f32], idx: &[u32]) -> Self {
        col[idx[0] as usize]
    }
    #[inline]
    fn scatter(self, col: &mut [f32], idx: &[u32], m: bool) {
        if m {
            col[idx[0] as usize] = self;
        }
    }
    #[inline]
    fn gather_bits(col: &[u32], idx: &[u32]) -> U32 {
        U32(col[idx[0] as usize])
    }
    #[inline]
    fn scatter_bits(b: U32, col: &mut [u32], idx: &[u32], m: bool) {
        if m {
            col[idx[0] as usize] = b.0;
        }
    }
    #[inline]
    fn bits_lane(b: U32, _j: usize) -> u32 {
        b.0
    }
    #[inline]
    fn select_bits(m: bool, t: U32, f: U32) -> U32 {
        if m {
            t
        } else {
            f
        }
    }
    #[inline]
    fn bits_to_unit(b: U32) -> Self {
        to_unit(b.0)
    }
    #[inline]
    fn bitmask(m: bool) -> u32 {
        m as u32
    }
    #[inline]
    fn mask_from_bitmask(bits: u32) -> bool {
        bits & 1 != 0
    }
    #[inline]
    fn to_bit_lanes(self) -> U32 {
        U32(self.to_bits())
    }
    #[inline]
    fn from_bit_lanes(b: U32) -> Self {
        f32::from_bits(b.0)
    }
    #[inline]
    fn load8<const R: usize>(recs: &[[f32; R]], idx: &[u32], first: usize) -> [Self; 8] {
        recs[idx[0] as usize][first..first + 8]
            .try_into()
            .expect("eight fields")
    }
    #[inline]
    fn store8<const R: usize>(vals: [Self; 8], recs: &mut [[f32; R]], idx: &[u32], first: usize) {
        recs[idx[0] as usize][first..first + 8].copy_from_slice(&vals);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every bit pattern of `W::LANES` lanes survives mask ↔ bitmask, and a
    /// select takes lane `j` from `t` exactly where bit `j` is set.
    fn masks_and_selects<W: Wide>() {
        let t = W::from_fn(|j| j as f64 + 1.0);
        let f = W::from_fn(|j| -(j as f64) - 0.5);
        let tb = t.to_bit_lanes();
        let fb = f.to_bit_lanes();
        for bits in 0..(1u32 << W::LANES) {
            let m = W::mask_from_bitmask(bits);
            assert_eq!(W::bitmask(m), bits);
            let s = W::select(m, t, f);
            let sb = W::select_bits(m, tb, fb);
            for j in 0..W::LANES {
                let on = bits & (1 << j) != 0;
                assert_eq!(m.lane(j), on);
                assert_eq!(s.lane(j), if on { t.lane(j) } else { f.lane(j) });
                let want = if on {
                    W::bits_lane(tb, j)
                } else {
                    W::bits_lane(fb, j)
                };
                assert_eq!(W::bits_lane(sb, j), want);
            }
        }
    }

    #[test]
    fn masks_and_selects_on_every_width() {
        masks_and_selects::<f32>();
        masks_and_selects::<F32x8>();
        masks_and_selects::<F32x16>();
    }

    /// `load8` transposes eight fields of the indexed records into lanes, and
    /// `store8` puts them back (records not indexed are left alone).
    fn load_store_round_trip<W: Wide>() {
        const R: usize = 24;
        let recs: Vec<[f32; R]> = (0..40)
            .map(|r| std::array::from_fn(|k| (r * R + k) as f32))
            .collect();
        let idx: Vec<u32> = (0..W::LANES as u32).map(|j| (7 * j + 3) % 40).collect();
        for first in [0, 8, 16] {
            let v = W::load8(&recs, &idx, first);
            for (k, vk) in v.iter().enumerate() {
                for (j, &i) in idx.iter().enumerate() {
                    assert_eq!(vk.lane(j) as f32, recs[i as usize][first + k]);
                }
            }
            let mut out = vec![[-1.0f32; R]; 40];
            W::store8(v, &mut out, &idx, first);
            for (r, rec) in out.iter().enumerate() {
                for k in 0..R {
                    let written = idx.contains(&(r as u32)) && (first..first + 8).contains(&k);
                    let want = if written { recs[r][k] } else { -1.0 };
                    assert_eq!(rec[k], want);
                }
            }
        }
    }

    /// Where `idx` repeats a record, `store8` leaves the lowest lane's values
    /// in it (a partial chunk pads its idle lanes with its last walk's slot,
    /// whose own lane is lower).
    fn store_keeps_the_lowest_lane<W: Wide>() {
        let idx: Vec<u32> = (0..W::LANES as u32).map(|j| j / 3).collect();
        let vals: [W; 8] = std::array::from_fn(|k| W::from_fn(|j| (10 * j + k) as f64));
        let mut out = vec![[0.0f32; 8]; W::LANES];
        W::store8(vals, &mut out, &idx, 0);
        for (r, rec) in out.iter().enumerate() {
            let lowest = idx.iter().position(|&i| i as usize == r);
            for (k, &x) in rec.iter().enumerate() {
                let want = lowest.map_or(0.0, |j| (10 * j + k) as f32);
                assert_eq!(x, want, "record {r} field {k}");
            }
        }
    }

    #[test]
    fn load_store_round_trip_on_every_width() {
        load_store_round_trip::<f32>();
        load_store_round_trip::<F32x8>();
        load_store_round_trip::<F32x16>();
        store_keeps_the_lowest_lane::<F32x8>();
        store_keeps_the_lowest_lane::<F32x16>();
    }
}
