//! The estimator's error type: data-dependent failures (a rig that cannot be rectified,
//! buffers of the wrong size, a model file that does not decode, calibration views that do
//! not determine the cameras).

use std::fmt;
use std::sync::Arc;

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
    /// Calibration views that do not determine the cameras (degenerate board poses) or a
    /// refinement that diverged.
    Calibration,
}

/// An estimator error with a one-line message naming the field and what was expected, and
/// the underlying error when another one caused it.
#[derive(Debug, Clone)]
pub struct Error {
    kind: ErrorKind,
    message: String,
    source: Option<Arc<dyn std::error::Error + Send + Sync + 'static>>,
}

impl Error {
    /// An error of `kind`.
    pub fn new(kind: ErrorKind, message: impl Into<String>) -> Self {
        Error { kind, message: message.into(), source: None }
    }

    /// An error of `kind` caused by `source`, which [`std::error::Error::source`] returns.
    pub fn with_source(
        kind: ErrorKind,
        message: impl Into<String>,
        source: impl std::error::Error + Send + Sync + 'static,
    ) -> Self {
        Error { kind, message: message.into(), source: Some(Arc::new(source)) }
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

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        self.source.as_deref().map(|e| e as &(dyn std::error::Error + 'static))
    }
}

/// The estimator's result type.
pub type Result<T> = std::result::Result<T, Error>;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_wrapped_error_is_the_source() {
        let config = camplace_config::Error::value("estimator.k", "expected at least 1");
        let e = Error::with_source(ErrorKind::Input, config.to_string(), config.clone());
        assert_eq!(e.kind(), ErrorKind::Input);
        assert_eq!(e.to_string(), config.to_string());
        let source = std::error::Error::source(&e).expect("a source");
        assert_eq!(source.to_string(), config.to_string());
        assert!(std::error::Error::source(&Error::new(ErrorKind::Model, "model: bad")).is_none());
    }
}
