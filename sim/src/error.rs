//! The simulator's error type: bad cell content found while building a scene, the
//! estimator's errors, and the errors of the files it reads and writes (a recorded
//! dataset's among them).

use std::fmt;

/// A simulator error, one line.
#[derive(Debug)]
#[non_exhaustive]
pub enum Error {
    /// A cell file, mesh or other input file is wrong.
    Config(camplace_config::Error),
    /// The estimator refused its inputs.
    Estimator(camplace_estimator::Error),
    /// An error that belongs to one input file, named before it.
    In(std::path::PathBuf, Box<Error>),
    /// The sensor at a placement sees too little of the tray to build a model from.
    TrayNotSeen(String),
    /// Anything else, said in words.
    Other(String),
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Config(e) => e.fmt(f),
            Error::Estimator(e) => e.fmt(f),
            Error::In(path, e) => write!(f, "{}: {e}", path.display()),
            Error::TrayNotSeen(s) | Error::Other(s) => f.write_str(s),
        }
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Error::Config(e) => Some(e),
            Error::Estimator(e) => Some(e),
            Error::In(_, e) => Some(e.as_ref()),
            Error::TrayNotSeen(_) | Error::Other(_) => None,
        }
    }
}

impl From<camplace_config::Error> for Error {
    fn from(e: camplace_config::Error) -> Self {
        Error::Config(e)
    }
}

impl From<camplace_plot::Error> for Error {
    fn from(e: camplace_plot::Error) -> Self {
        Error::Other(e.to_string())
    }
}

impl From<camplace_estimator::Error> for Error {
    fn from(e: camplace_estimator::Error) -> Self {
        Error::Estimator(e)
    }
}

impl Error {
    /// This error, said to belong to the file `path`.
    pub fn in_file(self, path: &std::path::Path) -> Error {
        Error::In(path.to_path_buf(), Box::new(self))
    }
}

/// The simulator's result type.
pub type Result<T> = std::result::Result<T, Error>;
