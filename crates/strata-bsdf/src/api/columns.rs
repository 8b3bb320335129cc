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

use super::bsdf::LayeredBsdf;
use super::error::{BatchError, QueryError};
use super::materials::Materials;
use super::param_sets::{ParamSets, Per, Returns};
use crate::stack::{LayerStack, SetError, SetPath};
use serde_json::Value;
use std::collections::HashMap;
use std::fmt;
use std::ops::Range;

/// One parameter's values, `width` floats per query (1 for a number, 3 for
/// an RGB triple or a normal), query after query. Where [`PerQuery`] writes
/// its rows in place ([`PerQuery::rows_in_place`]) a value enters as the
/// float it is (`0.1f32` is a material file's 0.100000001490116); where its
/// rows are materials, and in [`Materials::per_query`], it sets the number
/// of its shortest correctly rounded decimal (`0.1f32` is a file's 0.1: the
/// first of C's `%.1g` … `%.9g` that reads back as the float).
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
    /// [`Materials::per_query`] would hold the materials of more than
    /// [`MAX_MATERIAL_LAYERS`] layers: its batch runs through [`PerQuery`].
    TooManyRows {
        /// The distinct rows found so far (one more than fit).
        rows: usize,
        /// The stack's layers.
        layers: usize,
    },
    /// The working memory of the rows could not be allocated.
    OutOfMemory {
        /// The bytes asked for.
        bytes: usize,
    },
}

/// The most queries [`Materials::per_query`] takes: their materials are
/// numbered by `u32`.
pub const MAX_QUERIES: usize = u32::MAX as usize;

