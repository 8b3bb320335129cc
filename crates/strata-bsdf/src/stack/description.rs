//! The material description as read from TOML or JSON (serde), before validation.
//!
//! The format is documented in `docs/materials.md`. Every coloured field
//! accepts a single number (grey), three (RGB) or a tabulated spectrum, a
//! dielectric's `ior` a number, a tabulated spectrum or a dispersion law
//! ([`Spectrum`]); roughness accepts one number (isotropic) or
//! `[alpha_x, alpha_y]`.

use serde::de::{self, Deserializer, IgnoredAny, SeqAccess, Visitor};
use serde::{Deserialize, Serialize};
use std::fmt;

use super::spectrum::Spectrum;

/// Implements `Deserialize` for types whose derived impl is inherent
/// (`#[serde(remote = "Self")]`), taking a table (TOML) or an object (JSON)
/// only: serde's derived impls also take a sequence of the fields in order
/// (`["diffuse", 0.5]` for `{ kind = "diffuse", albedo = 0.5 }`), which
/// nothing documents and which reads a typo as a material. `what` is what
/// the error says was expected.
macro_rules! tables_only {
    ($($t:ty: $what:literal),* $(,)?) => {$(
        impl<'de> serde::Deserialize<'de> for $t {
            fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
                struct Table;
                impl<'de> serde::de::Visitor<'de> for Table {
                    type Value = $t;
                    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                        f.write_str($what)
                    }
                    fn visit_map<A: serde::de::MapAccess<'de>>(
                        self,
                        map: A,
                    ) -> Result<$t, A::Error> {
                        <$t>::deserialize(serde::de::value::MapAccessDeserializer::new(map))
                    }
                }
                d.deserialize_map(Table)
            }
        }
    )*};
}
pub(crate) use tables_only;

/// Implements `Serialize` by the inherent (`remote = "Self"`) derived impl.
macro_rules! serialized_as_derived {
    ($($t:ty),* $(,)?) => {$(
        impl Serialize for $t {
            fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
                <$t>::serialize(self, s)
            }
        }
    )*};
}

tables_only! {
    MaterialDesc: "a material (a table of `layers` and its other fields)",
    LayerDesc: "a layer (a table of `interface` and `medium`)",
    InterfaceDesc: "an interface (a table with `kind`)",
    MediumDesc: "a medium (a table with `thickness` and `sigma_t`)",
    PhaseDesc: "a phase function (a table with `kind`)",
    ComponentDesc: "a mixture's lobe (a table with `weight` and `kind`)",
}
serialized_as_derived!(
    MaterialDesc,
    LayerDesc,
    InterfaceDesc,
    MediumDesc,
    PhaseDesc,
    ComponentDesc
);

/// GGX alpha: one value (isotropic) or `[alpha_x, alpha_y]`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(untagged)]
pub enum Roughness {
    /// Isotropic alpha.
    Isotropic(f64),
    /// `[alpha_x, alpha_y]`.
    Anisotropic([f64; 2]),
}

impl Default for Roughness {
    fn default() -> Self {
        Roughness::Isotropic(0.0)
    }
}

impl<'de> Deserialize<'de> for Roughness {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let shape = "a number or [alpha_x, alpha_y]";
        Ok(match d.deserialize_any(OneOrN::<2>("roughness", shape))? {
            Ok(x) => Roughness::Isotropic(x),
            Err(a) => Roughness::Anisotropic(a),
        })
    }
}

/// Reads one number (`Ok`) or exactly `N` (`Err`), and says which field
/// wanted what when the value is neither: a derived untagged enum would only
/// say that "data did not match any variant" (and an interface's fields are
/// reported at the interface's table, not at the value, so the message is
/// all the reader has).
struct OneOrN<const N: usize>(&'static str, &'static str);

