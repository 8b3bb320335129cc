//! The walk controls the estimators share, the limits of events per walk and
//! of walks per query.

/// The most walks one query may ask for, 2^40: beyond it the walk counts of
/// a batch could overflow, and a query would run for weeks anyway.
pub const MAX_WALKS: u64 = 1 << 40;

/// The largest limit of events honoured exactly (see
/// [`Settings::max_events`]): events are counted in single precision.
pub const MAX_CAP: u32 = 1 << 24;

/// The default limit of events per walk ([`Settings::max_events`]): more
/// than five times the longest walk of the stress suite (docs/numerics.md).
pub const MAX_EVENTS: u32 = 1 << 20;

/// The default of [`Settings::rr_threshold`]: chosen by a renderer's
/// vertex (`strata bench --vertex --against pbrt-v4`: one-walk samples and
/// evals in high-albedo layers lose far less to the roulette than their
/// walks lengthen); the bidirectional estimator's subpaths keep 1, the
/// classic rule, as their cost grows with the square of their length.
pub const RR_THRESHOLD: f64 = 0.5;

/// Walk controls shared by the estimators.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    /// Russian roulette starts after this many events (interface or medium).
    /// It is unbiased: survivors are reweighted.
    pub rr_start: u32,
    /// Past `rr_start`, a walk whose throughput's largest channel `b` is
    /// below this survives the roulette with probability `b / rr_threshold`
    /// (and is divided by it); above it, it always survives. 1 is the
    /// classic rule (survival `min(1, b)`); lower values keep more walks
    /// of high-albedo media whole, at the cost of longer walks. Unbiased for
    /// any value; values are taken in
    /// `[`[`crate::estimator::events::MIN_RR_THRESHOLD`]`, 1]` (NaN as 1).
    pub rr_threshold: f64,
    /// The limit of events (interface events and collisions) per walk: a
    /// walk that reaches it ends there, and its result counts it as cut.
    /// The default, [`MAX_EVENTS`], bounds the time and memory of a
    /// walk on any stack (docs/numerics.md, *Walk length*) without changing
    /// an answer of the stress suite; below it the estimate loses
    /// the energy of longer paths, which is biased. A bidirectional walk
    /// connects every vertex of one subpath to every vertex of the other, so
    /// its subpaths end at `√max_events` vertices. Values are taken in
    /// `1..=`[`MAX_CAP`].
    pub max_events: u32,
    /// Keep only paths with at most this many medium scattering events
    /// (`Some(1)` gives single scattering, the analytic check of method.md §8).
    pub max_scatter_order: Option<u32>,
    /// Combine next-event estimation and path continuation with MIS (power
    /// heuristic); `false` uses next-event estimation alone where it applies,
    /// and the pdf's density walks leave out their medium connection (an
    /// unbiased estimate either way: `tests/estimators/pdf_density.rs` compares them).
    pub mis: bool,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            rr_start: 4,
            rr_threshold: RR_THRESHOLD,
            max_events: MAX_EVENTS,
            max_scatter_order: None,
            mis: true,
        }
    }
}
