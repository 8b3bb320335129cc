//! The C ABI of strata: layered BSDFs for C and C++ renderers.
//!
//! The header is `include/strata.h`, generated from this file by cbindgen
//! (`cbindgen.toml`; `.ci/capi.sh` fails if the committed header is stale).
//! Link `libstrata_capi.a` (with `-lpthread -ldl -lm`) or
//! `libstrata_capi.so`. docs/embedding.md has the guide.
//!
//! A BSDF's settings (walks per eval, seed, transport, estimator, walk
//! limits, threads, ...) are text in the library's
//! [`Config`](strata_bsdf::Config) form: `strata_bsdf_configure` applies
//! `key=value` pairs and `strata_bsdf_config` prints them all.
//!
//! Every function returns a status: [`STRATA_OK`] (0) or a negative
//! `STRATA_ERR_*` code, and then [`strata_last_error`] says what was wrong,
//! naming the argument and, in a batch, the query index. Nothing unwinds
//! across the boundary: a panic inside strata is caught and reported as
//! [`STRATA_ERR_PANIC`].
//!
//! A `StrataBsdf` is the library's [`LayeredBsdf`] behind a pointer; the
//! batch functions, one per verb (`strata_eval`, `strata_sample`,
//! `strata_pdf`, `strata_pdf_unbiased`, `strata_albedo`), take a
//! [`StrataBatch`] descriptor of the caller's arrays (either layout) and run
//! the library's slice calls (`eval_into`, `sample_records`, ...) over them,
//! so they give the Rust API's numbers bit for bit (tested in
//! `tests/abi_suite/abi.rs`), and the count of walks the limit of events
//! ended.
//!
//! Per-query parameters (a renderer's textures) are `StrataColumn`s, the
//! descriptor's `columns`: the call builds one material per query with
//! [`PerQuery`] (a bounded chunk of them at a time) and answers query `k` as
//! a BSDF made from a material file with row `k`'s values
//! (`tests/abi_suite/columns.rs`).

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
    check_walks, AlbedoRecord, BatchError, Bsdf, Column, ColumnsError, Estimate, Estimator,
    EvalBuffers, LayerStack, LayeredBsdf, PdfWalks, PerQuery, Queries, QueryError, SampleBuffers,
    SampleRecord, SetError, SetPath, SpectralColumns, SpectralError, Transport, Vectors,
    VectorsMut,
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
/// that is not UTF-8, a setting `strata_bsdf_configure` does not take (the
/// message names the key and the value), a buffer too small for
/// `strata_bsdf_config`'s text, or a bad `StrataColumn` (a width other than
/// 1 or 3, a path that is not settable or not in the material, a NaN or
/// infinite value, a value of the wrong shape for its field).
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
/// between two chunks of a call with `columns`) the outputs of the queries
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

/// `strata_bsdf_set_pdf_samples`'s `n` for the library's default rule (the
/// lobe pdf, no walks); any other `n` is a fixed count of density walks.
pub const STRATA_PDF_SAMPLES_RULE: u32 = 0;

/// `StrataSample::flags` bit: the walk left on the side it entered.
pub const STRATA_SAMPLE_REFLECTION: u32 = 1;
/// `StrataSample::flags` bit: the walk left on the other side.
pub const STRATA_SAMPLE_TRANSMISSION: u32 = 2;
/// `StrataSample::flags` bit: every event of the walk was a delta (the
/// direction is a specular one; treat the sample as a delta).
pub const STRATA_SAMPLE_DELTA: u32 = 4;

/// `StrataStackInfo::lobes` bit: a smooth entry interface reflects a delta
/// lobe (from below a transmissive stack, a smooth bottom does).
pub const STRATA_LOBE_DELTA_REFLECTION: u32 = 1;
/// `StrataStackInfo::lobes` bit: light can pass every interface without a
/// non-delta event (sample only).
pub const STRATA_LOBE_DELTA_TRANSMISSION: u32 = 2;
/// `StrataStackInfo::lobes` bit: a rough interface or a scattering medium.
pub const STRATA_LOBE_GLOSSY: u32 = 4;
/// `StrataStackInfo::lobes` bit: a Lambertian interface.
pub const STRATA_LOBE_DIFFUSE: u32 = 8;
/// `StrataStackInfo::lobes` bit: the stack transmits.
pub const STRATA_LOBE_TRANSMISSION: u32 = 16;

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
/// (`strata_bsdf_configure` and the `strata_bsdf_set_*` calls must not run
/// concurrently with them).
pub struct StrataBsdf {
    inner: LayeredBsdf,
}

const _: () = {
    const fn shareable<T: Send + Sync>() {}
    shareable::<StrataBsdf>();
};

/// One sample of `strata_sample` (`StrataBatch::sample`). An absorbed walk is all zeros
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
    /// The density of `wo` per solid angle: exactly what `strata_pdf`
    /// gives for `(wi, wo)`, so MIS sees the same number from either
    /// strategy. Approximate (exact on the coats over Lambertian bases that
    /// are sampled without a walk: `strata_bsdf_is_exact`), so the weight is
    /// not `f cos / pdf` in general.
    pub pdf: f32,
    /// `STRATA_SAMPLE_*` bits: REFLECTION or TRANSMISSION, and DELTA; 0 if
    /// absorbed.
    pub flags: u32,
}

/// One result of `strata_albedo` (`StrataBatch::albedo`): the fractions of light from `wi`
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
/// exteriors' IORs (for a transmitted sample's relative IOR), whether light
/// passes through, and the lobes it can produce. Filled by
/// `strata_bsdf_info`.
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
    /// The lobes the stack can produce: `STRATA_LOBE_*` bits.
    pub lobes: u32,
}

