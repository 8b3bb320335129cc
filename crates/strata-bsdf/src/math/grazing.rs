//! The grazing limit of directions, shared by the interfaces and the
//! orientation of queries.

/// Directions closer to the horizon than this (`|cos θ| < MIN_COS`) are
/// treated as grazing exactly, where no light enters or leaves. Single
/// precision cannot hold them: the kernels multiply two cosines (and
/// squares of cosines), which must stay normal numbers (>= 1.2e-38). The
/// stiff suite runs down to cos 1e-7.
pub const MIN_COS: f64 = 1e-18;
