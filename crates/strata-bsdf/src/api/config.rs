//! A BSDF's configuration as one value with one text form, so that every
//! front end (the CLI, C, Python) reads and prints settings the same way.

use super::bsdf::LayeredBsdf;
use super::error::{ThreadsError, MAX_THREADS, MAX_WALKS};
use super::strategy::{Engine, Estimator, EvalStart};
use super::transport::Transport;
use crate::estimator::events::{MAX_CAP, MIN_RR_THRESHOLD};
use crate::estimator::pdf::PdfWalks;
use crate::estimator::Settings;
use std::fmt;

/// How a [`LayeredBsdf`] answers, apart from its stack: one value per
/// setting, each with a text form.
///
/// Its text is `key=value` pairs separated by whitespace, in any order;
/// [`Config`]'s `Display` prints every key in the order of [`CONFIG_KEYS`],
/// and parsing what it prints gives the same value (`tests/api/config.rs`):
///
/// ```
/// use strata_bsdf::{Config, LayeredBsdf, PdfWalks, materials};
/// let c: Config = "samples=1 pdf_walks=adaptive transport=importance".parse().unwrap();
/// assert_eq!((c.samples, c.pdf_walks), (1, PdfWalks::ADAPTIVE));
/// let bsdf = LayeredBsdf::new(materials::builtin("coated_copper").unwrap())
///     .with_config(&c)
///     .unwrap();
/// assert_eq!(bsdf.config(), c);
/// assert_eq!(c.to_string().parse::<Config>().unwrap(), c);
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct Config {
    /// Walks per `eval` (`samples`, at least 1).
    pub samples: u64,
    /// The approximate pdf's walks (`pdf_walks`: `lobes`, `adaptive`,
    /// `tight`, a count, or `PILOT,MAX,REL_STDERR`).
    pub pdf_walks: PdfWalks,
    /// The seed of every random stream (`seed`).
    pub seed: u64,
    /// What flows from `wi` to `wo` (`transport`: `radiance`, `importance`).
    pub transport: Transport,
    /// Where `eval` starts its walks (`eval_start`: `normal`, `wi`).
    pub eval_start: EvalStart,
    /// The estimator of `eval` (`estimator`: `auto`, `uni`, `bidir`).
    pub estimator: Estimator,
    /// The engine (`engine`: `auto`, `scalar`, `wavefront`).
    pub engine: Engine,
    /// Where large batches run (`threads`): `None` (`current`) on rayon's
    /// current pool, `Some(1)` on the calling thread, `Some(n)` on a pool
    /// of the BSDF's own.
    pub threads: Option<usize>,
    /// The walk settings (`max_events`, `rr_start`, `rr_threshold`,
    /// `max_scatter_order`: a number or `none`, `mis`: `true` or `false`).
    pub settings: Settings,
}

/// The keys of [`Config`]'s text form, in the order it prints them.
pub const CONFIG_KEYS: [&str; 13] = [
    "samples",
    "pdf_walks",
    "seed",
    "transport",
    "eval_start",
    "estimator",
    "engine",
    "threads",
    "max_events",
    "rr_start",
    "rr_threshold",
    "max_scatter_order",
    "mis",
];

/// A setting that [`Config`] does not take: the key, the value as given,
/// and why.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ConfigError {
    /// The key (as given).
    pub key: String,
    /// The value (as given).
    pub value: String,
    /// What is wrong.
    pub why: String,
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}={}: {}", self.key, self.value, self.why)
    }
}

impl std::error::Error for ConfigError {}

impl Default for Config {
    /// A new [`LayeredBsdf`]'s configuration.
    fn default() -> Self {
        Config {
            samples: LayeredBsdf::DEFAULT_SAMPLES,
            pdf_walks: PdfWalks::DEFAULT,
            seed: 0,
            transport: Transport::default(),
            eval_start: EvalStart::default(),
            estimator: Estimator::default(),
            engine: Engine::default(),
            threads: None,
            settings: Settings::default(),
        }
    }
}

/// A whole number in `range`, or why not.
fn count(value: &str, range: std::ops::RangeInclusive<u64>) -> Result<u64, String> {
    match value.parse::<u64>() {
        Ok(n) if range.contains(&n) => Ok(n),
        _ => Err(format!(
            "expected a whole number from {} to {}",
            range.start(),
            range.end()
        )),
    }
}

