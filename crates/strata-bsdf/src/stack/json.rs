//! JSON materials read with the path of every value, so that an error names
//! where it is (`layers[0].interface: invalid type: string "NaN", expected
//! `ior` to be a number`), as a TOML error shows the line it is on.
//!
//! The text is parsed into a [`serde_json::Value`] first (a syntax error
//! keeps serde_json's line and column); the description is then read from
//! that tree by [`At`], a deserializer that knows the path of the value it
//! holds and puts it in front of the first error raised at or below it.

use serde::de::value::BorrowedStrDeserializer;
use serde::de::{self, DeserializeSeed, Deserializer, MapAccess, SeqAccess};
use serde::de::{DeserializeOwned, Visitor};
use serde_json::Value;
use std::fmt;

/// An error reading a tree, with the path of the value it is about.
#[derive(Debug)]
pub(crate) struct PathError {
    /// Where (`layers[0].interface`; empty at the root), once known.
    path: Option<String>,
    message: String,
}

impl PathError {
    /// `self`, at `path` unless a deeper value already claimed it.
    fn at(mut self, path: &str) -> Self {
        if self.path.is_none() {
            self.path = Some(path.to_owned());
        }
        self
    }
}

impl de::Error for PathError {
    fn custom<T: fmt::Display>(message: T) -> Self {
        PathError {
            path: None,
            message: message.to_string(),
        }
    }
}

impl fmt::Display for PathError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.path.as_deref() {
            Some(p) if !p.is_empty() => write!(f, "{p}: {}", self.message),
            _ => write!(f, "{}", self.message),
        }
    }
}

impl std::error::Error for PathError {}

/// Reads a `T` from `tree`; an error names the path of the value at fault.
pub(crate) fn from_tree<T: DeserializeOwned>(tree: &Value) -> Result<T, PathError> {
    T::deserialize(At {
        value: tree,
        path: String::new(),
    })
}

/// A value of the tree and its path.
struct At<'a> {
    value: &'a Value,
    path: String,
}

impl<'a> At<'a> {
    fn key(&self, key: &str, value: &'a Value) -> At<'a> {
        let path = if self.path.is_empty() {
            key.to_owned()
        } else {
            format!("{}.{key}", self.path)
        };
        At { value, path }
    }
    fn index(&self, i: usize, value: &'a Value) -> At<'a> {
        At {
            value,
            path: format!("{}[{i}]", self.path),
        }
    }
}

impl<'de> Deserializer<'de> for At<'de> {
    type Error = PathError;

    fn deserialize_any<V: Visitor<'de>>(self, v: V) -> Result<V::Value, PathError> {
        let r = match self.value {
            Value::Null => v.visit_unit(),
            Value::Bool(b) => v.visit_bool(*b),
            Value::Number(n) => {
                if let Some(u) = n.as_u64() {
                    v.visit_u64(u)
                } else if let Some(i) = n.as_i64() {
                    v.visit_i64(i)
                } else if let Some(x) = n.as_f64() {
                    v.visit_f64(x)
                } else {
                    Err(de::Error::custom(format_args!("{n}: not a number")))
                }
            }
            Value::String(s) => v.visit_borrowed_str(s),
            Value::Array(a) => {
                let mut seq = Seq {
                    at: &self,
                    items: a.iter().enumerate(),
                };
                v.visit_seq(&mut seq).and_then(|r| match seq.items.len() {
                    0 => Ok(r),
                    _ => Err(de::Error::invalid_length(a.len(), &"fewer elements")),
                })
            }
            Value::Object(m) => {
                let mut map = Map {
                    at: &self,
                    entries: m.iter(),
                    value: None,
                };
                v.visit_map(&mut map).and_then(|r| match map.entries.len() {
                    0 => Ok(r),
                    _ => Err(de::Error::invalid_length(m.len(), &"fewer entries")),
                })
            }
        };
        r.map_err(|e| e.at(&self.path))
    }

