//! Interface BSDFs: dielectric, conductor and diffuse, rough or smooth.
//!
//! Conventions (see `docs/conventions.md`): directions are in the interface's
//! frame, z up, and both point *away* from the interface. `a` is the direction
//! the light arrives from, `b` the direction it leaves along, so `eval(a, b)` is
//! the radiance BSDF for light flowing `a → b` (for refraction it carries the
//! `(n_b / n_a)²` factor of radiance transport, Walter et al. 2007, eq. 21).
//!
//! Sampling is from the light's side: given `a`, draw `b` with density
//! `pdf(a, b)` and weight `f(a → b) |b.z| / pdf`. In this flow the radiance
//! factor cancels against the solid-angle compression, so a smooth refraction
//! has weight `1 - F`.
//!
//! Every function takes the interface per lane ([`InterfaceLanes`]), so a
//! wavefront of walks sitting at different interfaces is served by one call;
//! each kind's code runs only if some lane needs it.

use crate::fresnel;
use crate::lane::{Lane, LaneMask, Rgb, V3};
use crate::math::{sample_cosine_hemisphere, Frame, MIN_COS};
use crate::microfacet::Microfacet;

/// One interface per lane.
#[derive(Clone, Copy, Debug)]
pub struct InterfaceLanes<L: Lane> {
    /// IOR of the region above.
    pub n_above: L,
    /// IOR of the region below (dielectrics only).
    pub n_below: L,
    /// Microfacet distribution (ignored where `smooth`).
    pub mf: Microfacet<L>,
    /// Smooth lanes: delta lobes, never evaluated.
    pub smooth: L::Mask,
    /// Dielectric lanes.
    pub dielectric: L::Mask,
    /// Conductor lanes.
    pub conductor: L::Mask,
    /// Lambertian lanes.
    pub diffuse: L::Mask,
    /// Conductor IOR, real part, relative to the region above.
    pub eta: Rgb<L>,
    /// Conductor IOR, imaginary part, relative to the region above.
    pub k: Rgb<L>,
    /// Lambertian albedo.
    pub albedo: Rgb<L>,
    /// Shading normal, in the slab's frame (z where untilted).
    pub normal: V3<L>,
    /// Some lane's normal is tilted: the frame change runs. Off, the
    /// interface runs exactly the untilted code.
    pub tilted: bool,
    /// The lanes answer for the adjoint of a tilted interface (the flow of
    /// importance): `eval` and `sample`'s weight carry Veach's factor
    /// (method.md §9; the η² of refraction stays with the transport mode).
    /// No effect where untilted.
    pub adjoint: bool,
    /// Run every code path whatever the lanes need: the unspecialized walk
    /// that benchmarks compare against. Results are identical, only slower.
    /// (Normally a kind's code runs only if some lane is of that kind, and
    /// microfacet code only if some lane is rough.)
    pub run_all: bool,
}

impl InterfaceLanes<f64> {
    /// This interface on every lane of `L`: the lanes
    /// `LayerStack::interface_lanes::<L>` makes of it, bit for bit (both
    /// splat the same numbers).
    pub fn splat<L: Lane>(&self) -> InterfaceLanes<L> {
        let m = L::Mask::splat;
        InterfaceLanes {
            n_above: L::splat(self.n_above),
            n_below: L::splat(self.n_below),
            mf: Microfacet {
                alpha_x: L::splat(self.mf.alpha_x),
                alpha_y: L::splat(self.mf.alpha_y),
                beckmann: m(self.mf.beckmann),
                separable: m(self.mf.separable),
            },
            smooth: m(self.smooth),
            dielectric: m(self.dielectric),
            conductor: m(self.conductor),
            diffuse: m(self.diffuse),
            eta: Rgb::from_array([self.eta.r, self.eta.g, self.eta.b]),
            k: Rgb::from_array([self.k.r, self.k.g, self.k.b]),
            albedo: Rgb::from_array([self.albedo.r, self.albedo.g, self.albedo.b]),
            normal: V3::new(
                L::splat(self.normal.x),
                L::splat(self.normal.y),
                L::splat(self.normal.z),
            ),
            tilted: self.tilted,
            adjoint: self.adjoint,
            run_all: self.run_all,
        }
    }
}