impl<'de, const N: usize> Visitor<'de> for OneOrN<N> {
    type Value = Result<f64, [f64; N]>;

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        write!(f, "`{}` to be {}", self.0, self.1)
    }
    fn visit_f64<E: de::Error>(self, v: f64) -> Result<Self::Value, E> {
        Ok(Ok(v))
    }
    fn visit_i64<E: de::Error>(self, v: i64) -> Result<Self::Value, E> {
        Ok(Ok(v as f64))
    }
    fn visit_u64<E: de::Error>(self, v: u64) -> Result<Self::Value, E> {
        Ok(Ok(v as f64))
    }
    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Self::Value, A::Error> {
        let mut a = [0.0; N];
        for (i, x) in a.iter_mut().enumerate() {
            *x = seq
                .next_element()
                .map_err(|e| de::Error::custom(format_args!("`{}`: {e}", self.0)))?
                .ok_or_else(|| de::Error::invalid_length(i, &self))?;
        }
        if seq.next_element::<IgnoredAny>()?.is_some() {
            return Err(de::Error::invalid_length(N + 1, &self));
        }
        Ok(Err(a))
    }
}

impl Roughness {
    /// `[alpha_x, alpha_y]`.
    pub fn alphas(self) -> [f64; 2] {
        match self {
            Roughness::Isotropic(a) => [a, a],
            Roughness::Anisotropic(a) => a,
        }
    }
}

/// Microfacet normal distribution.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Distribution {
    /// Trowbridge–Reitz (GGX), the default.
    #[default]
    Ggx,
    /// Beckmann.
    Beckmann,
}

/// Smith shadowing-masking form.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Shadowing {
    /// Height-correlated `1 / (1 + Λ(a) + Λ(b))`, the default (pbrt-v4).
    #[default]
    Correlated,
    /// Separable `G1(a) G1(b)` (Mitsuba, the authors' code).
    Separable,
}

/// One interface.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(remote = "Self")]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum InterfaceDesc {
    /// A dielectric boundary; `ior` is the IOR of the region below it.
    Dielectric {
        /// IOR of the region below (for the bottom interface: the exterior below).
        #[serde(deserialize_with = "field::ior")]
        ior: Spectrum,
        /// GGX alpha; 0 is smooth.
        #[serde(default)]
        roughness: Roughness,
        /// Normal distribution.
        #[serde(default)]
        distribution: Distribution,
        /// Shadowing form.
        #[serde(default)]
        shadowing: Shadowing,
        /// Shading normal `[x, y, z]` in the slab's frame (z up; normalized
        /// when read); absent or `[0, 0, 1]`: untilted (method.md §9).
        #[serde(
            default,
            skip_serializing_if = "Option::is_none",
            deserialize_with = "field::normal"
        )]
        normal: Option<[f64; 3]>,
    },
    /// An opaque conductor; complex IOR relative to vacuum, by preset or value.
    Conductor {
        /// A named metal (see [`crate::stack::presets`]).
        #[serde(default)]
        preset: Option<String>,
        /// Real part of the IOR per channel or as a spectrum.
        #[serde(default, deserialize_with = "field::eta")]
        eta: Option<Spectrum>,
        /// Imaginary part of the IOR per channel or as a spectrum.
        #[serde(default, deserialize_with = "field::k")]
        k: Option<Spectrum>,
        /// GGX alpha; 0 is smooth.
        #[serde(default)]
        roughness: Roughness,
        /// Normal distribution.
        #[serde(default)]
        distribution: Distribution,
        /// Shadowing form.
        #[serde(default)]
        shadowing: Shadowing,
        /// Shading normal `[x, y, z]` in the slab's frame (z up; normalized
        /// when read); absent or `[0, 0, 1]`: untilted (method.md §9).
        #[serde(
            default,
            skip_serializing_if = "Option::is_none",
            deserialize_with = "field::normal"
        )]
        normal: Option<[f64; 3]>,
    },
    /// An opaque Lambertian reflector.
    Diffuse {
        /// Reflectance per channel or as a spectrum.
        #[serde(deserialize_with = "field::albedo")]
        albedo: Spectrum,
        /// Shading normal `[x, y, z]` in the slab's frame (z up; normalized
        /// when read); absent or `[0, 0, 1]`: untilted (method.md §9).
        #[serde(
            default,
            skip_serializing_if = "Option::is_none",
            deserialize_with = "field::normal"
        )]
        normal: Option<[f64; 3]>,
    },
}

