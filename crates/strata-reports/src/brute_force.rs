//! The brute-force baseline: position-based explicit simulation, the paper's
//! "standard Monte Carlo", and what a user would write without the
//! position-free formulation.
//!
//! ## What it simulates
//! The stack becomes a real slab: interface `i` is the plane `z = -D_i`, where
//! `D_i` adds up the thicknesses of the layers above it (a layer whose medium
//! does not attenuate, or that has no medium, gets
//! [`BruteSettings::nominal_thickness`]: its thickness changes nothing but the
//! lateral spread). The slab is finite, `|x|, |y| <= W` with `W =`
//! [`BruteSettings::half_width`] times the slab's depth. A walk carries an
//! explicit 3D position in f64: it enters at the origin, intersects the planes
//! and the side walls along its direction, samples free-flight distances in 3D
//! along the ray (not in depth), samples Henyey–Greenstein directions at
//! collisions, and samples every interface with the same kernel as the
//! position-free estimators ([`InterfaceLanes::sample`]). Russian roulette
//! after [`BruteSettings::rr_start`] events keeps it unbiased. A walk that
//! reaches a side wall is lost: [`BinnedEstimate::lost`] counts them and
//! [`BinnedEstimate::lost_weight`] adds up their throughput, which bounds the
//! bias of the finite slab; the default width makes it negligible (the tests
//! check it). The walks that do get lost are mostly trapped at grazing angles
//! (total internal reflection over a rough base), where each crossing of a
//! layer moves them far sideways, and an absorbing layer has already taken
//! nearly all their weight.
//!
//! ## Colour
//! All channels share one walk. Distances are sampled with the extinction of
//! one "hero" channel drawn per walk, and every channel is weighted by the
//! path-level balance heuristic over the three channels' distance densities
//! (the same trick as [`strata_bsdf::medium::free_flight`], written independently
//! here): unbiased in every channel, and exact (weights 1 or the albedo) when
//! `sigma_t` is grey. A medium that does not scatter only attenuates the walk
//! by its 3D transmittance `exp(-sigma_t t)` (no collisions are sampled).
//!
//! ## How it estimates f, and its two errors
//! Exit directions are binned. The bin of a query `wo` is the cone of
//! half-angle `δ` ([`BruteSettings::half_angle`]) around it, cut to `wo`'s
//! hemisphere; with `C = ∫_bin |cos θ| dω` (closed form `π sin²δ |cos θo|` when
//! the cone stays in one hemisphere, see [`cap_cos_integral`]),
//!
//! `f̂(wi, wo) = Σ_{walks exiting in the bin} weight / (N C)`.
//!
//! Walks whose every event was a delta (a mirror reflection off a smooth coat,
//! say) are left out, since `eval` never returns delta lobes; the albedo keeps
//! them. The estimate has two errors:
//! * **statistical**: the standard error returned with it, about
//!   `1 / sqrt(N P_bin)` relative, with `P_bin ∝ δ²` the chance of landing in
//!   the bin;
//! * **binning bias**: `f̂` is unbiased for the cosine-weighted average of `f`
//!   over the bin, not for `f(wo)`. To second order the difference is
//!   `(δ² / 8) (Δ(f cos) - f Δcos) / cos`, the lobe's curvature over the bin
//!   (`Δ` the Laplacian on the sphere). It does not fall with `N`: the error of
//!   the baseline flattens at this floor, and shrinking `δ` to lower it raises
//!   the variance as `1 / δ²` (the best `δ` falls as `N^(-1/6)`, and the error
//!   then as `N^(-1/3)` rather than `N^(-1/2)`).
//!
//! The directional albedo (reflected and transmitted fractions) has no binning
//! error: it is the mean exit weight on each side.
//!
//! Every walk draws from its own stream `(seed, query, walk, Stream::BruteForce)`,
//! so results are deterministic.

use std::f64::consts::PI;
use strata_bsdf::estimator::{orient, Albedo, Estimate, MeanVar};
use strata_bsdf::interface::InterfaceLanes;
use strata_bsdf::lane::V3;
use strata_bsdf::phase::{PhaseKind, PhaseLanes};
use strata_bsdf::rng::{Stream, WalkRng};
use strata_bsdf::stack::{LayerStack, Phase};

