//! The pdfs of `sample()` (method.md §6), both from the density walk of
//! [`super::density`]:
//!
//! * **approximate** (what `pdf()` and `sample()` return): density walks,
//!   each stopped after [`APPROX_EVENTS`] events, as many as a pilot round
//!   says a relative standard error of 0.15 needs, the pilot's mean and the
//!   fresh walks' blended by a weight fixed in advance ([`PdfWalks`]), mixed
//!   with a uniform density, `pdf = (1 − f) p + f / 4π`
//!   ([`UNIFORM_FRACTION`]), so that it is positive wherever `f` can be. It is
//!   deterministic for a pair of directions (the walks are keyed by them).
//!   What it neglects: paths longer than the bound, and the noise of its
//!   walks (it is an unbiased estimate of the density of walks of at most
//!   [`APPROX_EVENTS`] events, then mixed);
//! * **unbiased**: the mean of many unbounded density walks, with its
//!   standard error: the density of `sample()`'s directions, for references
//!   and tests.

use super::density::DensityWalk;
use super::scalar::{v3, Scalar, ScalarEngine};
use super::settings::MAX_WALKS;
use crate::lane::LaneMask;
use crate::rng::{query_prefix, Stream, WalkRng};

/// Weight of the uniform density in the approximate pdf's mixture.
pub const UNIFORM_FRACTION: f64 = 0.03;

/// The approximate pdf's bound on a density walk's events: more than any
/// stack of the examples needs for 99 % of its density, and a bound on the
/// cost of a pdf in stacks whose walks are long (a white medium).
pub const APPROX_EVENTS: u32 = 64;

/// Mixes the estimated density `p` with the uniform one.
pub fn mix_uniform(p: f64) -> f64 {
    let uniform = UNIFORM_FRACTION / (4.0 * std::f64::consts::PI);
    let p = (1.0 - UNIFORM_FRACTION) * p + uniform;
    if p.is_finite() {
        p
    } else {
        uniform
    }
}

/// How an approximate pdf is made: the lobe pdf (no walks,
/// [`PdfWalks::LOBES`], the default), or density walks, a fixed number or a
/// pilot round that sets it. The pilot's walks give one walk's relative
/// variance `v`; then `v / rel_stderr²` fresh walks run (at least as many
/// as the pilot, at most `max`), so that the pdf's relative standard error
/// is about `rel_stderr`. A mean over all the walks would be biased (walks
/// that happened to agree stop early), so the pdf blends the pilot's mean
/// and the fresh walks' mean with a weight fixed in advance
/// ([`PdfWalks::pilot_weight`]): each mean is an unbiased estimate (the
/// fresh walks' whatever their number), and so is the blend. A pilot that
/// found nothing has no spread to read; the pilot's count of fresh walks
/// answers it. The walks of a query are numbered, pilot first, so both
/// engines run the same walks. Counts are at most [`crate::MAX_WALKS`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PdfWalks {
    pilot: u64,
    max: u64,
    rel_stderr: f64,
}

impl PdfWalks {
    /// No density walk: the closed-form lobe pdf
    /// ([`super::lobe_pdf`]), a renderer's MIS density for the cost of an
    /// interface pdf. The library's default.
    pub const LOBES: PdfWalks = PdfWalks {
        pilot: 0,
        max: 0,
        rel_stderr: 0.0,
    };

    /// The library's default rule: [`PdfWalks::LOBES`], chosen by the
    /// renderer's vertex benchmark (docs/performance.md).
    pub const DEFAULT: PdfWalks = PdfWalks::LOBES;

    /// Density walks for a pdf close to `sample()`'s density: a pilot of 8
    /// walks, then 8 to 64 walks for a relative standard error of 0.15
    /// (0.7–1.3× at two standard errors; docs/method.md §6 measures it).
    pub const ADAPTIVE: PdfWalks = PdfWalks {
        pilot: 8,
        max: 64,
        rel_stderr: 0.15,
    };

