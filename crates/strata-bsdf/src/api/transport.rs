//! Radiance or importance: which of two BSDFs a query across the stack answers.
//!
//! Light that crosses an interface into a denser medium is compressed into a
//! smaller solid angle, so radiance gains `(n_o/n_i)²` where importance does
//! not: transmission between exteriors of different IOR has two BSDFs, the
//! radiance BSDF `f(wi → wo)` and its adjoint `f*(wi → wo) = f(wo → wi)`,
//! related by `f(wo → wi) = f(wi → wo) · (n_i/n_o)²` (docs/conventions.md).
//! Reflection, and transmission between equal exteriors, is reciprocal: both
//! modes give the same numbers, bit for bit.

use crate::stack::LayerStack;

/// What flows from `wi` to `wo` in a query, and so which BSDF it answers.
///
/// `sample` walks start at `wi` (and `eval`'s are carried over to it when
/// they start at `wo`: [`crate::EvalStart`]); the mode says what that
/// direction is. A renderer that passes the direction its path arrived from as `wi`
/// (Mitsuba's `si.wi`, pbrt's `wo`) uses `Importance` for paths traced from
/// the camera (those renderers' "radiance" mode: the path carries
/// importance from the sensor, and light arrives from the sampled
/// direction) and `Radiance` for paths traced from the lights. The Mitsuba
/// plugin and the C ABI do this mapping (docs/embedding.md).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[repr(u32)]
pub enum Transport {
    /// Light flows from `wi` to `wo` (`wi` points to the light, `wo` to the
    /// viewer): `eval` is the radiance BSDF `f(wi → wo)`, and `sample(wi)`
    /// follows light. The default, and the convention of the CLI.
    #[default]
    Radiance = 0,
    /// Importance flows from `wi` to `wo` (`wi` points to the viewer, `wo` to
    /// the light): `eval` is the adjoint `f*(wi → wo) = f(wo → wi)`, and
    /// `sample(wi)` is a camera path's step, its weight `f(wo → wi) |cos θo| / p`.
    Importance = 1,
}

impl Transport {
    /// The mode's name, as [`str::parse`] reads it and the CLI and the
    /// bindings print it: `"radiance"` or `"importance"`.
    ///
    /// ```
    /// use strata_bsdf::Transport;
    /// let t = Transport::Importance;
    /// assert_eq!(t.as_str().parse::<Transport>(), Ok(t));
    /// ```
    pub fn as_str(self) -> &'static str {
        match self {
            Transport::Radiance => "radiance",
            Transport::Importance => "importance",
        }
    }

    /// The factor that turns the radiance BSDF from `wi` to `wo` (given by
    /// the z of each) into this mode's, or `None` where it is 1 (radiance,
    /// reflection, equal exteriors), so that those results are untouched.
    pub(crate) fn factor(self, stack: &LayerStack, wi_z: f64, wo_z: f64) -> Option<f64> {
        self.factor_of(stack, wi_z, wo_z, false)
    }

    /// The factor that turns an estimate of the radiance BSDF from `wo` to
    /// `wi` (the walks started at `wo`: `swapped`) or from `wi` to `wo` into
    /// this mode's BSDF from `wi` to `wo`; `None` where it is 1.
    pub(crate) fn factor_of(
        self,
        stack: &LayerStack,
        wi_z: f64,
        wo_z: f64,
        swapped: bool,
    ) -> Option<f64> {
        let forward = eta_squared(stack, wi_z, wo_z)?;
        match (self, swapped) {
            (Transport::Radiance, false) | (Transport::Importance, true) => None,
            (Transport::Importance, false) => Some(forward),
            (Transport::Radiance, true) => eta_squared(stack, wo_z, wi_z),
        }
    }
}

/// `(n_from / n_to)²` for light crossing the stack between exteriors of
/// different IOR, from the side of `from_z` to that of `to_z`; `None` for
/// reflection or equal exteriors.
fn eta_squared(stack: &LayerStack, from_z: f64, to_z: f64) -> Option<f64> {
    if (from_z > 0.0) == (to_z > 0.0) {
        return None;
    }
    let side = |z: f64| {
        if z > 0.0 {
            stack.exterior_above()
        } else {
            stack.exterior_below()
        }
    };
    let (a, b) = (side(from_z), side(to_z));
    (a != b).then(|| (a / b) * (a / b))
}

impl std::str::FromStr for Transport {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "radiance" => Ok(Transport::Radiance),
            "importance" => Ok(Transport::Importance),
            _ => Err(format!(
                "unknown transport mode {s:?} (expected radiance or importance)"
            )),
        }
    }
}
