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
    let q: Line =
        serde_json::from_str(line).map_err(|e| QueryParseError::Malformed(e.to_string()))?;
    let dir = |name: &'static str, v: [f64; 3]| {
        Direction::from_f64(name, v).map_err(QueryParseError::Direction)
    };
    Ok((dir("wi", q.wi)?, dir("wo", q.wo)?))
}
