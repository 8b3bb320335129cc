//! The C ABI of strata: layered BSDFs for C and C++ renderers.
//!
//! The header is `include/strata.h`, generated from this file by cbindgen
//! (`cbindgen.toml`; `.ci/capi.sh` fails if the committed header is stale).
//! Link `libstrata_capi.a` (with `-lpthread -ldl -lm`) or
//! `libstrata_capi.so`. docs/embedding.md has the guide.
//!
//! Every function returns a status: [`STRATA_OK`] (0) or a negative
//! `STRATA_ERR_*` code, and then [`strata_last_error`] says what was wrong,
//! naming the argument and, in a batch, the query index. Nothing unwinds
//! across the boundary: a panic inside strata is caught and reported as
//! [`STRATA_ERR_PANIC`].
//!
//! A `StrataBsdf` is the library's [`LayeredBsdf`] behind a pointer; the
//! batch functions are its slice calls (`eval_into`, `sample_records`, ...)
//! over the caller's flat arrays, so they give the Rust API's numbers bit for
//! bit (tested in `tests/abi_suite/abi.rs`).
//!
//! Per-query parameters (a renderer's textures) are `StrataColumn`s, taken by
//! the `*_columns` form of every batch call: the call builds one material per
//! query with [`PerQuery`] (a bounded chunk of them at a time) and answers query `k` as a BSDF made
//! from a material file with row `k`'s values (`tests/abi_suite/columns.rs`). Each
//! batch call has one body that both its forms share.

#![warn(missing_docs)]
#![deny(unsafe_op_in_unsafe_fn)]

use std::borrow::Cow;
use std::cell::{Cell, RefCell};
use std::ffi::{c_char, CStr, CString};
use std::mem::{align_of, offset_of, size_of};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::thread::AccessError;
use strata_bsdf::stack::MaterialError;
use strata_bsdf::{
    check_walks, AlbedoRecord, BatchError, Column, ColumnsError, Estimator, LayerStack,
    LayeredBsdf, PdfWalks, PerQuery, QueryError, SampleRecord, SetError, SetPath, Transport,
    Vectors, VectorsMut,
};

// ------------------------------------------------------------------ statuses

/// Success.
pub const STRATA_OK: i32 = 0;
/// A required pointer argument is NULL (the message names it).
pub const STRATA_ERR_NULL: i32 = -1;
/// An argument has a value strata cannot use: a direction that is NaN,
/// infinite or of zero length (the message names the query index and the
/// argument), a walk count of 0 or above 2^40, an unknown transport mode, a
/// batch too large to address, a misaligned or overlapping array, text
/// that is not UTF-8, or a bad `StrataColumn` (a width other than 1 or 3, a
/// path that is not settable or not in the material, a NaN or infinite
/// value, a value of the wrong shape for its field).
pub const STRATA_ERR_INVALID_ARGUMENT: i32 = -2;
/// The material text is malformed or describes an invalid stack, or a
/// query's `StrataColumn` values make an invalid material (the message names
/// the query, the layer, the field and the value).
pub const STRATA_ERR_MATERIAL: i32 = -3;
/// A material file could not be read (the message names the path).
pub const STRATA_ERR_IO: i32 = -4;
/// The call's working memory could not be allocated: the process is out
/// of memory or of address space (`RLIMIT_AS`). The message names the call
/// and the bytes asked for; nothing was written, or (if it was refused
/// between two chunks of a `*_columns` call) the outputs of the queries
/// before the chunk were; the BSDF is still usable.
pub const STRATA_ERR_OUT_OF_MEMORY: i32 = -5;
/// strata panicked: a bug. The panic was caught at the boundary; the BSDF is
/// still usable. Please report the message.
pub const STRATA_ERR_PANIC: i32 = -99;

/// Transport mode: light flows from `wi` to `wo` (`wi` points to the light).
/// The default.
pub const STRATA_TRANSPORT_RADIANCE: u32 = 0;
/// Transport mode: importance flows from `wi` to `wo` (`wi` points to the
/// viewer): `eval` is the adjoint `f(wo -> wi)`.
pub const STRATA_TRANSPORT_IMPORTANCE: u32 = 1;
/// Estimator of eval: a closed form where the stack has one, the
/// bidirectional estimator on stacks of three interfaces or more and rough coats over smooth or near-specular conductors (without optically thick scattering layers), the
/// unidirectional one elsewhere (the default).
pub const STRATA_ESTIMATOR_AUTO: u32 = 0;
/// Estimator of eval: the unidirectional walks, always.
pub const STRATA_ESTIMATOR_UNIDIRECTIONAL: u32 = 1;
/// Estimator of eval: the bidirectional walks, always.
pub const STRATA_ESTIMATOR_BIDIRECTIONAL: u32 = 2;

/// `strata_bsdf_set_pdf_samples`'s `n` for the library's rule (a pilot
/// round), the default; any other `n` is a fixed count.
pub const STRATA_PDF_SAMPLES_RULE: u32 = 0;

/// `StrataSample::flags` bit: the walk left on the side it entered.
pub const STRATA_SAMPLE_REFLECTION: u32 = 1;
/// `StrataSample::flags` bit: the walk left on the other side.
pub const STRATA_SAMPLE_TRANSMISSION: u32 = 2;
/// `StrataSample::flags` bit: every event of the walk was a delta (the
/// direction is a specular one; treat the sample as a delta).
pub const STRATA_SAMPLE_DELTA: u32 = 4;

const _: () = {
    assert!(STRATA_SAMPLE_REFLECTION == strata_bsdf::SampleFlags::REFLECTION);
    assert!(STRATA_SAMPLE_TRANSMISSION == strata_bsdf::SampleFlags::TRANSMISSION);
    assert!(STRATA_SAMPLE_DELTA == strata_bsdf::SampleFlags::DELTA);
    assert!(STRATA_TRANSPORT_RADIANCE == Transport::Radiance as u32);
    assert!(STRATA_TRANSPORT_IMPORTANCE == Transport::Importance as u32);
};

// --------------------------------------------------------------------- types

/// A layered BSDF: a material stack with its walk count and seed. Create it
/// with `strata_bsdf_from_toml`, `_from_json` or `_from_path`, free it with
/// `strata_bsdf_free`. It is immutable once configured: any number of threads
/// may call the batch functions on one `StrataBsdf` at the same time
/// (`strata_bsdf_set_transport` must not run concurrently with them).
pub struct StrataBsdf {
    inner: LayeredBsdf,
}

const _: () = {
    const fn shareable<T: Send + Sync>() {}
    shareable::<StrataBsdf>();
};

/// One sample of `strata_sample_batch`. An absorbed walk is all zeros
/// (flags 0): count it as a zero-weight sample.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StrataSample {
    /// The sampled direction (unit, pointing away from the surface), or zeros
    /// if the walk was absorbed.
    pub wo: [f32; 3],
    /// `f(wi, wo) |cos(theta_o)| / p(wo)` per RGB channel (in the BSDF's
    /// transport mode): an unbiased estimate, the walk's throughput.
    pub weight: [f32; 3],
    /// The density of `wo` per solid angle: exactly what `strata_pdf_batch`
    /// gives for `(wi, wo)`, so MIS sees the same number from either
    /// strategy. Approximate (exact on the coats over Lambertian bases that
    /// are sampled without a walk: `strata_bsdf_is_exact`), so the weight is
    /// not `f cos / pdf` in general.
    pub pdf: f32,
    /// `STRATA_SAMPLE_*` bits: REFLECTION or TRANSMISSION, and DELTA; 0 if
    /// absorbed.
    pub flags: u32,
}

/// One result of `strata_albedo_batch`: the fractions of light from `wi`
/// reflected and transmitted, per RGB channel, with standard errors.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StrataAlbedo {
    /// Reflected fraction per channel.
    pub reflected: [f32; 3],
    /// Transmitted fraction per channel.
    pub transmitted: [f32; 3],
    /// Standard error of the reflected fraction.
    pub reflected_stderr: [f32; 3],
    /// Standard error of the transmitted fraction.
    pub transmitted_stderr: [f32; 3],
}

// The C records are the library's records, field for field, so that the
// batch calls write straight into the caller's array.
const _: () = {
    assert!(size_of::<StrataSample>() == size_of::<SampleRecord>());
    assert!(align_of::<StrataSample>() == align_of::<SampleRecord>());
    assert!(offset_of!(StrataSample, wo) == offset_of!(SampleRecord, wo));
    assert!(offset_of!(StrataSample, weight) == offset_of!(SampleRecord, weight));
    assert!(offset_of!(StrataSample, pdf) == offset_of!(SampleRecord, pdf));
    assert!(offset_of!(StrataSample, flags) == offset_of!(SampleRecord, flags));
    assert!(size_of::<StrataAlbedo>() == size_of::<AlbedoRecord>());
    assert!(align_of::<StrataAlbedo>() == align_of::<AlbedoRecord>());
    assert!(offset_of!(StrataAlbedo, reflected) == offset_of!(AlbedoRecord, reflected));
    assert!(offset_of!(StrataAlbedo, transmitted) == offset_of!(AlbedoRecord, transmitted));
    assert!(
        offset_of!(StrataAlbedo, reflected_stderr) == offset_of!(AlbedoRecord, reflected_stderr)
    );
    assert!(
        offset_of!(StrataAlbedo, transmitted_stderr)
            == offset_of!(AlbedoRecord, transmitted_stderr)
    );
};

/// What a renderer needs to know of a stack to declare its BSDF: the
/// exteriors' IORs (for a transmitted sample's relative IOR) and whether light
/// passes through. Filled by `strata_bsdf_info`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StrataStackInfo {
    /// IOR of the exterior above the stack (`exterior_ior`, default 1).
    pub ior_above: f32,
    /// IOR of the exterior below (the last dielectric's `ior`) for a
    /// transmissive stack; for an opaque one, the IOR above its base.
    pub ior_below: f32,
    /// 1 if the bottom interface is a dielectric (light passes through, and
    /// samples may have `STRATA_SAMPLE_TRANSMISSION`), else 0.
    pub transmissive: u32,
    /// 1 if light from below an opaque stack is mirrored to the top (the
    /// material's `two_sided`), else 0.
    pub two_sided: u32,
}

