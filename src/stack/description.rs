//! The material description as read from TOML or JSON (serde), before validation.
//!
//! The format is documented in `docs/materials.md`. Every RGB field accepts a
//! single number (grey) or three; roughness accepts one number (isotropic) or
//! `[alpha_x, alpha_y]`.

use serde::{Deserialize, Serialize};

/// A value that may be given once for all channels or per RGB channel.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum RgbParam {
    /// The same value in every channel.
    Grey(f64),
    /// One value per channel.
    Rgb([f64; 3]),
}

impl RgbParam {
    /// As three channels.
    pub fn rgb(self) -> [f64; 3] {
        match self {
            RgbParam::Grey(v) => [v; 3],
            RgbParam::Rgb(a) => a,
        }
    }
}

/// GGX alpha: one value (isotropic) or `[alpha_x, alpha_y]`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Roughness {
    /// Isotropic alpha.
    Isotropic(f64),
    /// `[alpha_x, alpha_y]`.
    Anisotropic([f64; 2]),
}

impl Default for Roughness {
    fn default() -> Self {
        Roughness::Isotropic(0.0)
    }
}

impl Roughness {
    /// `[alpha_x, alpha_y]`.
    pub fn alphas(self) -> [f64; 2] {
        match self {
            Roughness::Isotropic(a) => [a, a],
            Roughness::Anisotropic(a) => a,
        }
    }
}

/// Microfacet normal distribution.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Distribution {
    /// Trowbridge–Reitz (GGX), the default.
    #[default]
    Ggx,
    /// Beckmann.
    Beckmann,
}

/// Smith shadowing-masking form.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Shadowing {
    /// Height-correlated `1 / (1 + Λ(a) + Λ(b))`, the default (pbrt-v4).
    #[default]
    Correlated,
    /// Separable `G1(a) G1(b)` (Mitsuba, the authors' code).
    Separable,
}

/// One interface.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum InterfaceDesc {
    /// A dielectric boundary; `ior` is the IOR of the region below it.
    Dielectric {
        /// IOR of the region below (for the bottom interface: the exterior below).
        ior: f64,
        /// GGX alpha; 0 is smooth.
        #[serde(default)]
        roughness: Roughness,
        /// Normal distribution.
        #[serde(default)]
        distribution: Distribution,
        /// Shadowing form.
        #[serde(default)]
        shadowing: Shadowing,
    },
    /// An opaque conductor; complex IOR relative to vacuum, by preset or value.
    Conductor {
        /// A named metal (see [`crate::stack::presets`]).
        #[serde(default)]
        preset: Option<String>,
        /// Real part of the IOR per channel.
        #[serde(default)]
        eta: Option<RgbParam>,
        /// Imaginary part of the IOR per channel.
        #[serde(default)]
        k: Option<RgbParam>,
        /// GGX alpha; 0 is smooth.
        #[serde(default)]
        roughness: Roughness,
        /// Normal distribution.
        #[serde(default)]
        distribution: Distribution,
        /// Shadowing form.
        #[serde(default)]
        shadowing: Shadowing,
    },
    /// An opaque Lambertian reflector.
    Diffuse {
        /// Reflectance per channel.
        albedo: RgbParam,
    },
}

/// Phase function of a medium.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum PhaseDesc {
    /// Isotropic scattering.
    #[default]
    Isotropic,
    /// Henyey–Greenstein with asymmetry `g` in (-1, 1).
    Hg {
        /// Mean cosine of the scattering angle.
        g: f64,
    },
}

/// A homogeneous medium below an interface.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MediumDesc {
    /// Geometric thickness (any unit; `sigma_t` is per that unit).
    pub thickness: f64,
    /// Extinction coefficient per channel.
    pub sigma_t: RgbParam,
    /// Single-scattering albedo per channel; 0 is a pure absorber.
    #[serde(default = "white")]
    pub albedo: RgbParam,
    /// Phase function.
    #[serde(default)]
    pub phase: PhaseDesc,
}

fn white() -> RgbParam {
    RgbParam::Grey(1.0)
}

/// One entry of the stack: an interface and the medium below it, if any.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LayerDesc {
    /// The interface.
    pub interface: InterfaceDesc,
    /// The medium below it (a clear gap if absent).
    #[serde(default)]
    pub medium: Option<MediumDesc>,
}

/// A whole material: interfaces listed top to bottom.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialDesc {
    /// Free text saying what the material models (ignored by the physics; JSON
    /// has no comments, so this is where a JSON file says what it is).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub description: Option<String>,
    /// IOR of the exterior above the top interface.
    #[serde(default = "one")]
    pub exterior_ior: f64,
    /// Mirror light arriving from below an opaque stack so the top faces it.
    #[serde(default)]
    pub two_sided: bool,
    /// Layers, top to bottom.
    pub layers: Vec<LayerDesc>,
}

fn one() -> f64 {
    1.0
}
