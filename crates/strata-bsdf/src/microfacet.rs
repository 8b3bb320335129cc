//! Microfacet distributions: GGX (Trowbridge–Reitz) and Beckmann, anisotropic,
//! with Smith shadowing-masking and normal sampling.
//!
//! All functions work in the interface frame (z = macro normal) and take the
//! distribution per lane, so lanes at different interfaces can share one call.
//!
//! * Shadowing: `G = 1 / (1 + Λ(a) + Λ(b))` (height-correlated, the default, as
//!   in pbrt-v4) or `G = G1(a) G1(b)` (separable, as in Mitsuba), chosen per
//!   interface by [`Microfacet::separable`].
//! * Sampling: GGX samples the distribution of visible normals exactly (Heitz
//!   2018), density `D_a(m) = G1(a) max(0, a·m) D(m) / |a.z|`. Beckmann samples
//!   `D(m) cos θm` (Walter et al. 2007), density `D(m) |m.z|`; its visible-normal
//!   sampler has no closed form.
//!
//! Its functions are `#[inline(always)]` (docs/architecture.md, *Code
//! generation is part of the design*).

use crate::lane::{Lane, LaneMask, V3};

/// One microfacet distribution per lane.
#[derive(Clone, Copy, Debug)]
pub struct Microfacet<L: Lane> {
    /// Roughness along x.
    pub alpha_x: L,
    /// Roughness along y.
    pub alpha_y: L,
    /// Lanes using Beckmann (others use GGX).
    pub beckmann: L::Mask,
    /// Lanes using the separable Smith term (others: height-correlated).
    pub separable: L::Mask,
}

impl<L: Lane> Microfacet<L> {
    /// Isotropic GGX with height-correlated shadowing.
    pub fn ggx(alpha: L) -> Self {
        Microfacet {
            alpha_x: alpha,
            alpha_y: alpha,
            beckmann: L::Mask::splat(false),
            separable: L::Mask::splat(false),
        }
    }

    /// `α sinθ` in the direction's azimuth, `sqrt(αx² wx² + αy² wy²)`, and
    /// `sqrt(wz² + (α sinθ)²)`. Shadowing is written with these two lengths
    /// so that nothing divides by `wz`: `α² tan²θ = (α sinθ / wz)²` overflows
    /// single precision near the horizon, and a floor on `wz²` (the former
    /// formulation) made `G` stop falling with `cos θ` below 1e-15, so that
    /// `f = D G F / (4 cos θi cos θo)` grew without bound there.
    #[inline(always)]
    fn lengths(&self, w: V3<L>) -> (L, L) {
        let s2 = self.alpha_x.sqr() * w.x.sqr() + self.alpha_y.sqr() * w.y.sqr();
        (s2.sqrt(), (w.z.sqr() + s2).sqrt())
    }

    /// Walter et al.'s rational fit of Beckmann's Λ in `a = 1 / (α tanθ)`, as
    /// a fraction `(num, den)` with `Λ = num / den`: `den` is 0 at the horizon
    /// (where Λ is infinite), and beyond `a = 1.6` the fit is `(0, 1)`. Kept as
    /// a fraction so that `G1 = den / (den + num)` and `G` never go through an
    /// infinity.
    #[inline(always)]
    fn lambda_beckmann(&self, w: V3<L>) -> (L, L) {
        let (s, _) = self.lengths(w);
        let c = w.z.abs();
        // a = c / s, finite (c <= 1): a direction with s = 0 has no shadowing.
        let a = c / s.max(L::splat(1e-30));
        let small = a.lt(L::splat(1.6));
        let af = a.min(L::splat(1.6));
        let num = L::one() - L::splat(1.259) * af + L::splat(0.396) * af * af;
        let den = L::splat(3.535) * af + L::splat(2.181) * af * af;
        (
            L::select(small, num, L::zero()),
            L::select(small, den, L::one()),
        )
    }

    /// Beckmann `G1 = 1 / (1 + Λ) = den / (den + num)`.
    #[inline(always)]
    fn g1_beckmann(&self, w: V3<L>) -> L {
        let (n, d) = self.lambda_beckmann(w);
        L::div_or_zero(d, d + n, (d + n).gt(L::zero()))
    }

