//! [`LayeredBsdf`]: a material's BSDF on either engine, with its single
//! queries and the batch core that every batch form calls.

use super::error::{check_walks, BatchError, Direction, QueryError, ThreadsError, MAX_THREADS};
use super::param_sets::Per;
use super::plan::{control_variate_for, rough_entry, EvalRoute};
use super::strategy::{Engine, Estimator, EvalStart};
use super::transport::Transport;
use crate::estimator::closed_form::SmoothCoatLambertian;
use crate::estimator::coat_lambertian::CoatLambertian;
use crate::estimator::lobe_pdf::lobe_pdf;
use crate::estimator::pdf::{PdfEstimate, PdfKind, PdfWalks};
use crate::estimator::scalar::{eval_without_walks, ScalarEngine};
use crate::estimator::wavefront::{
    with_kept, DefaultWide, Plan, Wavefront, PDF_CHUNK, SERIAL_WALKS,
};
use crate::estimator::{Albedo, Estimate, Settings, WalkSample};
use crate::rng::{mix64, Stream, WalkRng};
use crate::stack::{LayerStack, Shape};
use glam::Vec3;
use std::borrow::Cow;
use std::cell::RefCell;
use std::sync::Arc;

/// One sampled direction, with the pdf a renderer's MIS needs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// The outgoing direction (unit, pointing away from the surface).
    pub wo: Vec3,
    /// `f(wi, wo) |cos θo| / p(wo)` (in the BSDF's [`Transport`] mode): an
    /// unbiased estimate, the walk's throughput.
    pub weight: [f32; 3],
    /// The approximate density of `wo` (per solid angle), exactly the number
    /// [`LayeredBsdf::pdf`] returns for `(wi, wo)`: a function of the two
    /// directions and the seed, not of the sample's key, so that MIS sees
    /// the same number from either strategy. For a `specular` sample it is
    /// the density of the stack's non-delta lobes at `wo` (positive
    /// wherever light enters the stack, through the pdf's uniform floor; 0
    /// where none can, as beyond the critical angle under an exterior denser
    /// than the coat); a renderer treats the sample as a delta.
    pub pdf: f32,
    /// The walk left on the side it entered (reflection).
    pub reflection: bool,
    /// Every event of the walk was a delta (the direction is a specular one).
    pub specular: bool,
}

/// A layered BSDF ready to query.
///
/// Every query is deterministic: its random streams are seeded from the
/// BSDF's seed and a query key. The plain methods derive the key from the
/// directions' bits (so the same `(wi, wo)` always gives the same answer,
/// alone or in a batch, on either engine; the two engines agree bit for
/// bit, and [`Engine::Auto`] picks one by the size of the call); a batch
/// ([`Bsdf`](super::Bsdf), [`Queries`](super::Queries)) may take the keys
/// explicitly, so that a renderer can draw fresh noise per call.
///
/// ```
/// use strata_bsdf::{Bsdf, Engine, Estimate, LayeredBsdf, LayerStack, Queries};
/// use glam::Vec3;
/// let stack = LayerStack::from_toml_str(r#"
///     [[layers]]
///     interface = { kind = "dielectric", ior = 1.5, roughness = 0.2 }
///     [[layers]]
///     interface = { kind = "diffuse", albedo = 0.8 }
/// "#).unwrap();
/// let bsdf = LayeredBsdf::new(stack).samples(512);
/// let wi = [Vec3::Z, Vec3::new(0.3, 0.0, 0.9)];
/// let wo = [Vec3::new(0.5, 0.0, 0.8), Vec3::Z];
/// let mut batch = [Estimate::default(); 2];
/// bsdf.eval_into(&Queries::pairs(&wi[..], &wo[..]), &mut |k, e| batch[k] = *e).unwrap();
/// // A batch answers exactly what single queries answer, on either engine.
/// let single = bsdf.clone().engine(Engine::Scalar).eval(wi[1], wo[1]).unwrap();
/// assert_eq!(batch[1].value, single.value);
/// ```
#[derive(Clone, Debug)]
pub struct LayeredBsdf {
    scalar: ScalarEngine<f32>,
    pub(super) wave: Wavefront<DefaultWide>,
    pub(super) settings: Settings,
    pub(super) engine: Engine,
    pub(super) samples: u64,
    pub(super) pdf_walks: PdfWalks,
    pub(super) seed: u64,
    transport: Transport,
    pub(super) eval_start: EvalStart,
    pub(super) estimator: Estimator,
    /// A coat over a layer over a Lambertian base: its paths without a
    /// collision in the layer ([`CoatLambertian::unscattered`]), the whole
    /// BSDF where the layer does not scatter. One object, so that a rough
    /// coat's integral is computed once for the engines and the API.
    pub(super) coat: Option<CoatLambertian>,
    threads: Threads,
    /// The stack's shape, which parameter sets must have.
    pub(super) shape: Shape,
    /// How the stack's evals pick their estimator (decided when the
    /// stack or the estimator is set).
    route: EvalRoute,
    /// Whether the interface that walks from above (`[0]`) and from below
    /// (`[1]`) enter is rough (`EvalStart::Normal`'s side of a reflected
    /// pair): an opaque stack lit from below is mirrored, so both are its
    /// top.
    rough_entry: [bool; 2],
}

/// Where the wavefront engine's large batches run.
#[derive(Clone, Debug, Default)]
enum Threads {
    /// rayon's current pool (the global one, unless the caller runs in another).
    #[default]
    Current,
    /// The calling thread, every batch ([`LayeredBsdf::threads`]`(1)`).
    Calling,
    /// A pool of the BSDF's own (in a forked child, one of the child's).
    Pool(Arc<crate::pool::OwnPool>),
}

impl Threads {
    /// The same setting (one pool: the same pool).
    fn same(&self, other: &Threads) -> bool {
        match (self, other) {
            (Threads::Current, Threads::Current) | (Threads::Calling, Threads::Calling) => true,
            (Threads::Pool(a), Threads::Pool(b)) => Arc::ptr_eq(a, b),
            _ => false,
        }
    }
}

impl LayeredBsdf {
    /// Default number of walks per `eval`.
    pub const DEFAULT_SAMPLES: u64 = 256;

    /// A BSDF over `stack` with default settings.
    pub fn new(stack: LayerStack) -> Self {
        Self::with_settings(stack, Settings::default())
    }