/// One per-query parameter of a batch (`StrataBatch::columns`): the values
/// of the material parameter `path` for each of the call's `n` queries, `width`
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
/// BSDF's walk count, seed, transport mode and threads. Where every column
/// is a thickness, `sigma_t`, an albedo, a roughness, `eta` or `k` and the
/// rows keep one shape (the usual texture), the rows are written into the
/// BSDF's numbers in place, with no material built per query, and a float
/// enters as itself (`0.1f` is the material file's `0.100000001490116`);
/// otherwise (an IOR, a normal, a phase parameter) it sets the first of its
/// `%.1g` … `%.9g` decimals that reads back as it (`0.1f` is `0.1`).
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
/// Memory: a call with columns answers a bounded chunk of queries at a time
/// (at most 65536 queries and `min(4096, max(1, 65536 / layers))` distinct
/// rows), so its working memory is at most that many rows' numbers (or
/// materials, a few KB each on a two-layer stack, about 1.7 KB per layer on
/// a deep one) plus a few hundred bytes per query of a chunk, whatever `n`
/// and however many rows differ: about 20 MB on a two-layer stack
/// (`strata::PerQuery` in the Rust docs). Every row is
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
    name: impl Into<Cow<'static, str>>,
    ptr: *const T,
    per: usize,
    n: usize,
    written: bool,
    optional: bool,
) -> Result<Span, Failure> {
    let name = name.into();
    if optional && ptr.is_null() {
        return Ok((name, 0, 0, written));
    }
    let len = match per.checked_mul(n) {
        Some(len) => len,
        None if ptr.is_null() => usize::MAX,
        None => return Err(too_large(&name, n)),
    };
    check_array(&name, ptr, len, n)?;
    Ok((name, ptr as usize, len * size_of::<T>(), written))
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
/// between exteriors of different IOR only. `strata_bsdf_configure` is the
/// general form (`"transport=importance"`); this call stays for the ABI.
/// Configure a BSDF before sharing it: this call must not run while another
/// thread uses `b`.
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
/// (2). `strata_bsdf_configure` is the general form (`"estimator=uni"`,
/// `auto`, `bidir`); this call stays for the ABI. Configure a BSDF before
/// sharing it: this call must not run while another thread uses `b`.
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

/// Sets how the approximate pdf is made (the pdf that `strata_pdf` returns
/// and that the samples carry):
/// `STRATA_PDF_SAMPLES_RULE` (0, the default) is the library's default, the
/// lobe pdf (no walks: a closed-form density for MIS); `n ≥ 1` is exactly
/// `n` density walks (docs/method.md §6 compares them;
/// `strata_bsdf_set_pdf_walks` sets an adaptive rule).
/// Every `n` is valid. (The Rust API's `pdf_samples(0)` is one walk; here 0
/// names the rule.) `strata_bsdf_configure` is the general form
/// (`"pdf_walks=lobes"`, `"pdf_walks=16"`); this call stays for the ABI.
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
/// `strata_bsdf_configure` is the general form (`"max_events=4096"`); this
/// call stays for the ABI. Configure a BSDF before sharing it: this call
/// must not run while another thread uses `b`.
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
/// that `strata_pdf` returns and that the samples carry): a pilot of
/// `pilot` walks (at least 2) measures one walk's relative variance, then
/// `pilot` to `max` fresh walks run for a relative standard error of about
/// `rel_stderr` (a positive number), as the Rust API's `PdfWalks::adaptive`.
/// (8, 64, 0.15) is the Rust API's `PdfWalks::ADAPTIVE` (the default is the
/// lobe pdf, no walks: `strata_bsdf_set_pdf_samples`); (8, 128, 0.1), its `TIGHT` rule,
/// gives a pdf within 0.7–1.3× of the density of the samples at nearly
/// every direction for about twice the walks (docs/method.md §6). A pilot
/// under 2, a `max` under `pilot`, or a `rel_stderr` that is not a positive
/// finite number is `STRATA_ERR_INVALID_ARGUMENT`, naming the argument and its
/// value, and leaves the BSDF as it was. `strata_bsdf_configure` is the
/// general form (`"pdf_walks=8,64,0.15"`, `adaptive`, `tight`); this call
/// stays for the ABI. Configure a BSDF before sharing it: this call must not
/// run while another thread uses `b`.
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
/// use; calls from several threads share it. `strata_bsdf_configure` is the
/// general form (`"threads=4"`, or `"threads=current"` for the shared pool;
/// there 0 is not a count); this call stays for the ABI. Configure a BSDF
/// before sharing it: this call must not run while another thread uses `b`. Safe across
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

/// Applies `settings`, NUL-terminated UTF-8 text of `key=value` pairs
/// separated by whitespace (`"samples=64 transport=importance
/// max_events=4096"`), the library's `Config` text form: the keys are
/// `samples`, `pdf_walks`, `seed`, `transport`, `eval_start`, `estimator`,
/// `engine`, `threads`, `max_events`, `rr_start`, `rr_threshold`,
/// `max_scatter_order` and `mis` (docs/embedding.md lists their values),
/// and a key not given keeps its value. It is the general form of the
/// `strata_bsdf_set_*` calls, giving the same BSDF bit for bit, and reads
/// what `strata_bsdf_config` prints. An unknown key or a value out of its
/// range is `STRATA_ERR_INVALID_ARGUMENT`, the message naming the key and the
/// value (`"strata_bsdf_configure: rr_threshold=2: expected a number from
/// 0.001 to 1"`), and leaves the BSDF as it was. Configure a BSDF before
/// sharing it: this call must not run while another thread uses `b`.
///
/// # Safety
/// `b` is NULL or a live pointer from `strata_bsdf_from_*` that no other
/// thread uses during the call; `settings` is NULL or a NUL-terminated
/// string.
#[no_mangle]
pub unsafe extern "C" fn strata_bsdf_configure(b: *mut StrataBsdf, settings: *const c_char) -> i32 {
    guard("strata_bsdf_configure", || {
        // SAFETY: the caller guarantees that a non-NULL `b` is live and not
        // used by another thread.
        let b = unsafe { bsdf_mut(b)? };
        // SAFETY: the caller guarantees a non-NULL `settings` is
        // NUL-terminated.
        let settings = unsafe { text("settings", settings)? };
        let mut config = b.config();
        config
            .apply(settings)
            .map_err(|e| Failure::invalid(e.to_string()))?;
        *b = b.clone().with_config(&config).map_err(|e| {
            let threads = config.get("threads").unwrap_or_default();
            Failure::invalid(format!("threads={threads}: {e}"))
        })?;
        Ok(())
    })
}

/// Prints the BSDF's configuration, every key of `strata_bsdf_configure`
/// in its order (`"samples=64 pdf_walks=lobes seed=0 ..."`, text that
/// `strata_bsdf_configure` reads back to the same configuration), into
/// `buf`: `len` bytes, NUL-terminated. If `needed` is not NULL, `*needed` is
/// set to the bytes the text takes with its NUL, whatever happens after the
/// NULL check of `b`. `buf` = NULL with `len` = 0 only asks the size. Unlike
/// `snprintf`, a `len` under that size writes the empty string (if `len` >
/// 0) and is `STRATA_ERR_INVALID_ARGUMENT`, naming both sizes: a truncated
/// configuration could read back as a different one.
///
/// # Safety
/// `b` is NULL or live; `buf` is NULL or writable for `len` bytes; `needed`
/// is NULL or points to a writable `size_t`.
#[no_mangle]
pub unsafe extern "C" fn strata_bsdf_config(
    b: *const StrataBsdf,
    buf: *mut c_char,
    len: usize,
    needed: *mut usize,
) -> i32 {
    guard("strata_bsdf_config", || {
        // SAFETY: the caller guarantees `b` is NULL or live.
        let text = unsafe { bsdf_ref(b)? }.config().to_string();
        let size = text.len() + 1;
        if !needed.is_null() {
            // SAFETY: `needed` is non-NULL and the caller guarantees it is
            // writable.
            unsafe { needed.write(size) };
        }
        if buf.is_null() {
            return match len {
                0 => Ok(()),
                _ => Err(Failure::new(
                    STRATA_ERR_NULL,
                    format!("buf is NULL (len = {len})"),
                )),
            };
        }
        if len < size {
            if len > 0 {
                // SAFETY: `buf` is non-NULL and writable for `len` > 0 bytes.
                unsafe { buf.write(0) };
            }
            return Err(Failure::invalid(format!(
                "len = {len} is too small: the configuration takes {size} bytes"
            )));
        }
        // SAFETY: `buf` is non-NULL and writable for `len` ≥ `size` bytes;
        // `text` is a separate allocation, so they do not overlap.
        unsafe {
            std::ptr::copy_nonoverlapping(text.as_ptr().cast::<c_char>(), buf, text.len());
            buf.add(text.len()).write(0);
        }
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
            lobes: lobe_bits(&stack.lobes()),
        };
        // SAFETY: `out` is non-NULL and the caller guarantees it is writable.
        unsafe { out.write(info) };
        Ok(())
    })
}

