//! What a dielectric coat and the layer under it send back to a Lambertian
//! base: the fraction `R̄` of the base's diffuse exitance that returns to it.
//!
//! Light the base reflects leaves it cosine-distributed, crosses the layer
//! (transmittance `e^(−τ/μ)`), reflects inside the coat and crosses the layer
//! again. Since the base forgets directions, every bounce between base and
//! coat returns the same fraction `R̄`, and the bounces sum to the geometric
//! series `1 / (1 − ρ R̄)` of a coat over a Lambertian base
//! (`super::closed_form`, `super::rough_coat`). `R̄` is a constant of the
//! coat and the layer, computed here by quadrature to near f64 rounding:
//!
//! * a **smooth** coat: `R̄ = 2 ∫₀¹ F_in(μ) e^(−2τ/μ) μ dμ`, one dimension;
//! * a **rough** coat: `R̄ = (1/π) ∫ D(m) ∫ F(a·m) G(a, b) (a·m)
//!   e^(−τ/a.z) e^(−τ/b.z) da dm`, over microfacet normals `m` and the
//!   directions `a` the light arrives from (`b` its mirror about `m`), in the
//!   coat's frame turned over so that the coat's inside is up. It is the
//!   walks' own model: single-scattering microfacets, the interface's
//!   distribution and shadowing; what it leaves out (light that the
//!   shadowing term drops) the walks drop too.
//!
//! The rough integral is three-dimensional (for an isotropic coat), and its
//! integrand has kinks: total internal reflection sets in at a fixed angle
//! between `a` and `m`, and the directions whose mirror image leaves the
//! hemisphere end abruptly. Integrating over `m` outside and over `a` in
//! polar coordinates *about `m`* (angle `ψ`, azimuth `χ`) puts every kink on
//! a coordinate line: total reflection at `ψ = ψc`, the end of the whole
//! circle of azimuths at `ψ = π/2 − θm`, whose limits `χ0` follow in closed
//! form, and, for `m`, at the tilt where those two meet. Gauss–Legendre
//! panels end on those lines, with a square-root substitution at each end
//! (the integrands there behave like `√x`), so the quadrature converges
//! fast; `tests::rough_return_converges` measures it against twice the
//! nodes and against Monte Carlo with the walks' own sampler.

use crate::fresnel;
use crate::lane::V3;
use crate::microfacet::Microfacet;
use std::f64::consts::PI;

/// `R̄ = 2 ∫₀¹ F_in(μ) e^(−2τ/μ) μ dμ` of a smooth coat of relative IOR
/// `eta` (`n_below / n_above`) over a layer of optical depth `tau`, by
/// Gauss–Legendre quadrature. Beyond the critical cosine `μc`, `F_in` falls
/// like `1 − c √(μ − μc)`: the substitution `μ = μc + t²` makes the
/// integrand smooth there, and the quadrature converges to f64 rounding.
pub fn smooth(eta: f64, tau: f64) -> f64 {
    smooth_channels(eta, [tau])[0]
}

/// [`smooth`] of each of `C` optical depths (a layer's channels) in one
/// quadrature: the Fresnel term of a node is shared, each channel's sum is
/// [`smooth`]'s, bit for bit.
pub fn smooth_channels<const C: usize>(eta: f64, tau: [f64; C]) -> [f64; C] {
    let mut sum = [0.0; C];
    smooth_nodes(eta, &mut |mu, w| {
        for k in 0..C {
            sum[k] += w * attenuation(2.0 * tau[k], mu);
        }
    });
    sum
}

/// The nodes of [`smooth`]'s quadrature without the layer: calls
/// `f(μ, w)` for each, `w` the node's weight times `2 F_in(μ) μ`, so that
/// `R̄(τ) = Σ w e^(−2τ/μ)` for every depth at once.
fn smooth_nodes(eta: f64, f: &mut impl FnMut(f64, f64)) {
    // From inside, the cosine is negative in `fresnel`'s convention.
    let mut node = |mu: f64, w: f64| {
        let r = fresnel::dielectric_rt(-mu, eta).0;
        f(mu, w * 2.0 * r * mu)
    };
    let critical = if eta > 1.0 {
        (1.0 - 1.0 / (eta * eta)).sqrt()
    } else {
        0.0
    };
    gauss_legendre_nodes(0.0, critical, 64, &mut node);
    gauss_legendre_nodes(0.0, (1.0 - critical).sqrt(), 64, &mut |t, w| {
        node(critical + t * t, w * 2.0 * t)
    });
}

