//! The plan of automatic choices: how a row of a table (a BSDF's own
//! stack, or a parameter set) is answered, decided once when the row is
//! built, as pbrt-v4 fixes its BxDF at construction. Every rule that picks
//! an estimator, an engine or a side lives here, with its constants:
//!
//! | choice | rule | constants | measured in |
//! |---|---|---|---|
//! | eval without walks | `Estimator::Auto` on a dielectric coat over a clear or absorbing layer over a Lambertian base: the closed form under a smooth coat, the factorization under a rough one (`estimator::coat_and_base`) | | `tests/physics/rough_coat.rs`, docs/method.md §4 |
//! | control variate | `Auto` on a coat over a *scattering* layer over a Lambertian base, where it measured less variance per unit of time ([`CoatLambertian::control_variate_pays`]) | [`BOOSTED_CV_MAX_DEPTH`] 2, [`ROUGH_CV_MIN_BASE`] 0.5, scattering at most 0.1 of the base | `tests/estimators/layered_control_variate.rs` |
//! | bidirectional walks | `Auto` on optically thin stacks of three interfaces or more, on a rough coat over a smooth conductor, on near-specular coated conductors; not at the specular peak ([`Estimator::bidirectional_pays`], [`Estimator::is_bidirectional_at`]) | [`NEAR_SPECULAR_ALPHA`] 0.05, [`MAX_OPTICAL_DEPTH`] 3, [`MAX_COATED_CONDUCTOR_DEPTH`] 1 | docs/results.md |
//! | side walks start from | `EvalStart::Normal`: the direction nearer the normal, or farther from it for a reflected pair under a rough entrance; on an untilted stack | | docs/performance.md |
//! | engine | `Engine::Auto`: the scalar engine for a call of fewer walks than the wavefront has lanes ([`Engine::resolve`]; a pdf counts its first round twice) | lanes 8 | docs/performance.md, *criterion* |
//! | threads | a batch of at most `SERIAL_WALKS` walks (a pdf batch of at most `PDF_CHUNK` queries) runs on the calling thread | 256, 64 | `crates/strata-benches`, group `small` |
//! | pdf | the lobe pdf by default (`PdfWalks::DEFAULT`), exact where the sampler is walk-free | | `tests/estimators/layered_pdf.rs` |
//!
//! A row records its choices when it is built: a BSDF's in its fields
//! (`coat`, `route`, `rough_entry`, the engines' control variate), a
//! parameter set's beside its numbers (`ParamSets::coat`, `route`).

use super::strategy::{Engine, Estimator, EvalStart};
use crate::estimator::coat_and_base::coat_and_base;
use crate::estimator::coat_lambertian::CoatLambertian;
use crate::estimator::rough_coat::RoughCoatLambertian;
use crate::estimator::Settings;
use crate::lane::{DefaultWide, Lane};
use crate::stack::{LayerStack, PhaseKind};

/// The largest roughness (GGX or Beckmann α) of a near-specular coat and
/// conductor for which `Estimator::Auto` runs the bidirectional estimator
/// on a two-interface stack ([`Estimator::bidirectional_pays`]): it sits
/// where docs/results.md measured the bidirectional estimator's advantage
/// fading on near-specular coats over conductors, so that `Auto` takes it
/// only where it clearly wins.
pub const NEAR_SPECULAR_ALPHA: f64 = 0.05;

/// The largest optical depth of a scattering layer in a stack of three
/// interfaces or more for which `Estimator::Auto` runs the bidirectional
/// estimator ([`Estimator::bidirectional_pays`]): on three such stacks it
/// won at every depth up to 3 and, on two of them, lost at some direction
/// pairs from 4 on and at all from 8 or 12, where its
/// walks, whose cost grows with the cube of their length, are long
/// (docs/results.md, *The optical depth threshold*).
pub const MAX_OPTICAL_DEPTH: f64 = 3.0;

/// The same threshold on a two-interface coated conductor, where it has
/// not been measured between 0.5 (a win) and 10 (a loss).
pub const MAX_COATED_CONDUCTOR_DEPTH: f64 = 1.0;