/// The `STRATA_LOBE_*` bits of `l`.
fn lobe_bits(l: &strata_bsdf::stack::Lobes) -> u32 {
    [
        (l.delta_reflection, STRATA_LOBE_DELTA_REFLECTION),
        (l.delta_transmission, STRATA_LOBE_DELTA_TRANSMISSION),
        (l.glossy, STRATA_LOBE_GLOSSY),
        (l.diffuse, STRATA_LOBE_DIFFUSE),
        (l.transmission, STRATA_LOBE_TRANSMISSION),
    ]
    .iter()
    .filter(|(on, _)| *on)
    .fold(0, |bits, (_, bit)| bits | bit)
}

/// Writes to `*out` whether the BSDF answers sample and pdf without walks
/// (1) or with them (0): under `STRATA_ESTIMATOR_AUTO`, a smooth or rough
/// (isotropic) coat over a clear or absorbing layer over a Lambertian base
/// (untilted normals, an absorber whose extinction does not depend on the
/// direction, no depth cap). Then sample draws from a known density with
/// bounded weights, and `strata_pdf` returns that exact density
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

/// A call's columns, checked: their paths parsed, their values as slices.
struct Columns<'a> {
    paths: Vec<SetPath>,
    widths: Vec<usize>,
    values: Vec<&'a [f32]>,
    /// The columns array and every column's values: inputs of the call.
    spans: Vec<Span>,
    /// With wavelengths: the columns the queries run on, the material's
    /// spectra and the columns' RGB triples read at them.
    spectral: Option<SpectralColumns>,
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
unsafe fn read_columns<'a>(
    columns: *const StrataColumn,
    ncolumns: usize,
    n: usize,
) -> Result<Columns<'a>, Failure> {
    let mut cols = Columns {
        paths: Vec::new(),
        widths: Vec::new(),
        values: Vec::new(),
        spans: Vec::new(),
        spectral: None,
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
    /// The columns as the library takes them.
    fn columns(&self) -> Vec<Column<'_>> {
        (self.paths.iter().zip(&self.widths).zip(&self.values))
            .map(|((path, &width), values)| Column {
                path,
                width,
                values,
            })
            .collect()
    }

    /// Checks that no output of the call (in `spans`) overlaps another array
    /// of it, the columns' values included.
    fn disjoint(&self, mut spans: Vec<Span>) -> Result<(), Failure> {
        spans.extend(self.spans.iter().cloned());
        disjoint(&spans)
    }

    /// The per-query rows the call's `n` queries run on: none without
    /// columns, else one material per query (every row checked first: the
    /// error names the query, the path and the value).
    fn rows<'b>(
        &'b self,
        bsdf: &'b LayeredBsdf,
        n: usize,
    ) -> Result<Option<PerQuery<'b>>, Failure> {
        let columns = match &self.spectral {
            Some(s) => s.columns(),
            None => self.columns(),
        };
        if columns.is_empty() {
            return Ok(None);
        }
        match PerQuery::new(bsdf, n, &columns) {
            Ok(m) => Ok(Some(m)),
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

/// What a call's queries run on: the BSDF, or its per-query rows.
fn answers<'a>(bsdf: &'a LayeredBsdf, rows: &'a Option<PerQuery<'a>>) -> &'a dyn Bsdf {
    match rows {
        Some(rows) => rows,
        None => bsdf,
    }
}