/// The result of sampling an interface.
#[derive(Clone, Copy, Debug)]
pub struct BsdfSample<L: Lane> {
    /// The outgoing direction (pointing away from the interface).
    pub b: V3<L>,
    /// `f(a → b) |b.z| / pdf`; for a delta lobe, the discrete weight.
    pub weight: Rgb<L>,
    /// Solid-angle density of `b` (0 for a delta lobe).
    pub pdf: L,
    /// Lanes where a direction was produced (false: absorbed or impossible).
    pub valid: L::Mask,
    /// Lanes whose sample came from a delta lobe.
    pub delta: L::Mask,
}

impl<L: Lane> InterfaceLanes<L> {
    /// Lane `j` takes the interface `table[index(j)]` (whose entries are
    /// one-lane values): for walks whose lanes sit at different interfaces.
    pub fn gather<T: Lane>(table: &[InterfaceLanes<T>], index: impl Fn(usize) -> usize) -> Self {
        let v = |f: &dyn Fn(&InterfaceLanes<T>) -> T| L::from_fn(|j| f(&table[index(j)]).lane(0));
        let m = |f: &dyn Fn(&InterfaceLanes<T>) -> T::Mask| {
            L::Mask::from_fn(|j| f(&table[index(j)]).lane(0))
        };
        let rgb = |f: &dyn Fn(&InterfaceLanes<T>) -> Rgb<T>| {
            Rgb::new(v(&|t| f(t).r), v(&|t| f(t).g), v(&|t| f(t).b))
        };
        InterfaceLanes {
            n_above: v(&|t| t.n_above),
            n_below: v(&|t| t.n_below),
            mf: Microfacet {
                alpha_x: v(&|t| t.mf.alpha_x),
                alpha_y: v(&|t| t.mf.alpha_y),
                beckmann: m(&|t| t.mf.beckmann),
                separable: m(&|t| t.mf.separable),
            },
            smooth: m(&|t| t.smooth),
            dielectric: m(&|t| t.dielectric),
            conductor: m(&|t| t.conductor),
            diffuse: m(&|t| t.diffuse),
            eta: rgb(&|t| t.eta),
            k: rgb(&|t| t.k),
            albedo: rgb(&|t| t.albedo),
            normal: V3::new(v(&|t| t.normal.x), v(&|t| t.normal.y), v(&|t| t.normal.z)),
            tilted: table.iter().any(|t| t.tilted),
            adjoint: table.iter().any(|t| t.adjoint),
            run_all: table.iter().any(|t| t.run_all),
        }
    }

    /// Lane by lane, `a` where `m` is set and `b` elsewhere.
    pub fn select(m: L::Mask, a: &Self, b: &Self) -> Self {
        let v = |x: L, y: L| L::select(m, x, y);
        let mk = |x: L::Mask, y: L::Mask| (m & x) | (!m & y);
        let rgb = |x: Rgb<L>, y: Rgb<L>| Rgb::select(m, x, y);
        InterfaceLanes {
            n_above: v(a.n_above, b.n_above),
            n_below: v(a.n_below, b.n_below),
            mf: Microfacet {
                alpha_x: v(a.mf.alpha_x, b.mf.alpha_x),
                alpha_y: v(a.mf.alpha_y, b.mf.alpha_y),
                beckmann: mk(a.mf.beckmann, b.mf.beckmann),
                separable: mk(a.mf.separable, b.mf.separable),
            },
            smooth: mk(a.smooth, b.smooth),
            dielectric: mk(a.dielectric, b.dielectric),
            conductor: mk(a.conductor, b.conductor),
            diffuse: mk(a.diffuse, b.diffuse),
            eta: rgb(a.eta, b.eta),
            k: rgb(a.k, b.k),
            albedo: rgb(a.albedo, b.albedo),
            normal: V3::select(m, a.normal, b.normal),
            tilted: a.tilted || b.tilted,
            adjoint: a.adjoint || b.adjoint,
            run_all: a.run_all || b.run_all,
        }
    }

    /// `(n_a, n_b)`: the IORs on the side of `a` and on the other side.
    #[inline]
    pub fn sides(&self, a: V3<L>) -> (L, L) {
        let above = a.z.gt(L::zero());
        (
            L::select(above, self.n_above, self.n_below),
            L::select(above, self.n_below, self.n_above),
        )
    }

    /// `n_below / n_above`, the relative IOR the Fresnel term takes.
    #[inline]
    fn eta(&self) -> L {
        self.n_below / self.n_above
    }

