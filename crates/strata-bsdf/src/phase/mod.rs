//! Phase functions of the media, over lanes: evaluation, sampling and the
//! direction-dependent scale of the extinction.
//!
//! Directions are *travel* directions: a walk moving along `d` scatters into
//! `u`. A layer's phase kind ([`PhaseKind`]) is part of the stack's shape, the
//! same in every lane, so a walk branches on it once per event and a medium
//! pays only for what its phase function needs:
//!
//! | kind | value | sampling | uniforms: sample / estimate | extinction |
//! |---|---|---|---|---|
//! | Henyey–Greenstein | closed form | exact inversion | 2 / 0 | constant |
//! | mixture of HG lobes | closed form | a lobe by weight, then exact | 2 / 0 | constant |
//! | SGGX, specular flakes | closed form | visible normal, mirror | 2 / 0 | `σt sqrt(ωᵀSω)` |
//! | SGGX, diffuse flakes | one-sample estimate | visible normal, cosine lobe | 4 / 2 | `σt sqrt(ωᵀSω)` |
//!
//! Every sampler is exact: its weight is 1 and its density is the value.
//! Diffuse flakes have no closed-form phase function (Heitz et al. 2015), so
//! their value, and with it the density of their sampler, is an unbiased
//! one-sample estimate ([`sggx::Sggx::diffuse_estimate`]) wherever it is
//! needed; where a density enters nonlinearly (an MIS weight) the walks use
//! an estimate of its own, or no MIS ([`PhaseLanes::exact`]).

pub mod hg;
mod kind;
pub mod mixture;
pub mod sggx;

use crate::lane::{Lane, V3};
pub use kind::{PhaseKind, MAX_COMPONENTS};
use sggx::Sggx;

/// The parameters a phase function needs beyond `g`, in one row: a mixture's
/// weights (`0..4`) and asymmetries (`4..8`), or an SGGX axis (`0..3`) and
/// its eigenvalues along (`3`) and across (`4`) it.
pub const PHASE_ROW: usize = 8;

/// One medium's phase function in a lane type.
#[derive(Clone, Copy, Debug)]
pub struct PhaseLanes<L: Lane> {
    /// Its kind: the shape's, the same in every lane.
    pub kind: PhaseKind,
    /// Henyey–Greenstein asymmetry (0: isotropic; unused by other kinds).
    pub g: L,
    /// The rest of its parameters ([`PHASE_ROW`]).
    pub p: [L; PHASE_ROW],
}

impl PhaseLanes<f64> {
    /// This phase function on every lane of `L` (the lanes the stack makes
    /// of it, bit for bit).
    pub fn splat<L: Lane>(&self) -> PhaseLanes<L> {
        PhaseLanes {
            kind: self.kind,
            g: L::splat(self.g),
            p: self.p.map(L::splat),
        }
    }
}

impl<L: Lane> PhaseLanes<L> {
    /// Isotropic, direction-independent: what a layer without a medium has.
    pub fn isotropic() -> Self {
        PhaseLanes {
            kind: PhaseKind::Hg,
            g: L::zero(),
            p: [L::zero(); PHASE_ROW],
        }
    }

    /// How peaked the phase function is: `4π ∫ p(d → u)² du`, 1 for an
    /// isotropic one (one plus the relative variance of `p` at a uniformly
    /// random argument). Henyey–Greenstein lobes expand in Legendre
    /// polynomials as `Σ (2l + 1) g^l P_l / 4π`, so two lobes give
    /// `4π ∫ p_a p_b = Σ (2l + 1) (g_a g_b)^l = (1 + x) / (1 − x)²` with
    /// `x = g_a g_b`; a mixture sums that over pairs of lobes. 0 for the SGGX
    /// kinds, whose value depends on the direction, not on the angle alone.
    #[inline(always)]
    pub fn second_moment(&self) -> L {
        let one = L::one();
        let pair = |x: L| {
            let y = one - x;
            L::div_or_zero(one + x, y * y, y.gt(L::zero()))
        };
        match self.kind {
            PhaseKind::Hg => pair(self.g * self.g),
            PhaseKind::Mixture(n) => {
                let lobes = self.lobes(n);
                let mut m = L::zero();
                for (&wa, &ga) in lobes.weights.iter().zip(lobes.g) {
                    for (&wb, &gb) in lobes.weights.iter().zip(lobes.g) {
                        m += wa * wb * pair(ga * gb);
                    }
                }
                m
            }
            PhaseKind::SggxSpecular | PhaseKind::SggxDiffuse => L::zero(),
        }
    }

