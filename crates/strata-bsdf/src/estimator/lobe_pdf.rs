//! The lobe pdf: a closed-form density for a renderer's MIS weights, in
//! place of density walks (method.md §6).
//!
//! MIS needs, for a direction, a number that `sample` and `pdf` agree on and
//! that is positive wherever `f` can be; the estimator stays unbiased
//! whatever the number, and its variance depends on how well the number
//! follows `sample()`'s density. The lobe pdf follows it with the parts a
//! walk takes first: the entry interface's own density (exact for a stack of
//! one interface), and, for light that crosses it into the stack, a cosine
//! lobe on the side the light leaves (for an opaque stack weighted by what
//! the stack returns, [`super::body_return`], so that the pdf integrates to
//! about the albedo as the density does; half on each side of a
//! transmissive one), mixed with the uniform density
//! as the walked pdf is ([`super::pdf::mix_uniform`]). It costs one
//! interface pdf and one Fresnel term: no walk.

use super::orient;
use super::pdf::mix_uniform;
use super::scalar::{v3, Scalar, ScalarEngine};
use crate::interface::InterfaceLanes;
use crate::stack::{InterfaceKind, LayerStack};

impl<S: Scalar> ScalarEngine<S> {
    /// The lobe pdf of `wo` for `sample(wi)`: 0 where no light enters or
    /// leaves (as the walked pdf), else positive.
    pub fn lobe_pdf(&self, wi: [f64; 3], wo: [f64; 3]) -> f64 {
        lobe_pdf(&self.stack, &self.ifaces, self.body, wi, wo)
    }
}

/// [`ScalarEngine::lobe_pdf`] of `stack`'s shape with the interfaces
/// `ifaces` and the body return `body` (a parameter set's).
pub fn lobe_pdf<S: Scalar>(
    stack: &LayerStack,
    ifaces: &[InterfaceLanes<S>],
    body: f64,
    wi: [f64; 3],
    wo: [f64; 3],
) -> f64 {
    let Some(o) = orient(stack, wi, Some(wo)) else {
        return 0.0;
    };
    let (a, b) = (o.wi, o.apply(wo));
    let n = ifaces.len();
    let entry = if a[2] > 0.0 { 0 } else { n - 1 };
    let own = ifaces[entry].pdf(v3::<S>(a), v3::<S>(b), false).lane(0);
    if n == 1 {
        return mix_uniform(own);
    }
    let desc = &stack.interfaces()[entry];
    let enters = match desc.kind {
        InterfaceKind::Dielectric => {
            // The lanes' IORs: a row's own (written in place) where the
            // stack is its template's.
            let it = &ifaces[entry];
            let eta = it.n_below.lane(0) / it.n_above.lane(0);
            1.0 - crate::fresnel::dielectric(a[2], eta)
        }
        InterfaceKind::Conductor | InterfaceKind::Diffuse => 0.0,
    };
    let reflected = a[2] * b[2] > 0.0;
    let share = match (stack.transmissive(), reflected) {
        (false, true) => 1.0,
        (false, false) => 0.0,
        (true, _) => 0.5,
    };
    let lobe = enters * body * share * b[2].abs() * std::f64::consts::FRAC_1_PI;
    mix_uniform(if reflected { own + lobe } else { lobe })
}
