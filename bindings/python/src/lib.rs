//! Python bindings of strata: the module `strata_bsdf._strata_bsdf`,
//! re-exported by the Python package `strata_bsdf`.
//!
//! One class, [`Bsdf`], wraps a [`LayeredBsdf`] and answers batches of
//! queries given as numpy arrays: `float32` arrays of shape `(N, 3)`, or a
//! tuple of three contiguous `float32` arrays of shape `(N,)` (the structure
//! of arrays Dr.Jit hands out, read without a copy). Results mirror the
//! layout of `wi`. Each batch runs with the GIL released, through the
//! library's slice calls ([`LayeredBsdf::eval_into`] and the others), so the
//! numbers are bit for bit those of the Rust API for the same seed and keys.
//! With `params` (per-query parameter arrays, e.g. a texture's values at
//! every hit) a batch runs through [`PerQuery`] instead, query
//! `k` on the material with row `k`'s values (one helper, `Bsdf::run`, for
//! every method).

use numpy::prelude::*;
use numpy::{
    dtype, PyArray1, PyArrayDyn, PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArrayDyn,
    PyUntypedArray, PyUntypedArrayMethods,
};
use pyo3::create_exception;
use pyo3::exceptions::{PyMemoryError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyInt, PyList, PyTuple};
use pyo3::IntoPyObjectExt;
use strata_bsdf::{
    check_walks, AlbedoRecord, BatchError, Bsdf as Answers, Column, ColumnsError, Estimator,
    EvalBuffers, LayerStack, LayeredBsdf, MaterialError as StackMaterialError, PdfWalks, PerQuery,
    Queries, SampleBuffers, SetError, SetPath, SpectralColumns, SpectralError, Transport, Vectors,
    VectorsMut, MAX_WALKS,
};

create_exception!(
    strata_bsdf,
    QueryError,
    PyValueError,
    "A query that cannot be answered (a direction that is NaN, infinite or of zero length, \
     or a per-query argument of the wrong length). `index` is the query's index in the batch, \
     or None when the fault is in an argument of the whole call."
);

create_exception!(
    strata_bsdf,
    MaterialError,
    PyValueError,
    "A material that cannot be loaded: unreadable file, malformed TOML or JSON, or an invalid \
     value (the message names the layer, the field and the value)."
);

/// A `QueryError` exception with `.index` set: the query at fault, or None
/// for an argument of the whole call.
fn query_err(py: Python<'_>, message: String, index: Option<usize>) -> PyErr {
    let err = QueryError::new_err(message);
    // Setting an attribute on a fresh exception instance cannot fail in
    // practice; if it did, the message alone still says everything.
    let _ = err.value(py).setattr("index", index.map(|i| i as i64));
    err
}

/// A `QueryError` exception from a batch error.
fn batch_err(py: Python<'_>, e: BatchError) -> PyErr {
    match e.error {
        strata_bsdf::QueryError::OutOfMemory { .. } => PyMemoryError::new_err(e.to_string()),
        _ => query_err(py, e.to_string(), e.index),
    }
}

/// A whole-number argument, taken as any Python int (`i128`) so that a
/// negative or a huge one gets [`u64_arg`]'s message, not pyo3's bare
/// OverflowError; an int beyond `i128` is a ValueError, anything else (a
/// float, a string) a TypeError, each naming the argument and the value.
fn whole(argument: &str, obj: &Bound<'_, PyAny>) -> PyResult<i128> {
    obj.extract::<i128>().map_err(|_| {
        let value = repr(obj);
        if obj.is_instance_of::<PyInt>() {
            PyValueError::new_err(format!("{argument} = {value}: out of range"))
        } else {
            PyTypeError::new_err(format!(
                "{argument} = {value}: expected a whole number, got {}",
                type_name(obj)
            ))
        }
    })
}

fn samples_arg(obj: &Bound<'_, PyAny>) -> PyResult<i128> {
    whole("samples", obj)
}

fn seed_arg(obj: &Bound<'_, PyAny>) -> PyResult<i128> {
    whole("seed", obj)
}

fn max_events_arg(obj: &Bound<'_, PyAny>) -> PyResult<Option<i128>> {
    match obj.is_none() {
        true => Ok(None),
        false => whole("max_events", obj).map(Some),
    }
}

fn n_arg(obj: &Bound<'_, PyAny>) -> PyResult<i128> {
    whole("n", obj)
}

/// An integer argument as `u64`, or a message naming it and its value.
fn u64_arg(argument: &str, n: i128, expected: &str) -> Result<u64, String> {
    u64::try_from(n).map_err(|_| format!("{argument} = {n}: expected {expected}"))
}

/// A count of walks (`samples`, `n`): 1 to `MAX_WALKS`.
fn walks_arg(argument: &'static str, n: i128) -> Result<u64, String> {
    let n = u64_arg(argument, n, &format!("1 to {MAX_WALKS} walks"))?;
    check_walks(argument, n).map_err(|e| e.to_string())?;
    Ok(n)
}

fn material_err(e: StackMaterialError) -> PyErr {
    MaterialError::new_err(e.to_string())
}