/// One per-query parameter of a `*_columns` batch call: the values of the
/// material parameter `path` for each of the call's `n` queries, `width`
/// floats per query, query after query (`values[k * width + c]`).
///
/// `path` is a settable parameter of the BSDF's material, as in
/// docs/materials.md "Per-query overrides (set)": `"exterior_ior"`,
/// `"layers[i].interface.ior"` (or `roughness`, `eta`, `k`, `albedo`),
/// `"layers[i].medium.thickness"` (or `sigma_t`, `albedo`, `phase.g`).
/// `width` is 1 (a number per query) or 3 (an RGB triple per query: `eta`,
/// `k`, `sigma_t`, an albedo); a number where the field takes a triple sets
/// all three channels (an anisotropic roughness, two numbers, cannot be a
/// column). Query `k` then answers bit for bit what a BSDF made from a
/// material file with row `k`'s values answers (same seed and key), with the
/// BSDF's walk count, seed, transport mode and threads. A float sets the
/// first of its `%.1g` … `%.9g` decimals that reads back as it: a column's
/// `0.1f` is a material file's `0.1` (examples/c/textured.c prints it so).
///
/// Errors: every column and every row is checked before anything runs, and a
/// failed call writes nothing to its outputs. A bad column is named by its
/// index (`columns[1].path is NULL`, `columns[0].values is NULL (n = 4)`,
/// `columns[0].width = 2 ...`, `columns[0]: set path ...: unknown medium
/// field ...`; `STRATA_ERR_NULL` or `STRATA_ERR_INVALID_ARGUMENT`). The first
/// query whose values are invalid fails the whole batch, naming the query,
/// the path and the value: `STRATA_ERR_MATERIAL` if they make an invalid
/// material (``columns: query 3: set `layers[0].medium.thickness` = -1.0:
/// invalid material: layer 0: medium.thickness = -1: must be >= 0``), else
/// `STRATA_ERR_INVALID_ARGUMENT` (``columns: query 1: set
/// `layers[0].medium.sigma_t` = NaN: not a finite number``). A renderer clamps
/// its textures, or drops the query and calls again for the rest.
///
/// Memory: a `*_columns` call builds the materials of a bounded chunk of
/// queries at a time (at most 65536 queries and `min(4096, max(1, 65536 /
/// layers))` distinct rows), answers them and drops them, so its working
/// memory is at most that many materials (a few KB each on a two-layer
/// stack, about 1.7 KB per layer on a deep one) plus a few hundred bytes per
/// query of a chunk, whatever `n` and however many rows differ: about 20 MB
/// on a two-layer stack (`strata::PerQuery` in the Rust docs). Every row is
/// checked (a chunk at a time) before the first chunk runs. If the working
/// memory cannot be allocated the status is `STRATA_ERR_OUT_OF_MEMORY` and
/// `strata_last_error()` names the call and the bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct StrataColumn {
    /// The parameter's path, NUL-terminated UTF-8 (e.g.
    /// `"layers[0].medium.thickness"`).
    pub path: *const c_char,
    /// Floats per query: 1 or 3.
    pub width: usize,
    /// `width × n` floats, query after query.
    pub values: *const f32,
}

// ---------------------------------------------------------- errors, guarding

/// A failed call: its status and message.
#[derive(Debug)]
struct Failure {
    code: i32,
    message: String,
}

impl Failure {
    fn new(code: i32, message: impl Into<String>) -> Self {
        Failure {
            code,
            message: message.into(),
        }
    }
    fn invalid(message: impl Into<String>) -> Self {
        Self::new(STRATA_ERR_INVALID_ARGUMENT, message)
    }
}

impl From<BatchError> for Failure {
    fn from(e: BatchError) -> Self {
        let code = match e.error {
            QueryError::OutOfMemory { .. } => STRATA_ERR_OUT_OF_MEMORY,
            _ => STRATA_ERR_INVALID_ARGUMENT,
        };
        Failure::new(code, e.to_string())
    }
}

impl From<MaterialError> for Failure {
    fn from(e: MaterialError) -> Self {
        let code = match e {
            MaterialError::Io { .. } => STRATA_ERR_IO,
            _ => STRATA_ERR_MATERIAL,
        };
        Failure::new(code, e.to_string())
    }
}

thread_local! {
    /// The message of this thread's last failed call ("" after a success).
    static LAST_ERROR: RefCell<CString> = RefCell::new(CString::default());
    /// The message of a call made after `LAST_ERROR` was destroyed (from a
    /// thread-local's destructor at thread exit), as a pointer from
    /// `CString::into_raw` or NULL. No destructor, so it is never gone; the
    /// next such call frees it, the thread's exit does not (one message at
    /// most stays allocated per thread that failed a call so late).
    static LATE_ERROR: Cell<*mut c_char> = const { Cell::new(std::ptr::null_mut()) };
}

fn set_last_error(message: &str) {
    // A C string cannot hold NUL: show it escaped (it can only come from
    // material text quoted in a parser's message).
    let c = CString::new(message.replace('\0', "\\0")).unwrap_or_default();
    // `try_with`: a call made while the thread's locals are torn down (from
    // a destructor) must not panic outside the guard, which would abort the
    // process; its message goes to `LATE_ERROR`.
    if let Err(AccessError { .. }) = LAST_ERROR.try_with(|e| *e.borrow_mut() = c.clone()) {
        let late = if message.is_empty() {
            std::ptr::null_mut()
        } else {
            c.into_raw()
        };
        let old = LATE_ERROR.with(|e| e.replace(late));
        if !old.is_null() {
            // SAFETY: `old` came from `CString::into_raw` and is freed once
            // (it is no longer in `LATE_ERROR`).
            drop(unsafe { CString::from_raw(old) });
        }
    }
}

/// Runs the body of `function`, catching panics: the status, with the last
/// error set (to "" on success).
fn guard(function: &str, body: impl FnOnce() -> Result<(), Failure>) -> i32 {
    match catch_unwind(AssertUnwindSafe(body)) {
        Ok(Ok(())) => {
            set_last_error("");
            STRATA_OK
        }
        Ok(Err(f)) => {
            set_last_error(&format!("{function}: {}", f.message));
            f.code
        }
        Err(payload) => {
            let what = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown payload".into());
            set_last_error(&format!(
                "{function}: internal error (strata panicked: {what}); please report it"
            ));
            STRATA_ERR_PANIC
        }
    }
}

// ------------------------------------------------------- pointers to slices

/// The BSDF behind `b`, or an error if it is NULL.
///
/// # Safety
/// `b` is NULL or a pointer from `strata_bsdf_from_*` not yet freed.
unsafe fn bsdf_ref<'a>(b: *const StrataBsdf) -> Result<&'a LayeredBsdf, Failure> {
    // SAFETY: the caller guarantees that a non-NULL `b` points to a live
    // `StrataBsdf`, which nothing mutates during a batch call.
    match unsafe { b.as_ref() } {
        Some(b) => Ok(&b.inner),
        None => Err(Failure::new(STRATA_ERR_NULL, "b is NULL")),
    }
}

/// The BSDF behind `b` to configure, or an error if it is NULL.
///
/// # Safety
/// `b` is NULL or a pointer from `strata_bsdf_from_*` not yet freed, which
/// no other thread uses during the call.
unsafe fn bsdf_mut<'a>(b: *mut StrataBsdf) -> Result<&'a mut LayeredBsdf, Failure> {
    // SAFETY: the caller guarantees that a non-NULL `b` is live and not used
    // by another thread, so this is the only reference to it.
    match unsafe { b.as_mut() } {
        Some(b) => Ok(&mut b.inner),
        None => Err(Failure::new(STRATA_ERR_NULL, "b is NULL")),
    }
}

/// Checks an array argument of `len` elements of `T` (for `n` queries): not
/// NULL, aligned, and addressable.
fn check_array<T>(name: &str, ptr: *const T, len: usize, n: usize) -> Result<(), Failure> {
    if ptr.is_null() {
        return Err(Failure::new(
            STRATA_ERR_NULL,
            format!("{name} is NULL (n = {n})"),
        ));
    }
    if !ptr.is_aligned() {
        return Err(Failure::invalid(format!(
            "{name} = {ptr:p} is not aligned to {} bytes",
            align_of::<T>()
        )));
    }
    if len
        .checked_mul(size_of::<T>())
        .is_none_or(|b| b > isize::MAX as usize)
    {
        return Err(Failure::invalid(format!(
            "n = {n} is too large: {name} would not fit in memory"
        )));
    }
    Ok(())
}

/// A caller's input array of `per * n` elements.
///
/// # Safety
/// A non-NULL `ptr` is valid for reading `per * n` elements of `T`, which
/// nothing writes during the call.
unsafe fn input<'a, T>(
    name: &str,
    ptr: *const T,
    per: usize,
    n: usize,
) -> Result<&'a [T], Failure> {
    let len = per.checked_mul(n).ok_or_else(|| too_large(name, n))?;
    check_array(name, ptr, len, n)?;
    // SAFETY: `ptr` is non-NULL and aligned, `len` elements fit in isize
    // (checked above), and the caller guarantees they are readable and not
    // written during the call.
    Ok(unsafe { std::slice::from_raw_parts(ptr, len) })
}

/// A caller's output array of `per * n` elements.
///
/// # Safety
/// A non-NULL `ptr` is valid for writing `per * n` elements of `T`, which no
/// other argument of the call overlaps (checked by [`disjoint`] for the
/// arrays of one call).
unsafe fn output<'a, T>(
    name: &str,
    ptr: *mut T,
    per: usize,
    n: usize,
) -> Result<&'a mut [T], Failure> {
    let len = per.checked_mul(n).ok_or_else(|| too_large(name, n))?;
    check_array(name, ptr.cast_const(), len, n)?;
    // SAFETY: as in `input`; the caller guarantees the elements are
    // writable, and `disjoint` has checked that no other array of the call
    // overlaps them, so this is the only reference to them. The library
    // only writes to an output (never reads it), so memory the C caller has
    // not initialized is fine.
    Ok(unsafe { std::slice::from_raw_parts_mut(ptr, len) })
}

fn too_large(name: &str, n: usize) -> Failure {
    Failure::invalid(format!(
        "n = {n} is too large: {name} would not fit in memory"
    ))
}

/// Reads a float array of `3 n` as `n` triples.
fn triples(v: &[f32]) -> &[[f32; 3]] {
    // `Vectors::from_flat` returns `None` only for a length that is not a
    // multiple of 3; ours are `3 n`.
    match Vectors::from_flat(v) {
        Some(Vectors::Aos(t)) => t,
        _ => &[],
    }
}

