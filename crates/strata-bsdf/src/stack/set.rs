//! Per-query overrides ("set"): a number of the material tree replaced by
//! another, e.g. `layers[0].medium.thickness = 0.5`.
//!
//! A [`SetPath`] is parsed (and its grammar checked) once; applying it with
//! [`MaterialDesc::apply_set`] writes the value into the description through
//! the same serde deserializers a material file goes through, and
//! [`LayerStack::with_set`] rebuilds the stack through [`LayerStack::new`], so
//! that the result is `==` to the stack a file with those values gives. The
//! paths, rules and errors are documented in `docs/materials.md`, "Per-query
//! overrides (`set`)".
//!
//! Rules:
//! - Only numeric parameters can be set (the stack's shape, `kind`,
//!   `preset`, `distribution`, `shadowing`, `two_sided`, is not); a value is
//!   a number or an array of numbers, whose length the field decides.
//! - A path must exist in the material: a layer index out of range, a field
//!   the interface's kind does not have (`ior` of a conductor), a medium field
//!   of a layer without a medium, or `phase.g` of an isotropic phase is an
//!   error; nothing is created.
//! - Setting `eta` or `k` of a conductor given by `preset` replaces the
//!   preset: the other of the two takes the preset's measured spectrum, so
//!   the result is the conductor written with explicit `eta` and `k`.
//! - Entries at different paths commute (the preset rule included), so the
//!   order of a set does not matter; the same path twice is an error.

use super::description::{InterfaceDesc, LayerDesc, MaterialDesc, PhaseDesc};
use super::error::StackError;
use super::layer_stack::LayerStack;
use super::presets;
use serde::Deserialize;
use serde_json::Value;
use std::fmt;

/// What a [`SetPath`] designates.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(super) enum Target {
    /// `exterior_ior`.
    ExteriorIor,
    /// `layers[i].interface.<field>`.
    Interface(usize, InterfaceField),
    /// `layers[i].medium.<field>`.
    Medium(usize, MediumField),
}

/// A settable field of an interface.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(super) enum InterfaceField {
    Ior,
    Roughness,
    Eta,
    K,
    Albedo,
    Normal,
}

impl InterfaceField {
    fn name(self) -> &'static str {
        match self {
            InterfaceField::Ior => "ior",
            InterfaceField::Roughness => "roughness",
            InterfaceField::Eta => "eta",
            InterfaceField::K => "k",
            InterfaceField::Albedo => "albedo",
            InterfaceField::Normal => "normal",
        }
    }
}

/// A settable field of a medium.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(super) enum MediumField {
    Thickness,
    SigmaT,
    Albedo,
    PhaseG,
    PhaseRoughness,
    PhaseAxis,
}

impl MediumField {
    fn name(self) -> &'static str {
        match self {
            MediumField::Thickness => "thickness",
            MediumField::SigmaT => "sigma_t",
            MediumField::Albedo => "albedo",
            MediumField::PhaseG => "phase.g",
            MediumField::PhaseRoughness => "phase.roughness",
            MediumField::PhaseAxis => "phase.axis",
        }
    }
}

const INTERFACE_FIELDS: &str = "ior, roughness, eta, k, albedo, normal";
const MEDIUM_FIELDS: &str = "thickness, sigma_t, albedo, phase.g, phase.roughness, phase.axis";

/// A path to a numeric parameter of a material, parsed and checked once:
/// `exterior_ior`, `layers[i].interface.<ior|roughness|eta|k|albedo|normal>` or
/// `layers[i].medium.<thickness|sigma_t|albedo|phase.g|phase.roughness|phase.axis>`
/// (the last two of an SGGX phase).
///
/// Whether the path exists in a given material (the layer, the interface's
/// kind, the medium) is checked when it is applied.
///
/// ```
/// use strata_bsdf::stack::SetPath;
/// let p: SetPath = "layers[0].medium.thickness".parse().unwrap();
/// assert_eq!(p.to_string(), "layers[0].medium.thickness");
/// assert!("layers[0].medium.thicknes".parse::<SetPath>().is_err());
/// ```
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct SetPath {
    pub(super) target: Target,
}

