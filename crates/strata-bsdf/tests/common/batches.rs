//! The batch calls as the tests write them, over the library's one batch
//! path ([`Bsdf`] and [`Queries`]): vectors of pairs in and vectors of
//! answers out (`Batches`), or the caller's flat buffers (`Buffers`), as the
//! tests' assertions compare them. Each is a few lines over one trait call,
//! so every test that uses them runs that call. (They keep the argument
//! lists of the calls they stand for.)
#![allow(clippy::too_many_arguments)]

use glam::Vec3;
use strata_bsdf::{
    Albedo, AlbedoRecord, BatchError, Bsdf, Estimate, EvalBuffers, EvalRecord, LayeredBsdf,
    Materials, PdfEstimate, PerQuery, Queries, QueryError, Sample, SampleBuffers, SampleRecord,
    Vectors, VectorsMut,
};

/// Answers in query order, from a call that hands them out one by one.
fn collect<T: Clone + Send + Default>(
    n: usize,
    call: impl FnOnce(&mut (dyn FnMut(usize, T) + Send)) -> Result<(), BatchError>,
) -> Result<Vec<T>, BatchError> {
    let mut v = vec![T::default(); n];
    call(&mut |k, x| v[k] = x)?;
    Ok(v)
}

fn split(pairs: &[(Vec3, Vec3)]) -> (Vec<Vec3>, Vec<Vec3>) {
    pairs.iter().copied().unzip()
}

/// The Vec forms of a table's calls, with `rows` (a [`Materials`]' query
/// materials; `None` for a BSDF or per-query columns).
fn evals(
    b: &dyn Bsdf,
    rows: Option<&[u32]>,
    pairs: &[(Vec3, Vec3)],
    walks: Option<u64>,
    keys: Option<&[u64]>,
) -> Result<Vec<Estimate>, BatchError> {
    let (wi, wo) = split(pairs);
    let q = Queries {
        keys,
        rows,
        walks,
        ..Queries::pairs(&wi, &wo)
    };
    collect(pairs.len(), |out| {
        b.eval_into(&q, &mut |k, e| out(k, *e)).map(|_| ())
    })
}

fn samples(
    b: &dyn Bsdf,
    rows: Option<&[u32]>,
    wis: &[Vec3],
    keys: Option<&[u64]>,
    index: &[u64],
) -> Result<Vec<Option<Sample>>, BatchError> {
    let q = Queries {
        keys,
        rows,
        indices: Some(index),
        ..Queries::directions(wis)
    };
    collect(wis.len(), |out| {
        b.sample_into(&q, &mut |k, s| out(k, s.copied()))
    })
}

fn pdfs(
    b: &dyn Bsdf,
    rows: Option<&[u32]>,
    pairs: &[(Vec3, Vec3)],
) -> Result<Vec<f32>, BatchError> {
    let (wi, wo) = split(pairs);
    let q = Queries {
        rows,
        ..Queries::pairs(&wi, &wo)
    };
    collect(pairs.len(), |out| b.pdf_into(&q, out))
}

fn pdfs_unbiased(
    b: &dyn Bsdf,
    rows: Option<&[u32]>,
    pairs: &[(Vec3, Vec3)],
    walks: u64,
) -> Result<Vec<PdfEstimate>, BatchError> {
    let (wi, wo) = split(pairs);
    let q = Queries {
        rows,
        ..Queries::pairs(&wi, &wo).walks(walks)
    };
    collect(pairs.len(), |out| {
        b.pdf_unbiased_into(&q, &mut |k, e| out(k, *e)).map(|_| ())
    })
}

fn albedos(
    b: &dyn Bsdf,
    rows: Option<&[u32]>,
    wis: &[Vec3],
    walks: u64,
    keys: Option<&[u64]>,
) -> Result<Vec<Albedo>, BatchError> {
    let q = Queries {
        keys,
        rows,
        ..Queries::directions(wis).walks(walks)
    };
    collect(wis.len(), |out| {
        b.albedo_into(&q, &mut |k, a| out(k, *a)).map(|_| ())
    })
}