/// A Python shape as Python prints it: `(4,)`, `(4, 3)`.
fn shape_text(shape: &[usize]) -> String {
    match shape {
        [n] => format!("({n},)"),
        s => format!(
            "({})",
            s.iter()
                .map(|d| d.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// What a vector argument must be, for error messages.
const VECTORS_EXPECTED: &str =
    "a float32 numpy array of shape (N, 3) or a tuple of three contiguous float32 arrays of shape (N,)";

/// An input batch of 3-vectors, borrowed from numpy.
enum VecIn<'py> {
    Aos(PyReadonlyArray2<'py, f32>),
    Soa([PyReadonlyArray1<'py, f32>; 3]),
}

impl VecIn<'_> {
    /// The vectors as the library reads them. The arrays were checked to be
    /// C-contiguous when parsed, so the slices exist.
    fn vectors(&self) -> Vectors<'_> {
        match self {
            VecIn::Aos(a) => {
                let flat = a.as_slice().expect("checked contiguous");
                Vectors::from_flat(flat).expect("checked shape (N, 3)")
            }
            VecIn::Soa([x, y, z]) => Vectors::Soa([
                x.as_slice().expect("checked contiguous"),
                y.as_slice().expect("checked contiguous"),
                z.as_slice().expect("checked contiguous"),
            ]),
        }
    }

    fn layout(&self) -> Layout {
        match self {
            VecIn::Aos(_) => Layout::Aos,
            VecIn::Soa(_) => Layout::Soa,
        }
    }
}

/// What Python prints for `obj`, for messages.
fn repr(obj: &Bound<'_, PyAny>) -> String {
    obj.repr().map_or_else(|_| "?".into(), |r| r.to_string())
}

/// The Python type name of `obj`, for error messages.
fn type_name(obj: &Bound<'_, PyAny>) -> String {
    obj.get_type()
        .name()
        .map(|n| n.to_string())
        .unwrap_or_else(|_| "?".into())
}

/// An untyped numpy array, or a clear error naming `name`.
fn as_array<'a, 'py>(
    name: &str,
    obj: &'a Bound<'py, PyAny>,
) -> PyResult<&'a Bound<'py, PyUntypedArray>> {
    obj.cast::<PyUntypedArray>().map_err(|_| {
        PyTypeError::new_err(format!(
            "{name} must be {VECTORS_EXPECTED}; got {}",
            type_name(obj)
        ))
    })
}

/// Checks dtype, number of dimensions and contiguity of one array argument.
fn checked<'py, T: numpy::Element>(
    name: &str,
    arr: &Bound<'py, PyUntypedArray>,
    type_name: &str,
    ndim: usize,
    expected_shape: &str,
) -> PyResult<()> {
    let py = arr.py();
    if !arr.dtype().is_equiv_to(&dtype::<T>(py)) {
        return Err(PyTypeError::new_err(format!(
            "{name} must have dtype {type_name}; got {} (shape {}): convert with \
             numpy.asarray({name}, dtype=numpy.{type_name})",
            arr.dtype(),
            shape_text(arr.shape())
        )));
    }
    if arr.ndim() != ndim || (ndim == 2 && arr.shape()[1] != 3) {
        return Err(PyValueError::new_err(format!(
            "{name} must have shape {expected_shape}; got shape {}",
            shape_text(arr.shape())
        )));
    }
    if !arr.is_c_contiguous() || !arr.is_aligned() {
        return Err(PyValueError::new_err(format!(
            "{name} (shape {}) must be C-contiguous and aligned: pass numpy.ascontiguousarray({name})",
            shape_text(arr.shape())
        )));
    }
    Ok(())
}

/// A shared borrow of an input array (an error, not a panic, if Rust code
/// holds it mutably).
fn borrow<'py, T: numpy::Element, D: numpy::ndarray::Dimension>(
    name: &str,
    a: &Bound<'py, numpy::PyArray<T, D>>,
) -> PyResult<numpy::PyReadonlyArray<'py, T, D>> {
    a.try_readonly()
        .map_err(|e| PyValueError::new_err(format!("{name} cannot be read: {e}")))
}

/// Parses a vector argument: an `(N, 3)` float32 array or a tuple of three
/// `(N,)` ones. A list is refused rather than read either way: a list of
/// three rows and a list of three columns look alike (three arrays of shape
/// `(3,)`), and reading rows as columns would answer other queries silently.
fn vectors_in<'py>(name: &str, obj: &Bound<'py, PyAny>) -> PyResult<VecIn<'py>> {
    if obj.cast::<PyList>().is_ok() {
        return Err(PyTypeError::new_err(format!(
            "{name} must be {VECTORS_EXPECTED}; got a list (np.asarray({name}, np.float32) for rows, \
             tuple({name}) for x, y and z columns)"
        )));
    }
    let parts: Option<Vec<Bound<'py, PyAny>>> =
        obj.cast::<PyTuple>().ok().map(|t| t.iter().collect());
    if let Some(parts) = parts {
        if parts.len() != 3 {
            return Err(PyValueError::new_err(format!(
                "{name} must be {VECTORS_EXPECTED}; got a tuple of {} items",
                parts.len()
            )));
        }
        let mut arrays = Vec::with_capacity(3);
        for (c, p) in ["x", "y", "z"].iter().zip(&parts) {
            let label = format!("{name}.{c}");
            let a = p.cast::<PyUntypedArray>().map_err(|_| {
                PyTypeError::new_err(format!(
                    "{label} must be a contiguous float32 numpy array of shape (N,) \
                     ({name} was given as a tuple of three items, read as its x, y and z \
                     components); got {}",
                    type_name(p)
                ))
            })?;
            checked::<f32>(&label, a, "float32", 1, "(N,)")?;
            arrays.push(borrow(&label, a.cast::<PyArray1<f32>>()?)?);
        }
        let lens: Vec<usize> = arrays.iter().map(|a| a.len()).collect();
        if lens[1] != lens[0] || lens[2] != lens[0] {
            return Err(PyValueError::new_err(format!(
                "{name}.x, {name}.y and {name}.z have lengths {}, {} and {}: they must be equal",
                lens[0], lens[1], lens[2]
            )));
        }
        let z = arrays.pop().expect("three");
        let y = arrays.pop().expect("three");
        let x = arrays.pop().expect("three");
        return Ok(VecIn::Soa([x, y, z]));
    }
    let a = as_array(name, obj)?;
    checked::<f32>(name, a, "float32", 2, "(N, 3)")?;
    Ok(VecIn::Aos(borrow(name, a.cast::<numpy::PyArray2<f32>>()?)?))
}

/// Parses an optional `keys` argument: a contiguous uint64 array of shape `(N,)`.
fn keys_in<'py>(obj: Option<&Bound<'py, PyAny>>) -> PyResult<Option<PyReadonlyArray1<'py, u64>>> {
    let Some(obj) = obj.filter(|o| !o.is_none()) else {
        return Ok(None);
    };
    let a = obj.cast::<PyUntypedArray>().map_err(|_| {
        PyTypeError::new_err(format!(
            "keys must be None or a uint64 numpy array of shape (N,); got {}",
            type_name(obj)
        ))
    })?;
    checked::<u64>("keys", a, "uint64", 1, "(N,)")?;
    Ok(Some(borrow("keys", a.cast::<PyArray1<u64>>()?)?))
}

/// Whether every vector of `v` is plainly a direction: finite components,
/// not all zero. Those are what the library's checks accept (a finite
/// nonzero vector normalizes); this decides it without normalizing, which
/// the library's checks do for every vector (and the call does again).
fn plainly_directions(v: &Vectors<'_>) -> bool {
    let ok = |x: f32, y: f32, z: f32| {
        x.is_finite() && y.is_finite() && z.is_finite() && (x != 0.0 || y != 0.0 || z != 0.0)
    };
    match v {
        Vectors::Aos(a) => a.iter().all(|&[x, y, z]| ok(x, y, z)),
        Vectors::Soa([x, y, z]) => {
            x.len() == y.len()
                && x.len() == z.len()
                && x.iter().zip(*y).zip(*z).all(|((&x, &y), &z)| ok(x, y, z))
        }
        Vectors::Vec3(v) => v.iter().all(|v| ok(v.x, v.y, v.z)),
    }
}

/// Checks a pair call's vectors and keys as the library's call will
/// (lengths, directions), before anything is allocated for its results:
/// the number of queries, or the call's `QueryError`. A batch whose lengths
/// agree and whose vectors are [`plainly_directions`] passes at once; any
/// other goes through the library's own checks, which name what is wrong.
fn check_pairs(
    py: Python<'_>,
    wi: &VecIn<'_>,
    wo: &VecIn<'_>,
    keys: Option<&PyReadonlyArray1<'_, u64>>,
) -> PyResult<usize> {
    let k = keys.map(|k| k.as_slice().expect("checked contiguous"));
    let (a, b) = (wi.vectors(), wo.vectors());
    let n = a.len();
    if b.len() == n
        && k.is_none_or(|k| k.len() == n)
        && plainly_directions(&a)
        && plainly_directions(&b)
    {
        return Ok(n);
    }
    Vectors::check_pairs(&a, &b, k).map_err(|e| batch_err(py, e))
}

/// [`check_pairs`] for a call on incident directions alone.
fn check_directions(
    py: Python<'_>,
    wi: &VecIn<'_>,
    keys: Option<&PyReadonlyArray1<'_, u64>>,
) -> PyResult<usize> {
    let k = keys.map(|k| k.as_slice().expect("checked contiguous"));
    let a = wi.vectors();
    let n = a.len();
    if k.is_none_or(|k| k.len() == n) && plainly_directions(&a) {
        return Ok(n);
    }
    Vectors::check_directions(&a, k).map_err(|e| batch_err(py, e))
}