/// Controls of the brute-force baseline.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BruteSettings {
    /// Half-angle `δ` of the cone bins, in radians.
    pub half_angle: f64,
    /// Half-width of the slab in units of its depth: walks leaving through
    /// `|x| = W` or `|y| = W` are lost.
    pub half_width: f64,
    /// Thickness given to a layer with no attenuating medium.
    pub nominal_thickness: f64,
    /// Russian roulette starts after this many events.
    pub rr_start: u32,
}

impl Default for BruteSettings {
    fn default() -> Self {
        BruteSettings {
            half_angle: 5f64.to_radians(),
            half_width: 1e4,
            nominal_thickness: 1.0,
            rr_start: 4,
        }
    }
}

/// A medium in the slab.
#[derive(Clone, Copy, Debug)]
struct SlabMedium {
    sigma_t: [f64; 3],
    albedo: [f64; 3],
    /// Its phase function. Henyey–Greenstein is sampled by this file's own
    /// sampler; the other kinds by the library's kernels (each tested on its
    /// own by chi-square), so that what this checks of them is the transport.
    phase: PhaseLanes<f64>,
    /// An SGGX medium's axis and eigenvalues along and across it: its
    /// extinction along `d` is `sigma_t sqrt(dᵀSd)`, computed here apart
    /// from the library's lanes.
    sggx: Option<([f64; 3], f64, f64)>,
    scatters: bool,
}

impl SlabMedium {
    /// The extinction along the unit direction `d`.
    fn sigma(&self, d: V3<f64>) -> [f64; 3] {
        let Some((a, along, across)) = self.sggx else {
            return self.sigma_t;
        };
        let c = d.x * a[0] + d.y * a[1] + d.z * a[2];
        let s = (along * c * c + across * (1.0 - c * c).max(0.0)).sqrt();
        self.sigma_t.map(|x| x * s)
    }
}

/// One layer of the slab: the region between two interface planes.
#[derive(Clone, Copy, Debug)]
struct SlabLayer {
    top: f64,
    bottom: f64,
    medium: Option<SlabMedium>,
}

/// How a walk ended.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Exit {
    /// It left the slab through the top or the bottom.
    Out {
        /// Exit direction (unit, in the oriented stack frame).
        wo: [f64; 3],
        /// `f |cos θo| / p` in expectation: the walk's throughput.
        weight: [f64; 3],
        /// Every event was a delta.
        specular: bool,
    },
    /// Absorbed, or ended by Russian roulette.
    Absorbed,
    /// Left through a side wall of the finite slab, carrying this throughput.
    Lost {
        /// The throughput when it crossed the wall.
        weight: [f64; 3],
    },
}

/// A cone bin around a query direction, cut to its hemisphere.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bin {
    axis: [f64; 3],
    half_angle: f64,
    cos_half: f64,
    measure: f64,
}

impl Bin {
    /// The bin of half-angle `half_angle` (radians, in `(0, π/2)`) around the
    /// unit direction `axis`.
    pub fn new(axis: [f64; 3], half_angle: f64) -> Self {
        let axis = normalize(axis);
        Bin {
            axis,
            half_angle,
            cos_half: half_angle.cos(),
            measure: cap_cos_integral(axis, half_angle),
        }
    }
    /// The query direction.
    pub fn axis(&self) -> [f64; 3] {
        self.axis
    }
    /// Half-angle in radians.
    pub fn half_angle(&self) -> f64 {
        self.half_angle
    }
    /// `∫_bin |cos θ| dω`.
    pub fn measure(&self) -> f64 {
        self.measure
    }
    /// Solid angle of the whole cone (before the cut to the hemisphere).
    pub fn cone_solid_angle(&self) -> f64 {
        2.0 * PI * (1.0 - self.cos_half)
    }
    /// `d` (unit) lies in the bin.
    #[inline]
    pub fn contains(&self, d: [f64; 3]) -> bool {
        d[2] * self.axis[2] > 0.0 && dot(d, self.axis) >= self.cos_half
    }
    /// A direction uniformly distributed over the cone (it may fall outside
    /// the hemisphere, hence outside the bin). Used to average an estimator
    /// over the bin: `E[g(ω) 1_bin(ω)] · cone_solid_angle / measure` is the
    /// `|cos|`-weighted average when `g = f |cos|`.
    pub fn sample_cone(&self, u1: f64, u2: f64) -> [f64; 3] {
        let c = 1.0 - u1 * (1.0 - self.cos_half);
        let s = (1.0 - c * c).max(0.0).sqrt();
        let (t, b) = basis(self.axis);
        let (sp, cp) = (2.0 * PI * u2).sin_cos();
        normalize([
            c * self.axis[0] + s * (cp * t[0] + sp * b[0]),
            c * self.axis[1] + s * (cp * t[1] + sp * b[1]),
            c * self.axis[2] + s * (cp * t[2] + sp * b[2]),
        ])
    }
}