/// The Vec forms of a BSDF's (or per-query columns') batch calls.
pub trait Batches {
    /// `f` of every pair, keyed by the directions.
    fn eval_batch(&self, pairs: &[(Vec3, Vec3)]) -> Result<Vec<Estimate>, BatchError>;
    /// `f` of every pair from `samples` walks with explicit keys.
    fn eval_batch_keyed(
        &self,
        pairs: &[(Vec3, Vec3)],
        samples: u64,
        keys: &[u64],
    ) -> Result<Vec<Estimate>, BatchError>;
    /// One sample per direction, sample index `index[k]` of its direction's key.
    fn sample_batch(&self, wis: &[Vec3], index: &[u64]) -> Result<Vec<Option<Sample>>, BatchError>;
    /// One sample per direction from `(keys[k], index[k])`.
    fn sample_batch_keyed(
        &self,
        wis: &[Vec3],
        keys: &[u64],
        index: &[u64],
    ) -> Result<Vec<Option<Sample>>, BatchError>;
    /// The pdf of every pair.
    fn pdf_batch(&self, pairs: &[(Vec3, Vec3)]) -> Result<Vec<f32>, BatchError>;
    /// The unbiased pdf of every pair from `samples` density walks.
    fn pdf_unbiased_batch(
        &self,
        pairs: &[(Vec3, Vec3)],
        samples: u64,
    ) -> Result<Vec<PdfEstimate>, BatchError>;
    /// The albedo of every direction from `n` walks, keyed by the direction.
    fn albedo_batch(&self, wis: &[Vec3], n: u64) -> Result<Vec<Albedo>, BatchError>;
    /// The albedo of every direction from `n` walks with explicit keys.
    fn albedo_batch_keyed(
        &self,
        wis: &[Vec3],
        n: u64,
        keys: &[u64],
    ) -> Result<Vec<Albedo>, BatchError>;
    /// `f(wi, wo)` from `samples` walks with key `key`.
    fn eval_with(&self, wi: Vec3, wo: Vec3, samples: u64, key: u64)
        -> Result<Estimate, QueryError>;
}

/// The Vec forms of a BSDF's and of per-query columns' batch calls.
macro_rules! batches {
    ($t:ty) => {
        impl Batches for $t {
            fn eval_batch(&self, pairs: &[(Vec3, Vec3)]) -> Result<Vec<Estimate>, BatchError> {
                evals(self, None, pairs, None, None)
            }
            fn eval_batch_keyed(
                &self,
                pairs: &[(Vec3, Vec3)],
                samples: u64,
                keys: &[u64],
            ) -> Result<Vec<Estimate>, BatchError> {
                evals(self, None, pairs, Some(samples), Some(keys))
            }
            fn sample_batch(
                &self,
                wis: &[Vec3],
                index: &[u64],
            ) -> Result<Vec<Option<Sample>>, BatchError> {
                samples(self, None, wis, None, index)
            }
            fn sample_batch_keyed(
                &self,
                wis: &[Vec3],
                keys: &[u64],
                index: &[u64],
            ) -> Result<Vec<Option<Sample>>, BatchError> {
                samples(self, None, wis, Some(keys), index)
            }
            fn pdf_batch(&self, pairs: &[(Vec3, Vec3)]) -> Result<Vec<f32>, BatchError> {
                pdfs(self, None, pairs)
            }
            fn pdf_unbiased_batch(
                &self,
                pairs: &[(Vec3, Vec3)],
                samples: u64,
            ) -> Result<Vec<PdfEstimate>, BatchError> {
                pdfs_unbiased(self, None, pairs, samples)
            }
            fn albedo_batch(&self, wis: &[Vec3], n: u64) -> Result<Vec<Albedo>, BatchError> {
                albedos(self, None, wis, n, None)
            }
            fn albedo_batch_keyed(
                &self,
                wis: &[Vec3],
                n: u64,
                keys: &[u64],
            ) -> Result<Vec<Albedo>, BatchError> {
                albedos(self, None, wis, n, Some(keys))
            }
            fn eval_with(
                &self,
                wi: Vec3,
                wo: Vec3,
                samples: u64,
                key: u64,
            ) -> Result<Estimate, QueryError> {
                let e = evals(self, None, &[(wi, wo)], Some(samples), Some(&[key]));
                Ok(e.map_err(|e| e.error)?[0])
            }
        }
    };
}

