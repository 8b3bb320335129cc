//! Independent f64 references for the tests.
//!
//! Everything here is written from the formulas (Fresnel's equations, Walter
//! et al. 2007 for rough dielectrics, Henyey–Greenstein), not from strata's
//! kernels, so a bug in the library cannot hide in both sides of a comparison.
//! Directions follow strata's conventions: `a` is the direction light arrives
//! from, `b` the direction it leaves along, both pointing away from the
//! interface; `f(a → b)` is the radiance BSDF without the cosine.
#![allow(dead_code)]

use std::f64::consts::PI;

/// Unpolarized Fresnel reflectance of light in a medium of IOR `n1` hitting one
/// of IOR `n2` at incidence cosine `ci` (1 under total internal reflection).
pub fn fresnel(ci: f64, n1: f64, n2: f64) -> f64 {
    let ci = ci.abs().min(1.0);
    let s2t = (n1 / n2).powi(2) * (1.0 - ci * ci);
    if s2t >= 1.0 {
        return 1.0;
    }
    let ct = (1.0 - s2t).sqrt();
    let rs = (n1 * ci - n2 * ct) / (n1 * ci + n2 * ct);
    let rp = (n2 * ci - n1 * ct) / (n2 * ci + n1 * ct);
    0.5 * (rs * rs + rp * rp)
}

/// A complex number, just enough for the conductor Fresnel equations.
#[derive(Clone, Copy, Debug)]
struct C(f64, f64);

impl C {
    fn add(self, o: C) -> C {
        C(self.0 + o.0, self.1 + o.1)
    }
    fn sub(self, o: C) -> C {
        C(self.0 - o.0, self.1 - o.1)
    }
    fn mul(self, o: C) -> C {
        C(self.0 * o.0 - self.1 * o.1, self.0 * o.1 + self.1 * o.0)
    }
    fn div(self, o: C) -> C {
        let d = o.0 * o.0 + o.1 * o.1;
        C(
            (self.0 * o.0 + self.1 * o.1) / d,
            (self.1 * o.0 - self.0 * o.1) / d,
        )
    }
    fn sqrt(self) -> C {
        // Principal root.
        let r = (self.0 * self.0 + self.1 * self.1).sqrt();
        let re = (0.5 * (r + self.0)).max(0.0).sqrt();
        let im = (0.5 * (r - self.0)).max(0.0).sqrt();
        C(re, if self.1 < 0.0 { -im } else { im })
    }
    fn norm2(self) -> f64 {
        self.0 * self.0 + self.1 * self.1
    }
}

/// Unpolarized reflectance of a conductor of complex relative IOR `eta + i k`
/// at incidence cosine `ci`, from the complex Fresnel amplitudes.
pub fn fresnel_conductor(ci: f64, eta: f64, k: f64) -> f64 {
    let c = C(ci.abs().min(1.0), 0.0);
    let n = C(eta, k);
    let n2 = n.mul(n);
    let s2 = C(1.0 - c.0 * c.0, 0.0);
    let root = n2.sub(s2).sqrt();
    let rs = c.sub(root).div(c.add(root));
    let n2c = n2.mul(c);
    let rp = n2c.sub(root).div(n2c.add(root));
    0.5 * (rs.norm2() + rp.norm2())
}

