//! A medium's validated phase function, and its lanes.

use super::description::{ComponentKind, FlakeScattering, Flakes, PhaseDesc};
use super::error::StackError;
use crate::lane::Lane;
pub use crate::phase::{PhaseKind, MAX_COMPONENTS};
use crate::phase::{PhaseLanes, PHASE_ROW};

/// The smallest SGGX roughness: below it `r²` and `1 / r²` leave the
/// range single precision holds with the margin the kernels need
/// (docs/numerics.md); a roughness of 1e-4 is already a mirror to 1e-8 rad.
pub const MIN_SGGX_ROUGHNESS: f64 = 1e-4;

/// How far from 1 a mixture's weights may sum, or an SGGX axis's length be,
/// before it is an error rather than rounding in the file.
const UNIT_TOLERANCE: f64 = 1e-3;

/// A validated phase function.
#[derive(Clone, Debug, PartialEq)]
pub enum Phase {
    /// Henyey–Greenstein with asymmetry `g` in (−1, 1) (0: isotropic).
    Hg {
        /// Mean cosine of the scattering angle.
        g: f64,
    },
    /// Henyey–Greenstein lobes `(weight, g)`, 1 to [`MAX_COMPONENTS`] of
    /// them, the weights summing to 1 exactly.
    Mixture(Vec<(f64, f64)>),
    /// SGGX microflakes with `S = across · I + (along − across) a aᵀ`.
    Sggx {
        /// Unit axis `a`.
        axis: [f64; 3],
        /// Eigenvalue of S along the axis.
        along: f64,
        /// Eigenvalue of S across it.
        across: f64,
        /// Diffuse flakes (else specular).
        diffuse: bool,
    },
}

impl Phase {
    /// What it asks of a walk.
    pub fn kind(&self) -> PhaseKind {
        match self {
            Phase::Hg { .. } => PhaseKind::Hg,
            Phase::Mixture(c) => PhaseKind::Mixture(c.len() as u8),
            Phase::Sggx { diffuse: false, .. } => PhaseKind::SggxSpecular,
            Phase::Sggx { diffuse: true, .. } => PhaseKind::SggxDiffuse,
        }
    }

    /// The Henyey–Greenstein asymmetry, for an HG (or isotropic) phase.
    pub fn g(&self) -> Option<f64> {
        match self {
            Phase::Hg { g } => Some(*g),
            _ => None,
        }
    }

    /// The scale of the extinction along the unit direction `w`:
    /// `sqrt(wᵀ S w)` for SGGX, 1 otherwise.
    pub fn sigma_scale(&self, w: [f64; 3]) -> f64 {
        match self {
            Phase::Sggx {
                axis,
                along,
                across,
                ..
            } => {
                let c = w[0] * axis[0] + w[1] * axis[1] + w[2] * axis[2];
                let n2 = (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).max(c * c);
                (along * c * c + across * (n2 - c * c)).sqrt()
            }
            _ => 1.0,
        }
    }

