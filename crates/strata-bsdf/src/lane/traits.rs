//! What a lane is: [`LaneMask`] (a boolean per lane), [`Lane`] (a number
//! per lane) and [`LaneBits`] (the bit-level operations of the shared
//! single-precision functions).

use std::fmt::Debug;
use std::ops::{
    Add, AddAssign, BitAnd, BitOr, BitXor, Div, DivAssign, Mul, MulAssign, Neg, Not, Sub, SubAssign,
};

/// A boolean per lane.
pub trait LaneMask:
    Copy
    + Debug
    + Send
    + Sync
    + BitAnd<Output = Self>
    + BitOr<Output = Self>
    + BitXor<Output = Self>
    + Not<Output = Self>
{
    /// The same value in every lane.
    fn splat(b: bool) -> Self;
    /// Builds a mask lane by lane.
    fn from_fn(f: impl FnMut(usize) -> bool) -> Self;
    /// True if any lane is set.
    fn any(self) -> bool;
    /// True if every lane is set.
    fn all(self) -> bool;
    /// True if no lane is set.
    #[inline]
    fn none(self) -> bool {
        !self.any()
    }
    /// Lane `i` as a bool.
    fn lane(self, i: usize) -> bool;
}

/// A number per lane: `f32`, `f64` or [`F32x8`](super::F32x8).
pub trait Lane:
    Copy
    + Debug
    + Default
    + Send
    + Sync
    + 'static
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
    + MulAssign
    + DivAssign
{
    /// The mask type comparisons produce.
    type Mask: LaneMask;
    /// Number of lanes.
    const LANES: usize;

    /// The same value in every lane (constants are written in f64 so the f64
    /// instance keeps their full precision).
    fn splat(v: f64) -> Self;
    /// Builds a value lane by lane.
    fn from_fn(f: impl FnMut(usize) -> f64) -> Self;
    /// Lane `i` as f64.
    fn lane(self, i: usize) -> f64;

    /// Square root (exact IEEE rounding in every instance).
    fn sqrt(self) -> Self;
    /// Absolute value.
    fn abs(self) -> Self;
    /// `if self < o { self } else { o }`, lane by lane.
    fn min(self, o: Self) -> Self;
    /// `if self > o { self } else { o }`, lane by lane.
    fn max(self, o: Self) -> Self;
    /// Largest integer not greater than `self`.
    fn floor(self) -> Self;
    /// e^x. Underflows to 0; never NaN for finite or infinite input.
    fn exp(self) -> Self;
    /// e^x - 1, accurate for small |x| (no cancellation).
    fn exp_m1(self) -> Self;
    /// Natural logarithm (of a positive input).
    fn ln(self) -> Self;
    /// `(sin 2πx, cos 2πx)` for `x` in turns (used for azimuths `φ = 2πu`).
    fn sin_cos_turns(self) -> (Self, Self);

    /// `self < o`.
    fn lt(self, o: Self) -> Self::Mask;
    /// `self <= o`.
    fn le(self, o: Self) -> Self::Mask;
    /// `self > o`.
    fn gt(self, o: Self) -> Self::Mask;
    /// `self >= o`.
    fn ge(self, o: Self) -> Self::Mask;
    /// `self == o`.
    fn eq(self, o: Self) -> Self::Mask;
    /// Finite (neither NaN nor infinite).
    fn is_finite(self) -> Self::Mask;
    /// `t` where `m` is set, `f` elsewhere.
    fn select(m: Self::Mask, t: Self, f: Self) -> Self;

    /// Zero in every lane.
    #[inline]
    fn zero() -> Self {
        Self::splat(0.0)
    }
    /// One in every lane.
    #[inline]
    fn one() -> Self {
        Self::splat(1.0)
    }
    /// `x * x`.
    #[inline]
    fn sqr(self) -> Self {
        self * self
    }
    /// `sqrt(max(x, 0))`: the square root of a quantity that is non-negative
    /// in exact arithmetic but may round slightly below zero.
    #[inline]
    fn safe_sqrt(self) -> Self {
        self.max(Self::zero()).sqrt()
    }
    /// Clamps to `[lo, hi]`.
    #[inline]
    fn clamp(self, lo: Self, hi: Self) -> Self {
        self.max(lo).min(hi)
    }
    /// `+1` where `self >= 0` (including +0), `-1` elsewhere.
    #[inline]
    fn sign(self) -> Self {
        Self::select(self.ge(Self::zero()), Self::one(), -Self::one())
    }
    /// `a / b` where `m` is set and `b` may be zero or tiny elsewhere: lanes
    /// outside `m` divide by one and return 0.
    #[inline]
    fn div_or_zero(a: Self, b: Self, m: Self::Mask) -> Self {
        Self::select(m, a / Self::select(m, b, Self::one()), Self::zero())
    }
}

/// The two bit-level operations the shared single-precision `exp` and `ln`
/// need. Implemented by `f32` and [`F32x8`](super::F32x8) only.
pub trait LaneBits: Lane {
    /// `2^n` for integer-valued `n` in `[-126, 127]`.
    fn pow2i(n: Self) -> Self;
    /// `(m, e)` with `self = m * 2^e`, `m` in `[0.5, 1)`, for positive normal input.
    fn frexp(self) -> (Self, Self);
}