    fn deserialize_option<V: Visitor<'de>>(self, v: V) -> Result<V::Value, PathError> {
        match self.value {
            Value::Null => v.visit_none().map_err(|e: PathError| e.at(&self.path)),
            _ => {
                let path = self.path.clone();
                v.visit_some(self).map_err(|e| e.at(&path))
            }
        }
    }

    fn deserialize_enum<V: Visitor<'de>>(
        self,
        name: &'static str,
        variants: &'static [&'static str],
        v: V,
    ) -> Result<V::Value, PathError> {
        match self.value {
            // A unit variant, by name (`"ggx"`).
            Value::String(s) => BorrowedStrDeserializer::<PathError>::new(s)
                .deserialize_enum(name, variants, v)
                .map_err(|e| e.at(&self.path)),
            _ => self.deserialize_any(v),
        }
    }

    fn deserialize_newtype_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        v: V,
    ) -> Result<V::Value, PathError> {
        let path = self.path.clone();
        v.visit_newtype_struct(self).map_err(|e| e.at(&path))
    }

    serde::forward_to_deserialize_any! {
        bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string
        bytes byte_buf unit unit_struct seq tuple tuple_struct map struct
        identifier ignored_any
    }
}

/// The elements of an array, each with its index in the path.
struct Seq<'s, 'a> {
    at: &'s At<'a>,
    items: std::iter::Enumerate<std::slice::Iter<'a, Value>>,
}

impl<'de> SeqAccess<'de> for Seq<'_, 'de> {
    type Error = PathError;

    fn next_element_seed<T: DeserializeSeed<'de>>(
        &mut self,
        seed: T,
    ) -> Result<Option<T::Value>, PathError> {
        match self.items.next() {
            Some((i, value)) => seed.deserialize(self.at.index(i, value)).map(Some),
            None => Ok(None),
        }
    }

    fn size_hint(&self) -> Option<usize> {
        Some(self.items.len())
    }
}

/// The entries of an object, each value with its key in the path.
struct Map<'s, 'a> {
    at: &'s At<'a>,
    entries: serde_json::map::Iter<'a>,
    /// The value of the key just read.
    value: Option<(&'a str, &'a Value)>,
}

impl<'de> MapAccess<'de> for Map<'_, 'de> {
    type Error = PathError;

    fn next_key_seed<K: DeserializeSeed<'de>>(
        &mut self,
        seed: K,
    ) -> Result<Option<K::Value>, PathError> {
        match self.entries.next() {
            Some((key, value)) => {
                self.value = Some((key.as_str(), value));
                let d = BorrowedStrDeserializer::<PathError>::new(key);
                seed.deserialize(d).map(Some)
            }
            None => Ok(None),
        }
    }

    fn next_value_seed<V: DeserializeSeed<'de>>(&mut self, seed: V) -> Result<V::Value, PathError> {
        match self.value.take() {
            Some((key, value)) => seed.deserialize(self.at.key(key, value)),
            None => Err(de::Error::custom("a value asked for before its key")),
        }
    }

    fn size_hint(&self) -> Option<usize> {
        Some(self.entries.len())
    }
}

#[cfg(test)]
mod tests {
    use crate::stack::{LayerStack, MaterialError};

    fn json_error(json: &str) -> String {
        match LayerStack::from_json_str(json) {
            Err(e @ MaterialError::Parse { .. }) => e.to_string(),
            other => panic!("{json}: expected a parse error, got {other:?}"),
        }
    }