batches!(LayeredBsdf);
batches!(PerQuery<'_>);

/// The Vec forms of [`Materials`]' batch calls: query `k` on material
/// `material[k]`.
pub trait MaterialBatches {
    fn eval_batch(
        &self,
        material: &[u32],
        pairs: &[(Vec3, Vec3)],
    ) -> Result<Vec<Estimate>, BatchError>;
    fn eval_batch_keyed(
        &self,
        material: &[u32],
        pairs: &[(Vec3, Vec3)],
        samples: u64,
        keys: &[u64],
    ) -> Result<Vec<Estimate>, BatchError>;
    fn sample_batch(
        &self,
        material: &[u32],
        wis: &[Vec3],
        index: &[u64],
    ) -> Result<Vec<Option<Sample>>, BatchError>;
    fn sample_batch_keyed(
        &self,
        material: &[u32],
        wis: &[Vec3],
        keys: &[u64],
        index: &[u64],
    ) -> Result<Vec<Option<Sample>>, BatchError>;
    fn pdf_batch(&self, material: &[u32], pairs: &[(Vec3, Vec3)]) -> Result<Vec<f32>, BatchError>;
    fn pdf_unbiased_batch(
        &self,
        material: &[u32],
        pairs: &[(Vec3, Vec3)],
        samples: u64,
    ) -> Result<Vec<PdfEstimate>, BatchError>;
    fn albedo_batch_keyed(
        &self,
        material: &[u32],
        wis: &[Vec3],
        n: u64,
        keys: &[u64],
    ) -> Result<Vec<Albedo>, BatchError>;
}

impl MaterialBatches for Materials {
    fn eval_batch(
        &self,
        material: &[u32],
        pairs: &[(Vec3, Vec3)],
    ) -> Result<Vec<Estimate>, BatchError> {
        evals(self, Some(material), pairs, None, None)
    }
    fn eval_batch_keyed(
        &self,
        material: &[u32],
        pairs: &[(Vec3, Vec3)],
        samples: u64,
        keys: &[u64],
    ) -> Result<Vec<Estimate>, BatchError> {
        evals(self, Some(material), pairs, Some(samples), Some(keys))
    }
    fn sample_batch(
        &self,
        material: &[u32],
        wis: &[Vec3],
        index: &[u64],
    ) -> Result<Vec<Option<Sample>>, BatchError> {
        samples(self, Some(material), wis, None, index)
    }
    fn sample_batch_keyed(
        &self,
        material: &[u32],
        wis: &[Vec3],
        keys: &[u64],
        index: &[u64],
    ) -> Result<Vec<Option<Sample>>, BatchError> {
        samples(self, Some(material), wis, Some(keys), index)
    }
    fn pdf_batch(&self, material: &[u32], pairs: &[(Vec3, Vec3)]) -> Result<Vec<f32>, BatchError> {
        pdfs(self, Some(material), pairs)
    }
    fn pdf_unbiased_batch(
        &self,
        material: &[u32],
        pairs: &[(Vec3, Vec3)],
        samples: u64,
    ) -> Result<Vec<PdfEstimate>, BatchError> {
        pdfs_unbiased(self, Some(material), pairs, samples)
    }
    fn albedo_batch_keyed(
        &self,
        material: &[u32],
        wis: &[Vec3],
        n: u64,
        keys: &[u64],
    ) -> Result<Vec<Albedo>, BatchError> {
        albedos(self, Some(material), wis, n, Some(keys))
    }
}

/// The flat-buffer forms of the batch calls, as a renderer's arrays take
/// them: outputs are checked for one entry per query first (nothing is
/// written on an error).
pub trait Buffers {
    fn eval_buffers(
        &self,
        wi: Vectors,
        wo: Vectors,
        keys: Option<&[u64]>,
        f: VectorsMut,
        stderr: Option<VectorsMut>,
    ) -> Result<u64, BatchError>;
    fn eval_records(
        &self,
        wi: Vectors,
        wo: Vectors,
        keys: Option<&[u64]>,
        out: &mut [EvalRecord],
    ) -> Result<u64, BatchError>;
    fn eval_pdf_buffers(
        &self,
        wi: Vectors,
        wo: Vectors,
        keys: Option<&[u64]>,
        f: VectorsMut,
        stderr: Option<VectorsMut>,
        pdf: &mut [f32],
    ) -> Result<u64, BatchError>;
    fn sample_buffers(
        &self,
        wi: Vectors,
        keys: Option<&[u64]>,
        wo: VectorsMut,
        weight: VectorsMut,
        pdf: &mut [f32],
        flags: &mut [u32],
    ) -> Result<(), BatchError>;
    fn sample_records(
        &self,
        wi: Vectors,
        keys: Option<&[u64]>,
        out: &mut [SampleRecord],
    ) -> Result<(), BatchError>;
    fn pdf_buffers(&self, wi: Vectors, wo: Vectors, pdf: &mut [f32]) -> Result<(), BatchError>;
    fn pdf_unbiased_buffers(
        &self,
        wi: Vectors,
        wo: Vectors,
        samples: u64,
        pdf: &mut [f32],
        stderr: &mut [f32],
    ) -> Result<u64, BatchError>;
    fn albedo_records(
        &self,
        wi: Vectors,
        n: u64,
        keys: Option<&[u64]>,
        out: &mut [AlbedoRecord],
    ) -> Result<u64, BatchError>;
}

/// One entry per query in a plain output slice.
fn one_each(argument: &'static str, len: usize, queries: usize) -> Result<(), BatchError> {
    if len == queries {
        return Ok(());
    }
    Err(BatchError {
        index: None,
        error: QueryError::LengthMismatch {
            argument,
            len,
            queries,
        },
    })
}

fn eval_buffers(
    b: &dyn Bsdf,
    rows: Option<&[u32]>,
    wi: Vectors,
    wo: Vectors,
    keys: Option<&[u64]>,
    f: VectorsMut,
    stderr: Option<VectorsMut>,
) -> Result<u64, BatchError> {
    let q = Queries {
        keys,
        rows,
        ..Queries::pairs(wi, wo)
    };
    let mut out = EvalBuffers { f, stderr };
    out.check(wi.len())?;
    b.eval_into(&q, &mut |k, e| out.put(k, e))
}

fn eval_records(
    b: &dyn Bsdf,
    rows: Option<&[u32]>,
    wi: Vectors,
    wo: Vectors,
    keys: Option<&[u64]>,
    out: &mut [EvalRecord],
) -> Result<u64, BatchError> {
    one_each("out", out.len(), wi.len())?;
    let q = Queries {
        keys,
        rows,
        ..Queries::pairs(wi, wo)
    };
    b.eval_into(&q, &mut |k, e| out[k] = EvalRecord::of(e))
}

fn eval_pdf_buffers(
    b: &dyn Bsdf,
    rows: Option<&[u32]>,
    wi: Vectors,
    wo: Vectors,
    keys: Option<&[u64]>,
    f: VectorsMut,
    stderr: Option<VectorsMut>,
    pdf: &mut [f32],
) -> Result<u64, BatchError> {
    let q = Queries {
        keys,
        rows,
        ..Queries::pairs(wi, wo)
    };
    let mut out = EvalBuffers { f, stderr };
    out.check(wi.len())?;
    one_each("pdf", pdf.len(), wi.len())?;
    b.eval_pdf_into(&q, &mut |k, e| out.put(k, e), &mut |k, p| pdf[k] = p)
}

fn sample_buffers(
    b: &dyn Bsdf,
    rows: Option<&[u32]>,
    wi: Vectors,
    keys: Option<&[u64]>,
    wo: VectorsMut,
    weight: VectorsMut,
    pdf: &mut [f32],
    flags: &mut [u32],
) -> Result<(), BatchError> {
    let q = Queries {
        keys,
        rows,
        ..Queries::directions(wi)
    };
    let mut out = SampleBuffers {
        wo,
        weight,
        pdf,
        flags,
    };
    out.check(wi.len())?;
    b.sample_into(&q, &mut |k, s| out.put(k, s))
}

fn sample_records(
    b: &dyn Bsdf,
    rows: Option<&[u32]>,
    wi: Vectors,
    keys: Option<&[u64]>,
    out: &mut [SampleRecord],
) -> Result<(), BatchError> {
    one_each("out", out.len(), wi.len())?;
    let q = Queries {
        keys,
        rows,
        ..Queries::directions(wi)
    };
    b.sample_into(&q, &mut |k, s| out[k] = SampleRecord::of(s))
}

fn pdf_buffers(
    b: &dyn Bsdf,
    rows: Option<&[u32]>,
    wi: Vectors,
    wo: Vectors,
    pdf: &mut [f32],
) -> Result<(), BatchError> {
    one_each("pdf", pdf.len(), wi.len())?;
    let q = Queries {
        rows,
        ..Queries::pairs(wi, wo)
    };
    b.pdf_into(&q, &mut |k, p| pdf[k] = p)
}

fn pdf_unbiased_buffers(
    b: &dyn Bsdf,
    rows: Option<&[u32]>,
    wi: Vectors,
    wo: Vectors,
    samples: u64,
    pdf: &mut [f32],
    stderr: &mut [f32],
) -> Result<u64, BatchError> {
    one_each("pdf", pdf.len(), wi.len())?;
    one_each("stderr", stderr.len(), wi.len())?;
    let q = Queries {
        rows,
        ..Queries::pairs(wi, wo).walks(samples)
    };
    b.pdf_unbiased_into(&q, &mut |k, e| {
        pdf[k] = e.value as f32;
        stderr[k] = e.stderr as f32;
    })
}

fn albedo_records(
    b: &dyn Bsdf,
    rows: Option<&[u32]>,
    wi: Vectors,
    n: u64,
    keys: Option<&[u64]>,
    out: &mut [AlbedoRecord],
) -> Result<u64, BatchError> {
    one_each("out", out.len(), wi.len())?;
    let q = Queries {
        keys,
        rows,
        ..Queries::directions(wi).walks(n)
    };
    b.albedo_into(&q, &mut |k, a| out[k] = AlbedoRecord::of(a))
}

macro_rules! buffers {
    ($t:ty) => {
        impl Buffers for $t {
            fn eval_buffers(
                &self,
                wi: Vectors,
                wo: Vectors,
                keys: Option<&[u64]>,
                f: VectorsMut,
                stderr: Option<VectorsMut>,
            ) -> Result<u64, BatchError> {
                eval_buffers(self, None, wi, wo, keys, f, stderr)
            }
            fn eval_records(
                &self,
                wi: Vectors,
                wo: Vectors,
                keys: Option<&[u64]>,
                out: &mut [EvalRecord],
            ) -> Result<u64, BatchError> {
                eval_records(self, None, wi, wo, keys, out)
            }
            fn eval_pdf_buffers(
                &self,
                wi: Vectors,
                wo: Vectors,
                keys: Option<&[u64]>,
                f: VectorsMut,
                stderr: Option<VectorsMut>,
                pdf: &mut [f32],
            ) -> Result<u64, BatchError> {
                eval_pdf_buffers(self, None, wi, wo, keys, f, stderr, pdf)
            }
            fn sample_buffers(
                &self,
                wi: Vectors,
                keys: Option<&[u64]>,
                wo: VectorsMut,
                weight: VectorsMut,
                pdf: &mut [f32],
                flags: &mut [u32],
            ) -> Result<(), BatchError> {
                sample_buffers(self, None, wi, keys, wo, weight, pdf, flags)
            }
            fn sample_records(
                &self,
                wi: Vectors,
                keys: Option<&[u64]>,
                out: &mut [SampleRecord],
            ) -> Result<(), BatchError> {
                sample_records(self, None, wi, keys, out)
            }
            fn pdf_buffers(
                &self,
                wi: Vectors,
                wo: Vectors,
                pdf: &mut [f32],
            ) -> Result<(), BatchError> {
                pdf_buffers(self, None, wi, wo, pdf)
            }
            fn pdf_unbiased_buffers(
                &self,
                wi: Vectors,
                wo: Vectors,
                samples: u64,
                pdf: &mut [f32],
                stderr: &mut [f32],
            ) -> Result<u64, BatchError> {
                pdf_unbiased_buffers(self, None, wi, wo, samples, pdf, stderr)
            }
            fn albedo_records(
                &self,
                wi: Vectors,
                n: u64,
                keys: Option<&[u64]>,
                out: &mut [AlbedoRecord],
            ) -> Result<u64, BatchError> {
                albedo_records(self, None, wi, n, keys, out)
            }
        }
    };
}

buffers!(LayeredBsdf);
buffers!(PerQuery<'_>);

/// The flat-buffer forms of [`Materials`]' calls: query `k` on material
/// `material[k]`.
pub trait MaterialBuffers {
    fn eval_buffers(
        &self,
        material: &[u32],
        wi: Vectors,
        wo: Vectors,
        keys: Option<&[u64]>,
        f: VectorsMut,
        stderr: Option<VectorsMut>,
    ) -> Result<u64, BatchError>;
    fn sample_buffers(
        &self,
        material: &[u32],
        wi: Vectors,
        keys: Option<&[u64]>,
        wo: VectorsMut,
        weight: VectorsMut,
        pdf: &mut [f32],
        flags: &mut [u32],
    ) -> Result<(), BatchError>;
    fn sample_records(
        &self,
        material: &[u32],
        wi: Vectors,
        keys: Option<&[u64]>,
        out: &mut [SampleRecord],
    ) -> Result<(), BatchError>;
    fn pdf_buffers(
        &self,
        material: &[u32],
        wi: Vectors,
        wo: Vectors,
        pdf: &mut [f32],
    ) -> Result<(), BatchError>;
    fn pdf_unbiased_buffers(
        &self,
        material: &[u32],
        wi: Vectors,
        wo: Vectors,
        samples: u64,
        pdf: &mut [f32],
        stderr: &mut [f32],
    ) -> Result<u64, BatchError>;
    fn albedo_records(
        &self,
        material: &[u32],
        wi: Vectors,
        n: u64,
        keys: Option<&[u64]>,
        out: &mut [AlbedoRecord],
    ) -> Result<u64, BatchError>;
}

impl MaterialBuffers for Materials {
    fn eval_buffers(
        &self,
        material: &[u32],
        wi: Vectors,
        wo: Vectors,
        keys: Option<&[u64]>,
        f: VectorsMut,
        stderr: Option<VectorsMut>,
    ) -> Result<u64, BatchError> {
        eval_buffers(self, Some(material), wi, wo, keys, f, stderr)
    }
    fn sample_buffers(
        &self,
        material: &[u32],
        wi: Vectors,
        keys: Option<&[u64]>,
        wo: VectorsMut,
        weight: VectorsMut,
        pdf: &mut [f32],
        flags: &mut [u32],
    ) -> Result<(), BatchError> {
        sample_buffers(self, Some(material), wi, keys, wo, weight, pdf, flags)
    }
    fn sample_records(
        &self,
        material: &[u32],
        wi: Vectors,
        keys: Option<&[u64]>,
        out: &mut [SampleRecord],
    ) -> Result<(), BatchError> {
        sample_records(self, Some(material), wi, keys, out)
    }
    fn pdf_buffers(
        &self,
        material: &[u32],
        wi: Vectors,
        wo: Vectors,
        pdf: &mut [f32],
    ) -> Result<(), BatchError> {
        pdf_buffers(self, Some(material), wi, wo, pdf)
    }
    fn pdf_unbiased_buffers(
        &self,
        material: &[u32],
        wi: Vectors,
        wo: Vectors,
        samples: u64,
        pdf: &mut [f32],
        stderr: &mut [f32],
    ) -> Result<u64, BatchError> {
        pdf_unbiased_buffers(self, Some(material), wi, wo, samples, pdf, stderr)
    }
    fn albedo_records(
        &self,
        material: &[u32],
        wi: Vectors,
        n: u64,
        keys: Option<&[u64]>,
        out: &mut [AlbedoRecord],
    ) -> Result<u64, BatchError> {
        albedo_records(self, Some(material), wi, n, keys, out)
    }
}