/// One array argument of a call, checked: name, start, bytes, whether the
/// call writes it.
type Span = (Cow<'static, str>, usize, usize, bool);

/// Checks an array of `per * n` elements of `T` for a call of `n` queries:
/// non-NULL (unless `optional`), aligned and addressable.
fn span<T>(
    name: &'static str,
    ptr: *const T,
    per: usize,
    n: usize,
    written: bool,
    optional: bool,
) -> Result<Span, Failure> {
    if optional && ptr.is_null() {
        return Ok((name.into(), 0, 0, written));
    }
    let len = match per.checked_mul(n) {
        Some(len) => len,
        None if ptr.is_null() => usize::MAX,
        None => return Err(too_large(name, n)),
    };
    check_array(name, ptr, len, n)?;
    Ok((name.into(), ptr as usize, len * size_of::<T>(), written))
}

/// Checks that no array the call writes overlaps another array of the call
/// (NULL arrays are skipped). Run before any slice is made of them.
fn disjoint(spans: &[Span]) -> Result<(), Failure> {
    for (i, a) in spans.iter().enumerate() {
        for b in &spans[i + 1..] {
            if !(a.3 || b.3) || a.1 == 0 || b.1 == 0 {
                continue;
            }
            if a.1 < b.1.saturating_add(b.2) && b.1 < a.1.saturating_add(a.2) {
                return Err(Failure::invalid(format!(
                    "{} and {} overlap: an output array must not share memory with another array",
                    a.0, b.0
                )));
            }
        }
    }
    Ok(())
}

/// A NUL-terminated UTF-8 argument.
///
/// # Safety
/// A non-NULL `s` points to a NUL-terminated string.
unsafe fn text<'a>(name: &str, s: *const c_char) -> Result<&'a str, Failure> {
    if s.is_null() {
        return Err(Failure::new(STRATA_ERR_NULL, format!("{name} is NULL")));
    }
    // SAFETY: `s` is non-NULL and the caller guarantees it is NUL-terminated
    // and not written during the call.
    let c = unsafe { CStr::from_ptr(s) };
    c.to_str().map_err(|e| {
        Failure::invalid(format!(
            "{name} is not UTF-8 (invalid byte at offset {})",
            e.valid_up_to()
        ))
    })
}

// ------------------------------------------------------------ construction

/// Checks a walk count argument: 1 to 2^40 (the library's `MAX_WALKS`), by
/// the library's own check, as an invalid-argument failure.
fn walk_count(argument: &'static str, n: u64) -> Result<(), Failure> {
    check_walks(argument, n).map_err(|e| Failure::invalid(e.to_string()))
}

/// Builds a BSDF over `stack` and stores it in `*out`.
///
/// # Safety
/// `out` is non-NULL and writable (checked NULL by the callers).
unsafe fn create(
    stack: Result<LayerStack, MaterialError>,
    samples: u64,
    seed: u64,
    out: *mut *mut StrataBsdf,
) -> Result<(), Failure> {
    walk_count("samples", samples)?;
    let inner = LayeredBsdf::new(stack?).samples(samples).seed(seed);
    let b = Box::into_raw(Box::new(StrataBsdf { inner }));
    // SAFETY: the caller has checked that `out` is non-NULL, and the C
    // caller guarantees it points to a writable `StrataBsdf *`.
    unsafe { out.write(b) };
    Ok(())
}

/// Clears `*out` (so that it is NULL on failure), or fails if `out` is NULL.
///
/// # Safety
/// A non-NULL `out` points to a writable `StrataBsdf *`.
unsafe fn clear_out(out: *mut *mut StrataBsdf) -> Result<(), Failure> {
    if out.is_null() {
        return Err(Failure::new(STRATA_ERR_NULL, "out is NULL"));
    }
    // SAFETY: `out` is non-NULL and the caller guarantees it is writable.
    unsafe { out.write(std::ptr::null_mut()) };
    Ok(())
}

/// Creates a BSDF from a material in TOML text (the format of
/// docs/materials.md), with `samples` walks per eval (1 to 2^40) and the
/// seed of every random stream. On success `*out` holds the BSDF (free it
/// with `strata_bsdf_free`); on failure `*out` is NULL and
/// `strata_last_error()` names the layer, the field and the value
/// (`STRATA_ERR_MATERIAL`).
///
/// # Safety
/// `toml` is NULL or a NUL-terminated string; `out` is NULL or points to a
/// writable `StrataBsdf *`.
#[no_mangle]
pub unsafe extern "C" fn strata_bsdf_from_toml(
    toml: *const c_char,
    samples: u64,
    seed: u64,
    out: *mut *mut StrataBsdf,
) -> i32 {
    guard("strata_bsdf_from_toml", || {
        // SAFETY: the caller's guarantees on `out` and `toml` are those of
        // `clear_out`, `text` and `create`.
        unsafe {
            clear_out(out)?;
            let s = text("toml", toml)?;
            create(LayerStack::from_toml_str(s), samples, seed, out)
        }
    })
}

/// Creates a BSDF from a material in JSON text (the same tree as the TOML
/// form); otherwise as `strata_bsdf_from_toml`.
///
/// # Safety
/// `json` is NULL or a NUL-terminated string; `out` is NULL or points to a
/// writable `StrataBsdf *`.
#[no_mangle]
pub unsafe extern "C" fn strata_bsdf_from_json(
    json: *const c_char,
    samples: u64,
    seed: u64,
    out: *mut *mut StrataBsdf,
) -> i32 {
    guard("strata_bsdf_from_json", || {
        // SAFETY: as in `strata_bsdf_from_toml`.
        unsafe {
            clear_out(out)?;
            let s = text("json", json)?;
            create(LayerStack::from_json_str(s), samples, seed, out)
        }
    })
}

/// Creates a BSDF from a material file: `.json` as JSON, anything else as
/// TOML. A file that cannot be read is `STRATA_ERR_IO`; otherwise as
/// `strata_bsdf_from_toml`.
///
/// # Safety
/// `path` is NULL or a NUL-terminated string; `out` is NULL or points to a
/// writable `StrataBsdf *`.
#[no_mangle]
pub unsafe extern "C" fn strata_bsdf_from_path(
    path: *const c_char,
    samples: u64,
    seed: u64,
    out: *mut *mut StrataBsdf,
) -> i32 {
    guard("strata_bsdf_from_path", || {
        // SAFETY: as in `strata_bsdf_from_toml`.
        unsafe {
            clear_out(out)?;
            let p = text("path", path)?;
            create(LayerStack::from_path(p), samples, seed, out)
        }
    })
}

/// Sets what flows from `wi` to `wo`: `STRATA_TRANSPORT_RADIANCE` (0, the
/// default) or `STRATA_TRANSPORT_IMPORTANCE` (1). It changes transmission
/// between exteriors of different IOR only. Configure a BSDF before sharing
/// it: this call must not run while another thread uses `b`.
///
/// # Safety
/// `b` is NULL or a live pointer from `strata_bsdf_from_*` that no other
/// thread uses during the call.
#[no_mangle]
pub unsafe extern "C" fn strata_bsdf_set_transport(b: *mut StrataBsdf, mode: u32) -> i32 {
    guard("strata_bsdf_set_transport", || {
        // SAFETY: the caller guarantees that a non-NULL `b` is live and not
        // used by another thread.
        let b = unsafe { bsdf_mut(b)? };
        let t = match mode {
            STRATA_TRANSPORT_RADIANCE => Transport::Radiance,
            STRATA_TRANSPORT_IMPORTANCE => Transport::Importance,
            _ => {
                return Err(Failure::invalid(format!(
                    "mode = {mode}: expected 0 (STRATA_TRANSPORT_RADIANCE) or 1 \
                     (STRATA_TRANSPORT_IMPORTANCE)"
                )))
            }
        };
        *b = b.clone().transport(t);
        Ok(())
    })
}

/// Chooses the estimator of eval: `STRATA_ESTIMATOR_AUTO` (0, the default:
/// a closed form where the stack has one, the bidirectional estimator on
/// stacks of three interfaces or more and rough coats over smooth or near-specular conductors (without optically thick scattering layers), the unidirectional one elsewhere),
/// `STRATA_ESTIMATOR_UNIDIRECTIONAL` (1) or `STRATA_ESTIMATOR_BIDIRECTIONAL`
/// (2). Configure a BSDF before sharing it: this call must not run while
/// another thread uses `b`.
///
/// # Safety
/// `b` is NULL or a live pointer from `strata_bsdf_from_*` that no other
/// thread uses during the call.
#[no_mangle]
pub unsafe extern "C" fn strata_bsdf_set_estimator(b: *mut StrataBsdf, estimator: u32) -> i32 {
    guard("strata_bsdf_set_estimator", || {
        // SAFETY: the caller guarantees that a non-NULL `b` is live and not
        // used by another thread.
        let b = unsafe { bsdf_mut(b)? };
        let e = match estimator {
            STRATA_ESTIMATOR_AUTO => Estimator::Auto,
            STRATA_ESTIMATOR_UNIDIRECTIONAL => Estimator::Unidirectional,
            STRATA_ESTIMATOR_BIDIRECTIONAL => Estimator::Bidirectional,
            _ => {
                return Err(Failure::invalid(format!(
                    "estimator = {estimator}: expected 0 (STRATA_ESTIMATOR_AUTO), 1 \
                     (STRATA_ESTIMATOR_UNIDIRECTIONAL) or 2 (STRATA_ESTIMATOR_BIDIRECTIONAL)"
                )))
            }
        };
        *b = b.clone().estimator(e);
        Ok(())
    })
}

/// Sets how many density walks each approximate pdf runs (the pdf that
/// `strata_pdf_batch` returns and that the samples carry):
/// `STRATA_PDF_SAMPLES_RULE` (0, the default) is the library's default, the
/// lobe pdf (no walks: a closed-form density for MIS); `n ≥ 1` is exactly
/// `n` density walks (docs/method.md §6 compares them;
/// `strata_bsdf_set_pdf_walks` sets an adaptive rule).
/// Every `n` is valid. (The Rust API's `pdf_samples(0)` is one walk; here 0
/// names the rule.)
/// Configure a BSDF before sharing it: this call must not run while another
/// thread uses `b`.
///
/// # Safety
/// `b` is NULL or a live pointer from `strata_bsdf_from_*` that no other
/// thread uses during the call.
#[no_mangle]
pub unsafe extern "C" fn strata_bsdf_set_pdf_samples(b: *mut StrataBsdf, n: u32) -> i32 {
    guard("strata_bsdf_set_pdf_samples", || {
        // SAFETY: the caller guarantees that a non-NULL `b` is live and not
        // used by another thread.
        let b = unsafe { bsdf_mut(b)? };
        let walks = match n {
            STRATA_PDF_SAMPLES_RULE => PdfWalks::DEFAULT,
            n => PdfWalks::fixed(u64::from(n)),
        };
        *b = b.clone().pdf_walks(walks);
        Ok(())
    })
}

/// Sets the limit of events (interface events and collisions) per walk,
/// from 1 to 2^24: a walk that reaches it ends there. The default, 2^20, is
/// more than five times the longest walk of the library's stress suite
/// and bounds the time of a walk on any stack; a bidirectional
/// walk's subpaths end at its square root. Any other `n` is
/// `STRATA_ERR_INVALID_ARGUMENT`, naming it, and leaves the BSDF as it was.
/// Configure a BSDF before sharing it: this call must not run while another
/// thread uses `b`.
///
/// # Safety
/// `b` is NULL or a live pointer from `strata_bsdf_from_*` that no other
/// thread uses during the call.
#[no_mangle]
pub unsafe extern "C" fn strata_bsdf_set_max_events(b: *mut StrataBsdf, n: u32) -> i32 {
    guard("strata_bsdf_set_max_events", || {
        // SAFETY: the caller guarantees that a non-NULL `b` is live and not
        // used by another thread.
        let b = unsafe { bsdf_mut(b)? };
        let limit = strata_bsdf::estimator::events::MAX_CAP;
        if !(1..=limit).contains(&n) {
            return Err(Failure::invalid(format!(
                "n = {n}: the limit of events per walk is from 1 to {limit}"
            )));
        }
        *b = b.clone().max_events(n);
        Ok(())
    })
}

/// Sets an adaptive rule for the approximate pdf's density walks (the pdf
/// that `strata_pdf_batch` returns and that the samples carry): a pilot of
/// `pilot` walks (at least 2) measures one walk's relative variance, then
/// `pilot` to `max` fresh walks run for a relative standard error of about
/// `rel_stderr` (a positive number), as the Rust API's `PdfWalks::adaptive`.
/// The library's default is (8, 64, 0.15); (8, 128, 0.1), its `TIGHT` rule,
/// gives a pdf within 0.7–1.3× of the density of the samples at nearly
/// every direction for about twice the walks (docs/method.md §6). A pilot
/// under 2, a `max` under `pilot`, or a `rel_stderr` that is not a positive
/// finite number is `STRATA_ERR_INVALID_ARGUMENT`, naming the argument and its
/// value, and leaves the BSDF as it was. Configure a BSDF before sharing
/// it: this call must not run while another thread uses `b`.
///
/// # Safety
/// `b` is NULL or a live pointer from `strata_bsdf_from_*` that no other
/// thread uses during the call.
#[no_mangle]
pub unsafe extern "C" fn strata_bsdf_set_pdf_walks(
    b: *mut StrataBsdf,
    pilot: u32,
    max: u32,
    rel_stderr: f64,
) -> i32 {
    guard("strata_bsdf_set_pdf_walks", || {
        // SAFETY: the caller guarantees that a non-NULL `b` is live and not
        // used by another thread.
        let b = unsafe { bsdf_mut(b)? };
        let walks = PdfWalks::try_adaptive(u64::from(pilot), u64::from(max), rel_stderr)
            .map_err(Failure::invalid)?;
        *b = b.clone().pdf_walks(walks);
        Ok(())
    })
}

/// Runs the BSDF's large batches on a pool of `threads` threads of its own
/// (0: one per core; at most 1024). By default they run on a pool shared by
/// every BSDF of the process, one thread per core. Calls of a few walks
/// (n = 1 samples, small evals) run on the calling thread whatever the pool,
/// and `threads = 1` builds no pool: every batch runs on the calling thread,
/// allocation-free once that thread is warm; results never depend on it. A large batch runs on the pool while its
/// caller waits, so a pool of its own bounds how many cores a BSDF's batches
/// use; calls from several threads share it. Configure a BSDF before sharing
/// it: this call must not run while another thread uses `b`. Safe across
/// `fork()`: in a forked child, the batches that ran on a pool in the parent
/// (its own or the default one) run on a pool of the same size built for the
/// child, with the parent's results.
///
/// # Safety
/// `b` is NULL or a live pointer from `strata_bsdf_from_*` that no other
/// thread uses during the call.
#[no_mangle]
pub unsafe extern "C" fn strata_bsdf_set_threads(b: *mut StrataBsdf, threads: usize) -> i32 {
    guard("strata_bsdf_set_threads", || {
        // SAFETY: the caller guarantees that a non-NULL `b` is live and not
        // used by another thread.
        let b = unsafe { bsdf_mut(b)? };
        *b = b
            .clone()
            .threads(threads)
            .map_err(|e| Failure::invalid(e.to_string()))?;
        Ok(())
    })
}

/// Writes what the stack is to `*out` (see `StrataStackInfo`).
///
/// # Safety
/// `b` is NULL or live; `out` is NULL or points to a writable
/// `StrataStackInfo`.
#[no_mangle]
pub unsafe extern "C" fn strata_bsdf_info(b: *const StrataBsdf, out: *mut StrataStackInfo) -> i32 {
    guard("strata_bsdf_info", || {
        // SAFETY: the caller guarantees `b` is NULL or live.
        let stack = unsafe { bsdf_ref(b)? }.stack();
        if out.is_null() {
            return Err(Failure::new(STRATA_ERR_NULL, "out is NULL"));
        }
        let info = StrataStackInfo {
            ior_above: stack.exterior_above() as f32,
            ior_below: stack.exterior_below() as f32,
            transmissive: stack.transmissive() as u32,
            two_sided: stack.two_sided() as u32,
        };
        // SAFETY: `out` is non-NULL and the caller guarantees it is writable.
        unsafe { out.write(info) };
        Ok(())
    })
}

/// Writes to `*out` whether the BSDF answers sample and pdf without walks
/// (1) or with them (0): under `STRATA_ESTIMATOR_AUTO`, a smooth or rough
/// (isotropic) coat over a clear or absorbing layer over a Lambertian base
/// (untilted normals, an absorber whose extinction does not depend on the
/// direction, no depth cap). Then sample draws from a known density with
/// bounded weights, and `strata_pdf_batch` returns that exact density
/// (elsewhere an approximation). Eval is then answered without walks too
/// (`strata_bsdf_eval_without_walks`), exactly (standard error 0) under a
/// smooth coat.
///
/// # Safety
/// `b` is NULL or live; `out` is NULL or points to a writable `uint32_t`.
#[no_mangle]
pub unsafe extern "C" fn strata_bsdf_is_exact(b: *const StrataBsdf, out: *mut u32) -> i32 {
    guard("strata_bsdf_is_exact", || {
        // SAFETY: the caller guarantees `b` is NULL or live.
        let exact = unsafe { bsdf_ref(b)? }.sample_is_exact();
        if out.is_null() {
            return Err(Failure::new(STRATA_ERR_NULL, "out is NULL"));
        }
        // SAFETY: `out` is non-NULL and the caller guarantees it is writable.
        unsafe { out.write(exact as u32) };
        Ok(())
    })
}

/// Writes to `*out` whether the BSDF answers eval without walks (1) or with
/// them (0): under `STRATA_ESTIMATOR_AUTO`, a smooth coat over a clear or
/// absorbing layer over a Lambertian base (its closed form:
/// `strata_bsdf_is_exact`) or a rough, isotropic one (its factorization:
/// the coat's reflection plus samples of the light entering from `wi` and
/// from `wo` times a constant of the stack, integrated once, by the first
/// eval that needs it); untilted normals, no depth cap. The samples
/// per eval are then those draws, each much cheaper than a walk.
///
/// # Safety
/// `b` is NULL or live; `out` is NULL or points to a writable `uint32_t`.
#[no_mangle]
pub unsafe extern "C" fn strata_bsdf_eval_without_walks(
    b: *const StrataBsdf,
    out: *mut u32,
) -> i32 {
    guard("strata_bsdf_eval_without_walks", || {
        // SAFETY: the caller guarantees `b` is NULL or live.
        let without = unsafe { bsdf_ref(b)? }.eval_without_walks();
        if out.is_null() {
            return Err(Failure::new(STRATA_ERR_NULL, "out is NULL"));
        }
        // SAFETY: `out` is non-NULL and the caller guarantees it is writable.
        unsafe { out.write(without as u32) };
        Ok(())
    })
}

/// Frees a BSDF. NULL is a no-op.
///
/// # Safety
/// `b` is NULL or a pointer from `strata_bsdf_from_*` not yet freed, that no
/// other thread uses during or after the call.
#[no_mangle]
pub unsafe extern "C" fn strata_bsdf_free(b: *mut StrataBsdf) {
    if b.is_null() {
        return;
    }
    let _ = catch_unwind(AssertUnwindSafe(|| {
        // SAFETY: `b` came from `Box::into_raw` in `create` and the caller
        // guarantees it is freed once and not used afterwards.
        drop(unsafe { Box::from_raw(b) });
    }));
}

// ---------------------------------------------------- per-query parameters

/// The column arguments of a batch call: `ncolumns` columns at `columns`
/// (none for the plain calls).
#[derive(Clone, Copy)]
struct ColumnArgs {
    columns: *const StrataColumn,
    ncolumns: usize,
}

/// No columns: the BSDF's own parameters.
const OWN: ColumnArgs = ColumnArgs {
    columns: std::ptr::null(),
    ncolumns: 0,
};

/// A call's columns, checked: their paths parsed, their values as slices.
struct Columns<'a> {
    paths: Vec<SetPath>,
    widths: Vec<usize>,
    values: Vec<&'a [f32]>,
    /// The columns array and every column's values: inputs of the call.
    spans: Vec<Span>,
}