    /// The shading frame; the lanes whose normal is the slab's (`flat`),
    /// which take their directions as they are, so that they compute
    /// exactly what an untilted interface computes.
    #[inline]
    fn shading(&self) -> (Frame<L>, L::Mask) {
        let zero = L::zero();
        let flat = self.normal.x.eq(zero) & self.normal.y.eq(zero);
        (Frame::around(self.normal), flat)
    }

    /// `d` in the shading frame, and the lanes where it lies on the same
    /// side of the shading normal as of the slab's (the others carry no
    /// light: method.md §9). A direction closer to the shading horizon than
    /// the engines' grazing limit counts as beyond it, as at the slab's
    /// horizon: the kernels multiply cosines, which must stay normal numbers.
    #[inline]
    fn to_shading(f: &Frame<L>, flat: L::Mask, d: V3<L>) -> (V3<L>, L::Mask) {
        let dl = V3::select(flat, d, f.to_local(d));
        let open = (dl.z * d.z).gt(L::zero()) & dl.z.abs().ge(L::splat(MIN_COS));
        (dl, flat | open)
    }

    /// Samples `b` given `a`. `transmit_only` lanes sample the refraction lobe
    /// alone (used to enter a stack and for next-event estimation); their
    /// weight then includes the `1 - F` the selection would have removed.
    ///
    /// A tilted interface samples in its shading frame; a lane whose `a` or
    /// `b` lies on the other side of the shading normal than of the slab's
    /// normal produces nothing (method.md §9). The weight is the shading
    /// frame's `f |b'.z| / pdf`.
    #[inline(always)]
    pub fn sample(
        &self,
        a: V3<L>,
        u_select: L,
        u1: L,
        u2: L,
        transmit_only: L::Mask,
    ) -> BsdfSample<L> {
        if !self.tilted {
            return self.sample_local(a, u_select, u1, u2, transmit_only);
        }
        self.sample_tilted(a, u_select, u1, u2, transmit_only)
    }

    /// [`InterfaceLanes::sample`] of a tilted interface, out of line (the
    /// untilted walks then inline one copy of the kernel, not two).
    #[inline(never)]
    fn sample_tilted(
        &self,
        a: V3<L>,
        u_select: L,
        u1: L,
        u2: L,
        transmit_only: L::Mask,
    ) -> BsdfSample<L> {
        let (f, flat) = self.shading();
        let (al, front) = Self::to_shading(&f, flat, a);
        let s = self.sample_local(al, u_select, u1, u2, transmit_only);
        let b = V3::select(flat, s.b, f.to_world(s.b));
        let agree = flat | ((s.b.z * b.z).gt(L::zero()) & b.z.abs().ge(L::splat(MIN_COS)));
        let valid = s.valid & front & agree;
        let weight = if self.adjoint {
            s.weight.scale(self.veach(a, b))
        } else {
            s.weight
        };
        BsdfSample {
            b,
            weight: Rgb::select(front & agree, weight, Rgb::zero()),
            valid,
            ..s
        }
    }

    /// The radiance BSDF `f(a → b)` without the cosine, delta lobes excluded.
    /// A tilted interface's is its shading frame's `f(a' → b') |b'.z| /
    /// |b.z|` (so that `f |b.z|` is the shading frame's `f |b'.z|`), 0 where
    /// `a` or `b` lies on the other side of the shading normal.
    #[inline(always)]
    pub fn eval(&self, a: V3<L>, b: V3<L>) -> Rgb<L> {
        self.kernels::<true, false>(a, b, L::Mask::splat(false)).0
    }

    /// The density with which [`InterfaceLanes::sample`] (from `a`, with the
    /// same `transmit_only` mask) produces `b`; 0 for delta lobes.
    #[inline(always)]
    pub fn pdf(&self, a: V3<L>, b: V3<L>, transmit_only: L::Mask) -> L {
        self.kernels::<false, true>(a, b, transmit_only).1
    }

    /// [`InterfaceLanes::eval`] and [`InterfaceLanes::pdf`] (sampled from
    /// `a` with both lobes) of one pair, for less than the two apart.
    #[inline(always)]
    pub fn eval_pdf(&self, a: V3<L>, b: V3<L>) -> (Rgb<L>, L) {
        self.kernels::<true, true>(a, b, L::Mask::splat(false))
    }

