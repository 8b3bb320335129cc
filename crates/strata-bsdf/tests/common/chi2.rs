//! Chi-square goodness of fit for direction samplers, after Mitsuba's `chi2`
//! harness: a histogram of sampled directions over equal-area cells of the
//! sphere in (cos θ, φ), the sampler's claimed density integrated over each cell
//! numerically (nested adaptive Gauss–Kronrod in f64), cells with fewer than 5 expected
//! samples pooled, and a p-value from the regularized incomplete gamma
//! function. Written for these tests from the textbook formulas; no code is
//! shared with the crate under test.
//!
//! Samples a sampler reports as invalid carry probability mass that is missing
//! from the histogram: they form one extra bucket whose expected count is
//! `N (1 - ∫ pdf)`, and the test also checks `∫ pdf` against the fraction of
//! valid samples with a binomial standard error.

use std::f64::consts::{PI, TAU};
use strata_bsdf::rng::{Stream, WalkRng};

// ---------------------------------------------------------------------------
// Special functions
// ---------------------------------------------------------------------------

/// ln Γ(x) for x > 0 (Lanczos, g = 7, 9 terms; relative error ~1e-15).
pub fn ln_gamma(x: f64) -> f64 {
    const G: f64 = 7.0;
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        // Reflection: Γ(x) Γ(1 - x) = π / sin(πx).
        return (PI / (PI * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + G + 0.5;
    for (i, c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * (TAU).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// The regularized lower incomplete gamma function P(a, x).
pub fn gamma_p(a: f64, x: f64) -> f64 {
    1.0 - gamma_q(a, x)
}

/// The regularized upper incomplete gamma function Q(a, x) = 1 - P(a, x):
/// the power series of P for x < a + 1, Legendre's continued fraction for Q
/// (modified Lentz) elsewhere.
pub fn gamma_q(a: f64, x: f64) -> f64 {
    assert!(a > 0.0 && x >= 0.0, "gamma_q({a}, {x})");
    if x == 0.0 {
        return 1.0;
    }
    let ln_pre = a * x.ln() - x - ln_gamma(a);
    if x < a + 1.0 {
        // P = x^a e^-x / Γ(a+1) Σ x^n / ((a+1)...(a+n))
        let mut term = 1.0 / a;
        let mut sum = term;
        let mut ap = a;
        for _ in 0..100_000 {
            ap += 1.0;
            term *= x / ap;
            sum += term;
            if term.abs() < sum.abs() * 1e-16 {
                break;
            }
        }
        1.0 - sum * ln_pre.exp()
    } else {
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..100_000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-16 {
                break;
            }
        }
        ln_pre.exp() * h
    }
}

/// The survival function of the chi-square distribution with `dof` degrees of
/// freedom: P(X > stat).
pub fn chi2_sf(stat: f64, dof: f64) -> f64 {
    if stat <= 0.0 {
        return 1.0;
    }
    gamma_q(0.5 * dof, 0.5 * stat)
}

/// The per-test significance that keeps the family-wise false-rejection rate of
/// `m` independent tests at `alpha` (Šidák).
pub fn sidak(alpha: f64, m: usize) -> f64 {
    1.0 - (1.0 - alpha).powf(1.0 / m as f64)
}

// ---------------------------------------------------------------------------
// Quadrature
// ---------------------------------------------------------------------------

/// An integral and an estimate of its absolute error.
#[derive(Clone, Copy, Debug, Default)]
pub struct Quad {
    /// The integral.
    pub value: f64,
    /// Estimated absolute error (|Kronrod - Gauss| of the accepted intervals).
    pub err: f64,
}

/// Nodes (descending, the last is 0) and weights of the 15-point Kronrod rule
/// and the weights of the embedded 7-point Gauss rule (on the odd nodes).
const XGK: [f64; 8] = [
    0.991_455_371_120_812_6,
    0.949_107_912_342_758_5,
    0.864_864_423_359_769_1,
    0.741_531_185_599_394_4,
    0.586_087_235_467_691_1,
    0.405_845_151_377_397_2,
    0.207_784_955_007_898_5,
    0.0,
];
const WGK: [f64; 8] = [
    0.022_935_322_010_529_22,
    0.063_092_092_629_978_55,
    0.104_790_010_322_250_2,
    0.140_653_259_715_525_9,
    0.169_004_726_639_267_9,
    0.190_350_578_064_785_4,
    0.204_432_940_075_298_9,
    0.209_482_141_084_727_8,
];
const WG: [f64; 4] = [
    0.129_484_966_168_869_7,
    0.279_705_391_489_276_7,
    0.381_830_050_505_118_9,
    0.417_959_183_673_469_4,
];

/// One Gauss–Kronrod (7, 15) step on `[a, b]`: the Kronrod value, |K - G|,
/// and the rounding floor of the sum (below which refining cannot help).
fn gk15(f: &mut dyn FnMut(f64) -> f64, a: f64, b: f64) -> (Quad, f64) {
    let c = 0.5 * (a + b);
    let h = 0.5 * (b - a);
    let fc = f(c);
    let mut k = WGK[7] * fc;
    let mut g = WG[3] * fc;
    let mut abs = WGK[7] * fc.abs();
    for i in 0..7 {
        let (f1, f2) = (f(c - h * XGK[i]), f(c + h * XGK[i]));
        k += WGK[i] * (f1 + f2);
        abs += WGK[i] * (f1.abs() + f2.abs());
        if i % 2 == 1 {
            g += WG[i / 2] * (f1 + f2);
        }
    }
    let q = Quad {
        value: k * h,
        err: ((k - g) * h).abs(),
    };
    (q, 50.0 * f64::EPSILON * abs * h.abs())
}

/// Adaptive Gauss–Kronrod on `[a, b]` to absolute tolerance `tol`, refining
/// by bisection (half the tolerance to each half) down to `max_depth` levels
/// or to the rounding floor of the sums. With `careful`, an interval is
/// accepted only when its two halves agree with it (|K(a,b) - K(a,m) - K(m,b)|)
/// as well as with their embedded Gauss rules (|K - G|), which is much harder
/// to fool with a kink or a narrow peak but costs at least three rules;
/// otherwise |K - G| of the interval decides. The rule is open, so `f` is
/// never evaluated at `a` or `b`: a jump there is seen from inside.
pub fn gauss_kronrod(
    f: &mut dyn FnMut(f64) -> f64,
    [a, b]: [f64; 2],
    tol: f64,
    max_depth: u32,
    careful: bool,
) -> Quad {
    fn rec(
        f: &mut dyn FnMut(f64) -> f64,
        [a, b]: [f64; 2],
        (whole, floor): (Quad, f64),
        tol: f64,
        depth: u32,
        careful: bool,
    ) -> Quad {
        if !careful && (depth == 0 || whole.err <= tol.max(floor)) {
            return whole;
        }
        let m = 0.5 * (a + b);
        let (l, r) = (gk15(f, a, m), gk15(f, m, b));
        if careful {
            let err = (whole.value - l.0.value - r.0.value)
                .abs()
                .max(l.0.err + r.0.err);
            if depth == 0 || err <= tol.max(floor) {
                return Quad {
                    value: l.0.value + r.0.value,
                    err,
                };
            }
        }
        let depth = depth.saturating_sub(1);
        let l = rec(f, [a, m], l, 0.5 * tol, depth, careful);
        let r = rec(f, [m, b], r, 0.5 * tol, depth, careful);
        Quad {
            value: l.value + r.value,
            err: l.err + r.err,
        }
    }
    let whole = gk15(f, a, b);
    rec(f, [a, b], whole, tol, max_depth, careful)
}

/// ∫∫ f(x, y) over `[x0, x1] × [y0, y1]` as nested adaptive Gauss–Kronrod
/// (inner in x, outer in y) to absolute tolerance `tol` (see [`gauss_kronrod`]
/// for `careful`). Nesting adapts each direction separately, so a peak or a
/// kink that is narrow in one direction only costs refinement in that one.
pub fn integrate_2d(
    f: &dyn Fn(f64, f64) -> f64,
    [x0, x1, y0, y1]: [f64; 4],
    tol: f64,
    careful: bool,
) -> Quad {
    // The inner integrals get a tenth of the budget per unit of y.
    let inner_tol = 0.1 * tol / (y1 - y0);
    let mut inner_err = 0.0f64;
    let mut outer = |y: f64| {
        let q = gauss_kronrod(&mut |x| f(x, y), [x0, x1], inner_tol, 30, careful);
        inner_err = inner_err.max(q.err);
        q.value
    };
    let q = gauss_kronrod(&mut outer, [y0, y1], 0.9 * tol, 30, careful);
    Quad {
        value: q.value,
        err: q.err + inner_err * (y1 - y0),
    }
}

// ---------------------------------------------------------------------------
// The spherical histogram
// ---------------------------------------------------------------------------

/// Equal-area cells of the sphere: `n_cos` bands uniform in cos θ over [-1, 1]
/// (an even count puts a band edge on the horizon, where interface densities
/// jump) by `n_phi` sectors uniform in φ over [-π, π).
#[derive(Clone, Copy, Debug)]
pub struct SphereGrid {
    /// Bands in cos θ.
    pub n_cos: usize,
    /// Sectors in φ.
    pub n_phi: usize,
}

impl SphereGrid {
    /// Number of cells.
    pub fn len(&self) -> usize {
        self.n_cos * self.n_phi
    }

    /// The cell of a (not necessarily unit) direction.
    pub fn cell(&self, d: [f64; 3]) -> usize {
        let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let c = (d[2] / l).clamp(-1.0, 1.0);
        let phi = d[1].atan2(d[0]);
        let i = (((c + 1.0) * 0.5 * self.n_cos as f64) as usize).min(self.n_cos - 1);
        let j = (((phi + PI) / TAU * self.n_phi as f64) as usize).min(self.n_phi - 1);
        i * self.n_phi + j
    }

    /// Integrates a density over each cell. `cos_breaks` are values of cos θ
    /// where the density may jump (cells are split there, so the jump lies on
    /// an integration boundary); `tol_for(p)` is the absolute tolerance for a
    /// cell whose integral is about `p`; `careful` selects the robust error
    /// check of [`gauss_kronrod`]. Returns the cells' integrals and the sum of
    /// their error estimates.
    pub fn integrate(
        &self,
        pdf: &dyn Fn([f64; 3]) -> f64,
        cos_breaks: &[f64],
        tol_for: &dyn Fn(f64) -> f64,
        careful: bool,
    ) -> (Vec<f64>, f64) {
        // Near the poles the integrand is not smooth in cos θ (x and y go as
        // sqrt(1 - cos θ)); with cos θ = ±(1 - t²) it is smooth in t, and
        // dcos θ = 2t dt. sin θ = t sqrt(2 - t²) exactly.
        let at = |t: f64, phi: f64, z: f64| {
            let s = t * (2.0 - t * t).max(0.0).sqrt();
            [s * phi.cos(), s * phi.sin(), z]
        };
        let north = |t: f64, phi: f64| 2.0 * t * pdf(at(t, phi, 1.0 - t * t));
        let south = |t: f64, phi: f64| 2.0 * t * pdf(at(t, phi, t * t - 1.0));
        let mut cells = vec![0.0; self.len()];
        let mut err = 0.0;
        for i in 0..self.n_cos {
            let c0 = -1.0 + 2.0 * i as f64 / self.n_cos as f64;
            let c1 = -1.0 + 2.0 * (i + 1) as f64 / self.n_cos as f64;
            let mut edges = vec![c0];
            edges.extend(cos_breaks.iter().copied().filter(|&b| b > c0 && b < c1));
            edges.push(c1);
            edges.sort_by(f64::total_cmp);
            let up = c0 + c1 > 0.0;
            for j in 0..self.n_phi {
                let p0 = -PI + TAU * j as f64 / self.n_phi as f64;
                let p1 = -PI + TAU * (j + 1) as f64 / self.n_phi as f64;
                let mut q = Quad::default();
                for w in edges.windows(2) {
                    let (t0, t1) = if up {
                        ((1.0 - w[1]).max(0.0).sqrt(), (1.0 - w[0]).sqrt())
                    } else {
                        ((1.0 + w[0]).max(0.0).sqrt(), (1.0 + w[1]).sqrt())
                    };
                    let g: &dyn Fn(f64, f64) -> f64 = if up { &north } else { &south };
                    // A first pass sizes the tolerance.
                    let rect = [t0, t1, p0, p1];
                    let rough = integrate_2d(g, rect, f64::INFINITY, false);
                    let r = integrate_2d(g, rect, tol_for(rough.value.abs()), careful);
                    q.value += r.value;
                    q.err += r.err;
                }
                cells[i * self.n_phi + j] = q.value;
                err += q.err;
            }
        }
        (cells, err)
    }
}

/// The result of a chi-square test.
#[derive(Clone, Debug)]
pub struct Chi2 {
    /// The statistic Σ (O - E)² / E over the pooled buckets.
    pub stat: f64,
    /// Degrees of freedom (buckets - 1).
    pub dof: usize,
    /// P(X > stat).
    pub p_value: f64,
}

/// Pearson's chi-square test of `observed` counts against `expected` counts
/// with equal totals. Buckets expecting fewer than 5 are pooled (and the pool
/// merged into the smallest other bucket if it still expects fewer than 5).
/// A bucket that expects exactly nothing but received samples is an error.
pub fn chi2_test(observed: &[u64], expected: &[f64]) -> Result<Chi2, String> {
    assert_eq!(observed.len(), expected.len());
    let mut buckets: Vec<(f64, f64)> = Vec::new();
    let (mut pool_o, mut pool_e) = (0.0, 0.0);
    for (k, (&o, &e)) in observed.iter().zip(expected).enumerate() {
        if e <= 0.0 && o > 0 {
            return Err(format!(
                "bucket {k} received {o} samples where the density integrates to {e}"
            ));
        }
        if e < 5.0 {
            pool_o += o as f64;
            pool_e += e.max(0.0);
        } else {
            buckets.push((o as f64, e));
        }
    }
    if pool_e >= 5.0 {
        buckets.push((pool_o, pool_e));
    } else if pool_o > 0.0 || pool_e > 0.0 {
        let k = (0..buckets.len())
            .min_by(|&a, &b| buckets[a].1.total_cmp(&buckets[b].1))
            .ok_or("every bucket expects fewer than 5 samples")?;
        buckets[k].0 += pool_o;
        buckets[k].1 += pool_e;
    }
    if buckets.len() < 2 {
        return Err("fewer than two buckets after pooling".into());
    }
    let stat: f64 = buckets.iter().map(|(o, e)| (o - e) * (o - e) / e).sum();
    let dof = buckets.len() - 1;
    Ok(Chi2 {
        stat,
        dof,
        p_value: chi2_sf(stat, dof as f64),
    })
}

/// A goodness-of-fit run of one sampler against its density.
pub struct Fit<'a> {
    /// Name for messages.
    pub name: String,
    /// The histogram's cells.
    pub grid: SphereGrid,
    /// Number of samples drawn.
    pub samples: usize,
    /// Seed of the sample stream.
    pub seed: u64,
    /// Draws one direction from four uniforms, or `None` when the sampler
    /// reports the sample invalid.
    pub sampler: &'a dyn Fn([f32; 4]) -> Option<[f32; 3]>,
    /// The claimed density over the sphere, in f64.
    pub pdf: &'a dyn Fn([f64; 3]) -> f64,
    /// Values of cos θ where the density may jump (see [`SphereGrid::integrate`]).
    pub cos_breaks: Vec<f64>,
}

/// What a fit measured.
#[derive(Clone, Debug)]
pub struct FitReport {
    /// The chi-square test over cells plus the invalid bucket.
    pub chi2: Chi2,
    /// Fraction of valid samples.
    pub valid_fraction: f64,
    /// ∫ pdf over the sphere.
    pub pdf_mass: f64,
    /// Estimated quadrature error of `pdf_mass`.
    pub quad_err: f64,
    /// z-score of the valid count against `N ∫ pdf`.
    pub mass_z: f64,
}

impl Fit<'_> {
    /// Draws the samples, integrates the density, and asserts that (1) the
    /// valid fraction matches ∫ pdf within 4 binomial standard errors (plus
    /// twice the quadrature's own error estimate, itself required below 2e-5,
    /// and one count for rounding) and (2) the chi-square p-value exceeds
    /// `alpha`.
    #[track_caller]
    pub fn check(&self, alpha: f64) -> FitReport {
        let n = self.samples;
        let mut rng = WalkRng::new(self.seed, 0, 0, Stream::Walk);
        let mut counts = vec![0u64; self.grid.len() + 1];
        let invalid = self.grid.len();
        for _ in 0..n {
            let u = [rng.uniform(), rng.uniform(), rng.uniform(), rng.uniform()];
            match (self.sampler)(u) {
                Some(d) => {
                    assert!(
                        d.iter().all(|x| x.is_finite()),
                        "{}: non-finite sample {d:?} from {u:?}",
                        self.name
                    );
                    counts[self.grid.cell(d.map(f64::from))] += 1;
                }
                None => counts[invalid] += 1,
            }
        }
        // Per-cell tolerance: 1% of the standard deviation of the cell's count
        // (in probability units), so quadrature error cannot move the statistic.
        // The fast |K - G| error check suffices here: on every fit of
        // tests/kernels_chi2.rs the careful check changed ∫ pdf by < 4e-7.
        let nf = n as f64;
        let tol = move |p: f64| 1e-2 * ((p + 1.0 / nf) / nf).sqrt();
        let (cells, quad_err) = self.grid.integrate(self.pdf, &self.cos_breaks, &tol, false);
        let mass: f64 = cells.iter().sum();
        let mut expected: Vec<f64> = cells.iter().map(|p| p * nf).collect();
        expected.push((1.0 - mass).max(0.0) * nf);
        let valid = n as u64 - counts[invalid];
        let valid_fraction = valid as f64 / nf;

        // (1) Mass: binomial with success probability ∫ pdf.
        let p = mass.clamp(0.0, 1.0);
        let sd = (nf * p * (1.0 - p)).sqrt();
        let diff = (valid as f64 - nf * mass).abs();
        let allowed = 4.0 * sd + 2.0 * nf * quad_err + 1.0;
        let mass_z = if sd > 0.0 { diff / sd } else { 0.0 };
        assert!(
            quad_err < 2e-5,
            "{}: quadrature error {quad_err:e} is too large to check the mass",
            self.name
        );
        assert!(
            diff <= allowed,
            "{}: {valid} valid of {n} samples but ∫ pdf = {mass} ± {quad_err:e} (expected {:.1} ± {sd:.1}, z = {mass_z:.2})",
            self.name,
            nf * mass
        );

        // (2) Shape: chi-square over cells plus the invalid bucket.
        let chi2 = chi2_test(&counts, &expected).unwrap_or_else(|e| panic!("{}: {e}", self.name));
        if chi2.p_value <= alpha {
            // Show the worst cells before failing.
            let mut worst: Vec<(usize, f64)> = counts
                .iter()
                .zip(&expected)
                .enumerate()
                .filter(|(_, (_, &e))| e >= 5.0)
                .map(|(k, (&o, &e))| (k, (o as f64 - e) / e.sqrt()))
                .collect();
            worst.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
            for &(k, z) in worst.iter().take(10) {
                let (i, j) = (k / self.grid.n_phi, k % self.grid.n_phi);
                eprintln!(
                    "  cell cos band {i} phi sector {j}: observed {} expected {:.1} (z {z:.2})",
                    counts[k], expected[k]
                );
            }
        }
        assert!(
            chi2.p_value > alpha,
            "{}: chi-square {:.1} with {} dof, p = {:e} <= {alpha:e} (valid {valid_fraction}, ∫ pdf {mass})",
            self.name,
            chi2.stat,
            chi2.dof,
            chi2.p_value
        );
        FitReport {
            chi2,
            valid_fraction,
            pdf_mass: mass,
            quad_err,
            mass_z,
        }
    }
}
