//! The service's error type: what stopped `serve` from starting or running, one line each.

use std::fmt;

/// What kind of failure an [`Error`] is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum ErrorKind {
    /// An address could not be bound or a socket could not be set up.
    Network,
    /// A setting is out of its range.
    Setting,
    /// The flight recorder's folder could not be written.
    Recorder,
    /// A thread could not be started or ended unexpectedly.
    Thread,
}

/// A service error with a one-line message naming the address, flag or folder.
#[derive(Debug, Clone)]
pub struct Error {
    kind: ErrorKind,
    message: String,
}

impl Error {
    /// An error of `kind` saying `message`.
    pub fn new(kind: ErrorKind, message: impl Into<String>) -> Self {
        Error { kind, message: message.into() }
    }

    /// What kind of failure it is.
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

/// The service's result type.
pub type Result<T> = std::result::Result<T, Error>;