impl InterfaceDesc {
    /// The shading normal as given (`None`: untilted).
    pub fn normal(&self) -> Option<[f64; 3]> {
        match self {
            InterfaceDesc::Dielectric { normal, .. }
            | InterfaceDesc::Conductor { normal, .. }
            | InterfaceDesc::Diffuse { normal, .. } => *normal,
        }
    }
}

/// Phase function of a medium.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(remote = "Self")]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum PhaseDesc {
    /// Isotropic scattering. (A struct variant, so that a stray field such
    /// as `g` is an error rather than silently ignored.)
    Isotropic {},
    /// Henyey–Greenstein with asymmetry `g` in (-1, 1).
    Hg {
        /// Mean cosine of the scattering angle.
        #[serde(deserialize_with = "field::g")]
        g: f64,
    },
    /// A weighted sum of Henyey–Greenstein (or isotropic) lobes: the phase
    /// function of a mixture of particle kinds of the same extinction.
    Mixture {
        /// The lobes, 1 to 4 of them, with weights summing to 1.
        components: Vec<ComponentDesc>,
    },
    /// SGGX microflakes (Heitz et al. 2015): the medium's extinction along
    /// a direction ω is `sigma_t · sqrt(ωᵀ S ω)`.
    Sggx {
        /// The flakes' distribution about `axis`.
        flakes: Flakes,
        /// The distribution's axis (normalized when read).
        #[serde(deserialize_with = "field::axis")]
        axis: [f64; 3],
        /// In (0, 1]: the spread of the flakes (1: spheres, S = I).
        #[serde(deserialize_with = "field::flake_roughness")]
        roughness: f64,
        /// How a flake scatters (specular unless given).
        #[serde(default)]
        scattering: FlakeScattering,
    },
}

/// The kinds of SGGX microflake distribution.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Flakes {
    /// Flakes whose normals cluster about the axis:
    /// `S = r² I + (1 − r²) a aᵀ`.
    Surface,
    /// Fibres along the axis, normals across it: `S = I − (1 − r²) a aᵀ`.
    Fiber,
}

/// How an SGGX microflake scatters light.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FlakeScattering {
    /// A mirror: the phase function has a closed form.
    #[default]
    Specular,
    /// A Lambertian reflector: the phase function is estimated, one
    /// visible normal per evaluation (it has no closed form).
    Diffuse,
}

/// One lobe of a [`PhaseDesc::Mixture`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(remote = "Self", deny_unknown_fields)]
pub struct ComponentDesc {
    /// Its share, in (0, 1].
    #[serde(deserialize_with = "field::weight")]
    pub weight: f64,
    /// `hg` or `isotropic`.
    pub kind: ComponentKind,
    /// Henyey–Greenstein asymmetry (only for `hg`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub g: Option<f64>,
}

/// The kinds of lobe a mixture holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ComponentKind {
    /// Henyey–Greenstein (needs `g`).
    Hg,
    /// Isotropic (takes no `g`).
    Isotropic,
}

impl Default for PhaseDesc {
    fn default() -> Self {
        PhaseDesc::Isotropic {}
    }
}

/// A homogeneous medium below an interface.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(remote = "Self", deny_unknown_fields)]
pub struct MediumDesc {
    /// Geometric thickness (any unit; `sigma_t` is per that unit).
    pub thickness: f64,
    /// Extinction coefficient per channel or as a spectrum.
    #[serde(deserialize_with = "field::sigma_t")]
    pub sigma_t: Spectrum,
    /// Single-scattering albedo per channel or as a spectrum; 0 is a pure
    /// absorber.
    #[serde(default = "white", deserialize_with = "field::albedo")]
    pub albedo: Spectrum,
    /// Phase function.
    #[serde(default)]
    pub phase: PhaseDesc,
}

