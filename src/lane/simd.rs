//! The eight-wide instance of [`Lane`], on `wide::f32x8`.
//!
//! This file and `crate::rng`'s lane generator are the only places that touch
//! `wide`. With `-C target-cpu=x86-64-v3` (or any target with AVX) an `F32x8` is
//! one 256-bit register; on baseline x86-64 `wide` runs it as two SSE halves,
//! with identical results.

use super::{Lane, LaneBits, LaneMask};
use std::ops::{
    Add, AddAssign, BitAnd, BitOr, BitXor, Div, DivAssign, Mul, MulAssign, Neg, Not, Sub, SubAssign,
};
use wide::{f32x8, i32x8, u32x8};

/// Eight f32 lanes.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(transparent)]
pub struct F32x8(pub f32x8);

/// Eight boolean lanes (all bits set or all clear, as `wide` expects).
#[derive(Clone, Copy, Debug)]
#[repr(transparent)]
pub struct M8(pub f32x8);

impl F32x8 {
    /// Lanes as an array.
    #[inline]
    pub fn to_array(self) -> [f32; 8] {
        self.0.to_array()
    }
    /// From an array of lanes.
    #[inline]
    pub fn from_array(a: [f32; 8]) -> Self {
        F32x8(f32x8::from(a))
    }
    /// The raw bits of each lane.
    #[inline]
    pub fn to_bits(self) -> wide::u32x8 {
        self.0.to_bits()
    }
    /// From raw bits per lane.
    #[inline]
    pub fn from_bits(b: wide::u32x8) -> Self {
        F32x8(f32x8::from_bits(b))
    }
}

impl M8 {
    /// One bit per lane, lane 0 in bit 0.
    #[inline]
    pub fn bitmask(self) -> u32 {
        self.0.to_bitmask()
    }
    /// From one bool per lane.
    #[inline]
    pub fn from_bools(b: [bool; 8]) -> Self {
        let t = f32::from_bits(u32::MAX);
        M8(f32x8::from(b.map(|x| if x { t } else { 0.0 })))
    }
}

impl BitAnd for M8 {
    type Output = M8;
    #[inline]
    fn bitand(self, o: M8) -> M8 {
        M8(self.0 & o.0)
    }
}
impl BitOr for M8 {
    type Output = M8;
    #[inline]
    fn bitor(self, o: M8) -> M8 {
        M8(self.0 | o.0)
    }
}
impl BitXor for M8 {
    type Output = M8;
    #[inline]
    fn bitxor(self, o: M8) -> M8 {
        M8(self.0 ^ o.0)
    }
}
impl Not for M8 {
    type Output = M8;
    #[inline]
    fn not(self) -> M8 {
        M8(!self.0)
    }
}

impl LaneMask for M8 {
    #[inline]
    fn splat(b: bool) -> Self {
        M8(f32x8::splat(if b { f32::from_bits(u32::MAX) } else { 0.0 }))
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

macro_rules! binop {
    ($tr:ident, $f:ident, $atr:ident, $af:ident, $op:tt) => {
        impl $tr for F32x8 {
            type Output = F32x8;
            #[inline]
            fn $f(self, o: F32x8) -> F32x8 {
                F32x8(self.0 $op o.0)
            }
        }
        impl $atr for F32x8 {
            #[inline]
            fn $af(&mut self, o: F32x8) {
                self.0 = self.0 $op o.0;
            }
        }
    };
}
binop!(Add, add, AddAssign, add_assign, +);
binop!(Sub, sub, SubAssign, sub_assign, -);
binop!(Mul, mul, MulAssign, mul_assign, *);
binop!(Div, div, DivAssign, div_assign, /);

impl Neg for F32x8 {
    type Output = F32x8;
    #[inline]
    fn neg(self) -> F32x8 {
        F32x8(-self.0)
    }
}

impl Lane for F32x8 {
    type Mask = M8;
    const LANES: usize = 8;
    #[inline]
    fn splat(v: f64) -> Self {
        F32x8(f32x8::splat(v as f32))
    }
    #[inline]
    fn from_fn(mut f: impl FnMut(usize) -> f64) -> Self {
        F32x8(f32x8::from(std::array::from_fn::<f32, 8, _>(|i| {
            f(i) as f32
        })))
    }
    #[inline]
    fn lane(self, i: usize) -> f64 {
        self.0.to_array()[i] as f64
    }
    #[inline]
    fn sqrt(self) -> Self {
        F32x8(self.0.sqrt())
    }
    #[inline]
    fn abs(self) -> Self {
        F32x8(self.0.abs())
    }
    #[inline]
    fn min(self, o: Self) -> Self {
        // `if self < o { self } else { o }`, the scalar instance's definition.
        F32x8(self.0.simd_lt(o.0).select(self.0, o.0))
    }
    #[inline]
    fn max(self, o: Self) -> Self {
        F32x8(self.0.simd_gt(o.0).select(self.0, o.0))
    }
    #[inline]
    fn floor(self) -> Self {
        F32x8(self.0.floor())
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
    fn lt(self, o: Self) -> M8 {
        M8(self.0.simd_lt(o.0))
    }
    #[inline]
    fn le(self, o: Self) -> M8 {
        M8(self.0.simd_le(o.0))
    }
    #[inline]
    fn gt(self, o: Self) -> M8 {
        M8(self.0.simd_gt(o.0))
    }
    #[inline]
    fn ge(self, o: Self) -> M8 {
        M8(self.0.simd_ge(o.0))
    }
    #[inline]
    fn eq(self, o: Self) -> M8 {
        M8(self.0.simd_eq(o.0))
    }
    #[inline]
    fn is_finite(self) -> M8 {
        M8(self.0.is_finite())
    }
    #[inline]
    fn select(m: M8, t: Self, f: Self) -> Self {
        F32x8(m.0.select(t.0, f.0))
    }
}

impl LaneBits for F32x8 {
    #[inline]
    fn pow2i(n: Self) -> Self {
        let i: i32x8 = (n.0 + f32x8::splat(127.0)).round_int();
        let u: u32x8 = wide::bytemuck::cast(i);
        F32x8(f32x8::from_bits(u << 23))
    }
    #[inline]
    fn frexp(self) -> (Self, Self) {
        let b = self.0.to_bits();
        let e: i32x8 = wide::bytemuck::cast((b >> 23) & u32x8::splat(0xff));
        let m = (b & u32x8::splat(0x807f_ffff)) | u32x8::splat(0x3f00_0000);
        (
            F32x8(f32x8::from_bits(m)),
            F32x8(f32x8::from_i32x8(e) - f32x8::splat(126.0)),
        )
    }
}
