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
use std::cell::RefCell;
use std::f64::consts::PI;
use std::sync::{Arc, Mutex, OnceLock, PoisonError};
use std::thread::LocalKey;
use wide::f64x4;

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

/// `R̄(τ)` of a smooth coat of one relative IOR, for every optical depth:
/// a table built once per IOR (and cached process-wide,
/// [`SmoothReturn::for_eta`]) whose lookup is a cubic per channel where
/// [`smooth`] is a quadrature of 1024 nodes, for renderers whose queries
/// each carry their own depths. The closed form of a smooth coat
/// ([`super::closed_form`]) takes its `R̄` from it too, so that a stack and
/// a query with the same numbers get the same answer.
///
/// It interpolates the quadrature: cubic Hermite pieces, from the values
/// and depth derivatives of the same quadrature sums, in the depth
/// coordinate `x = (τ / (τ + 4))^(1/4)` (which maps `[0, ∞]` onto
/// `[0, 1]` and smooths the `τ² ln τ` of a thin layer); `τ = 0` is a node,
/// answered exactly.
#[derive(Debug)]
pub struct SmoothReturn {
    /// The coat's `n_below / n_above`.
    eta: f64,
    rows: DepthRows,
}

thread_local! {
    /// The thread's last [`SmoothReturn`] table.
    static SMOOTH_LAST: Last<u64, SmoothReturn> = const { RefCell::new(None) };
    /// The thread's last [`RoughReturn`] table.
    static ROUGH_LAST: Last<(u64, bool, bool), RoughReturn> = const { RefCell::new(None) };
}

impl SmoothReturn {
    /// The table of relative IOR `eta` (`n_below / n_above`), built on first
    /// request and shared by every later one (the cache holds the last
    /// [`CACHE_SIZE`] IORs; a handle outlives its eviction).
    pub fn for_eta(eta: f64) -> Arc<SmoothReturn> {
        static CACHE: Cache<u64, SmoothReturn> = Mutex::new(Vec::new());
        let key = eta.to_bits();
        last_or(&SMOOTH_LAST, key, || {
            cached(&CACHE, key, || SmoothReturn::new(eta))
        })
    }

    /// `R̄` per channel of relative IOR `eta` at the optical depths `tau`:
    /// [`SmoothReturn::for_eta`]'s [`SmoothReturn::r_bar`], read in place
    /// when it is the thread's last table (a per-query row's case).
    pub fn r_bar_of(eta: f64, tau: [f64; 3]) -> [f64; 3] {
        let read = |t: &SmoothReturn| t.r_bar(tau);
        read_last_or(&SMOOTH_LAST, eta.to_bits(), || Self::for_eta(eta), read)
    }

    /// The table of relative IOR `eta`, built now and not cached.
    pub fn new(eta: f64) -> SmoothReturn {
        let (mut ys, mut ws) = (Vec::new(), Vec::new());
        smooth_nodes(eta, &mut |mu, w| {
            ys.push(mu);
            ws.push(w);
        });
        let basis = DepthBasis::new(&ys, SMOOTH_DEPTHS);
        let mut nodes = vec![0.0; 2 * (SMOOTH_DEPTHS + 1)];
        basis.row(&ws, &mut nodes);
        SmoothReturn {
            eta,
            rows: DepthRows::from_nodes(SMOOTH_DEPTHS, 1, &nodes),
        }
    }

    /// The relative IOR the table is for.
    pub fn eta(&self) -> f64 {
        self.eta
    }

    /// `R̄` per channel at the optical depths `tau` (within 1e-7 of
    /// [`smooth`]; a depth that is not positive is a clear layer).
    #[inline]
    pub fn r_bar(&self, tau: [f64; 3]) -> [f64; 3] {
        let (j, t) = self.rows.at3(tau);
        let [a, b, c] = j.map(|j| &self.rows.block::<1>(0, j)[0]);
        channels(horner4(
            std::array::from_fn(|m| f64x4::new([a[m], b[m], c[m], 0.0])),
            t,
        ))
    }
}

