//! An orthonormal frame around a unit vector, branch-free so it runs on lanes.

use crate::lane::{Lane, V3};

/// Tangent, bitangent and normal.
#[derive(Clone, Copy, Debug)]
pub struct Frame<L> {
    /// First tangent.
    pub t: V3<L>,
    /// Second tangent.
    pub b: V3<L>,
    /// The unit vector the frame was built around.
    pub n: V3<L>,
}

impl<L: Lane> Frame<L> {
    /// The frame of Duff et al. (2017), "Building an orthonormal basis,
    /// revisited": continuous except at `n.z = -0`, no division by zero.
    #[inline]
    pub fn around(n: V3<L>) -> Self {
        let s = n.z.sign();
        let a = -L::one() / (s + n.z);
        let b = n.x * n.y * a;
        Frame {
            t: V3::new(L::one() + s * n.x * n.x * a, s * b, -s * n.x),
            b: V3::new(b, s + n.y * n.y * a, -n.y),
            n,
        }
    }
    /// World coordinates to local.
    #[inline]
    pub fn to_local(&self, v: V3<L>) -> V3<L> {
        V3::new(v.dot(self.t), v.dot(self.b), v.dot(self.n))
    }
    /// Local coordinates to world.
    #[inline]
    pub fn to_world(&self, v: V3<L>) -> V3<L> {
        self.t * v.x + self.b * v.y + self.n * v.z
    }
}