    /// `eval` (if `EVAL`) and `pdf` (if `PDF`) of the pair; 0 for what is
    /// not asked.
    #[inline(always)]
    fn kernels<const EVAL: bool, const PDF: bool>(
        &self,
        a: V3<L>,
        b: V3<L>,
        transmit_only: L::Mask,
    ) -> (Rgb<L>, L) {
        if !self.tilted {
            return self.local::<EVAL, PDF>(a, b, transmit_only);
        }
        self.tilted::<EVAL, PDF>(a, b, transmit_only)
    }

    /// [`InterfaceLanes::kernels`] of a tilted interface, out of line (the
    /// untilted walks then inline one copy of each kernel, not two).
    #[inline(never)]
    fn tilted<const EVAL: bool, const PDF: bool>(
        &self,
        a: V3<L>,
        b: V3<L>,
        transmit_only: L::Mask,
    ) -> (Rgb<L>, L) {
        let (f, flat) = self.shading();
        let (al, front) = Self::to_shading(&f, flat, a);
        let (bl, agree) = Self::to_shading(&f, flat, b);
        let ok = front & agree;
        let (v, p) = self.local::<EVAL, PDF>(al, bl, transmit_only);
        let v = if EVAL {
            let c = L::div_or_zero(bl.z.abs(), b.z.abs(), ok & b.z.abs().gt(L::zero()));
            let c = if self.adjoint {
                c * self.veach(a, b)
            } else {
                c
            };
            let c = L::select(flat, L::one(), c);
            Rgb::select(ok, v.scale(c), Rgb::zero())
        } else {
            v
        };
        (v, L::select(ok, p, L::zero()))
    }

    /// `f(b → a) / f(a → b)` of these lanes, without the η² of refraction:
    /// what turns a sample drawn from `a` (the side light *leaves* by) into
    /// one of light arriving from `b`. Next-event chains, which sample
    /// interfaces from the far side of the flow, apply it; 1 where untilted
    /// (a tilted interface is not reciprocal: method.md §9).
    #[inline]
    pub fn reverse(&self, a: V3<L>, b: V3<L>) -> L {
        if !self.tilted {
            return L::one();
        }
        if self.adjoint {
            self.veach(b, a)
        } else {
            self.veach(a, b)
        }
    }

    /// Veach's shading-normal factor `|a'.z| |b.z| / (|a.z| |b'.z|)`,
    /// primes in the shading frame (1 on flat lanes): `f(b → a) / f(a → b)`
    /// of a tilted interface, η² aside.
    #[inline]
    fn veach(&self, depart: V3<L>, arrive: V3<L>) -> L {
        let (f, flat) = self.shading();
        let (dl, al) = (f.to_local(depart), f.to_local(arrive));
        let num = dl.z.abs() * arrive.z.abs();
        let den = depart.z.abs() * al.z.abs();
        L::select(flat, L::one(), L::div_or_zero(num, den, den.gt(L::zero())))
    }

    /// `|d.z|` in the shading frame (the slab's `|d.z|` where untilted): the
    /// cosine a tilted interface's solid-angle Jacobians take.
    #[inline]
    pub fn cos_local(&self, d: V3<L>) -> L {
        if !self.tilted {
            return d.z.abs();
        }
        let (f, flat) = self.shading();
        Self::to_shading(&f, flat, d).0.z.abs()
    }