/// `R̄(α, τ)` of a rough, isotropic coat of one relative IOR, distribution
/// and shadowing form, for every roughness of [`ROUGHNESS`] and
/// every optical depth: a table built once per coat (and cached
/// process-wide, [`RoughReturn::for_coat`]) whose lookup interpolates
/// sixteen numbers per channel where [`rough`] is a quadrature of some
/// 200 000 nodes, for renderers whose queries each carry their own
/// roughness and depths. [`super::rough_coat`] takes its `R̄` from it too,
/// so that a stack and a query with the same numbers get the same answer.
///
/// Its rows are [`rough`]'s quadrature at roughnesses uniform in `α^(1/4)`
/// (to three rows past the greatest, so that the stencils there are
/// centred), each one pass of its nodes whose weights are gathered by the
/// harmonic mean `y` of the two cosines (`R̄(τ) = Σ w e^(−2τ/y)`, on a grid
/// of `√y` by cubic Lagrange weights), so that one pass gives every depth.
/// In depth, cubic Hermite pieces as in [`SmoothReturn`]; in roughness,
/// 8-point Lagrange interpolation onto a grid four times as fine, and cubic
/// interpolation there at lookup. (`α^(1/4)` rather than `ln α`: `R̄` falls
/// like a power of α at large roughness, which a logarithmic grid
/// resolves worst where `R̄` changes most.)
#[derive(Debug)]
pub struct RoughReturn {
    eta: f64,
    beckmann: bool,
    separable: bool,
    /// `α^(1/4)` of the first row, and rows per unit of it.
    u0: f64,
    rows_per_u: f64,
    rows: DepthRows,
    /// The threads that built it.
    built_on: usize,
}

impl RoughReturn {
    /// The table of a coat of relative IOR `eta` (`n_below / n_above`;
    /// checked over [`rough_coat::DOMAIN`]'s), Beckmann or GGX, with
    /// separable or height-correlated shadowing, built on first request
    /// ([`RoughReturn::new`]) and shared by every later one (the cache holds
    /// the last [`CACHE_SIZE`] coats; a handle outlives its eviction).
    ///
    /// [`rough_coat::DOMAIN`]: super::rough_coat::DOMAIN
    pub fn for_coat(eta: f64, beckmann: bool, separable: bool) -> Arc<RoughReturn> {
        static CACHE: Cache<(u64, bool, bool), RoughReturn> = Mutex::new(Vec::new());
        let key = (eta.to_bits(), beckmann, separable);
        last_or(&ROUGH_LAST, key, || {
            cached(&CACHE, key, || RoughReturn::new(eta, beckmann, separable))
        })
    }

    /// [`RoughReturn::for_coat`]'s [`RoughReturn::r_bar`], read in place
    /// when it is the thread's last table (a per-query row's case).
    pub fn r_bar_of(mf: &Microfacet<f64>, eta: f64, tau: [f64; 3]) -> [f64; 3] {
        let (beckmann, separable) = (mf.beckmann, mf.separable);
        let key = (eta.to_bits(), beckmann, separable);
        let get = || Self::for_coat(eta, beckmann, separable);
        read_last_or(&ROUGH_LAST, key, get, |t| t.r_bar(mf.alpha_x, tau))
    }

    /// The table of that coat, built now and not cached, on as many threads
    /// as the call that needs it may use ([`crate::pool::build_threads`]:
    /// the calling thread alone in a one-thread call). They are threads of
    /// their own, not a pool's: a pool's workers may be waiting for this
    /// very table, and the calling thread builds alone if none can start.
    pub fn new(eta: f64, beckmann: bool, separable: bool) -> RoughReturn {
        RoughReturn::built(eta, beckmann, separable, crate::pool::build_threads())
    }