    /// A BSDF with explicit walk settings.
    pub fn with_settings(stack: LayerStack, settings: Settings) -> Self {
        // The default estimator, `Auto`, uses the control variate where it
        // pays (`CoatLambertian::control_variate_pays`).
        let coat = CoatLambertian::unscattered(&stack, &settings);
        let auto = control_variate_for(Estimator::default(), &stack, &settings);
        let cv = coat.clone().filter(|_| auto);
        LayeredBsdf {
            scalar: ScalarEngine::new(&stack, settings).with_cv(cv.clone()),
            wave: Wavefront::new(&stack, settings, Plan::Specialized).with_cv(cv),
            settings,
            engine: Engine::default(),
            samples: Self::DEFAULT_SAMPLES,
            pdf_walks: PdfWalks::DEFAULT,
            seed: 0,
            transport: Transport::default(),
            eval_start: EvalStart::default(),
            estimator: Estimator::default(),
            coat,
            threads: Threads::Current,
            rough_entry: rough_entry(&stack),
            route: Estimator::default().route(&stack),
            shape: stack.shape(),
        }
    }

    /// A BSDF over `stack` with this one's configuration: walk settings,
    /// samples, seed, estimator, engine, transport, start side and threads
    /// (its engines are built for `stack`).
    pub fn with_stack(&self, stack: LayerStack) -> Self {
        self.rebuilt(stack, self.settings)
    }

    /// Sets the limit of events per walk ([`Settings::max_events`]; taken
    /// in `1..=`[`crate::estimator::events::MAX_CAP`]).
    #[must_use]
    pub fn max_events(self, n: u32) -> Self {
        let settings = Settings {
            max_events: crate::estimator::events::event_limit(n),
            ..self.settings
        };
        self.rebuilt(self.stack().clone(), settings)
    }

    /// Sets the throughput below which Russian roulette ends walks
    /// ([`Settings::rr_threshold`]; taken in
    /// `[`[`crate::estimator::events::MIN_RR_THRESHOLD`]`, 1]`, NaN as 1).
    #[must_use]
    pub fn rr_threshold(self, threshold: f64) -> Self {
        let settings = Settings {
            rr_threshold: threshold,
            ..self.settings
        };
        self.rebuilt(self.stack().clone(), settings)
    }

    /// This BSDF's configuration over `stack` with walk settings `settings`.
    /// Whether it answers with `other`'s configuration: everything but the
    /// stack (a BSDF [`LayeredBsdf::with_stack`] made of `other`).
    pub(super) fn same_configuration(&self, other: &LayeredBsdf) -> bool {
        self.settings == other.settings
            && self.engine == other.engine
            && self.samples == other.samples
            && self.pdf_walks == other.pdf_walks
            && self.seed == other.seed
            && self.eval_start == other.eval_start
            && self.estimator == other.estimator
            && self.transport == other.transport
            && self.threads.same(&other.threads)
    }

    /// The same stack and configuration under walk settings `settings`.
    pub(super) fn with_settings_of(self, settings: Settings) -> Self {
        self.rebuilt(self.stack().clone(), settings)
    }

    /// Its thread setting as [`crate::Config::threads`] gives it.
    pub(super) fn threads_setting(&self) -> Option<usize> {
        match &self.threads {
            Threads::Current => None,
            Threads::Calling => Some(1),
            Threads::Pool(p) => Some(p.threads()),
        }
    }

    /// Its large batches on rayon's current pool (the default).
    pub(super) fn on_current_pool(mut self) -> Self {
        self.threads = Threads::Current;
        self
    }

    fn rebuilt(&self, stack: LayerStack, settings: Settings) -> Self {
        let b = LayeredBsdf {
            engine: self.engine,
            samples: self.samples,
            pdf_walks: self.pdf_walks,
            seed: self.seed,
            eval_start: self.eval_start,
            threads: self.threads.clone(),
            ..Self::with_settings(stack, settings)
        };
        b.estimator(self.estimator).transport(self.transport)
    }

    /// Sets the number of walks per `eval` (at least 1; a call with more
    /// than [`MAX_WALKS`](crate::MAX_WALKS) is a [`QueryError::TooManySamples`]).
    #[must_use]
    pub fn samples(mut self, n: u64) -> Self {
        self.samples = n.max(1);
        self
    }

    /// Sets the number of density walks per approximate `pdf` (at least 1),
    /// in place of the default lobe pdf ([`PdfWalks::LOBES`]).
    #[must_use]
    pub fn pdf_samples(mut self, n: u32) -> Self {
        self.pdf_walks = PdfWalks::fixed(n as u64);
        self
    }

    /// Sets how an approximate `pdf` is made: the lobe pdf (the default,
    /// [`PdfWalks::LOBES`], no walks), a fixed number of density walks, or a
    /// pilot round that sets the count for a relative standard error
    /// ([`PdfWalks::ADAPTIVE`]; [`PdfWalks::TIGHT`] for a pdf within
    /// 0.7–1.3× of `sample()`'s density at nearly every direction).
    #[must_use]
    pub fn pdf_walks(mut self, walks: PdfWalks) -> Self {
        self.pdf_walks = walks;
        self
    }

    /// Sets the seed of every random stream.
    #[must_use]
    pub fn seed(mut self, seed: u64) -> Self {
        self.seed = seed;
        self
    }

    /// Chooses what flows from `wi` to `wo` (radiance, the default, or
    /// importance); it changes transmission between exteriors of different
    /// IOR only (see [`Transport`]).
    #[must_use]
    pub fn transport(mut self, transport: Transport) -> Self {
        self.transport = transport;
        let adjoint = self.adjoint();
        self.scalar.set_adjoint(adjoint);
        self.wave.set_adjoint(adjoint);
        self
    }

    /// The walks follow the adjoint of tilted interfaces: importance mode on
    /// a tilted stack (method.md §9).
    pub(super) fn adjoint(&self) -> bool {
        self.shape.tilted() && self.transport == Transport::Importance
    }

    /// Chooses where `eval` starts its walks (see [`EvalStart`]; by
    /// default from the direction nearer the normal).
    #[must_use]
    pub fn eval_start(mut self, start: EvalStart) -> Self {
        self.eval_start = start;
        self
    }

    /// Chooses the estimator of `eval` (see [`Estimator`]; by default the
    /// exact value where the stack has a closed form).
    #[must_use]
    pub fn estimator(mut self, estimator: Estimator) -> Self {
        self.estimator = estimator;
        self.route = estimator.route(self.stack());
        // The engines' walks leave out what the control variate holds only
        // for `Auto`; `Unidirectional` keeps the plain walks.
        let on = self.control_variate_for(self.stack());
        let cv = self.coat.clone().filter(|_| on);
        self.scalar.set_cv(cv.clone());
        self.wave.set_cv(cv);
        self
    }

    /// Whether eval walks on `stack` leave out the control variate's paths
    /// under this BSDF's estimator.
    pub(super) fn control_variate_for(&self, stack: &LayerStack) -> bool {
        control_variate_for(self.estimator, stack, &self.settings)
    }

    /// Whether `eval` runs the bidirectional estimator (the estimator is
    /// [`Estimator::Bidirectional`], or `Auto` on a stack where it pays).
    pub fn bidirectional(&self) -> bool {
        self.route.bidirectional()
    }

