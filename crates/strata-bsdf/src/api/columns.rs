//! Per-query parameters as columns: the form a renderer's textures take.
//!
//! A renderer that looks up a thickness map and an absorption map at every
//! hit has, per parameter, one array with a value (or an RGB triple) per
//! query. [`Materials::per_query`] turns such columns into one material per
//! query: the BSDF's stack with row `k` of every column set through
//! [`LayerStack::with_set`], so query `k` answers bit for bit what a material
//! file with those values answers (each float as the number it sets: see
//! [`Column`]). This is the one implementation behind the
//! C ABI's and the Python module's per-query arrays.

use super::{LayeredBsdf, Materials};
use crate::stack::{LayerStack, SetError, SetPath};
use serde_json::Value;
use std::collections::HashMap;
use std::fmt;

/// One parameter's values, `width` floats per query (1 for a number, 3 for
/// an RGB triple or a normal), query after query. A value sets the number
/// of its shortest correctly rounded decimal: `0.1f32` is a material file's
/// 0.1 (the first of C's `%.1g` … `%.9g` that reads back as the float).
#[derive(Clone, Copy, Debug)]
pub struct Column<'a> {
    /// The parameter, e.g. `layers[0].medium.thickness`.
    pub path: &'a SetPath,
    /// Floats per query: 1, or 3 for the fields that take triples.
    pub width: usize,
    /// `width × queries` values.
    pub values: &'a [f32],
}

/// Columns that cannot make the queries' materials.
#[derive(Clone, Debug, PartialEq)]
pub enum ColumnsError {
    /// A column whose width is not 1 or 3, or whose length is not `width ×
    /// queries`.
    Length {
        /// The column's path.
        path: String,
        /// Its width.
        width: usize,
        /// Its number of values.
        len: usize,
        /// The number of queries.
        queries: usize,
    },
    /// Query `query`'s values do not make a valid material (the error names
    /// the path, the value and, for an invalid material, the layer and field).
    Query {
        /// The query's index.
        query: usize,
        /// What is wrong.
        error: SetError,
    },
    /// Column `column` cannot be set on this material, whatever its values:
    /// a path the material does not have, a path given twice, or a width its
    /// field does not take. Found before any row is read, so an empty batch
    /// finds it too.
    Column {
        /// The column's index.
        column: usize,
        /// What is wrong.
        error: SetError,
    },
    /// More queries than materials can be numbered ([`MAX_QUERIES`]).
    TooManyQueries {
        /// The number of queries.
        queries: usize,
    },
}

/// The most queries [`Materials::per_query`] takes: their materials are
/// numbered by `u32`.
pub const MAX_QUERIES: usize = u32::MAX as usize;

impl fmt::Display for ColumnsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ColumnsError::Length {
                path,
                width,
                len,
                queries,
            } if *width == 1 || *width == 3 => write!(
                f,
                "`{path}`: {len} values for {queries} queries of width {width} \
                 (expected {})",
                width * queries
            ),
            ColumnsError::Length { path, width, .. } => write!(
                f,
                "`{path}`: width {width}; a column has 1 value per query, or 3 (an RGB triple, a normal)"
            ),
            ColumnsError::Query { query, error } => write!(f, "query {query}: {error}"),
            ColumnsError::Column { column, error } => write!(f, "column {column}: {error}"),
            ColumnsError::TooManyQueries { queries } => {
                write!(f, "{queries} queries: at most {MAX_QUERIES}")
            }
        }
    }
}

impl std::error::Error for ColumnsError {}

impl Materials {
    /// One material per query, `queries` of them: `template`'s stack with
    /// row `k` of every column as query `k`'s values, answered with
    /// `template`'s configuration (see [`Materials::new`]). Query `k` of a
    /// batch call then passes material `k` (see [`Materials::identity`]).
    ///
    /// Queries whose rows are equal share one material (a texture's texels
    /// repeat). Under [`crate::Estimator::Auto`], a rough coat over a
    /// Lambertian base is answered without walks through a constant of its
    /// coat and layer (an integral of 2–15 ms, `estimator::coat_return`):
    /// queries whose coat or layer differ from `template`'s would each need
    /// their own, so they are answered by the walks (which agree in
    /// expectation, not bit for bit, with what their material file
    /// answers); columns of the base's albedo keep it.
    /// A column that cannot be set on this material whatever its values (a
    /// path it does not have, a path twice, a width its field refuses) is
    /// [`ColumnsError::Column`], found before any row, in an empty batch too.
    /// Every row is checked before anything runs: the first query whose
    /// values are invalid is an error naming it, and no material is built
    /// (a renderer clamps its textures, or drops the query and retries the
    /// rest; nothing is answered silently for it).
    ///
    /// ```
    /// use strata_bsdf::{Column, LayerStack, LayeredBsdf, Materials};
    /// let bsdf = LayeredBsdf::new(LayerStack::from_toml_str(
    ///     "[[layers]]\ninterface = { kind = \"dielectric\", ior = 1.5 }\n\
    ///      medium = { thickness = 1, sigma_t = 0.5 }\n\
    ///      [[layers]]\ninterface = { kind = \"diffuse\", albedo = 0.8 }\n",
    /// ).unwrap());
    /// let path = "layers[0].medium.thickness".parse().unwrap();
    /// let thickness = [0.1, 0.5, 2.0];
    /// let m = Materials::per_query(&bsdf, 3, &[Column { path: &path, width: 1, values: &thickness }]).unwrap();
    /// assert_eq!(m.len(), 3);
    /// let bad = [0.1, -1.0, 2.0];
    /// let e = Materials::per_query(&bsdf, 3, &[Column { path: &path, width: 1, values: &bad }]).unwrap_err();
    /// assert!(e.to_string().starts_with("query 1: "), "{e}");
    /// ```
    pub fn per_query(
        template: &LayeredBsdf,
        queries: usize,
        columns: &[Column],
    ) -> Result<Materials, ColumnsError> {
        if queries > MAX_QUERIES {
            return Err(ColumnsError::TooManyQueries { queries });
        }
        for c in columns {
            let fits = c.width.checked_mul(queries) == Some(c.values.len());
            if !(c.width == 1 || c.width == 3) || !fits {
                return Err(ColumnsError::Length {
                    path: c.path.to_string(),
                    width: c.width,
                    len: c.values.len(),
                    queries,
                });
            }
        }
        check_columns(template.stack(), columns)?;
        // Equal rows (bit for bit: a texture's texels repeat) share one
        // material, built once.
        let mut first: HashMap<Vec<u32>, u32> = HashMap::new();
        let (mut stacks, mut of) = (Vec::new(), Vec::with_capacity(queries));
        for k in 0..queries {
            let row: Vec<u32> = (columns.iter())
                .flat_map(|c| c.values[k * c.width..(k + 1) * c.width].iter())
                .map(|x| x.to_bits())
                .collect();
            let u = match first.get(&row) {
                Some(&u) => u,
                None => {
                    stacks.push(query_stack(template.stack(), columns, k)?);
                    let u = stacks.len() as u32 - 1;
                    first.insert(row, u);
                    u
                }
            };
            of.push(u);
        }
        Ok(Materials::building(template, stacks, true).repeated(&of))
    }