/// The deepest grey medium on which [`crate::Estimator::Auto`] uses the
/// boosted control variate ([`CoatLambertian::control_variate_pays`]).
/// A conservative choice: the deepest measured stack inside the rule is at
/// τ 2; a grey τ 8 one about broke even at its worst pair, and the deep
/// example `jade` (which the other conditions leave out too) lost
/// efficiency (docs/performance.md).
pub const BOOSTED_CV_MAX_DEPTH: f64 = 2.0;

/// The darkest base (smallest albedo of a channel) over which
/// [`crate::Estimator::Auto`] uses the control variate under a *rough* coat
/// ([`CoatLambertian::control_variate_pays`]). Over a darker one the series
/// of bounces that the control variate takes out of the walks is short, and
/// sampling `f₀` costs about what it saves (docs/performance.md).
pub const ROUGH_CV_MIN_BASE: f64 = 0.5;

impl Estimator {
    /// Whether `Auto` answers `stack`'s eval with the bidirectional
    /// estimator, on stacks whose scattering layers are all optically thin
    /// (optical depth at most [`MAX_OPTICAL_DEPTH`] in every channel on
    /// three interfaces or more, [`MAX_COATED_CONDUCTOR_DEPTH`] on two):
    /// * on stacks of three interfaces or more, where vertices below the
    ///   exit's layer reach the viewer only through continuations in the
    ///   unidirectional estimator;
    /// * on a rough coat over a smooth conductor, and on a near-specular
    ///   rough coat over a rough conductor (both roughnesses at most
    ///   [`NEAR_SPECULAR_ALPHA`]): there the unidirectional estimator can
    ///   connect to the viewer only by evaluating the coat's lobe at
    ///   directions the walk drew from another narrow lobe (or a mirror),
    ///   and is heavy-tailed (its standard errors then understate its
    ///   error); the bidirectional one also draws that connection from the
    ///   viewer's side. Over a smooth conductor under pbrt-v4's rough coat
    ///   (α 0.1) it is far more efficient over pbrt-v4's direction pairs
    ///   (docs/performance.md, *Against pbrt-v4*); at the specular peak
    ///   the unidirectional walks still win, and `Auto` keeps them there
    ///   ([`Estimator::is_bidirectional_at`]).
    ///
    /// Measured with `strata converge` on the wavefront engine, one thread
    /// (docs/results.md, *Which estimator wins*). It is decided query by
    /// query, on the query's own stack (a parameter set's, so that a set
    /// answers what its material file answers); a batch whose sets fall on
    /// both sides of the rule runs as two batches.
    pub fn bidirectional_pays(stack: &crate::stack::LayerStack) -> bool {
        use crate::stack::InterfaceKind;
        // A bidirectional walk's cost grows with the cube of its length
        // (every pair of vertices, each weight O(n)): an optically thick
        // scattering layer makes it lose whatever the interfaces.
        let thin = |max: f64| {
            (0..stack.len().saturating_sub(1)).all(|l| {
                stack
                    .medium(l)
                    .is_none_or(|m| !m.scatters() || m.optical_depth().iter().all(|&t| t <= max))
            })
        };
        if stack.len() >= 3 {
            return thin(MAX_OPTICAL_DEPTH);
        }
        if !thin(MAX_COATED_CONDUCTOR_DEPTH) {
            return false;
        }
        if stack.len() != 2 {
            return false;
        }
        let (top, base) = (stack.interface(0), stack.interface(1));
        let near = |it: &crate::stack::Interface| {
            !it.smooth && it.alpha[0].max(it.alpha[1]) <= NEAR_SPECULAR_ALPHA
        };
        let coated_conductor = top.kind == InterfaceKind::Dielectric
            && !top.smooth
            && base.kind == InterfaceKind::Conductor;
        coated_conductor && (base.smooth || (near(top) && near(base)))
    }