/// `∫ |cos θ| dω` over the cone of half-angle `half_angle` around the unit
/// vector `axis`, cut to `axis`'s hemisphere.
///
/// When the cone stays in one hemisphere (`|axis.z| >= sin δ`) this is
/// `π sin²δ |axis.z|`, since `∫_cone ω dω = π sin²δ axis`. Otherwise the inner
/// integral over the cone's azimuth is done in closed form and the outer one
/// (over the angle from the axis) by a 4096-point midpoint rule.
pub fn cap_cos_integral(axis: [f64; 3], half_angle: f64) -> f64 {
    let az = axis[2].abs();
    let (s, _) = half_angle.sin_cos();
    if az >= s {
        return PI * s * s * az;
    }
    // ω.z (signed towards axis' side) = cos ρ az + sin ρ cos ψ ez.
    let ez = (1.0 - az * az).max(0.0).sqrt();
    let n = 4096;
    let h = half_angle / n as f64;
    let mut sum = 0.0;
    for k in 0..n {
        let rho = (k as f64 + 0.5) * h;
        let (sr, cr) = rho.sin_cos();
        let (a, b) = (cr * az, sr * ez);
        // ∫_0^{2π} max(0, a + b cos ψ) dψ
        let inner = if a >= b {
            2.0 * PI * a
        } else if a <= -b {
            0.0
        } else {
            let psi0 = (-a / b).acos();
            2.0 * (a * psi0 + b * psi0.sin())
        };
        sum += inner * sr * h;
    }
    sum
}

/// The result of a brute-force run from one incident direction.
#[derive(Clone, Debug, PartialEq)]
pub struct BinnedEstimate {
    /// `f` per query direction (the `|cos|`-weighted average over its bin),
    /// with the standard error of that average (the binning bias is not in it).
    pub f: Vec<Estimate>,
    /// Reflected and transmitted fractions (no binning involved).
    pub albedo: Albedo,
    /// Walks run.
    pub walks: u64,
    /// Walks lost through the slab's side walls.
    pub lost: u64,
    /// Their mean throughput per walk run, per channel: a bound on the bias the
    /// finite slab puts on `R + T` (a walk's expected future exit weight is at
    /// most its throughput).
    pub lost_weight: [f64; 3],
}

impl BinnedEstimate {
    /// Fraction of walks lost through the side walls (most of them carry a
    /// negligible throughput: see [`BinnedEstimate::lost_weight`]).
    pub fn lost_fraction(&self) -> f64 {
        self.lost as f64 / self.walks.max(1) as f64
    }
}

/// The position-based simulator of a stack.
#[derive(Clone, Debug)]
pub struct BruteForce {
    stack: LayerStack,
    ifaces: Vec<InterfaceLanes<f64>>,
    /// Depth (z, negative downwards) of each interface plane.
    planes: Vec<f64>,
    layers: Vec<SlabLayer>,
    half_width: f64,
    settings: BruteSettings,
}

