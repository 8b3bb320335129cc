//! Spectral queries: three wavelengths a query, one in each channel.
//!
//! A spectral renderer carries wavelengths per path. strata's walks carry
//! three channels, so a query may give three wavelengths (in nm) and read
//! its answer's channel `c` as the value at its wavelength `c`. Its
//! material's spectra are read at its wavelengths and become the query's
//! own numbers, per-query columns that [`PerQuery`] answers: a coloured
//! field (albedos, `sigma_t`, a conductor's `eta` and `k`) one value per
//! wavelength; an IOR that varies with wavelength one value, since a walk
//! refracts in one direction. A query of such a stack therefore gives one
//! wavelength, three times (a dispersive query's four wavelengths are four
//! queries). A renderer's own textures of coloured fields are RGB triples,
//! read at the query's wavelengths through the same uplift as a material
//! file's RGB values (`Spectrum::at`).
//!
//! [`PerQuery`]: super::PerQuery

use super::bsdf::LayeredBsdf;
use super::columns::{query_stack, Column, ColumnsError};
use crate::stack::spectrum::rgb_at;
use crate::stack::SetPath;
use std::fmt;

/// The per-query columns of spectral queries: a caller's own columns (at
/// their indices; coloured ones read at each query's three wavelengths)
/// and the template's fields that vary with wavelength, read at them. They
/// hold `4 × width` bytes per query and column, allocated fallibly. [`SpectralColumns::columns`]
/// gives them to [`super::PerQuery::new`] or [`super::Materials::per_query`].
///
/// ```
/// use strata_bsdf::{LayerStack, LayeredBsdf, PerQuery, SpectralColumns};
/// let bsdf = LayeredBsdf::new(LayerStack::from_toml_str(
///     "[[layers]]\ninterface = { kind = \"conductor\", preset = \"Au\", roughness = 0.2 }\n",
/// ).unwrap());
/// // Two queries: 450, 550 and 650 nm, then 700 nm three times.
/// let nm = [450.0, 550.0, 650.0, 700.0, 700.0, 700.0];
/// let spectral = SpectralColumns::new(&bsdf, &nm, &[]).unwrap();
/// let queries = PerQuery::new(&bsdf, spectral.queries(), &spectral.columns()).unwrap();
/// assert_eq!(queries.len(), 2);
/// ```
#[derive(Clone, Debug, Default)]
pub struct SpectralColumns {
    queries: usize,
    columns: Vec<(SetPath, usize, Vec<f32>)>,
}

/// Wavelengths or columns that cannot make spectral queries.
#[derive(Clone, Debug, PartialEq)]
pub enum SpectralError {
    /// Not three wavelengths a query (for [`LayeredBsdf::at_wavelengths`],
    /// not one to three).
    Length {
        /// The number of wavelengths given.
        len: usize,
    },
    /// A wavelength that is not a positive, finite number of nm.
    Wavelength {
        /// The query's index.
        query: usize,
        /// The wavelength.
        value: f32,
    },
    /// A query with different wavelengths on a stack whose IOR varies with
    /// wavelength: one walk cannot refract at three IORs.
    Dispersive {
        /// The query's index.
        query: usize,
        /// The IOR's path.
        path: String,
        /// The query's wavelengths.
        nm: [f32; 3],
    },
    /// A caller's column of the wrong width or length.
    Columns(Box<ColumnsError>),
    /// The columns' memory could not be allocated.
    OutOfMemory {
        /// The bytes asked for.
        bytes: usize,
    },
}

/// `len` zeros, allocated fallibly.
fn filled(len: usize) -> Result<Vec<f32>, SpectralError> {
    let mut v = Vec::new();
    let bytes = len.saturating_mul(std::mem::size_of::<f32>());
    v.try_reserve_exact(len)
        .map_err(|_| SpectralError::OutOfMemory { bytes })?;
    v.resize(len, 0.0);
    Ok(v)
}

impl fmt::Display for SpectralError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SpectralError::Length { len } => write!(
                f,
                "{len} wavelengths: a spectral query gives 3 (one per channel)"
            ),
            SpectralError::Wavelength { query, value } => write!(
                f,
                "query {query}: wavelength {value} nm; expected a positive, finite number"
            ),
            SpectralError::Dispersive { query, path, nm } => write!(
                f,
                "query {query}: `{path}` varies with wavelength and a walk refracts at one \
                 IOR: give one wavelength three times, not {} / {} / {} nm",
                nm[0], nm[1], nm[2]
            ),
            SpectralError::Columns(e) => e.fmt(f),
            SpectralError::OutOfMemory { bytes } => write!(
                f,
                "out of memory: cannot allocate {bytes} bytes of spectral columns"
            ),
        }
    }
}

impl std::error::Error for SpectralError {}