/// `R̄` per channel of a rough, isotropic coat with microfacets `mf` (one
/// lane, f64) and relative IOR `eta` (`n_below / n_above`) over a layer of
/// optical depth `tau` per channel: the integral of the module's
/// documentation, with [`Panels::DEFAULT`]. A grey layer is integrated
/// once. (An anisotropic coat adds the azimuth of the microfacet normal to
/// the outer integral: not built.)
pub fn rough(mf: &Microfacet<f64>, eta: f64, tau: [f64; 3]) -> [f64; 3] {
    if tau[0] == tau[1] && tau[1] == tau[2] {
        let [r] = rough_with(mf, eta, &[tau[0]], Panels::DEFAULT);
        return [r; 3];
    }
    rough_with(mf, eta, &tau, Panels::DEFAULT)
}

/// Gauss–Legendre panels (of eight nodes) per piece of each dimension of
/// [`rough`]'s quadrature.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Panels {
    /// The microfacet's slope, per piece.
    pub outer: usize,
    /// The angle ψ between the light and the microfacet normal, per end of
    /// a piece.
    pub psi: usize,
    /// An arc of azimuths χ (or half the whole circle), per end.
    pub chi: usize,
}

impl Panels {
    /// The default: twice as many panels in every dimension move `R̄` by
    /// less than 3e-7 on the twelve coats of
    /// `tests::rough_return_converges` (α 0.001–1.5, relative IOR 0.5–3,
    /// both distributions, both shadowing forms, τ 0–3), at a cost paid
    /// once per coat and layer (docs/performance.md).
    pub const DEFAULT: Panels = Panels {
        outer: 1,
        psi: 2,
        chi: 1,
    };

    /// `k` times as many panels in every dimension.
    pub fn times(self, k: usize) -> Panels {
        Panels {
            outer: self.outer * k,
            psi: self.psi * k,
            chi: self.chi * k,
        }
    }
}

/// [`rough`] with explicit panels, for the depths `tau` at once.
pub fn rough_with<const C: usize>(
    mf: &Microfacet<f64>,
    eta: f64,
    tau: &[f64; C],
    panels: Panels,
) -> [f64; C] {
    let mut sum = [0.0; C];
    rough_nodes(mf, eta, panels, &mut |az, bz, w| {
        for k in 0..C {
            sum[k] += w * attenuation(tau[k], az) * attenuation(tau[k], bz);
        }
    });
    sum
}

/// The nodes of [`rough_with`]'s quadrature without the layer: calls
/// `leaf(a.z, b.z, w)` for each pair of directions, `w` its weight (the
/// integrand but for the transmittances `e^(−τ/a.z) e^(−τ/b.z)`, times
/// the quadrature's weights), so that `R̄(τ) = Σ w e^(−τ/a.z) e^(−τ/b.z)`
/// for every depth at once.
fn rough_nodes(
    mf: &Microfacet<f64>,
    eta: f64,
    panels: Panels,
    leaf: &mut impl FnMut(f64, f64, f64),
) {
    debug_assert_eq!(mf.alpha_x, mf.alpha_y, "an isotropic coat");
    let alpha = mf.alpha_x;
    // Inside the coat, total reflection beyond ψc, the angle between the
    // light and the microfacet normal (none in a coat less dense than the
    // exterior).
    let psi_c = (eta > 1.0).then(|| (1.0 / eta).asin());
    slopes(mf.beckmann, alpha, psi_c, panels.outer, &mut |radius, w| {
        let m = V3::new(-alpha * radius, 0.0, 1.0).normalize_or_z();
        microfacet_nodes(mf, m, eta, psi_c, panels, &mut |az, bz, v| {
            leaf(az, bz, w * v / PI)
        });
    });
}

