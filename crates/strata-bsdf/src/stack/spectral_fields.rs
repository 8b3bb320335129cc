//! The fields of a material whose value depends on the wavelength, as
//! settable paths with their spectra: what a spectral query reads at its
//! wavelengths and sets as its own numbers (`api::spectral`).

use super::description::{InterfaceDesc, MaterialDesc};
use super::presets;
use super::set::{InterfaceField, MediumField, SetPath, Target};
use super::spectrum::Spectrum;

/// A field of a material whose value varies with wavelength.
#[derive(Clone, Debug, PartialEq)]
pub struct SpectralField {
    /// Where it is.
    pub path: SetPath,
    /// Its value; at a wavelength, [`Spectrum::at`].
    pub spectrum: Spectrum,
}

impl MaterialDesc {
    /// Its fields whose value varies with wavelength, top to bottom: the
    /// coloured ones (albedos, `sigma_t`, a conductor's `eta` and `k`, a
    /// preset's measured spectra) given as an RGB triple or a spectrum that
    /// is not constant, and a dielectric's `ior` given by a law or a
    /// spectrum that is not constant (a dispersive IOR). A grey value is
    /// the same at every wavelength and is left out.
    pub fn spectral_fields(&self) -> Vec<SpectralField> {
        let mut out = Vec::new();
        let mut add = |target: Target, s: &Spectrum| {
            if varies(s) {
                out.push(SpectralField {
                    path: SetPath { target },
                    spectrum: s.clone(),
                });
            }
        };
        for (i, layer) in self.layers.iter().enumerate() {
            let at = |f: InterfaceField| Target::Interface(i, f);
            match &layer.interface {
                InterfaceDesc::Dielectric { ior, .. } => add(at(InterfaceField::Ior), ior),
                InterfaceDesc::Conductor { preset, eta, k, .. } => {
                    let p = preset.as_deref().and_then(presets::preset);
                    let eta = eta.clone().or_else(|| p.map(presets::Preset::eta));
                    let k = k.clone().or_else(|| p.map(presets::Preset::k));
                    for (f, s) in [(InterfaceField::Eta, eta), (InterfaceField::K, k)] {
                        if let Some(s) = s {
                            add(at(f), &s);
                        }
                    }
                }
                InterfaceDesc::Diffuse { albedo, .. } => add(at(InterfaceField::Albedo), albedo),
            }
            if let Some(m) = &layer.medium {
                add(Target::Medium(i, MediumField::SigmaT), &m.sigma_t);
                add(Target::Medium(i, MediumField::Albedo), &m.albedo);
            }
        }
        out
    }
}

/// Whether `s` takes more than one value over the wavelengths.
fn varies(s: &Spectrum) -> bool {
    match s {
        Spectrum::Grey(_) => false,
        Spectrum::Rgb([r, g, b]) => !(r == g && g == b),
        Spectrum::Tabulated { values, .. } => values.iter().any(|v| *v != values[0]),
        Spectrum::Cauchy { cauchy: [_, b] } => *b != 0.0,
        // Its Cauchy B is (nd − 1) / (V (λF⁻² − λC⁻²)).
        Spectrum::Abbe { nd, abbe } => *nd != 1.0 && abbe.is_finite(),
    }
}

#[cfg(test)]
mod tests {
    use crate::stack::LayerStack;

    /// Which fields vary: grey values and constant spectra do not; RGB
    /// triples, spectra, laws and presets do.
    #[test]
    fn the_fields_that_vary_are_listed_with_their_paths() {
        let toml = "[[layers]]\n\
            interface = { kind = \"dielectric\", ior = { cauchy = [1.5, 0.004] } }\n\
            medium = { thickness = 1, sigma_t = [1, 2, 3], albedo = 0.5 }\n\
            [[layers]]\n\
            interface = { kind = \"dielectric\", ior = 1.3 }\n\
            medium = { thickness = 1, sigma_t = { nm = [400, 700], values = [2, 2] }, albedo = { nm = [400, 700], values = [0.1, 0.9] } }\n\
            [[layers]]\ninterface = { kind = \"conductor\", preset = \"Cu\" }\n";
        let st = LayerStack::from_toml_str(toml).unwrap();
        let paths: Vec<String> = (st.desc().spectral_fields().iter())
            .map(|f| f.path.to_string())
            .collect();
        assert_eq!(
            paths,
            [
                "layers[0].interface.ior",
                "layers[0].medium.sigma_t",
                "layers[1].medium.albedo",
                "layers[2].interface.eta",
                "layers[2].interface.k",
            ]
        );
        let diffuse = "[[layers]]\ninterface = { kind = \"diffuse\", albedo = 0.8 }\n";
        let st = LayerStack::from_toml_str(diffuse).unwrap();
        assert!(st.desc().spectral_fields().is_empty());
        // An Abbe form at nd = 1 has no spread (its Cauchy B is 0).
        let flat =
            "[[layers]]\ninterface = { kind = \"dielectric\", ior = { nd = 1.0, abbe = 30 } }\n";
        let st = LayerStack::from_toml_str(flat).unwrap();
        assert!(st.desc().spectral_fields().is_empty());
    }
}
