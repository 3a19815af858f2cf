//! The estimator's error type: data-dependent failures (a rig that cannot be rectified,
//! buffers of the wrong size, a model file that does not decode).

use std::fmt;

/// What went wrong, broadly.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum ErrorKind {
    /// The rig cannot be used (cameras not a stereo pair, degenerate geometry).
    Rig,
    /// Inputs of the wrong size or shape.
    Input,
    /// A model that does not decode or is of another format version.
    Model,
}

/// An estimator error with a one-line message naming the field and what was expected.
#[derive(Debug, Clone)]
pub struct Error {
    kind: ErrorKind,
    message: String,
}

impl Error {
    /// An error of `kind`.
    pub fn new(kind: ErrorKind, message: impl Into<String>) -> Self {
        Error { kind, message: message.into() }
    }

    /// What went wrong, broadly.
    pub fn kind(&self) -> ErrorKind {
        self.kind
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for Error {}

/// The estimator's result type.
pub type Result<T> = std::result::Result<T, Error>;