impl BruteForce {
    /// Builds the slab of `stack`.
    pub fn new(stack: &LayerStack, settings: BruteSettings) -> Self {
        let n = stack.len();
        let ifaces = (0..n).map(|i| stack.interface_lanes::<f64>(i)).collect();
        let mut planes = vec![0.0];
        let mut layers = Vec::with_capacity(n.saturating_sub(1));
        for l in 0..n.saturating_sub(1) {
            let m = stack.medium(l).filter(|m| m.attenuates());
            let h = m.map_or(settings.nominal_thickness, |m| m.thickness);
            let top = planes[l];
            let bottom = top - h;
            planes.push(bottom);
            layers.push(SlabLayer {
                top,
                bottom,
                medium: m.map(|m| SlabMedium {
                    sigma_t: m.sigma_t,
                    albedo: m.albedo,
                    phase: PhaseLanes::new(&m.phase, m.phase_kind()),
                    sggx: match m.phase {
                        Phase::Sggx {
                            axis,
                            along,
                            across,
                            ..
                        } => Some((axis, along, across)),
                        _ => None,
                    },
                    scatters: m.scatters(),
                }),
            });
        }
        let depth = -planes[planes.len() - 1];
        let half_width = settings.half_width * depth.max(settings.nominal_thickness);
        BruteForce {
            stack: stack.clone(),
            ifaces,
            planes,
            layers,
            half_width,
            settings,
        }
    }

    /// The settings.
    pub fn settings(&self) -> BruteSettings {
        self.settings
    }

    /// The slab's half-width `W` (absolute units).
    pub fn half_width(&self) -> f64 {
        self.half_width
    }

    /// Russian roulette after `settings.rr_start` events: always draws one
    /// uniform; false if the walk ends.
    fn survive(&self, beta: &mut [f64; 3], events: u32, rng: &mut WalkRng) -> bool {
        let u = rng.uniform() as f64;
        if events < self.settings.rr_start {
            return true;
        }
        let q = beta[0].max(beta[1]).max(beta[2]).min(1.0);
        if q <= 0.0 || u >= q {
            return false;
        }
        for b in beta.iter_mut() {
            *b /= q;
        }
        true
    }

    /// Distance along `d` from `p` to a side wall.
    fn to_side(&self, p: V3<f64>, d: V3<f64>) -> f64 {
        let w = self.half_width;
        let axis = |x: f64, dx: f64| {
            if dx > 0.0 {
                (w - x) / dx
            } else if dx < 0.0 {
                (-w - x) / dx
            } else {
                f64::INFINITY
            }
        };
        axis(p.x, d.x).min(axis(p.y, d.y)).max(0.0)
    }