    /// `0, 1, …, n − 1`: the material indices of a batch whose query `k`
    /// runs on material `k` (as [`Materials::per_query`] builds them; at
    /// most [`MAX_QUERIES`] of them, the rest left out).
    pub fn identity(n: usize) -> Vec<u32> {
        (0..n.min(MAX_QUERIES) as u32).collect()
    }
}

/// Checks every column against `base` before any row: its path is in the
/// material, it is given once, and its field takes its width. A probe of
/// that width (the first row, 1 for a number that is not finite, or ones in
/// an empty batch: the message then shows the caller's values) is set on a
/// copy of the material's description, which runs the field's parser; the
/// material is not validated (that is each row's check).
fn check_columns(base: &LayerStack, columns: &[Column]) -> Result<(), ColumnsError> {
    let mut desc = base.desc().clone();
    for (i, c) in columns.iter().enumerate() {
        let at = |error| ColumnsError::Column { column: i, error };
        if columns[..i].iter().any(|d| d.path == c.path) {
            let path = c.path.to_string();
            return Err(at(SetError::Duplicate { path }));
        }
        let first = (0..c.width).map(|j| c.values.get(j).copied().unwrap_or(1.0));
        let probe: Vec<f64> = first
            .map(|x| if x.is_finite() { decimal(x) } else { 1.0 })
            .collect();
        let probe = match probe[..] {
            [x] => Value::from(x),
            _ => Value::from(probe),
        };
        desc.apply_set(c.path, &probe).map_err(at)?;
    }
    Ok(())
}

/// The number a column's `x` sets: the first of its correctly rounded
/// decimals of 1 to 9 significant digits (ties to even, as C's `%.*g` and
/// Python's `'%.*g'` round) that reads back as `x`. A column's 0.1 is then
/// the 0.1 of a material file; widening the float would give
/// 0.10000000149011612, a material whose answers differ in the last bits
/// and whose errors name a value the caller never wrote. The rule is
/// spelled out (Rust's `Display` of an `f32` breaks exact ties upwards,
/// numpy's `str` takes the shortest digits even where they are not the
/// correctly rounded ones) so that C and Python can print the same text.
fn decimal(x: f32) -> f64 {
    let wide = f64::from(x);
    let digits = |p: usize| format!("{:.*e}", p - 1, wide);
    // Nine digits always read back (any f32), and what `format!` writes
    // always parses: the widened value is never reached.
    (1..=9)
        .map(digits)
        .find(|s| s.parse::<f32>() == Ok(x))
        .and_then(|s| s.parse().ok())
        .unwrap_or(wide)
}

/// `base` with query `k`'s row of every column.
fn query_stack(
    base: &LayerStack,
    columns: &[Column],
    k: usize,
) -> Result<LayerStack, ColumnsError> {
    let mut set: Vec<(SetPath, Value)> = Vec::with_capacity(columns.len());
    for c in columns {
        let row = &c.values[k * c.width..(k + 1) * c.width];
        if let Some(x) = row.iter().find(|x| !x.is_finite()) {
            // JSON has no NaN: said here, before it would become `null`.
            let error = SetError::Value {
                path: c.path.to_string(),
                value: x.to_string(),
                problem: "not a finite number".into(),
            };
            return Err(ColumnsError::Query { query: k, error });
        }
        let value = match row {
            [x] => Value::from(decimal(*x)),
            _ => Value::from(row.iter().map(|&x| decimal(x)).collect::<Vec<_>>()),
        };
        set.push((c.path.clone(), value));
    }
    base.with_set(&set)
        .map_err(|error| ColumnsError::Query { query: k, error })
}