// ------------------------------------------------------------------- batches
//
// One call per verb, each taking a `StrataBatch`: `begin` checks the BSDF,
// the descriptor and the fields the verb does not read, `StrataBatch::spans`
// every array (NULL, alignment, size, overlap), and the body makes slices of
// them and runs the library's batch call (`strata_bsdf::Bsdf`) on the BSDF,
// or on one material per query from the descriptor's columns.

/// The 3-vectors of a batch that a call reads (directions), in one of two
/// layouts: `xyz`, `3 n` floats `x, y, z` per query (an array of
/// structures), with `x`, `y`, `z` NULL; or `x`, `y`, `z`, `n` floats each
/// (a structure of arrays), with `xyz` NULL. All four NULL: not given.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct StrataVectors {
    /// `3 n` floats, `x, y, z` per query; or NULL.
    pub xyz: *const f32,
    /// `n` x components; or NULL.
    pub x: *const f32,
    /// `n` y components; or NULL.
    pub y: *const f32,
    /// `n` z components; or NULL.
    pub z: *const f32,
}

/// The 3-vectors a call writes (directions, or values per RGB channel: `x`,
/// `y`, `z` are `r`, `g`, `b`), laid out as `StrataVectors`: `xyz` (`3 n`
/// floats) or `x`, `y`, `z` (`n` floats each). All four NULL: not wanted.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct StrataVectorsOut {
    /// `3 n` floats, three per query; or NULL.
    pub xyz: *mut f32,
    /// `n` first components (`r`); or NULL.
    pub x: *mut f32,
    /// `n` second components (`g`); or NULL.
    pub y: *mut f32,
    /// `n` third components (`b`); or NULL.
    pub z: *mut f32,
}

/// One batch of `n` queries, for `strata_eval`, `strata_sample`,
/// `strata_pdf`, `strata_pdf_unbiased` and `strata_albedo`. Zero it
/// (`StrataBatch batch = {0};`) and set the fields the call reads: a
/// non-NULL (non-zero) field that the call does not read is an error naming
/// it (`STRATA_ERR_INVALID_ARGUMENT`), so that no argument is silently
/// ignored. Directions are in the local frame (z = normal), both pointing
/// away from the surface, normalized on input. Arrays hold one element (or
/// triple) per query; an output must not overlap another array of the call
/// (checked); a failed call writes nothing (but see `StrataColumn` on running
/// out of memory between chunks). n = 0 does nothing (but write `truncated`).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct StrataBatch {
    /// The number of queries.
    pub n: usize,
    /// Incident directions (all calls).
    pub wi: StrataVectors,
    /// Outgoing directions (eval, pdf, pdf_unbiased).
    pub wo: StrataVectors,
    /// Optional `n` keys (eval, sample, albedo): query `k` draws its walks
    /// from the stream `(seed, keys[k])`, so a renderer passes fresh keys for
    /// fresh noise. NULL: keyed by the directions' bits (the same query
    /// always gives the same estimate, as `strata eval` does; an unkeyed
    /// sample `k` draws sample index `k`, as line `k` of `strata sample`).
    /// The pdfs are always keyed by their directions.
    pub keys: *const u64,
    /// Optional per-query parameters (all calls): `ncolumns` columns, see
    /// `StrataColumn`. NULL with `ncolumns` = 0: the BSDF's own parameters.
    pub columns: *const StrataColumn,
    /// The number of `columns`.
    pub ncolumns: usize,
    /// Optional `3 n` floats (all calls): query `k`'s three wavelengths in
    /// nm, one per channel, making the queries spectral: channel `c` of
    /// every output is the value at wavelength `c`, the material's spectra
    /// (and the RGB triples of `columns`, through their uplift) read at
    /// them (docs/materials.md, *Spectra*). A material whose IOR varies
    /// with wavelength takes one wavelength three times per query. The
    /// queries' columns then take 4 bytes per query, channel and column,
    /// allocated fallibly (`STRATA_ERR_OUT_OF_MEMORY`). NULL: RGB.
    pub wavelengths: *const f32,
    /// Walks per query, 1 to 2^40 (albedo, pdf_unbiased); 0 for the others.
    pub walks: u64,
    /// Out (eval, required): `f(wi, wo)` per RGB channel, without the cosine.
    pub f: StrataVectorsOut,
    /// Out (eval, optional): the standard errors of `f`.
    pub stderr: StrataVectorsOut,
    /// Out, `n` floats: the approximate pdf of `wo` per solid angle (pdf,
    /// required; eval, optional: the pdf of the same pairs, as `strata_pdf`
    /// gives it), the unbiased pdf (pdf_unbiased, required), or the pdf of
    /// each sample (sample's components).
    pub pdf: *mut f32,
    /// Out (pdf_unbiased, required), `n` floats: the standard error of `pdf`.
    pub pdf_stderr: *mut f32,
    /// Out (sample): one `StrataSample` record per query; or NULL and the
    /// components `sampled`, `weight`, `pdf` and `flags` (all four).
    pub sample: *mut StrataSample,
    /// Out (sample's components): the sampled directions.
    pub sampled: StrataVectorsOut,
    /// Out (sample's components): the samples' weights per RGB channel.
    pub weight: StrataVectorsOut,
    /// Out (sample's components), `n` values: `STRATA_SAMPLE_*` bits.
    pub flags: *mut u32,
    /// Out (albedo, required): one `StrataAlbedo` record per query.
    pub albedo: *mut StrataAlbedo,
    /// Out (eval, pdf_unbiased, albedo; optional): how many walks the limit
    /// of events (`strata_bsdf_set_max_events`) ended in this call, summed
    /// over the batch (an albedo's walk counts once); 0 when none did. Their
    /// paths' energy beyond the limit is missing from the estimates. Eval
    /// counts the walks of `f` (not those of `pdf`); sample and pdf do not
    /// count theirs and do not take it.
    pub truncated: *mut u64,
}

