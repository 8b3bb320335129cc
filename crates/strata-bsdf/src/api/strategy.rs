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
    /// unidirectional estimator elsewhere. The default.
    #[default]
    Auto,
    /// The unidirectional random-walk estimator, always (method.md §4).
    Unidirectional,
}

impl std::str::FromStr for Estimator {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "auto" => Ok(Estimator::Auto),
            "uni" | "unidirectional" => Ok(Estimator::Unidirectional),
            _ => Err(format!("unknown estimator {s:?} (expected auto or uni)")),
        }
    }
}
