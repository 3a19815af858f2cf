//! The hardware crate's error type: every message is one line naming the file or device
//! and what was expected of it.

use std::fmt;
use std::path::Path;

/// What went wrong, broadly.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum ErrorKind {
    /// A file or folder could not be read.
    Io,
    /// A file or a camera buffer is not what was expected (format, size, missing image).
    Format,
    /// A device could not be opened, configured or read.
    Device,
    /// A source specification that does not parse.
    Spec,
    /// The source or output needs a feature this build does not have.
    NotBuilt,
    /// The projector window could not be shown.
    Display,
    /// The estimator refused a frame, or its thread ended unexpectedly.
    Estimate,
    /// A flag's value is not what was expected.
    Input,
}

/// A hardware I/O error with a one-line message.
#[derive(Debug, Clone)]
pub struct Error {
    kind: ErrorKind,
    message: String,
    /// The cell, rig or image file error this one reports, when it is one.
    // Boxed: a config error names a file and a key, and would make every `Result` of
    // this crate large.
    source: Option<Box<camplace_config::Error>>,
}

impl Error {
    /// An error of `kind` with a message naming the file or device.
    pub fn new(kind: ErrorKind, message: impl Into<String>) -> Self {
        Error { kind, message: message.into(), source: None }
    }

    /// A format error about `path`: `path: message`.
    pub fn format(path: &Path, message: impl fmt::Display) -> Self {
        Self::new(ErrorKind::Format, format!("{}: {message}", path.display()))
    }

    /// An I/O error about `path`, with the I/O error as its source.
    pub fn io(path: &Path, err: &std::io::Error) -> Self {
        camplace_config::Error::io(path, err).into()
    }

    /// A bad flag value or input: the message names the flag or file.
    pub fn input(message: impl Into<String>) -> Self {
        Self::new(ErrorKind::Input, message)
    }

    /// This error, said to belong to the file `path`: `path: message`.
    pub fn in_file(self, path: &Path) -> Self {
        Error { message: format!("{}: {}", path.display(), self.message), ..self }
    }

    /// A device error: `device: message`.
    pub fn device(device: impl fmt::Display, message: impl fmt::Display) -> Self {
        Self::new(ErrorKind::Device, format!("{device}: {message}"))
    }

    /// What went wrong, broadly.
    pub fn kind(&self) -> ErrorKind {
        self.kind
    }

    /// The message, one line.
    pub fn message(&self) -> &str {
        &self.message
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        // Device drivers and libraries like multi-line text; keep ours to one line.
        let mut first = true;
        for word in self.message.split_whitespace() {
            if !first {
                f.write_str(" ")?;
            }
            f.write_str(word)?;
            first = false;
        }
        Ok(())
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        self.source.as_deref().map(|e| e as &(dyn std::error::Error + 'static))
    }
}

impl From<camplace_config::Error> for Error {
    fn from(e: camplace_config::Error) -> Self {
        let kind = match e.kind() {
            camplace_config::ErrorKind::Io => ErrorKind::Io,
            _ => ErrorKind::Format,
        };
        Error { kind, message: e.to_string(), source: Some(Box::new(e)) }
    }
}

impl From<camplace_plot::Error> for Error {
    fn from(e: camplace_plot::Error) -> Self {
        Self::new(ErrorKind::Io, e.to_string())
    }
}

/// The hardware crate's result type.
impl From<camplace_estimator::Error> for Error {
    fn from(e: camplace_estimator::Error) -> Self {
        Error::new(ErrorKind::Estimate, e.to_string())
    }
}

pub type Result<T> = std::result::Result<T, Error>;

#[cfg(test)]
mod tests {
    use super::*;
    use std::error::Error as _;

    #[test]
    fn an_io_error_names_the_path_and_keeps_the_os_error() {
        let e = Error::io(Path::new("frames"), &std::io::Error::from_raw_os_error(13));
        assert_eq!(e.kind(), ErrorKind::Io);
        assert!(e.to_string().starts_with("frames: "), "{e}");
        let mut cause = e.source();
        let mut os = None;
        while let Some(c) = cause {
            os = os.or(c.downcast_ref::<std::io::Error>().and_then(|io| io.raw_os_error()));
            cause = c.source();
        }
        assert_eq!(os, Some(13));
    }
}