impl Config {
    /// Sets `key` to `value` (their text forms, as [`Config`] describes):
    /// an unknown key or a value out of its range is an error naming both.
    pub fn set(&mut self, key: &str, value: &str) -> Result<(), ConfigError> {
        let v = value.trim();
        let s = &mut self.settings;
        let done = match key.trim() {
            "samples" => count(v, 1..=MAX_WALKS).map(|n| self.samples = n),
            "pdf_walks" => v.parse().map(|w| self.pdf_walks = w),
            "seed" => count(v, 0..=u64::MAX).map(|n| self.seed = n),
            "transport" => v.parse().map(|t| self.transport = t),
            "eval_start" => v.parse().map(|e| self.eval_start = e),
            "estimator" => v.parse().map(|e| self.estimator = e),
            "engine" => v.parse().map(|e| self.engine = e),
            "threads" if v == "current" => {
                self.threads = None;
                Ok(())
            }
            "threads" => count(v, 1..=MAX_THREADS as u64).map(|n| self.threads = Some(n as usize)),
            "max_events" => count(v, 1..=MAX_CAP as u64).map(|n| s.max_events = n as u32),
            "rr_start" => count(v, 0..=u32::MAX as u64).map(|n| s.rr_start = n as u32),
            "rr_threshold" => match v.parse::<f64>() {
                Ok(t) if (MIN_RR_THRESHOLD..=1.0).contains(&t) => {
                    s.rr_threshold = t;
                    Ok(())
                }
                _ => Err(format!("expected a number from {MIN_RR_THRESHOLD} to 1")),
            },
            "max_scatter_order" if v == "none" => {
                s.max_scatter_order = None;
                Ok(())
            }
            "max_scatter_order" => count(v, 0..=u32::MAX as u64)
                .map(|n| s.max_scatter_order = Some(n as u32))
                .map_err(|e| format!("{e}, or none")),
            "mis" => v
                .parse()
                .map(|m| s.mis = m)
                .map_err(|_| "expected true or false".to_string()),
            _ => Err(format!(
                "unknown setting (known: {})",
                CONFIG_KEYS.join(", ")
            )),
        };
        done.map_err(|why| ConfigError {
            key: key.to_string(),
            value: value.to_string(),
            why,
        })
    }

    /// The text form of `key`'s value, if `key` is one of [`CONFIG_KEYS`].
    pub fn get(&self, key: &str) -> Option<String> {
        let s = &self.settings;
        Some(match key {
            "samples" => self.samples.to_string(),
            "pdf_walks" => self.pdf_walks.to_string(),
            "seed" => self.seed.to_string(),
            "transport" => self.transport.as_str().to_string(),
            "eval_start" => self.eval_start.as_str().to_string(),
            "estimator" => self.estimator.as_str().to_string(),
            "engine" => self.engine.as_str().to_string(),
            "threads" => self
                .threads
                .map_or_else(|| "current".to_string(), |n| n.to_string()),
            "max_events" => s.max_events.to_string(),
            "rr_start" => s.rr_start.to_string(),
            "rr_threshold" => s.rr_threshold.to_string(),
            "max_scatter_order" => s
                .max_scatter_order
                .map_or_else(|| "none".to_string(), |n| n.to_string()),
            "mis" => s.mis.to_string(),
            _ => return None,
        })
    }

    /// Sets every `key=value` pair of `text` (separated by whitespace), in
    /// order; the first that is not taken is the error, and then nothing is
    /// set.
    pub fn apply(&mut self, text: &str) -> Result<(), ConfigError> {
        let mut c = self.clone();
        for pair in text.split_whitespace() {
            let Some((key, value)) = pair.split_once('=') else {
                return Err(ConfigError {
                    key: pair.to_string(),
                    value: String::new(),
                    why: "expected key=value".to_string(),
                });
            };
            c.set(key, value)?;
        }
        *self = c;
        Ok(())
    }
}

impl fmt::Display for Config {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, key) in CONFIG_KEYS.iter().enumerate() {
            let sep = if i == 0 { "" } else { " " };
            let value = self.get(key).unwrap_or_default();
            write!(f, "{sep}{key}={value}")?;
        }
        Ok(())
    }
}

impl std::str::FromStr for Config {
    type Err = ConfigError;
    /// The default configuration with `text`'s settings ([`Config::apply`]).
    fn from_str(text: &str) -> Result<Self, ConfigError> {
        let mut c = Config::default();
        c.apply(text)?;
        Ok(c)
    }
}

impl LayeredBsdf {
    /// Its configuration.
    pub fn config(&self) -> Config {
        Config {
            samples: self.samples,
            pdf_walks: self.pdf_walks,
            seed: self.seed,
            transport: self.transport_mode(),
            eval_start: self.eval_start,
            estimator: self.estimator,
            engine: self.engine,
            threads: self.threads_setting(),
            settings: self.settings,
        }
    }

    /// The same stack answered with `config`: what the builder calls of
    /// each setting make (`tests/api/config.rs` checks it bit for bit). A
    /// pool of the BSDF's own is kept where `threads` is unchanged; a new
    /// one that cannot be built is the error.
    pub fn with_config(self, config: &Config) -> Result<LayeredBsdf, ThreadsError> {
        let threads = self.threads_setting();
        let mut b = self;
        if b.settings != config.settings {
            b = b.with_settings_of(config.settings);
        }
        let b = b
            .samples(config.samples)
            .pdf_walks(config.pdf_walks)
            .seed(config.seed)
            .eval_start(config.eval_start)
            .engine(config.engine)
            .estimator(config.estimator)
            .transport(config.transport);
        if threads == config.threads {
            return Ok(b);
        }
        match config.threads {
            Some(n) => b.threads(n),
            None => Ok(b.on_current_pool()),
        }
    }
}
