//! Parsing of query lines: `{"wi":[x,y,z],"wo":[x,y,z]}` (JSON, one per line),
//! as read by `strata eval` and by renderers that stream queries. A line may
//! carry a per-query override, `"set"` (see [`parse_query_line_set`] and
//! docs/materials.md, "Per-query overrides (`set`)").

use crate::api::{Direction, QueryError};
use crate::stack::{tables_only, LayerStack, SetError, SetPath};
use serde::de::{self, MapAccess, SeqAccess, Visitor};
use serde::{Deserialize, Deserializer};
use serde_json::Value;
use std::fmt;

#[derive(Deserialize)]
#[serde(remote = "Self", deny_unknown_fields)]
struct Line {
    wi: [f64; 3],
    wo: [f64; 3],
}

/// A query line that cannot be used.
#[derive(Clone, Debug, PartialEq)]
pub enum QueryParseError {
    /// Not a JSON object with exactly `wi` and `wo`, three numbers each.
    Malformed(String),
    /// A direction is NaN, infinite or zero.
    Direction(QueryError),
    /// The `"set"` of the line is not an object of paths to numbers or
    /// arrays of numbers.
    Set(SetError),
}

impl fmt::Display for QueryParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            QueryParseError::Malformed(m) => write!(
                f,
                "invalid query (expected {{\"wi\":[x,y,z],\"wo\":[x,y,z]}}): {m}"
            ),
            QueryParseError::Direction(e) => write!(f, "{e}"),
            QueryParseError::Set(e) => write!(f, "invalid query: {e}"),
        }
    }
}

impl std::error::Error for QueryParseError {}

/// Parses one query line into two unit directions `(wi, wo)`.
///
/// ```
/// let (wi, wo) = strata_bsdf::query::parse_query_line(r#"{"wi":[0,0,2],"wo":[1,0,1]}"#).unwrap();
/// assert_eq!(wi.get(), [0.0, 0.0, 1.0]);
/// assert!((wo.get()[0] - 0.5f64.sqrt()).abs() < 1e-12);
/// assert!(strata_bsdf::query::parse_query_line(r#"{"wi":[0,0,0],"wo":[1,0,1]}"#).is_err());
/// ```
pub fn parse_query_line(line: &str) -> Result<(Direction, Direction), QueryParseError> {
    let (wi, wo) = parse_query_vectors(line)?;
    let dir = |name, v| Direction::new(name, v).map_err(QueryParseError::Direction);
    Ok((dir("wi", wi)?, dir("wo", wo)?))
}

/// Parses one query line into the two vectors as the API takes them:
/// `f32`, checked to be directions but not normalized, so that a direction
/// printed by `strata sample` is passed on bit for bit (and so gets the pdf
/// the sample carried). Vectors beyond `f32`'s range are normalized from
/// their `f64` values first.
pub fn parse_query_vectors(line: &str) -> Result<(glam::Vec3, glam::Vec3), QueryParseError> {
    let q: Line =
        serde_json::from_str(line).map_err(|e| QueryParseError::Malformed(e.to_string()))?;
    Ok((vector("wi", q.wi)?, vector("wo", q.wo)?))
}

/// A direction as the API takes it (see [`parse_query_vectors`]).
fn vector(name: &'static str, v: [f64; 3]) -> Result<glam::Vec3, QueryParseError> {
    let f = v.map(|x| x as f32);
    let fits = v
        .iter()
        .zip(&f)
        .all(|(x, y)| y.is_finite() && (*x == 0.0 || *y != 0.0));
    let checked = if fits {
        Direction::new(name, glam::Vec3::from(f)).map(|_| glam::Vec3::from(f))
    } else {
        Direction::from_f64(name, v).map(Direction::to_vec3)
    };
    checked.map_err(QueryParseError::Direction)
}

/// The per-query override of a query line: parameters of the material, each
/// a path and a value, applied to that query alone (an empty set is the
/// material as it is).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct QuerySet {
    entries: Vec<(SetPath, Value)>,
}

