//! Which stacks the walk-free forms answer: a dielectric coat over one layer
//! over a Lambertian base ([`super::closed_form`] under a smooth coat,
//! [`super::rough_coat`] under a rough one).

use super::settings::{Settings, MAX_EVENTS};
use crate::stack::{Interface, InterfaceKind, LayerStack};

/// The coat and the base of `stack` if it is a dielectric coat over one
/// layer over a Lambertian base that the walk-free forms can answer under
/// `settings`: untilted (a tilted normal breaks their planar geometry), an
/// extinction that does not depend on the direction (SGGX breaks their
/// one-dimensional transmittances), no depth cap (which truncates the series
/// of bounces).
pub fn coat_and_base<'a>(
    stack: &'a LayerStack,
    settings: &Settings,
) -> Option<(&'a Interface, &'a Interface)> {
    let tilted = stack.interfaces().iter().any(|i| i.tilted());
    let directional = stack
        .medium(0)
        .is_some_and(|m| m.phase_kind().directional());
    if stack.len() != 2 || settings.max_events < MAX_EVENTS || tilted || directional {
        return None;
    }
    let (coat, base) = (stack.interface(0), stack.interface(1));
    let shape = coat.kind == InterfaceKind::Dielectric && base.kind == InterfaceKind::Diffuse;
    shape.then_some((coat, base))
}