// ------------------------------------------------------- per-query parameters

/// What a `params` value must be, for error messages.
const PARAMS_EXPECTED: &str = "a C-contiguous float32 numpy array of shape (N,) (one number per \
     query) or (N, 3) (a triple per query: RGB, a normal), N the number of queries";

/// One per-query parameter: a path of the material and its column of
/// values, borrowed from numpy.
struct Param<'py> {
    path: SetPath,
    width: usize,
    values: PyReadonlyArrayDyn<'py, f32>,
}

/// Parses the `params` argument: `None`, or a dict from a parameter path
/// (`layers[0].medium.thickness`, docs/materials.md) to a float32 array of
/// shape `(n,)` or `(n, 3)`. The fields and the widths they take are the
/// library's to check (each value goes through the material's own
/// deserializer); only the path's grammar and the arrays are checked here.
fn params_in<'py>(obj: Option<&Bound<'py, PyAny>>, n: usize) -> PyResult<Vec<Param<'py>>> {
    let Some(obj) = obj.filter(|o| !o.is_none()) else {
        return Ok(Vec::new());
    };
    let dict = obj.cast::<PyDict>().map_err(|_| {
        PyTypeError::new_err(format!(
            "params must be None or a dict from a parameter path (e.g. \
             \"layers[0].medium.thickness\") to {PARAMS_EXPECTED}; got {}",
            type_name(obj)
        ))
    })?;
    let mut out = Vec::with_capacity(dict.len());
    for (key, value) in dict.iter() {
        let key: String = key.extract().map_err(|_| {
            PyTypeError::new_err(format!(
                "params keys must be parameter paths (str), e.g. \"layers[0].medium.thickness\"; \
                 got {}",
                type_name(&key)
            ))
        })?;
        let path =
            SetPath::parse(&key).map_err(|e| PyValueError::new_err(format!("params: {e}")))?;
        let name = format!("params[{key:?}]");
        let a = value.cast::<PyUntypedArray>().map_err(|_| {
            PyTypeError::new_err(format!(
                "{name} must be {PARAMS_EXPECTED}; got {}",
                type_name(&value)
            ))
        })?;
        let shape = a.shape();
        if !a.dtype().is_equiv_to(&dtype::<f32>(a.py())) {
            return Err(PyTypeError::new_err(format!(
                "{name} must have dtype float32; got {} (shape {}): convert with \
                 numpy.asarray(value, dtype=numpy.float32)",
                a.dtype(),
                shape_text(shape)
            )));
        }
        let width = match shape {
            [m] if *m == n => 1,
            [m, 3] if *m == n => 3,
            _ => {
                return Err(PyValueError::new_err(format!(
                    "{name} must have shape ({n},) or ({n}, 3) for {n} queries; got shape {}",
                    shape_text(shape)
                )))
            }
        };
        if !a.is_c_contiguous() || !a.is_aligned() {
            return Err(PyValueError::new_err(format!(
                "{name} (shape {}) must be C-contiguous and aligned: pass \
                 numpy.ascontiguousarray(value)",
                shape_text(shape)
            )));
        }
        let values = borrow(&name, a.cast::<PyArrayDyn<f32>>()?)?;
        out.push(Param {
            path,
            width,
            values,
        });
    }
    Ok(out)
}

/// Parses the `wavelengths` argument: `None`, or a float32 array of shape
/// `(n, 3)`, query k's three wavelengths in nm (their values are the
/// library's to check).
fn wavelengths_in<'py>(
    obj: Option<&Bound<'py, PyAny>>,
    n: usize,
) -> PyResult<Option<PyReadonlyArrayDyn<'py, f32>>> {
    let Some(obj) = obj.filter(|o| !o.is_none()) else {
        return Ok(None);
    };
    let expected = format!("a float32 array of shape ({n}, 3): three wavelengths in nm per query");
    let a = obj.cast::<PyUntypedArray>().map_err(|_| {
        PyTypeError::new_err(format!(
            "wavelengths must be None or {expected}; got {}",
            type_name(obj)
        ))
    })?;
    let shape = a.shape();
    if !a.dtype().is_equiv_to(&dtype::<f32>(a.py())) || shape != [n, 3] {
        return Err(PyValueError::new_err(format!(
            "wavelengths must be {expected}; got dtype {}, shape {}",
            a.dtype(),
            shape_text(shape)
        )));
    }
    if !a.is_c_contiguous() || !a.is_aligned() {
        return Err(PyValueError::new_err(
            "wavelengths must be C-contiguous and aligned: pass numpy.ascontiguousarray(value)",
        ));
    }
    Ok(Some(borrow("wavelengths", a.cast::<PyArrayDyn<f32>>()?)?))
}

/// Why a call with `params` did not run.
enum CallError {
    /// Boxed: a `SetError` makes it large, and errors are rare.
    Columns(Box<ColumnsError>),
    Spectral(Box<SpectralError>),
    Batch(BatchError),
}

impl From<BatchError> for CallError {
    fn from(e: BatchError) -> Self {
        CallError::Batch(e)
    }
}

impl CallError {
    /// The Python exception, `columns` being the call's parameters.
    fn into_py(self, py: Python<'_>, columns: &[Column<'_>]) -> PyErr {
        match self {
            CallError::Batch(e) => batch_err(py, e),
            CallError::Columns(e) => columns_err(py, *e, columns),
            CallError::Spectral(e) => match *e {
                SpectralError::Columns(e) => columns_err(py, *e, columns),
                e @ (SpectralError::Wavelength { query, .. }
                | SpectralError::Dispersive { query, .. }) => {
                    query_err(py, format!("wavelengths: {e}"), Some(query))
                }
                e @ SpectralError::OutOfMemory { .. } => {
                    PyMemoryError::new_err(format!("wavelengths: {e}"))
                }
                e => PyValueError::new_err(format!("wavelengths: {e}")),
            },
        }
    }
}

/// The Python exception for columns that cannot make the queries' materials.
fn columns_err(py: Python<'_>, e: ColumnsError, columns: &[Column<'_>]) -> PyErr {
    match e {
        // A width the field's parser refuses: a triple for a field of one
        // number (or the reverse), whatever the values.
        ColumnsError::Column {
            column,
            error: error @ SetError::Value { .. },
        } if column < columns.len() => {
            let c = &columns[column];
            let n = c.values.len() / c.width;
            let (shape, per) = if c.width == 3 {
                (shape_text(&[n, 3]), "a triple per query")
            } else {
                (shape_text(&[n]), "one number per query")
            };
            PyValueError::new_err(format!(
                "params[\"{}\"] has shape {shape} ({per}), which this field does not take: \
                     {error}",
                c.path
            ))
        }
        // A path this material does not have (a layer, a field of its
        // interface's kind, a medium), or one path twice: the whole
        // call's fault, whatever the values.
        ColumnsError::Column { error, .. } => PyValueError::new_err(format!("params: {error}")),
        // A row that makes an invalid material: that query's fault.
        ColumnsError::Query { query, error } => {
            query_err(py, format!("query {query}: {error}"), Some(query))
        }
        ColumnsError::OutOfMemory { .. } => PyMemoryError::new_err(format!("params: {e}")),
        e => PyValueError::new_err(format!("params: {e}")),
    }
}