fn white() -> Spectrum {
    Spectrum::Grey(1.0)
}

/// Fields whose errors name them.
mod field {
    use crate::stack::spectrum::{spectrum_named, Forms, Spectrum};
    use serde::de::{self, IgnoredAny, SeqAccess, Visitor};
    use serde::Deserializer;
    use std::fmt;

    pub fn albedo<'de, D: Deserializer<'de>>(d: D) -> Result<Spectrum, D::Error> {
        spectrum_named(d, "albedo", Forms::Colour)
    }
    pub fn sigma_t<'de, D: Deserializer<'de>>(d: D) -> Result<Spectrum, D::Error> {
        spectrum_named(d, "sigma_t", Forms::Colour)
    }
    pub fn eta<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Spectrum>, D::Error> {
        d.deserialize_option(Optional("eta"))
    }
    pub fn k<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Spectrum>, D::Error> {
        d.deserialize_option(Optional("k"))
    }

    pub fn ior<'de, D: Deserializer<'de>>(d: D) -> Result<Spectrum, D::Error> {
        spectrum_named(d, "ior", Forms::Ior)
    }
    pub fn g<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        d.deserialize_f64(Number("g"))
    }
    pub fn flake_roughness<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        d.deserialize_f64(Number("roughness"))
    }
    pub fn weight<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        d.deserialize_f64(Number("weight"))
    }
    pub fn axis<'de, D: Deserializer<'de>>(d: D) -> Result<[f64; 3], D::Error> {
        d.deserialize_seq(Triple("axis"))
    }
    pub fn normal<'de, D: Deserializer<'de>>(d: D) -> Result<Option<[f64; 3]>, D::Error> {
        d.deserialize_option(OptionalTriple("normal"))
    }

    /// A number whose errors name its field: the fields of an interface or
    /// a phase function (tagged by `kind`) reach their deserializers from
    /// serde's buffer, which knows no field names, so the message is all
    /// that says which field is wrong.
    struct Number(&'static str);

    impl<'de> Visitor<'de> for Number {
        type Value = f64;
        fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
            write!(f, "`{}` to be a number", self.0)
        }
        fn visit_f64<E: de::Error>(self, v: f64) -> Result<f64, E> {
            Ok(v)
        }
        fn visit_i64<E: de::Error>(self, v: i64) -> Result<f64, E> {
            Ok(v as f64)
        }
        fn visit_u64<E: de::Error>(self, v: u64) -> Result<f64, E> {
            Ok(v as f64)
        }
    }

    /// Three numbers `[x, y, z]` whose errors name their field.
    struct Triple(&'static str);

    impl<'de> Visitor<'de> for Triple {
        type Value = [f64; 3];
        fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
            write!(f, "`{}` to be [x, y, z]", self.0)
        }
        fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<[f64; 3], A::Error> {
            let mut a = [0.0; 3];
            for (i, x) in a.iter_mut().enumerate() {
                *x = seq
                    .next_element_seed(NumberSeed(self.0))?
                    .ok_or_else(|| de::Error::invalid_length(i, &self))?;
            }
            if seq.next_element::<IgnoredAny>()?.is_some() {
                return Err(de::Error::invalid_length(4, &self));
            }
            Ok(a)
        }
    }

    /// A [`Number`] as an element of a sequence.
    struct NumberSeed(&'static str);

    impl<'de> de::DeserializeSeed<'de> for NumberSeed {
        type Value = f64;
        fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<f64, D::Error> {
            d.deserialize_f64(Number(self.0))
        }
    }

    /// An optional [`Triple`] (JSON writes an absent one as `null`).
    struct OptionalTriple(&'static str);

    impl<'de> Visitor<'de> for OptionalTriple {
        type Value = Option<[f64; 3]>;
        fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
            write!(f, "`{}` to be [x, y, z]", self.0)
        }
        fn visit_none<E: de::Error>(self) -> Result<Self::Value, E> {
            Ok(None)
        }
        fn visit_unit<E: de::Error>(self) -> Result<Self::Value, E> {
            Ok(None)
        }
        fn visit_some<D: Deserializer<'de>>(self, d: D) -> Result<Self::Value, D::Error> {
            d.deserialize_seq(Triple(self.0)).map(Some)
        }
    }

    /// An optional coloured field (JSON writes an absent one as `null`).
    struct Optional(&'static str);

    impl<'de> serde::de::Visitor<'de> for Optional {
        type Value = Option<Spectrum>;
        fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
            write!(
                f,
                "`{}` to be a number or [r, g, b], or a spectrum {{ nm = [...], values = [...] }}",
                self.0
            )
        }
        fn visit_none<E: serde::de::Error>(self) -> Result<Self::Value, E> {
            Ok(None)
        }
        fn visit_unit<E: serde::de::Error>(self) -> Result<Self::Value, E> {
            Ok(None)
        }
        fn visit_some<D: Deserializer<'de>>(self, d: D) -> Result<Self::Value, D::Error> {
            spectrum_named(d, self.0, Forms::Colour).map(Some)
        }
    }
}