/// Reads and checks the columns of a call of `n` queries (n > 0): the array
/// not NULL (if `ncolumns` > 0), each column's path not NULL, UTF-8 and a
/// settable path, its width 1 or 3 and its values not NULL, aligned and
/// addressable. The rows' values are checked by [`Columns::target`].
///
/// # Safety
/// A non-NULL `columns` points to `ncolumns` readable `StrataColumn`s whose
/// non-NULL `path`s are NUL-terminated and whose non-NULL `values` hold
/// `width × n` floats, none of them written during the call.
unsafe fn read_columns<'a>(args: ColumnArgs, n: usize) -> Result<Columns<'a>, Failure> {
    let ColumnArgs { columns, ncolumns } = args;
    let mut cols = Columns {
        paths: Vec::new(),
        widths: Vec::new(),
        values: Vec::new(),
        spans: Vec::new(),
    };
    if ncolumns == 0 {
        return Ok(cols);
    }
    if columns.is_null() {
        return Err(Failure::new(
            STRATA_ERR_NULL,
            format!("columns is NULL (ncolumns = {ncolumns})"),
        ));
    }
    cols.spans
        .push(span("columns", columns, 1, ncolumns, false, false)?);
    // SAFETY: `columns` is non-NULL, aligned and addressable (checked by
    // `span`), and the caller guarantees `ncolumns` columns are readable.
    let array = unsafe { input("columns", columns, 1, ncolumns)? };
    for (i, c) in array.iter().enumerate() {
        let name = format!("columns[{i}]");
        if c.path.is_null() {
            return Err(Failure::new(
                STRATA_ERR_NULL,
                format!("{name}.path is NULL"),
            ));
        }
        // SAFETY: `c.path` is non-NULL and the caller guarantees it is
        // NUL-terminated and not written during the call.
        let path = unsafe { text(&format!("{name}.path"), c.path)? };
        let path: SetPath = path
            .parse()
            .map_err(|e: SetError| Failure::invalid(format!("{name}: {e}")))?;
        if c.width != 1 && c.width != 3 {
            return Err(Failure::invalid(format!(
                "{name}.width = {} (`{path}`): expected 1 (a number per query) or 3 \
                 (an RGB triple or a normal per query)",
                c.width
            )));
        }
        let values = format!("{name}.values");
        let len = c
            .width
            .checked_mul(n)
            .ok_or_else(|| too_large(&values, n))?;
        let start = c.values as usize;
        check_array(&values, c.values, len, n)?;
        cols.spans
            .push((values.into(), start, len * size_of::<f32>(), false));
        // SAFETY: `c.values` is non-NULL, aligned and `width × n` floats fit
        // in isize (checked above); the caller guarantees they are readable
        // and not written during the call.
        cols.values
            .push(unsafe { std::slice::from_raw_parts(c.values, len) });
        cols.paths.push(path);
        cols.widths.push(c.width);
    }
    Ok(cols)
}

