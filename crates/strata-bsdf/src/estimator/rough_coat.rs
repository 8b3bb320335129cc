//! A rough dielectric coat over a clear or absorbing layer over a
//! Lambertian base: the BSDF factorizes, and its estimate needs no walk.
//!
//! Every path but the coat's own reflection enters the coat, crosses the
//! layer to the base, bounces between the base and the coat, and leaves. A
//! Lambertian base forgets directions, so the bounces sum to a geometric
//! series whose ratio does not depend on `wi` or `wo`:
//!
//! ```text
//! f(wi, wo) = f_coat(wi, wo) + (n0/n1)² ρ A(wi) A(wo) / (π (1 − ρ R̄))
//! A(w) = ∫ f_t(w → d) |d.z| e^(−τ/|d.z|) dd
//! ```
//!
//! `f_coat` is the coat's reflection (the first-order term the walks add
//! exactly too), `A(w)` the fraction of light from `w` that reaches the base
//! (the smooth closed form's `T(θ) e^(−τ/μ′)`), `R̄` the fraction of the
//! base's exitance that the layer and the coat send back to it
//! ([`super::coat_return::rough`]'s quadrature, from its table per coat,
//! [`super::coat_return::RoughReturn`], once per coat and layer),
//! `n0` and `n1` the IORs of the exterior and of the coat. The estimator
//! draws `A(wi)` and `A(wo)` by the coat's own transmission sampler, the one
//! a walk enters by (visible normals, weight `(1 − F) G/G1`, times the
//! layer's transmittance): the only variance left is that of those two
//! samples, with none from the number of bounces or where they go, which is
//! most of the walks' variance on these stacks. The samples are independent
//! of each other, so their product is unbiased.
//!
//! With a *scattering* layer the same formula at the layer's `σt` is the sum
//! over the paths that never collide in it: the part of `Auto`'s control
//! variate that the walks, which then score only paths with a collision,
//! leave out ([`super::coat_lambertian`]).

use super::accumulate::{BlockReducer, MeanVar};
use super::closed_form::ExactSample;
use super::coat_and_base::coat_and_base;
use super::coat_return;
use super::layout::MediumLanes;
use super::settings::Settings;
use crate::interface::InterfaceLanes;
use crate::lane::{DefaultWide, Lane, LaneMask, Rgb, V3};
use crate::math::sample_cosine_hemisphere;
use crate::microfacet::Microfacet;
use crate::rng::{seed_state_from, LaneRng, Stream};
use crate::stack::{Interface, LayerStack};
use std::f64::consts::PI;
use std::sync::{Arc, OnceLock};

/// The factorized BSDF of a rough coat over a layer over a Lambertian base.
#[derive(Clone, Debug)]
pub struct RoughCoatLambertian {
    /// The coat, and the layer as an absorber of its extinction, on one
    /// lane (splat onto the sampler's lanes where it samples: a per-query
    /// row stays small).
    coat_one: InterfaceLanes<f64>,
    layer_one: MediumLanes<f64>,
    /// The coat's microfacets and `n_below / n_above`, for `R̄`.
    mf: Microfacet<f64>,
    eta: f64,
    /// Optical depth of the layer per channel (0 without one).
    tau: [f64; 3],
    /// The base's albedo.
    rho: [f64; 3],
    /// `R̄` per channel.
    r_bar: ReturnOf,
}

/// Where a [`RoughCoatLambertian`]'s `R̄` comes from.
#[derive(Clone, Debug)]
enum ReturnOf {
    /// Its quadrature ([`coat_return::rough`]), on first use, shared by
    /// clones (and by the parameter sets that have this coat and layer).
    Quadrature(Arc<OnceLock<[f64; 3]>>),
    /// The coat's table ([`coat_return::RoughReturn`]), looked up when the
    /// factorization was made (a per-query row: no allocation).
    Table([f64; 3]),
}

impl RoughCoatLambertian {
    /// The factorization of `stack`, if it has one under `settings`: a rough,
    /// isotropic, untilted dielectric coat over a clear or absorbing layer
    /// over a Lambertian base, with no depth cap (which would truncate the
    /// series).
    pub fn of(stack: &LayerStack, settings: &Settings) -> Option<Self> {
        if stack.medium(0).is_some_and(|m| m.scatters()) {
            return None;
        }
        Self::unscattered(stack, settings)
    }