/// `E[g(T)]` over the magnitude `T` of standard GGX (or Beckmann) slopes
/// scaled by `1/α`, density `2T / (1 + T²)²` (or `2T e^(−T²)`), as nodes:
/// calls `g(T, w)` for each. `T < 1` by the distribution function `v`
/// (uniform density); `T ≥ 1` in `x = ln T`, in pieces of `ln 3`, to the
/// `T` beyond which less than 1e-12 of the distribution lies; either range
/// split where the microfacet's tilt is `π/2 − ψc` (its slope is `α T`).
fn slopes(
    beckmann: bool,
    alpha: f64,
    psi_c: Option<f64>,
    panels: usize,
    g: &mut impl FnMut(f64, f64),
) {
    let (v1, x_max) = if beckmann {
        (1.0 - (-1.0f64).exp(), 0.5 * 28.0f64.ln())
    } else {
        (0.5, 1e6f64.ln())
    };
    let radius = |v: f64| {
        if beckmann {
            (-(1.0 - v).ln()).sqrt()
        } else {
            (v / (1.0 - v)).sqrt()
        }
    };
    // The tilt π/2 − ψc, where the light the microfacet totally reflects
    // meets the directions whose mirror leaves the hemisphere, is a kink of
    // the inner integral, at the slope `T = cot ψc / α`: below `T = 1` (a
    // rough coat, or one little denser than the exterior) it splits the
    // distribution function's range too.
    let split_t = psi_c.map(|c| 1.0 / c.tan() / alpha);
    match split_t.filter(|&t| t > 0.0 && t < 1.0) {
        Some(t) => {
            let v = if beckmann {
                -(-t * t).exp_m1()
            } else {
                t * t / (1.0 + t * t)
            };
            ends(0.0, v, panels, &mut |v, w| g(radius(v), w));
            ends(v, v1, panels, &mut |v, w| g(radius(v), w));
        }
        None => gauss_legendre_nodes(0.0, v1, panels, &mut |v, w| g(radius(v), w)),
    }
    let density = |t: f64| {
        let t2 = t * t;
        if beckmann {
            2.0 * t2 * (-t2).exp()
        } else {
            2.0 * t2 / ((1.0 + t2) * (1.0 + t2))
        }
    };
    let mut g_x = |x: f64, w: f64| {
        let t = x.exp();
        g(t, w * density(t))
    };
    let split = split_t.map(f64::ln).filter(|&x| x > 0.0 && x < x_max);
    let step = 3.0f64.ln();
    let mut lo = 0.0;
    while lo < x_max {
        let hi = (lo + step).min(x_max);
        match split.filter(|&x| x > lo && x < hi) {
            Some(x) => {
                ends(lo, x, panels, &mut g_x);
                ends(x, hi, panels, &mut g_x);
            }
            None => gauss_legendre_nodes(lo, hi, panels, &mut g_x),
        }
        lo = hi;
    }
}

