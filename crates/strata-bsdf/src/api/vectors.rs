//! The flat buffers a renderer keeps, as a batch reads and writes them.
//!
//! A wavefront renderer holds the hits of one material as arrays: one array
//! per component (structure of arrays, as Dr.Jit and pbrt-v4's wavefront
//! integrator do), one `[x, y, z]` per hit, or `glam::Vec3`s. [`Vectors`]
//! reads any of them, [`VectorsMut`] writes either of the first two, and
//! the records are the `#[repr(C)]` layouts the C ABI hands out.

use super::bsdf::{direction_at, one_each, Sample};
use super::error::BatchError;
use crate::estimator::{Albedo, Estimate};
use glam::Vec3;
use std::ops::Range;

/// The 3-vectors of a batch (directions), in either layout.
#[derive(Clone, Copy, Debug)]
pub enum Vectors<'a> {
    /// One `[x, y, z]` per query.
    Aos(&'a [[f32; 3]]),
    /// One slice per component, `[x, y, z]`, of equal lengths.
    Soa([&'a [f32]; 3]),
    /// One `glam::Vec3` per query.
    Vec3(&'a [Vec3]),
}

impl<'a> From<&'a [[f32; 3]]> for Vectors<'a> {
    fn from(v: &'a [[f32; 3]]) -> Self {
        Vectors::Aos(v)
    }
}

impl<'a> From<[&'a [f32]; 3]> for Vectors<'a> {
    fn from(v: [&'a [f32]; 3]) -> Self {
        Vectors::Soa(v)
    }
}

impl<'a> From<&'a [Vec3]> for Vectors<'a> {
    fn from(v: &'a [Vec3]) -> Self {
        Vectors::Vec3(v)
    }
}

impl<'a> From<&'a Vec<Vec3>> for Vectors<'a> {
    fn from(v: &'a Vec<Vec3>) -> Self {
        Vectors::Vec3(v)
    }
}

impl<'a> Vectors<'a> {
    /// From a flat slice of `3 n` floats, `x, y, z` per query (the C layout);
    /// `None` if its length is not a multiple of 3.
    pub fn from_flat(v: &'a [f32]) -> Option<Self> {
        (v.len() % 3 == 0).then(|| Vectors::Aos(as_triples(v)))
    }

    /// The number of vectors (of the `x` slice, for SoA).
    pub fn len(&self) -> usize {
        match self {
            Vectors::Aos(v) => v.len(),
            Vectors::Soa(c) => c[0].len(),
            Vectors::Vec3(v) => v.len(),
        }
    }

    /// Vectors `r` of a checked batch.
    pub(super) fn range(&self, r: Range<usize>) -> Vectors<'a> {
        match self {
            Vectors::Aos(v) => Vectors::Aos(&v[r]),
            Vectors::Soa(c) => Vectors::Soa(c.map(|s| &s[r.clone()])),
            Vectors::Vec3(v) => Vectors::Vec3(&v[r]),
        }
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Vector `i`.
    ///
    /// # Panics
    /// If `i` is out of range of a slice (the batch calls check the lengths
    /// first, naming the argument).
    pub fn get(&self, i: usize) -> Vec3 {
        match self {
            Vectors::Aos(v) => Vec3::from(v[i]),
            Vectors::Soa(c) => Vec3::new(c[0][i], c[1][i], c[2][i]),
            Vectors::Vec3(v) => v[i],
        }
    }

    /// Checks the inputs of a call on pairs (`eval_into`, `eval_pdf_into`,
    /// `pdf_into` and `pdf_unbiased_into` of [`Bsdf`](super::Bsdf)) as the call
    /// checks them, without running it and allocating nothing: `wi` and
    /// `wo` hold one vector per query (the SoA slices too), each a direction
    /// (the error names the first query that is not), and `keys`, if given,
    /// one per query. Returns the number of queries. For a binding that must
    /// know the call can run before it allocates its results.
    pub fn check_pairs(
        wi: &Vectors,
        wo: &Vectors,
        keys: Option<&[u64]>,
    ) -> Result<usize, BatchError> {
        let n = wi.count("wi")?;
        one_each("wo", wo.count("wo")?, n)?;
        check_pairs(wi, wo)?;
        if let Some(k) = keys {
            one_each("keys", k.len(), n)?;
        }
        Ok(n)
    }

