//! The one error type of the config crate: every message names the file, the key (or
//! field) and what was expected, on one line. The underlying error (I/O, TOML, JSON, image
//! decoding), where there is one, stays reachable through `source()`.

use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The error an [`Error`] wraps; shared so that `Error` stays `Clone`.
type Source = Arc<dyn std::error::Error + Send + Sync + 'static>;

/// What went wrong, broadly.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum ErrorKind {
    /// The file could not be opened or read.
    Io,
    /// The file is not of the expected format (syntax, header, size).
    Format,
    /// A key is unknown, missing, of the wrong type, or its value out of range.
    Value,
}

/// A config or format error: `file: key: message`.
#[derive(Debug, Clone)]
pub struct Error {
    kind: ErrorKind,
    file: Option<PathBuf>,
    key: String,
    message: String,
    source: Option<Source>,
}

impl Error {
    /// An error of `kind` about `key` (may be empty) with an explanation.
    pub fn new(kind: ErrorKind, key: impl Into<String>, message: impl Into<String>) -> Self {
        Error { kind, file: None, key: key.into(), message: message.into(), source: None }
    }

    /// The same error, caused by `source`. The message stays as given: `source` is only
    /// reported through [`std::error::Error::source`].
    pub fn with_source(mut self, source: impl std::error::Error + Send + Sync + 'static) -> Self {
        self.source = Some(Arc::new(source));
        self
    }

    /// A value error about `key`.
    pub fn value(key: impl Into<String>, message: impl Into<String>) -> Self {
        Self::new(ErrorKind::Value, key, message)
    }

    /// A format error (no key).
    pub fn format(message: impl Into<String>) -> Self {
        Self::new(ErrorKind::Format, "", message)
    }

    /// An I/O error on `path`; a copy of `err` is its source.
    pub fn io(path: &Path, err: &std::io::Error) -> Self {
        let message = match err.kind() {
            std::io::ErrorKind::NotFound => "no such file".to_string(),
            _ => err.to_string(),
        };
        // io::Error is not Clone: an OS error is rebuilt from its code, any other from its
        // kind and text.
        let source = match err.raw_os_error() {
            Some(code) => std::io::Error::from_raw_os_error(code),
            None => std::io::Error::new(err.kind(), err.to_string()),
        };
        Self::new(ErrorKind::Io, "", message).in_file(path).with_source(source)
    }

    /// The same error, said of `file` (kept if a file is already named).
    pub fn in_file(mut self, file: &Path) -> Self {
        if self.file.is_none() {
            self.file = Some(file.to_path_buf());
        }
        self
    }

    /// The same error under a key prefix (`tray` + `mesh` -> `tray.mesh`).
    pub fn under_key(mut self, prefix: &str) -> Self {
        self.key = if self.key.is_empty() { prefix.to_string() } else { format!("{prefix}.{}", self.key) };
        self
    }

    /// What went wrong, broadly.
    pub fn kind(&self) -> ErrorKind {
        self.kind
    }

    /// The file the error is about, if any.
    pub fn file(&self) -> Option<&Path> {
        self.file.as_deref()
    }

    /// The key or field the error is about (may be empty).
    pub fn key(&self) -> &str {
        &self.key
    }

    /// The explanation, without file or key.
    pub fn message(&self) -> &str {
        &self.message
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(file) = &self.file {
            write!(f, "{}: ", file.display())?;
        }
        if !self.key.is_empty() {
            write!(f, "{}: ", self.key)?;
        }
        // Keep it to one line whatever the source said.
        let one_line: String = self.message.split_whitespace().collect::<Vec<_>>().join(" ");
        f.write_str(&one_line)
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        self.source.as_deref().map(|s| s as &(dyn std::error::Error + 'static))
    }
}

#[cfg(test)]
mod tests {
    use std::error::Error as _;
    use std::path::Path;

    use super::{Error, ErrorKind};

    #[test]
    fn io_error_keeps_its_message_and_source() {
        let io = std::io::Error::from(std::io::ErrorKind::NotFound);
        let e = Error::io(Path::new("cell.toml"), &io);
        assert_eq!(e.to_string(), "cell.toml: no such file");
        let source = e.source().expect("an io source");
        let source = source.downcast_ref::<std::io::Error>().expect("an io::Error");
        assert_eq!(source.kind(), std::io::ErrorKind::NotFound);
    }

    #[test]
    fn os_error_source_is_the_same_os_error() {
        let io = std::io::Error::from_raw_os_error(13);
        let e = Error::io(Path::new("rig.json"), &io);
        let source = e.source().and_then(|s| s.downcast_ref::<std::io::Error>()).expect("an io::Error");
        assert_eq!(source.raw_os_error(), Some(13));
    }

    #[test]
    fn parse_errors_keep_the_parser_error_as_source() {
        let e = crate::Cell::from_toml_str("[table", Path::new(".")).unwrap_err();
        assert!(e.source().and_then(|s| s.downcast_ref::<toml::de::Error>()).is_some());
        let e = crate::RigFile::from_json("{").unwrap_err();
        assert!(e.source().and_then(|s| s.downcast_ref::<serde_json::Error>()).is_some());
    }

    #[test]
    fn an_error_without_cause_has_no_source() {
        let e = Error::value("placement.r", "expected a positive distance in mm, got -1");
        assert!(e.source().is_none());
        assert_eq!(e.kind(), ErrorKind::Value);
    }
}
