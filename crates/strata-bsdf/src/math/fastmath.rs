//! Single-precision `exp`, `expm1`, `ln` and `sin/cos` of turns, written once
//! over [`LaneBits`] so that `f32` and `F32x8` compute them with the same
//! operations in the same order, and so give bit-identical results.
//!
//! `exp`, `ln` and the sine and cosine use the classic Cephes single-precision
//! minimax fits (Moshier) with Cody–Waite range reduction, `exp_m1` a Taylor
//! polynomial near 0. Each is within 2 ulp of the correctly rounded result over
//! the ranges strata uses: `exp` and `exp_m1` on [-87, 88], `ln` on the
//! positive normal numbers, `sin_cos_turns` on [0, 1] (tested against `f64` in
//! `tests/physics/kernels_closed_forms.rs`).
//! No fused multiply-add is used: `mul_add` fuses only when FMA is compiled in,
//! which would make results depend on target features.
//!
//! Its functions are `#[inline(always)]` (docs/architecture.md, *Code
//! generation is part of the design*).

use crate::lane::traits::LaneBits;

/// e^x. Inputs below -87 (where e^x is below the smallest normal f32) give 0;
/// inputs above 88 are clamped to 88 (e^88 ≈ 1.65e38).
#[inline(always)]
pub fn exp<L: LaneBits>(x: L) -> L {
    let c = |v: f64| L::splat(v);
    let tiny = x.lt(c(-87.0));
    let x = x.clamp(c(-87.0), c(88.0));
    let n = (x * c(std::f64::consts::LOG2_E) + c(0.5)).floor();
    let r = x - n * c(0.693_359_375) - n * c(-2.121_944_4e-4);
    let z = r * r;
    let p = ((((c(1.987_569_150_0e-4) * r + c(1.398_199_950_7e-3)) * r + c(8.333_451_907_3e-3))
        * r
        + c(4.166_579_589_4e-2))
        * r
        + c(1.666_666_545_9e-1))
        * r
        + c(5.000_000_120_1e-1);
    let y = p * z + r + L::one();
    L::select(tiny, L::zero(), y * L::pow2i(n))
}

/// e^x - 1 without cancellation near 0: a Taylor polynomial (degree 11,
/// truncation error below 1e-9 relative) for |x| < ln 2, `exp(x) - 1`
/// elsewhere. The switch sits at ln 2 because below it `exp(x) - 1` would
/// magnify exp's rounding error up to fourfold (e^x in [1, 2), the result in
/// [0.25, 1)); beyond it at most twofold, which keeps the 2 ulp bound.
#[inline(always)]
pub fn exp_m1<L: LaneBits>(x: L) -> L {
    let c = |v: f64| L::splat(v);
    let ln2 = std::f64::consts::LN_2;
    let small = x.abs().lt(c(ln2));
    let s = x.clamp(c(-ln2), c(ln2));
    // Σ s^k / k!, k = 1..=11, in Horner form: 1/11!, 1/10!, ..., 1/1!.
    const INV_FACT: [f64; 11] = [
        1.0 / 39_916_800.0,
        1.0 / 3_628_800.0,
        1.0 / 362_880.0,
        1.0 / 40_320.0,
        1.0 / 5_040.0,
        1.0 / 720.0,
        1.0 / 120.0,
        1.0 / 24.0,
        1.0 / 6.0,
        1.0 / 2.0,
        1.0,
    ];
    let mut t = c(INV_FACT[0]);
    for &k in &INV_FACT[1..] {
        t = t * s + c(k);
    }
    L::select(small, t * s, exp(x) - L::one())
}

/// Natural logarithm of a positive input. Inputs below the smallest normal
/// (including 0) are raised to it, so `ln(0)` is -87.34 rather than -inf:
/// callers use it for free-flight distances, where that is a safe finite value.
#[inline(always)]
pub fn ln<L: LaneBits>(x: L) -> L {
    let c = |v: f64| L::splat(v);
    let x = x.max(c(f32::MIN_POSITIVE as f64));
    let (m, e) = x.frexp();
    let low = m.lt(c(std::f64::consts::FRAC_1_SQRT_2));
    let e = L::select(low, e - L::one(), e);
    let r = L::select(low, m + m - L::one(), m - L::one());
    let z = r * r;
    let p = ((((((((c(7.037_683_629_2e-2) * r - c(1.151_461_031_0e-1)) * r
        + c(1.167_699_874_0e-1))
        * r
        - c(1.242_014_084_6e-1))
        * r
        + c(1.424_932_278_7e-1))
        * r
        - c(1.666_805_766_5e-1))
        * r
        + c(2.000_071_476_5e-1))
        * r
        - c(2.499_999_399_3e-1))
        * r
        + c(3.333_333_117_4e-1))
        * r
        * z;
    let y = p + e * c(-2.121_944_4e-4) - c(0.5) * z;
    r + y + e * c(0.693_359_375)
}

/// `(sin 2πt, cos 2πt)`. The reduction to `[-π/4, π/4]` is exact for `t` in
/// `[0, 1]` (the azimuths strata samples); what remains is the rounding of 2π
/// and of the product, so the result is within 2 ulp (measured).
#[inline(always)]
pub fn sin_cos_turns<L: LaneBits>(t: L) -> (L, L) {
    let c = |v: f64| L::splat(v);
    let t = t - t.floor();
    let q = (t * c(4.0) + c(0.5)).floor(); // 0..=4
    let x = (t - q * c(0.25)) * c(std::f64::consts::TAU); // [-π/4, π/4)
    let z = x * x;
    let s =
        ((c(-1.951_529_589_1e-4) * z + c(8.332_160_873_6e-3)) * z - c(1.666_665_461_1e-1)) * z * x
            + x;
    let co = ((c(2.443_315_711_809_948e-5) * z - c(1.388_731_625_493_765e-3)) * z
        + c(4.166_664_568_298_827e-2))
        * z
        * z
        - c(0.5) * z
        + L::one();
    let k = q - (q * c(0.25)).floor() * c(4.0); // quadrant 0..=3
    let swap = k.eq(c(1.0)) | k.eq(c(3.0));
    let sin_neg = k.ge(c(2.0));
    let cos_neg = k.eq(c(1.0)) | k.eq(c(2.0));
    let sn = L::select(swap, co, s);
    let cs = L::select(swap, s, co);
    (L::select(sin_neg, -sn, sn), L::select(cos_neg, -cs, cs))
}