    /// [`Vectors::check_pairs`] for a call on incident directions alone
    /// (`sample_into`, `albedo_into`).
    pub fn check_directions(wi: &Vectors, keys: Option<&[u64]>) -> Result<usize, BatchError> {
        let n = wi.count("wi")?;
        for k in 0..n {
            direction_at("wi", k, wi.get(k))?;
        }
        if let Some(k) = keys {
            one_each("keys", k.len(), n)?;
        }
        Ok(n)
    }

    /// The number of queries, checking that the three SoA slices agree.
    pub(super) fn count(&self, argument: &'static str) -> Result<usize, BatchError> {
        if let Vectors::Soa(c) = self {
            for (axis, s) in [(".y", c[1]), (".z", c[2])] {
                one_each(component(argument, axis), s.len(), c[0].len())?;
            }
        }
        Ok(self.len())
    }
}

/// Output 3-vectors (values per RGB channel, or directions), in either layout.
#[derive(Debug)]
pub enum VectorsMut<'a> {
    /// One `[x, y, z]` (or `[r, g, b]`) per query.
    Aos(&'a mut [[f32; 3]]),
    /// One slice per component, of equal lengths.
    Soa([&'a mut [f32]; 3]),
}

impl<'a> VectorsMut<'a> {
    /// From a flat slice of `3 n` floats; `None` if its length is not a
    /// multiple of 3.
    pub fn from_flat(v: &'a mut [f32]) -> Option<Self> {
        (v.len() % 3 == 0).then(|| VectorsMut::Aos(as_triples_mut(v)))
    }

    /// The number of vectors (of the first slice, for SoA).
    pub fn len(&self) -> usize {
        match self {
            VectorsMut::Aos(v) => v.len(),
            VectorsMut::Soa(c) => c[0].len(),
        }
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Writes vector `i`.
    ///
    /// # Panics
    /// If `i` is out of range of a slice (the batch calls check the lengths
    /// first, naming the argument).
    pub fn set(&mut self, i: usize, v: [f32; 3]) {
        match self {
            VectorsMut::Aos(a) => a[i] = v,
            VectorsMut::Soa(c) => {
                for (s, x) in c.iter_mut().zip(v) {
                    s[i] = x;
                }
            }
        }
    }

    /// Checks that it holds one vector per query (all three slices, for
    /// SoA); the error names `argument` (and the component).
    pub fn check(&self, argument: &'static str, queries: usize) -> Result<(), BatchError> {
        match self {
            VectorsMut::Aos(a) => one_each(argument, a.len(), queries),
            VectorsMut::Soa(c) => {
                for (axis, s) in [(".x", &c[0]), (".y", &c[1]), (".z", &c[2])] {
                    one_each(component(argument, axis), s.len(), queries)?;
                }
                Ok(())
            }
        }
    }
}

/// A caller's buffers for a batch of evals: `f` and, if given, `stderr`,
/// one 3-vector per query.
#[derive(Debug)]
pub struct EvalBuffers<'a> {
    /// `f(wi, wo)` per channel.
    pub f: VectorsMut<'a>,
    /// Its standard error per channel.
    pub stderr: Option<VectorsMut<'a>>,
}

impl EvalBuffers<'_> {
    /// Checks that every buffer holds `queries` entries (naming the one
    /// that does not).
    pub fn check(&self, queries: usize) -> Result<(), BatchError> {
        self.f.check("f", queries)?;
        match &self.stderr {
            Some(s) => s.check("stderr", queries),
            None => Ok(()),
        }
    }

    /// Writes query `k`'s estimate.
    pub fn put(&mut self, k: usize, e: &Estimate) {
        self.f.set(k, f32x3(e.value));
        if let Some(s) = &mut self.stderr {
            s.set(k, f32x3(e.stderr));
        }
    }
}

/// A caller's buffers for a batch of samples: the direction, weight, pdf
/// and [`SampleFlags`] of each query (an absorbed walk writes zeros).
#[derive(Debug)]
pub struct SampleBuffers<'a> {
    /// The sampled directions.
    pub wo: VectorsMut<'a>,
    /// `f |cos θo| / p` per channel.
    pub weight: VectorsMut<'a>,
    /// The pdf of each sampled direction.
    pub pdf: &'a mut [f32],
    /// [`SampleFlags`] bits.
    pub flags: &'a mut [u32],
}