impl SetPath {
    /// Parses a path, e.g. `layers[2].interface.eta`.
    pub fn parse(path: &str) -> Result<SetPath, SetError> {
        let bad = |problem: String| SetError::Path {
            path: path.to_string(),
            problem,
        };
        if path == "exterior_ior" {
            return Ok(SetPath {
                target: Target::ExteriorIor,
            });
        }
        if matches!(path, "two_sided" | "description") {
            return Err(bad(format!(
                "`{path}` is not a numeric parameter (a set changes numbers only)"
            )));
        }
        let Some(rest) = path.strip_prefix("layers[") else {
            return Err(bad(
                "expected `exterior_ior`, or a path starting with `layers[INDEX].`".into(),
            ));
        };
        let Some((index, rest)) = rest.split_once(']') else {
            return Err(bad("`layers[` without a closing `]`".into()));
        };
        if index.is_empty() || !index.bytes().all(|b| b.is_ascii_digit()) {
            return Err(bad(format!(
                "the layer index `{index}` is not a non-negative integer"
            )));
        }
        let layer: usize = index
            .parse()
            .map_err(|_| bad(format!("the layer index {index} is too large")))?;
        let Some(rest) = rest.strip_prefix('.') else {
            return Err(bad(format!(
                "expected `layers[{layer}].interface.FIELD` or `layers[{layer}].medium.FIELD`"
            )));
        };
        let not_numeric = |f: &str| {
            bad(format!(
                "`{f}` is not a numeric parameter (a set changes numbers only, not the stack's shape)"
            ))
        };
        let target = if let Some(field) = rest.strip_prefix("interface.") {
            let f = match field {
                "ior" => InterfaceField::Ior,
                "roughness" => InterfaceField::Roughness,
                "eta" => InterfaceField::Eta,
                "k" => InterfaceField::K,
                "albedo" => InterfaceField::Albedo,
                "normal" => InterfaceField::Normal,
                "kind" | "preset" | "distribution" | "shadowing" => return Err(not_numeric(field)),
                _ => {
                    return Err(bad(format!(
                        "unknown interface field `{field}` (settable: {INTERFACE_FIELDS})"
                    )))
                }
            };
            Target::Interface(layer, f)
        } else if let Some(field) = rest.strip_prefix("medium.") {
            let f = match field {
                "thickness" => MediumField::Thickness,
                "sigma_t" => MediumField::SigmaT,
                "albedo" => MediumField::Albedo,
                "phase.g" => MediumField::PhaseG,
                "phase.roughness" => MediumField::PhaseRoughness,
                "phase.axis" => MediumField::PhaseAxis,
                "phase" | "phase.kind" | "phase.flakes" | "phase.scattering" => {
                    return Err(not_numeric(field))
                }
                _ => {
                    return Err(bad(format!(
                        "unknown medium field `{field}` (settable: {MEDIUM_FIELDS})"
                    )))
                }
            };
            Target::Medium(layer, f)
        } else if matches!(rest, "interface" | "medium") {
            return Err(bad(format!(
                "name a field of the {rest}: a set replaces numbers, not whole tables"
            )));
        } else {
            return Err(bad(format!(
                "expected `interface.FIELD` or `medium.FIELD` after `layers[{layer}].`"
            )));
        };
        Ok(SetPath { target })
    }

    /// The layer the path is in (top = 0), or `None` for `exterior_ior`.
    pub fn layer(&self) -> Option<usize> {
        match self.target {
            Target::ExteriorIor => None,
            Target::Interface(l, _) | Target::Medium(l, _) => Some(l),
        }
    }

    /// Whether the field takes one value per colour channel (an albedo,
    /// `sigma_t`, a conductor's `eta` or `k`): what a spectral query reads
    /// at each of its wavelengths.
    pub fn coloured(&self) -> bool {
        matches!(
            self.target,
            Target::Interface(
                _,
                InterfaceField::Albedo | InterfaceField::Eta | InterfaceField::K
            ) | Target::Medium(_, MediumField::SigmaT | MediumField::Albedo)
        )
    }

    /// The field as [`StackError::field`] spells it: `exterior_ior`,
    /// `interface.eta`, `medium.phase.g`, ...
    pub fn field(&self) -> String {
        match self.target {
            Target::ExteriorIor => "exterior_ior".into(),
            Target::Interface(_, f) => format!("interface.{}", f.name()),
            Target::Medium(_, f) => format!("medium.{}", f.name()),
        }
    }
}

impl fmt::Display for SetPath {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.layer() {
            None => write!(f, "{}", self.field()),
            Some(l) => write!(f, "layers[{l}].{}", self.field()),
        }
    }
}

impl std::str::FromStr for SetPath {
    type Err = SetError;
    fn from_str(s: &str) -> Result<Self, SetError> {
        SetPath::parse(s)
    }
}

/// A set could not be applied.
#[derive(Clone, Debug, PartialEq)]
pub enum SetError {
    /// The path is not a path to a numeric parameter.
    Path {
        /// The path as given.
        path: String,
        /// What is wrong with it.
        problem: String,
    },
    /// The path is well formed but does not exist in this material.
    Missing {
        /// The path.
        path: String,
        /// What is missing.
        problem: String,
    },
    /// The value has the wrong type or shape for the field (the message is
    /// the material parser's).
    Value {
        /// The path.
        path: String,
        /// The value, as JSON.
        value: String,
        /// What is wrong.
        problem: String,
    },
    /// The same path appears twice in one set.
    Duplicate {
        /// The path.
        path: String,
    },
    /// The material with the values set is invalid: the same check, and the
    /// same message, as for a file with those values.
    Invalid {
        /// The entries (path and value, as JSON) the error is about: the one
        /// at the field the error names, or every entry of the set if the
        /// error names a field that was not set (a thickness set so large
        /// that `sigma_t` gives too deep a medium).
        set: Vec<(String, String)>,
        /// The validation error.
        error: StackError,
    },
}