    /// The microflake distribution of an SGGX phase.
    #[inline(always)]
    pub fn sggx(&self) -> Sggx<L> {
        let p = &self.p;
        Sggx {
            axis: V3::new(p[0], p[1], p[2]),
            along: p[3],
            across: p[4],
        }
    }

    /// The extinction along `d` is the medium's `sigma_t` times this
    /// (1 unless [`PhaseKind::directional`]; callers skip it then).
    #[inline(always)]
    pub fn sigma_scale(&self, d: V3<L>) -> L {
        if self.kind.directional() {
            self.sggx().sigma(d)
        } else {
            L::one()
        }
    }

    /// Uniforms [`PhaseLanes::sample`] uses (a fixed number per kind).
    #[inline(always)]
    pub fn sample_uniforms(&self) -> usize {
        match self.kind {
            PhaseKind::SggxDiffuse => 4,
            _ => 2,
        }
    }

    /// The value has a closed form (else [`PhaseLanes::eval`] estimates it
    /// from [`PhaseLanes::estimate_uniforms`] uniforms).
    #[inline(always)]
    pub fn exact(&self) -> bool {
        self.kind != PhaseKind::SggxDiffuse
    }

    /// Uniforms [`PhaseLanes::eval`] uses: 2 where the value is estimated.
    #[inline(always)]
    pub fn estimate_uniforms(&self) -> usize {
        if self.exact() {
            0
        } else {
            2
        }
    }

    /// The phase function from `d` into `u`, which is also the density
    /// [`PhaseLanes::sample`] samples `u` with: its value, or for diffuse
    /// flakes an unbiased estimate of it from the uniforms `e`.
    #[inline(always)]
    pub fn eval(&self, d: V3<L>, u: V3<L>, e: (L, L)) -> L {
        match self.kind {
            PhaseKind::Hg => hg::hg_eval_dirs(self.g, d, u),
            PhaseKind::Mixture(n) => mixture::eval(self.lobes(n), d, u),
            PhaseKind::SggxSpecular => self.sggx().specular_eval(d, u),
            PhaseKind::SggxDiffuse => self.sggx().diffuse_estimate(d, u, e.0, e.1),
        }
    }

    /// A scattering direction from `d` (weight 1), from the first
    /// [`PhaseLanes::sample_uniforms`] of `u`.
    #[inline(always)]
    pub fn sample(&self, d: V3<L>, u: [L; 4]) -> V3<L> {
        match self.kind {
            PhaseKind::Hg => hg::hg_sample(self.g, d, u[0], u[1]),
            PhaseKind::Mixture(n) => mixture::sample(self.lobes(n), d, u[0], u[1]),
            PhaseKind::SggxSpecular => self.sggx().specular_sample(d, u[0], u[1]),
            PhaseKind::SggxDiffuse => self.sggx().diffuse_sample(d, u),
        }
    }

    /// A mixture's first `n` lobes.
    #[inline(always)]
    fn lobes(&self, n: u8) -> mixture::Lobes<'_, L> {
        mixture::Lobes {
            weights: &self.p[..n as usize],
            g: &self.p[MAX_COMPONENTS..MAX_COMPONENTS + n as usize],
        }
    }
}