impl Columns<'_> {
    /// Checks that no output of the call (in `spans`) overlaps another array
    /// of it, the columns' values included.
    fn disjoint(&self, mut spans: Vec<Span>) -> Result<(), Failure> {
        spans.extend(self.spans.iter().cloned());
        disjoint(&spans)
    }

    /// What the call's `n` queries run on: `bsdf` itself without columns,
    /// else one material per query (every row checked first: the error
    /// names the query, the path and the value).
    fn target<'b>(&'b self, bsdf: &'b LayeredBsdf, n: usize) -> Result<Target<'b>, Failure> {
        if self.paths.is_empty() {
            return Ok(Target::Own(bsdf));
        }
        let columns: Vec<Column> = (self.paths.iter().zip(&self.widths).zip(&self.values))
            .map(|((path, &width), values)| Column {
                path,
                width,
                values,
            })
            .collect();
        match PerQuery::new(bsdf, n, &columns) {
            Ok(m) => Ok(Target::PerQuery(m)),
            // A fault of the whole column (its path, its width): named as
            // the argument it is.
            Err(ColumnsError::Column { column, error }) => {
                let c = &columns[column];
                Err(Failure::invalid(format!(
                    "columns[{column}] (`{}`, width {}): {error}",
                    c.path, c.width
                )))
            }
            Err(e) => {
                let code = match &e {
                    ColumnsError::Query {
                        error: SetError::Invalid { .. },
                        ..
                    } => STRATA_ERR_MATERIAL,
                    ColumnsError::OutOfMemory { .. } => STRATA_ERR_OUT_OF_MEMORY,
                    _ => STRATA_ERR_INVALID_ARGUMENT,
                };
                Err(Failure::new(code, format!("columns: {e}")))
            }
        }
    }
}

/// What a batch runs on.
enum Target<'a> {
    /// The BSDF's own parameters: its slice calls.
    Own(&'a LayeredBsdf),
    /// One material per query (query `k` on material `k`), with the BSDF's
    /// configuration, built a bounded chunk at a time.
    PerQuery(PerQuery<'a>),
}

/// Where samples go.
enum SampleOut<'a> {
    /// One record per query.
    Records(&'a mut [SampleRecord]),
    /// Component arrays.
    Soa {
        wo: VectorsMut<'a>,
        weight: VectorsMut<'a>,
        pdf: &'a mut [f32],
        flags: &'a mut [u32],
    },
}

// Both kinds of target run the library's slice calls: the BSDF's own, or
// `PerQuery`'s with query `k` on its own row (keyed and indexed as the own
// ones are, so that query `k` answers what a BSDF of its material does).
impl Target<'_> {
    fn eval(
        &self,
        wi: Vectors,
        wo: Vectors,
        keys: Option<&[u64]>,
        f: VectorsMut,
        se: Option<VectorsMut>,
    ) -> Result<(), Failure> {
        Ok((match self {
            Target::Own(b) => b.eval_into(wi, wo, keys, f, se),
            Target::PerQuery(m) => m.eval_into(wi, wo, keys, f, se),
        })?)
    }

    fn sample(&self, wi: Vectors, keys: Option<&[u64]>, out: SampleOut) -> Result<(), Failure> {
        Ok((match (self, out) {
            (Target::Own(b), SampleOut::Records(out)) => b.sample_records(wi, keys, out),
            (Target::PerQuery(m), SampleOut::Records(out)) => m.sample_records(wi, keys, out),
            (
                Target::Own(b),
                SampleOut::Soa {
                    wo,
                    weight,
                    pdf,
                    flags,
                },
            ) => b.sample_into(wi, keys, wo, weight, pdf, flags),
            (
                Target::PerQuery(m),
                SampleOut::Soa {
                    wo,
                    weight,
                    pdf,
                    flags,
                },
            ) => m.sample_into(wi, keys, wo, weight, pdf, flags),
        })?)
    }

    fn pdf(&self, wi: Vectors, wo: Vectors, pdf: &mut [f32]) -> Result<(), Failure> {
        Ok((match self {
            Target::Own(b) => b.pdf_into(wi, wo, pdf),
            Target::PerQuery(m) => m.pdf_into(wi, wo, pdf),
        })?)
    }

    fn pdf_unbiased(
        &self,
        wi: Vectors,
        wo: Vectors,
        walks: u64,
        pdf: &mut [f32],
        stderr: &mut [f32],
    ) -> Result<(), Failure> {
        Ok((match self {
            Target::Own(b) => b.pdf_unbiased_into(wi, wo, walks, pdf, stderr),
            Target::PerQuery(m) => m.pdf_unbiased_into(wi, wo, walks, pdf, stderr),
        })?)
    }

    fn albedo(
        &self,
        wi: Vectors,
        walks: u64,
        keys: Option<&[u64]>,
        out: &mut [AlbedoRecord],
    ) -> Result<(), Failure> {
        Ok((match self {
            Target::Own(b) => b.albedo_records(wi, walks, keys, out),
            Target::PerQuery(m) => m.albedo_records(wi, walks, keys, out),
        })?)
    }
}

// ------------------------------------------------------------------- batches
//
// Each batch call has one body, `*_body`, that checks the arguments, makes
// slices of them and runs the batch on a `Target`: the BSDF's own parameters
// (the plain entry points, `OWN` columns) or one material per query built
// from the caller's columns (the `*_columns` entry points).

/// Evaluates `f(wi[k], wo[k])` (without the cosine, no delta lobes) for `n`
/// queries with the BSDF's walk count, keyed by the directions' bits (the
/// same pair always gives the same estimate). `wi`, `wo`: `3 n` floats,
/// `x, y, z` per query, in the local frame (z = normal), both pointing away
/// from the surface; normalized on input. Writes `3 n` floats `r, g, b` to
/// `f_out` and, if `stderr_out` is not NULL, the standard errors to
/// `stderr_out`. n = 0 does nothing. On an error nothing is written and the
/// message names the query index and the argument (`"query 3: wi = [NaN, 0,
/// 1] is not a direction: components must be finite"`).
///
/// # Safety
/// Each non-NULL array holds at least `3 n` floats; output arrays do not
/// overlap each other or the inputs (checked); `b` is NULL or live.
#[no_mangle]
pub unsafe extern "C" fn strata_eval_batch(
    b: *const StrataBsdf,
    n: usize,
    wi: *const f32,
    wo: *const f32,
    f_out: *mut f32,
    stderr_out: *mut f32,
) -> i32 {
    guard("strata_eval_batch", || {
        // SAFETY: the caller's guarantees are those of `eval_aos`.
        unsafe { eval_aos(b, n, wi, wo, None, OWN, f_out, stderr_out) }
    })
}

/// `strata_eval_batch` with a key per query (`keys`: `n` values, not NULL):
/// query `k` draws its walks from the stream `(seed, keys[k])`, so a renderer
/// passes fresh keys for fresh noise. (The unkeyed call keys each query by
/// its directions' bits, as `strata eval` does.)
///
/// # Safety
/// As `strata_eval_batch`; a non-NULL `keys` holds at least `n` values.
#[no_mangle]
pub unsafe extern "C" fn strata_eval_batch_keyed(
    b: *const StrataBsdf,
    n: usize,
    wi: *const f32,
    wo: *const f32,
    keys: *const u64,
    f_out: *mut f32,
    stderr_out: *mut f32,
) -> i32 {
    guard("strata_eval_batch_keyed", || {
        // SAFETY: the caller's guarantees are those of `eval_aos`.
        unsafe { eval_aos(b, n, wi, wo, Some(keys), OWN, f_out, stderr_out) }
    })
}

/// `strata_eval_batch` with per-query parameters: query `k` is evaluated on
/// the BSDF's material with row `k` of every column set (see
/// `StrataColumn`), and answers bit for bit what a BSDF made from a material
/// file with those values answers. `ncolumns` = 0 is `strata_eval_batch`
/// (and `columns` may then be NULL); n = 0 does nothing. If any column or any
/// query's values are invalid nothing runs and nothing is written: the
/// status is `STRATA_ERR_MATERIAL` (the values make an invalid material),
/// `STRATA_ERR_NULL` or `STRATA_ERR_INVALID_ARGUMENT`, and
/// `strata_last_error()` names the column or the query, the path and the
/// value (see `StrataColumn`). The columns' values must not overlap an
/// output (checked).
///
/// # Safety
/// As `strata_eval_batch`; a non-NULL `columns` holds `ncolumns` columns,
/// each with a NUL-terminated `path` and `width × n` `values` that nothing
/// writes during the call.
#[no_mangle]
pub unsafe extern "C" fn strata_eval_batch_columns(
    b: *const StrataBsdf,
    n: usize,
    wi: *const f32,
    wo: *const f32,
    columns: *const StrataColumn,
    ncolumns: usize,
    f_out: *mut f32,
    stderr_out: *mut f32,
) -> i32 {
    guard("strata_eval_batch_columns", || {
        let cols = ColumnArgs { columns, ncolumns };
        // SAFETY: the caller's guarantees are those of `eval_aos`.
        unsafe { eval_aos(b, n, wi, wo, None, cols, f_out, stderr_out) }
    })
}