    /// Samples `b` given `a` in the interface's own frame (see
    /// [`InterfaceLanes::sample`]).
    #[inline]
    fn sample_local(
        &self,
        a: V3<L>,
        u_select: L,
        u1: L,
        u2: L,
        transmit_only: L::Mask,
    ) -> BsdfSample<L> {
        let zero = L::zero();
        // The result's fields, kept in locals (not in a `BsdfSample` updated
        // in place: that is the return slot, in memory, and LLVM would turn
        // each masked update of it into a slow masked store).
        let mut out_b = V3::z_axis();
        let mut weight = Rgb::zero();
        let mut pdf_out = zero;
        let mut valid = L::Mask::splat(false);
        let mut delta = self.smooth;
        let a_up = a.z.gt(zero);
        let rough = !self.smooth;
        let any_rough = self.run_all || rough.any();
        // Microfacet normal (smooth lanes: the macro normal), on the +z side.
        let m_up = if any_rough {
            V3::select(self.smooth, V3::z_axis(), self.mf.sample(a, u1, u2))
        } else {
            V3::z_axis()
        };

        if self.run_all || self.dielectric.any() {
            let (n_a, n_b) = self.sides(a);
            let eta = self.eta();
            let m = V3::select(a_up, m_up, -m_up); // on a's side
            let am = a.dot(m);
            let (f, ft) = fresnel::dielectric_rt(a.dot(m_up), eta);
            let (t_dir, t_ok) = fresnel::refract(a, m, n_b / n_a);
            let reflect = !transmit_only & u_select.lt(f);
            let b = V3::select(reflect, a.reflect(m), t_dir);
            let side_ok = L::select(reflect, a.z * b.z, -(a.z * b.z)).gt(zero);
            let ok = self.dielectric & am.gt(zero) & side_ok & (reflect | t_ok);
            // Weight: (G / G1-like ratio) × (Fresnel / selection probability).
            let fresnel_w = L::select(transmit_only, ft, L::one());
            let (w_rough, pdf) = if any_rough {
                (
                    self.rough_weight(a, b, m_up),
                    L::select(rough, self.pdf_local(a, b, transmit_only), zero),
                )
            } else {
                (L::one(), zero)
            };
            let w = L::select(self.smooth, L::one(), w_rough) * fresnel_w;
            let ok = ok & (self.smooth | pdf.gt(zero));
            out_b = V3::select(self.dielectric, b, out_b);
            weight = Rgb::select(ok, Rgb::splat(w), weight);
            pdf_out = L::select(self.dielectric, pdf, pdf_out);
            valid = valid | ok;
        }

        if self.run_all || self.conductor.any() {
            let m = m_up;
            let b = a.reflect(m);
            let f = fresnel::conductor(a.dot(m), self.eta, self.k);
            let (w_rough, pdf) = if any_rough {
                (
                    self.rough_weight(a, b, m),
                    L::select(rough, self.pdf_local(a, b, transmit_only), zero),
                )
            } else {
                (L::one(), zero)
            };
            let w = L::select(self.smooth, L::one(), w_rough);
            let ok = self.conductor
                & a_up
                & b.z.gt(zero)
                & !transmit_only
                & (self.smooth | pdf.gt(zero));
            out_b = V3::select(self.conductor, b, out_b);
            weight = Rgb::select(ok, f.scale(w), weight);
            pdf_out = L::select(self.conductor, pdf, pdf_out);
            valid = valid | ok;
        }

        if self.run_all || self.diffuse.any() {
            let b = sample_cosine_hemisphere(u1, u2);
            let pdf = b.z * L::splat(std::f64::consts::FRAC_1_PI);
            let ok = self.diffuse & a_up & pdf.gt(zero) & !transmit_only;
            out_b = V3::select(self.diffuse, b, out_b);
            weight = Rgb::select(ok, self.albedo, weight);
            pdf_out = L::select(self.diffuse, pdf, pdf_out);
            valid = valid | ok;
            delta = delta & !self.diffuse;
        }
        BsdfSample {
            b: out_b,
            weight,
            pdf: pdf_out,
            valid,
            delta,
        }
    }

    /// `f(a → b) |b.z| / pdf` for a microfacet sample `b` made from normal `m`,
    /// divided by the Fresnel factor (the caller applies it): `G |a·m| /
    /// (|a.z| pdf_m / D(m))`, which is `G(a, b) / G1(a)` for visible-normal
    /// sampling.
    #[inline]
    fn rough_weight(&self, a: V3<L>, b: V3<L>, m_up: V3<L>) -> L {
        let visible = self.mf.g_over_g1(a, b);
        if self.mf.beckmann.any() {
            let g = self.mf.g(a, b);
            let am = a.dot(m_up).abs();
            let den = a.z.abs() * m_up.z;
            let ok = den.gt(L::zero());
            let beck = L::div_or_zero(g * am, den, ok);
            L::select(self.mf.beckmann, beck, visible)
        } else {
            visible
        }
    }