impl SpectralColumns {
    /// The columns of `nm.len() / 3` queries of `template`'s material, query
    /// `k` at wavelengths `nm[3k..3k + 3]` (nm), with the caller's
    /// `columns` (a texture): a coloured one's RGB triples read at the
    /// query's wavelengths, the others as given. A caller's column replaces
    /// the material's field of the same path.
    pub fn new(
        template: &LayeredBsdf,
        nm: &[f32],
        columns: &[Column],
    ) -> Result<Self, SpectralError> {
        if nm.len() % 3 != 0 {
            return Err(SpectralError::Length { len: nm.len() });
        }
        let queries = nm.len() / 3;
        let at = |k: usize| -> [f32; 3] { [nm[3 * k], nm[3 * k + 1], nm[3 * k + 2]] };
        for k in 0..queries {
            if let Some(&value) = at(k).iter().find(|x| !(x.is_finite() && **x > 0.0)) {
                return Err(SpectralError::Wavelength { query: k, value });
            }
        }
        for c in columns {
            if !matches!(c.width, 1 | 3) || c.values.len() != c.width * queries {
                return Err(SpectralError::Columns(Box::new(ColumnsError::Length {
                    path: c.path.to_string(),
                    width: c.width,
                    len: c.values.len(),
                    queries,
                })));
            }
        }
        let mut out = SpectralColumns {
            queries,
            columns: Vec::new(),
        };
        // The caller's columns first, at their own indices (an error about
        // column `i` names the caller's column `i`).
        for c in columns {
            let mut values = filled(c.values.len())?;
            if c.path.coloured() && c.width == 3 {
                for (k, v) in values.chunks_exact_mut(3).enumerate() {
                    let rgb = std::array::from_fn(|i| f64::from(c.values[3 * k + i]));
                    for (v, x) in v.iter_mut().zip(at(k)) {
                        *v = rgb_at(rgb, f64::from(x)) as f32;
                    }
                }
            } else {
                values.copy_from_slice(c.values);
            }
            out.columns.push((c.path.clone(), c.width, values));
        }
        let fields = template.stack().desc().spectral_fields();
        for f in fields
            .iter()
            .filter(|f| columns.iter().all(|c| *c.path != f.path))
        {
            let read = |x: f32| f.spectrum.at(f64::from(x)) as f32;
            let width = if f.path.coloured() { 3 } else { 1 };
            let mut values = filled(width * queries)?;
            for (k, v) in values.chunks_exact_mut(width).enumerate() {
                let w = at(k);
                if width == 3 {
                    for (v, x) in v.iter_mut().zip(w) {
                        *v = read(x);
                    }
                } else if w[1] != w[0] || w[2] != w[0] {
                    let path = f.path.to_string();
                    return Err(SpectralError::Dispersive {
                        query: k,
                        path,
                        nm: w,
                    });
                } else {
                    v[0] = read(w[0]);
                }
            }
            out.columns.push((f.path.clone(), width, values));
        }
        Ok(out)
    }

    /// The number of queries.
    pub fn queries(&self) -> usize {
        self.queries
    }

    /// The columns, for [`super::PerQuery::new`].
    pub fn columns(&self) -> Vec<Column<'_>> {
        (self.columns.iter())
            .map(|(path, width, values)| Column {
                path,
                width: *width,
                values,
            })
            .collect()
    }
}

impl LayeredBsdf {
    /// This BSDF's material at the wavelengths `nm` (one to three; channel
    /// `c` at `nm[c]`, the spare channels repeating the last), with the same
    /// configuration: the material of one spectral query
    /// ([`SpectralColumns`]), for a batch whose queries share their
    /// wavelengths.
    pub fn at_wavelengths(&self, nm: &[f32]) -> Result<LayeredBsdf, SpectralError> {
        let Some(&last) = nm.last().filter(|_| nm.len() <= 3) else {
            return Err(SpectralError::Length { len: nm.len() });
        };
        let nm: [f32; 3] = std::array::from_fn(|c| nm.get(c).copied().unwrap_or(last));
        let s = SpectralColumns::new(self, &nm, &[])?;
        let stack = query_stack(self.stack(), &s.columns(), 0)
            .map_err(|e| SpectralError::Columns(Box::new(e)))?;
        Ok(self.with_stack(stack))
    }

    /// How many wavelengths one walk carries: three, or one where the
    /// stack's IOR varies with wavelength (a walk refracts at one IOR).
    pub fn wavelengths_per_walk(&self) -> usize {
        let fields = self.stack().desc().spectral_fields();
        match fields.iter().any(|f| !f.path.coloured()) {
            true => 1,
            false => 3,
        }
    }

    /// The wavelengths each walk answers of `nm`, in groups of
    /// [`LayeredBsdf::wavelengths_per_walk`] ([`LayeredBsdf::at_wavelengths`]
    /// of each is a walk's material).
    pub fn wavelength_groups<'n>(&self, nm: &'n [f32]) -> Vec<&'n [f32]> {
        nm.chunks(self.wavelengths_per_walk()).collect()
    }
}