impl Default for StrataVectors {
    fn default() -> Self {
        let null = std::ptr::null();
        StrataVectors {
            xyz: null,
            x: null,
            y: null,
            z: null,
        }
    }
}

impl Default for StrataVectorsOut {
    fn default() -> Self {
        let null = std::ptr::null_mut();
        StrataVectorsOut {
            xyz: null,
            x: null,
            y: null,
            z: null,
        }
    }
}

/// The zeroed descriptor, `StrataBatch batch = {0};` in C.
impl Default for StrataBatch {
    fn default() -> Self {
        StrataBatch {
            n: 0,
            wi: StrataVectors::default(),
            wo: StrataVectors::default(),
            keys: std::ptr::null(),
            columns: std::ptr::null(),
            ncolumns: 0,
            wavelengths: std::ptr::null(),
            walks: 0,
            f: StrataVectorsOut::default(),
            stderr: StrataVectorsOut::default(),
            pdf: std::ptr::null_mut(),
            pdf_stderr: std::ptr::null_mut(),
            sample: std::ptr::null_mut(),
            sampled: StrataVectorsOut::default(),
            weight: StrataVectorsOut::default(),
            flags: std::ptr::null_mut(),
            albedo: std::ptr::null_mut(),
            truncated: std::ptr::null_mut(),
        }
    }
}

/// The vector fields of a `StrataBatch` and the names of their arrays.
const VECTOR_FIELDS: [(&str, [&str; 4]); 6] = [
    ("wi", ["wi.xyz", "wi.x", "wi.y", "wi.z"]),
    ("wo", ["wo.xyz", "wo.x", "wo.y", "wo.z"]),
    ("f", ["f.xyz", "f.x", "f.y", "f.z"]),
    ("stderr", ["stderr.xyz", "stderr.x", "stderr.y", "stderr.z"]),
    (
        "sampled",
        ["sampled.xyz", "sampled.x", "sampled.y", "sampled.z"],
    ),
    ("weight", ["weight.xyz", "weight.x", "weight.y", "weight.z"]),
];

impl StrataVectors {
    fn is_set(&self) -> bool {
        [self.xyz, self.x, self.y, self.z]
            .iter()
            .any(|p| !p.is_null())
    }

    /// The arrays of the field `name` for `n` queries, checked: one layout,
    /// all three SoA components or none, not NULL if `required`.
    fn spans(
        &self,
        name: &str,
        n: usize,
        written: bool,
        required: bool,
        out: &mut Vec<Span>,
    ) -> Result<(), Failure> {
        let soa = [self.x, self.y, self.z];
        let nulls = soa.map(|p| p.is_null());
        // The arrays' names, static: no allocation on the good path.
        let names = VECTOR_FIELDS
            .iter()
            .find(|f| f.0 == name)
            .map_or(["?"; 4], |f| f.1);
        let mut one = |i: usize, p, per| {
            out.push(span(names[i], p, per, n, written, false)?);
            Ok(())
        };
        match (self.xyz.is_null(), nulls) {
            (true, [true, true, true]) if !required => Ok(()),
            (true, [true, true, true]) => Err(Failure::new(
                STRATA_ERR_NULL,
                format!("{name} is NULL (n = {n}): set {name}.xyz, or {name}.x, .y and .z"),
            )),
            (false, [true, true, true]) => one(0, self.xyz, 3),
            (true, [false, false, false]) => (1..4).try_for_each(|i| one(i, soa[i - 1], 1)),
            (false, _) => Err(Failure::invalid(format!(
                "{name}.xyz and {name}.x, .y, .z are both set: pass one layout"
            ))),
            (true, _) => {
                let axis = ["x", "y", "z"];
                let null = (0..3).find(|&i| nulls[i]).unwrap_or(0);
                let given = (0..3).find(|&i| !nulls[i]).unwrap_or(0);
                Err(Failure::new(
                    STRATA_ERR_NULL,
                    format!(
                        "{name}.{} is NULL but {name}.{} is not (n = {n}): pass all three or none",
                        axis[null], axis[given]
                    ),
                ))
            }
        }
    }

    /// The vectors of a field checked by [`StrataVectors::spans`], or `None`.
    ///
    /// # Safety
    /// The field's arrays hold `n` queries' floats and are not written
    /// during the call.
    unsafe fn read<'a>(&self, name: &str, n: usize) -> Result<Option<Vectors<'a>>, Failure> {
        // SAFETY: the caller guarantees the arrays' lengths; `input` checks
        // the rest.
        unsafe {
            if !self.xyz.is_null() {
                return Ok(Some(Vectors::Aos(triples(input(name, self.xyz, 3, n)?))));
            }
            if self.x.is_null() {
                return Ok(None);
            }
            let [x, y, z] = [self.x, self.y, self.z];
            let c = [
                input(name, x, 1, n)?,
                input(name, y, 1, n)?,
                input(name, z, 1, n)?,
            ];
            Ok(Some(Vectors::Soa(c)))
        }
    }
}

impl StrataVectorsOut {
    fn view(&self) -> StrataVectors {
        StrataVectors {
            xyz: self.xyz.cast_const(),
            x: self.x.cast_const(),
            y: self.y.cast_const(),
            z: self.z.cast_const(),
        }
    }

    /// The vectors to write of a field checked by [`StrataVectors::spans`]
    /// (through [`StrataVectorsOut::view`]), or `None`.
    ///
    /// # Safety
    /// The field's arrays hold `n` queries' floats, writable, and overlap no
    /// other array of the call (checked by [`disjoint`]).
    unsafe fn write<'a>(&self, name: &str, n: usize) -> Result<Option<VectorsMut<'a>>, Failure> {
        // SAFETY: the caller guarantees the arrays' lengths and that they
        // are disjoint; `output` checks the rest.
        unsafe {
            if !self.xyz.is_null() {
                let v = output(name, self.xyz, 3, n)?;
                return Ok(Some(VectorsMut::Aos(triples_mut(v))));
            }
            if self.x.is_null() {
                return Ok(None);
            }
            let [x, y, z] = [self.x, self.y, self.z];
            let c = [
                output(name, x, 1, n)?,
                output(name, y, 1, n)?,
                output(name, z, 1, n)?,
            ];
            Ok(Some(VectorsMut::Soa(c)))
        }
    }
}