    /// Whether query `k`'s eval, from `a` to `b`, runs the bidirectional
    /// estimator: by its own stack and directions.
    pub(super) fn bidirectional_in(&self, per: Per, k: usize, a: Pt, b: Pt) -> bool {
        match per.0 {
            None => self.route.bidirectional_at(a, b),
            Some((p, s)) => p.route[s[k] as usize].bidirectional_at(a, b),
        }
    }

    /// The estimator of `eval`.
    pub fn estimator_choice(&self) -> Estimator {
        self.estimator
    }

    /// Whether `eval` is answered by a closed form (the stack has one and the
    /// estimator is [`Estimator::Auto`]): exact values, standard error 0.
    pub fn eval_is_exact(&self) -> bool {
        self.without_walks().is_some_and(|c| c.smooth().is_some())
    }

    /// Whether `eval` is answered without walks: by a closed form
    /// ([`LayeredBsdf::eval_is_exact`]) or, for a rough coat over a clear or
    /// absorbing layer over a Lambertian base, by its factorization
    /// (`estimator::rough_coat`: two sampled transmissions and a constant
    /// of the stack, integrated on first use), under
    /// [`Estimator::Auto`].
    pub fn eval_without_walks(&self) -> bool {
        self.without_walks().is_some()
    }

    /// What answers `eval` without walks, under `Auto`: the coat over a
    /// Lambertian base, where its layer does not scatter.
    pub(super) fn without_walks(&self) -> Option<&CoatLambertian> {
        self.walks_can_be_skipped()
            .then_some(self.coat.as_ref())
            .flatten()
    }

    /// Whether queries of this BSDF's shape may be answered without walks
    /// (under `Auto`, where the layer does not scatter), if their own stack
    /// has a walk-free form.
    pub(super) fn walks_can_be_skipped(&self) -> bool {
        let scatters = self.stack().medium(0).is_some_and(|m| m.scatters());
        self.estimator == Estimator::Auto && !scatters
    }

    /// Whether `sample` and `pdf` are answered without walks (the same
    /// condition as [`LayeredBsdf::eval_without_walks`]): a direction drawn
    /// from a known density with bounded weights and an exact pdf, which
    /// [`LayeredBsdf::pdf_unbiased`] then also returns (standard error 0).
    /// Under a smooth coat it is the closed form's sampler, under a rough
    /// one a mixture of the coat's lobe and a cosine lobe, weighted by one
    /// sample of the factorization (`estimator::rough_coat`).
    pub fn sample_is_exact(&self) -> bool {
        self.eval_without_walks()
    }

    /// Query `k`'s walk-free sampler, where `sample` and `pdf` use it.
    fn exact_sampler<'a>(&'a self, per: Per<'a>, k: usize) -> Option<&'a CoatLambertian> {
        self.without_walks_in(per, k)
    }

    /// The transport mode.
    pub fn transport_mode(&self) -> Transport {
        self.transport
    }

    /// The seed.
    pub fn seed_value(&self) -> u64 {
        self.seed
    }

    /// How many density walks an approximate `pdf` runs.
    pub fn pdf_walks_value(&self) -> PdfWalks {
        self.pdf_walks
    }

    /// The walks per `eval`.
    pub fn samples_per_eval(&self) -> u64 {
        self.samples
    }

    /// Chooses the engine.
    #[must_use]
    pub fn engine(mut self, engine: Engine) -> Self {
        self.engine = engine;
        self
    }

    /// Runs the wavefront engine's batches on a pool of `n` threads (by
    /// default, rayon's global pool; `n = 0` also means one thread per
    /// core). `n = 1` builds no pool: every batch runs on the calling thread
    /// (a pool of one would only add a hand-over while the caller waits),
    /// where the slice calls allocate nothing once the thread has made a call
    /// as large (docs/embedding.md, *Memory*). Calls of at most
    /// [`SERIAL_WALKS`] walks (and pdf batches of at most [`PDF_CHUNK`]
    /// queries) run on the calling thread whatever the pool. Results do not
    /// depend on it. At most [`MAX_THREADS`].
    ///
    /// Safe across `fork()`: a pool's threads stay in the process that built
    /// it, so in a forked child a batch runs on a pool of the same size that
    /// strata builds for the child on its first such batch (one per process
    /// and size, kept until exit; on the calling thread if none can be
    /// built), with the parent's results. This holds for rayon's global pool
    /// too if strata used it before the fork (docs/embedding.md, *Threads*).
    pub fn threads(mut self, n: usize) -> Result<Self, ThreadsError> {
        if n > MAX_THREADS {
            return Err(ThreadsError::TooMany(n));
        }
        if n == 1 {
            self.threads = Threads::Calling;
            return Ok(self);
        }
        let pool = crate::pool::OwnPool::new(n).map_err(ThreadsError::Pool)?;
        self.threads = Threads::Pool(Arc::new(pool));
        Ok(self)
    }

    /// The stack.
    pub fn stack(&self) -> &LayerStack {
        self.scalar.stack()
    }

    /// The walk settings.
    pub fn settings(&self) -> Settings {
        self.settings
    }

    /// The scalar reference engine.
    pub fn scalar(&self) -> &ScalarEngine<f32> {
        &self.scalar
    }

    /// The wavefront engine.
    pub fn wavefront(&self) -> &Wavefront<DefaultWide> {
        &self.wave
    }

    /// Runs `f` where this BSDF's batches run when the work (`queries`
    /// queries of `walks` walks each) is more than [`SERIAL_WALKS`]; less
    /// runs on the calling thread (a hand-over to a pool's thread costs
    /// more than such a batch). See [`LayeredBsdf::install_if`].
    fn install<R: Send>(&self, queries: usize, walks: u64, f: impl FnOnce() -> R + Send) -> R {
        self.install_if((queries as u64).saturating_mul(walks) > SERIAL_WALKS, f)
    }

    /// Runs `f`, the one way a batch's engine call goes parallel: if
    /// `parallel` is set, on this BSDF's pool (rayon's current pool without
    /// one); else, or with `threads(1)` (or a pool of one thread), on the
    /// calling thread with every parallel section inside it there too
    /// ([`crate::pool::on_calling_thread`]), whichever path the engine
    /// takes.
    fn install_if<R: Send>(&self, parallel: bool, f: impl FnOnce() -> R + Send) -> R {
        match &self.threads {
            Threads::Pool(p) if parallel && p.threads() > 1 => p.install(f),
            Threads::Current if parallel => f(),
            _ => crate::pool::on_calling_thread(f),
        }
    }

    /// Runs `f`, a call's work on the calling thread, within this BSDF's
    /// thread setting: what it builds on first use and shares (a coat's
    /// table of `R̄`) is built on as many threads as the setting allows.
    pub(super) fn on_own_threads<R>(&self, f: impl FnOnce() -> R) -> R {
        match &self.threads {
            Threads::Calling => crate::pool::on_calling_thread(f),
            Threads::Pool(p) => crate::pool::with_budget(p.threads(), f),
            Threads::Current => f(),
        }
    }