impl fmt::Display for SetError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SetError::Path { path, problem } => write!(f, "set path `{path}`: {problem}"),
            SetError::Missing { path, problem } => write!(f, "set `{path}`: {problem}"),
            SetError::Value {
                path,
                value,
                problem,
            } => write!(f, "set `{path}` = {value}: {problem}"),
            SetError::Duplicate { path } => write!(f, "set `{path}`: given twice"),
            SetError::Invalid { set, error } => {
                write!(f, "set ")?;
                for (i, (p, v)) in set.iter().enumerate() {
                    if i > 0 {
                        write!(f, ", ")?;
                    }
                    write!(f, "`{p}` = {v}")?;
                }
                write!(f, ": invalid material: {error}")
            }
        }
    }
}

impl std::error::Error for SetError {}

/// The part of a layer a path is in.
enum Part {
    Interface(InterfaceField),
    Medium(MediumField),
}

/// Checks that a value is a number or an array of numbers (the shapes every
/// settable field takes; `null`, which would make `eta` absent, is refused).
fn check_shape(path: &SetPath, value: &Value) -> Result<(), SetError> {
    let ok = match value {
        Value::Number(_) => true,
        Value::Array(a) => a.iter().all(Value::is_number),
        _ => false,
    };
    if ok {
        Ok(())
    } else {
        Err(SetError::Value {
            path: path.to_string(),
            value: value.to_string(),
            problem: "expected a number or an array of numbers".into(),
        })
    }
}

impl MaterialDesc {
    /// Sets the parameter at `path` to `value`, read by the same deserializer
    /// as the field in a material file (so `0.5` and `[0.1, 0.2, 0.3]` are
    /// kept as given). Does not validate the values (see
    /// [`LayerStack::with_set`]); on error `self` is unchanged.
    ///
    /// Setting `eta` or `k` of a conductor given by `preset` replaces the
    /// preset, the other of the two taking the preset's measured spectrum.
    ///
    /// ```
    /// use strata_bsdf::stack::{MaterialDesc, SetPath};
    /// let mut d: MaterialDesc = toml::from_str(
    ///     "[[layers]]\ninterface = { kind = \"dielectric\", ior = 1.5 }\n",
    /// ).unwrap();
    /// d.apply_set(&"layers[0].interface.ior".parse().unwrap(), &serde_json::json!(1.33)).unwrap();
    /// assert!(d.apply_set(&"layers[1].interface.ior".parse().unwrap(), &serde_json::json!(1)).is_err());
    /// ```
    pub fn apply_set(&mut self, path: &SetPath, value: &Value) -> Result<(), SetError> {
        check_shape(path, value)?;
        let value_error = |e: serde_json::Error| SetError::Value {
            path: path.to_string(),
            value: value.to_string(),
            problem: e.to_string(),
        };
        let missing = |problem: String| SetError::Missing {
            path: path.to_string(),
            problem,
        };
        let (layer, part) = match path.target {
            Target::ExteriorIor => {
                self.exterior_ior = f64::deserialize(value).map_err(value_error)?;
                return Ok(());
            }
            Target::Interface(l, f) => (l, Part::Interface(f)),
            Target::Medium(l, f) => (l, Part::Medium(f)),
        };
        let n = self.layers.len();
        let Some(old) = self.layers.get(layer) else {
            return Err(missing(format!(
                "there is no layer {layer}: the material has {n} (layers[0] to layers[{}])",
                n.saturating_sub(1)
            )));
        };
        // The layer as JSON, the value written in, read back: every field
        // goes through its own deserializer, with its messages.
        let mut tree = serde_json::to_value(old).map_err(value_error)?;
        match part {
            Part::Interface(f) => {
                let (kind, has) = match &old.interface {
                    InterfaceDesc::Dielectric { .. } => (
                        "dielectric",
                        matches!(f, InterfaceField::Ior | InterfaceField::Roughness),
                    ),
                    InterfaceDesc::Conductor { .. } => (
                        "conductor",
                        matches!(
                            f,
                            InterfaceField::Eta | InterfaceField::K | InterfaceField::Roughness
                        ),
                    ),
                    InterfaceDesc::Diffuse { .. } => {
                        ("diffuse", matches!(f, InterfaceField::Albedo))
                    }
                };
                if !has && f != InterfaceField::Normal {
                    return Err(missing(format!(
                        "layer {layer}'s interface is a {kind}, which has no `{}`",
                        f.name()
                    )));
                }
                let iface = &mut tree["interface"];
                if let InterfaceDesc::Conductor {
                    preset: Some(p),
                    eta,
                    k,
                    ..
                } = &old.interface
                {
                    if matches!(f, InterfaceField::Eta | InterfaceField::K) {
                        let preset = presets::preset(p).ok_or_else(|| {
                            missing(format!(
                                "layer {layer}'s conductor preset {p:?} is unknown, so the \
                                 value it would leave for the other of eta and k is too"
                            ))
                        })?;
                        // The preset's measured spectra, as a file would write them.
                        let given = |v: &Option<_>, d| serde_json::to_value(v.clone().unwrap_or(d));
                        iface["eta"] = given(eta, preset.eta()).map_err(value_error)?;
                        iface["k"] = given(k, preset.k()).map_err(value_error)?;
                        iface["preset"] = Value::Null;
                    }
                }
                iface[f.name()] = value.clone();
            }
            Part::Medium(f) => {
                let Some(medium) = &old.medium else {
                    return Err(missing(format!(
                        "layer {layer} has no medium (a set does not create one; \
                         give the layer a medium in the material)"
                    )));
                };
                let m = &mut tree["medium"];
                if f == MediumField::PhaseG {
                    let kind = match medium.phase {
                        PhaseDesc::Hg { .. } => None,
                        PhaseDesc::Isotropic {} => Some("an isotropic"),
                        PhaseDesc::Mixture { .. } => Some("a mixture"),
                        PhaseDesc::Sggx { .. } => Some("an SGGX"),
                    };
                    if let Some(kind) = kind {
                        return Err(missing(format!(
                            "layer {layer}'s medium has {kind} phase, which has no `g` \
                             (an isotropic one can be given as phase = {{ kind = \"hg\", g = 0 }} \
                             in the material)"
                        )));
                    }
                    m["phase"]["g"] = value.clone();
                } else if matches!(f, MediumField::PhaseRoughness | MediumField::PhaseAxis) {
                    if !matches!(medium.phase, PhaseDesc::Sggx { .. }) {
                        return Err(missing(format!(
                            "layer {layer}'s medium has no SGGX phase, so no `{}`",
                            f.name()
                        )));
                    }
                    m["phase"][f.name().trim_start_matches("phase.")] = value.clone();
                } else {
                    m[f.name()] = value.clone();
                }
            }
        }
        self.layers[layer] = <LayerDesc as Deserialize>::deserialize(&tree).map_err(value_error)?;
        Ok(())
    }
}

