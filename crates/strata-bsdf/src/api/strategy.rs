//! How `eval` estimates: with which estimator, and from which side.

/// Where `eval` starts its walks.
///
/// `f(wi, wo)` can be estimated by walks from `wi`, or by walks from `wo` and
/// reciprocity (reflection: `f(wi, wo) = f(wo, wi)`; transmission: the η²
/// relation). Both are unbiased; their variances differ, most at grazing
/// angles. Under a smooth entrance, walks that start grazing mostly
/// reflect off it and score little, while walks from the other direction
/// enter and connect to the grazing exit by next-event estimation; under a
/// rough one, walks that start grazing enter by its own lobe, while the
/// connection to a grazing exit evaluates its narrow transmission lobe at
/// directions drawn from other lobes. `Normal`, the default, starts a
/// reflected pair under a rough entrance from the direction farther from
/// the normal, and every other pair from the direction nearer it
/// (docs/performance.md has the measured gains); `Wi` always starts from
/// `wi`, as the engines do.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum EvalStart {
    /// From whichever of `wi` and `wo` has the larger `|cos θ|` (`wi` on a
    /// tie), or the smaller for a reflected pair under a rough entrance.
    #[default]
    Normal,
    /// From `wi`, always.
    Wi,
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

impl EvalStart {
    /// The name `FromStr` takes: `normal` or `wi`.
    pub fn as_str(self) -> &'static str {
        match self {
            EvalStart::Normal => "normal",
            EvalStart::Wi => "wi",
        }
    }
}

impl std::str::FromStr for EvalStart {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "normal" => Ok(EvalStart::Normal),
            "wi" => Ok(EvalStart::Wi),
            _ => Err(format!("unknown eval start {s:?} (expected normal or wi)")),
        }
    }
}

/// The largest roughness (GGX or Beckmann α) of a near-specular coat and
/// conductor for which `Estimator::Auto` runs the bidirectional estimator
/// on a two-interface stack ([`Estimator::bidirectional_pays`]): it sits
/// where docs/results.md measured the bidirectional estimator's advantage
/// fading on near-specular coats over conductors, so that `Auto` takes it
/// only where it clearly wins.
pub const NEAR_SPECULAR_ALPHA: f64 = 0.05;

/// The largest optical depth of a scattering layer for which
/// `Estimator::Auto` runs the bidirectional estimator
/// ([`Estimator::bidirectional_pays`]): it won at 0.5 on three interfaces
/// and lost by far at 8 and 10, where its walks, whose cost grows with the
/// cube of their length, are long (docs/results.md).
pub const MAX_OPTICAL_DEPTH: f64 = 1.0;

/// Which estimator answers `eval`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Estimator {
    /// The exact value where the stack has a closed form (a smooth coat over
    /// a clear or absorbing layer over a Lambertian base:
    /// `estimator::closed_form`; standard error 0); for a rough coat over a
    /// clear or absorbing layer over a Lambertian base, its factorization
    /// (`estimator::rough_coat`: the coat's reflection exactly, plus samples
    /// of the light that enters from `wi` and from `wo` times a constant of
    /// the stack, integrated once; no walks); for a coat over a
    /// *scattering* layer over a Lambertian base, a control variate: the
    /// paths that never collide in the medium (the same expressions with the
    /// medium as a pure absorber) added, plus the walks of the unidirectional
    /// estimator scoring only the paths with a collision (unbiased; in a grey
    /// medium they make their first collision more likely and weight it
    /// down: `estimator::events::FIRST_COLLISION_BOOST`), where that measured
    /// lower variance per unit of time (`CoatLambertian::control_variate_pays`:
    /// docs/performance.md); the bidirectional estimator on stacks of three
    /// interfaces or more, on rough coats over smooth conductors and on
    /// near-specular coated conductors ([`Estimator::bidirectional_pays`]);
    /// the unidirectional estimator elsewhere. The default.
    #[default]
    Auto,
    /// The unidirectional random-walk estimator, always (method.md §4).
    Unidirectional,
    /// The bidirectional estimator, always (method.md §4,
    /// `estimator::bidir`).
    Bidirectional,
}

impl Estimator {
    /// Whether `Auto` answers `stack`'s eval with the bidirectional
    /// estimator, on stacks whose scattering layers are all optically thin
    /// (optical depth at most [`MAX_OPTICAL_DEPTH`] in every channel):
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
        let thin = (0..stack.len().saturating_sub(1)).all(|l| {
            stack.medium(l).is_none_or(|m| {
                !m.scatters() || m.optical_depth().iter().all(|&t| t <= MAX_OPTICAL_DEPTH)
            })
        });
        if !thin {
            return false;
        }
        if stack.len() >= 3 {
            return true;
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

    /// The name `FromStr` takes: `auto`, `uni` or `bidir`.
    pub fn as_str(self) -> &'static str {
        match self {
            Estimator::Auto => "auto",
            Estimator::Unidirectional => "uni",
            Estimator::Bidirectional => "bidir",
        }
    }
}

impl std::str::FromStr for Estimator {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "auto" => Ok(Estimator::Auto),
            "uni" | "unidirectional" => Ok(Estimator::Unidirectional),
            "bidir" | "bidirectional" => Ok(Estimator::Bidirectional),
            _ => Err(format!(
                "unknown estimator {s:?} (expected auto, uni or bidir)"
            )),
        }
    }
}

/// `(wi, wo)` is a reflected pair whose half vector lies within the top
/// interface's roughness of the normal: `tan θh ≤ α` (the larger α of an
/// anisotropic coat).
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
