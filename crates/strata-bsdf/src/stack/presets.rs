//! Named conductors: complex IOR `eta + i k` per RGB channel, relative to vacuum.
//!
//! The values are RGB reductions of measured spectral data (copper, gold and
//! silver: Johnson & Christy 1972; aluminium and chromium: Palik 1985, via
//! Rakić 1995 and Rakić et al. 1998), as shipped with Mitsuba's conductor
//! tables and reproduced in many renderers. strata divides them by the IOR of
//! the region above the conductor.

/// `(name, eta, k)` of every preset.
pub const PRESETS: &[(&str, [f64; 3], [f64; 3])] = &[
    (
        "Cu",
        [0.200438, 0.924033, 1.10221],
        [3.91295, 2.45285, 2.14219],
    ),
    (
        "Au",
        [0.143119, 0.374957, 1.44248],
        [3.98316, 2.38572, 1.60322],
    ),
    (
        "Ag",
        [0.155265, 0.116723, 0.138342],
        [4.82835, 3.12225, 2.14696],
    ),
    (
        "Al",
        [1.65746, 0.880369, 0.521229],
        [9.22387, 6.26952, 4.837],
    ),
    ("Cr", [4.36968, 2.9167, 1.6547], [5.20643, 4.23136, 3.75495]),
];

/// Looks up a preset by name (case-insensitive).
pub fn conductor(name: &str) -> Option<([f64; 3], [f64; 3])> {
    PRESETS
        .iter()
        .find(|(n, _, _)| n.eq_ignore_ascii_case(name))
        .map(|&(_, e, k)| (e, k))
}