impl StrataBatch {
    /// Fails on the first field the call does not read (`reads`) that is set.
    fn only(&self, reads: &[&str]) -> Result<(), Failure> {
        let fields = [
            ("wo", self.wo.is_set()),
            ("keys", !self.keys.is_null()),
            ("walks", self.walks != 0),
            ("f", self.f.view().is_set()),
            ("stderr", self.stderr.view().is_set()),
            ("pdf", !self.pdf.is_null()),
            ("pdf_stderr", !self.pdf_stderr.is_null()),
            ("sample", !self.sample.is_null()),
            ("sampled", self.sampled.view().is_set()),
            ("weight", self.weight.view().is_set()),
            ("flags", !self.flags.is_null()),
            ("albedo", !self.albedo.is_null()),
            ("truncated", !self.truncated.is_null()),
        ];
        match fields.iter().find(|(f, set)| *set && !reads.contains(f)) {
            None => Ok(()),
            Some(("walks", _)) => Err(Failure::invalid(format!(
                "walks = {}, but this call takes no walk count: set it to 0",
                self.walks
            ))),
            Some((f, _)) => Err(Failure::invalid(format!(
                "{f} is not NULL, but this call does not take it: set it to NULL"
            ))),
        }
    }

    /// Every array of the batch, checked: not NULL if its name is in
    /// `required` (`wi` always is), aligned and addressable.
    fn spans(&self, required: &[&str]) -> Result<Vec<Span>, Failure> {
        let n = self.n;
        let need = |f: &str| required.contains(&f);
        let mut s = Vec::with_capacity(24);
        self.wi.spans("wi", n, false, true, &mut s)?;
        self.wo.spans("wo", n, false, need("wo"), &mut s)?;
        s.push(span("keys", self.keys, 1, n, false, true)?);
        s.push(span("wavelengths", self.wavelengths, 3, n, false, true)?);
        let vectors = [
            ("f", self.f),
            ("stderr", self.stderr),
            ("sampled", self.sampled),
            ("weight", self.weight),
        ];
        for (name, v) in vectors {
            v.view().spans(name, n, true, need(name), &mut s)?;
        }
        for (name, p) in [("pdf", self.pdf), ("pdf_stderr", self.pdf_stderr)] {
            s.push(span(name, p, 1, n, true, !need(name))?);
        }
        s.push(span("flags", self.flags, 1, n, true, !need("flags"))?);
        s.push(span("sample", self.sample, 1, n, true, !need("sample"))?);
        s.push(span("albedo", self.albedo, 1, n, true, !need("albedo"))?);
        s.push(span("truncated", self.truncated, 1, 1, true, true)?);
        Ok(s)
    }

    /// Reads the columns and checks every array (`required` as in
    /// [`StrataBatch::spans`]) and that no output overlaps another array.
    ///
    /// # Safety
    /// As the batch calls': the descriptor's arrays and columns hold what
    /// [`StrataBatch`] says.
    unsafe fn checked<'a>(
        &self,
        bsdf: &LayeredBsdf,
        required: &[&str],
    ) -> Result<Columns<'a>, Failure> {
        // SAFETY: the caller's guarantees on the columns are `read_columns`'.
        let mut cols = unsafe { read_columns(self.columns, self.ncolumns, self.n)? };
        cols.disjoint(self.spans(required)?)?;
        if !self.wavelengths.is_null() {
            // SAFETY: checked aligned and addressable by `spans`; the caller
            // guarantees `3 n` readable floats.
            let nm = unsafe { input("wavelengths", self.wavelengths, 3, self.n)? };
            let spectral = SpectralColumns::new(bsdf, nm, &cols.columns());
            cols.spectral = Some(spectral.map_err(|e| match e {
                SpectralError::Columns(e) => Failure::invalid(format!("columns: {e}")),
                e @ SpectralError::OutOfMemory { .. } => {
                    Failure::new(STRATA_ERR_OUT_OF_MEMORY, format!("wavelengths: {e}"))
                }
                e => Failure::invalid(format!("wavelengths: {e}")),
            })?);
        }
        Ok(cols)
    }

    /// The incident and (if given) outgoing directions of a checked batch.
    ///
    /// # Safety
    /// As [`StrataBatch::checked`], which has run.
    unsafe fn directions<'a>(&self) -> Result<(Vectors<'a>, Option<Vectors<'a>>), Failure> {
        // SAFETY: the caller guarantees the arrays hold `n` queries' floats.
        let (wi, wo) = unsafe { (self.wi.read("wi", self.n)?, self.wo.read("wo", self.n)?) };
        let wi = wi.ok_or_else(|| Failure::new(STRATA_ERR_NULL, "wi is NULL"))?;
        Ok((wi, wo))
    }

    /// The keys of a checked batch, if given.
    ///
    /// # Safety
    /// As [`StrataBatch::checked`], which has run.
    unsafe fn keys<'a>(&self) -> Result<Option<&'a [u64]>, Failure> {
        if self.keys.is_null() {
            return Ok(None);
        }
        // SAFETY: the caller guarantees `keys` holds `n` values.
        Ok(Some(unsafe { input("keys", self.keys, 1, self.n)? }))
    }

    /// Writes the count of truncated walks, if asked.
    ///
    /// # Safety
    /// A non-NULL `truncated` has been checked aligned (and disjoint) by
    /// [`StrataBatch::spans`] and is writable.
    unsafe fn count(&self, cut: u64) -> Result<(), Failure> {
        if !self.truncated.is_null() {
            // SAFETY: as the caller guarantees.
            unsafe { self.truncated.write(cut) };
        }
        Ok(())
    }
}