/// `strata_eval_batch_keyed` with per-query parameters, as
/// `strata_eval_batch_columns`.
///
/// # Safety
/// As `strata_eval_batch_keyed` and `strata_eval_batch_columns`.
#[no_mangle]
pub unsafe extern "C" fn strata_eval_batch_keyed_columns(
    b: *const StrataBsdf,
    n: usize,
    wi: *const f32,
    wo: *const f32,
    keys: *const u64,
    columns: *const StrataColumn,
    ncolumns: usize,
    f_out: *mut f32,
    stderr_out: *mut f32,
) -> i32 {
    guard("strata_eval_batch_keyed_columns", || {
        let cols = ColumnArgs { columns, ncolumns };
        // SAFETY: the caller's guarantees are those of `eval_aos`.
        unsafe { eval_aos(b, n, wi, wo, Some(keys), cols, f_out, stderr_out) }
    })
}

/// The body of the AoS evals (`keys`: `None` unkeyed, `Some` keyed, which
/// must not be NULL).
///
/// # Safety
/// As `strata_eval_batch_keyed_columns`.
#[allow(clippy::too_many_arguments)]
unsafe fn eval_aos(
    b: *const StrataBsdf,
    n: usize,
    wi: *const f32,
    wo: *const f32,
    keys: Option<*const u64>,
    cols: ColumnArgs,
    f_out: *mut f32,
    stderr_out: *mut f32,
) -> Result<(), Failure> {
    // SAFETY: the caller guarantees `b` is NULL or live.
    let bsdf = unsafe { bsdf_ref(b)? };
    if n == 0 {
        return Ok(());
    }
    if keys.is_some_and(|k| k.is_null()) {
        return Err(Failure::new(
            STRATA_ERR_NULL,
            format!("keys is NULL (n = {n}): use strata_eval_batch for unkeyed queries"),
        ));
    }
    // SAFETY: the caller's guarantees on the columns are `read_columns`'.
    let cols = unsafe { read_columns(cols, n)? };
    cols.disjoint(vec![
        span("wi", wi, 3, n, false, false)?,
        span("wo", wo, 3, n, false, false)?,
        span("keys", keys.unwrap_or(std::ptr::null()), 1, n, false, true)?,
        span("f_out", f_out, 3, n, true, false)?,
        span("stderr_out", stderr_out, 3, n, true, true)?,
    ])?;
    let target = cols.target(bsdf, n)?;
    // SAFETY: the caller guarantees each non-NULL array holds 3 n floats
    // (n keys) and that inputs are not written during the call; the outputs
    // were checked disjoint from every other array (and column) above.
    let (wi, wo, keys, f, se) = unsafe {
        (
            input("wi", wi, 3, n)?,
            input("wo", wo, 3, n)?,
            keys.map(|k| input("keys", k, 1, n)).transpose()?,
            output("f_out", f_out, 3, n)?,
            if stderr_out.is_null() {
                None
            } else {
                Some(output("stderr_out", stderr_out, 3, n)?)
            },
        )
    };
    let f = VectorsMut::Aos(triples_mut(f));
    let se = se.map(|s| VectorsMut::Aos(triples_mut(s)));
    target.eval(
        Vectors::Aos(triples(wi)),
        Vectors::Aos(triples(wo)),
        keys,
        f,
        se,
    )
}

/// Writes to a float array of `3 n` as `n` triples.
fn triples_mut(v: &mut [f32]) -> &mut [[f32; 3]] {
    match VectorsMut::from_flat(v) {
        Some(VectorsMut::Aos(t)) => t,
        _ => &mut [],
    }
}

/// `strata_eval_batch` over component arrays (structure of arrays): `n`
/// floats each of `wi_x, wi_y, wi_z, wo_x, wo_y, wo_z`, results to `f_r,
/// f_g, f_b` and, unless all three are NULL, the standard errors to `se_r,
/// se_g, se_b`. `keys` is NULL (unkeyed: the same numbers as
/// `strata_eval_batch`) or `n` keys (as `strata_eval_batch_keyed`).
///
/// # Safety
/// Each non-NULL array holds at least `n` elements; output arrays do not
/// overlap each other or the inputs (checked); `b` is NULL or live.
#[no_mangle]
pub unsafe extern "C" fn strata_eval_batch_soa(
    b: *const StrataBsdf,
    n: usize,
    wi_x: *const f32,
    wi_y: *const f32,
    wi_z: *const f32,
    wo_x: *const f32,
    wo_y: *const f32,
    wo_z: *const f32,
    keys: *const u64,
    f_r: *mut f32,
    f_g: *mut f32,
    f_b: *mut f32,
    se_r: *mut f32,
    se_g: *mut f32,
    se_b: *mut f32,
) -> i32 {
    guard("strata_eval_batch_soa", || {
        let (wi, wo, f, se) = (
            [wi_x, wi_y, wi_z],
            [wo_x, wo_y, wo_z],
            [f_r, f_g, f_b],
            [se_r, se_g, se_b],
        );
        // SAFETY: the caller's guarantees are those of `eval_soa`.
        unsafe { eval_soa(b, n, wi, wo, keys, OWN, f, se) }
    })
}

/// `strata_eval_batch_soa` with per-query parameters, as
/// `strata_eval_batch_columns`.
///
/// # Safety
/// As `strata_eval_batch_soa` and `strata_eval_batch_columns`.
#[no_mangle]
pub unsafe extern "C" fn strata_eval_batch_soa_columns(
    b: *const StrataBsdf,
    n: usize,
    wi_x: *const f32,
    wi_y: *const f32,
    wi_z: *const f32,
    wo_x: *const f32,
    wo_y: *const f32,
    wo_z: *const f32,
    keys: *const u64,
    columns: *const StrataColumn,
    ncolumns: usize,
    f_r: *mut f32,
    f_g: *mut f32,
    f_b: *mut f32,
    se_r: *mut f32,
    se_g: *mut f32,
    se_b: *mut f32,
) -> i32 {
    guard("strata_eval_batch_soa_columns", || {
        let (wi, wo, f, se) = (
            [wi_x, wi_y, wi_z],
            [wo_x, wo_y, wo_z],
            [f_r, f_g, f_b],
            [se_r, se_g, se_b],
        );
        let cols = ColumnArgs { columns, ncolumns };
        // SAFETY: the caller's guarantees are those of `eval_soa`.
        unsafe { eval_soa(b, n, wi, wo, keys, cols, f, se) }
    })
}

/// The body of the SoA evals.
///
/// # Safety
/// As `strata_eval_batch_soa_columns`.
#[allow(clippy::too_many_arguments)]
unsafe fn eval_soa(
    b: *const StrataBsdf,
    n: usize,
    [wi_x, wi_y, wi_z]: [*const f32; 3],
    [wo_x, wo_y, wo_z]: [*const f32; 3],
    keys: *const u64,
    cols: ColumnArgs,
    [f_r, f_g, f_b]: [*mut f32; 3],
    [se_r, se_g, se_b]: [*mut f32; 3],
) -> Result<(), Failure> {
    // SAFETY: the caller guarantees `b` is NULL or live.
    let bsdf = unsafe { bsdf_ref(b)? };
    if n == 0 {
        return Ok(());
    }
    let with_stderr = match [se_r, se_g, se_b].map(|p| p.is_null()) {
        [true, true, true] => false,
        [false, false, false] => true,
        nulls => {
            let names = ["se_r", "se_g", "se_b"];
            let null = (0..3).find(|&i| nulls[i]).unwrap_or(0);
            let given = (0..3).find(|&i| !nulls[i]).unwrap_or(0);
            return Err(Failure::new(
                STRATA_ERR_NULL,
                format!(
                    "{} is NULL but {} is not (n = {n}): pass all three or none",
                    names[null], names[given]
                ),
            ));
        }
    };
    // SAFETY: the caller's guarantees on the columns are `read_columns`'.
    let cols = unsafe { read_columns(cols, n)? };
    cols.disjoint(vec![
        span("wi_x", wi_x, 1, n, false, false)?,
        span("wi_y", wi_y, 1, n, false, false)?,
        span("wi_z", wi_z, 1, n, false, false)?,
        span("wo_x", wo_x, 1, n, false, false)?,
        span("wo_y", wo_y, 1, n, false, false)?,
        span("wo_z", wo_z, 1, n, false, false)?,
        span("keys", keys, 1, n, false, true)?,
        span("f_r", f_r, 1, n, true, false)?,
        span("f_g", f_g, 1, n, true, false)?,
        span("f_b", f_b, 1, n, true, false)?,
        span("se_r", se_r, 1, n, true, true)?,
        span("se_g", se_g, 1, n, true, true)?,
        span("se_b", se_b, 1, n, true, true)?,
    ])?;
    let target = cols.target(bsdf, n)?;
    // SAFETY: the caller guarantees each non-NULL array holds n elements and
    // that inputs are not written during the call; the outputs were checked
    // disjoint from every other array (and column) above.
    unsafe {
        let wi = [
            input("wi_x", wi_x, 1, n)?,
            input("wi_y", wi_y, 1, n)?,
            input("wi_z", wi_z, 1, n)?,
        ];
        let wo = [
            input("wo_x", wo_x, 1, n)?,
            input("wo_y", wo_y, 1, n)?,
            input("wo_z", wo_z, 1, n)?,
        ];
        let keys = if keys.is_null() {
            None
        } else {
            Some(input("keys", keys, 1, n)?)
        };
        let f = [
            output("f_r", f_r, 1, n)?,
            output("f_g", f_g, 1, n)?,
            output("f_b", f_b, 1, n)?,
        ];
        let se = if with_stderr {
            Some(VectorsMut::Soa([
                output("se_r", se_r, 1, n)?,
                output("se_g", se_g, 1, n)?,
                output("se_b", se_b, 1, n)?,
            ]))
        } else {
            None
        };
        target.eval(
            Vectors::Soa(wi),
            Vectors::Soa(wo),
            keys,
            VectorsMut::Soa(f),
            se,
        )
    }
}

