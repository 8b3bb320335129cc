//! A spectral value of a material: one number, an RGB triple, a tabulated
//! spectrum or, for a dielectric's IOR, a Cauchy or Abbe dispersion law.
//!
//! Every coloured field of a material file (albedos, `sigma_t`, a conductor's
//! `eta` and `k`) takes the first three forms, a dielectric's `ior` all but
//! the RGB triple (a refracted direction is one per walk, so an IOR is one
//! number per wavelength, not per channel). A value answers at a wavelength
//! ([`Spectrum::at`], for spectral queries) and as the three numbers RGB
//! queries use ([`Spectrum::rgb`]).

use super::cie;
use super::uplift;
use serde::de::{self, Deserializer, IgnoredAny, MapAccess, SeqAccess, Visitor};
use serde::Serialize;
use std::fmt;

/// The Fraunhofer d line (helium), in nm: where an RGB query reads a
/// dispersive IOR, and where the Abbe form's `nd` is given.
pub const D_LINE_NM: f64 = 587.56;
/// The Fraunhofer F line (hydrogen), in nm.
pub const F_LINE_NM: f64 = 486.13;
/// The Fraunhofer C line (hydrogen), in nm.
pub const C_LINE_NM: f64 = 656.27;

/// A value given once for all wavelengths, per RGB channel, or as a
/// spectrum. Wavelengths are in nm.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(untagged)]
pub enum Spectrum {
    /// The same value at every wavelength and in every channel.
    Grey(f64),
    /// One value per RGB channel; at a wavelength, the value of its uplift
    /// (Mallett and Yuksel 2019, see [`Spectrum::at`]).
    Rgb([f64; 3]),
    /// Samples `values[i]` at `nm[i]`: linear between samples, constant
    /// outside them. `nm` strictly increasing, one value per wavelength.
    Tabulated {
        /// The wavelengths, in nm.
        nm: Vec<f64>,
        /// The value at each wavelength.
        values: Vec<f64>,
    },
    /// Cauchy's law with two terms, `n = A + B / λ²`, λ in µm: an IOR only.
    Cauchy {
        /// `[A, B]` (B in µm²).
        cauchy: [f64; 2],
    },
    /// An IOR given by its value at the d line and its Abbe number
    /// `V = (nd − 1) / (nF − nC)`, as glTF's `KHR_materials_dispersion`
    /// defines it: the Cauchy law through `nd` whose F-to-C spread is
    /// `(nd − 1) / V` ([`abbe_to_cauchy`]). An IOR only.
    Abbe {
        /// The IOR at the d line, 587.56 nm.
        nd: f64,
        /// The Abbe number V.
        abbe: f64,
    },
}

/// Alias of [`Spectrum`].
pub type RgbParam = Spectrum;

impl Spectrum {
    /// The value at the wavelength `nm`. An RGB triple answers with its
    /// uplift (Mallett and Yuksel 2019: `super::uplift`), a grey value
    /// with itself. An invalid spectrum (no samples, a NaN at an end of its
    /// wavelengths; which [`crate::stack::LayerStack::new`] refuses)
    /// answers NaN.
    pub fn at(&self, nm: f64) -> f64 {
        match self {
            Spectrum::Grey(v) => *v,
            Spectrum::Rgb(c) => uplift::rgb_at(*c, nm),
            Spectrum::Tabulated { nm: x, values } => interpolate(x, values, nm),
            Spectrum::Cauchy { cauchy: [a, b] } => cauchy(*a, *b, nm),
            Spectrum::Abbe { nd, abbe } => {
                let [a, b] = abbe_to_cauchy(*nd, *abbe);
                cauchy(a, b, nm)
            }
        }
    }

    /// The three numbers an RGB query uses. A grey value or an RGB triple
    /// as given; a tabulated spectrum by its CIE reduction (`super::cie`:
    /// XYZ under D65, then linear sRGB), each channel clamped to the
    /// spectrum's range of values (a colour outside the sRGB gamut has no
    /// RGB within it; the clamp keeps the numbers within the values the
    /// field's checks accepted), NaN where the spectrum is invalid or its
    /// reduction overflows; a Cauchy or Abbe law its value at the d
    /// line in every channel ([`Spectrum::d_line`]).
    pub fn rgb(&self) -> [f64; 3] {
        match self {
            Spectrum::Grey(v) => [*v; 3],
            Spectrum::Rgb(c) => *c,
            Spectrum::Tabulated { values, .. } => {
                if values.is_empty() || values.iter().any(|v| !v.is_finite()) {
                    return [f64::NAN; 3];
                }
                let lo = values.iter().copied().fold(f64::INFINITY, f64::min);
                let hi = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                if lo == hi {
                    return [lo; 3];
                }
                // A reduction that overflows is NaN, which the field's
                // checks refuse, not a clamped number.
                cie::to_rgb(|nm| self.at(nm)).map(|c| match c.is_finite() {
                    true => c.max(lo).min(hi),
                    false => f64::NAN,
                })
            }
            Spectrum::Cauchy { .. } | Spectrum::Abbe { .. } => [self.d_line(); 3],
        }
    }

