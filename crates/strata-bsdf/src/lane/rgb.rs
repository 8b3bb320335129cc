//! An RGB triple of lanes: throughputs, Fresnel terms, extinction.

use super::traits::Lane;
use std::ops::{Add, AddAssign, Mul, MulAssign, Sub};

/// One value per colour channel, per lane.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Rgb<L> {
    /// Red.
    pub r: L,
    /// Green.
    pub g: L,
    /// Blue.
    pub b: L,
}

impl<L: Lane> Rgb<L> {
    /// From channels.
    #[inline]
    pub fn new(r: L, g: L, b: L) -> Self {
        Rgb { r, g, b }
    }
    /// The same value in all three channels.
    #[inline]
    pub fn splat(v: L) -> Self {
        Rgb::new(v, v, v)
    }
    /// Black.
    #[inline]
    pub fn zero() -> Self {
        Rgb::splat(L::zero())
    }
    /// White.
    #[inline]
    pub fn one() -> Self {
        Rgb::splat(L::one())
    }
    /// From three f64 constants (a material parameter).
    #[inline]
    pub fn from_array(a: [f64; 3]) -> Self {
        Rgb::new(L::splat(a[0]), L::splat(a[1]), L::splat(a[2]))
    }
    /// Applies `f` to each channel.
    #[inline]
    pub fn map(self, mut f: impl FnMut(L) -> L) -> Self {
        Rgb::new(f(self.r), f(self.g), f(self.b))
    }
    /// Combines two triples channel by channel.
    #[inline]
    pub fn zip(self, o: Self, mut f: impl FnMut(L, L) -> L) -> Self {
        Rgb::new(f(self.r, o.r), f(self.g, o.g), f(self.b, o.b))
    }
    /// Largest channel.
    #[inline]
    pub fn max_channel(self) -> L {
        self.r.max(self.g).max(self.b)
    }
    /// Mean of the channels.
    #[inline]
    pub fn average(self) -> L {
        (self.r + self.g + self.b) * L::splat(1.0 / 3.0)
    }
    /// Channel `c` (0, 1 or 2).
    #[inline]
    pub fn channel(self, c: usize) -> L {
        match c {
            0 => self.r,
            1 => self.g,
            _ => self.b,
        }
    }
    /// `t` where `m` is set, `f` elsewhere.
    #[inline]
    pub fn select(m: L::Mask, t: Self, f: Self) -> Self {
        Rgb::new(
            L::select(m, t.r, f.r),
            L::select(m, t.g, f.g),
            L::select(m, t.b, f.b),
        )
    }
    /// Multiplies every channel by a scalar lane.
    #[inline]
    pub fn scale(self, s: L) -> Self {
        self.map(|c| c * s)
    }
}

impl Rgb<f32> {
    /// As an array.
    #[inline]
    pub fn to_array(self) -> [f32; 3] {
        [self.r, self.g, self.b]
    }
}

impl<L: Lane> Add for Rgb<L> {
    type Output = Self;
    #[inline]
    fn add(self, o: Self) -> Self {
        self.zip(o, |a, b| a + b)
    }
}
impl<L: Lane> AddAssign for Rgb<L> {
    #[inline]
    fn add_assign(&mut self, o: Self) {
        *self = *self + o;
    }
}
impl<L: Lane> Sub for Rgb<L> {
    type Output = Self;
    #[inline]
    fn sub(self, o: Self) -> Self {
        self.zip(o, |a, b| a - b)
    }
}
impl<L: Lane> Mul for Rgb<L> {
    type Output = Self;
    #[inline]
    fn mul(self, o: Self) -> Self {
        self.zip(o, |a, b| a * b)
    }
}
impl<L: Lane> MulAssign for Rgb<L> {
    #[inline]
    fn mul_assign(&mut self, o: Self) {
        *self = *self * o;
    }
}
impl<L: Lane> Mul<L> for Rgb<L> {
    type Output = Self;
    #[inline]
    fn mul(self, s: L) -> Self {
        self.scale(s)
    }
}