/// Samples one outgoing direction per incident direction `wi[k]` (`3 n`
/// floats), into `out[k]`. `keys` NULL: query `k` is keyed by its
/// direction's bits and draws sample index `k` (as line `k` of `strata
/// sample` does); otherwise `n` keys, query `k` drawing from `(seed,
/// keys[k])`. Each sample carries the pdf `strata_pdf_batch` gives for its
/// direction. n = 0 does nothing.
///
/// # Safety
/// `wi` holds at least `3 n` floats, `keys` (if not NULL) `n` values, `out`
/// `n` records; `out` does not overlap the inputs (checked); `b` is NULL or
/// live.
#[no_mangle]
pub unsafe extern "C" fn strata_sample_batch(
    b: *const StrataBsdf,
    n: usize,
    wi: *const f32,
    keys: *const u64,
    out: *mut StrataSample,
) -> i32 {
    guard("strata_sample_batch", || {
        // SAFETY: the caller's guarantees are those of `sample_aos`.
        unsafe { sample_aos(b, n, wi, keys, OWN, out) }
    })
}

/// `strata_sample_batch` with per-query parameters, as
/// `strata_eval_batch_columns`: query `k` samples the material with row `k`
/// of every column, from the same stream as the plain call.
///
/// # Safety
/// As `strata_sample_batch` and `strata_eval_batch_columns`.
#[no_mangle]
pub unsafe extern "C" fn strata_sample_batch_columns(
    b: *const StrataBsdf,
    n: usize,
    wi: *const f32,
    keys: *const u64,
    columns: *const StrataColumn,
    ncolumns: usize,
    out: *mut StrataSample,
) -> i32 {
    guard("strata_sample_batch_columns", || {
        let cols = ColumnArgs { columns, ncolumns };
        // SAFETY: the caller's guarantees are those of `sample_aos`.
        unsafe { sample_aos(b, n, wi, keys, cols, out) }
    })
}

/// The body of the AoS samples.
///
/// # Safety
/// As `strata_sample_batch_columns`.
unsafe fn sample_aos(
    b: *const StrataBsdf,
    n: usize,
    wi: *const f32,
    keys: *const u64,
    cols: ColumnArgs,
    out: *mut StrataSample,
) -> Result<(), Failure> {
    // SAFETY: the caller guarantees `b` is NULL or live.
    let bsdf = unsafe { bsdf_ref(b)? };
    if n == 0 {
        return Ok(());
    }
    // SAFETY: the caller's guarantees on the columns are `read_columns`'.
    let cols = unsafe { read_columns(cols, n)? };
    cols.disjoint(vec![
        span("wi", wi, 3, n, false, false)?,
        span("keys", keys, 1, n, false, true)?,
        span("out", out, 1, n, true, false)?,
    ])?;
    let target = cols.target(bsdf, n)?;
    // SAFETY: the caller guarantees the arrays' lengths and that inputs are
    // not written during the call; `out` was checked disjoint from them.
    // `StrataSample` has the layout of `SampleRecord` (asserted at compile
    // time), so `out`'s records may be written as those.
    unsafe {
        let wi = input("wi", wi, 3, n)?;
        let keys = if keys.is_null() {
            None
        } else {
            Some(input("keys", keys, 1, n)?)
        };
        let out = output("out", out.cast::<SampleRecord>(), 1, n)?;
        target.sample(Vectors::Aos(triples(wi)), keys, SampleOut::Records(out))
    }
}

/// `strata_sample_batch` over component arrays: `n` floats each of `wi_x,
/// wi_y, wi_z`; results to `wo_x, wo_y, wo_z`, `weight_r, weight_g,
/// weight_b`, `pdf` and `flags` (`STRATA_SAMPLE_*` bits; an absorbed walk
/// writes zeros everywhere). The same numbers as `strata_sample_batch`.
///
/// # Safety
/// Each non-NULL array holds at least `n` elements; output arrays do not
/// overlap each other or the inputs (checked); `b` is NULL or live.
#[no_mangle]
pub unsafe extern "C" fn strata_sample_batch_soa(
    b: *const StrataBsdf,
    n: usize,
    wi_x: *const f32,
    wi_y: *const f32,
    wi_z: *const f32,
    keys: *const u64,
    wo_x: *mut f32,
    wo_y: *mut f32,
    wo_z: *mut f32,
    weight_r: *mut f32,
    weight_g: *mut f32,
    weight_b: *mut f32,
    pdf: *mut f32,
    flags: *mut u32,
) -> i32 {
    guard("strata_sample_batch_soa", || {
        let (wi, wo, w) = (
            [wi_x, wi_y, wi_z],
            [wo_x, wo_y, wo_z],
            [weight_r, weight_g, weight_b],
        );
        // SAFETY: the caller's guarantees are those of `sample_soa`.
        unsafe { sample_soa(b, n, wi, keys, OWN, wo, w, pdf, flags) }
    })
}

/// `strata_sample_batch_soa` with per-query parameters, as
/// `strata_sample_batch_columns`.
///
/// # Safety
/// As `strata_sample_batch_soa` and `strata_eval_batch_columns`.
#[no_mangle]
pub unsafe extern "C" fn strata_sample_batch_soa_columns(
    b: *const StrataBsdf,
    n: usize,
    wi_x: *const f32,
    wi_y: *const f32,
    wi_z: *const f32,
    keys: *const u64,
    columns: *const StrataColumn,
    ncolumns: usize,
    wo_x: *mut f32,
    wo_y: *mut f32,
    wo_z: *mut f32,
    weight_r: *mut f32,
    weight_g: *mut f32,
    weight_b: *mut f32,
    pdf: *mut f32,
    flags: *mut u32,
) -> i32 {
    guard("strata_sample_batch_soa_columns", || {
        let (wi, wo, w) = (
            [wi_x, wi_y, wi_z],
            [wo_x, wo_y, wo_z],
            [weight_r, weight_g, weight_b],
        );
        let cols = ColumnArgs { columns, ncolumns };
        // SAFETY: the caller's guarantees are those of `sample_soa`.
        unsafe { sample_soa(b, n, wi, keys, cols, wo, w, pdf, flags) }
    })
}

/// The body of the SoA samples.
///
/// # Safety
/// As `strata_sample_batch_soa_columns`.
#[allow(clippy::too_many_arguments)]
unsafe fn sample_soa(
    b: *const StrataBsdf,
    n: usize,
    [wi_x, wi_y, wi_z]: [*const f32; 3],
    keys: *const u64,
    cols: ColumnArgs,
    [wo_x, wo_y, wo_z]: [*mut f32; 3],
    [weight_r, weight_g, weight_b]: [*mut f32; 3],
    pdf: *mut f32,
    flags: *mut u32,
) -> Result<(), Failure> {
    // SAFETY: the caller guarantees `b` is NULL or live.
    let bsdf = unsafe { bsdf_ref(b)? };
    if n == 0 {
        return Ok(());
    }
    // SAFETY: the caller's guarantees on the columns are `read_columns`'.
    let cols = unsafe { read_columns(cols, n)? };
    cols.disjoint(vec![
        span("wi_x", wi_x, 1, n, false, false)?,
        span("wi_y", wi_y, 1, n, false, false)?,
        span("wi_z", wi_z, 1, n, false, false)?,
        span("keys", keys, 1, n, false, true)?,
        span("wo_x", wo_x, 1, n, true, false)?,
        span("wo_y", wo_y, 1, n, true, false)?,
        span("wo_z", wo_z, 1, n, true, false)?,
        span("weight_r", weight_r, 1, n, true, false)?,
        span("weight_g", weight_g, 1, n, true, false)?,
        span("weight_b", weight_b, 1, n, true, false)?,
        span("pdf", pdf, 1, n, true, false)?,
        span("flags", flags, 1, n, true, false)?,
    ])?;
    let target = cols.target(bsdf, n)?;
    // SAFETY: the caller guarantees each non-NULL array holds n elements and
    // that inputs are not written during the call; the outputs were checked
    // disjoint from every other array (and column) above.
    unsafe {
        let wi = [
            input("wi_x", wi_x, 1, n)?,
            input("wi_y", wi_y, 1, n)?,
            input("wi_z", wi_z, 1, n)?,
        ];
        let keys = if keys.is_null() {
            None
        } else {
            Some(input("keys", keys, 1, n)?)
        };
        let wo = [
            output("wo_x", wo_x, 1, n)?,
            output("wo_y", wo_y, 1, n)?,
            output("wo_z", wo_z, 1, n)?,
        ];
        let weight = [
            output("weight_r", weight_r, 1, n)?,
            output("weight_g", weight_g, 1, n)?,
            output("weight_b", weight_b, 1, n)?,
        ];
        let out = SampleOut::Soa {
            wo: VectorsMut::Soa(wo),
            weight: VectorsMut::Soa(weight),
            pdf: output("pdf", pdf, 1, n)?,
            flags: output("flags", flags, 1, n)?,
        };
        target.sample(Vectors::Soa(wi), keys, out)
    }
}

/// The approximate pdf of `wo[k]` for sampling from `wi[k]` (`3 n` floats
/// each), per solid angle, into `pdf_out` (`n` floats). A function of the two
/// directions and the seed: it is the number a sample of that direction
/// carries. n = 0 does nothing.
///
/// # Safety
/// `wi`, `wo` hold at least `3 n` floats, `pdf_out` `n`; `pdf_out` does not
/// overlap the inputs (checked); `b` is NULL or live.
#[no_mangle]
pub unsafe extern "C" fn strata_pdf_batch(
    b: *const StrataBsdf,
    n: usize,
    wi: *const f32,
    wo: *const f32,
    pdf_out: *mut f32,
) -> i32 {
    guard("strata_pdf_batch", || {
        // SAFETY: the caller's guarantees are those of `pdf_body`.
        unsafe { pdf_body(b, n, wi, wo, None, OWN, pdf_out, std::ptr::null_mut()) }
    })
}

/// `strata_pdf_batch` with per-query parameters, as
/// `strata_eval_batch_columns`: the pdf a sample of query `k`'s material
/// carries.
///
/// # Safety
/// As `strata_pdf_batch` and `strata_eval_batch_columns`.
#[no_mangle]
pub unsafe extern "C" fn strata_pdf_batch_columns(
    b: *const StrataBsdf,
    n: usize,
    wi: *const f32,
    wo: *const f32,
    columns: *const StrataColumn,
    ncolumns: usize,
    pdf_out: *mut f32,
) -> i32 {
    guard("strata_pdf_batch_columns", || {
        let cols = ColumnArgs { columns, ncolumns };
        // SAFETY: the caller's guarantees are those of `pdf_body`.
        unsafe { pdf_body(b, n, wi, wo, None, cols, pdf_out, std::ptr::null_mut()) }
    })
}