    /// The rule for a pdf within 0.7–1.3× of `sample()`'s density at
    /// nearly every direction: a pilot of 8 walks, then 8 to 128 walks for
    /// a relative standard error of 0.1 (0.7–1.3× at three standard
    /// errors). About twice [`PdfWalks::ADAPTIVE`]'s walks where one walk is noisy
    /// (docs/method.md §6 measures both; a renderer's MIS weights rarely
    /// need it, a pdf compared direction by direction may).
    pub const TIGHT: PdfWalks = PdfWalks {
        pilot: 8,
        max: 128,
        rel_stderr: 0.1,
    };

    /// Exactly `n` walks (1 to [`crate::MAX_WALKS`]), no pilot.
    pub fn fixed(n: u64) -> Self {
        PdfWalks {
            pilot: 0,
            max: n.clamp(1, MAX_WALKS),
            rel_stderr: 0.0,
        }
    }

    /// A pilot of `pilot` walks (at least two: one walk has no spread),
    /// then `pilot` to `max` walks for a relative standard error of
    /// `rel_stderr` (one that is not positive, or NaN, means `max`); both
    /// counts at most [`crate::MAX_WALKS`].
    pub fn adaptive(pilot: u64, max: u64, rel_stderr: f64) -> Self {
        let pilot = pilot.clamp(2, MAX_WALKS);
        PdfWalks {
            pilot,
            max: max.clamp(pilot, MAX_WALKS),
            rel_stderr: if rel_stderr > 0.0 { rel_stderr } else { 0.0 },
        }
    }

    /// [`PdfWalks::adaptive`] for input from outside (the C ABI, Python, the
    /// CLI): a count out of range or a relative standard error that is not
    /// a positive finite number is an error naming the field and the value,
    /// not clamped.
    pub fn try_adaptive(pilot: u64, max: u64, rel_stderr: f64) -> Result<Self, String> {
        if !(2..=MAX_WALKS).contains(&pilot) {
            return Err(format!(
                "pilot = {pilot}: expected 2 to {} walks (one walk has no spread)",
                MAX_WALKS
            ));
        }
        if !(pilot..=MAX_WALKS).contains(&max) {
            return Err(format!(
                "max = {max}: expected pilot ({pilot}) to {} walks",
                MAX_WALKS
            ));
        }
        if !(rel_stderr.is_finite() && rel_stderr > 0.0) {
            return Err(format!(
                "rel_stderr = {rel_stderr}: expected a positive relative standard error"
            ));
        }
        Ok(PdfWalks::adaptive(pilot, max, rel_stderr))
    }

    /// Whether the rule runs no walk: the lobe pdf.
    pub fn is_lobes(&self) -> bool {
        self.max == 0
    }

    /// The walks of the pilot round (0 for a fixed number).
    pub fn pilot(&self) -> u64 {
        self.pilot
    }

    /// The most walks in a pdf's mean.
    pub fn max(&self) -> u64 {
        self.max
    }

    /// The relative standard error the walks aim at (0 for a fixed number).
    pub fn rel_stderr(&self) -> f64 {
        self.rel_stderr
    }

    /// The walks of a pdf's first round: its pilot, or all of them.
    pub fn first_round(&self) -> u64 {
        if self.pilot > 0 {
            self.pilot
        } else {
            self.max
        }
    }

    /// The pilot mean's weight in the pdf, `pilot / (pilot + max / 2)`: fixed
    /// before any walk runs, as the blend's unbiasedness needs. A blend of
    /// weight `w` has a lower variance than the fresh walks' mean alone
    /// wherever they number under `pilot (2 − w) / w`, which for this weight
    /// is `pilot + max`; it gains the most where the pilot asked for few.
    pub fn pilot_weight(&self) -> f64 {
        if self.pilot == 0 {
            return 0.0;
        }
        let p = self.pilot as f64;
        p / (p + self.max as f64 / 2.0)
    }