    /// Whether this estimator answers `stack`'s eval with the
    /// bidirectional estimator (for `Auto`, at some direction pairs: see
    /// [`Estimator::is_bidirectional_at`]).
    pub fn is_bidirectional_for(self, stack: &crate::stack::LayerStack) -> bool {
        match self {
            Estimator::Bidirectional => true,
            Estimator::Auto => Self::bidirectional_pays(stack),
            Estimator::Unidirectional => false,
        }
    }

    /// Whether this estimator answers `stack`'s eval at `(wi, wo)` with the
    /// bidirectional estimator: as [`Estimator::is_bidirectional_for`],
    /// except that `Auto` keeps the unidirectional walks at the specular
    /// peak of a coated conductor (the half vector of a reflected pair
    /// within `tan θh ≤ α` of the normal, α the coat's roughness), where
    /// the walks' continuation meets the coat's lobe head on and their
    /// lower cost per walk wins (docs/performance.md, *Against pbrt-v4, with
    /// the bidirectional estimator*).
    pub fn is_bidirectional_at(
        self,
        stack: &crate::stack::LayerStack,
        wi: [f64; 3],
        wo: [f64; 3],
    ) -> bool {
        self.route(stack).bidirectional_at(wi, wo)
    }

    /// What decides the estimator of `stack`'s evals, taken once from its
    /// numbers ([`Estimator::is_bidirectional_at`] at any directions).
    pub(crate) fn route(self, stack: &crate::stack::LayerStack) -> EvalRoute {
        let top = stack.interface(0);
        EvalRoute {
            bidirectional: self.is_bidirectional_for(stack),
            peak: (self == Estimator::Auto && stack.len() < 3)
                .then(|| top.alpha[0].max(top.alpha[1])),
        }
    }
}

impl CoatLambertian {
    /// Whether [`crate::Estimator::Auto`] uses the control variate on
    /// `stack`: it has the shape ([`CoatLambertian::unscattered`]), its
    /// medium scatters, and, under a **smooth** coat, either
    ///
    /// * the medium is grey (one extinction and one albedo for the three
    ///   channels), of optical depth at most [`BOOSTED_CV_MAX_DEPTH`], with a
    ///   Henyey–Greenstein phase function: its walks then boost their first
    ///   collision ([`super::events::FIRST_COLLISION_BOOST`]): the thin
    ///   layers measured large gains at the median, the deeper ones (τ 0.5
    ///   to 2) small losses at some (`control_variate_efficiency`); or
    /// * the medium scatters little against what the base reflects,
    ///   `max_c(τ_c a_c) <= 0.1 min_c ρ_c` (optical depth `τ`,
    ///   single-scattering albedo `a`, base albedo `ρ`).
    ///
    /// Elsewhere (a chromatic albedo, a mixture of lobes, or chromatic
    /// extinction, which the boost does not cover) the control variate
    /// measured more variance per unit of time at some pairs: a collided
    /// path scores about what the uncollided one it replaces would have, and
    /// the boosted walks' longer roulette costs time; deeper grey media are
    /// left out by choice ([`BOOSTED_CV_MAX_DEPTH`]). A mixture of a single
    /// lobe counts as a mixture here.
    ///
    /// Under a **rough** coat, whose `f₀` is sampled, only where the medium
    /// scatters little against what the base reflects (as above) over a
    /// base no darker than [`ROUGH_CV_MIN_BASE`]: under rough coats the grey
    /// media of the first rule lost efficiency at some pair or gained
    /// little.
    ///
    /// Measured in `tests/estimators/layered_control_variate.rs`
    /// (`control_variate_efficiency`; docs/performance.md).
    pub fn control_variate_pays(stack: &LayerStack, settings: &Settings) -> bool {
        // The shape of `unscattered`, without building it.
        let Some((coat, _)) = coat_and_base(stack, settings) else {
            return false;
        };
        if !coat.smooth && !RoughCoatLambertian::in_domain(coat) {
            return false;
        }
        let Some(m) = stack.medium(0).filter(|m| m.scatters()) else {
            return false;
        };
        let tau = m.optical_depth();
        let rho = stack.interface(1).albedo;
        let scatter = (0..3).map(|c| tau[c] * m.albedo[c]).fold(0.0, f64::max);
        let base = rho.iter().copied().fold(f64::INFINITY, f64::min);
        let little = scatter <= 0.1 * base;
        if !stack.interface(0).smooth {
            return little && base >= ROUGH_CV_MIN_BASE;
        }
        let grey = m.grey() && m.albedo.iter().all(|&a| a == m.albedo[0]);
        let boosted_pays =
            grey && tau[0] <= BOOSTED_CV_MAX_DEPTH && m.phase_kind() == PhaseKind::Hg;
        boosted_pays || little
    }
}

