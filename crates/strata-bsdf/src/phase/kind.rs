//! What a phase function asks of a walk ([`PhaseKind`], part of a stack's
//! shape), and the most lobes a mixture holds.

/// Most lobes a mixture holds (a fixed bound keeps its lanes a fixed size).
pub const MAX_COMPONENTS: usize = 4;

/// What a phase function asks of a walk: part of a stack's shape.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PhaseKind {
    /// Henyey–Greenstein (or isotropic).
    Hg,
    /// A mixture of this many Henyey–Greenstein lobes.
    Mixture(u8),
    /// SGGX with specular flakes: direction-dependent extinction.
    SggxSpecular,
    /// SGGX with diffuse flakes: direction-dependent extinction, and a
    /// phase value that is estimated.
    SggxDiffuse,
}

impl PhaseKind {
    /// The extinction depends on the direction of travel.
    pub fn directional(self) -> bool {
        matches!(self, PhaseKind::SggxSpecular | PhaseKind::SggxDiffuse)
    }
}
