//! SGGX microflake phase functions (Heitz, Dupuy, Crassin and Dachsbacher
//! 2015, "The SGGX microflake distribution").
//!
//! A microflake medium is a cloud of tiny mirrors (specular flakes) or tiny
//! Lambertian reflectors (diffuse flakes) whose normals follow the
//! distribution `D(m) = 1 / (π sqrt(det S) (mᵀS⁻¹m)²)` of a symmetric
//! positive matrix `S`. Its extinction along `ω` is the flakes' projected
//! area, `σt sqrt(ωᵀSω)`.
//!
//! strata's flakes are *uniaxial*: `S = across · I + (along − across) a aᵀ`
//! (surface flakes about the normal `a`: along 1, across r²; fibres along
//! `a`: along r², across 1). Everything is written in that eigen form, never
//! from S's six entries: at r = 0.01, det S = 1e-8 is what single precision
//! would be left with after cancelling entries of order 1.
//!
//! Directions are travel directions: a walk along `d` scatters into `u`; in
//! Heitz et al.'s notation `ωi = −d` and `ωo = u`.

use crate::lane::{Lane, V3};
use crate::math::{sample_cosine_hemisphere, Frame};

const INV_PI: f64 = 1.0 / std::f64::consts::PI;

/// A uniaxial SGGX distribution, per lane.
#[derive(Clone, Copy, Debug)]
pub struct Sggx<L: Lane> {
    /// Unit axis `a`.
    pub axis: V3<L>,
    /// Eigenvalue of S along `a`.
    pub along: L,
    /// Eigenvalue of S across `a`.
    pub across: L,
}

impl<L: Lane> Sggx<L> {
    /// Surface flakes of roughness `r` about the unit normal `axis`.
    pub fn surface(axis: [f64; 3], r: f64) -> Self {
        Self::splat(axis, 1.0, r * r)
    }

    /// Fibres of roughness `r` along the unit `axis`.
    pub fn fiber(axis: [f64; 3], r: f64) -> Self {
        Self::splat(axis, r * r, 1.0)
    }

    fn splat(axis: [f64; 3], along: f64, across: f64) -> Self {
        Sggx {
            axis: V3::new(L::splat(axis[0]), L::splat(axis[1]), L::splat(axis[2])),
            along: L::splat(along),
            across: L::splat(across),
        }
    }

    /// `ωᵀ S ω` for a unit `w`, as a sum of non-negative terms.
    #[inline(always)]
    fn quadratic(&self, w: V3<L>) -> L {
        let c = w.dot(self.axis);
        self.along * c * c + self.across * cross_sq(w, self.axis)
    }

    /// The projected area `σ(ω) = sqrt(ωᵀSω)` (even in `ω`): the factor of
    /// the extinction along `ω`.
    #[inline(always)]
    pub fn sigma(&self, w: V3<L>) -> L {
        self.quadratic(w).safe_sqrt()
    }

    /// The microflake normal distribution `D(m)` at a unit `m`.
    #[inline(always)]
    pub fn d(&self, m: V3<L>) -> L {
        let c = m.dot(self.axis);
        let q = c * c / self.along + cross_sq(m, self.axis) / self.across;
        let sqrt_det = self.across * self.along.sqrt();
        let den = L::splat(std::f64::consts::PI) * sqrt_det * q * q;
        L::div_or_zero(L::one(), den, den.gt(L::zero()))
    }

