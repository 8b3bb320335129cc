//! Which side light enters and leaves, shared by every engine.

use crate::stack::LayerStack;

/// A query after orientation: directions in the stack's frame with the top
/// facing `+z`, and whether they were mirrored (two-sided opaque stacks).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Oriented {
    /// The incident direction, mirrored if `flipped`.
    pub wi: [f64; 3],
    /// The query was mirrored in z.
    pub flipped: bool,
}

impl Oriented {
    /// Applies the same mirroring to another direction.
    pub fn apply(&self, mut w: [f64; 3]) -> [f64; 3] {
        if self.flipped {
            w[2] = -w[2];
        }
        w
    }
}

/// Directions closer to the horizon than this (`|cos θ| < MIN_COS`) are
/// treated as grazing exactly, where no light enters or leaves. Single
/// precision cannot hold them: the kernels multiply two cosines (and
/// squares of cosines), which must stay normal numbers (>= 1.2e-38). The
/// stiff suite runs down to cos 1e-7.
pub const MIN_COS: f64 = 1e-18;

/// Orients the incident direction for `stack`, or `None` when no light enters:
/// `wi` grazing (|cos| < [`MIN_COS`]), or arriving at the back of an opaque
/// one-sided stack. `wo` (when given) must then leave on a side light can leave
/// through (not grazing; above, or below for a transmissive stack).
pub fn orient(stack: &LayerStack, wi: [f64; 3], wo: Option<[f64; 3]>) -> Option<Oriented> {
    // NaN is grazing too: `is_nan() ||` keeps the comparison NaN-aware.
    if wi[2].is_nan() || wi[2].abs() < MIN_COS {
        return None;
    }
    let mut o = Oriented { wi, flipped: false };
    if wi[2] < 0.0 && !stack.transmissive() {
        if !stack.two_sided() {
            return None;
        }
        o.wi[2] = -wi[2];
        o.flipped = true;
    }
    if let Some(wo) = wo {
        let wo = o.apply(wo);
        if wo[2].is_nan() || wo[2].abs() < MIN_COS || (!stack.transmissive() && wo[2] < 0.0) {
            return None;
        }
    }
    Some(o)
}