    /// [`RoughReturn::new`] on at most `threads` threads.
    fn built(eta: f64, beckmann: bool, separable: bool, threads: usize) -> RoughReturn {
        let domain = ROUGHNESS;
        // Rows from the domain's least roughness, past its greatest by
        // three so that the stencils there are centred.
        let within = ROUGH_ROWS[usize::from(beckmann)];
        let coarse_rows = within + 3;
        let (u0, u1) = (domain.0.sqrt().sqrt(), domain.1.sqrt().sqrt());
        let du = (u1 - u0) / (within - 1) as f64;
        let grid: Vec<f64> = (0..=ROUGH_BINS)
            .map(|k| {
                let v = k as f64 / ROUGH_BINS as f64;
                v * v
            })
            .collect();
        let basis = DepthBasis::new(&grid, ROUGH_DEPTHS);
        // The quadrature's rows, one pass of its nodes each.
        let stride = 2 * (ROUGH_DEPTHS + 1);
        let mut coarse = vec![0.0; coarse_rows * stride];
        let next = std::sync::atomic::AtomicUsize::new(0);
        let threads = threads.clamp(1, coarse_rows);
        let mut built_on = 1;
        let rows: Vec<Vec<(usize, Vec<f64>)>> = std::thread::scope(|scope| {
            let work = || {
                let mut done = Vec::new();
                loop {
                    let k = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                    if k >= coarse_rows {
                        return done;
                    }
                    let u = u0 + du * k as f64;
                    let alpha = (u * u * u * u).max(domain.0);
                    let mf = Microfacet {
                        alpha_x: alpha,
                        alpha_y: alpha,
                        beckmann,
                        separable,
                    };
                    let mut bins = vec![0.0; ROUGH_BINS + 1];
                    rough_nodes(&mf, eta, Panels::DEFAULT, &mut |az, bz, w| {
                        spread(&mut bins, (2.0 * az * bz / (az + bz)).sqrt(), w)
                    });
                    let mut row = vec![0.0; stride];
                    basis.row(&bins, &mut row);
                    done.push((k, row));
                }
            };
            let handles: Vec<_> = (1..threads)
                .map_while(|_| std::thread::Builder::new().spawn_scoped(scope, work).ok())
                .collect();
            built_on = 1 + handles.len();
            let mut all = vec![work()];
            all.extend(handles.into_iter().map(|h| h.join().expect("a row")));
            all
        });
        for (k, row) in rows.into_iter().flatten() {
            coarse[k * stride..(k + 1) * stride].copy_from_slice(&row);
        }
        // Onto the fine grid, to one row past the domain (the cubic
        // stencil of its last interval): 8-point Lagrange in α^(1/4), the
        // stencil shifted inward at the least roughness (a fine row on a
        // coarse one copies it).
        let fine_rows = ROUGH_REFINE * (within - 1) + 2;
        let mut fine = vec![0.0; fine_rows * stride];
        for (r, out) in fine.chunks_exact_mut(stride).enumerate() {
            let s = r as f64 / ROUGH_REFINE as f64;
            let first = (r / ROUGH_REFINE).saturating_sub(3).min(coarse_rows - 8);
            for k in first..first + 8 {
                let mut w = 1.0;
                for l in first..first + 8 {
                    if l != k {
                        w *= (s - l as f64) / (k as f64 - l as f64);
                    }
                }
                let row = &coarse[k * stride..(k + 1) * stride];
                for (o, x) in out.iter_mut().zip(row) {
                    *o += w * x;
                }
            }
        }
        RoughReturn {
            eta,
            beckmann,
            separable,
            u0,
            rows_per_u: (ROUGH_REFINE as f64) / du,
            rows: DepthRows::from_nodes(ROUGH_DEPTHS, fine_rows, &fine),
            built_on,
        }
    }

    /// How many threads built it (the caller's included): what a test of
    /// the thread setting reads.
    pub fn built_on(&self) -> usize {
        self.built_on
    }

    /// The coat the table is for: its relative IOR, whether Beckmann (else
    /// GGX), whether with separable shadowing (else height-correlated).
    pub fn coat(&self) -> (f64, bool, bool) {
        (self.eta, self.beckmann, self.separable)
    }

    /// `R̄` per channel at roughness `alpha` (clamped to [`ROUGHNESS`]) and
    /// the optical depths `tau` (a depth that is not positive is a clear
    /// layer): within 1e-6 of [`rough`] for GGX, 1.5e-6 for Beckmann, whose
    /// quadrature wobbles by about 1e-6 in α.
    #[inline]
    pub fn r_bar(&self, alpha: f64, tau: [f64; 3]) -> [f64; 3] {
        let domain = ROUGHNESS;
        // (Not clamp: NaN is the least roughness.)
        let alpha = if alpha > domain.0 {
            alpha.min(domain.1)
        } else {
            domain.0
        };
        let u = alpha.sqrt().sqrt();
        let s = (u - self.u0) * self.rows_per_u;
        let f = s.floor().clamp(1.0, (self.rows.rows - 3) as f64);
        let (i, t) = (f as u32 as usize, s - f);
        // Cubic Lagrange weights on the rows i − 1 … i + 2.
        let (a, b, c, d) = (t + 1.0, t, t - 1.0, t - 2.0);
        let weights = [
            -b * c * d * (1.0 / 6.0),
            a * c * d * 0.5,
            -a * b * d * 0.5,
            a * b * c * (1.0 / 6.0),
        ];
        let (j, t) = self.rows.at3(tau);
        let [x, y, z] = j.map(|j| self.at(i, weights, j));
        channels(horner4(
            std::array::from_fn(|m| f64x4::new([x[m], y[m], z[m], 0.0])),
            t,
        ))
    }