    /// The normal distribution D(m) (zero below the macro surface).
    #[inline(always)]
    pub fn d(&self, m: V3<L>) -> L {
        let up = m.z.gt(L::zero());
        let ax = self.alpha_x;
        let ay = self.alpha_y;
        let inv_pi_axay = L::one() / (L::splat(std::f64::consts::PI) * ax * ay);
        // GGX: 1 / (π αx αy (mx²/αx² + my²/αy² + mz²)²), with no division by mz.
        let q = m.x.sqr() / ax.sqr() + m.y.sqr() / ay.sqr();
        let ggx = inv_pi_axay / (q + m.z.sqr()).sqr();
        let d = if self.beckmann.any() {
            let mz2 = m.z.sqr().max(L::splat(1e-15));
            let e = q / mz2;
            let beck = L::select(
                e.lt(L::splat(80.0)),
                inv_pi_axay / (mz2 * mz2) * (-e).exp(),
                L::zero(),
            );
            L::select(self.beckmann, beck, ggx)
        } else {
            ggx
        };
        L::select(up, d, L::zero())
    }

    /// Smith's Λ(w); at the horizon (`w.z = 0`), where it is infinite, the
    /// largest finite number (no lane ever holds an infinity).
    /// GGX: `(sqrt(1 + α² tan²θ) - 1) / 2`, written `(αs)² / (2c (S + c))`
    /// with `c = |w.z|`, `S = sqrt(c² + (αs)²)`: no cancellation for small
    /// `α tanθ`. [`Microfacet::g1`] and [`Microfacet::g`] do not go through Λ.
    #[inline(always)]
    pub fn lambda(&self, w: V3<L>) -> L {
        let (s, root) = self.lengths(w);
        let c = w.z.abs();
        let ok = c.gt(L::zero());
        let horizon = L::select(s.gt(L::zero()), L::splat(f32::MAX as f64), L::zero());
        let ggx = L::select(
            ok,
            L::div_or_zero(s * s, L::splat(2.0) * c * (root + c), ok),
            horizon,
        );
        if self.beckmann.any() {
            let (n, d) = self.lambda_beckmann(w);
            let beck = L::select(
                d.gt(L::zero()),
                L::div_or_zero(n, d, d.gt(L::zero())),
                L::splat(f32::MAX as f64),
            );
            L::select(self.beckmann, beck, ggx)
        } else {
            ggx
        }
    }

    /// Masking `G1(w) = 1 / (1 + Λ(w))`; for GGX `2c / (c + S)` (see
    /// [`Microfacet::lambda`]), which goes to 0 with `c` instead of dividing by it.
    #[inline(always)]
    pub fn g1(&self, w: V3<L>) -> L {
        let (_, root) = self.lengths(w);
        let c = w.z.abs();
        let den = c + root;
        let ggx = L::div_or_zero(L::splat(2.0) * c, den, den.gt(L::zero()));
        if self.beckmann.any() {
            L::select(self.beckmann, self.g1_beckmann(w), ggx)
        } else {
            ggx
        }
    }

    /// Shadowing-masking for the pair (a, b). GGX height-correlated:
    /// `1 / (1 + Λ(a) + Λ(b)) = 2 ca cb / (cb Sa + ca Sb)`; separable:
    /// `G1(a) G1(b)`.
    #[inline(always)]
    pub fn g(&self, a: V3<L>, b: V3<L>) -> L {
        let two = L::splat(2.0);
        let (_, ra) = self.lengths(a);
        let (_, rb) = self.lengths(b);
        let (ca, cb) = (a.z.abs(), b.z.abs());
        let den = cb * ra + ca * rb;
        let corr = L::div_or_zero(two * ca * cb, den, den.gt(L::zero()));
        let ggx = if self.separable.any() {
            let sep = L::div_or_zero(two * ca, ca + ra, (ca + ra).gt(L::zero()))
                * L::div_or_zero(two * cb, cb + rb, (cb + rb).gt(L::zero()));
            L::select(self.separable, sep, corr)
        } else {
            corr
        };
        if self.beckmann.any() {
            // 1 / (1 + na/da + nb/db) = da db / (da db + na db + nb da).
            let (na, da) = self.lambda_beckmann(a);
            let (nb, db) = self.lambda_beckmann(b);
            let dd = da * db;
            let den = dd + na * db + nb * da;
            let bc = L::div_or_zero(dd, den, den.gt(L::zero()));
            let bs = self.g1_beckmann(a) * self.g1_beckmann(b);
            L::select(self.beckmann, L::select(self.separable, bs, bc), ggx)
        } else {
            ggx
        }
    }

