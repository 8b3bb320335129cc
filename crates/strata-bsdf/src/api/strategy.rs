//! The choices a caller makes of how a BSDF answers: which estimator,
//! from which side eval's walks start, which engine runs them (`Auto`
//! leaves each to the plan, `api::plan`).

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

/// Which engine answers a query. The scalar and the wavefront engine give the
/// same results for the same seeds (walk by walk, bit for bit: they run the
/// same f32 operations; tested); `Auto` gives one of theirs.
///
/// The wavefront engine pays a fixed setup cost per call (preparing the
/// queries and a wave), which its lanes repay many times over on a batch, or
/// on an `eval` of many walks, but not on a call of fewer walks than it has
/// lanes (a single `sample`'s walk): there the scalar engine is the cheaper
/// one (docs/performance.md, *criterion*).
/// [`Engine::Auto`], the default, picks per call. Calls of at most
/// [`SERIAL_WALKS`](crate::estimator::wavefront::SERIAL_WALKS) walks (pdf batches of at most
/// [`PDF_CHUNK`](crate::estimator::wavefront::PDF_CHUNK) queries) run
/// on the calling thread on either engine, with or without
/// [`LayeredBsdf::threads`](super::LayeredBsdf::threads).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Engine {
    /// Per call: the scalar engine for calls of fewer walks (queries × walks
    /// per query) than the wavefront has lanes, the wavefront otherwise. A
    /// pdf counts the walks of its first round twice (a density walk costs
    /// several eval walks), so a single `pdf` of the default walks runs on
    /// the wavefront.
    #[default]
    Auto,
    /// The scalar reference: one walk at a time.
    Scalar,
    /// The SIMD wavefront engine: walks in lanes, batches over threads.
    Wavefront,
}

impl Engine {
    /// The name `FromStr` takes: `auto`, `scalar` or `wavefront`.
    pub fn as_str(self) -> &'static str {
        match self {
            Engine::Auto => "auto",
            Engine::Scalar => "scalar",
            Engine::Wavefront => "wavefront",
        }
    }
}

impl std::str::FromStr for Engine {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "auto" => Ok(Engine::Auto),
            "scalar" => Ok(Engine::Scalar),
            "wavefront" => Ok(Engine::Wavefront),
            _ => Err(format!(
                "unknown engine {s:?} (expected auto, scalar or wavefront)"
            )),
        }
    }
}