    fn layers(first: &str) -> String {
        format!(r#"{{"layers":[{first},{{"interface":{{"kind":"diffuse","albedo":0.5}}}}]}}"#)
    }

    /// An error in a JSON material's values names the layer and the field
    /// (it once said only "expected f64 at line 1 column 63").
    #[test]
    fn json_errors_name_the_layer_and_the_field() {
        let cases = [
            (
                layers(r#"{"interface":{"kind":"dielectric","ior":"NaN"}}"#),
                "layers[0].interface: invalid type: string \"NaN\", expected `ior` to be a number",
            ),
            (
                layers(
                    r#"{"interface":{"kind":"dielectric","ior":1.5},"medium":{"thickness":"x","sigma_t":1}}"#,
                ),
                "layers[0].medium.thickness: invalid type: string \"x\", expected f64",
            ),
            (
                r#"{"layers":[{"interface":{"kind":"diffuse","albedo":[0.5,true,0.5]}}]}"#.into(),
                "layers[0].interface: `albedo`: invalid type: boolean `true`, expected f64",
            ),
            (
                r#"{"exterior_ior":"1","layers":[]}"#.into(),
                "exterior_ior: invalid type: string \"1\", expected f64",
            ),
            (
                layers(
                    r#"{"interface":{"kind":"dielectric","ior":1.5},"medium":{"thickness":1,"sigma_t":1,"phase":{"kind":"hg","g":null}}}"#,
                ),
                "layers[0].medium.phase: invalid type: unit value, expected `g` to be a number",
            ),
            (
                layers(r#"{"interface":{"kind":"dielectric","ior":1.5,"normal":[0,"a",1]}}"#),
                "layers[0].interface: invalid type: string \"a\", expected `normal` to be a number",
            ),
            (
                layers(r#"{"interface":{"kind":"dielectric","ior":1.5},"medum":{}}"#),
                "layers[0]: unknown field `medum`",
            ),
            (
                r#"{"layers":[{"interface":{"kind":"diffuse","albedo":0.5}}],"two_sided":1}"#
                    .into(),
                "two_sided: invalid type: integer `1`, expected a boolean",
            ),
        ];
        for (json, want) in cases {
            let e = json_error(&json);
            assert!(e.contains(want), "{json}:\n{e}\nwants {want}");
        }
        // A syntax error still says where it is in the text.
        let e = json_error(r#"{"layers":[}"#);
        assert!(e.contains("line 1 column 12"), "{e}");
        // TOML names the field of an interface too (it pointed at the table).
        let toml = "[[layers]]\ninterface = { kind = \"dielectric\", ior = \"NaN\" }\n";
        let e = LayerStack::from_toml_str(toml).unwrap_err().to_string();
        assert!(e.contains("expected `ior` to be a number"), "{e}");
    }

    /// A table written as a positional array (`["diffuse", 0.5]` for
    /// `{kind = "diffuse", albedo = 0.5}`) is an error naming where, in
    /// JSON and TOML (serde's derived impls took one).
    #[test]
    fn positional_arrays_are_not_tables() {
        let json = [
            (
                r#"[null, 1.0, false, [{"interface":{"kind":"diffuse","albedo":0.5}}]]"#,
                "invalid type: sequence, expected a material",
            ),
            (
                r#"{"layers":[[{"kind":"diffuse","albedo":0.5}]]}"#,
                "layers[0]: invalid type: sequence, expected a layer",
            ),
            (
                r#"{"layers":[{"interface":["diffuse",0.5]}]}"#,
                "layers[0].interface: invalid type: sequence, expected an interface",
            ),
            (
                r#"{"layers":[{"interface":{"kind":"dielectric","ior":1.5},"medium":[1,1]},{"interface":{"kind":"diffuse","albedo":0.5}}]}"#,
                "layers[0].medium: invalid type: sequence, expected a medium",
            ),
            (
                r#"{"layers":[{"interface":{"kind":"dielectric","ior":1.5},"medium":{"thickness":1,"sigma_t":1,"phase":["hg",0.5]}},{"interface":{"kind":"diffuse","albedo":0.5}}]}"#,
                "layers[0].medium.phase: invalid type: sequence, expected a phase function",
            ),
            (
                r#"{"layers":[{"interface":{"kind":"dielectric","ior":1.5},"medium":{"thickness":1,"sigma_t":1,"phase":{"kind":"mixture","components":[[1.0,"isotropic"]]}}},{"interface":{"kind":"diffuse","albedo":0.5}}]}"#,
                "layers[0].medium.phase: invalid type: sequence, expected a mixture's lobe",
            ),
        ];
        for (text, want) in json {
            let e = json_error(text);
            assert!(e.contains(want), "{text}:\n{e}\nwants {want}");
        }
        let toml = [
            (
                "[[layers]]\ninterface = [\"diffuse\", 0.5]\n",
                "expected an interface",
            ),
            (
                "layers = [[{ kind = \"diffuse\", albedo = 0.5 }]]\n",
                "expected a layer",
            ),
        ];
        for (text, want) in toml {
            let e = LayerStack::from_toml_str(text).unwrap_err().to_string();
            assert!(
                e.contains("invalid type: sequence") && e.contains(want),
                "{text}:\n{e}"
            );
        }
    }

    /// Every built-in material reads back from its JSON as the same stack.
    #[test]
    fn builtin_materials_read_back_from_json() {
        for (name, _) in crate::materials::BUILTIN {
            let st = crate::materials::builtin(name).expect("built in");
            let json = serde_json::to_string(st.desc()).expect("serializes");
            let back = LayerStack::from_json_str(&json).expect(name);
            assert_eq!(back, st, "{name}");
            let toml = toml::to_string(st.desc()).expect("serializes");
            assert_eq!(LayerStack::from_toml_str(&toml).expect(name), st, "{name}");
        }
    }
}