    /// The part of `stack`'s BSDF carried by the paths that never collide
    /// in its layer, for the shape of [`RoughCoatLambertian::of`] with any
    /// layer (clear, absorbing or scattering): the factorization of the same
    /// stack with the layer a pure absorber of the same `σt`, which is the
    /// whole BSDF where the layer does not scatter. `None` for other stacks,
    /// and under a depth cap. (An extinction that depends on the direction,
    /// SGGX, breaks the factorization's one-dimensional transmittance; an
    /// anisotropic coat's `R̄` is not built; outside [`DOMAIN`] `R̄` is not
    /// checked.)
    pub fn unscattered(stack: &LayerStack, settings: &Settings) -> Option<Self> {
        Self::unscattered_with(stack, settings, false)
    }

    /// [`RoughCoatLambertian::unscattered`], with `R̄` from the coat's
    /// table where `tabulated` ([`RoughCoatLambertian::tabulated`]).
    pub fn unscattered_with(
        stack: &LayerStack,
        settings: &Settings,
        tabulated: bool,
    ) -> Option<Self> {
        let (coat, _) = coat_and_base(stack, settings)?;
        Self::of_coat(stack, coat).map(|r| match tabulated {
            true => r.tabulated(),
            false => RoughCoatLambertian {
                r_bar: ReturnOf::Quadrature(Arc::default()),
                ..r
            },
        })
    }

    /// The factorization of `stack`, whose shape has one (a per-query row
    /// written in place), with `R̄` from the coat's table:
    /// [`RoughCoatLambertian::unscattered_with`]'s tabulated form, without
    /// analysing the stack's shape again. `None` where the row's roughness
    /// leaves [`DOMAIN`].
    pub fn of_row(stack: &LayerStack) -> Option<Self> {
        Self::of_coat(stack, stack.interface(0)).map(Self::tabulated)
    }

    /// The factorization of `stack`, whose shape has one, with coat `coat`
    /// (its `R̄` still to be found), if the coat is in [`DOMAIN`].
    fn of_coat(stack: &LayerStack, coat: &Interface) -> Option<Self> {
        if !Self::in_domain(coat) {
            return None;
        }
        let mut layer_one = MediumLanes::<f64>::new(stack, 0);
        if layer_one.thickness > 0.0 {
            // The uncollided paths see only the extinction.
            layer_one.kind = super::layout::LayerKind::Absorbing;
        }
        // The integral takes the numbers the walks take, in single precision,
        // so that a stack whose numbers differ below that (a texture's f32
        // value and a material file's decimal) integrates to the same `R̄`.
        let (it, medium) = (
            stack.interface_lanes::<f32>(0),
            MediumLanes::<f32>::new(stack, 0),
        );
        let f64s = |c: Rgb<f32>| [c.r, c.g, c.b].map(f64::from);
        let mf = Microfacet {
            alpha_x: it.mf.alpha_x as f64,
            alpha_y: it.mf.alpha_y as f64,
            beckmann: it.mf.beckmann,
            separable: it.mf.separable,
        };
        Some(RoughCoatLambertian {
            coat_one: stack.interface_lanes(0),
            layer_one,
            mf,
            eta: (it.n_below / it.n_above) as f64,
            tau: f64s(medium.sigma_t).map(|t| t * medium.thickness as f64),
            // (The numbers the walks take: the albedo in single precision.)
            rho: stack.interface(1).albedo.map(|a| f64::from(a as f32)),
            r_bar: ReturnOf::Table([0.0; 3]),
        })
    }

    /// Whether `coat` is a rough coat the factorization answers: isotropic
    /// (an anisotropic coat's `R̄` is not built) and within [`DOMAIN`].
    pub fn in_domain(coat: &Interface) -> bool {
        let eta = coat.n_below / coat.n_above;
        let alpha = coat.alpha[0];
        !coat.smooth
            && coat.alpha[1] == alpha
            && (DOMAIN.alpha.0..=DOMAIN.alpha.1).contains(&alpha)
            && (DOMAIN.eta.0..=DOMAIN.eta.1).contains(&eta)
    }

    /// This factorization with `R̄` from the coat's table
    /// ([`coat_return::RoughReturn`], within 1e-6 of [`coat_return::rough`],
    /// 1.5e-6 for Beckmann, built once per coat and process): what a
    /// per-query row takes, where a quadrature per row would cost far more
    /// than its queries.
    pub fn tabulated(mut self) -> Self {
        let r_bar = coat_return::RoughReturn::r_bar_of(&self.mf, self.eta, self.tau);
        self.r_bar = ReturnOf::Table(r_bar);
        self
    }