    /// A visible normal for `wi` (unit, `wi · m >= 0`), with density
    /// `max(0, wi · m) D(m) / σ(wi)`, from two uniforms: Heitz et al.'s
    /// construction (a cosine-distributed point mapped by the matrix that
    /// S gives in a frame around `wi`), in the eigen form.
    #[inline(always)]
    pub fn visible_normal(&self, wi: V3<L>, u1: L, u2: L) -> V3<L> {
        let f = Frame::around(wi);
        // The axis in the frame (k, j, i) = (t, b, wi).
        let (bk, bj, bi) = (self.axis.dot(f.t), self.axis.dot(f.b), self.axis.dot(f.n));
        let (c, delta) = (self.across, self.along - self.across);
        let s_ii = self.along * bi * bi + c * (bk * bk + bj * bj);
        let s_ki = delta * bk * bi;
        let s_ji = delta * bj * bi;
        // S_jj S_ii − S_ji² = c (along (bj² + bi²) + c bk²), and
        // S_ki S_ji − S_kj S_ii = −c Δ bk bj: no cancellation left.
        let minor = c * (self.along * (bj * bj + bi * bi) + c * bk * bk);
        let tmp = minor.safe_sqrt();
        let sqrt_det = c * self.along.sqrt();
        let inv_sii = L::div_or_zero(L::one(), s_ii.safe_sqrt(), s_ii.gt(L::zero()));
        let ok = tmp.gt(L::zero());
        let mk = L::div_or_zero(sqrt_det, tmp, ok);
        let mj_k = L::div_or_zero(c * delta * bk * bj * inv_sii, tmp, ok);
        let mj_j = tmp * inv_sii;
        let p = sample_cosine_hemisphere(u1, u2);
        let local = V3::new(
            p.x * mk + p.y * mj_k + p.z * s_ki * inv_sii,
            p.y * mj_j + p.z * s_ji * inv_sii,
            p.z * s_ii * inv_sii,
        );
        let m = f.to_world(local.normalize_or_z());
        // Rounding can leave a normal a hair behind wi: turn it over.
        V3::select(m.dot(wi).lt(L::zero()), -m, m)
    }

    /// Specular flakes: the phase function from `d` into `u`,
    /// `D(h) / (4 σ(d))` with `h` the half vector of `ωi = −d` and `u`
    /// (0 where `u = d`, a direction of measure zero).
    #[inline(always)]
    pub fn specular_eval(&self, d: V3<L>, u: V3<L>) -> L {
        let h = u - d;
        let len2 = h.dot(h);
        let ok = len2.gt(L::zero());
        let h = h * L::div_or_zero(L::one(), len2.sqrt(), ok);
        let s = self.sigma(d);
        let v = L::div_or_zero(self.d(h), L::splat(4.0) * s, ok & s.gt(L::zero()));
        L::select(ok, v, L::zero())
    }

    /// Specular flakes: `u` sampled exactly (weight 1, density
    /// [`Sggx::specular_eval`]): `ωi` mirrored about a visible normal.
    #[inline(always)]
    pub fn specular_sample(&self, d: V3<L>, u1: L, u2: L) -> V3<L> {
        let wi = -d;
        let m = self.visible_normal(wi, u1, u2);
        (m * (L::splat(2.0) * wi.dot(m)) - wi).normalize_or_z()
    }

    /// Diffuse flakes: `u` sampled exactly (weight 1): a visible normal
    /// (`u[0]`, `u[1]`), then a cosine-distributed direction about it.
    #[inline(always)]
    pub fn diffuse_sample(&self, d: V3<L>, u: [L; 4]) -> V3<L> {
        let m = self.visible_normal(-d, u[0], u[1]);
        Frame::around(m).to_world(sample_cosine_hemisphere(u[2], u[3]))
    }

    /// Diffuse flakes: an unbiased one-sample estimate of the phase function
    /// `∫ max(0, u · m) / π · D_ωi(m) dm` from `d` into `u`, drawing `m` as a
    /// visible normal of `ωi = −d` from `(u1, u2)` (it has no closed form).
    #[inline(always)]
    pub fn diffuse_estimate(&self, d: V3<L>, u: V3<L>, u1: L, u2: L) -> L {
        let m = self.visible_normal(-d, u1, u2);
        u.dot(m).max(L::zero()) * L::splat(INV_PI)
    }
}

/// `|w × a|²`: `1 − (w·a)²` for unit vectors, without its cancellation near
/// the axis.
#[inline(always)]
fn cross_sq<L: Lane>(w: V3<L>, a: V3<L>) -> L {
    let x = w.y * a.z - w.z * a.y;
    let y = w.z * a.x - w.x * a.z;
    let z = w.x * a.y - w.y * a.x;
    x * x + y * y + z * z
}