    /// The cubic of depth interval `j` between the rows `i − 1 … i + 2`
    /// with `weights`.
    #[inline(always)]
    fn at(&self, i: usize, weights: [f64; 4], j: usize) -> [f64; 4] {
        let [p, q, r, s] = self.rows.block::<4>(i - 1, j);
        let [a, b, c, d] = weights;
        std::array::from_fn(|m| a * p[m] + b * q[m] + c * r[m] + d * s[m])
    }
}

/// The roughnesses α a [`RoughReturn`] covers, from nearly a mirror to
/// very rough: those of [`rough_coat::DOMAIN`], where the factorization of
/// a rough coat answers.
///
/// [`rough_coat::DOMAIN`]: super::rough_coat::DOMAIN
pub const ROUGHNESS: (f64, f64) = (0.001, 1.5);

/// How many tables of each kind the process keeps ([`SmoothReturn::for_eta`],
/// [`RoughReturn::for_coat`]); past it the oldest is dropped.
pub const CACHE_SIZE: usize = 64;

/// Intervals of the smooth table in depth.
const SMOOTH_DEPTHS: usize = 128;
/// Intervals of the rough table in depth, its quadrature's rows in
/// roughness (GGX, Beckmann: the Beckmann shadowing's rational fit makes
/// `R̄` less smooth in α), its rows per quadrature row, and its bins of
/// `√y`.
const ROUGH_DEPTHS: usize = 64;
const ROUGH_ROWS: [usize; 2] = [25, 41];
const ROUGH_REFINE: usize = 4;
const ROUGH_BINS: usize = 128;

/// The scale of the depth coordinate `x = (τ / (τ + TAU_SCALE))^(1/4)`.
const TAU_SCALE: f64 = 4.0;

/// Tables by key, each built once (concurrent requests for one key wait for
/// its build; other keys build meanwhile).
type Cache<K, T> = Mutex<Vec<(K, Arc<OnceLock<Arc<T>>>)>>;

/// A thread's last table and its key: the rows of one per-query table ask
/// for the same coat's, one after another.
type Last<K, T> = RefCell<Option<(K, Arc<T>)>>;

/// The thread's last table if it is `key`'s, else `get()`'s, kept as the
/// last.
fn last_or<K: PartialEq + Copy + 'static, T: 'static>(
    last: &'static LocalKey<Last<K, T>>,
    key: K,
    get: impl FnOnce() -> Arc<T>,
) -> Arc<T> {
    if let Some(t) = last.with_borrow(|l| {
        l.as_ref()
            .filter(|(k, _)| *k == key)
            .map(|(_, t)| Arc::clone(t))
    }) {
        return t;
    }
    let t = get();
    last.set(Some((key, Arc::clone(&t))));
    t
}

/// `read` of the thread's last table if it is `key`'s (read in place, no
/// handle taken), else of [`last_or`]'s.
fn read_last_or<K: PartialEq + Copy + 'static, T: 'static, R>(
    last: &'static LocalKey<Last<K, T>>,
    key: K,
    get: impl FnOnce() -> Arc<T>,
    read: impl Fn(&T) -> R,
) -> R {
    let hit = last.with_borrow(|l| l.as_ref().filter(|(k, _)| *k == key).map(|(_, t)| read(t)));
    hit.unwrap_or_else(|| read(&last_or(last, key, get)))
}

fn cached<K: PartialEq, T>(cache: &Cache<K, T>, key: K, build: impl FnOnce() -> T) -> Arc<T> {
    let slot = {
        let mut entries = cache.lock().unwrap_or_else(PoisonError::into_inner);
        match entries.iter().find(|(k, _)| *k == key) {
            Some((_, slot)) => Arc::clone(slot),
            None => {
                if entries.len() >= CACHE_SIZE {
                    entries.remove(0);
                }
                let slot = Arc::new(OnceLock::new());
                entries.push((key, Arc::clone(&slot)));
                slot
            }
        }
    };
    Arc::clone(slot.get_or_init(|| Arc::new(build())))
}

/// Rows of cubic Hermite pieces in the depth coordinate `x` (uniform nodes
/// `j / n`, `j = 0 … n`), stored by interval: piece `j` of row `r` is the
/// cubic's coefficients in `t = n x − j`, the pieces of one interval for
/// consecutive rows side by side (what a lookup reads).
#[derive(Debug)]
struct DepthRows {
    /// Intervals per row.
    n: usize,
    rows: usize,
    pieces: Vec<[f64; 4]>,
}