    /// Validates the phase of layer `layer`'s medium.
    pub(crate) fn new(layer: usize, desc: &PhaseDesc) -> Result<Phase, StackError> {
        let li = Some(layer);
        let number = |field: &str, v: f64| {
            if v.is_finite() {
                Ok(v)
            } else {
                Err(StackError::new(li, field, v, "must be a finite number"))
            }
        };
        let asymmetry = |field: &str, g: f64| {
            let g = number(field, g)?;
            if g.abs() >= 1.0 {
                return Err(StackError::new(li, field, g, "must be in (-1, 1)"));
            }
            Ok(g)
        };
        match desc {
            PhaseDesc::Isotropic {} => Ok(Phase::Hg { g: 0.0 }),
            PhaseDesc::Hg { g } => Ok(Phase::Hg {
                g: asymmetry("medium.phase.g", *g)?,
            }),
            PhaseDesc::Mixture { components } => {
                let field = "medium.phase.components";
                if components.is_empty() || components.len() > MAX_COMPONENTS {
                    return Err(StackError::new(
                        li,
                        field,
                        components.len() as f64,
                        &format!("a mixture needs 1 to {MAX_COMPONENTS} components"),
                    ));
                }
                let mut lobes = Vec::with_capacity(components.len());
                for (k, c) in components.iter().enumerate() {
                    let f = |name: &str| format!("{field}[{k}].{name}");
                    let w = number(&f("weight"), c.weight)?;
                    if !(w > 0.0 && w <= 1.0) {
                        return Err(StackError::new(li, &f("weight"), w, "must be in (0, 1]"));
                    }
                    let g = match (c.kind, c.g) {
                        (ComponentKind::Hg, Some(g)) => asymmetry(&f("g"), g)?,
                        (ComponentKind::Hg, None) => {
                            return Err(StackError::msg(li, &f("g"), "an hg lobe needs `g`"))
                        }
                        (ComponentKind::Isotropic, None) => 0.0,
                        (ComponentKind::Isotropic, Some(g)) => {
                            return Err(StackError::new(
                                li,
                                &f("g"),
                                g,
                                "an isotropic lobe has no `g`",
                            ))
                        }
                    };
                    lobes.push((w, g));
                }
                let sum: f64 = lobes.iter().map(|l| l.0).sum();
                if (sum - 1.0).abs() > UNIT_TOLERANCE {
                    return Err(StackError::new(
                        li,
                        &format!("{field}[..].weight"),
                        sum,
                        "the weights must sum to 1",
                    ));
                }
                for l in &mut lobes {
                    l.0 /= sum;
                }
                Ok(Phase::Mixture(lobes))
            }
            PhaseDesc::Sggx {
                flakes,
                axis,
                roughness,
                scattering,
            } => {
                let field = "medium.phase.axis";
                if !axis.iter().all(|x| x.is_finite()) {
                    return Err(StackError::new_rgb(li, field, *axis, "must be finite"));
                }
                let len = axis.iter().map(|x| x * x).sum::<f64>().sqrt();
                if (len - 1.0).abs() > UNIT_TOLERANCE {
                    return Err(StackError::new_rgb(
                        li,
                        field,
                        *axis,
                        &format!("must be a unit vector (its length is {len})"),
                    ));
                }
                let r = number("medium.phase.roughness", *roughness)?;
                if !(MIN_SGGX_ROUGHNESS..=1.0).contains(&r) {
                    return Err(StackError::new(
                        li,
                        "medium.phase.roughness",
                        r,
                        &format!("must be in [{MIN_SGGX_ROUGHNESS}, 1]"),
                    ));
                }
                let r2 = r * r;
                let (along, across) = match flakes {
                    Flakes::Surface => (1.0, r2),
                    Flakes::Fiber => (r2, 1.0),
                };
                Ok(Phase::Sggx {
                    axis: axis.map(|x| x / len),
                    along,
                    across,
                    diffuse: *scattering == FlakeScattering::Diffuse,
                })
            }
        }
    }
}

impl<L: Lane> PhaseLanes<L> {
    /// The lanes of `phase`, as a layer of kind `kind` runs it (an absorbing
    /// layer keeps only what its extinction needs).
    pub fn new(phase: &Phase, kind: PhaseKind) -> Self {
        let mut p = [0.0; PHASE_ROW];
        match phase {
            Phase::Mixture(lobes) => {
                for (k, &(w, g)) in lobes.iter().enumerate() {
                    p[k] = w;
                    p[MAX_COMPONENTS + k] = g;
                }
            }
            Phase::Sggx {
                axis,
                along,
                across,
                ..
            } => {
                p[..3].copy_from_slice(axis);
                p[3] = *along;
                p[4] = *across;
            }
            Phase::Hg { .. } => {}
        }
        PhaseLanes {
            kind,
            g: L::splat(phase.g().unwrap_or(0.0)),
            p: p.map(L::splat),
        }
    }
}