/// The nodes of the inner integral over the directions `a` the light
/// arrives from, for the microfacet normal `m`, divided by `cos θm` (the
/// outer measure is the projected distribution `D cos θm`): calls
/// `leaf(a.z, b.z, w)` as [`rough_nodes`] does.
fn microfacet_nodes(
    mf: &Microfacet<f64>,
    m: V3<f64>,
    eta: f64,
    psi_c: Option<f64>,
    panels: Panels,
    leaf: &mut impl FnMut(f64, f64, f64),
) {
    let cm = m.z;
    let sm = (1.0 - cm * cm).max(0.0).sqrt();
    // An orthonormal frame about m: t1 in the plane of m and z (t1.z = sin θm).
    let (t1, t2) = if sm > 1e-12 {
        let t1 = V3::new(-m.x * cm / sm, -m.y * cm / sm, sm);
        (t1, cross(m, t1))
    } else {
        (V3::new(1.0, 0.0, 0.0), V3::new(0.0, 1.0, 0.0))
    };
    // Over χ at one ψ: the whole circle while cot ψ cot θm ≥ 1, else the
    // two arcs |cos χ| < cot ψ cot θm, between which a or its mirror b is
    // below the horizon. The integrand is even in χ (m lies in the xz
    // plane, the coat is isotropic): half the circle, or one arc, doubled.
    // Where the circle is whole, b and a come nearest the horizon at χ = 0
    // and π, the ends of the half, where the nodes crowd.
    let mut around = |psi: f64, w: f64| {
        let (s, c) = psi.sin_cos();
        let f = fresnel::dielectric_rt(-c, eta).0;
        // The factors that depend on ψ alone.
        let w = w * 2.0 * f * c * s / cm;
        if w == 0.0 {
            return;
        }
        let limit = if sm > 1e-12 {
            c / s * cm / sm
        } else {
            f64::INFINITY
        };
        let c0 = if limit >= 1.0 { 0.0 } else { limit.acos() };
        // `ends` over [c0, π − c0]: its halves' nodes c0 + t² and
        // π − c0 − t² share a sine and have opposite cosines.
        if c0 >= PI / 2.0 {
            return;
        }
        let l = (PI / 2.0 - c0).sqrt();
        gauss_legendre_nodes(0.0, l, panels.chi, &mut |t, v| {
            let (sc, cc) = (c0 + t * t).sin_cos();
            let v = v * 2.0 * t;
            for cc in [cc, -cc] {
                let a = m * c + (t1 * cc + t2 * sc) * s;
                let b = m * (2.0 * c) - a;
                if a.z > 0.0 && b.z > 0.0 {
                    leaf(a.z, b.z, w * v * mf.g(a, b));
                }
            }
        });
    };
    let mut cuts = vec![0.0, PI / 2.0];
    cuts.extend(psi_c);
    let full_circle_ends = PI / 2.0 - cm.acos();
    if full_circle_ends > 0.0 && full_circle_ends < PI / 2.0 {
        cuts.push(full_circle_ends);
    }
    cuts.sort_by(f64::total_cmp);
    for w in cuts.windows(2) {
        ends(w[0], w[1], panels.psi, &mut around);
    }
}

fn cross(a: V3<f64>, b: V3<f64>) -> V3<f64> {
    V3::new(
        a.y * b.z - a.z * b.y,
        a.z * b.x - a.x * b.z,
        a.x * b.y - a.y * b.x,
    )
}

/// `e^(−τ/μ)`, 1 without a layer.
fn attenuation(tau: f64, mu: f64) -> f64 {
    if tau > 0.0 {
        (-tau / mu).exp()
    } else {
        1.0
    }
}

/// The nodes of `∫ₐᵇ f` with a square-root substitution toward each end
/// (`x = a + t²` on the first half, `x = b − t²` on the second), for
/// integrands that behave like `√(x − a)` or `√(b − x)` at the ends: calls
/// `f(x, w)` for each node `x` of weight `w`.
fn ends(a: f64, b: f64, panels: usize, f: &mut impl FnMut(f64, f64)) {
    if b <= a {
        return;
    }
    let l = (0.5 * (b - a)).sqrt();
    gauss_legendre_nodes(0.0, l, panels, &mut |t, w| f(a + t * t, w * 2.0 * t));
    gauss_legendre_nodes(0.0, l, panels, &mut |t, w| f(b - t * t, w * 2.0 * t));
}

/// The nodes of 8-point Gauss–Legendre on `panels` equal panels of `[a, b]`:
/// calls `f(x, w)` for each node `x` of weight `w`.
fn gauss_legendre_nodes(a: f64, b: f64, panels: usize, f: &mut impl FnMut(f64, f64)) {
    let h = (b - a) / panels as f64;
    for p in 0..panels {
        let (m, r) = (a + (p as f64 + 0.5) * h, 0.5 * h);
        for (&x, w) in GL_X.iter().zip(GL_W) {
            f(m - r * x, w * r);
            f(m + r * x, w * r);
        }
    }
}