    /// Whether the wavefront's batches run serially on the calling thread
    /// (`threads(1)`, or a pool of one thread), where they allocate nothing
    /// once the thread is warm.
    pub(super) fn serial(&self) -> bool {
        match &self.threads {
            Threads::Calling => true,
            Threads::Pool(p) => p.threads() == 1,
            Threads::Current => crate::pool::current_threads() == 1,
        }
    }

    // ------------------------------------------------------------ single queries

    /// `f(wi, wo)` (without the cosine) with its standard error, from
    /// `samples()` walks keyed by the directions' bits.
    pub fn eval(&self, wi: Vec3, wo: Vec3) -> Result<Estimate, QueryError> {
        let pair = (
            Direction::new("wi", wi)?.get(),
            Direction::new("wo", wo)?.get(),
        );
        check_walks("samples", self.samples)?;
        let key = direction_key(wi, wo);
        Ok(self.eval_validated(Per::OWN, &[pair], self.samples, &[key])[0])
    }

    /// Samples an outgoing direction for light from `wi`; `None` if the walk
    /// was absorbed. `sample_index` selects the random stream (the key is
    /// the direction's bits).
    pub fn sample(&self, wi: Vec3, sample_index: u64) -> Result<Option<Sample>, QueryError> {
        let key = direction_key(wi, wi);
        let s = self.sample_checked(Per::OWN, &[wi], &[key], &[sample_index]);
        Ok(s.map_err(|e| e.error)?[0])
    }

    /// The approximate pdf of `wo` for `sample(wi)` (see [`crate::estimator::pdf`]).
    pub fn pdf(&self, wi: Vec3, wo: Vec3) -> Result<f32, QueryError> {
        let pairs = directions2(&[(wi, wo)]).map_err(|e| e.error)?;
        Ok(self.pdf_validated(Per::OWN, &pairs)[0])
    }

    /// The unbiased pdf of `wo` for `sample(wi)`: the density of
    /// `sample()`'s directions, estimated by `samples` density walks with its
    /// standard error (see [`crate::estimator::density`]). Slow; for
    /// references and tests. Keyed by the directions, like [`LayeredBsdf::pdf`].
    pub fn pdf_unbiased(
        &self,
        wi: Vec3,
        wo: Vec3,
        samples: u64,
    ) -> Result<PdfEstimate, QueryError> {
        let e = self.pdf_unbiased_checked(Per::OWN, &[(wi, wo)], samples);
        Ok(e.map_err(|e| e.error)?[0])
    }

    /// Reflected and transmitted fractions of light from `wi`, from `n` walks.
    pub fn albedo(&self, wi: Vec3, n: u64) -> Result<Albedo, QueryError> {
        let key = direction_key(wi, wi);
        let a = self.albedo_checked(Per::OWN, &[wi], n, &[key]);
        Ok(a.map_err(|e| e.error)?[0])
    }

    // ------------------------------------ the batch calls' checks, for any `per`

    /// Whether the walks of a query `(a, b)` start from `b`: as `eval_start`
    /// says, on a reciprocal (untilted) stack only.
    fn swaps(&self, a_z: f64, b_z: f64) -> bool {
        let rough_entry = a_z * b_z > 0.0 && self.rough_entry[usize::from(a_z < 0.0)];
        !self.shape.tilted() && self.eval_start.swaps(a_z, b_z, rough_entry)
    }

    /// Eval after checking the directions, keys and walk count.
    pub(super) fn eval_checked(
        &self,
        per: Per,
        pairs: &[(Vec3, Vec3)],
        samples: u64,
        keys: &[u64],
    ) -> Result<Vec<Estimate>, BatchError> {
        let dirs = directions2(pairs)?;
        one_each("keys", keys.len(), pairs.len())?;
        check_walks("samples", samples).map_err(BatchError::call)?;
        Ok(self.eval_validated(per, &dirs, samples, keys))
    }

    /// Samples after checking the directions, keys and sample indices.
    pub(super) fn sample_checked(
        &self,
        per: Per,
        wis: &[Vec3],
        keys: &[u64],
        sample_index: &[u64],
    ) -> Result<Vec<Option<Sample>>, BatchError> {
        let dirs = directions1(wis)?;
        one_each("keys", keys.len(), wis.len())?;
        one_each("sample_index", sample_index.len(), wis.len())?;
        Ok(self.sample_validated(per, &dirs, keys, sample_index))
    }

    /// The unbiased pdf after checking the directions and walk count.
    pub(super) fn pdf_unbiased_checked(
        &self,
        per: Per,
        pairs: &[(Vec3, Vec3)],
        samples: u64,
    ) -> Result<Vec<PdfEstimate>, BatchError> {
        let dirs = directions2(pairs)?;
        check_walks("samples", samples).map_err(BatchError::call)?;
        Ok(self.pdf_unbiased_validated(per, &dirs, samples))
    }

    /// Albedos after checking the directions, keys and walk count.
    pub(super) fn albedo_checked(
        &self,
        per: Per,
        wis: &[Vec3],
        n: u64,
        keys: &[u64],
    ) -> Result<Vec<Albedo>, BatchError> {
        let dirs = directions1(wis)?;
        one_each("keys", keys.len(), wis.len())?;
        check_walks("n", n).map_err(BatchError::call)?;
        Ok(self.albedo_validated(per, &dirs, n, keys))
    }

    // ------------------------------------------- the engines, on valid input

    /// Eval of validated pairs on the engine the call resolves to, in the
    /// BSDF's transport mode.
    fn eval_validated(&self, per: Per, dirs: &[Pair], samples: u64, keys: &[u64]) -> Vec<Estimate> {
        let mut est = Vec::with_capacity(dirs.len());
        self.eval_each(
            per,
            dirs.len(),
            samples,
            |k| (dirs[k], keys[k]),
            |_, e| est.push(e),
        );
        est
    }

    /// Eval of the `n` validated queries `query(k) = (pair, key)`, handed to
    /// `out` in query order, in the transport mode. Allocates nothing when
    /// the call runs query by query, or serially on a warm thread.
    pub(super) fn eval_each(
        &self,
        per: Per,
        n: usize,
        samples: u64,
        query: impl Fn(usize) -> (Pair, u64) + Sync,
        out: impl FnMut(usize, Estimate) + Send,
    ) {
        self.on_own_threads(|| self.eval_each_here(per, n, samples, query, out))
    }