    /// `R̄` per channel: by quadrature ([`coat_return::rough`]) the first
    /// time, or from the coat's table ([`RoughCoatLambertian::tabulated`]).
    pub fn r_bar(&self) -> [f64; 3] {
        match &self.r_bar {
            ReturnOf::Quadrature(r) => {
                *r.get_or_init(|| coat_return::rough(&self.mf, self.eta, self.tau))
            }
            ReturnOf::Table(r) => *r,
        }
    }

    /// Whether `R̄` comes from the coat's table.
    fn is_tabulated(&self) -> bool {
        matches!(self.r_bar, ReturnOf::Table(_))
    }

    /// Whether `other` has the same coat and layer, so that it can share this
    /// one's `R̄` (the base's albedo may differ).
    pub fn same_return(&self, other: &RoughCoatLambertian) -> bool {
        let mf = |m: &Microfacet<f64>| (m.alpha_x, m.alpha_y, m.beckmann, m.separable);
        mf(&self.mf) == mf(&other.mf)
            && self.eta == other.eta
            && self.tau == other.tau
            && self.is_tabulated() == other.is_tabulated()
    }

    /// `other` with this one's `R̄` (computed or not), where they have the
    /// same coat and layer ([`RoughCoatLambertian::same_return`]).
    pub fn sharing_return(&self, mut other: RoughCoatLambertian) -> RoughCoatLambertian {
        if self.same_return(&other) {
            other.r_bar = self.r_bar.clone();
        }
        other
    }

    /// `n` samples of `f − f_coat` at `(wi, wo)`, in the stack's oriented
    /// frame (both above the coat), each `(n0/n1)² ρ Â(wi) Â(wo) / (π (1 −
    /// ρ R̄))`, reduced in sample order. The samples draw from the
    /// [`Stream::Coat`] streams of the query (`prefix`): lane `j` of the
    /// sampler's lanes takes samples `j`, `j + LANES`, … from stream `j`,
    /// so the result is a function of the query and `n`, whichever engine
    /// asks.
    pub fn sample_mean(&self, wi: [f64; 3], wo: [f64; 3], n: u64, prefix: u64) -> MeanVar {
        type W = DefaultWide;
        let scale = self.scale();
        let splat = |w: [f64; 3]| V3::new(W::splat(w[0]), W::splat(w[1]), W::splat(w[2]));
        let (wi, wo) = (splat(wi), splat(wo));
        let mut rng =
            LaneRng::<W>::from_states(|j| seed_state_from(prefix, j as u64, Stream::Coat));
        let all = <W as Lane>::Mask::splat(true);
        let mut sum = BlockReducer::new();
        let (coat, layer) = (self.coat_one.splat::<W>(), self.layer_one.splat::<W>());
        let mut k = 0;
        while k < n {
            let u = [(); 4].map(|_| rng.uniform(all));
            let a = entrance_product(&coat, &layer, wi, wo, u);
            let lanes = (n - k).min(W::LANES as u64) as usize;
            for j in 0..lanes {
                let v = [a.r.lane(j), a.g.lane(j), a.b.lane(j)];
                sum.push(std::array::from_fn(|c| scale[c] * v[c]));
            }
            k += lanes as u64;
        }
        sum.finish()
    }

    /// `(n0/n1)² ρ / (π (1 − ρ R̄))` per channel: what multiplies `A(wi) A(wo)`.
    fn scale(&self) -> [f64; 3] {
        let r_bar = self.r_bar();
        std::array::from_fn(|c| {
            self.rho[c] / (PI * self.eta * self.eta * (1.0 - self.rho[c] * r_bar[c]))
        })
    }

    /// `sample()` without a walk, in the stack's oriented frame (`wi` above
    /// the coat), from seven uniforms: with probability `P` (the coat's
    /// Fresnel reflectance at `θi` as if it were smooth, kept within
    /// [`COAT_SHARE`]) a direction of the coat's reflection lobe, drawn as a
    /// walk draws it (visible normals), else a cosine-distributed one;
    /// weight `f̂ cos θo / p`, with `f̂` the coat's reflection plus one sample
    /// of the factorized part (four uniforms). `p`, the mixture's density
    /// ([`RoughCoatLambertian::pdf`]), is exact; the weight is an unbiased
    /// estimate of `f cos θo / p`, bounded by `F G/G1 / P + π f_rest / (1 −
    /// P)`. `None` for `wi` below the coat and for a reflection that the
    /// microfacet leaves below the horizon (the lobe's share the
    /// single-scattering model loses).
    pub fn sample(&self, wi: [f64; 3], u: [f64; 7]) -> Option<ExactSample> {
        if wi[2] <= 0.0 {
            return None;
        }
        let a = V3::new(wi[0], wi[1], wi[2]);
        let wo = if u[0] < self.coat_share(wi[2]) {
            let s = self.coat_one.sample(a, 0.0, u[1], u[2], false);
            if !s.valid || s.b.z <= 0.0 {
                return None;
            }
            [s.b.x, s.b.y, s.b.z]
        } else {
            let d = sample_cosine_hemisphere(u[1], u[2]);
            [d.x, d.y, d.z]
        };
        let p = self.pdf(wi, wo);
        if p <= 0.0 {
            return None;
        }
        let b = V3::new(wo[0], wo[1], wo[2]);
        let coat = self.coat_one.eval(a, b);
        let rest = entrance_product(
            &self.coat_one,
            &self.layer_one,
            a,
            b,
            [u[3], u[4], u[5], u[6]],
        );
        let scale = self.scale();
        let f = [
            coat.r + scale[0] * rest.r,
            coat.g + scale[1] * rest.g,
            coat.b + scale[2] * rest.b,
        ];
        Some(ExactSample {
            wo,
            weight: f.map(|v| v * wo[2] / p),
            specular: false,
        })
    }