/// A batch method's result, or `(result, truncated)` if the caller asked for
/// the count of walks the limit of events ended (`return_truncated=True`).
fn counted<'py>(
    py: Python<'py>,
    result: impl IntoPyObjectExt<'py>,
    truncated: Option<u64>,
) -> PyResult<Bound<'py, PyAny>> {
    let result = result.into_bound_py_any(py)?;
    match truncated {
        None => Ok(result),
        Some(cut) => (result, cut).into_bound_py_any(py),
    }
}

/// Walks a call may run with the GIL held: releasing and retaking it costs
/// more than such a call when other Python threads want it (Mitsuba's
/// scalar variants call one query at a time from each render thread).
const KEEP_GIL_WALKS: u64 = 64;

impl Bsdf {
    /// The density walks a pdf query runs at most under this BSDF's rule
    /// (none for the lobe pdf; a sample's pdf counts them too).
    fn pdf_walks_at_most(&self) -> u64 {
        self.inner.pdf_walks_value().max().max(1)
    }

    /// Runs `call` on the answerer `params` makes for `n` queries of
    /// `walks` walks each: the BSDF itself without params, else one material
    /// per query ([`PerQuery`], every row checked first), with the GIL
    /// released unless the call is small ([`KEEP_GIL_WALKS`]). The one path
    /// of every batch method.
    fn run<R: Send>(
        &self,
        py: Python<'_>,
        (params, wavelengths): (&[Param<'_>], Option<&PyReadonlyArrayDyn<'_, f32>>),
        n: usize,
        walks: u64,
        call: impl FnOnce(&dyn Answers) -> Result<R, BatchError> + Send,
    ) -> PyResult<R> {
        let columns: Vec<Column<'_>> = params
            .iter()
            .map(|p| Column {
                path: &p.path,
                width: p.width,
                values: p.values.as_slice().expect("checked contiguous"),
            })
            .collect();
        let bsdf = &self.inner;
        let nm = wavelengths.map(|w| w.as_slice().expect("checked contiguous"));
        let work = || {
            // Spectral queries: the material's spectra at each query's
            // wavelengths, and the params' RGB triples, as columns.
            let spectral = nm
                .map(|nm| SpectralColumns::new(bsdf, nm, &columns))
                .transpose()
                .map_err(|e| CallError::Spectral(Box::new(e)))?;
            let columns = spectral.as_ref().map_or(columns.clone(), |s| s.columns());
            if columns.is_empty() {
                return Ok(call(bsdf)?);
            }
            // A bounded chunk of rows' materials at a time (equal rows of a
            // chunk share one): memory bounded whatever `n`.
            let q =
                PerQuery::new(bsdf, n, &columns).map_err(|e| CallError::Columns(Box::new(e)))?;
            Ok(call(&q)?)
        };
        let small = (n as u64).saturating_mul(walks) <= KEEP_GIL_WALKS;
        let result: Result<R, CallError> = if small { work() } else { py.detach(work) };
        result.map_err(|e| e.into_py(py, &columns))
    }
}

/// Types whose all-zero bytes are a value: what [`zeros`] may allocate.
///
/// # Safety
/// Every field is a float or an integer.
unsafe trait Zero: Copy {}
// SAFETY: numbers, and records of them.
unsafe impl Zero for f32 {}
// SAFETY: as above.
unsafe impl Zero for u32 {}
// SAFETY: as above (`#[repr(C)]` arrays of f32).
unsafe impl Zero for AlbedoRecord {}

/// `len` zeros, or a `MemoryError` naming `call` where the process cannot
/// have them (`vec!` would abort the interpreter). Zeroed by the allocator,
/// not written, so that pages the system maps lazily stay untouched until
/// the results are.
fn zeros<T: Zero>(call: &str, len: usize) -> PyResult<Vec<T>> {
    let fail = || {
        PyMemoryError::new_err(format!(
            "{call}: cannot allocate its results ({len} values of {} bytes)",
            std::mem::size_of::<T>()
        ))
    };
    let layout = std::alloc::Layout::array::<T>(len).map_err(|_| fail())?;
    if layout.size() == 0 {
        return Ok(Vec::new());
    }
    // SAFETY: the layout's size is not zero.
    let p = unsafe { std::alloc::alloc_zeroed(layout) }.cast::<T>();
    if p.is_null() {
        return Err(fail());
    }
    // SAFETY: `p` is from the global allocator with the layout of `len`
    // values of `T`, all of them initialized: all-zero bytes are a `T`
    // (`Zero`).
    Ok(unsafe { Vec::from_raw_parts(p, len, len) })
}

/// How results are laid out: as the `wi` argument was.
#[derive(Clone, Copy)]
enum Layout {
    Aos,
    Soa,
}

/// An output batch of 3-vectors, owned until handed to numpy.
enum VecOut {
    Aos(Vec<f32>),
    Soa([Vec<f32>; 3]),
}

impl VecOut {
    /// Zeros for `n` queries, or a `MemoryError` naming `call`.
    fn new(call: &str, layout: Layout, n: usize) -> PyResult<Self> {
        Ok(match layout {
            Layout::Aos => VecOut::Aos(zeros(call, n.saturating_mul(3))?),
            Layout::Soa => VecOut::Soa([zeros(call, n)?, zeros(call, n)?, zeros(call, n)?]),
        })
    }

    fn as_mut(&mut self) -> VectorsMut<'_> {
        match self {
            VecOut::Aos(v) => VectorsMut::from_flat(v).expect("3 n floats"),
            VecOut::Soa([x, y, z]) => VectorsMut::Soa([x, y, z]),
        }
    }

    fn set(&mut self, i: usize, v: [f32; 3]) {
        match self {
            VecOut::Aos(a) => a[3 * i..3 * i + 3].copy_from_slice(&v),
            VecOut::Soa(c) => {
                for (s, x) in c.iter_mut().zip(v) {
                    s[i] = x;
                }
            }
        }
    }