/// The BSDF and the descriptor of a batch call, checked (not NULL; no field
/// the call does not `read` set), or `None` if `n` = 0 (then `truncated`, if
/// given, is set to 0: there is nothing to do).
///
/// # Safety
/// `b` is NULL or live; a non-NULL `batch` points to a readable descriptor
/// whose arrays hold what [`StrataBatch`] says.
unsafe fn begin<'a>(
    b: *const StrataBsdf,
    batch: *const StrataBatch,
    reads: &[&str],
) -> Result<Option<(&'a LayeredBsdf, &'a StrataBatch)>, Failure> {
    // SAFETY: the caller guarantees `b` is NULL or live.
    let bsdf = unsafe { bsdf_ref(b)? };
    // SAFETY: the caller guarantees a non-NULL `batch` is readable; nothing
    // writes it during the call.
    let d =
        unsafe { batch.as_ref() }.ok_or_else(|| Failure::new(STRATA_ERR_NULL, "batch is NULL"))?;
    d.only(reads)?;
    if d.n > 0 {
        return Ok(Some((bsdf, d)));
    }
    span("truncated", d.truncated, 1, 1, true, true)?;
    // SAFETY: `truncated` was checked aligned just above.
    unsafe { d.count(0)? };
    Ok(None)
}

/// Evaluates `f(wi[k], wo[k])` (without the cosine, no delta lobes) for the
/// batch's `n` queries with the BSDF's walk count: reads `wi`, `wo`, `keys`
/// and `columns`, writes `f`, `stderr` (if given), `pdf` (if given: the
/// approximate pdf of each pair, bit for bit what `strata_pdf` gives, for a
/// light sample's MIS; one library call, `eval_pdf_into`, checks and
/// normalizes the directions once for both) and `truncated` (if given). On
/// an error nothing is written and the message names the query index and
/// the field (`"query 3: wi = [NaN, 0, 1] is not a direction: components
/// must be finite"`).
///
/// # Safety
/// `b` is NULL or live; `batch` is NULL or a descriptor whose arrays hold
/// what `StrataBatch` says, inputs not written during the call.
#[no_mangle]
pub unsafe extern "C" fn strata_eval(b: *const StrataBsdf, batch: *const StrataBatch) -> i32 {
    guard("strata_eval", || {
        let reads = ["wo", "keys", "f", "stderr", "pdf", "truncated"];
        // SAFETY: the caller guarantees `b` and `batch` (`begin`'s terms).
        let Some((bsdf, d)) = (unsafe { begin(b, batch, &reads)? }) else {
            return Ok(());
        };
        // SAFETY: as above; `checked` verifies every array before the body
        // makes slices of them.
        let cols = unsafe { d.checked(bsdf, &["wo", "f"])? };
        let rows = cols.rows(bsdf, d.n)?;
        let answers = answers(bsdf, &rows);
        // SAFETY: the arrays were checked by `checked` (outputs disjoint
        // from every other array) and hold what `StrataBatch` says.
        unsafe {
            let (wi, wo) = d.directions()?;
            let wo = wo.ok_or_else(|| Failure::new(STRATA_ERR_NULL, "wo is NULL"))?;
            let f =
                d.f.write("f", d.n)?
                    .ok_or_else(|| Failure::new(STRATA_ERR_NULL, "f is NULL"))?;
            let (keys, stderr) = (d.keys()?, d.stderr.write("stderr", d.n)?);
            let q = Queries {
                keys,
                ..Queries::pairs(wi, wo)
            };
            let mut out = EvalBuffers { f, stderr };
            let evals = &mut |k, e: &Estimate| out.put(k, e);
            let cut = if d.pdf.is_null() {
                answers.eval_into(&q, evals)?
            } else {
                // Both in one library call: the directions are checked and
                // normalized once.
                let pdf = output("pdf", d.pdf, 1, d.n)?;
                answers.eval_pdf_into(&q, evals, &mut |k, p| pdf[k] = p)?
            };
            d.count(cut)
        }
    })
}

/// Samples one outgoing direction per incident direction `wi[k]`: reads
/// `wi`, `keys` and `columns`, writes the records `sample` or the components
/// `sampled`, `weight`, `pdf` and `flags` (an absorbed walk writes zeros).
/// Each sample carries the pdf `strata_pdf` gives for its direction.
///
/// # Safety
/// As `strata_eval`.
#[no_mangle]
pub unsafe extern "C" fn strata_sample(b: *const StrataBsdf, batch: *const StrataBatch) -> i32 {
    guard("strata_sample", || {
        let reads = ["keys", "sample", "sampled", "weight", "pdf", "flags"];
        // SAFETY: the caller guarantees `b` and `batch` (`begin`'s terms).
        let Some((bsdf, d)) = (unsafe { begin(b, batch, &reads)? }) else {
            return Ok(());
        };
        let parts = [
            d.sampled.view().is_set() || d.weight.view().is_set(),
            !d.pdf.is_null() || !d.flags.is_null(),
        ];
        let required: &[&str] = match (d.sample.is_null(), parts) {
            (false, [false, false]) => &["sample"],
            (false, _) => {
                return Err(Failure::invalid(
                    "sample and sampled, weight, pdf or flags are set: \
                     pass the records or the components",
                ))
            }
            (true, [false, false]) => {
                return Err(Failure::new(
                    STRATA_ERR_NULL,
                    format!("sample is NULL (n = {}): pass records in sample, or sampled, weight, pdf and flags", d.n),
                ))
            }
            (true, _) => &["sampled", "weight", "pdf", "flags"],
        };
        // SAFETY: as in `strata_eval`.
        let cols = unsafe { d.checked(bsdf, required)? };
        let rows = cols.rows(bsdf, d.n)?;
        let answers = answers(bsdf, &rows);
        // SAFETY: as in `strata_eval`. `StrataSample` has the layout of
        // `SampleRecord` (asserted at compile time), so records may be
        // written as those.
        unsafe {
            let (wi, _) = d.directions()?;
            let n = d.n;
            let q = Queries {
                keys: d.keys()?,
                ..Queries::directions(wi)
            };
            match (d.sampled.write("sampled", n)?, d.weight.write("weight", n)?) {
                (Some(wo), Some(weight)) => {
                    let mut out = SampleBuffers {
                        wo,
                        weight,
                        pdf: output("pdf", d.pdf, 1, n)?,
                        flags: output("flags", d.flags, 1, n)?,
                    };
                    answers.sample_into(&q, &mut |k, s| out.put(k, s))?;
                }
                _ => {
                    let out = output("sample", d.sample.cast::<SampleRecord>(), 1, n)?;
                    answers.sample_into(&q, &mut |k, s| out[k] = SampleRecord::of(s))?;
                }
            }
            Ok(())
        }
    })
}