    /// [`LayeredBsdf::eval_each`] within the thread setting.
    fn eval_each_here(
        &self,
        per: Per,
        n: usize,
        samples: u64,
        query: impl Fn(usize) -> (Pair, u64) + Sync,
        mut out: impl FnMut(usize, Estimate) + Send,
    ) {
        // Each query's estimator is its own stack's (parameter sets answer
        // what their material files answer): without walks, or walks of one
        // of the two estimators. A batch whose queries differ runs as one
        // batch per kind, merged back in query order. On the BSDF's own
        // stack the route is decided once where directions cannot change it.
        let own = if !per.is_own() {
            None
        } else if self.without_walks().is_some() {
            Some(Route::WithoutWalks)
        } else if !self.route.bidirectional() {
            Some(Route::Unidirectional)
        } else {
            None
        };
        let route = |k: usize| {
            if let Some(r) = own {
                return r;
            }
            let ((a, b), _) = query(k);
            if self.without_walks_in(per, k).is_some() {
                Route::WithoutWalks
            } else if self.bidirectional_in(per, k, a, b) {
                Route::Bidirectional
            } else {
                Route::Unidirectional
            }
        };
        let one = |k: usize| {
            let ((a, b), key) = query(k);
            self.eval_one(per, k, a, b, samples, key)
        };
        let without_walks = (0..n).all(|k| route(k) == Route::WithoutWalks);
        // A rough coat's factorization costs its samples; a closed form
        // costs nothing, and runs on the calling thread.
        let sampled = |k: usize| {
            matches!(
                self.without_walks_in(per, k),
                Some(CoatLambertian::Rough(_))
            )
        };
        let large = (n as u64).saturating_mul(samples) > SERIAL_WALKS && (0..n).any(sampled);
        if without_walks && large && !self.serial() {
            // Query by query, over the pool's threads.
            let est = self.install(n, samples, || crate::pool::par_map(n, one));
            est.into_iter().enumerate().for_each(|(k, e)| out(k, e));
            return;
        }
        if without_walks || self.engine.resolve(n, samples) == Engine::Scalar {
            (0..n).for_each(|k| out(k, one(k)));
            return;
        }
        // Each query's walks start from the side `eval_start` chooses.
        let walked = |k: usize| {
            let ((a, b), key) = query(k);
            let s = self.swaps(a[2], b[2]);
            (if s { (b, a) } else { (a, b) }, key)
        };
        // The walks' estimate of query `k` in the transport mode.
        let scaled = |k: usize, e: Estimate| {
            let ((a, b), _) = query(k);
            let swapped = self.swaps(a[2], b[2]);
            self.scaled(self.stack_in(per, k), e, a, b, swapped)
        };
        let serial = self.serial();
        let seed = self.seed;
        let first = if n > 0 {
            route(0)
        } else {
            Route::Unidirectional
        };
        if (1..n).all(|k| route(k) == first) {
            let sets = per.sets();
            let finish = |k: usize, e: Estimate| out(k, scaled(k, e));
            self.install(n, samples, || {
                if first == Route::Bidirectional {
                    (self.wave).eval_bidir_each(sets, n, walked, samples, seed, serial, finish)
                } else {
                    (self.wave).eval_each(sets, n, walked, samples, seed, serial, finish);
                }
            });
            return;
        }
        let mut done: Vec<Option<Estimate>> = vec![None; n];
        for r in [Route::Unidirectional, Route::Bidirectional] {
            let ks: Vec<usize> = (0..n).filter(|&k| route(k) == r).collect();
            let set: Vec<u32> = ks.iter().map(|&k| per.set(k) as u32).collect();
            let sub = per.with_set(&set);
            let (sets, m) = (sub.sets(), ks.len());
            let q = |j: usize| walked(ks[j]);
            let put = |j: usize, e: Estimate| done[ks[j]] = Some(e);
            self.install(m, samples, || {
                if r == Route::Bidirectional {
                    (self.wave).eval_bidir_each(sets, m, q, samples, seed, serial, put)
                } else {
                    (self.wave).eval_each(sets, m, q, samples, seed, serial, put);
                }
            });
        }
        for (k, e) in done.into_iter().enumerate() {
            let ((a, b), key) = query(k);
            out(
                k,
                match route(k) {
                    Route::WithoutWalks => self.eval_one(per, k, a, b, samples, key),
                    _ => scaled(
                        k,
                        e.unwrap_or_else(|| crate::estimator::MeanVar::zeros(samples).estimate()),
                    ),
                },
            );
        }
    }

    /// Query `k`'s eval without walks or on the scalar engine, from the
    /// side `eval_start` chooses, in the transport mode; allocates nothing.
    fn eval_one(&self, per: Per, k: usize, a: Pt, b: Pt, samples: u64, key: u64) -> Estimate {
        let stack = self.stack_in(per, k);
        match self.without_walks_in(per, k) {
            Some(CoatLambertian::Smooth(exact)) => {
                return self.exact_eval(stack, exact, a, b, samples)
            }
            // Reflection only (the stack is opaque): both transport modes
            // and both starting sides agree.
            Some(coat) => {
                let top = match per.0 {
                    None => &self.scalar.ifaces()[0],
                    Some((p, s)) => p.table.iface(s[k] as usize, 0),
                };
                return eval_without_walks(stack, top, coat, a, b, samples, self.seed, key);
            }
            None => {}
        }
        let s = self.swaps(a[2], b[2]);
        let (x, y) = if s { (b, a) } else { (a, b) };
        let eng = self.scalar_in(per, k);
        let e = if self.bidirectional_in(per, k, a, b) {
            eng.eval_bidir(x, y, samples, self.seed, key)
        } else {
            eng.eval(x, y, samples, self.seed, key)
        };
        self.scaled(stack, e, a, b, s)
    }

    /// An estimate of the radiance BSDF of `stack` from `a` to `b` (or,
    /// `swapped`, from `b` to `a`) as this mode's BSDF from `a` to `b`.
    fn scaled(&self, stack: &LayerStack, mut e: Estimate, a: Pt, b: Pt, swapped: bool) -> Estimate {
        if let Some(x) = self.transport.factor_of(stack, a[2], b[2], swapped) {
            e.value = e.value.map(|v| v * x);
            e.stderr = e.stderr.map(|v| v * x);
        }
        e
    }

    /// The closed form of a query, as an estimate of standard error 0 (the
    /// stack is opaque, so reflection only: both transport modes agree).
    fn exact_eval(
        &self,
        stack: &LayerStack,
        exact: &SmoothCoatLambertian,
        a: Pt,
        b: Pt,
        n: u64,
    ) -> Estimate {
        let value = match crate::estimator::orient(stack, a, Some(b)) {
            Some(o) => exact.eval(o.wi, o.apply(b)),
            None => [0.0; 3],
        };
        Estimate {
            value,
            stderr: [0.0; 3],
            samples: n,
            truncated: 0,
        }
    }