/// The unbiased pdf of `wo[k]` for sampling from `wi[k]` (`3 n` floats
/// each): the density of the sampler's directions from `walks` density walks
/// (1 to 2^40), into `pdf_out`, with its standard error in `stderr_out` (`n`
/// floats each). Slow: for references and tests. n = 0 does nothing.
///
/// # Safety
/// `wi`, `wo` hold at least `3 n` floats, `pdf_out` and `stderr_out` `n`;
/// the outputs overlap neither the inputs nor each other (checked); `b` is
/// NULL or live.
#[no_mangle]
pub unsafe extern "C" fn strata_pdf_unbiased_batch(
    b: *const StrataBsdf,
    n: usize,
    wi: *const f32,
    wo: *const f32,
    walks: u64,
    pdf_out: *mut f32,
    stderr_out: *mut f32,
) -> i32 {
    guard("strata_pdf_unbiased_batch", || {
        // SAFETY: the caller's guarantees are those of `pdf_body`.
        unsafe { pdf_body(b, n, wi, wo, Some(walks), OWN, pdf_out, stderr_out) }
    })
}

/// `strata_pdf_unbiased_batch` with per-query parameters, as
/// `strata_eval_batch_columns`.
///
/// # Safety
/// As `strata_pdf_unbiased_batch` and `strata_eval_batch_columns`.
#[no_mangle]
pub unsafe extern "C" fn strata_pdf_unbiased_batch_columns(
    b: *const StrataBsdf,
    n: usize,
    wi: *const f32,
    wo: *const f32,
    walks: u64,
    columns: *const StrataColumn,
    ncolumns: usize,
    pdf_out: *mut f32,
    stderr_out: *mut f32,
) -> i32 {
    guard("strata_pdf_unbiased_batch_columns", || {
        let cols = ColumnArgs { columns, ncolumns };
        // SAFETY: the caller's guarantees are those of `pdf_body`.
        unsafe { pdf_body(b, n, wi, wo, Some(walks), cols, pdf_out, stderr_out) }
    })
}

/// The body of the pdfs: approximate (`walks` `None`; `stderr_out` unused)
/// or unbiased from `walks` density walks.
///
/// # Safety
/// As `strata_pdf_unbiased_batch_columns`.
#[allow(clippy::too_many_arguments)]
unsafe fn pdf_body(
    b: *const StrataBsdf,
    n: usize,
    wi: *const f32,
    wo: *const f32,
    walks: Option<u64>,
    cols: ColumnArgs,
    pdf_out: *mut f32,
    stderr_out: *mut f32,
) -> Result<(), Failure> {
    // SAFETY: the caller guarantees `b` is NULL or live.
    let bsdf = unsafe { bsdf_ref(b)? };
    if n == 0 {
        return Ok(());
    }
    if let Some(w) = walks {
        walk_count("walks", w)?;
    }
    // SAFETY: the caller's guarantees on the columns are `read_columns`'.
    let cols = unsafe { read_columns(cols, n)? };
    let mut spans = vec![
        span("wi", wi, 3, n, false, false)?,
        span("wo", wo, 3, n, false, false)?,
        span("pdf_out", pdf_out, 1, n, true, false)?,
    ];
    if walks.is_some() {
        spans.push(span("stderr_out", stderr_out, 1, n, true, false)?);
    }
    cols.disjoint(spans)?;
    let target = cols.target(bsdf, n)?;
    // SAFETY: the caller guarantees the arrays' lengths and that inputs are
    // not written during the call; the outputs were checked disjoint.
    unsafe {
        let wi = Vectors::Aos(triples(input("wi", wi, 3, n)?));
        let wo = Vectors::Aos(triples(input("wo", wo, 3, n)?));
        let pdf = output("pdf_out", pdf_out, 1, n)?;
        match walks {
            None => target.pdf(wi, wo, pdf),
            Some(w) => {
                let se = output("stderr_out", stderr_out, 1, n)?;
                target.pdf_unbiased(wi, wo, w, pdf, se)
            }
        }
    }
}

/// The directional albedo of each incident direction `wi[k]` (`3 n` floats)
/// from `walks` walks each (1 to 2^40), into `out[k]`. `keys` NULL: keyed by
/// the directions' bits; otherwise `n` keys. n = 0 does nothing.
///
/// # Safety
/// `wi` holds at least `3 n` floats, `keys` (if not NULL) `n` values, `out`
/// `n` records; `out` does not overlap the inputs (checked); `b` is NULL or
/// live.
#[no_mangle]
pub unsafe extern "C" fn strata_albedo_batch(
    b: *const StrataBsdf,
    n: usize,
    wi: *const f32,
    walks: u64,
    keys: *const u64,
    out: *mut StrataAlbedo,
) -> i32 {
    guard("strata_albedo_batch", || {
        // SAFETY: the caller's guarantees are those of `albedo_body`.
        unsafe { albedo_body(b, n, wi, walks, keys, OWN, out) }
    })
}

/// `strata_albedo_batch` with per-query parameters, as
/// `strata_eval_batch_columns`.
///
/// # Safety
/// As `strata_albedo_batch` and `strata_eval_batch_columns`.
#[no_mangle]
pub unsafe extern "C" fn strata_albedo_batch_columns(
    b: *const StrataBsdf,
    n: usize,
    wi: *const f32,
    walks: u64,
    keys: *const u64,
    columns: *const StrataColumn,
    ncolumns: usize,
    out: *mut StrataAlbedo,
) -> i32 {
    guard("strata_albedo_batch_columns", || {
        let cols = ColumnArgs { columns, ncolumns };
        // SAFETY: the caller's guarantees are those of `albedo_body`.
        unsafe { albedo_body(b, n, wi, walks, keys, cols, out) }
    })
}

/// The body of the albedos.
///
/// # Safety
/// As `strata_albedo_batch_columns`.
unsafe fn albedo_body(
    b: *const StrataBsdf,
    n: usize,
    wi: *const f32,
    walks: u64,
    keys: *const u64,
    cols: ColumnArgs,
    out: *mut StrataAlbedo,
) -> Result<(), Failure> {
    // SAFETY: the caller guarantees `b` is NULL or live.
    let bsdf = unsafe { bsdf_ref(b)? };
    if n == 0 {
        return Ok(());
    }
    walk_count("walks", walks)?;
    // SAFETY: the caller's guarantees on the columns are `read_columns`'.
    let cols = unsafe { read_columns(cols, n)? };
    cols.disjoint(vec![
        span("wi", wi, 3, n, false, false)?,
        span("keys", keys, 1, n, false, true)?,
        span("out", out, 1, n, true, false)?,
    ])?;
    let target = cols.target(bsdf, n)?;
    // SAFETY: the caller guarantees the arrays' lengths and that inputs are
    // not written during the call; `out` was checked disjoint.
    // `StrataAlbedo` has the layout of `AlbedoRecord` (asserted at compile
    // time).
    unsafe {
        let wi = input("wi", wi, 3, n)?;
        let keys = if keys.is_null() {
            None
        } else {
            Some(input("keys", keys, 1, n)?)
        };
        let out = output("out", out.cast::<AlbedoRecord>(), 1, n)?;
        target.albedo(Vectors::Aos(triples(wi)), walks, keys, out)
    }
}

// ------------------------------------------------------------------- strings

/// The message of this thread's last failed call: the function, the
/// argument, and in a batch the query index and what is wrong. "" if the
/// last call succeeded; never NULL. Valid until the next strata call on this
/// thread; each thread has its own.
#[no_mangle]
pub extern "C" fn strata_last_error() -> *const c_char {
    LAST_ERROR
        .try_with(|e| e.borrow().as_ptr())
        .unwrap_or_else(|_| {
            let late = LATE_ERROR.with(Cell::get);
            if late.is_null() {
                EMPTY.as_ptr()
            } else {
                late
            }
        })
}

/// A C string from a Rust literal ending in NUL.
const fn c_str(bytes: &'static [u8]) -> &'static CStr {
    match CStr::from_bytes_with_nul(bytes) {
        Ok(v) => v,
        Err(_) => panic!("not a C string"),
    }
}

const EMPTY: &CStr = c_str(b"\0");
const VERSION: &CStr = c_str(concat!(env!("CARGO_PKG_VERSION"), "\0").as_bytes());

/// The version of strata, e.g. "0.1.0" (static; never NULL).
#[no_mangle]
pub extern "C" fn strata_version() -> *const c_char {
    VERSION.as_ptr()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn last() -> String {
        // SAFETY: `strata_last_error` returns a NUL-terminated string that
        // lives until the next strata call on this thread.
        unsafe { CStr::from_ptr(strata_last_error()) }
            .to_str()
            .unwrap()
            .to_owned()
    }

    #[test]
    fn a_panic_is_caught_and_reported() {
        let status = guard("strata_test", || panic!("boom {}", 7));
        assert_eq!(status, STRATA_ERR_PANIC);
        assert_eq!(
            last(),
            "strata_test: internal error (strata panicked: boom 7); please report it"
        );
        assert_eq!(guard("strata_test", || Ok(())), STRATA_OK);
        assert_eq!(last(), "");
    }

    #[test]
    fn a_nul_in_a_message_is_escaped() {
        let status = guard("strata_test", || Err(Failure::invalid("a\0b")));
        assert_eq!(status, STRATA_ERR_INVALID_ARGUMENT);
        assert_eq!(last(), "strata_test: a\\0b");
    }

    #[test]
    fn overlapping_outputs_are_found() {
        let v = [0f32; 8];
        let p = v.as_ptr();
        // Inputs may share memory; an output may not share with anything.
        let s = |name, p, written| span(name, p, 1, 4, written, false).unwrap();
        assert!(disjoint(&[s("a", p, false), s("b", p, false)]).is_ok());
        // SAFETY: `p + 3` is within `v`.
        let q = unsafe { p.add(3) };
        let e = disjoint(&[s("a", p, false), s("out", q, true)]).unwrap_err();
        assert_eq!(e.code, STRATA_ERR_INVALID_ARGUMENT);
        assert!(e.message.starts_with("a and out overlap"), "{}", e.message);
        // SAFETY: `p + 4` is within `v`.
        let r = unsafe { p.add(4) };
        assert!(disjoint(&[s("a", p, false), s("out", r, true)]).is_ok());
    }
}
