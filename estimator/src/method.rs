//! How the sensor captures depth: one random-dot shot matched by stereo, or twelve
//! phase-shift fringe shots decoded per pixel.

use std::fmt;
use std::str::FromStr;

use crate::{Error, ErrorKind};

/// The sensor's capture method.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Method {
    /// One random-dot image per camera, matched by the ELAS-class stereo matcher.
    OneShot,
    /// Twelve phase-shift fringe images per camera (3 frequencies x 4 steps by default).
    Phase12,
}

impl Method {
    /// Images per camera for this method with `fringe_periods` frequencies.
    pub fn shots(self, fringe_periods: usize) -> usize {
        match self {
            Method::OneShot => 1,
            Method::Phase12 => 4 * fringe_periods,
        }
    }
}

/// The method a source of `shots` images per side was captured with.
pub fn method_for(shots: usize) -> Method {
    if shots == 1 {
        Method::OneShot
    } else {
        Method::Phase12
    }
}

impl fmt::Display for Method {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Method::OneShot => "one-shot",
            Method::Phase12 => "phase-12",
        })
    }
}

impl FromStr for Method {
    type Err = Error;

    fn from_str(s: &str) -> Result<Method, Error> {
        match s {
            "one-shot" => Ok(Method::OneShot),
            "phase-12" => Ok(Method::Phase12),
            _ => Err(Error::new(
                ErrorKind::Input,
                format!("unknown method \"{s}\", expected \"one-shot\" or \"phase-12\""),
            )),
        }
    }
}