    /// Samples of validated directions, each with the pdf
    /// [`LayeredBsdf::pdf`] gives for its direction.
    fn sample_validated(
        &self,
        per: Per,
        dirs: &[Pt],
        keys: &[u64],
        sample_index: &[u64],
    ) -> Vec<Option<Sample>> {
        let mut res = Vec::with_capacity(dirs.len());
        let query = |k: usize| (dirs[k], keys[k], sample_index[k]);
        self.sample_each(per, dirs.len(), query, |_, s| res.push(s));
        res
    }

    /// The samples of the `n` validated queries `query(k) = (wi, key, sample
    /// index)`, each with the pdf [`LayeredBsdf::pdf`] gives for its
    /// direction, handed to `out` in query order. Allocates nothing on the
    /// scalar engine, or serially on a warm thread.
    pub(super) fn sample_each(
        &self,
        per: Per,
        n: usize,
        query: impl Fn(usize) -> (Pt, u64, u64) + Sync,
        out: impl FnMut(usize, Option<Sample>),
    ) {
        self.on_own_threads(|| self.sample_each_here(per, n, query, out))
    }

    /// [`LayeredBsdf::sample_each`] within the thread setting.
    fn sample_each_here(
        &self,
        per: Per,
        n: usize,
        query: impl Fn(usize) -> (Pt, u64, u64) + Sync,
        mut out: impl FnMut(usize, Option<Sample>),
    ) {
        let one = |k: usize| {
            let (a, key, index) = query(k);
            self.sample_one(per, k, a, key, index)
        };
        if self.engine.resolve(n, 1) == Engine::Scalar {
            (0..n).for_each(|k| out(k, one(k)));
            return;
        }
        // Walk-free samplers answer query by query (over the pool's threads
        // when the batch is large); the walks run as a batch of their own.
        let free = |k: usize| self.exact_sampler(per, k).is_some();
        let n_free = (0..n).filter(|&k| free(k)).count();
        if n_free == n {
            // The closed form's sampler costs next to nothing: the pool only
            // for the rough coats' (a few of their transmissions a sample).
            let rough =
                |k: usize| matches!(self.exact_sampler(per, k), Some(CoatLambertian::Rough(_)));
            if n as u64 > SERIAL_WALKS && !self.serial() && (0..n).any(rough) {
                let s = self.install(n, 1, || crate::pool::par_map(n, one));
                s.into_iter().enumerate().for_each(|(k, s)| out(k, s));
            } else {
                (0..n).for_each(|k| out(k, one(k)));
            }
            return;
        }
        if n_free == 0 {
            self.sample_walked(per, n, query, out);
            return;
        }
        let ks: Vec<usize> = (0..n).filter(|&k| !free(k)).collect();
        let set: Vec<u32> = ks.iter().map(|&k| per.set(k) as u32).collect();
        let mut walked = Vec::with_capacity(ks.len());
        let sub = |j: usize| query(ks[j]);
        self.sample_walked(per.with_set(&set), ks.len(), sub, |_, s| walked.push(s));
        let mut walked = walked.into_iter();
        for k in 0..n {
            let s = if free(k) {
                one(k)
            } else {
                walked.next().flatten()
            };
            out(k, s);
        }
    }

    /// [`LayeredBsdf::sample_each`] of queries that all walk, on the
    /// wavefront engine.
    fn sample_walked(
        &self,
        per: Per,
        n: usize,
        query: impl Fn(usize) -> (Pt, u64, u64) + Sync,
        mut out: impl FnMut(usize, Option<Sample>),
    ) {
        with_kept(&SAMPLES, |b| {
            let serial = self.serial();
            let walks = &mut b.walks;
            walks.clear();
            self.install(n, 1, || {
                let push = |_, w| walks.push(w);
                (self.wave).sample_each(per.sets(), n, &query, self.seed, serial, push)
            });
            // The pdf of each sampled direction, as `pdf(wi, wo)` computes it
            // (0 for a direction that is not one, as on the scalar path).
            let pair = |w: &Option<WalkSample>, a: Pt| {
                Some((a, Direction::new("wo", w.as_ref()?.wo).ok()?.get()))
            };
            b.pairs.clear();
            b.sets.clear();
            for (k, w) in b.walks.iter().enumerate() {
                if let Some(p) = pair(w, query(k).0) {
                    b.pairs.push(p);
                    b.sets.push(per.set(k) as u32);
                }
            }
            let sub = per.with_set(&b.sets);
            b.pdf.clear();
            if self.pdf_walks.is_lobes() {
                let (pairs, sub) = (&b.pairs, per.with_set(&b.sets));
                b.pdf.extend(
                    pairs
                        .iter()
                        .enumerate()
                        .map(|(j, &(a, wo))| self.lobe_pdf_in(sub, j, a, wo)),
                );
            } else if serial || b.pairs.len() <= PDF_CHUNK {
                // On this thread (where `pdf_validated` would run them too),
                // lane for lane its numbers, from buffers the thread keeps.
                let (pairs, pdf) = (&b.pairs, &mut b.pdf);
                let keyed = |j: usize| (pairs[j], pdf_key(pairs[j].0, pairs[j].1));
                let push = |_, p: PdfEstimate| pdf.push(p.value as f32);
                let (n, walks) = (pairs.len(), self.pdf_walks);
                let kind = PdfKind::Approximate;
                (self.wave).pdf_each(sub.sets(), n, keyed, walks, self.seed, kind, push);
            } else {
                b.pdf.extend(self.pdf_validated(sub, &b.pairs));
            }
            let mut pdfs = b.pdf.iter();
            for (k, &w) in b.walks.iter().enumerate() {
                let a = query(k).0;
                let pdf = match pair(&w, a) {
                    Some(_) => pdfs.next().copied().unwrap_or(0.0),
                    None => 0.0,
                };
                out(
                    k,
                    w.map(|w| self.finish_sample(self.stack_in(per, k), w, a, pdf)),
                );
            }
        })
    }

    /// Query `k`'s sample on the scalar engine, with its pdf; allocates nothing.
    fn sample_one(&self, per: Per, k: usize, a: Pt, key: u64, index: u64) -> Option<Sample> {
        let mut rng = WalkRng::new(self.seed, key, index, Stream::Walk);
        let stack = self.stack_in(per, k);
        let w = match self.exact_sampler(per, k) {
            Some(exact) => exact.sample_query(stack, a, &mut rng)?,
            None => self.scalar_in(per, k).sample(a, &mut rng)?,
        };
        let pdf = Direction::new("wo", w.wo).map_or(0.0, |b| self.pdf_one(per, k, a, b.get()));
        Some(self.finish_sample(stack, w, a, pdf))
    }