impl QuerySet {
    /// Reads the value of a line's `"set"`: an object from paths to numbers
    /// or arrays of numbers. Each path is parsed; whether it exists in the
    /// material, and whether the value is valid for it, is checked by
    /// [`QuerySet::apply`].
    ///
    /// A [`Value`] holds one value per key, so a path given twice in the text
    /// it was parsed from is gone by now: [`parse_set`] reads text and
    /// refuses it.
    pub fn from_json(set: &Value) -> Result<QuerySet, SetError> {
        match set {
            Value::Object(map) => Self::from_entries(map.iter().map(|(k, v)| (k.as_str(), v))),
            _ => Err(not_an_object(set)),
        }
    }

    /// The set of `entries` (path, value), in order; a path given twice is
    /// an error naming it.
    fn from_entries<'a>(
        entries: impl ExactSizeIterator<Item = (&'a str, &'a Value)>,
    ) -> Result<QuerySet, SetError> {
        let map = entries;
        let mut entries = Vec::with_capacity(map.len());
        for (path, value) in map {
            let p = SetPath::parse(path)?;
            let ok = match value {
                Value::Number(_) => true,
                Value::Array(a) => a.iter().all(Value::is_number),
                _ => false,
            };
            if !ok {
                return Err(SetError::Value {
                    path: p.to_string(),
                    value: value.to_string(),
                    problem: "expected a number or an array of numbers".into(),
                });
            }
            if entries.iter().any(|(q, _)| *q == p) {
                return Err(SetError::Duplicate {
                    path: p.to_string(),
                });
            }
            entries.push((p, value.clone()));
        }
        Ok(QuerySet { entries })
    }

    /// The entries, paths with their values.
    pub fn entries(&self) -> &[(SetPath, Value)] {
        &self.entries
    }

    /// No override.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// The stack with the override applied ([`LayerStack::with_set`]).
    pub fn apply(&self, stack: &LayerStack) -> Result<LayerStack, SetError> {
        stack.with_set(&self.entries)
    }
}

/// The error for a `"set"` that is not an object.
fn not_an_object(set: &Value) -> SetError {
    SetError::Path {
        path: "set".into(),
        problem: format!(
            "expected an object from paths to values, e.g. \
             {{\"layers[0].medium.thickness\":0.5}}, not {set}"
        ),
    }
}

#[derive(Deserialize)]
#[serde(remote = "Self", deny_unknown_fields)]
struct SetLine {
    wi: [f64; 3],
    wo: [f64; 3],
    #[serde(default)]
    set: Option<RawSet>,
}

#[derive(Deserialize)]
#[serde(remote = "Self", deny_unknown_fields)]
struct SampleLine {
    wi: [f64; 3],
    #[serde(default)]
    set: Option<RawSet>,
}

tables_only! {
    Line: "an object {\"wi\":[x,y,z],\"wo\":[x,y,z]}",
    SetLine: "an object {\"wi\":[x,y,z],\"wo\":[x,y,z]} with an optional \"set\"",
    SampleLine: "an object {\"wi\":[x,y,z]} with an optional \"set\"",
}

/// A `"set"` as written: an object's entries in order, a path given twice
/// kept twice (a JSON map keeps the last, which would hide it), or a value
/// that is not an object, kept for the error.
enum RawSet {
    Entries(Vec<(String, Value)>),
    Other(Value),
}

impl<'de> Deserialize<'de> for RawSet {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_any(RawSetVisitor)
    }
}

struct RawSetVisitor;