impl LayerStack {
    /// The stack with the values of `set` in its description, validated by
    /// [`LayerStack::new`]: `==` to the stack read from a material file with
    /// those values. The entries are applied in order (entries at different
    /// paths commute; the same path twice is an error).
    ///
    /// ```
    /// use strata_bsdf::stack::{LayerStack, SetPath};
    /// let base = LayerStack::from_toml_str(
    ///     "[[layers]]\ninterface = { kind = \"dielectric\", ior = 1.5 }\n\
    ///      medium = { thickness = 1, sigma_t = 0.5 }\n\
    ///      [[layers]]\ninterface = { kind = \"conductor\", preset = \"Au\" }\n",
    /// ).unwrap();
    /// let set = [("layers[0].medium.thickness".parse::<SetPath>().unwrap(), serde_json::json!(0.25))];
    /// let thin = base.with_set(&set).unwrap();
    /// assert_eq!(thin.medium(0).unwrap().thickness, 0.25);
    /// let bad = [("layers[0].medium.thickness".parse::<SetPath>().unwrap(), serde_json::json!(-1))];
    /// assert!(base.with_set(&bad).is_err());
    /// ```
    pub fn with_set(&self, set: &[(SetPath, Value)]) -> Result<LayerStack, SetError> {
        for (i, (p, _)) in set.iter().enumerate() {
            if set[..i].iter().any(|(q, _)| q == p) {
                return Err(SetError::Duplicate {
                    path: p.to_string(),
                });
            }
        }
        let mut desc = self.desc().clone();
        for (p, v) in set {
            desc.apply_set(p, v)?;
        }
        LayerStack::new(&desc).map_err(|error| {
            let entry = |(p, v): &(SetPath, Value)| (p.to_string(), v.to_string());
            let at: Vec<_> = set
                .iter()
                .filter(|(p, _)| p.layer() == error.layer && p.field() == error.field)
                .map(entry)
                .collect();
            SetError::Invalid {
                set: if at.is_empty() {
                    set.iter().map(entry).collect()
                } else {
                    at
                },
                error,
            }
        })
    }
}