/// The approximate pdf of `wo[k]` for sampling from `wi[k]`, per solid
/// angle: reads `wi`, `wo` and `columns`, writes `pdf`. A function of the
/// two directions and the seed: the number a sample of that direction
/// carries.
///
/// # Safety
/// As `strata_eval`.
#[no_mangle]
pub unsafe extern "C" fn strata_pdf(b: *const StrataBsdf, batch: *const StrataBatch) -> i32 {
    guard("strata_pdf", || {
        // SAFETY: the caller guarantees `b` and `batch` (`begin`'s terms).
        let Some((bsdf, d)) = (unsafe { begin(b, batch, &["wo", "pdf"])? }) else {
            return Ok(());
        };
        // SAFETY: as in `strata_eval`.
        let cols = unsafe { d.checked(bsdf, &["wo", "pdf"])? };
        let rows = cols.rows(bsdf, d.n)?;
        let answers = answers(bsdf, &rows);
        // SAFETY: as in `strata_eval`.
        unsafe {
            let (wi, wo) = d.directions()?;
            let wo = wo.ok_or_else(|| Failure::new(STRATA_ERR_NULL, "wo is NULL"))?;
            let pdf = output("pdf", d.pdf, 1, d.n)?;
            Ok(answers.pdf_into(&Queries::pairs(wi, wo), &mut |k, p| pdf[k] = p)?)
        }
    })
}

/// The unbiased pdf of `wo[k]` for sampling from `wi[k]`: the density of the
/// sampler's directions from `walks` density walks (1 to 2^40). Reads `wi`,
/// `wo`, `walks` and `columns`, writes `pdf`, `pdf_stderr` and `truncated`
/// (if given). Slow: for references and tests.
///
/// # Safety
/// As `strata_eval`.
#[no_mangle]
pub unsafe extern "C" fn strata_pdf_unbiased(
    b: *const StrataBsdf,
    batch: *const StrataBatch,
) -> i32 {
    guard("strata_pdf_unbiased", || {
        let reads = ["wo", "walks", "pdf", "pdf_stderr", "truncated"];
        // SAFETY: the caller guarantees `b` and `batch` (`begin`'s terms).
        let Some((bsdf, d)) = (unsafe { begin(b, batch, &reads)? }) else {
            return Ok(());
        };
        walk_count("walks", d.walks)?;
        // SAFETY: as in `strata_eval`.
        let cols = unsafe { d.checked(bsdf, &["wo", "pdf", "pdf_stderr"])? };
        let rows = cols.rows(bsdf, d.n)?;
        let answers = answers(bsdf, &rows);
        // SAFETY: as in `strata_eval`.
        unsafe {
            let (wi, wo) = d.directions()?;
            let wo = wo.ok_or_else(|| Failure::new(STRATA_ERR_NULL, "wo is NULL"))?;
            let pdf = output("pdf", d.pdf, 1, d.n)?;
            let se = output("pdf_stderr", d.pdf_stderr, 1, d.n)?;
            let q = Queries::pairs(wi, wo).walks(d.walks);
            let cut = answers.pdf_unbiased_into(&q, &mut |k, e| {
                pdf[k] = e.value as f32;
                se[k] = e.stderr as f32;
            })?;
            d.count(cut)
        }
    })
}

/// The directional albedo of each incident direction `wi[k]` from `walks`
/// walks each (1 to 2^40): reads `wi`, `walks`, `keys` and `columns`,
/// writes the records `albedo` and `truncated` (if given).
///
/// # Safety
/// As `strata_eval`.
#[no_mangle]
pub unsafe extern "C" fn strata_albedo(b: *const StrataBsdf, batch: *const StrataBatch) -> i32 {
    guard("strata_albedo", || {
        let reads = ["walks", "keys", "albedo", "truncated"];
        // SAFETY: the caller guarantees `b` and `batch` (`begin`'s terms).
        let Some((bsdf, d)) = (unsafe { begin(b, batch, &reads)? }) else {
            return Ok(());
        };
        walk_count("walks", d.walks)?;
        // SAFETY: as in `strata_eval`.
        let cols = unsafe { d.checked(bsdf, &["albedo"])? };
        let rows = cols.rows(bsdf, d.n)?;
        let answers = answers(bsdf, &rows);
        // SAFETY: as in `strata_eval`. `StrataAlbedo` has the layout of
        // `AlbedoRecord` (asserted at compile time).
        unsafe {
            let (wi, _) = d.directions()?;
            let out = output("albedo", d.albedo.cast::<AlbedoRecord>(), 1, d.n)?;
            let q = Queries {
                keys: d.keys()?,
                ..Queries::directions(wi)
            }
            .walks(d.walks);
            let cut = answers.albedo_into(&q, &mut |k, a| out[k] = AlbedoRecord::of(a))?;
            d.count(cut)
        }
    })
}

/// Writes to a float array of `3 n` as `n` triples.
fn triples_mut(v: &mut [f32]) -> &mut [[f32; 3]] {
    match VectorsMut::from_flat(v) {
        Some(VectorsMut::Aos(t)) => t,
        _ => &mut [],
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
