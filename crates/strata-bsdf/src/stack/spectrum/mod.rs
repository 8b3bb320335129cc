//! Spectra in material descriptions: the value type ([`Spectrum`]), the RGB
//! numbers of a spectrum (`cie`: CIE 1931 XYZ under D65, then linear sRGB)
//! and the spectrum of an RGB value (`uplift`: Mallett and Yuksel 2019).
//! docs/materials.md, "Spectra", says which field takes which form.

mod cie;
mod uplift;
mod value;

pub use cie::{to_rgb, to_rgb_under, Illuminant, CIE_FIRST_NM, CIE_SAMPLES, CIE_STEP_NM};
pub use uplift::rgb_at;
pub use value::{abbe_to_cauchy, RgbParam, Spectrum, C_LINE_NM, D_LINE_NM, F_LINE_NM};
pub(crate) use value::{spectrum_named, Forms};
