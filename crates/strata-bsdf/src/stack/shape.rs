//! A stack's *shape*: what decides the schedule of its walks, apart from the
//! numbers (its *parameters*).
//!
//! Two stacks of one shape run the same stages in the same order: the same
//! number of interfaces, each of the same kind, rough or smooth, with the
//! same distribution and shadowing form; each layer of the same class (no
//! medium, clear, absorbing or scattering; grey or chromatic extinction);
//! the same sidedness. Their IORs, roughnesses, conductor constants,
//! albedos, thicknesses, extinctions, single-scattering albedos and phase
//! parameters may all differ: the engines take those per query
//! (the rows of a [`Materials`](crate::Materials) table). A value that changes the shape (a
//! roughness of 0 on a rough interface, an IOR that matches the region
//! above, a tilted normal on an untilted interface or back, a single-scattering albedo of 0 in a scattering layer) gives a
//! stack of another shape, which an engine of this one does not run.

use super::description::{Distribution, Shadowing};
use super::layer_stack::{InterfaceKind, LayerStack, Medium};
use super::phase::PhaseKind;

/// What a layer asks of a walk crossing it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LayerKind {
    /// No medium (or one that neither scatters nor attenuates): crossed for free.
    Clear,
    /// Attenuates without scattering: crossed with its transmittance, no free flight.
    Absorbing,
    /// Scatters: free-flight sampling, collisions, phase sampling.
    Scattering,
}

impl Medium {
    /// What the medium asks of a walk.
    pub fn kind(&self) -> LayerKind {
        if self.scatters() {
            LayerKind::Scattering
        } else if self.attenuates() {
            LayerKind::Absorbing
        } else {
            LayerKind::Clear
        }
    }

    /// The same extinction in every channel (free flights need no spectral MIS).
    pub fn grey(&self) -> bool {
        self.sigma_t[0] == self.sigma_t[1] && self.sigma_t[1] == self.sigma_t[2]
    }

    /// What its phase function asks of a walk crossing it: all of it in a
    /// scattering layer; in an absorbing one only whether the extinction
    /// depends on the direction; nothing in a clear one.
    pub fn phase_kind(&self) -> PhaseKind {
        let k = self.phase.kind();
        match self.kind() {
            LayerKind::Scattering => k,
            LayerKind::Absorbing if k.directional() => PhaseKind::SggxSpecular,
            _ => PhaseKind::Hg,
        }
    }
}

/// The shape of one interface.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct InterfaceShape {
    /// Dielectric, conductor or diffuse.
    pub kind: InterfaceKind,
    /// Delta lobes only (also an index-matched dielectric).
    pub smooth: bool,
    /// Microfacet distribution.
    pub distribution: Distribution,
    /// Shadowing form.
    pub shadowing: Shadowing,
    /// Its shading normal is tilted (the frame change runs).
    pub tilted: bool,
}

/// The shape of one layer: its medium's class, if it has one.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LayerShape {
    /// No medium: crossed for free, with no depth.
    Empty,
    /// A medium of this class, grey (one extinction) or chromatic.
    Medium {
        /// What it asks of a walk.
        kind: LayerKind,
        /// One extinction for all channels.
        grey: bool,
        /// What its phase function asks of a walk.
        phase: PhaseKind,
    },
}

/// A stack's shape (see the module documentation).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Shape {
    /// Interfaces, top first.
    pub interfaces: Vec<InterfaceShape>,
    /// Layers, `layers[l]` between interfaces `l` and `l + 1`.
    pub layers: Vec<LayerShape>,
    /// Lit from below, an opaque stack is mirrored.
    pub two_sided: bool,
}

impl Shape {
    /// Some interface has a tilted shading normal: the stack's BSDF is then
    /// not reciprocal (method.md §9), so no engine may use reciprocity.
    pub fn tilted(&self) -> bool {
        self.interfaces.iter().any(|i| i.tilted)
    }

    /// The first difference from `other`, in words (`None` if the shapes
    /// are the same), for errors that say why a parameter set does not fit.
    pub fn difference(&self, other: &Shape) -> Option<String> {
        if self.interfaces.len() != other.interfaces.len() {
            return Some(format!(
                "{} interfaces instead of {}",
                other.interfaces.len(),
                self.interfaces.len()
            ));
        }
        for (i, (a, b)) in self.interfaces.iter().zip(&other.interfaces).enumerate() {
            if a != b {
                return Some(format!("layer {i}: interface {b:?} instead of {a:?}"));
            }
        }
        for (l, (a, b)) in self.layers.iter().zip(&other.layers).enumerate() {
            if a != b {
                return Some(format!("layer {l}: medium {b:?} instead of {a:?}"));
            }
        }
        (self.two_sided != other.two_sided).then(|| {
            format!(
                "two_sided = {} instead of {}",
                other.two_sided, self.two_sided
            )
        })
    }
}

impl LayerStack {
    /// The stack's shape: what an engine built for it fixes (its parameters
    /// may then vary per query).
    pub fn shape(&self) -> Shape {
        Shape {
            interfaces: (0..self.len()).map(|i| self.interface_shape(i)).collect(),
            layers: (0..self.media.len()).map(|l| self.layer_shape(l)).collect(),
            two_sided: self.two_sided,
        }
    }

    /// The shape of interface `i`.
    pub fn interface_shape(&self, i: usize) -> InterfaceShape {
        let it = &self.interfaces[i];
        InterfaceShape {
            kind: it.kind,
            smooth: it.smooth,
            distribution: it.distribution,
            shadowing: it.shadowing,
            tilted: it.tilted(),
        }
    }

    /// The shape of layer `l`.
    pub fn layer_shape(&self, l: usize) -> LayerShape {
        match &self.media[l] {
            None => LayerShape::Empty,
            Some(m) => LayerShape::Medium {
                kind: m.kind(),
                grey: m.grey(),
                phase: m.phase_kind(),
            },
        }
    }
}
