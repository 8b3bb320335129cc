//! Parsing of query lines: `{"wi":[x,y,z],"wo":[x,y,z]}` (JSON, one per line),
//! as read by `strata eval` and by renderers that stream queries.

use crate::api::{Direction, QueryError};
use serde::Deserialize;
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
}

impl fmt::Display for QueryParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            QueryParseError::Malformed(m) => write!(
                f,
                "invalid query (expected {{\"wi\":[x,y,z],\"wo\":[x,y,z]}}): {m}"
            ),
            QueryParseError::Direction(e) => write!(f, "{e}"),
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
    let vector = |name: &'static str, v: [f64; 3]| {
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
    };
    Ok((vector("wi", q.wi)?, vector("wo", q.wo)?))
}