    /// Hands the buffers to numpy without copying: an `(N, 3)` array or a
    /// tuple of three `(N,)` arrays.
    fn into_py(self, py: Python<'_>) -> PyResult<Bound<'_, PyAny>> {
        match self {
            VecOut::Aos(v) => {
                let n = v.len() / 3;
                Ok(v.into_pyarray(py).reshape([n, 3])?.into_any())
            }
            VecOut::Soa([x, y, z]) => Ok(PyTuple::new(
                py,
                [
                    x.into_pyarray(py).into_any(),
                    y.into_pyarray(py).into_any(),
                    z.into_pyarray(py).into_any(),
                ],
            )?
            .into_any()),
        }
    }
}

/// A layered BSDF (a strata `LayeredBsdf`), answering batches of queries.
///
/// Create one with `Bsdf.from_toml`, `Bsdf.from_json` or `Bsdf.from_path`.
/// Directions are in the local frame (z = normal of the stack's top), both
/// pointing away from the surface; in radiance mode `wi` points to the light
/// and `wo` to the viewer (docs/conventions.md). Vector arguments are float32
/// arrays of shape (N, 3), or tuples of three contiguous float32 arrays of
/// shape (N,); results have the layout of `wi`. A call reads its inputs with
/// the GIL released: do not modify them from another thread meanwhile. One
/// `Bsdf` may be used from several threads at once.
#[pyclass(frozen, module = "strata_bsdf")]
struct Bsdf {
    inner: LayeredBsdf,
}

/// What `pdf_samples` accepts.
const PDF_SAMPLES_EXPECTED: &str =
    "None (the library's rule), a number of walks, \"default\", \"lobes\", \"adaptive\", \"tight\" or (pilot, max, rel_stderr)";

/// The `pdf_samples` argument as a rule of density walks: `None` or
/// "default" for the library's rule (the lobe pdf), "lobes", "adaptive",
/// "tight", a fixed count, or an adaptive
/// rule `(pilot, max, rel_stderr)`; anything else is an error naming the
/// value.
fn pdf_walks_in(obj: Option<&Bound<'_, PyAny>>) -> PyResult<PdfWalks> {
    let Some(obj) = obj.filter(|o| !o.is_none()) else {
        return Ok(PdfWalks::DEFAULT);
    };
    if obj.is_instance_of::<PyInt>() {
        // (`whole`: an int beyond i128 is a ValueError too.)
        return walks_arg("pdf_samples", whole("pdf_samples", obj)?)
            .map(PdfWalks::fixed)
            .map_err(PyValueError::new_err);
    }
    if let Ok(name) = obj.extract::<String>() {
        return match name.as_str() {
            "default" | "lobes" | "adaptive" | "tight" => {
                name.parse().map_err(PyValueError::new_err)
            }
            _ => Err(PyValueError::new_err(format!(
                "pdf_samples = {}: expected {PDF_SAMPLES_EXPECTED}",
                repr(obj)
            ))),
        };
    }
    if let Ok((pilot, max, rel_stderr)) = obj.extract::<(Bound<PyAny>, Bound<PyAny>, f64)>() {
        let count = |field: &str, v: &Bound<PyAny>| {
            u64_arg(field, whole(field, v)?, "a number of walks").map_err(PyValueError::new_err)
        };
        let rule = PdfWalks::try_adaptive(count("pilot", &pilot)?, count("max", &max)?, rel_stderr);
        return rule
            .map_err(|e| PyValueError::new_err(format!("pdf_samples = {}: {e}", repr(obj))));
    }
    Err(PyTypeError::new_err(format!(
        "pdf_samples = {}: expected {PDF_SAMPLES_EXPECTED}, got {}",
        repr(obj),
        type_name(obj)
    )))
}

fn build(
    stack: LayerStack,
    samples: i128,
    seed: i128,
    transport: &str,
    pdf_samples: Option<&Bound<'_, PyAny>>,
    estimator: &str,
    max_events: Option<i128>,
) -> PyResult<Bsdf> {
    let samples = walks_arg("samples", samples).map_err(PyValueError::new_err)?;
    let limit = strata_bsdf::estimator::events::MAX_CAP;
    let max_events = match max_events {
        None => strata_bsdf::estimator::events::MAX_EVENTS,
        Some(n) if (1..=i128::from(limit)).contains(&n) => n as u32,
        Some(n) => {
            return Err(PyValueError::new_err(format!(
                "max_events = {n}: expected an integer from 1 to {limit}"
            )))
        }
    };
    let seed = u64_arg("seed", seed, "0 to 2^64 − 1").map_err(PyValueError::new_err)?;
    let pdf_walks = pdf_walks_in(pdf_samples)?;
    let transport: Transport = transport.parse().map_err(PyValueError::new_err)?;
    let estimator: Estimator = estimator.parse().map_err(PyValueError::new_err)?;
    Ok(Bsdf {
        inner: LayeredBsdf::new(stack)
            .samples(samples)
            .seed(seed)
            .pdf_walks(pdf_walks)
            .transport(transport)
            .estimator(estimator)
            .max_events(max_events),
    })
}

#[pymethods]
impl Bsdf {
    /// A BSDF from a TOML material description (docs/materials.md).
    ///
    /// `samples` is the number of walks per `eval` query, `seed` seeds every
    /// random stream, `transport` is "radiance" (light flows from `wi` to
    /// `wo`) or "importance" (the adjoint), `pdf_samples` a fixed number of
    /// density walks per approximate `pdf` (by default, the library's pilot
    /// round: 8 walks, then 8 to 64 fresh ones for a relative standard error
    /// of 0.15), `estimator` the estimator of `eval`: "auto" (a closed form where the stack has one,
    /// the bidirectional walks on stacks of three interfaces or more and rough coats over smooth or near-specular conductors (without optically thick scattering layers), the
    /// unidirectional walks elsewhere), "uni" or "bidir", `max_events` the
    /// limit of events per walk (1 to 2^24; by default 2^20, more than five
    /// times the longest walk of the library's stress suite). Raises
    /// `MaterialError` (a ValueError) naming the layer, the field and the
    /// value.
    #[staticmethod]
    #[pyo3(signature = (text, samples=1, seed=0, transport="radiance", pdf_samples=None, estimator="auto", max_events=None))]
    fn from_toml(
        text: &str,
        #[pyo3(from_py_with = samples_arg)] samples: i128,
        #[pyo3(from_py_with = seed_arg)] seed: i128,
        transport: &str,
        pdf_samples: Option<&Bound<'_, PyAny>>,
        estimator: &str,
        #[pyo3(from_py_with = max_events_arg)] max_events: Option<i128>,
    ) -> PyResult<Self> {
        let stack = LayerStack::from_toml_str(text).map_err(material_err)?;
        build(
            stack,
            samples,
            seed,
            transport,
            pdf_samples,
            estimator,
            max_events,
        )
    }

    /// A BSDF from a JSON material description; arguments as `from_toml`.
    #[staticmethod]
    #[pyo3(signature = (text, samples=1, seed=0, transport="radiance", pdf_samples=None, estimator="auto", max_events=None))]
    fn from_json(
        text: &str,
        #[pyo3(from_py_with = samples_arg)] samples: i128,
        #[pyo3(from_py_with = seed_arg)] seed: i128,
        transport: &str,
        pdf_samples: Option<&Bound<'_, PyAny>>,
        estimator: &str,
        #[pyo3(from_py_with = max_events_arg)] max_events: Option<i128>,
    ) -> PyResult<Self> {
        let stack = LayerStack::from_json_str(text).map_err(material_err)?;
        build(
            stack,
            samples,
            seed,
            transport,
            pdf_samples,
            estimator,
            max_events,
        )
    }

    /// A BSDF from a material file (`.json` as JSON, anything else as TOML);
    /// arguments as `from_toml`.
    #[staticmethod]
    #[pyo3(signature = (path, samples=1, seed=0, transport="radiance", pdf_samples=None, estimator="auto", max_events=None))]
    fn from_path(
        path: std::path::PathBuf,
        #[pyo3(from_py_with = samples_arg)] samples: i128,
        #[pyo3(from_py_with = seed_arg)] seed: i128,
        transport: &str,
        pdf_samples: Option<&Bound<'_, PyAny>>,
        estimator: &str,
        #[pyo3(from_py_with = max_events_arg)] max_events: Option<i128>,
    ) -> PyResult<Self> {
        let stack = LayerStack::from_path(path).map_err(material_err)?;
        build(
            stack,
            samples,
            seed,
            transport,
            pdf_samples,
            estimator,
            max_events,
        )
    }

    /// The same material and settings in another transport mode
    /// ("radiance" or "importance").
    fn with_transport(&self, transport: &str) -> PyResult<Self> {
        let t: Transport = transport.parse().map_err(PyValueError::new_err)?;
        Ok(Bsdf {
            inner: self.inner.clone().transport(t),
        })
    }