    /// One walk from `wi` (unit, already oriented so that light enters).
    pub fn walk(&self, wi: [f64; 3], rng: &mut WalkRng) -> Exit {
        let n = self.ifaces.len();
        let hero = ((rng.uniform() as f64 * 3.0) as usize).min(2);
        let mut i = if wi[2] > 0.0 { 0 } else { n - 1 };
        let mut p = V3::new(0.0, 0.0, self.planes[i]);
        let mut d = -V3::new(wi[0], wi[1], wi[2]);
        let mut beta = [1.0f64; 3];
        let mut ratios = [1.0f64; 3];
        let mut specular = true;
        let mut events = 0u32;
        loop {
            // Interface event at plane i: the light arrives from -d.
            let (us, u1, u2) = (
                rng.uniform() as f64,
                rng.uniform() as f64,
                rng.uniform() as f64,
            );
            let s = self.ifaces[i].sample(-d, us, u1, u2, false);
            if !s.valid {
                return Exit::Absorbed;
            }
            for (b, w) in beta.iter_mut().zip([s.weight.r, s.weight.g, s.weight.b]) {
                *b *= w;
            }
            specular &= s.delta;
            d = s.b;
            events += 1;
            // Which layer the new direction enters, or out of the slab.
            let l = if d.z > 0.0 {
                if i == 0 {
                    return self.out(d, beta, specular);
                }
                i - 1
            } else {
                if i + 1 == n {
                    return self.out(d, beta, specular);
                }
                i
            };
            if !self.survive(&mut beta, events, rng) {
                return Exit::Absorbed;
            }
            // Fly through layer l until an interface plane (or a side wall).
            let layer = self.layers[l];
            loop {
                let t_plane = if d.z > 0.0 {
                    ((layer.top - p.z) / d.z).max(0.0)
                } else if d.z < 0.0 {
                    ((layer.bottom - p.z) / d.z).max(0.0)
                } else {
                    f64::INFINITY
                };
                let t_side = self.to_side(p, d);
                let t_max = t_plane.min(t_side);
                match layer.medium {
                    Some(m) if m.scatters => {
                        let u = rng.uniform() as f64;
                        let sigma = m.sigma(d);
                        match flight(&m, sigma, t_max, hero, u, &mut beta, &mut ratios) {
                            Some(t) => {
                                p = p + d * t;
                                let mut u = [0.0; 4];
                                for x in u.iter_mut().take(m.phase.sample_uniforms()) {
                                    *x = rng.uniform() as f64;
                                }
                                d = if m.phase.kind == PhaseKind::Hg {
                                    hg_sample(m.phase.g, d, u[0], u[1])
                                } else {
                                    m.phase.sample(d, u)
                                };
                                specular = false;
                                events += 1;
                                if !self.survive(&mut beta, events, rng) {
                                    return Exit::Absorbed;
                                }
                                continue;
                            }
                            None => {
                                if beta.iter().all(|&b| b <= 0.0) {
                                    return Exit::Absorbed;
                                }
                            }
                        }
                    }
                    // A pure absorber: its 3D transmittance.
                    Some(m) if t_max.is_finite() => {
                        for (b, s) in beta.iter_mut().zip(m.sigma(d)) {
                            *b *= (-s * t_max).exp();
                        }
                    }
                    _ => {}
                }
                if t_side <= t_plane {
                    return Exit::Lost { weight: beta };
                }
                // Reach the plane; snap the depth to it exactly.
                p = p + d * t_plane;
                if d.z > 0.0 {
                    p.z = layer.top;
                    i = l;
                } else {
                    p.z = layer.bottom;
                    i = l + 1;
                }
                break;
            }
        }
    }

    fn out(&self, d: V3<f64>, weight: [f64; 3], specular: bool) -> Exit {
        Exit::Out {
            wo: [d.x, d.y, d.z],
            weight,
            specular,
        }
    }

    /// Runs `n` walks from `wi` and bins their exits around each of `wos`
    /// (unit directions pointing away from the surface); also returns the
    /// directional albedo. `query` keys the random streams.
    pub fn run(
        &self,
        wi: [f64; 3],
        wos: &[[f64; 3]],
        n: u64,
        seed: u64,
        query: u64,
    ) -> BinnedEstimate {
        let mut acc_f = vec![MeanVar::new(); wos.len()];
        let mut acc_r = MeanVar::new();
        let mut acc_t = MeanVar::new();
        let mut lost = 0;
        let mut lost_w = [0.0f64; 3];
        let finish =
            |acc_f: Vec<MeanVar>, acc_r: MeanVar, acc_t: MeanVar, lost, lost_w: [f64; 3]| {
                BinnedEstimate {
                    f: acc_f.iter().map(|a| a.estimate()).collect(),
                    albedo: Albedo {
                        reflected: acc_r.estimate(),
                        transmitted: acc_t.estimate(),
                    },
                    walks: n,
                    lost,
                    lost_weight: lost_w.map(|w| w / n.max(1) as f64),
                }
            };
        let wi = normalize(wi);
        let Some(o) = orient(&self.stack, wi, None) else {
            for _ in 0..n {
                acc_f.iter_mut().for_each(|a| a.push([0.0; 3]));
                acc_r.push([0.0; 3]);
                acc_t.push([0.0; 3]);
            }
            return finish(acc_f, acc_r, acc_t, 0, [0.0; 3]);
        };
        let bins: Vec<Bin> = wos
            .iter()
            .map(|&w| Bin::new(o.apply(w), self.settings.half_angle))
            .collect();
        let up = o.wi[2] > 0.0;
        for k in 0..n {
            let mut rng = WalkRng::new(seed, query, k, Stream::BruteForce);
            let (mut xr, mut xt) = ([0.0; 3], [0.0; 3]);
            let mut exit = None;
            match self.walk(o.wi, &mut rng) {
                Exit::Out {
                    wo,
                    weight,
                    specular,
                } => {
                    if (wo[2] > 0.0) == up {
                        xr = weight;
                    } else {
                        xt = weight;
                    }
                    if !specular {
                        exit = Some((wo, weight));
                    }
                }
                Exit::Lost { weight } => {
                    lost += 1;
                    for (l, w) in lost_w.iter_mut().zip(weight) {
                        *l += w;
                    }
                }
                Exit::Absorbed => {}
            }
            for (a, b) in acc_f.iter_mut().zip(&bins) {
                match exit {
                    Some((wo, w)) if b.contains(wo) && b.measure > 0.0 => {
                        a.push(w.map(|x| x / b.measure))
                    }
                    _ => a.push([0.0; 3]),
                }
            }
            acc_r.push(xr);
            acc_t.push(xt);
        }
        finish(acc_f, acc_r, acc_t, lost, lost_w)
    }
}

