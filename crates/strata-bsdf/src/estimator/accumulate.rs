//! Streaming mean and variance (Welford), per RGB channel, in f64.

use super::estimate::Estimate;

/// Running mean and variance of RGB samples.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MeanVar {
    n: u64,
    mean: [f64; 3],
    m2: [f64; 3],
    /// Walks that reached the limit of events ([`Estimate::truncated`]).
    cut: u64,
}

impl MeanVar {
    /// Empty.
    pub fn new() -> Self {
        Self::default()
    }
    /// `n` samples of zero: what pushing them one by one gives, bit for bit
    /// (every update adds an exact zero), in constant time.
    pub fn zeros(n: u64) -> Self {
        MeanVar {
            n,
            ..Self::default()
        }
    }
    /// Adds one walk's value; `cut`: the walk reached the limit of events.
    #[inline]
    pub fn push_walk(&mut self, x: [f64; 3], cut: bool) {
        self.cut += u64::from(cut);
        self.push(x);
    }
    /// Adds one sample.
    #[inline]
    pub fn push(&mut self, x: [f64; 3]) {
        self.n += 1;
        // One division per sample, off the chain of dependent updates (a
        // division per channel on that chain set the pace of the reduction).
        let inv_n = 1.0 / self.n as f64;
        for ((m, m2), x) in self.mean.iter_mut().zip(&mut self.m2).zip(x) {
            let d = x - *m;
            *m += d * inv_n;
            *m2 += d * (x - *m);
        }
    }
    /// Merges another accumulator (Chan et al.), so batches can be combined in
    /// any grouping with the same result up to rounding.
    pub fn merge(&mut self, o: &MeanVar) {
        if o.n == 0 {
            return;
        }
        if self.n == 0 {
            *self = *o;
            return;
        }
        self.cut += o.cut;
        let n = (self.n + o.n) as f64;
        for c in 0..3 {
            let d = o.mean[c] - self.mean[c];
            self.mean[c] += d * o.n as f64 / n;
            self.m2[c] += o.m2[c] + d * d * self.n as f64 * o.n as f64 / n;
        }
        self.n += o.n;
    }
    /// Number of samples.
    pub fn count(&self) -> u64 {
        self.n
    }
    /// Mean and standard error of the mean.
    pub fn estimate(&self) -> Estimate {
        let n = self.n.max(1) as f64;
        let se = |c: usize| {
            if self.n > 1 {
                (self.m2[c] / (n - 1.0) / n).sqrt()
            } else {
                0.0
            }
        };
        Estimate {
            value: self.mean,
            stderr: [se(0), se(1), se(2)],
            samples: self.n,
            truncated: self.cut,
        }
    }
    /// The estimate shifted by a deterministic term (e.g. the first-order
    /// reflection), which adds no variance.
    pub fn estimate_plus(&self, d: [f64; 3]) -> Estimate {
        let mut e = self.estimate();
        for (v, d) in e.value.iter_mut().zip(d) {
            *v += d;
        }
        e
    }
}

/// Walks are reduced in blocks of this many consecutive samples.
pub const BLOCK: u64 = 256;

/// Reduces one query's walk values in the canonical order that makes results
/// independent of threads and batching: samples in blocks of [`BLOCK`], each
/// block accumulated in sample order, blocks merged in block order. The scalar
/// engine pushes in sample order; the wavefront engine reduces each finished
/// block the same way and merges blocks by index, so the two agree bit for bit
/// whenever their walks do.
#[derive(Clone, Copy, Debug, Default)]
pub struct BlockReducer {
    total: MeanVar,
    block: MeanVar,
}

impl BlockReducer {
    /// Empty.
    pub fn new() -> Self {
        Self::default()
    }
    /// Adds the next sample's value.
    #[inline]
    pub fn push(&mut self, x: [f64; 3]) {
        self.push_walk(x, false);
    }
    /// Adds the next walk's value; `cut`: it reached the limit of events.
    #[inline]
    pub fn push_walk(&mut self, x: [f64; 3], cut: bool) {
        self.block.push_walk(x, cut);
        if self.block.count() == BLOCK {
            self.total.merge(&self.block);
            self.block = MeanVar::new();
        }
    }
    /// Adds a whole block (the next one in order).
    pub fn push_block(&mut self, b: &MeanVar) {
        debug_assert_eq!(self.block.count(), 0);
        self.total.merge(b);
    }
    /// The reduction of everything pushed.
    pub fn finish(mut self) -> MeanVar {
        self.total.merge(&self.block);
        self.total
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zeros_is_pushing_zeros() {
        for n in [0, 1, 2, 255, 256, 257, 1000] {
            let mut r = BlockReducer::new();
            (0..n).for_each(|_| r.push([0.0; 3]));
            let pushed = r.finish();
            assert_eq!(pushed, MeanVar::zeros(n), "n = {n}");
            assert_eq!(pushed.estimate(), MeanVar::zeros(n).estimate());
        }
    }
}
