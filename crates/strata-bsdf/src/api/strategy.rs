//! How `eval` estimates: with which estimator, and from which side.

/// Where `eval` starts its walks.
///
/// `f(wi, wo)` can be estimated by walks from `wi`, or by walks from `wo` and
/// reciprocity (reflection: `f(wi, wo) = f(wo, wi)`; transmission: the η²
/// relation). Both are unbiased; their variances differ, most at grazing
/// angles: walks that start grazing mostly reflect off the top and score
/// little, while walks from the other direction enter and connect to the
/// grazing exit by next-event estimation. `Normal`, the default, starts
/// from whichever direction is nearer the normal (docs/performance.md has
/// the measured gain); `Wi` always starts from `wi`, as the engines do.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum EvalStart {
    /// From whichever of `wi` and `wo` has the larger `|cos θ|` (`wi` on a tie).
    #[default]
    Normal,
    /// From `wi`, always.
    Wi,
}

impl EvalStart {
    /// Whether the walks of a query start from `wo`.
    pub(crate) fn swaps(self, wi_z: f64, wo_z: f64) -> bool {
        self == EvalStart::Normal && wo_z.abs() > wi_z.abs()
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

/// Which estimator answers `eval`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Estimator {
    /// The exact value where the stack has a closed form (a smooth coat over
    /// a clear or absorbing layer over a Lambertian base:
    /// `estimator::closed_form`; standard error 0); for a smooth coat over a
    /// *scattering* layer over a Lambertian base, a control variate: the
    /// paths that never collide in the medium (the closed form of the same
    /// stack with the medium as a pure absorber) exactly, plus the walks of
    /// the unidirectional estimator scoring only the paths with a collision
    /// (unbiased), where the medium scatters little against what the base
    /// reflects (`SmoothCoatLambertian::control_variate_pays`, the rule under
    /// which it measured lower variance: docs/performance.md); the
    /// bidirectional estimator on stacks of three interfaces or more
    /// ([`Estimator::bidirectional_pays`]); the unidirectional estimator
    /// elsewhere. The default.
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
    /// estimator: on stacks of three interfaces or more, where vertices
    /// below the exit's layer reach the viewer only through continuations
    /// in the unidirectional estimator. Measured on the wavefront engine,
    /// one thread (docs/results.md, *Which estimator wins*): on five stacks
    /// of three or four interfaces the bidirectional estimator's efficiency
    /// was 1.6–8.9× the unidirectional one's (median over direction pairs);
    /// on eleven stacks of two, 0.02–0.27×.
    pub fn bidirectional_pays(stack: &crate::LayerStack) -> bool {
        stack.len() >= 3
    }

    /// Whether this estimator answers `stack`'s eval with the
    /// bidirectional estimator.
    pub fn is_bidirectional_for(self, stack: &crate::LayerStack) -> bool {
        match self {
            Estimator::Bidirectional => true,
            Estimator::Auto => Self::bidirectional_pays(stack),
            Estimator::Unidirectional => false,
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