    /// `G(a, b) / G1(a)`, the weight of visible-normal sampling from `a`,
    /// without dividing two small numbers: for GGX height-correlated
    /// `cb (ca + Sa) / (cb Sa + ca Sb)`, separable `G1(b)`.
    #[inline(always)]
    pub fn g_over_g1(&self, a: V3<L>, b: V3<L>) -> L {
        let two = L::splat(2.0);
        let (_, ra) = self.lengths(a);
        let (_, rb) = self.lengths(b);
        let (ca, cb) = (a.z.abs(), b.z.abs());
        let den = cb * ra + ca * rb;
        let corr = L::div_or_zero(cb * (ca + ra), den, den.gt(L::zero()));
        let ggx = if self.separable.any() {
            let g1b = L::div_or_zero(two * cb, cb + rb, (cb + rb).gt(L::zero()));
            L::select(self.separable, g1b, corr)
        } else {
            corr
        };
        if self.beckmann.any() {
            let g1a = self.g1(a);
            let beck = L::div_or_zero(self.g(a, b), g1a, g1a.gt(L::zero()));
            L::select(self.beckmann, beck, ggx)
        } else {
            ggx
        }
    }

    /// Samples a microfacet normal (on the +z side) as seen from `w`, which may
    /// lie on either side. See the module docs for the densities.
    #[inline(always)]
    pub fn sample(&self, w: V3<L>, u1: L, u2: L) -> V3<L> {
        let w = V3::select(w.z.lt(L::zero()), -w, w);
        let ggx = self.sample_ggx_visible(w, u1, u2);
        if self.beckmann.any() {
            V3::select(self.beckmann, self.sample_beckmann(u1, u2), ggx)
        } else {
            ggx
        }
    }

    /// The density of [`Microfacet::sample`] producing `m`, seen from `w`.
    #[inline(always)]
    pub fn pdf(&self, w: V3<L>, m: V3<L>) -> L {
        self.pdf_of(w, m, self.d(m))
    }

    /// [`Microfacet::pdf`] from `d = D(m)`, for a caller that has it.
    #[inline(always)]
    pub fn pdf_of(&self, w: V3<L>, m: V3<L>, d: L) -> L {
        let wz = w.z.abs();
        let wm = w.dot(m) * w.z.sign();
        // G1(w) / |w.z| = 2 / (c + S): no division by w.z.
        let (_, root) = self.lengths(w);
        let ok = wz.gt(L::zero()) & wm.gt(L::zero());
        let visible = L::div_or_zero(L::splat(2.0) * wm * d, wz + root, ok);
        if self.beckmann.any() {
            L::select(self.beckmann, d * m.z.max(L::zero()), visible)
        } else {
            visible
        }
    }

    /// Heitz (2018), "Sampling the GGX distribution of visible normals".
    #[inline(always)]
    fn sample_ggx_visible(&self, w: V3<L>, u1: L, u2: L) -> V3<L> {
        let ax = self.alpha_x;
        let ay = self.alpha_y;
        let vh = V3::new(ax * w.x, ay * w.y, w.z).normalize_or_z();
        let len2 = vh.x * vh.x + vh.y * vh.y;
        let has = len2.gt(L::zero());
        let inv = L::div_or_zero(L::one(), len2.sqrt(), has);
        let t1 = V3::select(
            has,
            V3::new(-vh.y * inv, vh.x * inv, L::zero()),
            V3::new(L::one(), L::zero(), L::zero()),
        );
        // t2 = vh × t1
        let t2 = V3::new(
            vh.y * t1.z - vh.z * t1.y,
            vh.z * t1.x - vh.x * t1.z,
            vh.x * t1.y - vh.y * t1.x,
        );
        let r = u1.sqrt();
        let (sp, cp) = u2.sin_cos_turns();
        let p1 = r * cp;
        let p2 = r * sp;
        let s = L::splat(0.5) * (L::one() + vh.z);
        let p2 = (L::one() - s) * (L::one() - p1 * p1).safe_sqrt() + s * p2;
        let pz = (L::one() - p1 * p1 - p2 * p2).safe_sqrt();
        let nh = t1 * p1 + t2 * p2 + vh * pz;
        V3::new(ax * nh.x, ay * nh.y, nh.z.max(L::splat(1e-7))).normalize_or_z()
    }

    /// Beckmann normals with density D(m) cos θm: Gaussian slopes by Box–Muller.
    #[inline(always)]
    fn sample_beckmann(&self, u1: L, u2: L) -> V3<L> {
        let r = (-(L::one() - u1).ln()).safe_sqrt();
        let (s, c) = u2.sin_cos_turns();
        let sx = self.alpha_x * r * c;
        let sy = self.alpha_y * r * s;
        V3::new(-sx, -sy, L::one()).normalize_or_z()
    }
}