    /// The same material and settings with another estimator of `eval`
    /// ("auto", "uni" or "bidir").
    fn with_estimator(&self, estimator: &str) -> PyResult<Self> {
        let e: Estimator = estimator.parse().map_err(PyValueError::new_err)?;
        Ok(Bsdf {
            inner: self.inner.clone().estimator(e),
        })
    }

    /// The same material with `settings` applied: `key=value` pairs
    /// separated by whitespace, the library's configuration text (the keys
    /// and values of `config`; a key not given keeps its value), as the C
    /// ABI's `strata_bsdf_configure` and the CLI's `--config` read it. A new
    /// `Bsdf`, as `with_transport`: a `Bsdf` is immutable, so that threads
    /// may share it. Raises ValueError naming the key and the value
    /// (`rr_threshold=2: expected a number from 0.001 to 1`).
    fn configure(&self, settings: &str) -> PyResult<Self> {
        let mut config = self.inner.config();
        config
            .apply(settings)
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        let inner = self.inner.clone().with_config(&config).map_err(|e| {
            let threads = config.get("threads").unwrap_or_default();
            PyValueError::new_err(format!("threads={threads}: {e}"))
        })?;
        Ok(Bsdf { inner })
    }

    /// Every setting as `key=value` pairs, in a fixed order (`samples=1
    /// pdf_walks=lobes seed=0 transport=radiance ...`): text that `configure`
    /// reads back to the same settings.
    #[getter]
    fn config(&self) -> String {
        self.inner.config().to_string()
    }

    /// The limit of events per walk.
    #[getter]
    fn max_events(&self) -> u32 {
        self.inner.settings().max_events
    }

    /// The estimator of `eval` as chosen ("auto", "uni" or "bidir").
    #[getter]
    fn estimator(&self) -> &'static str {
        self.inner.estimator_choice().as_str()
    }