    /// The one number an RGB query uses for an IOR: a grey value as given;
    /// a spectrum or a dispersion law its value at the d line (587.56 nm;
    /// the Abbe form's `nd` exactly). An RGB triple, which no IOR takes,
    /// answers its green channel.
    pub fn d_line(&self) -> f64 {
        match self {
            Spectrum::Grey(v) => *v,
            Spectrum::Rgb(c) => c[1],
            Spectrum::Abbe { nd, .. } => *nd,
            _ => self.at(D_LINE_NM),
        }
    }
}

impl From<f64> for Spectrum {
    fn from(v: f64) -> Self {
        Spectrum::Grey(v)
    }
}

impl From<[f64; 3]> for Spectrum {
    fn from(c: [f64; 3]) -> Self {
        Spectrum::Rgb(c)
    }
}

/// Linear interpolation of the samples, constant outside them; NaN for no
/// samples, a NaN wavelength, or a NaN in the table's ends.
fn interpolate(nm: &[f64], values: &[f64], x: f64) -> f64 {
    let n = nm.len().min(values.len());
    if n == 0 || x.is_nan() {
        return f64::NAN;
    }
    if x <= nm[0] {
        return values[0];
    }
    if x >= nm[n - 1] {
        return values[n - 1];
    }
    if !(nm[0] < x && x < nm[n - 1]) {
        // A NaN wavelength in the table (which the checks refuse).
        return f64::NAN;
    }
    // nm[0] < x < nm[n-1]: the sample below x is in 0..n-1.
    let i = (nm[..n].partition_point(|&w| w <= x) - 1).min(n - 2);
    let t = (x - nm[i]) / (nm[i + 1] - nm[i]);
    values[i] + t * (values[i + 1] - values[i])
}

/// `A + B / λ²` with λ in µm.
fn cauchy(a: f64, b: f64, nm: f64) -> f64 {
    let um = nm * 1e-3;
    a + b / (um * um)
}

/// The Cauchy coefficients `[A, B]` (λ in µm) of an IOR given by `nd` and
/// the Abbe number `abbe`, as glTF's `KHR_materials_dispersion` defines
/// them: `B = (nd − 1) / (V (λF⁻² − λC⁻²))`, `A = nd − B / λd²`, with the
/// F, d and C lines at 486.13, 587.56 and 656.27 nm. The law then gives `nd`
/// at the d line and `(nd − 1) / V` as `nF − nC`.
pub fn abbe_to_cauchy(nd: f64, abbe: f64) -> [f64; 2] {
    let inv2 = |nm: f64| {
        let um = nm * 1e-3;
        1.0 / (um * um)
    };
    let b = (nd - 1.0) / (abbe * (inv2(F_LINE_NM) - inv2(C_LINE_NM)));
    [nd - b * inv2(D_LINE_NM), b]
}

/// Which forms a field takes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Forms {
    /// A coloured field: a number, `[r, g, b]` or a table.
    Colour,
    /// An IOR: a number, a table or a dispersion law.
    Ior,
    /// Any form (a [`Spectrum`] read on its own).
    Any,
}

/// Reads a [`Spectrum`] whose errors name `field`, in the forms `forms`.
pub(crate) fn spectrum_named<'de, D: Deserializer<'de>>(
    d: D,
    field: &'static str,
    forms: Forms,
) -> Result<Spectrum, D::Error> {
    d.deserialize_any(SpectrumVisitor { field, forms })
}

impl<'de> serde::Deserialize<'de> for Spectrum {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        spectrum_named(d, "the value", Forms::Any)
    }
}

struct SpectrumVisitor {
    field: &'static str,
    forms: Forms,
}

const COLOUR_KEYS: &[&str] = &["nm", "values"];
const LAW_KEYS: &[&str] = &["nm", "values", "cauchy", "nd", "abbe"];