/// The positive nodes of 8-point Gauss–Legendre on `[−1, 1]`, and their
/// weights.
const GL_X: [f64; 4] = [
    0.183_434_642_495_649_8,
    0.525_532_409_916_329,
    0.796_666_477_413_626_7,
    0.960_289_856_497_536_3,
];
const GL_W: [f64; 4] = [
    0.362_683_783_378_362,
    0.313_706_645_877_887_3,
    0.222_381_034_453_374_5,
    0.101_228_536_290_376_3,
];

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::{Stream, WalkRng};
    use crate::LayerStack;

    /// The channels' quadrature is the one-channel quadrature, bit for bit.
    #[test]
    fn smooth_channels_are_smooth_bit_for_bit() {
        for eta in [1.5, 2.2, 1.0 / 1.3] {
            let tau = [0.0, 0.013, 0.7];
            let each = tau.map(|t| smooth(eta, t).to_bits());
            assert_eq!(
                smooth_channels(eta, tau).map(f64::to_bits),
                each,
                "eta {eta}"
            );
        }
    }

    #[test]
    fn smooth_quadrature_is_exact_where_it_can_be_checked() {
        // ∫₀¹ 2μ dμ = 1, and a smooth integrand converges: against the
        // midpoint rule on a fine grid.
        let mut sum = 0.0;
        gauss_legendre_nodes(0.0, 1.0, 4, &mut |m, w| sum += w * 2.0 * m);
        assert!((sum - 1.0).abs() < 1e-15);
        let n = 2_000_000;
        for (eta, tau) in [(1.5, 0.0), (1.5, 0.3), (2.2, 0.01), (1.0 / 1.3, 0.5)] {
            let mid: f64 = (0..n)
                .map(|k| {
                    let mu = (k as f64 + 0.5) / n as f64;
                    let r = fresnel::dielectric_rt(-mu, eta).0;
                    2.0 * r * (-2.0 * tau / mu).exp() * mu / n as f64
                })
                .sum();
            let gl = smooth(eta, tau);
            assert!(
                (gl - mid).abs() < 1e-7,
                "eta {eta} tau {tau}: {gl} vs {mid}"
            );
        }
    }

    /// `R̄` by Monte Carlo with the walks' own sampler: a cosine-distributed
    /// direction up from the base, the coat's reflection from below as
    /// `InterfaceLanes::sample` draws it (visible normals, weight `G/G1`,
    /// times the Fresnel reflectance the lobe choice would apply), the
    /// layer's transmittance both ways. Mean and standard error.
    fn return_by_walks(
        coat: &crate::interface::InterfaceLanes<f64>,
        tau: f64,
        n: u64,
    ) -> (f64, f64) {
        let eta = coat.n_below / coat.n_above;
        let mut rng = WalkRng::new(11, 12, 13, Stream::Walk);
        let (mut s, mut s2) = (0.0, 0.0);
        for _ in 0..n {
            let mut u = || rng.uniform() as f64;
            let (u1, u2) = (u(), u());
            let mu = u1.sqrt();
            let st = (1.0 - mu * mu).sqrt();
            let a = V3::new(st * (2.0 * PI * u2).cos(), st * (2.0 * PI * u2).sin(), -mu);
            let smp = coat.sample(a, 0.0, u(), u(), false);
            let mut x = 0.0;
            if smp.valid && smp.b.z < 0.0 {
                let h = (a + smp.b).normalize_or_z();
                let h = if h.z < 0.0 { -h } else { h };
                let f = fresnel::dielectric_rt(a.dot(h), eta).0;
                x = f * smp.weight.r * attenuation(tau, mu) * attenuation(tau, -smp.b.z);
            }
            s += x;
            s2 += x * x;
        }
        let m = s / n as f64;
        (m, ((s2 / n as f64 - m * m) / n as f64).sqrt())
    }

    /// The rough quadrature converges (twice the panels move it by less
    /// than 3e-7) and agrees with the walks' own sampler within 4 standard
    /// errors, over the domain where `rough_coat` uses it (roughness
    /// 0.001–1.5, relative IOR 0.5–3: `rough_coat::DOMAIN`; its corners
    /// included), both distributions, both shadowing forms, coats denser and
    /// lighter than the exterior and optical depths 0–3: twelve coats.
    #[test]
    fn rough_return_converges() {
        let coats = [
            (1.0, "ior = 1.5, roughness = 0.1", 0.01),
            (1.0, "ior = 1.5, roughness = 0.002", 0.001),
            (1.0, "ior = 1.5, roughness = 0.6", 0.0),
            (1.0, "ior = 1.5, roughness = 0.3", 0.5),
            (1.0, "ior = 1.8, roughness = 0.05", 0.2),
            (
                1.0,
                "ior = 1.5, roughness = 0.2, distribution = \"beckmann\"",
                0.1,
            ),
            (
                1.0,
                "ior = 1.5, roughness = 0.2, shadowing = \"separable\"",
                0.1,
            ),
            (1.0, "ior = 2.5, roughness = 1.0", 3.0),
            (2.0, "ior = 1.6, roughness = 0.3", 0.0),
            (1.0, "ior = 3.0, roughness = 0.001", 0.0),
            (1.0, "ior = 1.5, roughness = 1.5", 0.2),
            (2.0, "ior = 1.0, roughness = 0.3", 0.0),
        ];
        for (exterior, coat, tau) in coats {
            let toml = format!(
                "exterior_ior = {exterior}\n[[layers]]\ninterface = {{ kind = \"dielectric\", {coat} }}\n\
                 [[layers]]\ninterface = {{ kind = \"diffuse\", albedo = 0.5 }}\n"
            );
            let stack = LayerStack::from_toml_str(&toml).unwrap();
            let it = stack.interface_lanes::<f64>(0);
            let eta = it.n_below / it.n_above;
            let [r] = rough_with(&it.mf, eta, &[tau], Panels::DEFAULT);
            let [fine] = rough_with(&it.mf, eta, &[tau], Panels::DEFAULT.times(2));
            assert!(
                (r - fine).abs() < 3e-7,
                "{coat} τ {tau}: {r} against {fine}"
            );
            let (m, se) = return_by_walks(&it, tau, 1_000_000);
            assert!(
                (r - m).abs() < 4.0 * se,
                "{coat} τ {tau} exterior {exterior}: quadrature {r}, walks {m} ± {se}"
            );
        }
    }

    /// Where the kink of the inner integral (the tilt `π/2 − ψc`) lies at
    /// a slope below the distribution's scale (`cot ψc < α`: a rough coat
    /// little denser than the exterior), twice the panels still move `R̄`
    /// by less than 3e-7. Without the split there, these three moved by
    /// 6e-7, 1.1e-6 and 2.7e-6, oscillating with α as the kink crossed the
    /// nodes.
    #[test]
    fn rough_return_converges_where_the_kink_is_a_gentle_slope() {
        for (eta, alpha, beckmann, separable) in [
            (1.1, 0.58, false, false),
            (1.1, 0.69, false, false),
            (1.2, 0.96, true, true),
        ] {
            let mf = Microfacet {
                alpha_x: alpha,
                alpha_y: alpha,
                beckmann,
                separable,
            };
            for tau in [0.0, 0.3] {
                let [r] = rough_with(&mf, eta, &[tau], Panels::DEFAULT);
                let [fine] = rough_with(&mf, eta, &[tau], Panels::DEFAULT.times(2));
                assert!(
                    (r - fine).abs() < 3e-7,
                    "η {eta} α {alpha} τ {tau}: {r} against {fine}"
                );
            }
        }
    }

    /// A nearly smooth rough coat returns what the smooth coat returns.
    #[test]
    fn a_nearly_smooth_coat_returns_the_smooth_fraction() {
        let mf = Microfacet::ggx(1e-4);
        for (eta, tau) in [(1.5, 0.0), (1.5, 0.2), (1.0 / 1.3, 0.0)] {
            let (r, s) = (rough(&mf, eta, [tau; 3])[0], smooth(eta, tau));
            assert!(
                (r - s).abs() < 2e-4,
                "η {eta} τ {tau}: rough {r}, smooth {s}"
            );
        }
    }
}