    /// The density walks per approximate pdf, as `pdf_samples` takes them:
    /// `None` for the library's rule (the default), a fixed count, "tight",
    /// or `(pilot, max, rel_stderr)`.
    #[getter]
    fn pdf_samples<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let walks = self.inner.pdf_walks_value();
        Ok(if walks == PdfWalks::DEFAULT {
            py.None().into_bound(py)
        } else if walks == PdfWalks::ADAPTIVE || walks == PdfWalks::TIGHT {
            walks.to_string().into_pyobject(py)?.into_any()
        } else if walks.pilot() == 0 {
            walks.max().into_pyobject(py)?.into_any()
        } else {
            (walks.pilot(), walks.max(), walks.rel_stderr())
                .into_pyobject(py)?
                .into_any()
        })
    }

    /// Whether `eval` runs the bidirectional estimator on this material.
    #[getter]
    fn bidirectional(&self) -> bool {
        self.inner.bidirectional()
    }

    /// Whether `sample` and `pdf` use a walk-free sampler (`estimator =
    /// "auto"` on a smooth or rough coat over a clear or absorbing layer over
    /// a Lambertian base): no walk, bounded weights, and `pdf` is the exact
    /// density of `sample`'s directions (`pdf_unbiased` then has standard
    /// error 0).
    #[getter]
    fn exact_sampling(&self) -> bool {
        self.inner.sample_is_exact()
    }

    /// Whether `eval` is answered without walks (`estimator = "auto"` on a
    /// coat over a clear or absorbing layer over a Lambertian base): the
    /// smooth coat's closed form (standard error 0), or a rough coat's
    /// factorization, whose samples are draws of the light entering from
    /// `wi` and `wo`, far cheaper than walks.
    #[getter]
    fn eval_without_walks(&self) -> bool {
        self.inner.eval_without_walks()
    }

    /// `f(wi, wo)` per RGB channel, without the cosine, and its standard
    /// error: `(f, stderr)`, each in the layout of `wi`.
    ///
    /// `keys` (uint64, shape (N,)) selects each query's random stream; by
    /// default a query is keyed by its directions' bits (the same pair
    /// always gives the same estimate). Delta lobes are never returned.
    ///
    /// `params` (every batch method takes it) gives each query its own
    /// parameters: a dict from a parameter path of the material
    /// (`"layers[0].medium.thickness"`, `"layers[1].interface.albedo"`,
    /// `"exterior_ior"`; docs/materials.md) to a float32 array of shape
    /// (N,), or (N, 3) for a triple (RGB) per query. Query k then answers
    /// bit for bit what the material with row k's values answers, with the
    /// same seed and keys. Every row is checked first: an invalid one raises
    /// `QueryError` naming the query, the path and the value.
    ///
    /// `wavelengths` (every batch method takes it) makes the queries
    /// spectral: a float32 array of shape (N, 3), query k's three
    /// wavelengths in nm, and channel c of every result is the value at
    /// wavelength c. The material's spectra (and `params`' RGB triples, by
    /// their uplift) are read at them (docs/materials.md, *Spectra*). A
    /// material whose IOR varies with wavelength takes one wavelength three
    /// times per query; four wavelengths are two calls.
    ///
    /// `return_truncated=True` (`eval`, `pdf_unbiased` and `albedo` take it)
    /// returns `(result, truncated)`: the result as above and the number of
    /// walks the limit of events (`max_events`) ended in the call, summed
    /// over the batch (0 when none did; their paths' energy beyond the limit
    /// is missing from the estimates).
    #[pyo3(signature = (wi, wo, keys=None, *, params=None, wavelengths=None, return_truncated=false))]
    #[expect(
        clippy::too_many_arguments,
        reason = "a Python method's positional and keyword arguments"
    )]
    fn eval<'py>(
        &self,
        py: Python<'py>,
        wi: &Bound<'py, PyAny>,
        wo: &Bound<'py, PyAny>,
        keys: Option<&Bound<'py, PyAny>>,
        params: Option<&Bound<'py, PyAny>>,
        wavelengths: Option<&Bound<'py, PyAny>>,
        return_truncated: bool,
    ) -> PyResult<Bound<'py, PyAny>> {
        let wi = vectors_in("wi", wi)?;
        let wo = vectors_in("wo", wo)?;
        let keys = keys_in(keys)?;
        let n = check_pairs(py, &wi, &wo, keys.as_ref())?;
        let params = params_in(params, n)?;
        let wavelengths = wavelengths_in(wavelengths, n)?;
        let mut f = VecOut::new("Bsdf.eval", wi.layout(), n)?;
        let mut se = VecOut::new("Bsdf.eval", wi.layout(), n)?;
        let cut = {
            let (wiv, wov) = (wi.vectors(), wo.vectors());
            let keys = keys
                .as_ref()
                .map(|k| k.as_slice().expect("checked contiguous"));
            let (fm, sm) = (f.as_mut(), se.as_mut());
            self.run(
                py,
                (&params, wavelengths.as_ref()),
                n,
                self.inner.samples_per_eval(),
                |a| {
                    let q = Queries {
                        keys,
                        ..Queries::pairs(wiv, wov)
                    };
                    let mut out = EvalBuffers {
                        f: fm,
                        stderr: Some(sm),
                    };
                    a.eval_into(&q, &mut |k, e| out.put(k, e))
                },
            )?
        };
        let result = (f.into_py(py)?, se.into_py(py)?);
        counted(py, result, return_truncated.then_some(cut))
    }

    /// `eval` and `pdf` of the same pairs in one call: `(f, stderr, pdf)`,
    /// bit for bit what `eval(wi, wo, keys)` and `pdf(wi, wo)` return (a
    /// light sample's value and its density for MIS), with the directions
    /// checked and normalized once. `keys`, `params` and `return_truncated`
    /// as for `eval`, and `wavelengths` (the count is that of `f`'s walks).
    #[pyo3(signature = (wi, wo, keys=None, *, params=None, wavelengths=None, return_truncated=false))]
    #[expect(
        clippy::too_many_arguments,
        reason = "a Python method's positional and keyword arguments"
    )]
    fn eval_pdf<'py>(
        &self,
        py: Python<'py>,
        wi: &Bound<'py, PyAny>,
        wo: &Bound<'py, PyAny>,
        keys: Option<&Bound<'py, PyAny>>,
        params: Option<&Bound<'py, PyAny>>,
        wavelengths: Option<&Bound<'py, PyAny>>,
        return_truncated: bool,
    ) -> PyResult<Bound<'py, PyAny>> {
        let wi = vectors_in("wi", wi)?;
        let wo = vectors_in("wo", wo)?;
        let keys = keys_in(keys)?;
        let n = check_pairs(py, &wi, &wo, keys.as_ref())?;
        let params = params_in(params, n)?;
        let wavelengths = wavelengths_in(wavelengths, n)?;
        let mut f = VecOut::new("Bsdf.eval_pdf", wi.layout(), n)?;
        let mut se = VecOut::new("Bsdf.eval_pdf", wi.layout(), n)?;
        let mut pdf: Vec<f32> = zeros("Bsdf.eval_pdf", n)?;
        let cut = {
            let (wiv, wov) = (wi.vectors(), wo.vectors());
            let keys = keys
                .as_ref()
                .map(|k| k.as_slice().expect("checked contiguous"));
            let mut out = EvalBuffers {
                f: f.as_mut(),
                stderr: Some(se.as_mut()),
            };
            let p = &mut pdf[..];
            let walks = self
                .inner
                .samples_per_eval()
                .saturating_add(self.pdf_walks_at_most());
            self.run(py, (&params, wavelengths.as_ref()), n, walks, |a| {
                let q = Queries {
                    keys,
                    ..Queries::pairs(wiv, wov)
                };
                a.eval_pdf_into(&q, &mut |k, e| out.put(k, e), &mut |k, x| p[k] = x)
            })?
        };
        let result = (f.into_py(py)?, se.into_py(py)?, pdf.into_pyarray(py));
        counted(py, result, return_truncated.then_some(cut))
    }

    /// One sampled direction per query: `(wo, weight, pdf, flags)`.
    ///
    /// `wo` and `weight` (`f |cos θo| / p`, per channel) have the layout of
    /// `wi`; `pdf` (float32) is exactly what `pdf(wi, wo)` returns; `flags`
    /// (uint32) has bits REFLECTION = 1, TRANSMISSION = 2, DELTA = 4, and 0
    /// for an absorbed walk (then everything is zero: count it as a zero
    /// sample). With `keys`, query k draws from the stream (seed, keys[k]);
    /// without, from sample index k of its direction's key. `params` and
    /// `wavelengths` as for `eval`.
    #[pyo3(signature = (wi, keys=None, *, params=None, wavelengths=None))]
    #[allow(clippy::type_complexity)]
    fn sample<'py>(
        &self,
        py: Python<'py>,
        wi: &Bound<'py, PyAny>,
        keys: Option<&Bound<'py, PyAny>>,
        params: Option<&Bound<'py, PyAny>>,
        wavelengths: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<(
        Bound<'py, PyAny>,
        Bound<'py, PyAny>,
        Bound<'py, PyArray1<f32>>,
        Bound<'py, PyArray1<u32>>,
    )> {
        let wi = vectors_in("wi", wi)?;
        let keys = keys_in(keys)?;
        let n = check_directions(py, &wi, keys.as_ref())?;
        let params = params_in(params, n)?;
        let wavelengths = wavelengths_in(wavelengths, n)?;
        let mut wo = VecOut::new("Bsdf.sample", wi.layout(), n)?;
        let mut weight = VecOut::new("Bsdf.sample", wi.layout(), n)?;
        let mut pdf: Vec<f32> = zeros("Bsdf.sample", n)?;
        let mut flags: Vec<u32> = zeros("Bsdf.sample", n)?;
        {
            let wiv = wi.vectors();
            let keys = keys
                .as_ref()
                .map(|k| k.as_slice().expect("checked contiguous"));
            let mut out = SampleBuffers {
                wo: wo.as_mut(),
                weight: weight.as_mut(),
                pdf: &mut pdf[..],
                flags: &mut flags[..],
            };
            self.run(
                py,
                (&params, wavelengths.as_ref()),
                n,
                self.pdf_walks_at_most(),
                |a| {
                    let q = Queries {
                        keys,
                        ..Queries::directions(wiv)
                    };
                    a.sample_into(&q, &mut |k, s| out.put(k, s))
                },
            )?;
        }
        Ok((
            wo.into_py(py)?,
            weight.into_py(py)?,
            pdf.into_pyarray(py),
            flags.into_pyarray(py),
        ))
    }

    /// The approximate density of `sample`'s direction `wo` for each pair
    /// (float32, shape (N,)), keyed by the directions: a function of
    /// `(wi, wo)`, the seed and the query's `params` and `wavelengths` (see
    /// `eval`).
    #[pyo3(signature = (wi, wo, *, params=None, wavelengths=None))]
    fn pdf<'py>(
        &self,
        py: Python<'py>,
        wi: &Bound<'py, PyAny>,
        wo: &Bound<'py, PyAny>,
        params: Option<&Bound<'py, PyAny>>,
        wavelengths: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArray1<f32>>> {
        let wi = vectors_in("wi", wi)?;
        let wo = vectors_in("wo", wo)?;
        let n = check_pairs(py, &wi, &wo, None)?;
        let params = params_in(params, n)?;
        let wavelengths = wavelengths_in(wavelengths, n)?;
        let mut pdf: Vec<f32> = zeros("Bsdf.pdf", n)?;
        {
            let (wiv, wov) = (wi.vectors(), wo.vectors());
            let p = &mut pdf[..];
            let walks = self.pdf_walks_at_most();
            self.run(py, (&params, wavelengths.as_ref()), n, walks, |a| {
                a.pdf_into(&Queries::pairs(wiv, wov), &mut |k, x| p[k] = x)
            })?;
        }
        Ok(pdf.into_pyarray(py))
    }

    /// The unbiased pdf of each pair from `samples` density walks:
    /// `(pdf, stderr)`, float32 arrays of shape (N,), the density of
    /// `sample`'s directions with its standard error. Slow: for references.
    /// `params`, `wavelengths` and `return_truncated` as for `eval`.
    #[pyo3(signature = (wi, wo, samples, *, params=None, wavelengths=None, return_truncated=false))]
    #[expect(
        clippy::too_many_arguments,
        reason = "a Python method's positional and keyword arguments"
    )]
    fn pdf_unbiased<'py>(
        &self,
        py: Python<'py>,
        wi: &Bound<'py, PyAny>,
        wo: &Bound<'py, PyAny>,
        #[pyo3(from_py_with = samples_arg)] samples: i128,
        params: Option<&Bound<'py, PyAny>>,
        wavelengths: Option<&Bound<'py, PyAny>>,
        return_truncated: bool,
    ) -> PyResult<Bound<'py, PyAny>> {
        let samples = walks_arg("samples", samples).map_err(|e| query_err(py, e, None))?;
        let wi = vectors_in("wi", wi)?;
        let wo = vectors_in("wo", wo)?;
        let n = check_pairs(py, &wi, &wo, None)?;
        let params = params_in(params, n)?;
        let wavelengths = wavelengths_in(wavelengths, n)?;
        let mut pdf: Vec<f32> = zeros("Bsdf.pdf_unbiased", n)?;
        let mut stderr: Vec<f32> = zeros("Bsdf.pdf_unbiased", n)?;
        let cut = {
            let (wiv, wov) = (wi.vectors(), wo.vectors());
            let (p, s) = (&mut pdf[..], &mut stderr[..]);
            self.run(py, (&params, wavelengths.as_ref()), n, samples, |a| {
                let q = Queries::pairs(wiv, wov).walks(samples);
                a.pdf_unbiased_into(&q, &mut |k, e| {
                    p[k] = e.value as f32;
                    s[k] = e.stderr as f32;
                })
            })?
        };
        let result = (pdf.into_pyarray(py), stderr.into_pyarray(py));
        counted(py, result, return_truncated.then_some(cut))
    }

    /// Directional albedo from `n` walks per direction:
    /// `(R, T, R_stderr, T_stderr)`, reflected and transmitted fractions per
    /// channel with their standard errors, each in the layout of `wi`.
    /// `keys`, `params`, `wavelengths` and `return_truncated` as for `eval` (an albedo's
    /// walk counts once: R and T come from the same walks).
    #[pyo3(signature = (wi, n, keys=None, *, params=None, wavelengths=None, return_truncated=false))]
    #[expect(
        clippy::too_many_arguments,
        reason = "a Python method's positional and keyword arguments"
    )]
    fn albedo<'py>(
        &self,
        py: Python<'py>,
        wi: &Bound<'py, PyAny>,
        #[pyo3(from_py_with = n_arg)] n: i128,
        keys: Option<&Bound<'py, PyAny>>,
        params: Option<&Bound<'py, PyAny>>,
        wavelengths: Option<&Bound<'py, PyAny>>,
        return_truncated: bool,
    ) -> PyResult<Bound<'py, PyAny>> {
        let n = walks_arg("n", n).map_err(|e| query_err(py, e, None))?;
        let wi = vectors_in("wi", wi)?;
        let keys = keys_in(keys)?;
        let m = check_directions(py, &wi, keys.as_ref())?;
        let params = params_in(params, m)?;
        let wavelengths = wavelengths_in(wavelengths, m)?;
        let mut rec: Vec<AlbedoRecord> = zeros("Bsdf.albedo", m)?;
        let cut = {
            let wiv = wi.vectors();
            let keys = keys
                .as_ref()
                .map(|k| k.as_slice().expect("checked contiguous"));
            let out = &mut rec[..];
            self.run(py, (&params, wavelengths.as_ref()), m, n, |a| {
                let q = Queries {
                    keys,
                    ..Queries::directions(wiv)
                }
                .walks(n);
                a.albedo_into(&q, &mut |k, x| out[k] = AlbedoRecord::of(x))
            })?
        };
        let layout = wi.layout();
        let mut outs = [
            VecOut::new("Bsdf.albedo", layout, m)?,
            VecOut::new("Bsdf.albedo", layout, m)?,
            VecOut::new("Bsdf.albedo", layout, m)?,
            VecOut::new("Bsdf.albedo", layout, m)?,
        ];
        for (i, r) in rec.iter().enumerate() {
            outs[0].set(i, r.reflected);
            outs[1].set(i, r.transmitted);
            outs[2].set(i, r.reflected_stderr);
            outs[3].set(i, r.transmitted_stderr);
        }
        let [a, b, c, d] = outs;
        let result = (
            a.into_py(py)?,
            b.into_py(py)?,
            c.into_py(py)?,
            d.into_py(py)?,
        );
        counted(py, result, return_truncated.then_some(cut))
    }

    /// Walks per `eval` query.
    #[getter]
    fn samples(&self) -> u64 {
        self.inner.samples_per_eval()
    }

    /// The seed of every random stream.
    #[getter]
    fn seed(&self) -> u64 {
        self.inner.seed_value()
    }

    /// "radiance" or "importance".
    #[getter]
    fn transport(&self) -> &'static str {
        self.inner.transport_mode().as_str()
    }

    /// The material's description text, if it has one.
    #[getter]
    fn description(&self) -> Option<String> {
        self.inner.stack().desc().description.clone()
    }

    /// Number of interfaces.
    #[getter]
    fn interfaces(&self) -> usize {
        self.inner.stack().len()
    }

    /// The bottom interface is a dielectric: light passes through.
    #[getter]
    fn transmissive(&self) -> bool {
        self.inner.stack().transmissive()
    }

    /// An opaque stack that mirrors light from below (see conventions).
    #[getter]
    fn two_sided(&self) -> bool {
        self.inner.stack().two_sided()
    }

    /// How many wavelengths one walk carries: 3, or 1 where the material's
    /// IOR varies with wavelength (so a call's `wavelengths` rows then
    /// repeat one wavelength three times).
    #[getter]
    fn wavelengths_per_walk(&self) -> usize {
        self.inner.wavelengths_per_walk()
    }

    /// IOR of the exterior above the top interface.
    #[getter]
    fn exterior_ior(&self) -> f64 {
        self.inner.stack().exterior_above()
    }

    /// IOR of the exterior below (for a transmissive stack).
    #[getter]
    fn exterior_ior_below(&self) -> f64 {
        self.inner.stack().exterior_below()
    }

    /// The lobes the stack can produce, as a dict of booleans:
    /// `delta_reflection`, `delta_transmission` (from `sample` only),
    /// `glossy` (a rough interface or a scattering medium), `diffuse` (a
    /// Lambertian interface) and `transmission` (the stack transmits).
    #[getter]
    fn lobes<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let l = self.inner.stack().lobes();
        let d = PyDict::new(py);
        d.set_item("delta_reflection", l.delta_reflection)?;
        d.set_item("delta_transmission", l.delta_transmission)?;
        d.set_item("glossy", l.glossy)?;
        d.set_item("diffuse", l.diffuse)?;
        d.set_item("transmission", l.transmission)?;
        Ok(d)
    }

    fn __repr__(&self, py: Python<'_>) -> PyResult<String> {
        let what = self
            .inner
            .stack()
            .desc()
            .description
            .clone()
            .unwrap_or_else(|| format!("{} interfaces", self.inner.stack().len()));
        Ok(format!(
            "Bsdf({what:?}, samples={}, seed={}, transport={:?}, estimator={:?}, pdf_samples={})",
            self.inner.samples_per_eval(),
            self.inner.seed_value(),
            self.inner.transport_mode().as_str(),
            self.inner.estimator_choice().as_str(),
            self.pdf_samples(py)?.repr()?
        ))
    }
}

/// strata's layered BSDFs for Python (the compiled part of `strata_bsdf`).
#[pymodule]
fn _strata_bsdf(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add_class::<Bsdf>()?;
    m.add("QueryError", py.get_type::<QueryError>())?;
    m.add("MaterialError", py.get_type::<MaterialError>())?;
    m.add("REFLECTION", strata_bsdf::SampleFlags::REFLECTION)?;
    m.add("TRANSMISSION", strata_bsdf::SampleFlags::TRANSMISSION)?;
    m.add("DELTA", strata_bsdf::SampleFlags::DELTA)?;
    m.add("MAX_WALKS", MAX_WALKS)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
