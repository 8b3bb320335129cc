//! Batch calls over the flat buffers a renderer keeps.
//!
//! A wavefront renderer holds the hits of one material as arrays: one array
//! per component (structure of arrays, as Dr.Jit and pbrt-v4's wavefront
//! integrator do) or one `[x, y, z]` per hit. [`Vectors`] reads either,
//! [`VectorsMut`] writes either, and the `*_into` / `*_records` methods of
//! [`LayeredBsdf`] take them, write into the caller's buffers and return
//! nothing but an error, or, for the calls that run walks to an estimate
//! (`eval_*`, `pdf_unbiased_into`, `albedo_records`), the number of walks
//! the limit of events ended in the call ([`LayeredBsdf::max_events`]),
//! summed over the batch: the sum of the [`Estimate::truncated`] the
//! per-query calls give (an albedo's reflected and transmitted fractions
//! share their walks, counted once). The records are `#[repr(C)]`, the
//! layout the C ABI hands out.
//!
//! Keys: with `keys = None` a query is keyed by its directions' bits, as the
//! plain methods key it, so the same pair always gives the same estimate
//! (and query `k` of an unkeyed sample batch draws sample index `k`, as line
//! `k` of `strata sample` does). With `Some(keys)` the renderer's sampler
//! drives the streams: query `k` draws from `(seed, keys[k])`.

use super::bsdf::{direction_at, direction_key, one_each, pdf_key, LayeredBsdf, Pair, Sample};
use super::columns::PerQuery;
use super::error::{check_walks, BatchError, Direction};
use super::materials::Materials;
use super::param_sets::Per;
use crate::estimator::pdf::{PdfEstimate, PdfKind};
use crate::estimator::wavefront::{with_kept, Sets, PDF_CHUNK};
use crate::estimator::Estimate;
use glam::Vec3;
use std::ops::Range;