impl DepthRows {
    /// The rows of `nodes`: per row, `R̄` and `dR̄/dx / n` per node.
    fn from_nodes(n: usize, rows: usize, nodes: &[f64]) -> DepthRows {
        let stride = 2 * (n + 1);
        debug_assert_eq!(nodes.len(), rows * stride);
        let mut pieces = Vec::with_capacity(n * rows);
        for j in 0..n {
            for r in 0..rows {
                let k = r * stride + 2 * j;
                let (f0, d0, f1, d1) = (nodes[k], nodes[k + 1], nodes[k + 2], nodes[k + 3]);
                pieces.push([
                    f0,
                    d0,
                    3.0 * (f1 - f0) - 2.0 * d0 - d1,
                    2.0 * (f0 - f1) + d0 + d1,
                ]);
            }
        }
        DepthRows { n, rows, pieces }
    }

    /// The pieces of interval `j` of the `R` rows from `first`.
    #[inline(always)]
    fn block<const R: usize>(&self, first: usize, j: usize) -> &[[f64; 4]; R] {
        let k = j * self.rows + first;
        self.pieces[k..k + R].try_into().expect("R rows")
    }

    /// The interval of each depth of `tau` and where in it (`t ∈ [0, 1]`).
    /// A depth that is not positive (or NaN) is 0; ∞ is `x = 1`, where
    /// every row is 0. The division and square roots of the three run in
    /// the lanes of one vector.
    #[inline(always)]
    fn at3(&self, tau: [f64; 3]) -> ([usize; 3], f64x4) {
        let v = f64x4::new([tau[0], tau[1], tau[2], 0.0]);
        // Not positive or NaN: 0; ∞: the largest finite depth.
        let v = v
            .simd_gt(f64x4::ZERO)
            .select(v.min(f64x4::splat(f64::MAX)), f64x4::ZERO);
        let s = (v / (v + f64x4::splat(TAU_SCALE))).sqrt().sqrt() * f64x4::splat(self.n as f64);
        let j = s.floor().min(f64x4::splat((self.n - 1) as f64));
        let i = j.to_array();
        (
            [
                i[0] as u32 as usize,
                i[1] as u32 as usize,
                i[2] as u32 as usize,
            ],
            s - j,
        )
    }
}

/// The cubic with coefficients `c` at `t`, in every lane.
#[inline(always)]
fn horner4(c: [f64x4; 4], t: f64x4) -> f64x4 {
    c[0] + t * (c[1] + t * (c[2] + t * c[3]))
}

/// The first three lanes: one per channel.
#[inline(always)]
fn channels(v: f64x4) -> [f64; 3] {
    let a = v.to_array();
    [a[0], a[1], a[2]]
}

/// `e^(−2τ/y)` and its derivative in the depth coordinate at the nodes of
/// [`DepthRows`], per `y`: what turns the weights `w` of `R̄(τ) = Σ w
/// e^(−2τ/y)` into a row.
struct DepthBasis {
    n: usize,
    ys: usize,
    /// Per node, per `y`: the value and `d/dx / n`.
    value: Vec<f64>,
    slope: Vec<f64>,
}

impl DepthBasis {
    fn new(ys: &[f64], n: usize) -> DepthBasis {
        let mut value = Vec::with_capacity((n + 1) * ys.len());
        let mut slope = Vec::with_capacity((n + 1) * ys.len());
        for j in 0..=n {
            let x = j as f64 / n as f64;
            // τ = c x⁴ / (1 − x⁴), dτ/dx = 4 c x³ / (1 − x⁴)².
            let x4 = x * x * x * x;
            let (tau, dtau) = if j < n {
                (
                    TAU_SCALE * x4 / (1.0 - x4),
                    4.0 * TAU_SCALE * x * x * x / ((1.0 - x4) * (1.0 - x4)),
                )
            } else {
                (f64::INFINITY, 0.0)
            };
            for &y in ys {
                let (v, d) = if j == 0 {
                    (1.0, 0.0)
                } else if y > 0.0 && j < n {
                    let e = (-2.0 * tau / y).exp();
                    (e, -2.0 / y * e * dtau / n as f64)
                } else {
                    (0.0, 0.0)
                };
                value.push(v);
                slope.push(d);
            }
        }
        DepthBasis {
            n,
            ys: ys.len(),
            value,
            slope,
        }
    }