impl SampleBuffers<'_> {
    /// Checks that every buffer holds `queries` entries (naming the one
    /// that does not).
    pub fn check(&self, queries: usize) -> Result<(), BatchError> {
        self.wo.check("wo", queries)?;
        self.weight.check("weight", queries)?;
        one_each("pdf", self.pdf.len(), queries)?;
        one_each("flags", self.flags.len(), queries)
    }

    /// Writes query `k`'s sample.
    pub fn put(&mut self, k: usize, s: Option<&Sample>) {
        let r = SampleRecord::of(s);
        self.wo.set(k, r.wo);
        self.weight.set(k, r.weight);
        self.pdf[k] = r.pdf;
        self.flags[k] = r.flags;
    }
}

/// The name of one component of an argument (`"wi.y"`), for errors.
fn component(argument: &'static str, axis: &'static str) -> &'static str {
    const NAMES: &[(&str, &str, &str)] = &[
        ("wi", ".x", "wi.x"),
        ("wi", ".y", "wi.y"),
        ("wi", ".z", "wi.z"),
        ("wo", ".x", "wo.x"),
        ("wo", ".y", "wo.y"),
        ("wo", ".z", "wo.z"),
        ("f", ".x", "f.r"),
        ("f", ".y", "f.g"),
        ("f", ".z", "f.b"),
        ("stderr", ".x", "stderr.r"),
        ("stderr", ".y", "stderr.g"),
        ("stderr", ".z", "stderr.b"),
        ("weight", ".x", "weight.r"),
        ("weight", ".y", "weight.g"),
        ("weight", ".z", "weight.b"),
    ];
    NAMES
        .iter()
        .find(|(a, x, _)| *a == argument && *x == axis)
        .map_or(argument, |n| n.2)
}

fn as_triples(v: &[f32]) -> &[[f32; 3]] {
    let n = v.len() / 3;
    // SAFETY: `[f32; 3]` has the size and alignment of three `f32`s, and the
    // slice holds at least `3 n` of them, so the first `n` triples are in
    // bounds; the borrow is carried over.
    unsafe { std::slice::from_raw_parts(v.as_ptr().cast::<[f32; 3]>(), n) }
}

fn as_triples_mut(v: &mut [f32]) -> &mut [[f32; 3]] {
    let n = v.len() / 3;
    // SAFETY: as in `as_triples`; the exclusive borrow is carried over.
    unsafe { std::slice::from_raw_parts_mut(v.as_mut_ptr().cast::<[f32; 3]>(), n) }
}

/// One eval result, as the C ABI lays it out.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct EvalRecord {
    /// `f(wi, wo)` per channel, without the cosine.
    pub f: [f32; 3],
    /// Its standard error per channel.
    pub stderr: [f32; 3],
}

impl EvalRecord {
    /// The record of an estimate.
    pub fn of(e: &Estimate) -> Self {
        EvalRecord {
            f: f32x3(e.value),
            stderr: f32x3(e.stderr),
        }
    }
}

/// The lobe a sample came from, as bits: [`SampleFlags::REFLECTION`] or
/// [`SampleFlags::TRANSMISSION`], and [`SampleFlags::DELTA`] when every
/// event of its walk was a delta. An absorbed walk has no bit set.
#[repr(transparent)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SampleFlags(pub u32);

impl SampleFlags {
    /// The walk left on the side it entered.
    pub const REFLECTION: u32 = 1;
    /// The walk left on the other side.
    pub const TRANSMISSION: u32 = 2;
    /// Every event of the walk was a delta: a specular direction.
    pub const DELTA: u32 = 4;

    /// The flags of a sample, or of an absorbed walk (`None`).
    pub fn of(s: Option<&Sample>) -> Self {
        SampleFlags(s.map_or(0, |s| {
            let side = if s.reflection {
                Self::REFLECTION
            } else {
                Self::TRANSMISSION
            };
            side | if s.specular { Self::DELTA } else { 0 }
        }))
    }
}