    /// The pdf of `kind` from the pilot's sums and the fresh walks'. Each
    /// mean's standard error is from its own round's variance: the fresh
    /// walks' is independent of their count, while a variance pooled over
    /// both rounds is not (the pilot's spread set the count) and reads low.
    pub fn finish(&self, pilot: &DensitySums, fresh: &DensitySums, kind: PdfKind) -> PdfEstimate {
        let w = self.pilot_weight();
        let fresh = fresh.estimate();
        let e = if w == 0.0 {
            fresh
        } else {
            let pilot = pilot.estimate();
            PdfEstimate {
                value: w * pilot.value + (1.0 - w) * fresh.value,
                stderr: (w * pilot.stderr).hypot((1.0 - w) * fresh.stderr),
                samples: pilot.samples + fresh.samples,
                truncated: pilot.truncated + fresh.truncated,
            }
        };
        match kind {
            PdfKind::Unbiased => e,
            PdfKind::Approximate => PdfEstimate {
                value: mix_uniform(e.value),
                stderr: (1.0 - UNIFORM_FRACTION) * e.stderr,
                ..e
            },
        }
    }

    /// The fresh walks after a pilot round that summed to `pilot`.
    pub fn after_pilot(&self, pilot: &DensitySums) -> u64 {
        if self.pilot == 0 || self.rel_stderr == 0.0 {
            return self.max;
        }
        let walks = (pilot.rel_variance() / (self.rel_stderr * self.rel_stderr)).ceil();
        // A pilot that found nothing (0 / 0) casts to 0: the clamp's floor.
        (walks as u64).clamp(self.pilot, self.max)
    }
}

impl Default for PdfWalks {
    fn default() -> Self {
        PdfWalks::DEFAULT
    }
}

/// A rule by name, as the CLI and the bindings take it: `default` (the
/// library's), `lobes`, `adaptive`, `tight`, a fixed count `N` (1 to
/// [`crate::MAX_WALKS`]) or an adaptive rule `PILOT,MAX,REL_STDERR`
/// ([`PdfWalks::try_adaptive`]).
impl std::str::FromStr for PdfWalks {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let expected =
            "expected default, lobes, adaptive, tight, a number of walks or PILOT,MAX,REL_STDERR";
        match s.trim() {
            "default" => Ok(PdfWalks::DEFAULT),
            "lobes" => Ok(PdfWalks::LOBES),
            "adaptive" => Ok(PdfWalks::ADAPTIVE),
            "tight" => Ok(PdfWalks::TIGHT),
            t => match t.split(',').map(str::trim).collect::<Vec<_>>()[..] {
                [n] if !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()) => {
                    match n.parse::<u64>() {
                        Ok(n @ 1..=MAX_WALKS) => Ok(PdfWalks::fixed(n)),
                        _ => Err(format!("{n} walks: expected 1 to {}", MAX_WALKS)),
                    }
                }
                [pilot, max, rel] => {
                    let count = |field: &str, v: &str| {
                        v.parse::<u64>()
                            .map_err(|_| format!("{s:?}: {field} {v:?} is not a number of walks"))
                    };
                    let rel_stderr = rel
                        .parse::<f64>()
                        .map_err(|_| format!("{s:?}: rel_stderr {rel:?} is not a number"))?;
                    PdfWalks::try_adaptive(count("pilot", pilot)?, count("max", max)?, rel_stderr)
                        .map_err(|e| format!("{s:?}: {e}"))
                }
                _ => Err(format!("{s:?}: {expected}")),
            },
        }
    }
}

/// The rule's name: `lobes`, `adaptive`, `tight`, the count, or
/// `PILOT,MAX,REL_STDERR`. [`PdfWalks::from_str`](std::str::FromStr) reads
/// back every rule that [`PdfWalks::fixed`] and [`PdfWalks::try_adaptive`]
/// make; not [`PdfWalks::adaptive`]'s with a relative standard error that
/// is not a positive finite number (which runs `max` walks).
impl std::fmt::Display for PdfWalks {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.is_lobes() {
            f.write_str("lobes")
        } else if *self == PdfWalks::ADAPTIVE {
            f.write_str("adaptive")
        } else if *self == PdfWalks::TIGHT {
            f.write_str("tight")
        } else if self.pilot == 0 {
            write!(f, "{}", self.max)
        } else {
            write!(f, "{},{},{}", self.pilot, self.max, self.rel_stderr)
        }
    }
}