/// The most layers' worth of materials [`Materials::per_query`] holds at
/// once (distinct rows times the stack's layers), which bounds its memory:
/// the bound of one [`PerQuery`] chunk ([`CHUNK_LAYERS`]).
pub const MAX_MATERIAL_LAYERS: usize = CHUNK_LAYERS;

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
            ColumnsError::TooManyRows { rows, layers } => write!(
                f,
                "{rows} distinct rows of {layers} layers: Materials::per_query holds at most \
                 {MAX_MATERIAL_LAYERS} layers' worth of materials; PerQuery answers any number \
                 in bounded chunks"
            ),
            ColumnsError::OutOfMemory { bytes } => write!(
                f,
                "out of memory: cannot allocate {bytes} bytes of per-query working memory"
            ),
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
    /// coat and layer (an integral, `estimator::coat_return`, far costlier
    /// than an eval):
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
    /// Memory: the materials of all distinct rows are held at once, a few
    /// KB each on a two-layer stack and about 1.7 KB per layer on a deep
    /// one, so at most [`MAX_MATERIAL_LAYERS`] layers' worth of them: more
    /// distinct rows are [`ColumnsError::TooManyRows`]. Such a batch runs
    /// through [`PerQuery`], which builds them a bounded chunk at a time and
    /// answers the same numbers. The per-query index (4 bytes a query) is
    /// allocated fallibly ([`ColumnsError::OutOfMemory`]).
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
        check_lengths(template, queries, columns)?;
        // Equal rows (bit for bit: a texture's texels repeat) share one
        // material, built once.
        let mut first: HashMap<Vec<u32>, u32> = HashMap::new();
        let (mut stacks, mut of) = (Vec::new(), Vec::new());
        reserve(&mut of, queries).map_err(|bytes| ColumnsError::OutOfMemory { bytes })?;
        for k in 0..queries {
            let row: Vec<u32> = (columns.iter())
                .flat_map(|c| c.values[k * c.width..(k + 1) * c.width].iter())
                .map(|x| x.to_bits())
                .collect();
            let u = match first.get(&row) {
                Some(&u) => u,
                None => {
                    let layers = template.stack().len().max(1);
                    if (stacks.len() + 1) * layers > MAX_MATERIAL_LAYERS {
                        let rows = stacks.len() + 1;
                        return Err(ColumnsError::TooManyRows { rows, layers });
                    }
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

/// The most distinct rows a chunk of a [`PerQuery`] batch holds the
/// materials of at once (fewer on a deep stack: see [`CHUNK_LAYERS`]).
pub const CHUNK_ROWS: usize = 4096;

/// The most layers' worth of materials a chunk of a [`PerQuery`] batch
/// holds at once: a stack of `L` layers has at most `max(1, CHUNK_LAYERS /
/// L)` distinct rows a chunk (and at most [`CHUNK_ROWS`]).
pub const CHUNK_LAYERS: usize = 1 << 16;

/// The most queries a chunk of a [`PerQuery`] batch holds (its directions,
/// keys and answers are copied per chunk).
pub const CHUNK_QUERIES: usize = 1 << 16;

/// Per-query columns answered a chunk at a time, with memory bounded by
/// the chunk, not by the batch's rows.
///
/// Where every column is a field a built stack takes in place
/// ([`SetPath::in_place`]: thicknesses, extinctions, albedos, roughnesses,
/// a conductor's `eta` and `k`, a dielectric's IOR) and the rows run on one shape (the same, or
/// a grey extinction where the shape's is chromatic), the rows are
/// a table of the template's numbers: each row is written into a copy of
/// the template's stack and checked as a material file's fields are, its
/// numbers go to the lanes, and what its stack decides (a walk-free form and
/// its constants, the control variate, the estimator) is decided once, with
/// no material built; a query answers bit for bit what a material file with
/// its floats answers, or over a Lambertian base to within its `R̄`, which a
/// row takes from the coat's table (`estimator::coat_return`, within 1e-6)
/// where a material integrates it, or, for a grey extinction on a
/// chromatic shape, with its file's expectation, not its bits; a row
/// with its own IOR walks a coat over a Lambertian base, whose `R̄` is
/// tabulated per IOR (`tests/api/rows_in_place.rs`). Build it once for the
/// calls of a batch of vertices (sample, then eval and pdf of the light
/// samples): it holds the table of a batch of one chunk. Other columns make
/// a material per distinct row, as described below.
///
/// [`Materials::per_query`] holds one material per distinct row; a
/// renderer's textures can make every row of a million-query batch
/// distinct, and a material is a few KB on a two-layer stack, 1.7 MB on a
/// 1000-layer one. `PerQuery` cuts the batch into contiguous chunks of at
/// most [`CHUNK_QUERIES`] queries and `R = min(CHUNK_ROWS, max(1,
/// CHUNK_LAYERS / L))` distinct rows (`L` the stack's layers), builds only
/// the chunk's materials, answers its queries (in parallel, as any batch),
/// drops them and goes on. Its working memory is therefore at most
///
/// `R × (one material of the stack) + CHUNK_QUERIES × (a few hundred bytes:
/// a query's directions, keys, index and answer)`
///
/// plus the caller's inputs and outputs, whatever the batch's size: about
/// 20 MB on a two-layer stack, 110 MB on a 1000-layer one. A query's
/// answer is keyed by the query alone (its key, its row), so the chunks
/// change no number: every call answers bit for bit what
/// [`Materials::per_query`] and the [`Materials`] call of the same name
/// answer (`tests/api/per_query_chunks.rs`). Equal rows share one material
/// within a chunk.
///
/// Every row is checked by [`PerQuery::new`], and every argument by each
/// call, before anything runs or is written. The working memory of each
/// call is allocated fallibly when it starts: a refusal is
/// [`ColumnsError::OutOfMemory`] or [`QueryError::OutOfMemory`] naming the
/// call and the bytes, not an abort. (The numbers inside one material are
/// allocated as any Rust value; the chunk bounds how many exist at once.)
///
/// ```
/// use strata_bsdf::{Bsdf, Column, LayerStack, LayeredBsdf, PerQuery, Queries};
/// let bsdf = LayeredBsdf::new(LayerStack::from_toml_str(
///     "[[layers]]\ninterface = { kind = \"dielectric\", ior = 1.5 }\n\
///      medium = { thickness = 1, sigma_t = 0.5 }\n\
///      [[layers]]\ninterface = { kind = \"diffuse\", albedo = 0.8 }\n",
/// ).unwrap());
/// let path = "layers[0].medium.thickness".parse().unwrap();
/// let thickness = [0.1, 0.5, 2.0];
/// let q = PerQuery::new(&bsdf, 3, &[Column { path: &path, width: 1, values: &thickness }]).unwrap();
/// let wi = [[0.0, 0.0, 1.0]; 3];
/// let mut f = [0.0; 3];
/// q.eval_into(&Queries::pairs(&wi[..], &wi[..]), &mut |k, e| f[k] = e.value[0]).unwrap();
/// assert!(f.iter().all(|&v| v > 0.0));
/// ```
#[derive(Clone, Debug)]
pub struct PerQuery<'a> {
    pub(super) template: &'a LayeredBsdf,
    pub(super) queries: usize,
    columns: Vec<Column<'a>>,
    /// The most distinct rows a chunk holds.
    rows: usize,
    /// A batch of one chunk: its materials and each query's among them,
    /// built once by the check in [`PerQuery::new`] and used by every call.
    one_chunk: Option<(Materials, Vec<u32>)>,
    /// Every column is written into the template's stack in place and no
    /// row changes its shape: the rows are parameter sets of the template
    /// (see [`InPlace`]), not materials.
    in_place: Option<InPlace>,
}

/// The rows of a [`PerQuery`] batch as parameter sets of its template: each
/// query's values written into a copy of the template's built stack
/// ([`LayerStack::write`], checked as a material file's fields are), its
/// numbers put in the lanes and every choice its stack makes (walk-free
/// form, control variate, estimator) taken, with no material built. A
/// chunk holds one set per query.
#[derive(Clone, Debug)]
struct InPlace {
    /// The BSDF of the rows' shape, where it is not the template's (a
    /// grey extinction given per query as RGB): the template's
    /// configuration over the first row.
    shape: Option<Box<LayeredBsdf>>,
    /// `0, 1, …`: query `k` of a chunk has set `k`.
    identity: Vec<u32>,
    /// A batch of one chunk: its sets, built by [`PerQuery::new`]...
    sets: Option<ParamSets>,
    /// ...from this.
    key: Key,
}

impl Drop for InPlace {
    fn drop(&mut self) {
        if let Some(sets) = self.sets.take() {
            let key = std::mem::take(&mut self.key);
            keep_spare(Spare {
                key,
                sets,
                shape: self.shape.take(),
            });
        }
    }
}

/// What a table of rows was built from: the template's stack and the
/// columns (paths, widths and values, as bits). Equal keys build equal
/// tables, so the sample, eval and pdf calls of one batch of vertices, each
/// given the same columns (a C or Python caller's), build one table.
#[derive(Clone, Debug, Default)]
struct Key {
    stack: Option<LayerStack>,
    columns: Vec<(SetPath, usize)>,
    bits: Vec<u32>,
}

impl Key {
    /// Whether it is the key of `template`'s stack with `columns`.
    fn is(&self, template: &LayeredBsdf, columns: &[Column]) -> bool {
        let mut at = 0;
        self.stack.as_ref() == Some(template.stack())
            && self.columns.len() == columns.len()
            && (self.columns.iter().zip(columns)).all(|((p, w), c)| p == c.path && *w == c.width)
            && columns.iter().all(|c| {
                let n = c.values.len();
                let same = self
                    .bits
                    .get(at..at + n)
                    .is_some_and(|b| b.iter().zip(c.values).all(|(&b, x)| b == x.to_bits()));
                at += n;
                same
            })
            && at == self.bits.len()
    }

    /// Makes it the key of `template`'s stack with `columns`, reusing its
    /// memory.
    fn set(&mut self, template: &LayeredBsdf, columns: &[Column]) {
        if self.stack.as_ref() != Some(template.stack()) {
            self.stack = Some(template.stack().clone());
        }
        self.columns.clear();
        self.columns
            .extend(columns.iter().map(|c| (c.path.clone(), c.width)));
        self.bits.clear();
        for c in columns {
            self.bits.extend(c.values.iter().map(|x| x.to_bits()));
        }
    }
}

/// A table of rows kept for the thread's next one.
struct Spare {
    /// What it was built from.
    key: Key,
    sets: ParamSets,
    /// The BSDF of the rows' shape, where it was not the template's.
    shape: Option<Box<LayeredBsdf>>,
}

impl Spare {
    /// A table's memory, with nothing it was built from.
    fn memory(sets: ParamSets) -> Self {
        Spare {
            key: Key::default(),
            sets,
            shape: None,
        }
    }
}

thread_local! {
    /// This thread's last table of rows and its key: the next one reuses
    /// it if built from the same (a renderer's three calls at a batch of
    /// vertices), or its memory.
    static SPARE: std::cell::RefCell<Option<Spare>> = const { std::cell::RefCell::new(None) };
}

/// The thread's spare table, if it has one.
fn take_spare() -> Option<Spare> {
    SPARE.try_with(|s| s.borrow_mut().take()).ok().flatten()
}

/// Empty parameter sets of `bsdf`, in the memory of the thread's spare
/// ones if it has some.
fn spare_sets(bsdf: &LayeredBsdf) -> ParamSets {
    match take_spare() {
        Some(spare) => bsdf.reuse_sets(spare.sets),
        None => bsdf.empty_sets(),
    }
}

/// Keeps `spare` as the thread's spare table.
fn keep_spare(spare: Spare) {
    let _ = SPARE.try_with(|s| *s.borrow_mut() = Some(spare));
}

/// Why rows cannot be written in place.
enum Refused {
    /// A query's values are invalid: the error a material file with them
    /// gives.
    Query(Box<ColumnsError>),
    /// A row changes the stack's shape (or a check in place and the
    /// material's own disagree at the margin): the batch runs as materials.
    Materials,
}

/// Writes rows `range` of `columns` into a copy of `template`'s stack one
/// by one, checking each against the stack's own checks and against
/// `bsdf`'s shape, and adding it to `sets` (of `bsdf`) if given.
fn write_rows(
    template: &LayeredBsdf,
    bsdf: &LayeredBsdf,
    columns: &[Column],
    range: Range<usize>,
    sets: Option<&mut ParamSets>,
) -> Result<(), Refused> {
    let own = template.stack();
    let mut row = own.clone();
    let mut v = [0.0f64; 3];
    let paths: Vec<&SetPath> = columns.iter().map(|c| c.path).collect();
    let order = write_order(columns);
    // A coat whose IOR is the row's own has no table of `R̄`: walks.
    let returns = match order.first().is_some_and(|c| c.path.writes_ior()) {
        true => Returns::Walked,
        false => Returns::Tabulated,
    };
    let mut adding = sets.map(ParamSets::sets_mut);
    for k in range {
        let written = order.iter().try_for_each(|c| {
            let x = &c.values[k * c.width..(k + 1) * c.width];
            for (v, &x) in v.iter_mut().zip(x) {
                *v = f64::from(x);
            }
            row.write(c.path, &v[..c.width])
        });
        if written.and_then(|()| row.check_depths()).is_err() {
            // The material's own check names the query, the path and the
            // value as the caller wrote it.
            return Err(match query_stack(own, columns, k) {
                Err(e) => Refused::Query(Box::new(e)),
                Ok(_) => Refused::Materials,
            });
        }
        // (The row is the template's stack written at `paths`, and the
        // rows' BSDF has the template's shape there but for the first
        // row's values at those paths.)
        if !row.runs_on_at(bsdf.stack(), &paths) {
            return Err(Refused::Materials);
        }
        if let Some(adding) = adding.as_mut() {
            bsdf.push_set(adding, &row, returns);
        }
    }
    Ok(())
}

/// The columns in the order a row writes them: IORs first, since writing
/// an IOR derives the fields below it (a conductor's relative constants,
/// index matching) that a later column of their own then replaces.
fn write_order<'c, 'a>(columns: &'c [Column<'a>]) -> Vec<&'c Column<'a>> {
    let (ior, rest): (Vec<_>, Vec<_>) = columns.iter().partition(|c| c.path.writes_ior());
    ior.into_iter().chain(rest).collect()
}

impl<'a> PerQuery<'a> {
    /// `queries` queries of `template`'s material with row `k` of every
    /// column as query `k`'s values, answered with `template`'s
    /// configuration: the same checks and the same answers as
    /// [`Materials::per_query`] (see it for the rules), with memory bounded
    /// as the type says. Every row is checked here, a chunk at a time
    /// (each distinct row's material built and dropped): the first query
    /// whose values are invalid is an error naming it.
    pub fn new(
        template: &'a LayeredBsdf,
        queries: usize,
        columns: &[Column<'a>],
    ) -> Result<Self, ColumnsError> {
        check_lengths(template, queries, columns)?;
        let layers = template.stack().desc().layers.len().max(1);
        let mut q = PerQuery {
            template,
            queries,
            columns: columns.to_vec(),
            rows: (CHUNK_LAYERS / layers).clamp(1, CHUNK_ROWS),
            one_chunk: None,
            in_place: None,
        };
        if columns.iter().all(|c| c.path.in_place()) {
            match q.write_in_place() {
                Ok(p) => {
                    q.in_place = Some(p);
                    return Ok(q);
                }
                Err(Refused::Query(e)) => return Err(*e),
                Err(Refused::Materials) => {}
            }
        }
        let mut rows = Rows::new(&q).map_err(|bytes| ColumnsError::OutOfMemory { bytes })?;
        // The first chunk's materials are kept when it is the whole batch
        // (a renderer's batch), so that its calls do not build them again.
        let mut start = rows.next(&q, 0, true)?;
        if start >= queries && queries > 0 {
            let m = Materials::building(template, rows.stacks.drain(..), true);
            q.one_chunk = Some((m, std::mem::take(&mut rows.of)));
        }
        while start < queries {
            start = rows.next(&q, start, false)?;
        }
        Ok(q)
    }

    /// Checks every row in place, keeping the sets of a batch of one chunk.
    /// The rows share one shape: the template's, or the first row's.
    fn write_in_place(&self) -> Result<InPlace, Refused> {
        let n = self.queries;
        let mut key = Key::default();
        if n <= self.rows {
            // The thread's last table, if these columns built it for this
            // configuration.
            if let Some(spare) = take_spare() {
                let bsdf = spare.shape.as_deref().unwrap_or(self.template);
                if spare.key.is(self.template, &self.columns)
                    && bsdf.same_configuration(self.template)
                    && bsdf.built(&spare.sets)
                {
                    return Ok(InPlace {
                        shape: spare.shape,
                        identity: Materials::identity(n),
                        sets: Some(spare.sets),
                        key: spare.key,
                    });
                }
                key = spare.key;
                keep_spare(Spare::memory(spare.sets));
            }
            key.set(self.template, &self.columns);
        }
        let mut shape = None;
        if n > 0 {
            let mut first = self.template.stack().clone();
            for c in write_order(&self.columns) {
                let v: Vec<f64> = c.values[..c.width].iter().map(|&x| x.into()).collect();
                if first.write(c.path, &v).is_err() {
                    // Found by the rows below, as any invalid row.
                    break;
                }
            }
            if !first.runs_on(self.template.stack()) {
                shape = Some(Box::new(self.template.with_stack(first)));
            }
        }
        let bsdf = shape.as_deref().unwrap_or(self.template);
        // Kept for every call but albedo's, which builds its own.
        let mut sets = (n <= self.rows).then(|| {
            let mut sets = spare_sets(bsdf);
            sets.table_mut().set_lean(true);
            sets
        });
        // What a row's choices compute (a coat's table of `R̄`) honours the
        // thread setting.
        bsdf.on_own_threads(|| {
            (0..n).step_by(self.rows).try_for_each(|start| {
                let end = n.min(start + self.rows);
                let rows = start..end;
                write_rows(self.template, bsdf, &self.columns, rows, sets.as_mut())
            })
        })?;
        Ok(InPlace {
            identity: Materials::identity(self.rows.min(n)),
            sets,
            shape,
            key,
        })
    }

    /// The BSDF that answers rows written in place.
    pub(super) fn rows_bsdf(&self) -> &LayeredBsdf {
        match self.in_place.as_ref().and_then(|p| p.shape.as_deref()) {
            Some(b) => b,
            None => self.template,
        }
    }

    /// Runs `run` on every chunk of a batch whose rows are written in place
    /// ([`InPlace`]), in order: the queries' sets and their range. Errors
    /// name the query's index in the whole batch; `call` names the call in
    /// an out-of-memory error; `walks_every_row`: the call walks rows that
    /// eval, sample and pdf answer without walks (albedo), so its sets carry
    /// every row's lanes. `None` if the rows are materials.
    pub(super) fn in_place_chunks(
        &self,
        call: &'static str,
        walks_every_row: bool,
        mut run: impl FnMut(Per, Range<usize>) -> Result<(), BatchError>,
    ) -> Option<Result<(), BatchError>> {
        let p = self.in_place.as_ref()?;
        if let Some(sets) = p
            .sets
            .as_ref()
            .filter(|s| !walks_every_row || !s.table.is_lean())
        {
            return Some(run(Per(Some((sets, &p.identity))), 0..self.queries));
        }
        let bsdf = self.rows_bsdf();
        let mut sets = spare_sets(bsdf);
        for start in (0..self.queries).step_by(self.rows) {
            let end = self.queries.min(start + self.rows);
            sets.clear();
            sets.table_mut().set_lean(!walks_every_row);
            if let Err(bytes) = sets.try_reserve(end - start) {
                let error = QueryError::OutOfMemory { call, bytes };
                return Some(Err(BatchError::call(error)));
            }
            let rows = start..end;
            if write_rows(self.template, bsdf, &self.columns, rows, Some(&mut sets)).is_err() {
                // `new` wrote every row with the same function.
                unreachable!("rows are checked by PerQuery::new");
            }
            let per = Per(Some((&sets, &p.identity[..end - start])));
            if let Err(e) = run(per, start..end) {
                let index = e.index.map(|i| i + start);
                keep_spare(Spare::memory(sets));
                return Some(Err(BatchError { index, ..e }));
            }
        }
        keep_spare(Spare::memory(sets));
        Some(Ok(()))
    }

    /// The same, with at most `rows` (at least 1) distinct rows a chunk:
    /// fewer to hold less memory, more for fewer, larger parallel batches.
    #[must_use]
    pub fn with_chunk_rows(mut self, rows: usize) -> Self {
        self.rows = rows.max(1);
        if let Some(p) = &mut self.in_place {
            if self.queries > self.rows {
                p.sets = None;
            }
            p.identity = Materials::identity(self.rows.min(self.queries));
        }
        if self
            .one_chunk
            .as_ref()
            .is_some_and(|(m, _)| m.len() > self.rows)
        {
            self.one_chunk = None;
        }
        self
    }

    /// Whether its rows are parameter sets of the template, written in
    /// place (every column is a field [`SetPath::in_place`] takes, and no
    /// row changes the stack's shape), rather than a material per distinct
    /// row.
    pub fn rows_in_place(&self) -> bool {
        self.in_place.is_some()
    }

    /// Whether the batch is one chunk of rows written in place, whose
    /// sets [`PerQuery::new`] built.
    pub(super) fn one_chunk_in_place(&self) -> bool {
        self.in_place.as_ref().is_some_and(|p| p.sets.is_some())
    }

    /// The most distinct rows a chunk holds.
    pub fn chunk_rows(&self) -> usize {
        self.rows
    }

    /// Number of queries.
    pub fn len(&self) -> usize {
        self.queries
    }

    /// No queries.
    pub fn is_empty(&self) -> bool {
        self.queries == 0
    }

    /// Runs `run` on every chunk, in order: its materials, each query's
    /// material among them, and its range of queries. Errors name the
    /// query's index in the whole batch; `call` names the call in an
    /// out-of-memory error.
    pub(super) fn chunks(
        &self,
        call: &'static str,
        mut run: impl FnMut(&Materials, &[u32], Range<usize>) -> Result<(), BatchError>,
    ) -> Result<(), BatchError> {
        if let Some((m, of)) = &self.one_chunk {
            return run(m, of, 0..self.queries);
        }
        let oom = |bytes| BatchError::call(QueryError::OutOfMemory { call, bytes });
        let mut rows = Rows::new(self).map_err(oom)?;
        let mut start = 0;
        while start < self.queries {
            let end = match rows.next(self, start, true) {
                Ok(end) => end,
                Err(ColumnsError::OutOfMemory { bytes }) => return Err(oom(bytes)),
                // `new` built every row with the same function.
                Err(e) => unreachable!("rows are checked by PerQuery::new: {e}"),
            };
            let m = Materials::building(self.template, rows.stacks.drain(..), true);
            run(&m, &rows.of, start..end).map_err(|e| BatchError {
                index: e.index.map(|i| i + start),
                ..e
            })?;
            start = end;
        }
        Ok(())
    }

    /// A buffer for a chunk's values (one per query), allocated fallibly.
    pub(super) fn buffer<T>(&self, call: &'static str) -> Result<Vec<T>, BatchError> {
        let mut v = Vec::new();
        reserve(&mut v, self.queries.min(CHUNK_QUERIES))
            .map_err(|bytes| BatchError::call(QueryError::OutOfMemory { call, bytes }))?;
        Ok(v)
    }
}

/// The rows of one chunk: its distinct rows' materials, and each query's
/// among them. Its buffers are allocated once, for the largest chunk.
struct Rows {
    /// Each distinct row's bits, and its index.
    first: HashMap<Vec<u32>, u32>,
    /// The current query's row.
    row: Vec<u32>,
    /// The distinct rows' stacks.
    stacks: Vec<LayerStack>,
    /// Per query of the chunk: its row's index.
    of: Vec<u32>,
}

impl Rows {
    /// Buffers for `q`'s chunks, or the bytes the allocator refused.
    fn new(q: &PerQuery) -> Result<Self, usize> {
        let rows = q.rows.min(q.queries);
        let width: usize = q.columns.iter().map(|c| c.width).sum();
        let mut r = Rows {
            first: HashMap::new(),
            row: Vec::new(),
            stacks: Vec::new(),
            of: Vec::new(),
        };
        r.first
            .try_reserve(rows)
            .map_err(|_| rows.saturating_mul(std::mem::size_of::<(Vec<u32>, u32)>() + width * 4))?;
        reserve(&mut r.row, width)?;
        reserve(&mut r.stacks, rows)?;
        reserve(&mut r.of, q.queries.min(CHUNK_QUERIES))?;
        Ok(r)
    }

    /// Reads the chunk that starts at query `start` (at most `q.rows`
    /// distinct rows and [`CHUNK_QUERIES`] queries), building each distinct
    /// row's stack (kept if `keep`, else only checked); returns its end.
    fn next(&mut self, q: &PerQuery, start: usize, keep: bool) -> Result<usize, ColumnsError> {
        self.first.clear();
        self.stacks.clear();
        self.of.clear();
        let end = q.queries.min(start.saturating_add(CHUNK_QUERIES));
        for k in start..end {
            self.row.clear();
            for c in &q.columns {
                let v = &c.values[k * c.width..(k + 1) * c.width];
                self.row.extend(v.iter().map(|x| x.to_bits()));
            }
            let u = match self.first.get(&self.row[..]) {
                Some(&u) => u,
                None if self.first.len() == q.rows => return Ok(k),
                None => {
                    let st = query_stack(q.template.stack(), &q.columns, k)?;
                    let u = self.first.len() as u32;
                    if keep {
                        self.stacks.push(st);
                    }
                    self.first.insert(self.row.clone(), u);
                    u
                }
            };
            self.of.push(u);
        }
        Ok(end)
    }
}

/// Checks the columns' lengths and paths (not their rows): what
/// [`Materials::per_query`] and [`PerQuery::new`] check first.
fn check_lengths(
    template: &LayeredBsdf,
    queries: usize,
    columns: &[Column],
) -> Result<(), ColumnsError> {
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
    Ok(())
}

/// Reserves room for `n` more values, or says how many bytes were refused.
fn reserve<T>(v: &mut Vec<T>, n: usize) -> Result<(), usize> {
    v.try_reserve_exact(n)
        .map_err(|_| n.saturating_mul(std::mem::size_of::<T>()))
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
    // No fewer digits than the shortest that read back (`{:e}`'s) can: the
    // search starts there. Nine digits always read back (any f32), and
    // what `format!` writes always parses: the widened value is never
    // reached.
    let shortest = format!("{x:e}");
    let mantissa = shortest.split('e').next().unwrap_or("");
    let fewest = mantissa
        .bytes()
        .filter(u8::is_ascii_digit)
        .count()
        .clamp(1, 9);
    (fewest..=9)
        .map(digits)
        .find(|s| s.parse::<f32>() == Ok(x))
        .and_then(|s| s.parse().ok())
        .unwrap_or(wide)
}

/// `base` with query `k`'s row of every column.
pub(super) fn query_stack(
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
