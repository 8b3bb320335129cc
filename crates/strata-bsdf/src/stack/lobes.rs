//! Which lobes a stack can produce: what a renderer declares of a BSDF
//! (Mitsuba's flags, pbrt-v4's `BxDFFlags`) before it samples one.

use super::layer_stack::{Interface, InterfaceKind, LayerStack};

/// The kinds of scattering a stack's samples and evals can have.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Lobes {
    /// A smooth entry interface reflects a delta lobe (from below a
    /// transmissive stack, a smooth bottom does).
    pub delta_reflection: bool,
    /// Light can pass every interface without a non-delta event: all are
    /// smooth dielectrics and no medium scatters (sample only).
    pub delta_transmission: bool,
    /// A rough interface or a scattering medium: non-delta, non-Lambertian
    /// scattering.
    pub glossy: bool,
    /// A Lambertian interface.
    pub diffuse: bool,
    /// The stack transmits (its bottom interface is a dielectric).
    pub transmission: bool,
}

impl LayerStack {
    /// Which lobes this stack can produce.
    pub fn lobes(&self) -> Lobes {
        let its = self.interfaces();
        let scattering = self.features().scattering;
        let delta = |i: &Interface| i.smooth && i.kind != InterfaceKind::Diffuse;
        let transmission = self.transmissive();
        let (top, bottom) = (&its[0], &its[its.len() - 1]);
        Lobes {
            delta_reflection: delta(top) || (transmission && delta(bottom)),
            delta_transmission: transmission && its.iter().all(delta) && !scattering,
            glossy: its
                .iter()
                .any(|i| !i.smooth && i.kind != InterfaceKind::Diffuse)
                || scattering,
            diffuse: its.iter().any(|i| i.kind == InterfaceKind::Diffuse),
            transmission,
        }
    }
}