/// A free flight of at most `t_max` along the ray in a scattering medium, with
/// the distance drawn from the hero channel's extinction; updates the
/// MIS-weighted throughput `beta` and the channel-density ratios `ratios`
/// (kept at mean 1). Returns the collision distance, or `None` if the walk
/// reaches `t_max`.
///
/// Channel `c`'s estimate is `F_c / mean_k p_k` (balance heuristic over the
/// three channels' path densities). Per event, with `h` the hero: at a
/// collision at `t` the value factor is `a_c σ_c e^{-σ_c t}` and channel `k`'s
/// density `σ_k e^{-σ_k t}`; passing `t_max` has value and probability
/// `e^{-σ t_max}`. Both are divided by the hero's density to stay finite.
fn flight(
    m: &SlabMedium,
    sigma_t: [f64; 3],
    t_max: f64,
    hero: usize,
    u: f64,
    beta: &mut [f64; 3],
    ratios: &mut [f64; 3],
) -> Option<f64> {
    let sh = sigma_t[hero];
    let t = if sh > 0.0 {
        -(1.0 - u).ln() / sh
    } else {
        f64::INFINITY
    };
    let collide = t < t_max;
    let dist = if collide { t } else { t_max };
    let mut y = [0.0; 3];
    let mut x = [0.0; 3];
    for c in 0..3 {
        let s = sigma_t[c];
        let rel = if dist.is_finite() {
            (-(s - sh) * dist).clamp(-700.0, 700.0).exp()
        } else if s == sh {
            1.0
        } else {
            0.0
        };
        y[c] = if collide { s / sh * rel } else { rel };
        x[c] = if collide { m.albedo[c] * y[c] } else { y[c] };
    }
    let mean = (0..3).map(|c| ratios[c] * y[c]).sum::<f64>() / 3.0;
    if mean > 0.0 {
        for c in 0..3 {
            ratios[c] = ratios[c] * y[c] / mean;
            beta[c] *= x[c] / mean;
        }
    } else {
        *beta = [0.0; 3];
    }
    collide.then_some(t)
}

/// Henyey–Greenstein sampling around the travel direction `d` (exact
/// inversion of the cdf of `μ = d·d'`; forward for `g > 0`).
fn hg_sample(g: f64, d: V3<f64>, u1: f64, u2: f64) -> V3<f64> {
    let mu = if g.abs() < 1e-3 {
        1.0 - 2.0 * u1
    } else {
        let s = (1.0 - g * g) / (1.0 - g + 2.0 * g * u1);
        (1.0 + g * g - s * s) / (2.0 * g)
    }
    .clamp(-1.0, 1.0);
    let sin = (1.0 - mu * mu).max(0.0).sqrt();
    let (sp, cp) = (2.0 * PI * u2).sin_cos();
    let (t, b) = basis([d.x, d.y, d.z]);
    let w = [
        mu * d.x + sin * (cp * t[0] + sp * b[0]),
        mu * d.y + sin * (cp * t[1] + sp * b[1]),
        mu * d.z + sin * (cp * t[2] + sp * b[2]),
    ];
    let w = normalize(w);
    V3::new(w[0], w[1], w[2])
}

