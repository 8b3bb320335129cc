//! Errors from building or loading a material.

use std::fmt;

/// An invalid value in a material description: names the layer, the field and
/// the value.
#[derive(Clone, Debug, PartialEq)]
pub struct StackError {
    /// Index of the layer (top = 0), or `None` for a material-level field.
    pub layer: Option<usize>,
    /// The field, as spelled in the file (e.g. `medium.thickness`).
    pub field: String,
    /// The offending value, as text (empty when the problem is structural).
    pub value: String,
    /// What is wrong.
    pub problem: String,
}

impl StackError {
    #[cold]
    pub(crate) fn new(layer: Option<usize>, field: &str, value: f64, problem: &str) -> Self {
        StackError {
            layer,
            field: field.into(),
            value: format!("{value}"),
            problem: problem.into(),
        }
    }
    #[cold]
    pub(crate) fn new_rgb(layer: Option<usize>, field: &str, v: [f64; 3], problem: &str) -> Self {
        StackError {
            layer,
            field: field.into(),
            value: format!("[{}, {}, {}]", v[0], v[1], v[2]),
            problem: problem.into(),
        }
    }
    pub(crate) fn msg(layer: Option<usize>, field: &str, problem: &str) -> Self {
        StackError {
            layer,
            field: field.into(),
            value: String::new(),
            problem: problem.into(),
        }
    }
}

impl fmt::Display for StackError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(l) = self.layer {
            write!(f, "layer {l}: ")?;
        }
        if self.value.is_empty() {
            write!(f, "{}: {}", self.field, self.problem)
        } else {
            write!(f, "{} = {}: {}", self.field, self.value, self.problem)
        }
    }
}

impl std::error::Error for StackError {}

/// Loading a material file failed.
#[derive(Clone, Debug, PartialEq)]
pub enum MaterialError {
    /// The file could not be read.
    Io {
        /// The path.
        path: String,
        /// The operating system's message.
        message: String,
    },
    /// The text is not valid TOML/JSON for the format (the message names the
    /// line and the field).
    Parse {
        /// "TOML" or "JSON".
        format: &'static str,
        /// The parser's message.
        message: String,
    },
    /// The values are invalid.
    Invalid(StackError),
}

impl From<StackError> for MaterialError {
    fn from(e: StackError) -> Self {
        MaterialError::Invalid(e)
    }
}

impl fmt::Display for MaterialError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MaterialError::Io { path, message } => write!(f, "cannot read {path}: {message}"),
            MaterialError::Parse { format, message } => {
                write!(f, "invalid {format} material: {}", message.trim_end())
            }
            MaterialError::Invalid(e) => write!(f, "invalid material: {e}"),
        }
    }
}

impl std::error::Error for MaterialError {}
