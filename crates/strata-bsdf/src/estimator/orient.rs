//! Which side light enters and leaves, shared by every engine.

use crate::math::MIN_COS;
use crate::stack::LayerStack;

/// A query after orientation: directions in the stack's frame with the top
/// facing `+z`, and whether they were turned over (two-sided opaque stacks).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Oriented {
    /// The incident direction, turned over if `flipped`.
    pub wi: [f64; 3],
    /// The query was turned over: mirrored in z, or (a stack with tilted
    /// normals or an SGGX medium, whose mirror image would tilt them or its
    /// axis the other way) negated. For other stacks the two are the same
    /// BSDF, which is symmetric under the half turn about z that tells them
    /// apart.
    pub flipped: bool,
    /// Turning over negates every component.
    negates: bool,
}

impl Oriented {
    /// Applies the same turning over to another direction (its own inverse).
    pub fn apply(&self, mut w: [f64; 3]) -> [f64; 3] {
        if self.flipped {
            w[2] = -w[2];
            if self.negates {
                w[0] = -w[0];
                w[1] = -w[1];
            }
        }
        w
    }
}

/// `w` turned over as [`orient`] turns a query on `stack` over (for
/// results in single precision).
pub fn turned_over(stack: &LayerStack, w: [f32; 3]) -> [f32; 3] {
    let o = Oriented {
        wi: [0.0; 3],
        flipped: true,
        negates: negates(stack),
    };
    o.apply(w.map(f64::from)).map(|x| x as f32)
}

/// Turning `stack` over negates directions (see [`Oriented::flipped`]).
fn negates(stack: &LayerStack) -> bool {
    stack.interfaces().iter().any(|i| i.tilted())
        || (0..stack.len().saturating_sub(1))
            .filter_map(|l| stack.medium(l))
            .any(|m| m.phase_kind().directional())
}

/// Orients the incident direction for `stack`, or `None` when no light enters:
/// `wi` grazing (|cos| < [`MIN_COS`]), or arriving at the back of an opaque
/// one-sided stack. `wo` (when given) must then leave on a side light can leave
/// through (not grazing; above, or below for a transmissive stack).
pub fn orient(stack: &LayerStack, wi: [f64; 3], wo: Option<[f64; 3]>) -> Option<Oriented> {
    // NaN is grazing too: `is_nan() ||` keeps the comparison NaN-aware.
    if wi[2].is_nan() || wi[2].abs() < MIN_COS {
        return None;
    }
    let negates = negates(stack);
    let mut o = Oriented {
        wi,
        flipped: false,
        negates,
    };
    if wi[2] < 0.0 && !stack.transmissive() {
        if !stack.two_sided() {
            return None;
        }
        o.flipped = true;
        o.wi = o.apply(wi);
    }
    if let Some(wo) = wo {
        let wo = o.apply(wo);
        if wo[2].is_nan() || wo[2].abs() < MIN_COS || (!stack.transmissive() && wo[2] < 0.0) {
            return None;
        }
    }
    Some(o)
}