    /// A walk's sample from `a` with its pdf, in the transport mode.
    fn finish_sample(&self, stack: &LayerStack, w: WalkSample, a: Pt, pdf: f32) -> Sample {
        let mut weight = w.weight;
        if let Some(s) = self.transport.factor(stack, a[2], w.wo.z as f64) {
            weight = weight.map(|v| (v as f64 * s) as f32);
        }
        Sample {
            wo: w.wo,
            weight,
            pdf,
            reflection: w.reflection,
            specular: w.specular,
        }
    }

    /// The engine of a pdf call of `queries` queries, by the walks of its
    /// first round (a pilot's, or a fixed count): a density walk costs
    /// several eval walks and one query's walks share a chunk, so the
    /// wavefront answers from 4 query-walks on (docs/performance.md measures
    /// the crossing).
    pub(super) fn pdf_engine(&self, queries: usize) -> Engine {
        self.engine
            .resolve(queries, 2 * self.pdf_walks.first_round())
    }

    /// Whether a pdf call of `queries` queries of the BSDF's own stack runs
    /// query by query: by the walk-free sampler, or on the scalar engine.
    pub(super) fn pdf_by_query(&self, queries: usize) -> bool {
        self.sample_is_exact()
            || self.pdf_walks.is_lobes()
            || self.pdf_engine(queries) == Engine::Scalar
    }

    /// Whether the `n` queries of `per` take their pdfs one by one
    /// ([`LayeredBsdf::pdf_one`]): [`LayeredBsdf::pdf_by_query`] on the
    /// BSDF's own stack; with sets, by the lobe pdf, where every query's set
    /// has a walk-free sampler, or on the scalar engine.
    pub(super) fn pdf_by_query_in(&self, per: Per, n: usize) -> bool {
        if per.is_own() {
            return self.pdf_by_query(n);
        }
        let free = |k: usize| self.exact_sampler(per, k).is_some();
        self.pdf_walks.is_lobes() || (0..n).all(free) || self.pdf_engine(n) == Engine::Scalar
    }

    /// Query `k`'s approximate pdf, keyed by the directions, on the engine
    /// [`LayeredBsdf::pdf_engine`] picks; allocates nothing once the thread
    /// is warm.
    pub(super) fn pdf_one(&self, per: Per, k: usize, a: Pt, b: Pt) -> f32 {
        if let Some(exact) = self.exact_sampler(per, k) {
            return exact.pdf_query(self.stack_in(per, k), a, b) as f32;
        }
        if self.pdf_walks.is_lobes() {
            return self.lobe_pdf_in(per, k, a, b);
        }
        let key = pdf_key(a, b);
        if self.pdf_engine(1) == Engine::Scalar {
            return (self.scalar_in(per, k)).pdf(a, b, self.pdf_walks, self.seed, key) as f32;
        }
        let mut p = 0.0;
        let (walks, kind) = (self.pdf_walks, PdfKind::Approximate);
        let put = |_, e: PdfEstimate| p = e.value as f32;
        let one = per.one(k);
        (self.wave).pdf_each(
            one.sets(),
            1,
            |_| ((a, b), key),
            walks,
            self.seed,
            kind,
            put,
        );
        p
    }

    /// The approximate pdf of validated pairs, keyed by the directions.
    pub(super) fn pdf_validated(&self, per: Per, dirs: &[Pair]) -> Vec<f32> {
        let n = dirs.len();
        let free = |k: usize| self.exact_sampler(per, k).is_some();
        if self.pdf_by_query_in(per, n) {
            let pdf = |(k, &(a, b)): (usize, &Pair)| self.pdf_one(per, k, a, b);
            return dirs.iter().enumerate().map(pdf).collect();
        }
        if (0..n).any(free) {
            // Walk-free pdfs query by query, the density walks as a batch.
            let ks: Vec<usize> = (0..n).filter(|&k| !free(k)).collect();
            let set: Vec<u32> = ks.iter().map(|&k| per.set(k) as u32).collect();
            let sub: Vec<Pair> = ks.iter().map(|&k| dirs[k]).collect();
            let mut walked = self.pdf_validated(per.with_set(&set), &sub).into_iter();
            return (0..n)
                .map(|k| match free(k) {
                    true => self.pdf_one(per, k, dirs[k].0, dirs[k].1),
                    false => walked.next().unwrap_or(0.0),
                })
                .collect();
        }
        let keys: Vec<u64> = dirs.iter().map(|&(a, b)| pdf_key(a, b)).collect();
        let p = self.install_if(dirs.len() > PDF_CHUNK, || {
            self.wave.pdf_batch_in(
                per.sets(),
                dirs,
                self.pdf_walks,
                self.seed,
                &keys,
                PdfKind::Approximate,
            )
        });
        p.into_iter().map(|x| x.value as f32).collect()
    }

    /// The unbiased pdf of validated pairs, `samples` density walks each,
    /// keyed by the directions.
    pub(super) fn pdf_unbiased_validated(
        &self,
        per: Per,
        dirs: &[Pair],
        samples: u64,
    ) -> Vec<PdfEstimate> {
        let kind = PdfKind::Unbiased;
        let n = dirs.len();
        let free = |k: usize| self.exact_sampler(per, k).is_some();
        if (0..n).any(free) && !(0..n).all(free) {
            // Walk-free pdfs query by query, the density walks as a batch.
            let ks: Vec<usize> = (0..n).filter(|&k| !free(k)).collect();
            let set: Vec<u32> = ks.iter().map(|&k| per.set(k) as u32).collect();
            let sub: Vec<Pair> = ks.iter().map(|&k| dirs[k]).collect();
            let walked = self.pdf_unbiased_validated(per.with_set(&set), &sub, samples);
            let mut walked = walked.into_iter();
            return (0..n)
                .map(|k| match free(k) {
                    true => self.exact_pdf(per, k, dirs[k], samples),
                    false => walked.next().expect("one per walked query"),
                })
                .collect();
        }
        if (0..n).all(free) || self.engine.resolve(n, samples) == Engine::Scalar {
            return dirs
                .iter()
                .enumerate()
                .map(|(k, &(a, b))| {
                    if free(k) {
                        return self.exact_pdf(per, k, (a, b), samples);
                    }
                    let key = pdf_key(a, b);
                    self.scalar_in(per, k)
                        .pdf_estimate(a, b, samples, self.seed, key, kind)
                })
                .collect();
        }
        let keys: Vec<u64> = dirs.iter().map(|&(a, b)| pdf_key(a, b)).collect();
        self.install(dirs.len(), samples, || {
            (self.wave).pdf_batch_in(per.sets(), dirs, samples, self.seed, &keys, kind)
        })
    }

    /// Query `k`'s exact pdf from its walk-free sampler, as an estimate of
    /// standard error 0.
    fn exact_pdf(&self, per: Per, k: usize, (a, b): Pair, samples: u64) -> PdfEstimate {
        let value = self
            .exact_sampler(per, k)
            .map_or(0.0, |e| e.pdf_query(self.stack_in(per, k), a, b));
        PdfEstimate {
            value,
            stderr: 0.0,
            samples,
            truncated: 0,
        }
    }