    /// The density of [`RoughCoatLambertian::sample`]'s directions (oriented
    /// frame): `P p_coat(wo) + (1 − P) cos θo / π`, `p_coat` the density of
    /// the coat's reflection lobe as the walks sample it, `D_vis(h) / (4
    /// wi·h)` (the single-scattering model's lost share left out).
    pub fn pdf(&self, wi: [f64; 3], wo: [f64; 3]) -> f64 {
        if wi[2] <= 0.0 || wo[2] <= 0.0 {
            return 0.0;
        }
        let (a, b) = (V3::new(wi[0], wi[1], wi[2]), V3::new(wo[0], wo[1], wo[2]));
        let h = (a + b).normalize_or_z();
        let (ah, bh) = (a.dot(h), b.dot(h));
        let lobe = if h.z > 0.0 && ah > 0.0 && bh > 0.0 {
            self.coat_one.mf.pdf(a, h) / (4.0 * ah)
        } else {
            0.0
        };
        let share = self.coat_share(wi[2]);
        share * lobe + (1.0 - share) * wo[2] * std::f64::consts::FRAC_1_PI
    }

    /// The probability of the coat's lobe in [`RoughCoatLambertian::sample`].
    fn coat_share(&self, cos_i: f64) -> f64 {
        let f = crate::fresnel::dielectric_rt(cos_i, self.eta).0;
        f.clamp(COAT_SHARE.0, COAT_SHARE.1)
    }
}

/// Where the factorization answers: roughness (the range of `R̄`'s table,
/// [`coat_return::ROUGHNESS`]) and relative IOR (`n_below / n_above`) of
/// the coat, the ranges over which its integral `R̄` and the table of it are
/// checked (`coat_return::tests::rough_return_converges` and
/// `rough_table_is_the_quadrature_*`, corners included).
/// Outside them (a coat nearly a mirror, or so dense that almost no light
/// escapes and `1 − ρ R̄` would rest on the quadrature's last digits) the
/// walks answer.
pub const DOMAIN: Domain = Domain {
    alpha: coat_return::ROUGHNESS,
    eta: (0.5, 3.0),
};

/// The ranges of [`DOMAIN`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Domain {
    /// Roughness α.
    pub alpha: (f64, f64),
    /// Relative IOR of the coat, `n_below / n_above`.
    pub eta: (f64, f64),
}

/// The range of the probability with which [`RoughCoatLambertian::sample`]
/// draws from the coat's lobe: a share never so small that the lobe's
/// weights grow past 1/0.05, nor so large that the cosine part's do.
pub const COAT_SHARE: (f64, f64) = (0.05, 0.95);

/// `Â(wi) Â(wo)` per channel on every lane, from four uniforms: each factor
/// is the coat's transmission sampled from that direction as a walk enters
/// (`transmit_only`: weight `(1 − F) G/G1`) times the layer's transmittance
/// along the refracted direction; 0 where the coat lets nothing through.
#[inline(always)]
pub fn entrance_product<L: Lane>(
    coat: &InterfaceLanes<L>,
    layer: &MediumLanes<L>,
    wi: V3<L>,
    wo: V3<L>,
    u: [L; 4],
) -> Rgb<L> {
    let all = L::Mask::splat(true);
    let enter = |w: V3<L>, u1: L, u2: L| {
        let s = coat.sample(w, L::zero(), u1, u2, all);
        let t = layer.transmittance(L::one(), s.b);
        Rgb::select(s.valid, s.weight * t, Rgb::zero())
    };
    enter(wi, u[0], u[1]) * enter(wo, u[2], u[3])
}