/// The 3-vectors of a batch (directions), in either layout.
#[derive(Clone, Copy, Debug)]
pub enum Vectors<'a> {
    /// One `[x, y, z]` per query.
    Aos(&'a [[f32; 3]]),
    /// One slice per component, `[x, y, z]`, of equal lengths.
    Soa([&'a [f32]; 3]),
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
        }
    }

    /// Vectors `r` of a checked batch.
    fn range(&self, r: Range<usize>) -> Vectors<'a> {
        match self {
            Vectors::Aos(v) => Vectors::Aos(&v[r]),
            Vectors::Soa(c) => Vectors::Soa(c.map(|s| &s[r.clone()])),
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
        }
    }

    /// Checks the inputs of a call on pairs (`eval_into`, `eval_records`,
    /// `pdf_into`, `pdf_unbiased_into` and [`Materials`]' forms) as the call
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
    /// (`sample_into`, `sample_records`, `albedo_records`).
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
    fn count(&self, argument: &'static str) -> Result<usize, BatchError> {
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

    /// Checks that it holds one vector per query (all three slices, for SoA).
    fn check(&self, argument: &'static str, queries: usize) -> Result<(), BatchError> {
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
    /// The pdf [`LayeredBsdf::pdf`] gives for `(wi, wo)`.
    pub pdf: f32,
    /// [`SampleFlags`] bits.
    pub flags: u32,
}

impl SampleRecord {
    fn of(s: Option<&Sample>) -> Self {
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
    fn of(a: &crate::estimator::Albedo) -> Self {
        AlbedoRecord {
            reflected: f32x3(a.reflected.value),
            transmitted: f32x3(a.transmitted.value),
            reflected_stderr: f32x3(a.reflected.stderr),
            transmitted_stderr: f32x3(a.transmitted.stderr),
        }
    }
}

fn f32x3(v: [f64; 3]) -> [f32; 3] {
    v.map(|x| x as f32)
}

impl LayeredBsdf {
    /// `f(wi[k], wo[k])` for every query, `samples()` walks each, written to
    /// `f[k]` and (if given) `stderr[k]`; returns the number of walks the
    /// limit of events ended. Nothing is written on an error.
    pub fn eval_into(
        &self,
        wi: Vectors,
        wo: Vectors,
        keys: Option<&[u64]>,
        mut f: VectorsMut,
        mut stderr: Option<VectorsMut>,
    ) -> Result<u64, BatchError> {
        let n = self.pairs_count(&wi, &wo)?;
        f.check("f", n)?;
        if let Some(s) = &stderr {
            s.check("stderr", n)?;
        }
        self.evals(Per::OWN, &wi, &wo, keys, |k, e| {
            f.set(k, f32x3(e.value));
            if let Some(s) = &mut stderr {
                s.set(k, f32x3(e.stderr));
            }
        })
    }

    /// [`LayeredBsdf::eval_into`] into `#[repr(C)]` records.
    pub fn eval_records(
        &self,
        wi: Vectors,
        wo: Vectors,
        keys: Option<&[u64]>,
        out: &mut [EvalRecord],
    ) -> Result<u64, BatchError> {
        let n = self.pairs_count(&wi, &wo)?;
        one_each("out", out.len(), n)?;
        self.evals(Per::OWN, &wi, &wo, keys, |k, e| {
            out[k] = EvalRecord {
                f: f32x3(e.value),
                stderr: f32x3(e.stderr),
            }
        })
    }

    /// One sample per query, written to `wo`, `weight`, `pdf` and `flags`
    /// ([`SampleFlags`] bits; an absorbed walk writes zeros everywhere).
    pub fn sample_into(
        &self,
        wi: Vectors,
        keys: Option<&[u64]>,
        mut wo: VectorsMut,
        mut weight: VectorsMut,
        pdf: &mut [f32],
        flags: &mut [u32],
    ) -> Result<(), BatchError> {
        let n = wi.count("wi")?;
        wo.check("wo", n)?;
        weight.check("weight", n)?;
        one_each("pdf", pdf.len(), n)?;
        one_each("flags", flags.len(), n)?;
        self.samples_of(Per::OWN, &wi, keys, 0, |k, s| {
            let r = SampleRecord::of(s);
            wo.set(k, r.wo);
            weight.set(k, r.weight);
            pdf[k] = r.pdf;
            flags[k] = r.flags;
        })
    }

    /// [`LayeredBsdf::sample_into`] into `#[repr(C)]` records.
    pub fn sample_records(
        &self,
        wi: Vectors,
        keys: Option<&[u64]>,
        out: &mut [SampleRecord],
    ) -> Result<(), BatchError> {
        let n = wi.count("wi")?;
        one_each("out", out.len(), n)?;
        self.samples_of(Per::OWN, &wi, keys, 0, |k, s| out[k] = SampleRecord::of(s))
    }

    /// The approximate pdf of every pair, written to `pdf` (keyed by the
    /// directions, as [`LayeredBsdf::pdf`]).
    pub fn pdf_into(&self, wi: Vectors, wo: Vectors, pdf: &mut [f32]) -> Result<(), BatchError> {
        let n = self.pairs_count(&wi, &wo)?;
        one_each("pdf", pdf.len(), n)?;
        check_pairs(&wi, &wo)?;
        self.pdfs(Per::OWN, |k| pair_at(&wi, &wo, k), pdf);
        Ok(())
    }

    /// [`LayeredBsdf::eval_into`] and [`LayeredBsdf::pdf_into`] of the same
    /// pairs in one call, the numbers of the two (a renderer's light sample
    /// needs both): the directions are checked and normalized once. Returns
    /// the walks the limit of events ended; nothing is written on an error.
    pub fn eval_pdf_into(
        &self,
        wi: Vectors,
        wo: Vectors,
        keys: Option<&[u64]>,
        f: VectorsMut,
        stderr: Option<VectorsMut>,
        pdf: &mut [f32],
    ) -> Result<u64, BatchError> {
        let n = self.pairs_count(&wi, &wo)?;
        f.check("f", n)?;
        if let Some(s) = &stderr {
            s.check("stderr", n)?;
        }
        one_each("pdf", pdf.len(), n)?;
        let (mut f, mut stderr) = (f, stderr);
        let outputs = (0, &mut f, &mut stderr);
        self.eval_pdfs(Per::OWN, &wi, &wo, keys, outputs, pdf)
    }

    /// The evals and pdfs of checked queries, from one check of the pairs:
    /// query `k`'s eval to `f` and `stderr` at `start + k`, its pdf to
    /// `pdf[k]`.
    fn eval_pdfs(
        &self,
        per: Per,
        wi: &Vectors,
        wo: &Vectors,
        keys: Option<&[u64]>,
        (start, f, stderr): (usize, &mut VectorsMut, &mut Option<VectorsMut>),
        pdf: &mut [f32],
    ) -> Result<u64, BatchError> {
        let out = |k: usize, e: &Estimate| {
            f.set(start + k, f32x3(e.value));
            if let Some(s) = stderr {
                s.set(start + k, f32x3(e.stderr));
            }
        };
        let pdfs = |q: &[(Pair, u64)]| self.pdfs(per, |k| q[k].0, pdf);
        self.evals_then(per, wi, wo, keys, out, pdfs)
    }

    /// The approximate pdf of every checked pair (`pair(k)`, normalized),
    /// written to `pdf`.
    fn pdfs(&self, per: Per, pair: impl Fn(usize) -> Pair, pdf: &mut [f32]) {
        let n = pdf.len();
        if self.pdf_by_query_in(per, n) {
            for (k, p) in pdf.iter_mut().enumerate() {
                let (a, b) = pair(k);
                *p = self.pdf_one(per, k, a, b);
            }
            return;
        }
        if !per.is_own() {
            let pairs: Vec<Pair> = (0..n).map(pair).collect();
            pdf.copy_from_slice(&self.pdf_validated(per, &pairs));
            return;
        }
        if self.serial() || n <= PDF_CHUNK {
            // On this thread, from the buffers it keeps: allocates nothing
            // once warm (the numbers of `pdf_validated`, lane for lane).
            let keyed = |k: usize| {
                let (a, b) = pair(k);
                ((a, b), pdf_key(a, b))
            };
            let (walks, kind) = (self.pdf_walks, PdfKind::Approximate);
            let put = |k: usize, e: PdfEstimate| pdf[k] = e.value as f32;
            let own = Sets::Own;
            self.wave
                .pdf_each(own, n, keyed, walks, self.seed, kind, put);
            return;
        }
        let pairs: Vec<Pair> = (0..n).map(pair).collect();
        pdf.copy_from_slice(&self.pdf_validated(Per::OWN, &pairs));
    }

    /// The unbiased pdf of every pair from `samples` density walks each,
    /// written to `pdf` with its standard error in `stderr` (keyed by the
    /// directions, as [`LayeredBsdf::pdf_unbiased`]); returns the number of
    /// walks the limit of events ended.
    pub fn pdf_unbiased_into(
        &self,
        wi: Vectors,
        wo: Vectors,
        samples: u64,
        pdf: &mut [f32],
        stderr: &mut [f32],
    ) -> Result<u64, BatchError> {
        let n = self.pairs_count(&wi, &wo)?;
        one_each("pdf", pdf.len(), n)?;
        one_each("stderr", stderr.len(), n)?;
        check_walks("samples", samples).map_err(BatchError::call)?;
        check_pairs(&wi, &wo)?;
        Ok(self.pdfs_unbiased(Per::OWN, &wi, &wo, samples, pdf, stderr))
    }

    /// The unbiased pdfs of checked pairs into `pdf` and `stderr`; the
    /// walks the limit ended.
    fn pdfs_unbiased(
        &self,
        per: Per,
        wi: &Vectors,
        wo: &Vectors,
        samples: u64,
        pdf: &mut [f32],
        stderr: &mut [f32],
    ) -> u64 {
        let pairs: Vec<Pair> = (0..pdf.len()).map(|k| pair_at(wi, wo, k)).collect();
        let est = self.pdf_unbiased_validated(per, &pairs, samples);
        put_pdfs(&est, pdf, stderr)
    }

    /// The directional albedo of every incident direction, `n` walks each,
    /// into records; returns the number of walks the limit of events ended.
    pub fn albedo_records(
        &self,
        wi: Vectors,
        n: u64,
        keys: Option<&[u64]>,
        out: &mut [AlbedoRecord],
    ) -> Result<u64, BatchError> {
        let m = wi.count("wi")?;
        one_each("out", out.len(), m)?;
        check_walks("n", n).map_err(BatchError::call)?;
        for k in 0..m {
            direction_at("wi", k, wi.get(k))?;
        }
        if let Some(k) = keys {
            one_each("keys", k.len(), m)?;
        }
        Ok(self.albedos(Per::OWN, &wi, n, keys, out))
    }

    /// The albedos of checked directions into `out`; the walks the limit
    /// ended.
    fn albedos(
        &self,
        per: Per,
        wi: &Vectors,
        n: u64,
        keys: Option<&[u64]>,
        out: &mut [AlbedoRecord],
    ) -> u64 {
        let query = |k: usize| {
            let key = keys.map_or_else(|| direction_key(wi.get(k), wi.get(k)), |x| x[k]);
            (dir_at(wi, k), key)
        };
        let mut cut = 0;
        self.albedo_each(per, out.len(), n, query, |k, a| {
            cut += a.reflected.truncated;
            out[k] = AlbedoRecord::of(&a);
        });
        cut
    }

    /// The number of `(wi, wo)` queries, checking that the two agree.
    fn pairs_count(&self, wi: &Vectors, wo: &Vectors) -> Result<usize, BatchError> {
        let n = wi.count("wi")?;
        one_each("wo", wo.count("wo")?, n)?;
        Ok(n)
    }

    /// The eval of every pair, handed to `out` in query order once every
    /// input is known to be valid; returns the walks the limit ended. Calls that run query by query (the
    /// scalar engine, a closed form) allocate nothing, nor do serial
    /// wavefront batches on a warm thread; parallel ones allocate in rayon.
    fn evals(
        &self,
        per: Per,
        wi: &Vectors,
        wo: &Vectors,
        keys: Option<&[u64]>,
        out: impl FnMut(usize, &Estimate) + Send,
    ) -> Result<u64, BatchError> {
        self.evals_then(per, wi, wo, keys, out, |_| ())
    }

    /// [`LayeredBsdf::evals`], then `then` of the checked queries (each
    /// pair normalized, and its key).
    fn evals_then(
        &self,
        per: Per,
        wi: &Vectors,
        wo: &Vectors,
        keys: Option<&[u64]>,
        mut out: impl FnMut(usize, &Estimate) + Send,
        then: impl FnOnce(&[(Pair, u64)]),
    ) -> Result<u64, BatchError> {
        let n = wi.len();
        check_walks("samples", self.samples).map_err(BatchError::call)?;
        // Each query's directions, normalized and keyed once (the engines
        // read a query several times), in a buffer the thread keeps.
        with_kept(&QUERIES, |queries| {
            queries.clear();
            for k in 0..n {
                let (a, b) = (wi.get(k), wo.get(k));
                let pair = (direction_at("wi", k, a)?, direction_at("wo", k, b)?);
                queries.push((pair, direction_key(a, b)));
            }
            if let Some(keys) = keys {
                one_each("keys", keys.len(), n)?;
                for (q, &key) in queries.iter_mut().zip(keys) {
                    q.1 = key;
                }
            }
            let queries = &queries[..];
            let mut cut = 0;
            self.eval_each(
                per,
                n,
                self.samples,
                |k| queries[k],
                |k, e| {
                    cut += e.truncated;
                    out(k, &e)
                },
            );
            then(queries);
            Ok(cut)
        })
    }

    /// The sample of every query, handed to `out` in query order: unkeyed
    /// queries draw sample index `k` of their direction's key, keyed ones
    /// sample index 0 of their key. Allocates nothing on the scalar engine,
    /// nor serially on a warm thread.
    fn samples_of(
        &self,
        per: Per,
        wi: &Vectors,
        keys: Option<&[u64]>,
        first: usize,
        mut out: impl FnMut(usize, Option<&Sample>),
    ) -> Result<(), BatchError> {
        let n = wi.len();
        for k in 0..n {
            direction_at("wi", k, wi.get(k))?;
        }
        if let Some(k) = keys {
            one_each("keys", k.len(), n)?;
        }
        let stream = |k: usize| match keys {
            Some(x) => (x[k], 0),
            None => (direction_key(wi.get(k), wi.get(k)), (first + k) as u64),
        };
        let query = |k: usize| {
            let (key, index) = stream(k);
            (dir_at(wi, k), key, index)
        };
        self.sample_each(per, n, query, |k, s| out(k, s.as_ref()));
        Ok(())
    }
}

/// The slice calls of [`Materials`]: query `k` on material `material[k]`,
/// keyed and indexed as [`LayeredBsdf`]'s slice calls key theirs (unkeyed
/// queries by their directions' bits, an unkeyed sample `k` with sample
/// index `k`, a keyed one with index 0), so that a query answers what the
/// BSDF of its material alone answers. Nothing is written before every
/// query is known to be valid. What the C ABI's and the Python module's
/// per-query forms run.
impl Materials {
    /// [`LayeredBsdf::eval_into`] of every pair on its material.
    pub fn eval_into(
        &self,
        material: &[u32],
        wi: Vectors,
        wo: Vectors,
        keys: Option<&[u64]>,
        mut f: VectorsMut,
        mut stderr: Option<VectorsMut>,
    ) -> Result<u64, BatchError> {
        let pairs = pairs_of(&wi, &wo)?;
        f.check("f", pairs.len())?;
        if let Some(s) = &stderr {
            s.check("stderr", pairs.len())?;
        }
        let est = match keys {
            None => self.eval_batch(material, &pairs)?,
            Some(k) => self.eval_batch_keyed(material, &pairs, self.samples(), k)?,
        };
        Ok(put_evals(0, &est, &mut f, &mut stderr))
    }

    /// [`LayeredBsdf::sample_into`] of every query on its material (its
    /// arguments and the materials).
    #[allow(clippy::too_many_arguments)]
    pub fn sample_into(
        &self,
        material: &[u32],
        wi: Vectors,
        keys: Option<&[u64]>,
        mut wo: VectorsMut,
        mut weight: VectorsMut,
        pdf: &mut [f32],
        flags: &mut [u32],
    ) -> Result<(), BatchError> {
        let n = wi.count("wi")?;
        wo.check("wo", n)?;
        weight.check("weight", n)?;
        one_each("pdf", pdf.len(), n)?;
        one_each("flags", flags.len(), n)?;
        for (k, s) in self.samples_of(material, &wi, keys)?.iter().enumerate() {
            let r = SampleRecord::of(s.as_ref());
            wo.set(k, r.wo);
            weight.set(k, r.weight);
            pdf[k] = r.pdf;
            flags[k] = r.flags;
        }
        Ok(())
    }

    /// [`Materials::sample_into`] into `#[repr(C)]` records.
    pub fn sample_records(
        &self,
        material: &[u32],
        wi: Vectors,
        keys: Option<&[u64]>,
        out: &mut [SampleRecord],
    ) -> Result<(), BatchError> {
        one_each("out", out.len(), wi.count("wi")?)?;
        for (o, s) in out.iter_mut().zip(self.samples_of(material, &wi, keys)?) {
            *o = SampleRecord::of(s.as_ref());
        }
        Ok(())
    }

    /// [`LayeredBsdf::pdf_into`] of every pair on its material.
    pub fn pdf_into(
        &self,
        material: &[u32],
        wi: Vectors,
        wo: Vectors,
        pdf: &mut [f32],
    ) -> Result<(), BatchError> {
        let pairs = pairs_of(&wi, &wo)?;
        one_each("pdf", pdf.len(), pairs.len())?;
        pdf.copy_from_slice(&self.pdf_batch(material, &pairs)?);
        Ok(())
    }

    /// [`LayeredBsdf::pdf_unbiased_into`] of every pair on its material.
    pub fn pdf_unbiased_into(
        &self,
        material: &[u32],
        wi: Vectors,
        wo: Vectors,
        samples: u64,
        pdf: &mut [f32],
        stderr: &mut [f32],
    ) -> Result<u64, BatchError> {
        let pairs = pairs_of(&wi, &wo)?;
        one_each("pdf", pdf.len(), pairs.len())?;
        one_each("stderr", stderr.len(), pairs.len())?;
        let est = self.pdf_unbiased_batch(material, &pairs, samples)?;
        Ok(put_pdfs(&est, pdf, stderr))
    }

    /// [`LayeredBsdf::albedo_records`] of every query on its material.
    pub fn albedo_records(
        &self,
        material: &[u32],
        wi: Vectors,
        n: u64,
        keys: Option<&[u64]>,
        out: &mut [AlbedoRecord],
    ) -> Result<u64, BatchError> {
        let wis = dirs_of(&wi)?;
        one_each("out", out.len(), wis.len())?;
        let own: Vec<u64>;
        let keys = match keys {
            Some(k) => k,
            None => {
                own = wis.iter().map(|&w| direction_key(w, w)).collect();
                &own
            }
        };
        let albedos = self.albedo_batch_keyed(material, &wis, n, keys)?;
        Ok(put_albedos(&albedos, out))
    }

    /// The samples of every query, keyed and indexed as the slice calls do.
    fn samples_of(
        &self,
        material: &[u32],
        wi: &Vectors,
        keys: Option<&[u64]>,
    ) -> Result<Vec<Option<Sample>>, BatchError> {
        let wis = dirs_of(wi)?;
        let n = wis.len();
        match keys {
            None => self.sample_batch(material, &wis, &(0..n as u64).collect::<Vec<_>>()),
            Some(k) => self.sample_batch_keyed(material, &wis, k, &vec![0; n]),
        }
    }
}

/// The slice calls of [`PerQuery`]: [`Materials`]' calls of the same
/// name on the materials of [`Materials::per_query`] (query `k` on material
/// `k`), run a chunk at a time: the same numbers, bit for bit. Every
/// argument is checked before the first chunk runs, so nothing is written
/// on an error; a chunk's buffers are allocated fallibly when the call
/// starts ([`QueryError::OutOfMemory`](super::QueryError::OutOfMemory)).
impl PerQuery<'_> {
    /// [`Materials::eval_into`].
    pub fn eval_into(
        &self,
        wi: Vectors,
        wo: Vectors,
        keys: Option<&[u64]>,
        mut f: VectorsMut,
        mut stderr: Option<VectorsMut>,
    ) -> Result<u64, BatchError> {
        let n = self.pairs_checked(&wi, &wo, keys, true)?;
        f.check("f", n)?;
        if let Some(s) = &stderr {
            s.check("stderr", n)?;
        }
        check_walks("samples", self.template.samples).map_err(BatchError::call)?;
        let mut cut = 0;
        let in_place = self.in_place_chunks("eval", |per, r| {
            let (a, b) = (wi.range(r.clone()), wo.range(r.clone()));
            let keys = keys.map(|x| &x[r.clone()]);
            cut += self.rows_bsdf().evals(per, &a, &b, keys, |k, e| {
                f.set(r.start + k, f32x3(e.value));
                if let Some(s) = &mut stderr {
                    s.set(r.start + k, f32x3(e.stderr));
                }
            })?;
            Ok(())
        });
        if let Some(done) = in_place {
            return done.map(|()| cut);
        }
        let mut pairs = self.buffer("eval")?;
        self.chunks("eval", |m, ids, r| {
            pairs.clear();
            pairs.extend(r.clone().map(|k| (wi.get(k), wo.get(k))));
            let est = match keys {
                None => m.eval_batch(ids, &pairs)?,
                Some(x) => m.eval_batch_keyed(ids, &pairs, m.samples(), &x[r.clone()])?,
            };
            cut += put_evals(r.start, &est, &mut f, &mut stderr);
            Ok(())
        })?;
        Ok(cut)
    }

    /// [`Materials::sample_into`].
    pub fn sample_into(
        &self,
        wi: Vectors,
        keys: Option<&[u64]>,
        mut wo: VectorsMut,
        mut weight: VectorsMut,
        pdf: &mut [f32],
        flags: &mut [u32],
    ) -> Result<(), BatchError> {
        let n = self.directions_checked(&wi, keys, true)?;
        wo.check("wo", n)?;
        weight.check("weight", n)?;
        one_each("pdf", pdf.len(), n)?;
        one_each("flags", flags.len(), n)?;
        self.samples_of(&wi, keys, |k, s| {
            let r = SampleRecord::of(s);
            wo.set(k, r.wo);
            weight.set(k, r.weight);
            pdf[k] = r.pdf;
            flags[k] = r.flags;
        })
    }

    /// [`Materials::sample_records`].
    pub fn sample_records(
        &self,
        wi: Vectors,
        keys: Option<&[u64]>,
        out: &mut [SampleRecord],
    ) -> Result<(), BatchError> {
        let n = self.directions_checked(&wi, keys, true)?;
        one_each("out", out.len(), n)?;
        self.samples_of(&wi, keys, |k, s| out[k] = SampleRecord::of(s))
    }

    /// [`LayeredBsdf::eval_pdf_into`]: [`PerQuery::eval_into`] and
    /// [`PerQuery::pdf_into`] of the same pairs in one call, the numbers of
    /// the two, each row's table found once.
    pub fn eval_pdf_into(
        &self,
        wi: Vectors,
        wo: Vectors,
        keys: Option<&[u64]>,
        mut f: VectorsMut,
        mut stderr: Option<VectorsMut>,
        pdf: &mut [f32],
    ) -> Result<u64, BatchError> {
        let n = self.pairs_checked(&wi, &wo, keys, true)?;
        f.check("f", n)?;
        if let Some(s) = &stderr {
            s.check("stderr", n)?;
        }
        one_each("pdf", pdf.len(), n)?;
        check_walks("samples", self.template.samples).map_err(BatchError::call)?;
        let mut cut = 0;
        let in_place = self.in_place_chunks("eval_pdf", |per, r| {
            let (a, b) = (wi.range(r.clone()), wo.range(r.clone()));
            let keys = keys.map(|x| &x[r.clone()]);
            let outputs = (r.start, &mut f, &mut stderr);
            cut += (self.rows_bsdf()).eval_pdfs(per, &a, &b, keys, outputs, &mut pdf[r])?;
            Ok(())
        });
        if let Some(done) = in_place {
            return done.map(|()| cut);
        }
        // Rows that are materials: the two calls (every pair is checked
        // above, so the second cannot fail after the first wrote).
        let cut = self.eval_into(wi, wo, keys, f, stderr)?;
        self.pdf_into(wi, wo, pdf)?;
        Ok(cut)
    }

    /// [`Materials::pdf_into`].
    pub fn pdf_into(&self, wi: Vectors, wo: Vectors, pdf: &mut [f32]) -> Result<(), BatchError> {
        let n = self.pairs_checked(&wi, &wo, None, false)?;
        one_each("pdf", pdf.len(), n)?;
        let in_place = self.in_place_chunks("pdf", |per, r| {
            let (a, b) = (wi.range(r.clone()), wo.range(r.clone()));
            self.rows_bsdf()
                .pdfs(per, |k| pair_at(&a, &b, k), &mut pdf[r]);
            Ok(())
        });
        if let Some(done) = in_place {
            return done;
        }
        let mut pairs = self.buffer("pdf")?;
        self.chunks("pdf", |m, ids, r| {
            pairs.clear();
            pairs.extend(r.clone().map(|k| (wi.get(k), wo.get(k))));
            pdf[r].copy_from_slice(&m.pdf_batch(ids, &pairs)?);
            Ok(())
        })
    }

    /// [`Materials::pdf_unbiased_into`].
    pub fn pdf_unbiased_into(
        &self,
        wi: Vectors,
        wo: Vectors,
        samples: u64,
        pdf: &mut [f32],
        stderr: &mut [f32],
    ) -> Result<u64, BatchError> {
        let n = self.pairs_checked(&wi, &wo, None, false)?;
        one_each("pdf", pdf.len(), n)?;
        one_each("stderr", stderr.len(), n)?;
        check_walks("samples", samples).map_err(BatchError::call)?;
        let mut cut = 0;
        let in_place = self.in_place_chunks("pdf_unbiased", |per, r| {
            let (a, b) = (wi.range(r.clone()), wo.range(r.clone()));
            let (p, e) = (&mut pdf[r.clone()], &mut stderr[r]);
            cut += self.rows_bsdf().pdfs_unbiased(per, &a, &b, samples, p, e);
            Ok(())
        });
        if let Some(done) = in_place {
            return done.map(|()| cut);
        }
        let mut pairs = self.buffer("pdf_unbiased")?;
        self.chunks("pdf_unbiased", |m, ids, r| {
            pairs.clear();
            pairs.extend(r.clone().map(|k| (wi.get(k), wo.get(k))));
            let est = m.pdf_unbiased_batch(ids, &pairs, samples)?;
            cut += put_pdfs(&est, &mut pdf[r.clone()], &mut stderr[r]);
            Ok(())
        })?;
        Ok(cut)
    }

    /// [`Materials::albedo_records`].
    pub fn albedo_records(
        &self,
        wi: Vectors,
        n: u64,
        keys: Option<&[u64]>,
        out: &mut [AlbedoRecord],
    ) -> Result<u64, BatchError> {
        let m = self.directions_checked(&wi, keys, false)?;
        one_each("out", out.len(), m)?;
        check_walks("n", n).map_err(BatchError::call)?;
        let mut cut = 0;
        let in_place = self.in_place_chunks("albedo", |per, r| {
            let keys = keys.map(|x| &x[r.clone()]);
            let a = wi.range(r.clone());
            cut += self.rows_bsdf().albedos(per, &a, n, keys, &mut out[r]);
            Ok(())
        });
        if let Some(done) = in_place {
            return done.map(|()| cut);
        }
        let (mut wis, mut own) = (self.buffer("albedo")?, self.buffer("albedo")?);
        self.chunks("albedo", |mats, ids, r| {
            wis.clear();
            wis.extend(r.clone().map(|k| wi.get(k)));
            let keys = match keys {
                Some(x) => &x[r.clone()],
                None => {
                    own.clear();
                    own.extend(wis.iter().map(|&w| direction_key(w, w)));
                    &own[..]
                }
            };
            let albedos = mats.albedo_batch_keyed(ids, &wis, n, keys)?;
            cut += put_albedos(&albedos, &mut out[r]);
            Ok(())
        })?;
        Ok(cut)
    }

    /// The samples of every query, keyed and indexed as
    /// [`Materials::sample_into`] does (an unkeyed query `k` of the whole
    /// batch draws sample index `k`), handed to `out` in query order.
    fn samples_of(
        &self,
        wi: &Vectors,
        keys: Option<&[u64]>,
        mut out: impl FnMut(usize, Option<&Sample>),
    ) -> Result<(), BatchError> {
        let in_place = self.in_place_chunks("sample", |per, r| {
            let keys = keys.map(|x| &x[r.clone()]);
            let a = wi.range(r.clone());
            let start = r.start;
            (self.rows_bsdf()).samples_of(per, &a, keys, start, |k, s| out(start + k, s))
        });
        if let Some(done) = in_place {
            return done;
        }
        let (mut wis, mut index) = (self.buffer("sample")?, self.buffer("sample")?);
        self.chunks("sample", |m, ids, r| {
            wis.clear();
            wis.extend(r.clone().map(|k| wi.get(k)));
            index.clear();
            let s = match keys {
                None => {
                    index.extend(r.clone().map(|k| k as u64));
                    m.sample_batch(ids, &wis, &index)?
                }
                Some(x) => {
                    index.resize(r.len(), 0);
                    m.sample_batch_keyed(ids, &wis, &x[r.clone()], &index)?
                }
            };
            for (k, s) in r.zip(&s) {
                out(k, s.as_ref());
            }
            Ok(())
        })
    }

    /// Checks a call on pairs before anything runs: one pair per query, each
    /// of two directions, and keys (if given) one per query. Where the
    /// call's own checks run first (`call_checks`: eval and sample check
    /// every direction and key of a chunk before they write) and the batch
    /// is one chunk of rows in place, only the lengths (which slicing a
    /// chunk needs).
    fn pairs_checked(
        &self,
        wi: &Vectors,
        wo: &Vectors,
        keys: Option<&[u64]>,
        call_checks: bool,
    ) -> Result<usize, BatchError> {
        let n = if call_checks && self.one_chunk_in_place() {
            let n = wi.count("wi")?;
            one_each("wo", wo.count("wo")?, n)?;
            if let Some(k) = keys {
                one_each("keys", k.len(), n)?;
            }
            n
        } else {
            Vectors::check_pairs(wi, wo, keys)?
        };
        one_each("wi", n, self.queries)?;
        Ok(n)
    }

    /// [`PerQuery::pairs_checked`] for a call on incident directions.
    fn directions_checked(
        &self,
        wi: &Vectors,
        keys: Option<&[u64]>,
        call_checks: bool,
    ) -> Result<usize, BatchError> {
        let n = if call_checks && self.one_chunk_in_place() {
            let n = wi.count("wi")?;
            if let Some(k) = keys {
                one_each("keys", k.len(), n)?;
            }
            n
        } else {
            Vectors::check_directions(wi, keys)?
        };
        one_each("wi", n, self.queries)?;
        Ok(n)
    }
}

/// Writes the evals of queries `start..` to `f` and `stderr`; the walks
/// the limit ended.
fn put_evals(
    start: usize,
    est: &[Estimate],
    f: &mut VectorsMut,
    stderr: &mut Option<VectorsMut>,
) -> u64 {
    for (k, e) in (start..).zip(est) {
        f.set(k, f32x3(e.value));
        if let Some(s) = stderr {
            s.set(k, f32x3(e.stderr));
        }
    }
    est.iter().map(|e| e.truncated).sum()
}

/// Writes unbiased pdfs to `pdf` and `stderr`; the walks the limit ended.
fn put_pdfs(est: &[PdfEstimate], pdf: &mut [f32], stderr: &mut [f32]) -> u64 {
    for ((e, p), s) in est.iter().zip(pdf).zip(stderr) {
        *p = e.value as f32;
        *s = e.stderr as f32;
    }
    est.iter().map(|e| e.truncated).sum()
}

/// Writes albedos to records; the walks the limit ended (the reflected and
/// transmitted fractions come from the same walks: counted once).
fn put_albedos(albedos: &[crate::estimator::Albedo], out: &mut [AlbedoRecord]) -> u64 {
    for (o, a) in out.iter_mut().zip(albedos) {
        *o = AlbedoRecord::of(a);
    }
    albedos.iter().map(|a| a.reflected.truncated).sum()
}

/// The pairs of a batch, checking that `wi` and `wo` have one each.
fn pairs_of(wi: &Vectors, wo: &Vectors) -> Result<Vec<(Vec3, Vec3)>, BatchError> {
    let n = wi.count("wi")?;
    one_each("wo", wo.count("wo")?, n)?;
    Ok((0..n).map(|k| (wi.get(k), wo.get(k))).collect())
}

/// The directions of a batch.
fn dirs_of(wi: &Vectors) -> Result<Vec<Vec3>, BatchError> {
    Ok((0..wi.count("wi")?).map(|k| wi.get(k)).collect())
}

/// Checks that every pair holds two directions (the error names the first
/// query that does not), allocating nothing.
fn check_pairs(wi: &Vectors, wo: &Vectors) -> Result<(), BatchError> {
    for k in 0..wi.len() {
        direction_at("wi", k, wi.get(k))?;
        direction_at("wo", k, wo.get(k))?;
    }
    Ok(())
}

thread_local! {
    /// The checked queries of this thread's eval calls.
    static QUERIES: std::cell::RefCell<Option<Vec<(Pair, u64)>>> =
        const { std::cell::RefCell::new(None) };
}

/// Direction `k` of a checked batch.
fn dir_at(v: &Vectors, k: usize) -> [f64; 3] {
    Direction::new("wi", v.get(k)).map_or([0.0; 3], Direction::get)
}

/// Pair `k` of a checked batch.
fn pair_at(wi: &Vectors, wo: &Vectors, k: usize) -> Pair {
    (dir_at(wi, k), dir_at(wo, k))
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
        let mut f = [[0.0f32; 3]; 4];
        let bsdf =
            crate::LayeredBsdf::new(crate::materials::builtin("clear_coat_lambertian").unwrap());
        let call = bsdf.eval_into(g, b, None, super::VectorsMut::Aos(&mut f), None);
        // (As text: NaN != NaN.)
        let check = Vectors::check_pairs(&g, &b, None).map(|_| ());
        assert_eq!(
            call.map(|_| ()).map_err(|e| e.to_string()),
            check.map_err(|e| e.to_string())
        );
    }
}