impl EvalStart {
    /// Whether the walks of a query start from `wo`; `rough_entry`: the
    /// pair is reflected and the interface its walks enter is rough.
    pub(crate) fn swaps(self, wi_z: f64, wo_z: f64, rough_entry: bool) -> bool {
        self == EvalStart::Normal
            && if rough_entry {
                wo_z.abs() < wi_z.abs()
            } else {
                wo_z.abs() > wi_z.abs()
            }
    }
}

impl Engine {
    /// The engine that answers a call of `queries` queries of `walks` walks
    /// each: `Scalar` or `Wavefront`, never `Auto`.
    pub fn resolve(self, queries: usize, walks: u64) -> Engine {
        match self {
            Engine::Auto
                if (queries as u64).saturating_mul(walks) < <DefaultWide as Lane>::LANES as u64 =>
            {
                Engine::Scalar
            }
            Engine::Auto => Engine::Wavefront,
            e => e,
        }
    }
}

/// `Estimator::Auto` uses the control variate where it pays
/// ([`CoatLambertian::control_variate_pays`]); `Unidirectional` keeps the
/// plain walks.
pub(super) fn control_variate_for(
    estimator: Estimator,
    stack: &LayerStack,
    settings: &Settings,
) -> bool {
    estimator == Estimator::Auto && CoatLambertian::control_variate_pays(stack, settings)
}

/// Whether the interface that walks from above (`[0]`) and from below
/// (`[1]`) enter is rough (`EvalStart::Normal`'s side of a reflected pair):
/// an opaque stack lit from below is mirrored, so both are its top.
pub(super) fn rough_entry(stack: &LayerStack) -> [bool; 2] {
    let top = !stack.interface(0).smooth;
    let below = if stack.transmissive() {
        !stack.interface(stack.len() - 1).smooth
    } else {
        top
    };
    [top, below]
}

/// How a stack's (or a parameter set's) evals pick their estimator, decided
/// when the stack or set is built: the walks of [`Estimator::is_bidirectional_for`],
/// except at the specular peak where `Auto` keeps the unidirectional ones.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct EvalRoute {
    /// The estimator is bidirectional (at some pairs).
    bidirectional: bool,
    /// Under `Auto` on a stack of one or two interfaces: the top's largest
    /// alpha, within which of the normal a half vector is at the peak.
    peak: Option<f64>,
}

impl EvalRoute {
    /// Whether the estimator is bidirectional (at some pairs).
    pub(crate) fn bidirectional(&self) -> bool {
        self.bidirectional
    }

    /// Whether an eval from `wi` to `wo` runs the bidirectional walks.
    pub(crate) fn bidirectional_at(&self, wi: [f64; 3], wo: [f64; 3]) -> bool {
        self.bidirectional && !self.peak.is_some_and(|alpha| specular_peak(alpha, wi, wo))
    }
}

/// The half vector of a reflected pair lies within `tan θh ≤ alpha` of the
/// normal.
fn specular_peak(alpha: f64, wi: [f64; 3], wo: [f64; 3]) -> bool {
    if wi[2] * wo[2] <= 0.0 {
        return false;
    }
    let h = [wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]];
    (h[0] * h[0] + h[1] * h[1]).sqrt() <= alpha * h[2].abs()
}
