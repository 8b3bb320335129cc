//! The scalar lanes: `f32` (the reference) and `f64` (the accuracy oracle),
//! with `bool` as their mask.

use super::traits::{Lane, LaneBits, LaneMask};

impl LaneMask for bool {
    #[inline]
    fn splat(b: bool) -> Self {
        b
    }
    #[inline]
    fn from_fn(mut f: impl FnMut(usize) -> bool) -> Self {
        f(0)
    }
    #[inline]
    fn any(self) -> bool {
        self
    }
    #[inline]
    fn all(self) -> bool {
        self
    }
    #[inline]
    fn lane(self, _i: usize) -> bool {
        self
    }
}

impl Lane for f32 {
    type Mask = bool;
    const LANES: usize = 1;
    #[inline]
    fn splat(v: f64) -> Self {
        v as f32
    }
    #[inline]
    fn from_fn(mut f: impl FnMut(usize) -> f64) -> Self {
        f(0) as f32
    }
    #[inline]
    fn lane(self, _i: usize) -> f64 {
        self as f64
    }
    #[inline]
    fn sqrt(self) -> Self {
        f32::sqrt(self)
    }
    #[inline]
    fn abs(self) -> Self {
        f32::abs(self)
    }
    #[inline]
    fn min(self, o: Self) -> Self {
        if self < o {
            self
        } else {
            o
        }
    }
    #[inline]
    fn max(self, o: Self) -> Self {
        if self > o {
            self
        } else {
            o
        }
    }
    #[inline]
    fn floor(self) -> Self {
        f32::floor(self)
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
    fn lt(self, o: Self) -> bool {
        self < o
    }
    #[inline]
    fn le(self, o: Self) -> bool {
        self <= o
    }
    #[inline]
    fn gt(self, o: Self) -> bool {
        self > o
    }
    #[inline]
    fn ge(self, o: Self) -> bool {
        self >= o
    }
    #[inline]
    fn eq(self, o: Self) -> bool {
        self == o
    }
    #[inline]
    fn is_finite(self) -> bool {
        f32::is_finite(self)
    }
    #[inline]
    fn select(m: bool, t: Self, f: Self) -> Self {
        if m {
            t
        } else {
            f
        }
    }
}

impl Lane for f64 {
    type Mask = bool;
    const LANES: usize = 1;
    #[inline]
    fn splat(v: f64) -> Self {
        v
    }
    #[inline]
    fn from_fn(mut f: impl FnMut(usize) -> f64) -> Self {
        f(0)
    }
    #[inline]
    fn lane(self, _i: usize) -> f64 {
        self
    }
    #[inline]
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
    #[inline]
    fn abs(self) -> Self {
        f64::abs(self)
    }
    #[inline]
    fn min(self, o: Self) -> Self {
        if self < o {
            self
        } else {
            o
        }
    }
    #[inline]
    fn max(self, o: Self) -> Self {
        if self > o {
            self
        } else {
            o
        }
    }
    #[inline]
    fn floor(self) -> Self {
        f64::floor(self)
    }
    #[inline]
    fn exp(self) -> Self {
        f64::exp(self)
    }
    #[inline]
    fn exp_m1(self) -> Self {
        f64::exp_m1(self)
    }
    #[inline]
    fn ln(self) -> Self {
        f64::ln(self)
    }
    #[inline]
    fn sin_cos_turns(self) -> (Self, Self) {
        (std::f64::consts::TAU * self).sin_cos()
    }
    #[inline]
    fn lt(self, o: Self) -> bool {
        self < o
    }
    #[inline]
    fn le(self, o: Self) -> bool {
        self <= o
    }
    #[inline]
    fn gt(self, o: Self) -> bool {
        self > o
    }
    #[inline]
    fn ge(self, o: Self) -> bool {
        self >= o
    }
    #[inline]
    fn eq(self, o: Self) -> bool {
        self == o
    }
    #[inline]
    fn is_finite(self) -> bool {
        f64::is_finite(self)
    }
    #[inline]
    fn select(m: bool, t: Self, f: Self) -> Self {
        if m {
            t
        } else {
            f
        }
    }
}

impl LaneBits for f32 {
    #[inline]
    fn pow2i(n: Self) -> Self {
        f32::from_bits(((n as i32 + 127) as u32) << 23)
    }
    #[inline]
    fn frexp(self) -> (Self, Self) {
        let b = self.to_bits();
        let e = ((b >> 23) & 0xff) as i32 - 126;
        (f32::from_bits((b & 0x807f_ffff) | 0x3f00_0000), e as f32)
    }
}