/// Two unit vectors completing the unit vector `n` to an orthonormal basis.
fn basis(n: [f64; 3]) -> ([f64; 3], [f64; 3]) {
    let helper = if n[0].abs() < 0.6 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let t = normalize(cross(helper, n));
    let b = cross(n, t);
    (t, b)
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn normalize(a: [f64; 3]) -> [f64; 3] {
    let l = dot(a, a).sqrt();
    if l > 0.0 {
        a.map(|x| x / l)
    } else {
        [0.0, 0.0, 1.0]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cap_integral_closed_form_matches_quadrature_near_the_horizon() {
        // Just inside the closed-form region, the quadrature branch (forced by
        // a tiny perturbation across the threshold) must agree with it.
        let d = 10f64.to_radians();
        let th = std::f64::consts::FRAC_PI_2 - d;
        let a = [th.sin(), 0.0, th.cos()];
        let closed = PI * d.sin().powi(2) * th.cos();
        let th2 = th + 1e-9;
        let quad = cap_cos_integral([th2.sin(), 0.0, th2.cos()], d);
        assert!((cap_cos_integral(a, d) - closed).abs() < 1e-15);
        assert!((quad - closed).abs() < 1e-6 * closed, "{quad} vs {closed}");
    }

    #[test]
    fn cap_integral_at_the_horizon_by_monte_carlo() {
        // A cone centred on the horizon: half of it is cut off.
        let d = 20f64.to_radians();
        let a = [1.0, 0.0, 1e-12];
        let bin = Bin::new(a, d);
        let mut rng = WalkRng::new(3, 0, 0, Stream::BruteForce);
        let n = 400_000;
        let mut s = 0.0;
        for _ in 0..n {
            let w = bin.sample_cone(rng.uniform() as f64, rng.uniform() as f64);
            if bin.contains(w) {
                s += w[2].abs();
            }
        }
        // Exactly: ∫ sin²θ dθ over [0, d] times ∫ sin ψ dψ over the upper half.
        let exact = d - d.sin() * d.cos();
        // (`measure` is a 4096-point midpoint quadrature here: about 1e-8.)
        assert!(
            (bin.measure() - exact).abs() < 1e-6 * exact,
            "{} vs {exact}",
            bin.measure()
        );
        // The cone sampler and `contains` by Monte Carlo (relative standard
        // error about 0.2 %: 4σ).
        let mc = s / n as f64 * bin.cone_solid_angle();
        let rel = (mc - exact).abs() / exact;
        assert!(rel < 0.008, "{mc} vs {exact}");
    }

    #[test]
    fn hg_sampler_has_mean_cosine_g() {
        // For Henyey–Greenstein, E[μ] = g and E[μ²] = (1 + 2g²)/3.
        for g in [-0.7, 0.0, 0.5, 0.9] {
            let mut rng = WalkRng::new(5, 1, 0, Stream::BruteForce);
            let d = V3::new(0.6, 0.0, -0.8);
            let n = 200_000;
            let (mut s1, mut s2, mut s4) = (0.0, 0.0, 0.0);
            for _ in 0..n {
                let w = hg_sample(g, d, rng.uniform() as f64, rng.uniform() as f64);
                let mu = w.x * d.x + w.y * d.y + w.z * d.z;
                s1 += mu;
                s2 += mu * mu;
                s4 += mu.powi(4);
            }
            let (m1, m2) = (s1 / n as f64, s2 / n as f64);
            let se = ((m2 - m1 * m1) / n as f64).sqrt();
            assert!((m1 - g).abs() < 5.0 * se, "g {g}: mean {m1} ± {se}");
            let se2 = ((s4 / n as f64 - m2 * m2) / n as f64).sqrt();
            let e2 = (1.0 + 2.0 * g * g) / 3.0;
            assert!(
                (m2 - e2).abs() < 5.0 * se2,
                "g {g}: E[μ²] {m2} ± {se2} vs {e2}"
            );
        }
    }
}