impl<'de> Visitor<'de> for RawSetVisitor {
    type Value = RawSet;
    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("an object from paths to values")
    }
    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<RawSet, A::Error> {
        let mut entries = Vec::with_capacity(map.size_hint().unwrap_or(0).min(64));
        while let Some(entry) = map.next_entry::<String, Value>()? {
            entries.push(entry);
        }
        Ok(RawSet::Entries(entries))
    }
    fn visit_seq<A: SeqAccess<'de>>(self, seq: A) -> Result<RawSet, A::Error> {
        let d = de::value::SeqAccessDeserializer::new(seq);
        Value::deserialize(d).map(RawSet::Other)
    }
    fn visit_unit<E: de::Error>(self) -> Result<RawSet, E> {
        Ok(RawSet::Other(Value::Null))
    }
    fn visit_bool<E: de::Error>(self, v: bool) -> Result<RawSet, E> {
        Ok(RawSet::Other(Value::Bool(v)))
    }
    fn visit_i64<E: de::Error>(self, v: i64) -> Result<RawSet, E> {
        Ok(RawSet::Other(v.into()))
    }
    fn visit_u64<E: de::Error>(self, v: u64) -> Result<RawSet, E> {
        Ok(RawSet::Other(v.into()))
    }
    fn visit_f64<E: de::Error>(self, v: f64) -> Result<RawSet, E> {
        Ok(RawSet::Other(v.into()))
    }
    fn visit_str<E: de::Error>(self, v: &str) -> Result<RawSet, E> {
        Ok(RawSet::Other(Value::String(v.into())))
    }
}

fn query_set(set: Option<RawSet>) -> Result<QuerySet, QueryParseError> {
    let set = match set {
        None => Ok(QuerySet::default()),
        Some(RawSet::Entries(e)) => QuerySet::from_entries(e.iter().map(|(k, v)| (k.as_str(), v))),
        Some(RawSet::Other(v)) => Err(not_an_object(&v)),
    };
    set.map_err(QueryParseError::Set)
}

/// Parses the text of a set, as `strata sample --set` takes it:
/// `{"layers[0].medium.thickness":0.5}`, into a [`QuerySet`]. A path given
/// twice is an error naming it, as in a query line (`null` is no override).
///
/// ```
/// use strata_bsdf::query::parse_set;
/// assert_eq!(parse_set(r#"{"exterior_ior":1.2}"#).unwrap().entries().len(), 1);
/// let e = parse_set(r#"{"exterior_ior":1.2,"exterior_ior":1.3}"#).unwrap_err();
/// assert_eq!(e.to_string(), "invalid query: set `exterior_ior`: given twice");
/// ```
pub fn parse_set(text: &str) -> Result<QuerySet, QueryParseError> {
    let set: Option<RawSet> =
        serde_json::from_str(text).map_err(|e| QueryParseError::Malformed(e.to_string()))?;
    query_set(set)
}

/// Parses a query line that may carry a `"set"`:
/// `{"wi":[x,y,z],"wo":[x,y,z],"set":{"layers[0].medium.thickness":0.5}}`,
/// into the vectors of [`parse_query_vectors`] (the same for a line without
/// `"set"`) and the set (empty without one).
///
/// ```
/// use strata_bsdf::query::parse_query_line_set;
/// let (wi, wo, set) = parse_query_line_set(
///     r#"{"wi":[0,0,1],"wo":[0,0,1],"set":{"layers[0].interface.roughness":[0.1,0.2]}}"#,
/// ).unwrap();
/// assert_eq!(set.entries()[0].0.to_string(), "layers[0].interface.roughness");
/// assert!(parse_query_line_set(r#"{"wi":[0,0,1],"wo":[0,0,1],"set":3}"#).is_err());
/// ```
pub fn parse_query_line_set(
    line: &str,
) -> Result<(glam::Vec3, glam::Vec3, QuerySet), QueryParseError> {
    let q: SetLine =
        serde_json::from_str(line).map_err(|e| QueryParseError::Malformed(e.to_string()))?;
    let wi = vector("wi", q.wi)?;
    let wo = vector("wo", q.wo)?;
    Ok((wi, wo, query_set(q.set)?))
}