/// Henyey–Greenstein phase function for the cosine `mu` between the travel
/// directions before and after scattering (forward peaked for `g > 0`).
pub fn hg(g: f64, mu: f64) -> f64 {
    (1.0 - g * g) / (4.0 * PI * (1.0 + g * g - 2.0 * g * mu).powf(1.5))
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn normalize(a: [f64; 3]) -> [f64; 3] {
    let l = dot(a, a).sqrt();
    [a[0] / l, a[1] / l, a[2] / l]
}

/// Isotropic GGX (Trowbridge–Reitz) normal distribution, `m` on the +z side.
pub fn ggx_d(alpha: f64, m: [f64; 3]) -> f64 {
    if m[2] <= 0.0 {
        return 0.0;
    }
    let a2 = alpha * alpha;
    let c2 = m[2] * m[2];
    let t = c2 * (a2 - 1.0) + 1.0;
    a2 / (PI * t * t)
}

/// Smith's Λ for GGX.
pub fn ggx_lambda(alpha: f64, w: [f64; 3]) -> f64 {
    let c2 = w[2] * w[2];
    let tan2 = (1.0 - c2).max(0.0) / c2;
    0.5 * ((1.0 + alpha * alpha * tan2).sqrt() - 1.0)
}

/// Height-correlated Smith shadowing-masking.
pub fn ggx_g(alpha: f64, a: [f64; 3], b: [f64; 3]) -> f64 {
    1.0 / (1.0 + ggx_lambda(alpha, a) + ggx_lambda(alpha, b))
}

/// Rough dielectric (GGX, height-correlated Smith) radiance BSDF `f(a → b)`:
/// reflection `F D G / (4 |a.z| |b.z|)` and Walter et al.'s transmission
/// `|a·h| |b·h| n_b² (1 - F) D G / (|a.z| |b.z| (n_a a·h + n_b b·h)²)`, with the
/// `n_b²` of radiance transport. `n_above`/`n_below` are the absolute IORs.
pub fn rough_dielectric(alpha: f64, n_above: f64, n_below: f64, a: [f64; 3], b: [f64; 3]) -> f64 {
    let (n_a, n_b) = if a[2] > 0.0 {
        (n_above, n_below)
    } else {
        (n_below, n_above)
    };
    let reflect = a[2] * b[2] > 0.0;
    let mut h = if reflect {
        normalize([a[0] + b[0], a[1] + b[1], a[2] + b[2]])
    } else {
        normalize([
            -(n_a * a[0] + n_b * b[0]),
            -(n_a * a[1] + n_b * b[1]),
            -(n_a * a[2] + n_b * b[2]),
        ])
    };
    if h[2] < 0.0 {
        h = [-h[0], -h[1], -h[2]];
    }
    let (ah, bh) = (dot(a, h), dot(b, h));
    // Each direction must see the microfacet from the side it sees the surface.
    if ah * a[2] <= 0.0 || bh * b[2] <= 0.0 {
        return 0.0;
    }
    let d = ggx_d(alpha, h);
    let g = ggx_g(alpha, a, b);
    let f = fresnel(ah, n_a, n_b);
    let (ca, cb) = (a[2].abs(), b[2].abs());
    if reflect {
        f * d * g / (4.0 * ca * cb)
    } else {
        let den = n_a * ah + n_b * bh;
        (ah * bh).abs() * n_b * n_b * (1.0 - f) * d * g / (ca * cb * den * den)
    }
}

/// Rough conductor (GGX) radiance BRDF for one channel, light from above.
pub fn rough_conductor(alpha: f64, eta: f64, k: f64, a: [f64; 3], b: [f64; 3]) -> f64 {
    if a[2] <= 0.0 || b[2] <= 0.0 {
        return 0.0;
    }
    let h = normalize([a[0] + b[0], a[1] + b[1], a[2] + b[2]]);
    fresnel_conductor(dot(a, h), eta, k) * ggx_d(alpha, h) * ggx_g(alpha, a, b)
        / (4.0 * a[2] * b[2])
}

/// Streaming mean and variance (Welford), independent of the library's.
#[derive(Clone, Copy, Debug, Default)]
pub struct Acc {
    n: u64,
    mean: f64,
    m2: f64,
}

impl Acc {
    /// Adds one sample.
    pub fn push(&mut self, x: f64) {
        self.n += 1;
        let d = x - self.mean;
        self.mean += d / self.n as f64;
        self.m2 += d * (x - self.mean);
    }
    /// The mean.
    pub fn mean(&self) -> f64 {
        self.mean
    }
    /// The standard error of the mean.
    pub fn stderr(&self) -> f64 {
        if self.n < 2 {
            return 0.0;
        }
        (self.m2 / (self.n - 1) as f64 / self.n as f64).sqrt()
    }
    /// The number of samples.
    pub fn count(&self) -> u64 {
        self.n
    }
}

/// SplitMix64: a tiny deterministic generator for quadrature jitter.
#[derive(Clone, Debug)]
pub struct SplitMix(pub u64);

impl SplitMix {
    /// A uniform in [0, 1).
    pub fn next_f64(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// ∫ f(w) |cos θ| dω over the whole sphere by jittered (stratified) sampling:
/// `replicas` independent estimates, each with one uniformly placed point per
/// cell of an `n_theta × 2 n_theta` grid in (θ, φ) per hemisphere. Returns the
/// mean and its standard error over the replicas. Unlike a fixed midpoint
/// grid, the error is unbiased even where `f` jumps (GGX lobes cut off where
/// the half vector crosses the horizon), and it comes with an error bar.
pub fn sphere_integral(
    n_theta: usize,
    replicas: usize,
    seed: u64,
    f: impl Fn([f64; 3]) -> f64,
) -> (f64, f64) {
    let n_phi = 2 * n_theta;
    let (dt, dphi) = (0.5 * PI / n_theta as f64, 2.0 * PI / n_phi as f64);
    let mut rng = SplitMix(seed);
    let mut acc = Acc::default();
    for _ in 0..replicas {
        let mut s = 0.0;
        for sign in [1.0, -1.0] {
            for i in 0..n_theta {
                for j in 0..n_phi {
                    let theta = (i as f64 + rng.next_f64()) * dt;
                    let phi = (j as f64 + rng.next_f64()) * dphi;
                    let (st, ct) = theta.sin_cos();
                    let w = [st * phi.cos(), st * phi.sin(), sign * ct];
                    s += f(w) * ct * st;
                }
            }
        }
        acc.push(s * dt * dphi);
    }
    (acc.mean(), acc.stderr())
}
