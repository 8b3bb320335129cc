//! A weighted sum of Henyey–Greenstein lobes (a medium holding particles of
//! several kinds with one extinction: the paper's jade is
//! `0.8 HG(0.8) + 0.2 HG(−0.8)`).
//!
//! Sampling spends no extra uniform on the choice of lobe: the first uniform
//! picks the lobe by its weight and is stretched back to a full uniform for
//! it, so the sampler stays exact (its density is [`eval`], its weight 1).

use super::hg::{hg_eval_dirs, hg_sample};
use crate::lane::{Lane, LaneMask, V3};

/// A mixture's lobes: `weights` (summing to 1) and asymmetries `g`, per lane.
#[derive(Clone, Copy, Debug)]
pub struct Lobes<'a, L: Lane> {
    /// Each lobe's weight.
    pub weights: &'a [L],
    /// Each lobe's asymmetry.
    pub g: &'a [L],
}

/// The mixture's value from `d` into `u`.
#[inline(always)]
pub fn eval<L: Lane>(lobes: Lobes<'_, L>, d: V3<L>, u: V3<L>) -> L {
    let mut f = L::zero();
    for (&w, &g) in lobes.weights.iter().zip(lobes.g) {
        f += w * hg_eval_dirs(g, d, u);
    }
    f
}

/// A direction from the mixture about `d`, from two uniforms.
#[inline(always)]
pub fn sample<L: Lane>(lobes: Lobes<'_, L>, d: V3<L>, u1: L, u2: L) -> V3<L> {
    // The lobe k whose share [c_k, c_k + w_k) of [0, 1) holds u1; the last
    // lobe takes whatever rounding leaves above the sum of the weights.
    let n = lobes.weights.len();
    let mut g = lobes.g[n - 1];
    let mut start = L::zero();
    let mut width = lobes.weights[n - 1];
    let mut c = L::zero();
    let mut found = L::Mask::splat(false);
    for k in 0..n - 1 {
        let w = lobes.weights[k];
        let here = !found & u1.lt(c + w);
        g = L::select(here, lobes.g[k], g);
        start = L::select(here, c, start);
        width = L::select(here, w, width);
        found = found | here;
        c += w;
    }
    let start = L::select(found, start, c);
    let width = L::select(found, width, (L::one() - c).max(L::zero()));
    let ok = width.gt(L::zero());
    let v = L::div_or_zero(u1 - start, width, ok).clamp(L::zero(), L::splat(1.0 - 1e-7));
    hg_sample(g, d, v, u2)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The mixture integrates to 1 and is the weighted sum of its lobes.
    #[test]
    fn mixture_is_normalized() {
        let w = [0.8f64, 0.2];
        let g = [0.8f64, -0.8];
        let lobes = Lobes { weights: &w, g: &g };
        let n = 200_000;
        let d = V3::new(0.0, 0.0, 1.0);
        let mut s = 0.0;
        for i in 0..n {
            let mu = -1.0 + (i as f64 + 0.5) * 2.0 / n as f64;
            let u = V3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
            s += eval(lobes, d, u) * 2.0 / n as f64;
        }
        s *= 2.0 * std::f64::consts::PI;
        assert!((s - 1.0).abs() < 1e-3, "{s}");
    }
}