    /// Albedos of validated directions; the transmitted fraction follows the
    /// transport mode.
    fn albedo_validated(&self, per: Per, dirs: &[Pt], n: u64, keys: &[u64]) -> Vec<Albedo> {
        let mut res = Vec::with_capacity(dirs.len());
        let query = |k| (dirs[k], keys[k]);
        self.albedo_each(per, dirs.len(), n, query, |_, a| res.push(a));
        res
    }

    /// The albedos of the `m` validated queries `query(k) = (wi, key)`, `n`
    /// walks each, handed to `out` in query order; the transmitted fraction
    /// follows the transport mode. Allocates nothing on the scalar engine,
    /// or serially on a warm thread.
    pub(super) fn albedo_each(
        &self,
        per: Per,
        m: usize,
        n: u64,
        query: impl Fn(usize) -> (Pt, u64) + Sync,
        mut out: impl FnMut(usize, Albedo) + Send,
    ) {
        debug_assert!(
            !per.0.is_some_and(|(p, _)| p.table.is_lean()),
            "albedo walks every set: its table has every set's lanes"
        );
        let mut finish = |k: usize, mut r: Albedo| {
            let a = query(k).0;
            if let Some(s) = self.transport.factor(self.stack_in(per, k), a[2], -a[2]) {
                let t = &mut r.transmitted;
                t.value = t.value.map(|v| v * s);
                t.stderr = t.stderr.map(|v| v * s);
            }
            out(k, r);
        };
        if self.engine.resolve(m, n) == Engine::Scalar {
            for k in 0..m {
                let (a, key) = query(k);
                finish(k, self.scalar_in(per, k).albedo(a, n, self.seed, key));
            }
            return;
        }
        let serial = self.serial();
        let sets = per.sets();
        self.install(m, n, || {
            (self.wave).albedo_each(sets, m, &query, n, self.seed, serial, finish)
        });
    }

    /// Query `k`'s stack, as far as the calls read it beyond the lanes'
    /// numbers: its shape, IORs and sidedness.
    pub(super) fn stack_in<'a>(&'a self, per: Per<'a>, k: usize) -> &'a LayerStack {
        match per.0 {
            Some((p, s)) if !p.stacks.is_empty() => &p.stacks[s[k] as usize],
            _ => self.stack(),
        }
    }

    /// Query `k`'s scalar engine: the BSDF's, or one made for its set.
    pub(super) fn scalar_in<'a>(&'a self, per: Per<'a>, k: usize) -> Cow<'a, ScalarEngine<f32>> {
        match per.0 {
            None => Cow::Borrowed(&self.scalar),
            Some((p, s)) => {
                let s = s[k] as usize;
                Cow::Owned(self.scalar.for_set(p.stacks.get(s), &p.table, s))
            }
        }
    }

    /// Query `k`'s lobe pdf (`estimator::lobe_pdf`), with no engine made.
    pub(super) fn lobe_pdf_in(&self, per: Per, k: usize, a: Pt, b: Pt) -> f32 {
        let v = match per.0 {
            None => self.scalar.lobe_pdf(a, b),
            Some((p, s)) => {
                let s = s[k] as usize;
                let ifaces = p.table.ifaces_of(s);
                lobe_pdf(self.stack_in(per, k), ifaces, p.table.body(s), a, b)
            }
        };
        v as f32
    }

    /// What answers query `k`'s eval without walks, if anything
    /// ([`LayeredBsdf::eval_without_walks`], per set).
    pub(super) fn without_walks_in<'a>(
        &'a self,
        per: Per<'a>,
        k: usize,
    ) -> Option<&'a CoatLambertian> {
        match per.0 {
            None => self.without_walks(),
            // The estimator and the layer's class are the shape's: the same
            // for every set; whether the set has a walk-free form is its own.
            Some((p, s)) => self
                .walks_can_be_skipped()
                .then_some(p.coat[s[k] as usize].as_ref())
                .flatten(),
        }
    }
}

/// What a wavefront sample call keeps between calls on its thread.
#[derive(Default)]
struct SampleBuffers {
    walks: Vec<Option<WalkSample>>,
    pairs: Vec<Pair>,
    /// Each pair's parameter set (with sets).
    sets: Vec<u32>,
    pdf: Vec<f32>,
}

thread_local! {
    /// The buffers of this thread's wavefront sample calls.
    static SAMPLES: RefCell<Option<SampleBuffers>> = const { RefCell::new(None) };
}

/// One entry of a per-query argument for every query.
pub(super) fn one_each(
    argument: &'static str,
    len: usize,
    queries: usize,
) -> Result<(), BatchError> {
    if len == queries {
        Ok(())
    } else {
        Err(BatchError::call(QueryError::LengthMismatch {
            argument,
            len,
            queries,
        }))
    }
}

/// A direction of query `index`, validated.
pub(super) fn direction_at(
    argument: &'static str,
    index: usize,
    w: Vec3,
) -> Result<[f64; 3], BatchError> {
    Direction::new(argument, w)
        .map(Direction::get)
        .map_err(|error| BatchError {
            index: Some(index),
            error,
        })
}

fn directions1(wis: &[Vec3]) -> Result<Vec<[f64; 3]>, BatchError> {
    wis.iter()
        .enumerate()
        .map(|(i, &w)| direction_at("wi", i, w))
        .collect()
}

/// A validated direction.
type Pt = [f64; 3];

/// A validated `(wi, wo)` pair.
pub(super) type Pair = ([f64; 3], [f64; 3]);

/// How a query's eval is answered.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Route {
    /// By what `CoatLambertian` knows, query by query.
    WithoutWalks,
    /// By the unidirectional walks.
    Unidirectional,
    /// By the bidirectional walks.
    Bidirectional,
}

pub(super) fn directions2(pairs: &[(Vec3, Vec3)]) -> Result<Vec<Pair>, BatchError> {
    pairs
        .iter()
        .enumerate()
        .map(|(i, &(a, b))| Ok((direction_at("wi", i, a)?, direction_at("wo", i, b)?)))
        .collect()
}

/// The key of a pdf query: the bits of the normalized directions in f32.
pub(super) fn pdf_key(a: [f64; 3], b: [f64; 3]) -> u64 {
    let f32s = |d: [f64; 3]| Vec3::new(d[0] as f32, d[1] as f32, d[2] as f32);
    direction_key(f32s(a), f32s(b))
}

/// A query key from the bits of two directions.
pub fn direction_key(wi: Vec3, wo: Vec3) -> u64 {
    let mut k = 0x5bd1_e995u64;
    for x in wi.to_array().into_iter().chain(wo.to_array()) {
        k = mix64(k ^ x.to_bits() as u64);
    }
    k
}
