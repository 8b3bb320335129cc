//! Named conductors: measured complex IOR `eta + i k` relative to vacuum, as
//! tabulated spectra, and the RGB numbers RGB queries use.
//!
//! Each preset is a published measurement (`super::measured` names the
//! source of each table; docs/materials.md lists them with their ranges),
//! read linearly between its samples. Its RGB numbers are the CIE reduction
//! of the spectra (`super::spectrum::to_rgb`: XYZ under D65, linear sRGB).
//! strata divides them by the IOR of the region above the conductor.

use super::measured;
use super::spectrum::Spectrum;
use std::sync::OnceLock;

/// A named metal and its measured optical constants.
#[derive(Debug)]
pub struct Preset {
    /// The name a material file gives (`preset = "Cu"`), case-insensitive.
    pub name: &'static str,
    /// The metal.
    pub metal: &'static str,
    /// Where the measurement is published.
    pub source: &'static str,
    /// `(wavelength in nm, n, k)`, increasing in wavelength.
    pub samples: &'static [(f64, f64, f64)],
}

impl Preset {
    /// The real part of the IOR as a tabulated spectrum.
    pub fn eta(&self) -> Spectrum {
        Spectrum::Tabulated {
            nm: self.samples.iter().map(|s| s.0).collect(),
            values: self.samples.iter().map(|s| s.1).collect(),
        }
    }
    /// The imaginary part (extinction coefficient) as a tabulated spectrum.
    pub fn k(&self) -> Spectrum {
        Spectrum::Tabulated {
            nm: self.samples.iter().map(|s| s.0).collect(),
            values: self.samples.iter().map(|s| s.2).collect(),
        }
    }
    /// The wavelengths the table spans, in nm.
    pub fn range_nm(&self) -> [f64; 2] {
        let first = self.samples.first().map_or(f64::NAN, |s| s.0);
        let last = self.samples.last().map_or(f64::NAN, |s| s.0);
        [first, last]
    }
}

const JC72: &str = "P. B. Johnson and R. W. Christy, Phys. Rev. B 6, 4370 (1972)";
const JC74: &str = "P. B. Johnson and R. W. Christy, Phys. Rev. B 9, 5056 (1974)";

/// Every preset.
pub const PRESETS: &[Preset] = &[
    Preset {
        name: "Cu",
        metal: "copper",
        source: JC72,
        samples: &measured::COPPER,
    },
    Preset {
        name: "Au",
        metal: "gold",
        source: JC72,
        samples: &measured::GOLD,
    },
    Preset {
        name: "Ag",
        metal: "silver",
        source: JC72,
        samples: &measured::SILVER,
    },
    Preset {
        name: "Al",
        metal: "aluminium",
        source: "A. D. Rakić, Appl. Opt. 34, 4755 (1995)",
        samples: &measured::ALUMINIUM,
    },
    Preset {
        name: "Cr",
        metal: "chromium",
        source: JC74,
        samples: &measured::CHROMIUM,
    },
    Preset {
        name: "Ni",
        metal: "nickel",
        source: JC74,
        samples: &measured::NICKEL,
    },
    Preset {
        name: "Ti",
        metal: "titanium",
        source: JC74,
        samples: &measured::TITANIUM,
    },
    Preset {
        name: "Fe",
        metal: "iron",
        source: JC74,
        samples: &measured::IRON,
    },
];

/// Looks up a preset by name (case-insensitive).
pub fn preset(name: &str) -> Option<&'static Preset> {
    PRESETS.iter().find(|p| p.name.eq_ignore_ascii_case(name))
}

/// The RGB numbers `(eta, k)` of a preset, by name (case-insensitive):
/// the reductions of its spectra, computed once.
pub fn conductor(name: &str) -> Option<([f64; 3], [f64; 3])> {
    static RGB: OnceLock<Vec<([f64; 3], [f64; 3])>> = OnceLock::new();
    let rgb = RGB.get_or_init(|| {
        PRESETS
            .iter()
            .map(|p| (p.eta().rgb(), p.k().rgb()))
            .collect()
    });
    let i = PRESETS
        .iter()
        .position(|p| p.name.eq_ignore_ascii_case(name))?;
    rgb.get(i).copied()
}

/// The names of the presets, comma-separated (for messages).
pub fn names() -> String {
    PRESETS
        .iter()
        .map(|p| p.name)
        .collect::<Vec<_>>()
        .join(", ")
}