/// One sample, as the C ABI lays it out. An absorbed walk is all zeros
/// (flags 0): count it as a zero-weight sample.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SampleRecord {
    /// The sampled direction (unit), or zeros if absorbed.
    pub wo: [f32; 3],
    /// `f |cos θo| / p` per channel.
    pub weight: [f32; 3],
    /// The pdf [`LayeredBsdf::pdf`](super::LayeredBsdf::pdf) gives for `(wi, wo)`.
    pub pdf: f32,
    /// [`SampleFlags`] bits.
    pub flags: u32,
}

impl SampleRecord {
    /// The record of a sample, or of an absorbed walk (`None`).
    pub fn of(s: Option<&Sample>) -> Self {
        match s {
            Some(s) => SampleRecord {
                wo: s.wo.to_array(),
                weight: s.weight,
                pdf: s.pdf,
                flags: SampleFlags::of(Some(s)).0,
            },
            None => SampleRecord::default(),
        }
    }
}

/// One albedo result, as the C ABI lays it out.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AlbedoRecord {
    /// Reflected fraction per channel.
    pub reflected: [f32; 3],
    /// Transmitted fraction per channel.
    pub transmitted: [f32; 3],
    /// Standard error of the reflected fraction.
    pub reflected_stderr: [f32; 3],
    /// Standard error of the transmitted fraction.
    pub transmitted_stderr: [f32; 3],
}

impl AlbedoRecord {
    /// The record of an estimate.
    pub fn of(a: &Albedo) -> Self {
        AlbedoRecord {
            reflected: f32x3(a.reflected.value),
            transmitted: f32x3(a.transmitted.value),
            reflected_stderr: f32x3(a.reflected.stderr),
            transmitted_stderr: f32x3(a.transmitted.stderr),
        }
    }
}

pub(super) fn f32x3(v: [f64; 3]) -> [f32; 3] {
    v.map(|x| x as f32)
}

/// Checks that every pair holds two directions (the error names the first
/// query that does not), allocating nothing.
pub(super) fn check_pairs(wi: &Vectors, wo: &Vectors) -> Result<(), BatchError> {
    for k in 0..wi.len() {
        direction_at("wi", k, wi.get(k))?;
        direction_at("wo", k, wo.get(k))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::Vectors;
    use crate::api::QueryError;

    /// The checks a binding runs before it allocates results give the
    /// errors of the calls themselves.
    #[test]
    fn inputs_are_checked_as_the_calls_check_them() {
        let good = [[0.0, 0.0, 1.0f32]; 4];
        let mut bad = good;
        bad[2] = [f32::NAN, 0.0, 1.0];
        let (g, b) = (Vectors::Aos(&good), Vectors::Aos(&bad));
        assert_eq!(Vectors::check_pairs(&g, &g, None), Ok(4));
        assert_eq!(Vectors::check_directions(&g, Some(&[1, 2, 3, 4])), Ok(4));
        let e = Vectors::check_pairs(&g, &b, None).unwrap_err();
        assert_eq!(e.index, Some(2));
        assert!(
            matches!(e.error, QueryError::NonFinite { argument: "wo", .. }),
            "{e}"
        );
        assert_eq!(
            Vectors::check_directions(&b, None).unwrap_err().index,
            Some(2)
        );
        let short = Vectors::Aos(&good[..3]);
        let e = Vectors::check_pairs(&g, &short, None).unwrap_err();
        assert_eq!((e.index, e.to_string().contains("wo")), (None, true), "{e}");
        let e = Vectors::check_directions(&g, Some(&[1])).unwrap_err();
        assert!(e.to_string().contains("keys"), "{e}");
        use crate::api::{Bsdf, Queries};
        let bsdf =
            crate::LayeredBsdf::new(crate::materials::builtin("clear_coat_lambertian").unwrap());
        let mut written = false;
        let call = bsdf.eval_into(&Queries::pairs(g, b), &mut |_, _| written = true);
        assert!(!written, "nothing is handed out on an error");
        // (As text: NaN != NaN.)
        let check = Vectors::check_pairs(&g, &b, None).map(|_| ());
        assert_eq!(
            call.map(|_| ()).map_err(|e| e.to_string()),
            check.map_err(|e| e.to_string())
        );
    }
}