impl From<u64> for PdfWalks {
    fn from(n: u64) -> Self {
        PdfWalks::fixed(n)
    }
}

/// Which pdf of `sample()`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PdfKind {
    /// Bounded walks mixed with a uniform density (the default; what
    /// `sample()` returns).
    #[default]
    Approximate,
    /// Unbounded walks, no mixture: the density itself, with its standard
    /// error.
    Unbiased,
}

impl std::str::FromStr for PdfKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "approx" => Ok(PdfKind::Approximate),
            "unbiased" => Ok(PdfKind::Unbiased),
            _ => Err(format!("unknown pdf {s:?} (expected approx or unbiased)")),
        }
    }
}

impl PdfKind {
    /// The density walk's bound on events.
    pub fn max_events(self) -> Option<u32> {
        match self {
            PdfKind::Approximate => Some(APPROX_EVENTS),
            PdfKind::Unbiased => None,
        }
    }
}

/// A pdf estimate: the mean of density walks and its standard error.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PdfEstimate {
    /// The density (solid angle, stack frame).
    pub value: f64,
    /// The standard error of `value` (0 for an exact one).
    pub stderr: f64,
    /// Number of walks in `value`, a pilot round's included.
    pub samples: u64,
    /// How many of them reached the limit of events
    /// ([`crate::estimator::Settings::max_events`]) and ended there.
    pub truncated: u64,
}

/// Sums of density walks, in walk order (so that engines agree bit for bit).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DensitySums {
    sum: f64,
    sum_sq: f64,
    n: u64,
    cut: u64,
}

impl DensitySums {
    /// Adds one walk's density.
    #[inline]
    pub fn push(&mut self, x: f64) {
        self.sum += x;
        self.sum_sq += x * x;
        self.n += 1;
    }

    /// Counts a walk the limit of events ended.
    #[inline]
    pub fn count_cut(&mut self, cut: bool) {
        self.cut += u64::from(cut);
    }

    /// The walks' mean and sample variance (0 from fewer than two walks).
    fn mean_var(&self) -> (f64, f64) {
        let n = self.n.max(1) as f64;
        let mean = self.sum / n;
        let var = if self.n > 1 {
            ((self.sum_sq - n * mean * mean) / (n - 1.0)).max(0.0)
        } else {
            0.0
        };
        (mean, var)
    }

    /// One walk's relative variance, `var / mean²`.
    fn rel_variance(&self) -> f64 {
        let (mean, var) = self.mean_var();
        var / (mean * mean)
    }

    /// The walks' mean and its standard error.
    pub fn estimate(&self) -> PdfEstimate {
        let (mean, var) = self.mean_var();
        PdfEstimate {
            value: mean,
            stderr: (var / self.n.max(1) as f64).sqrt(),
            samples: self.n,
            truncated: self.cut,
        }
    }
}

impl<S: Scalar> ScalarEngine<S> {
    /// The approximate pdf of `wo` for `sample(wi)`, from `walks`.
    pub fn pdf(
        &self,
        wi: [f64; 3],
        wo: [f64; 3],
        walks: impl Into<PdfWalks>,
        seed: u64,
        query: u64,
    ) -> f64 {
        self.pdf_estimate(wi, wo, walks, seed, query, PdfKind::Approximate)
            .value
    }