/// One entry of the stack: an interface and the medium below it, if any.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(remote = "Self", deny_unknown_fields)]
pub struct LayerDesc {
    /// The interface.
    pub interface: InterfaceDesc,
    /// The medium below it (a clear gap if absent).
    #[serde(default)]
    pub medium: Option<MediumDesc>,
}

/// A whole material: interfaces listed top to bottom.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(remote = "Self", deny_unknown_fields)]
pub struct MaterialDesc {
    /// Free text saying what the material models (ignored by the physics; JSON
    /// has no comments, so this is where a JSON file says what it is).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub description: Option<String>,
    /// IOR of the exterior above the top interface.
    #[serde(default = "one")]
    pub exterior_ior: f64,
    /// Mirror light arriving from below an opaque stack so the top faces it.
    #[serde(default)]
    pub two_sided: bool,
    /// Layers, top to bottom.
    pub layers: Vec<LayerDesc>,
}

fn one() -> f64 {
    1.0
}

#[cfg(test)]
mod tests {
    use super::InterfaceDesc;
    use crate::stack::RgbParam;
    use crate::LayerStack;

    fn error(toml: &str) -> String {
        LayerStack::from_toml_str(toml)
            .expect_err("invalid material")
            .to_string()
    }

    /// A field the isotropic phase does not have is an error, not silently
    /// dropped (`g` with the wrong kind once gave isotropic scattering).
    #[test]
    fn isotropic_phase_rejects_fields() {
        let m = |phase: &str| {
            format!(
                "[[layers]]\ninterface = {{ kind = \"dielectric\", ior = 1.5 }}\n\
                 medium = {{ thickness = 1, sigma_t = 1, phase = {phase} }}\n\
                 [[layers]]\ninterface = {{ kind = \"diffuse\", albedo = 0.5 }}\n"
            )
        };
        let e = error(&m(r#"{ kind = "isotropic", g = 0.9 }"#));
        assert!(e.contains("unknown field `g`"), "{e}");
        let e = error(&m(r#"{ kind = "isotropic", bogus = "x" }"#));
        assert!(e.contains("unknown field `bogus`"), "{e}");
        let json = r#"{"layers":[{"interface":{"kind":"dielectric","ior":1.5},
            "medium":{"thickness":1,"sigma_t":1,"phase":{"kind":"isotropic","g":0.5}}},
            {"interface":{"kind":"diffuse","albedo":0.5}}]}"#;
        let e = LayerStack::from_json_str(json).expect_err("g on isotropic");
        assert!(e.to_string().contains("unknown field `g`"), "{e}");
        assert!(LayerStack::from_toml_str(&m(r#"{ kind = "isotropic" }"#)).is_ok());
        assert!(LayerStack::from_toml_str(&m(r#"{ kind = "hg", g = 0.9 }"#)).is_ok());
    }

    /// A per-channel or roughness value of the wrong shape names its field
    /// and the shapes it takes (a derived untagged enum named neither).
    #[test]
    fn wrong_shapes_name_the_field() {
        let cases = [
            (
                "interface = { kind = \"diffuse\", albedo = [0.5, 0.5] }",
                "invalid length 2, expected `albedo` to be a number or [r, g, b]",
            ),
            (
                "interface = { kind = \"diffuse\", albedo = \"x\" }",
                "invalid type: string \"x\", expected `albedo` to be a number or [r, g, b]",
            ),
            (
                "interface = { kind = \"conductor\", eta = [1, 2, 3, 4], k = 1 }",
                "invalid length 4, expected `eta` to be a number or [r, g, b]",
            ),
            (
                "interface = { kind = \"conductor\", eta = 1, k = true }",
                "invalid type: boolean `true`, expected `k` to be a number or [r, g, b]",
            ),
            (
                "interface = { kind = \"dielectric\", ior = 1.5, roughness = [0.1, 0.2, 0.3] }",
                "invalid length 3, expected `roughness` to be a number or [alpha_x, alpha_y]",
            ),
            (
                "interface = { kind = \"dielectric\", ior = 1.5 }\n\
                 medium = { thickness = 1, sigma_t = \"1\" }",
                "invalid type: string \"1\", expected `sigma_t` to be a number or [r, g, b]",
            ),
            (
                "interface = { kind = \"dielectric\", ior = 1.5 }\n\
                 medium = { thickness = 1, sigma_t = 1, albedo = [] }",
                "invalid length 0, expected `albedo` to be a number or [r, g, b]",
            ),
            (
                "interface = { kind = \"diffuse\", albedo = [0.5, \"x\", 0.5] }",
                "`albedo`: invalid type: string \"x\", expected f64",
            ),
        ];
        for (layer, want) in cases {
            let e = error(&format!("[[layers]]\n{layer}\n"));
            assert!(e.contains(want), "{layer}: {e}");
        }
        // JSON writes an absent optional field as null: it reads back as absent.
        let json =
            r#"{"layers":[{"interface":{"kind":"conductor","preset":"Cu","eta":null,"k":null}}]}"#;
        let st = LayerStack::from_json_str(json).expect("null is absent");
        let cu = LayerStack::from_toml_str(
            "[[layers]]\ninterface = { kind = \"conductor\", preset = \"Cu\" }\n",
        )
        .expect("preset");
        assert_eq!(st, cu);
        // The right shapes still parse, integers included.
        let ok = "[[layers]]\ninterface = { kind = \"dielectric\", ior = 1.5, roughness = [0.1, 0.2] }\n\
                  medium = { thickness = 1, sigma_t = [1, 2, 3], albedo = 1 }\n\
                  [[layers]]\ninterface = { kind = \"conductor\", eta = [0.2, 0.9, 1.1], k = 3 }\n";
        let st = LayerStack::from_toml_str(ok).expect("valid");
        let m = st.medium(0).expect("a medium");
        assert_eq!((m.sigma_t, m.albedo), ([1.0, 2.0, 3.0], [1.0; 3]));
        // (The stack keeps k relative to the coat above; the description as given.)
        let InterfaceDesc::Conductor { eta, k, .. } = &st.desc().layers[1].interface else {
            panic!("a conductor");
        };
        assert_eq!(
            (eta.clone(), k.clone()),
            (
                Some(RgbParam::Rgb([0.2, 0.9, 1.1])),
                Some(RgbParam::Grey(3.0))
            )
        );
        assert_eq!(st.interface(0).alpha, [0.1, 0.2]);
    }
}
