//! A 3-vector of lanes, with glam's method names.

use super::traits::Lane;
use std::ops::{Add, Mul, Neg, Sub};

/// A direction or vector per lane. In strata's frame `z` is the stack normal.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct V3<L> {
    /// x component.
    pub x: L,
    /// y component.
    pub y: L,
    /// z component (along the stack normal).
    pub z: L,
}

impl<L: Lane> V3<L> {
    /// From components.
    #[inline]
    pub fn new(x: L, y: L, z: L) -> Self {
        V3 { x, y, z }
    }
    /// The +z axis.
    #[inline]
    pub fn z_axis() -> Self {
        V3::new(L::zero(), L::zero(), L::one())
    }
    /// Dot product.
    #[inline]
    pub fn dot(self, o: Self) -> L {
        self.x * o.x + self.y * o.y + self.z * o.z
    }
    /// Squared length.
    #[inline]
    pub fn length_squared(self) -> L {
        self.dot(self)
    }
    /// Length.
    #[inline]
    pub fn length(self) -> L {
        self.length_squared().sqrt()
    }
    /// Unit vector; a zero vector (where it occurs in a masked-off lane) maps
    /// to +z rather than NaN.
    #[inline]
    pub fn normalize_or_z(self) -> Self {
        let l2 = self.length_squared();
        let ok = l2.gt(L::zero());
        let inv = L::div_or_zero(L::one(), l2.sqrt(), ok);
        let n = self * inv;
        V3::select(ok, n, V3::z_axis())
    }
    /// `t` where `m` is set, `f` elsewhere.
    #[inline]
    pub fn select(m: L::Mask, t: Self, f: Self) -> Self {
        V3::new(
            L::select(m, t.x, f.x),
            L::select(m, t.y, f.y),
            L::select(m, t.z, f.z),
        )
    }
    /// Mirror reflection of `self` (pointing away from the surface) about the
    /// unit normal `m`: `2 (a·m) m - a`.
    #[inline]
    pub fn reflect(self, m: Self) -> Self {
        m * (L::splat(2.0) * self.dot(m)) - self
    }
    /// Mirror about the xy plane (flip z).
    #[inline]
    pub fn flip_z(self) -> Self {
        V3::new(self.x, self.y, -self.z)
    }
}

impl V3<f32> {
    /// From a glam vector.
    #[inline]
    pub fn from_glam(v: glam::Vec3) -> Self {
        V3::new(v.x, v.y, v.z)
    }
    /// To a glam vector.
    #[inline]
    pub fn to_glam(self) -> glam::Vec3 {
        glam::Vec3::new(self.x, self.y, self.z)
    }
}

impl<L: Lane> Add for V3<L> {
    type Output = Self;
    #[inline]
    fn add(self, o: Self) -> Self {
        V3::new(self.x + o.x, self.y + o.y, self.z + o.z)
    }
}
impl<L: Lane> Sub for V3<L> {
    type Output = Self;
    #[inline]
    fn sub(self, o: Self) -> Self {
        V3::new(self.x - o.x, self.y - o.y, self.z - o.z)
    }
}
impl<L: Lane> Mul<L> for V3<L> {
    type Output = Self;
    #[inline]
    fn mul(self, s: L) -> Self {
        V3::new(self.x * s, self.y * s, self.z * s)
    }
}
impl<L: Lane> Neg for V3<L> {
    type Output = Self;
    #[inline]
    fn neg(self) -> Self {
        V3::new(-self.x, -self.y, -self.z)
    }
}