    /// The half vector of the pair (a, b) on the +z side, and whether the pair
    /// is a valid microfacet configuration (each direction on the same side of
    /// the microfacet as of the macro surface).
    #[inline]
    fn half_vector(&self, a: V3<L>, b: V3<L>, reflection: L::Mask) -> (V3<L>, L::Mask) {
        let (n_a, n_b) = self.sides(a);
        let hr = a + b;
        let ht = -(a * n_a + b * n_b);
        let h = V3::select(reflection, hr, ht);
        let h = V3::select(h.z.lt(L::zero()), -h, h);
        let l2 = h.length_squared();
        let h = h.normalize_or_z();
        let ok = l2.gt(L::splat(1e-24))
            & (a.dot(h) * a.z).gt(L::zero())
            & (b.dot(h) * b.z).gt(L::zero());
        (h, ok)
    }

    /// The density of `b` given `a` in the interface's own frame.
    #[inline]
    fn pdf_local(&self, a: V3<L>, b: V3<L>, transmit_only: L::Mask) -> L {
        self.local::<false, true>(a, b, transmit_only).1
    }

    /// `f(a → b)` (if `EVAL`) and the density of `b` given `a` (if `PDF`)
    /// in the interface's own frame, 0 for what is not asked: one kernel,
    /// so that a caller that needs both computes the half vector, the
    /// normal distribution and the Fresnel terms once.
    #[inline]
    fn local<const EVAL: bool, const PDF: bool>(
        &self,
        a: V3<L>,
        b: V3<L>,
        transmit_only: L::Mask,
    ) -> (Rgb<L>, L) {
        let zero = L::zero();
        let rough = !self.smooth;
        let reflection = (a.z * b.z).gt(zero);
        let cos_a = a.z.abs();
        let cos_b = b.z.abs();
        let cos_ok = cos_a.gt(zero) & cos_b.gt(zero);
        let mut f = Rgb::zero();
        let mut p = zero;

        if self.run_all || (self.dielectric & rough).any() {
            let (h, ok) = self.half_vector(a, b, reflection);
            let d = self.mf.d(h);
            let (fr, ft) = fresnel::dielectric_rt(a.dot(h), self.eta());
            let (n_a, n_b) = self.sides(a);
            let ah = a.dot(h);
            let bh = b.dot(h);
            let den = n_a * ah + n_b * bh;
            let den2 = den * den;
            if EVAL {
                let ok = ok & self.dielectric & rough & cos_ok;
                let g = self.mf.g(a, b);
                let fr_val = L::div_or_zero(d * g * fr, L::splat(4.0) * cos_a * cos_b, ok);
                let ft_ok = ok & den2.gt(zero);
                let ft_val = L::div_or_zero(
                    d * g * ft * (ah * bh).abs() * n_b * n_b,
                    cos_a * cos_b * den2,
                    ft_ok,
                );
                let v = L::select(reflection, fr_val, ft_val);
                f = Rgb::select(ok, Rgb::splat(v), f);
            }
            if PDF {
                let ok = ok & self.dielectric & rough & !(reflection & transmit_only);
                let pm = self.mf.pdf_of(a, h, d);
                let pr = L::div_or_zero(pm * fr, L::splat(4.0) * ah.abs(), ok);
                let sel_t = L::select(transmit_only, L::one(), ft);
                let pt =
                    L::div_or_zero(pm * sel_t * n_b * n_b * bh.abs(), den2, ok & den2.gt(zero));
                p = L::select(ok, L::select(reflection, pr, pt), p);
            }
        }

        if self.run_all || (self.conductor & rough).any() {
            let h = (a + b).normalize_or_z();
            let d = self.mf.d(h);
            if EVAL {
                let ok = self.conductor & rough & a.z.gt(zero) & b.z.gt(zero);
                let g = self.mf.g(a, b);
                let fr = fresnel::conductor(a.dot(h), self.eta, self.k);
                let s = L::div_or_zero(d * g, L::splat(4.0) * cos_a * cos_b, ok);
                f = Rgb::select(ok, fr.scale(s), f);
            }
            if PDF {
                let ok = self.conductor & rough & a.z.gt(zero) & b.z.gt(zero) & !transmit_only;
                let ah = a.dot(h);
                let v = L::div_or_zero(
                    self.mf.pdf_of(a, h, d),
                    L::splat(4.0) * ah,
                    ok & ah.gt(zero),
                );
                p = L::select(ok, v, p);
            }
        }

        if self.run_all || self.diffuse.any() {
            let ok = self.diffuse & a.z.gt(zero) & b.z.gt(zero);
            if EVAL {
                let v = self.albedo.scale(L::splat(std::f64::consts::FRAC_1_PI));
                f = Rgb::select(ok, v, f);
            }
            if PDF {
                let ok = ok & !transmit_only;
                p = L::select(ok, b.z * L::splat(std::f64::consts::FRAC_1_PI), p);
            }
        }
        (f, p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::{Stream, WalkRng};

    /// Running every code path (the general walk) changes nothing but speed.
    #[test]
    fn run_all_gives_identical_results() {
        let stacks = [
            "[[layers]]\ninterface = { kind = \"dielectric\", ior = 1.5, roughness = 0.3 }",
            "[[layers]]\ninterface = { kind = \"dielectric\", ior = 1.5 }",
            "[[layers]]\ninterface = { kind = \"conductor\", preset = \"Au\", roughness = [0.1, 0.4] }",
            "[[layers]]\ninterface = { kind = \"diffuse\", albedo = 0.7 }",
        ];
        let mut rng = WalkRng::new(1, 2, 3, Stream::Walk);
        for toml in stacks {
            let st = crate::LayerStack::from_toml_str(toml).unwrap();
            let a = st.interface_lanes::<f32>(0);
            let b = InterfaceLanes { run_all: true, ..a };
            for _ in 0..2000 {
                let mut u = || rng.uniform();
                let d =
                    |x: f32, y: f32, z: f32| V3::new(x - 0.5, y - 0.5, z - 0.5).normalize_or_z();
                let (w, v) = (d(u(), u(), u()), d(u(), u(), u()));
                let (u0, u1, u2) = (u(), u(), u());
                for t in [false, true] {
                    let (sa, sb) = (a.sample(w, u0, u1, u2, t), b.sample(w, u0, u1, u2, t));
                    assert_eq!(
                        (sa.b, sa.weight, sa.pdf, sa.valid),
                        (sb.b, sb.weight, sb.pdf, sb.valid)
                    );
                    assert_eq!(a.pdf(w, v, t), b.pdf(w, v, t));
                }
                assert_eq!(a.eval(w, v), b.eval(w, v));
            }
        }
    }

    /// `eval_pdf` is `eval` and `pdf` bit for bit, tilted or not, in both
    /// transports: the density walk takes it in their place. All three are
    /// the one kernel `local`, so this checks only that asking for both
    /// computes what each alone does (a value shared between the two wrongly
    /// fails it); the kernel's physics is checked against sampling
    /// histograms and closed forms (`tests/kernels_chi2.rs`,
    /// `tests/physics/kernels_closed_forms.rs`).
    #[test]
    fn eval_pdf_is_eval_and_pdf() {
        let tilt = ", normal = [0.3, -0.2, 0.93]";
        let stacks = [
            "interface = { kind = \"dielectric\", ior = 1.5, roughness = 0.3 NORMAL }",
            "interface = { kind = \"dielectric\", ior = 1.33, roughness = 0.05, distribution = \"beckmann\" NORMAL }",
            "interface = { kind = \"conductor\", preset = \"Au\", roughness = [0.1, 0.4] NORMAL }",
            "interface = { kind = \"diffuse\", albedo = 0.7 NORMAL }",
            "interface = { kind = \"dielectric\", ior = 1.5 NORMAL }",
        ];
        let mut rng = WalkRng::new(4, 5, 6, Stream::Walk);
        for toml in stacks {
            for normal in ["", tilt] {
                let toml = format!("[[layers]]\n{}", toml.replace("NORMAL", normal));
                let st = crate::LayerStack::from_toml_str(&toml).unwrap();
                let it = st.interface_lanes::<f32>(0);
                for it in [
                    it,
                    InterfaceLanes {
                        adjoint: true,
                        ..it
                    },
                ] {
                    for _ in 0..2000 {
                        let mut u = || rng.uniform() - 0.5;
                        let (w, v) = (
                            V3::new(u(), u(), u()).normalize_or_z(),
                            V3::new(u(), u(), u()).normalize_or_z(),
                        );
                        let (f, p) = it.eval_pdf(w, v);
                        let no = false;
                        assert_eq!(
                            (f, p.to_bits()),
                            (it.eval(w, v), it.pdf(w, v, no).to_bits()),
                            "{toml}"
                        );
                    }
                }
            }
        }
    }
}