impl<'de> Visitor<'de> for SpectrumVisitor {
    type Value = Spectrum;

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        let field = self.field;
        match self.forms {
            Forms::Colour => write!(
                f,
                "`{field}` to be a number or [r, g, b], or a spectrum {{ nm = [...], values = [...] }}"
            ),
            Forms::Ior => write!(
                f,
                "`{field}` to be a number, or a spectrum: {{ nm = [...], values = [...] }}, \
                 {{ cauchy = [A, B] }} or {{ nd = N, abbe = V }}"
            ),
            Forms::Any => write!(
                f,
                "`{field}` to be a number or [r, g, b], or a spectrum: {{ nm = [...], values = [...] }}, \
                 {{ cauchy = [A, B] }} or {{ nd = N, abbe = V }}"
            ),
        }
    }
    fn visit_f64<E: de::Error>(self, v: f64) -> Result<Spectrum, E> {
        Ok(Spectrum::Grey(v))
    }
    fn visit_i64<E: de::Error>(self, v: i64) -> Result<Spectrum, E> {
        Ok(Spectrum::Grey(v as f64))
    }
    fn visit_u64<E: de::Error>(self, v: u64) -> Result<Spectrum, E> {
        Ok(Spectrum::Grey(v as f64))
    }
    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Spectrum, A::Error> {
        if self.forms == Forms::Ior {
            return Err(de::Error::invalid_type(de::Unexpected::Seq, &self));
        }
        let mut a = [0.0; 3];
        for (i, x) in a.iter_mut().enumerate() {
            *x = seq
                .next_element()
                .map_err(|e| de::Error::custom(format_args!("`{}`: {e}", self.field)))?
                .ok_or_else(|| de::Error::invalid_length(i, &self))?;
        }
        if seq.next_element::<IgnoredAny>()?.is_some() {
            return Err(de::Error::invalid_length(4, &self));
        }
        Ok(Spectrum::Rgb(a))
    }
    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Spectrum, A::Error> {
        let field = self.field;
        let keys = if self.forms == Forms::Colour {
            COLOUR_KEYS
        } else {
            LAW_KEYS
        };
        let (mut nm, mut values, mut law, mut nd, mut abbe) = (None, None, None, None, None);
        let mut given: Vec<&'static str> = Vec::new();
        while let Some(key) = map.next_key::<String>()? {
            let Some(&k) = keys.iter().find(|&&k| k == key) else {
                return Err(de::Error::custom(format_args!(
                    "`{field}`: unknown field `{key}` of a spectrum, expected {}",
                    keys.iter()
                        .map(|k| format!("`{k}`"))
                        .collect::<Vec<_>>()
                        .join(", ")
                )));
            };
            if given.contains(&k) {
                return Err(de::Error::custom(format_args!(
                    "`{field}`: duplicate field `{k}`"
                )));
            }
            given.push(k);
            let bad = |e: A::Error| de::Error::custom(format_args!("`{field}.{k}`: {e}"));
            match k {
                "nm" => nm = Some(map.next_value::<Vec<f64>>().map_err(bad)?),
                "values" => values = Some(map.next_value::<Vec<f64>>().map_err(bad)?),
                "cauchy" => law = Some(map.next_value::<[f64; 2]>().map_err(bad)?),
                "nd" => nd = Some(map.next_value::<f64>().map_err(bad)?),
                _ => abbe = Some(map.next_value::<f64>().map_err(bad)?),
            }
        }
        match (nm, values, law, nd, abbe) {
            (Some(nm), Some(values), None, None, None) => Ok(Spectrum::Tabulated { nm, values }),
            (None, None, Some(cauchy), None, None) => Ok(Spectrum::Cauchy { cauchy }),
            (None, None, None, Some(nd), Some(abbe)) => Ok(Spectrum::Abbe { nd, abbe }),
            _ => {
                let forms = if self.forms != Forms::Colour {
                    "{ nm = [...], values = [...] }, { cauchy = [A, B] } or { nd = N, abbe = V }"
                } else {
                    "{ nm = [...], values = [...] }"
                };
                Err(de::Error::custom(format_args!(
                    "`{field}`: a spectrum is {forms}; got the fields {}",
                    if given.is_empty() {
                        "none".to_string()
                    } else {
                        given
                            .iter()
                            .map(|k| format!("`{k}`"))
                            .collect::<Vec<_>>()
                            .join(", ")
                    }
                )))
            }
        }
    }
}