    /// A pdf of `wo` for `sample(wi)` from density walks: a count, or
    /// [`PdfWalks`] (a pilot round, then the walks it sets). The unbiased
    /// pdf's callers give a count: its standard error is that of the walks.
    pub fn pdf_estimate(
        &self,
        wi: [f64; 3],
        wo: [f64; 3],
        walks: impl Into<PdfWalks>,
        seed: u64,
        query: u64,
        kind: PdfKind,
    ) -> PdfEstimate {
        let walks = walks.into();
        if walks.is_lobes() {
            // No walk: the closed form, exact as far as it goes.
            return PdfEstimate {
                value: self.lobe_pdf(wi, wo),
                ..PdfEstimate::default()
            };
        }
        let Some(o) = super::orient(&self.stack, wi, Some(wo)) else {
            return PdfEstimate::default();
        };
        let wi = v3::<S>(o.wi);
        let wo = v3::<S>(o.apply(wo));
        let walk = DensityWalk {
            ifaces: &self.ifaces,
            media: &self.media,
            settings: &self.settings,
            max_events: kind.max_events(),
        };
        let prefix = query_prefix(seed, query);
        let run = |ks: std::ops::Range<u64>| {
            let mut sums = DensitySums::default();
            for k in ks {
                let mut rng = WalkRng::from_prefix(prefix, k, Stream::Pdf);
                let draw = |m: bool| {
                    if m {
                        S::splat(rng.uniform() as f64)
                    } else {
                        S::zero()
                    }
                };
                let (p, cut) = walk.run(wi, wo, draw);
                sums.push(p.lane(0));
                sums.count_cut(cut.lane(0));
            }
            sums
        };
        let p = walks.pilot();
        let pilot = run(0..p);
        let n = walks.after_pilot(&pilot);
        walks.finish(&pilot, &run(p..p.saturating_add(n)), kind)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sums(xs: &[f64]) -> DensitySums {
        let mut s = DensitySums::default();
        xs.iter().for_each(|&x| s.push(x));
        s
    }

    #[test]
    fn a_fixed_count_has_no_pilot() {
        assert_eq!(PdfWalks::fixed(0), PdfWalks::fixed(1));
        assert_eq!(PdfWalks::fixed(7).after_pilot(&sums(&[0.0; 3])), 7);
        let w = PdfWalks::fixed(5);
        assert_eq!((w.pilot(), w.first_round()), (0, 5));
        assert_eq!(w.after_pilot(&DensitySums::default()), 5);
    }

    #[test]
    fn the_pilot_sets_the_walks_for_the_relative_error() {
        let w = PdfWalks::adaptive(4, 100, 0.1);
        // Mean 1, sample variance 1/3: 1/3 / 0.1² walks, rounded up.
        let pilot = sums(&[1.5, 0.5, 1.5, 0.5]);
        assert!((pilot.rel_variance() - 1.0 / 3.0).abs() < 1e-12);
        assert_eq!(w.after_pilot(&pilot), 34);
        // At least the pilot's count, at most `max`.
        assert_eq!(w.after_pilot(&sums(&[1.0; 4])), 4);
        assert_eq!(w.after_pilot(&sums(&[100.0, 0.0, 0.0, 0.1])), 100);
        // Nothing found, or no spread: the fewest walks.
        assert_eq!(w.after_pilot(&sums(&[0.0; 4])), 4);
        assert_eq!(w.after_pilot(&sums(&[f64::INFINITY, 1.0])), 4);
        // A target that is not positive means `max`, even without spread.
        for t in [0.0, -1.0, f64::NAN] {
            let w = PdfWalks::adaptive(4, 9, t);
            assert_eq!(w.after_pilot(&pilot), 9);
            assert_eq!(w.after_pilot(&sums(&[1.0; 4])), 9);
        }
        // The pilot is at least 2, `max` at least the pilot, both at most
        // MAX_WALKS.
        assert_eq!(PdfWalks::adaptive(0, 1, 0.1).pilot(), 2);
        assert_eq!(PdfWalks::adaptive(8, 2, 0.1).max(), 8);
        let huge = PdfWalks::adaptive(u64::MAX, u64::MAX, 1e-200);
        assert_eq!(
            (huge.pilot(), huge.max()),
            (crate::MAX_WALKS, crate::MAX_WALKS)
        );
        assert_eq!(PdfWalks::fixed(u64::MAX).max(), crate::MAX_WALKS);
    }

    #[test]
    fn a_rule_reads_back_from_its_name() {
        for (name, rule) in [
            ("default", PdfWalks::LOBES),
            ("lobes", PdfWalks::LOBES),
            ("adaptive", PdfWalks::ADAPTIVE),
            ("tight", PdfWalks::TIGHT),
            ("32", PdfWalks::fixed(32)),
            ("4,200,0.05", PdfWalks::adaptive(4, 200, 0.05)),
            // The named rules by their parameters are the named rules.
            ("8,128,0.1", PdfWalks::TIGHT),
            (" 8, 64, 0.15 ", PdfWalks::ADAPTIVE),
        ] {
            let parsed: PdfWalks = name.parse().unwrap();
            assert_eq!(parsed, rule, "{name}");
            assert_eq!(parsed.to_string().parse::<PdfWalks>().unwrap(), rule);
        }
        assert_eq!(PdfWalks::fixed(1).to_string(), "1");
        assert_eq!(PdfWalks::adaptive(4, 200, 0.05).to_string(), "4,200,0.05");
    }

    #[test]
    fn a_bad_rule_names_the_field_and_the_value() {
        for (name, message) in [
            ("0", "0 walks: expected 1 to 1099511627776"),
            ("1099511627777", "1099511627777 walks"),
            (
                "99999999999999999999",
                "99999999999999999999 walks: expected 1 to",
            ),
            ("+5", "\"+5\": expected default"),
            (
                "tighter",
                "\"tighter\": expected default, lobes, adaptive, tight",
            ),
            ("-3", "\"-3\": expected default"),
            ("8,64", "\"8,64\": expected default"),
            ("1,64,0.1", "pilot = 1: expected 2 to"),
            ("8,4,0.1", "max = 4: expected pilot (8) to"),
            ("8,64,0", "rel_stderr = 0: expected a positive"),
            ("8,64,NaN", "rel_stderr = NaN"),
            ("8,64,inf", "rel_stderr = inf"),
            ("8,x,0.1", "max \"x\" is not a number of walks"),
            ("8,64,y", "rel_stderr \"y\" is not a number"),
        ] {
            let e = name.parse::<PdfWalks>().unwrap_err();
            assert!(e.contains(message), "{name}: {e}");
        }
        assert!(PdfWalks::try_adaptive(2, crate::MAX_WALKS + 1, 0.1).is_err());
        assert!(PdfWalks::try_adaptive(8, 8, -0.1).is_err());
        assert_eq!(PdfWalks::try_adaptive(8, 128, 0.1), Ok(PdfWalks::TIGHT));
    }

    #[test]
    fn the_pdf_blends_the_pilot_by_a_weight_fixed_in_advance() {
        let w = PdfWalks::adaptive(8, 64, 0.15);
        assert!((w.pilot_weight() - 0.2).abs() < 1e-15);
        let (pilot, fresh) = (sums(&[2.0, 0.0]), sums(&[1.0, 3.0, 1.0, 3.0]));
        let e = w.finish(&pilot, &fresh, PdfKind::Unbiased);
        // Means 1 and 2; variances of the means 1 and 1/3.
        assert!((e.value - (0.2 * 1.0 + 0.8 * 2.0)).abs() < 1e-12, "{e:?}");
        let se = (0.2f64.powi(2) * 1.0 + 0.8f64.powi(2) / 3.0).sqrt();
        assert!((e.stderr - se).abs() < 1e-12, "{e:?}");
        assert_eq!(e.samples, 6);
        // At every count of fresh walks the rule can choose, the blend's
        // variance (per unit of one walk's) is below the fresh mean's.
        let p = w.pilot() as f64;
        let b = w.pilot_weight();
        for n in w.pilot()..=w.max() {
            let n = n as f64;
            assert!(b * b / p + (1.0 - b).powi(2) / n < 1.0 / n, "{n} walks");
        }
        // A fixed count has no pilot: its mean alone, mixed for approx.
        let f = PdfWalks::fixed(4);
        assert_eq!(f.pilot_weight(), 0.0);
        let e = f.finish(&DensitySums::default(), &fresh, PdfKind::Approximate);
        assert_eq!((e.value, e.samples), (mix_uniform(2.0), 4));
    }
}