/// Parses an incident-direction line, as a sampling query is written:
/// `{"wi":[x,y,z]}` with an optional `"set"`, into the vector (checked, not
/// normalized, as in [`parse_query_vectors`]) and the set.
///
/// ```
/// use strata_bsdf::query::parse_sample_line;
/// let (wi, set) = parse_sample_line(r#"{"wi":[0,0,2]}"#).unwrap();
/// assert_eq!((wi.z, set.is_empty()), (2.0, true));
/// ```
pub fn parse_sample_line(line: &str) -> Result<(glam::Vec3, QuerySet), QueryParseError> {
    let q: SampleLine =
        serde_json::from_str(line).map_err(|e| QueryParseError::Malformed(e.to_string()))?;
    Ok((vector("wi", q.wi)?, query_set(q.set)?))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A query line written as a positional array is malformed, not read
    /// as its fields in order.
    #[test]
    fn positional_lines_are_refused() {
        let e = parse_query_line("[[0,0,1],[0,0,1]]").unwrap_err();
        assert!(e.to_string().contains("invalid type: sequence"), "{e}");
        let e = parse_query_vectors("[[0,0,1],[0,0,1]]").unwrap_err();
        assert!(matches!(e, QueryParseError::Malformed(_)), "{e}");
        let e = parse_query_line_set("[[0,0,1],[0,0,1],null]").unwrap_err();
        assert!(e.to_string().contains("invalid type: sequence"), "{e}");
        let e = parse_sample_line("[[0,0,1]]").unwrap_err();
        assert!(e.to_string().contains("invalid type: sequence"), "{e}");
        // Objects still read.
        assert!(parse_query_line_set(r#"{"wi":[0,0,1],"wo":[0,0,1]}"#).is_ok());
        assert!(parse_sample_line(r#"{"wi":[0,0,1],"set":null}"#).is_ok());
    }

    /// The same path twice in a line's set is an error naming it (a JSON
    /// map kept the last value).
    #[test]
    fn a_path_given_twice_is_an_error() {
        let line = r#"{"wi":[0,0,1],"wo":[0,0,1],"set":{"exterior_ior":1.2,"layers[0].interface.ior":1.4,"exterior_ior":1.3}}"#;
        let e = parse_query_line_set(line).unwrap_err();
        assert_eq!(
            e,
            QueryParseError::Set(SetError::Duplicate {
                path: "exterior_ior".into()
            })
        );
        assert_eq!(
            e.to_string(),
            "invalid query: set `exterior_ior`: given twice"
        );
        let e = parse_sample_line(r#"{"wi":[0,0,1],"set":{"exterior_ior":1,"exterior_ior":1}}"#);
        assert!(matches!(
            e,
            Err(QueryParseError::Set(SetError::Duplicate { .. }))
        ));
        let e = parse_set(r#"{"layers[0].medium.thickness":1,"layers[0].medium.thickness":2}"#);
        assert!(matches!(
            e,
            Err(QueryParseError::Set(SetError::Duplicate { .. }))
        ));
        // Distinct paths, in order; a set that is not an object says so.
        let (_, _, set) = parse_query_line_set(
            r#"{"wi":[0,0,1],"wo":[0,0,1],"set":{"exterior_ior":1.2,"layers[0].interface.ior":1.4}}"#,
        )
        .unwrap();
        let paths: Vec<String> = set.entries().iter().map(|(p, _)| p.to_string()).collect();
        assert_eq!(paths, ["exterior_ior", "layers[0].interface.ior"]);
        for bad in ["3", "[1]", "\"x\"", "true"] {
            let line = format!(r#"{{"wi":[0,0,1],"wo":[0,0,1],"set":{bad}}}"#);
            let e = parse_query_line_set(&line).unwrap_err().to_string();
            assert!(e.contains("expected an object from paths to values"), "{e}");
            assert!(e.ends_with(&format!("not {bad}")), "{e}");
        }
    }
}