    /// The row (`R̄` and its scaled slope per node) of the weights `w`.
    fn row(&self, w: &[f64], out: &mut [f64]) {
        debug_assert_eq!(w.len(), self.ys);
        debug_assert_eq!(out.len(), 2 * (self.n + 1));
        let dot = |basis: &[f64]| -> f64 { basis.iter().zip(w).map(|(a, b)| a * b).sum() };
        for j in 0..=self.n {
            let r = j * self.ys..(j + 1) * self.ys;
            out[2 * j] = dot(&self.value[r.clone()]);
            out[2 * j + 1] = dot(&self.slope[r]);
        }
    }
}

/// Adds the weight `w` at `v ∈ [0, 1]` to the four nearest of the uniform
/// nodes `k / n` of `bins` (`n + 1` of them) by cubic Lagrange weights: a
/// cubic's sum over the nodes is then its sum over the points spread.
#[inline(always)]
fn spread(bins: &mut [f64], v: f64, w: f64) {
    let n = bins.len() - 1;
    let s = v * n as f64;
    let i = (s as usize).clamp(1, n - 2);
    let t = s - i as f64;
    let (a, b, c, d) = (t + 1.0, t, t - 1.0, t - 2.0);
    bins[i - 1] -= w * b * c * d * (1.0 / 6.0);
    bins[i] += w * a * c * d * 0.5;
    bins[i + 1] -= w * a * b * d * 0.5;
    bins[i + 2] += w * a * b * c * (1.0 / 6.0);
}

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

    /// The smooth table is the quadrature within 1e-7 at every depth (a
    /// dense grid from 1e-12 to 1e3, uniform to 20, and 0, 1e-300, 1e30,
    /// the largest float and ∞), for coats denser and lighter than the
    /// exterior and index-matched, and exactly at τ = 0.
    #[test]
    fn smooth_table_is_the_quadrature() {
        let mut taus = vec![0.0, 1e-300, 1e-30, 1e30, f64::MAX, f64::INFINITY];
        taus.extend((0..=600).map(|k| 10f64.powf(-12.0 + 15.0 * k as f64 / 600.0)));
        taus.extend((1..=400).map(|k| 20.0 * k as f64 / 400.0));
        for eta in [
            1.0 / 3.0,
            0.5,
            1.0 / 1.3,
            0.95,
            1.0,
            1.05,
            1.33,
            1.5,
            2.0,
            2.4,
            3.0,
        ] {
            let table = SmoothReturn::new(eta);
            assert_eq!(
                table.r_bar([0.0; 3])[0].to_bits(),
                smooth(eta, 0.0).to_bits(),
                "η {eta}"
            );
            let mut worst = (0.0, 0.0);
            for chunk in taus.chunks(3) {
                let tau = [chunk[0], chunk[chunk.len() / 2], chunk[chunk.len() - 1]];
                let (r, q) = (table.r_bar(tau), smooth_channels(eta, tau));
                for c in 0..3 {
                    let e = (r[c] - q[c]).abs();
                    if e.is_nan() || e > worst.0 {
                        worst = (e, tau[c]);
                    }
                }
            }
            assert!(worst.0 <= 1e-7, "η {eta}: {:e} at τ {}", worst.0, worst.1);
        }
    }

    /// `R̄` of the rough table against [`rough`] at random points (fixed
    /// seed): per coat of `etas` (the domain's two ends and random ones),
    /// its roughness' two ends at τ = 0 and at random depths, and random
    /// roughnesses and depths (some 0, from 1e-5 to 10).
    fn rough_table_against_quadrature(beckmann: bool, seed: u64, tolerance: f64) {
        let mut rng = WalkRng::new(seed, 3, 4, Stream::Walk);
        let mut u = || rng.uniform() as f64;
        let (lo, hi) = super::super::rough_coat::DOMAIN.eta;
        let etas = [lo, hi, 1.0, lo + (hi - lo) * u(), lo + (hi - lo) * u()];
        let (a0, a1) = ROUGHNESS;
        let mut points = 0;
        for (n, eta) in etas.into_iter().enumerate() {
            let separable = n % 2 == 1;
            let table = RoughReturn::for_coat(eta, beckmann, separable);
            let mut worst = (0.0, 0.0, 0.0);
            for k in 0..40 {
                let alpha = match k {
                    0 | 2 => a0,
                    1 | 3 => a1,
                    _ => a0 * (a1 / a0).powf(u()),
                };
                let depth = |u: f64| 10f64.powf(-5.0 + 6.0 * u);
                let tau = if k < 2 {
                    [0.0; 3]
                } else if k % 4 == 0 {
                    [0.0, depth(u()), depth(u())]
                } else {
                    [depth(u()), depth(u()), depth(u())]
                };
                let mf = Microfacet {
                    alpha_x: alpha,
                    alpha_y: alpha,
                    beckmann,
                    separable,
                };
                let (r, q) = (table.r_bar(alpha, tau), rough(&mf, eta, tau));
                for c in 0..3 {
                    let e = (r[c] - q[c]).abs();
                    if e.is_nan() || e > worst.0 {
                        worst = (e, alpha, tau[c]);
                    }
                }
                points += 1;
            }
            assert!(
                worst.0 <= tolerance,
                "η {eta} beckmann {beckmann} separable {separable}: {:e} at α {} τ {}",
                worst.0,
                worst.1,
                worst.2
            );
        }
        assert_eq!(points, 200);
    }

    /// GGX: within 1e-6 of the quadrature (within 2.1e-7 on these points).
    #[test]
    fn rough_table_is_the_quadrature_ggx() {
        rough_table_against_quadrature(false, 17, 1e-6);
    }

    /// Beckmann: within 1.5e-6 of the quadrature (within 5.5e-7 on these
    /// points but one, 1.06e-6 at η 3, α 0.277, τ 0), because the
    /// quadrature itself is not smooth in α to 1e-6 for Beckmann coats: its
    /// shadowing's rational fit jumps by 6e-5 at `a = 1.6` (`Λ(1.6⁻) =
    /// −5.7e-5`), a surface its panels do not follow. There [`rough`] steps
    /// by 1.2e-6 between α 0.259 and 0.268, and lies up to 5e-6 from twice
    /// its panels elsewhere; the table, smooth in α, stays within 9e-7 of
    /// twice the panels at that point.
    #[test]
    fn rough_table_is_the_quadrature_beckmann() {
        rough_table_against_quadrature(true, 23, 1.5e-6);
    }

    /// A per-query row's factorization takes `R̄` from the coat's table; a
    /// material's own takes the quadrature.
    #[test]
    fn a_rough_row_takes_r_bar_from_the_table() {
        let toml = "[[layers]]\n\
                    interface = { kind = \"dielectric\", ior = 1.6, roughness = 0.3, \
                    distribution = \"beckmann\" }\n\
                    medium = { thickness = 1.0, sigma_t = [0.1, 0.5, 2.0], albedo = 0.0 }\n\
                    [[layers]]\n\
                    interface = { kind = \"diffuse\", albedo = 0.8 }\n";
        let stack = LayerStack::from_toml_str(toml).expect("a stack");
        let own = super::super::rough_coat::RoughCoatLambertian::of(&stack, &Default::default())
            .expect("a factorization");
        let coat = own.clone().tabulated();
        let it = stack.interface_lanes::<f32>(0);
        let (alpha, eta) = (it.mf.alpha_x as f64, (it.n_below / it.n_above) as f64);
        let tau = [0.1f32, 0.5, 2.0].map(f64::from);
        let table = RoughReturn::for_coat(eta, true, false).r_bar(alpha, tau);
        assert_eq!(coat.r_bar().map(f64::to_bits), table.map(f64::to_bits));
        let mf = Microfacet {
            alpha_x: alpha,
            alpha_y: alpha,
            beckmann: true,
            separable: false,
        };
        assert_eq!(own.r_bar(), rough(&mf, eta, tau));
    }

    /// The cache builds a table once per key and keeps the last
    /// [`CACHE_SIZE`] keys (on a cache of its own, so that other tests'
    /// tables do not interfere).
    #[test]
    fn the_cache_builds_once_and_keeps_the_last_keys() {
        let cache: Cache<u64, u64> = Mutex::new(Vec::new());
        let builds = std::cell::Cell::new(0);
        let get = |k: u64| {
            cached(&cache, k, || {
                builds.set(builds.get() + 1);
                k
            })
        };
        let first = get(0);
        assert!(Arc::ptr_eq(&first, &get(0)));
        assert_eq!(builds.get(), 1);
        for k in 1..CACHE_SIZE as u64 {
            get(k);
        }
        assert!(Arc::ptr_eq(&first, &get(0)), "still cached");
        assert_eq!(builds.get(), CACHE_SIZE);
        get(CACHE_SIZE as u64);
        let again = get(0);
        assert!(!Arc::ptr_eq(&first, &again), "evicted, built again");
        assert_eq!((*first, *again, builds.get()), (0, 0, CACHE_SIZE + 2));
        assert!(Arc::ptr_eq(
            &SmoothReturn::for_eta(1.25),
            &SmoothReturn::for_eta(1.25)
        ));
    }

    /// Nanoseconds per query of `f` over `queries`: the least and the
    /// median of 15 runs of `reps` passes (the machine's other work slows
    /// some runs).
    fn per_query(
        queries: &[(f64, [f64; 3])],
        f: impl Fn(f64, [f64; 3]) -> [f64; 3],
        reps: usize,
    ) -> (f64, f64) {
        use std::hint::black_box;
        let mut runs: Vec<f64> = (0..15)
            .map(|_| {
                let start = std::time::Instant::now();
                let mut sum = [0.0; 3];
                for _ in 0..reps {
                    for &(alpha, tau) in black_box(queries) {
                        let r = f(alpha, tau);
                        for c in 0..3 {
                            sum[c] += r[c];
                        }
                    }
                }
                black_box(sum);
                start.elapsed().as_secs_f64() * 1e9 / (reps * queries.len()) as f64
            })
            .collect();
        runs.sort_by(f64::total_cmp);
        (runs[0], runs[runs.len() / 2])
    }

    /// Milliseconds of `f`: the least and the median of `runs` runs.
    fn millis<T>(runs: usize, f: impl Fn() -> T) -> (f64, f64) {
        let mut times: Vec<f64> = (0..runs)
            .map(|_| {
                let start = std::time::Instant::now();
                std::hint::black_box(f());
                start.elapsed().as_secs_f64() * 1e3
            })
            .collect();
        times.sort_by(f64::total_cmp);
        (times[0], times[times.len() / 2])
    }

    /// What the tables cost, printed, not checked (timings vary with the
    /// machine and its load; each is the least and the median of several
    /// runs): `cargo test --release -p strata-bsdf --lib table_costs --
    /// --ignored --nocapture`. Builds on one thread and on all, lookups of
    /// 4096 random queries (three channels each), and the quadratures they
    /// replace.
    #[test]
    #[ignore]
    fn table_costs() {
        let eta = 1.5;
        let all = std::thread::available_parallelism().map_or(1, usize::from);
        let (least, median) = millis(9, || SmoothReturn::new(eta));
        println!("smooth table build: {least:.2} ms (median {median:.2})");
        for beckmann in [false, true] {
            for threads in [1, all] {
                let (least, median) =
                    millis(5, || RoughReturn::built(eta, beckmann, false, threads));
                println!(
                    "rough table build ({}, {threads} thread(s)): {least:.1} ms (median {median:.1})",
                    if beckmann { "Beckmann" } else { "GGX" },
                );
            }
        }
        let smooth_table = SmoothReturn::new(eta);
        let tables = [false, true].map(|b| RoughReturn::new(eta, b, false));
        let mut rng = WalkRng::new(1, 2, 3, Stream::Walk);
        let mut u = || rng.uniform() as f64;
        let queries: Vec<(f64, [f64; 3])> = (0..4096)
            .map(|_| {
                let alpha = 0.001 * 1500f64.powf(u());
                (alpha, [u(), u(), u()].map(|v| 10f64.powf(-3.0 + 3.5 * v)))
            })
            .collect();
        let (least, median) = per_query(&queries, |_, tau| smooth_table.r_bar(tau), 100);
        println!("smooth lookup, 3 channels: {least:.1} ns/query (median {median:.1})");
        for (name, table) in ["GGX", "Beckmann"].iter().zip(&tables) {
            let (least, median) = per_query(&queries, |alpha, tau| table.r_bar(alpha, tau), 100);
            println!("rough lookup ({name}), 3 channels: {least:.1} ns/query (median {median:.1})");
        }
        let (least, median) = per_query(&queries[..256], |_, tau| smooth_channels(eta, tau), 1);
        println!(
            "smooth_channels (the quadrature), 3 channels: {:.1} µs/query (median {:.1})",
            least * 1e-3,
            median * 1e-3
        );
        let (least, median) = millis(5, || rough(&Microfacet::ggx(0.3), eta, [0.1, 0.2, 0.3]));
        println!(
            "rough (the quadrature, GGX), 3 channels: {least:.1} ms/query (median {median:.1})"
        );
    }
}
