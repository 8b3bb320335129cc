//! Parsing of query lines: `{"wi":[x,y,z],"wo":[x,y,z]}` (JSON, one per line),
//! as read by `strata eval` and by renderers that stream queries. A line may
//! carry a per-query override, `"set"` (see [`parse_query_line_set`] and
//! docs/materials.md, "Per-query overrides (`set`)").

use crate::api::{Direction, QueryError};
use crate::stack::{LayerStack, SetError, SetPath};
use serde::Deserialize;
use serde_json::Value;
use std::fmt;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
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
    pub fn from_json(set: &Value) -> Result<QuerySet, SetError> {
        let Value::Object(map) = set else {
            return Err(SetError::Path {
                path: "set".into(),
                problem: format!(
                    "expected an object from paths to values, e.g. \
                     {{\"layers[0].medium.thickness\":0.5}}, not {set}"
                ),
            });
        };
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

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SetLine {
    wi: [f64; 3],
    wo: [f64; 3],
    #[serde(default)]
    set: Option<Value>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SampleLine {
    wi: [f64; 3],
    #[serde(default)]
    set: Option<Value>,
}

fn query_set(set: Option<Value>) -> Result<QuerySet, QueryParseError> {
    match set {
        None => Ok(QuerySet::default()),
        Some(v) => QuerySet::from_json(&v).map_err(QueryParseError::Set),
    }
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
