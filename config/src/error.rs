//! The one error type of the config crate: every message names the file, the key (or
//! field) and what was expected, on one line.

use std::fmt;
use std::path::{Path, PathBuf};

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
}

impl Error {
    /// An error of `kind` about `key` (may be empty) with an explanation.
    pub fn new(kind: ErrorKind, key: impl Into<String>, message: impl Into<String>) -> Self {
        Error { kind, file: None, key: key.into(), message: message.into() }
    }

    /// A value error about `key`.
    pub fn value(key: impl Into<String>, message: impl Into<String>) -> Self {
        Self::new(ErrorKind::Value, key, message)
    }

    /// A format error (no key).
    pub fn format(message: impl Into<String>) -> Self {
        Self::new(ErrorKind::Format, "", message)
    }

    /// An I/O error on `path`.
    pub fn io(path: &Path, err: &std::io::Error) -> Self {
        let message = match err.kind() {
            std::io::ErrorKind::NotFound => "no such file".to_string(),
            _ => err.to_string(),
        };
        Self::new(ErrorKind::Io, "", message).in_file(path)
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

impl std::error::Error for Error {}
