//! The one-line range checks a cell's values go through: positive, from 0 to a bound, from
//! 0 to 1, a size, an open angle, a [min, max] pair; each error names the key.

use crate::{Error, MAX_DISTANCE_MM};

pub(crate) fn pos(key: &str, v: f64) -> Result<(), Error> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(Error::value(key, format!("expected a positive number, got {v}")))
    }
}

/// `v` from 0 to `most` (in `unit`).
pub(crate) fn at_most(key: &str, v: f64, most: f64, unit: &str) -> Result<(), Error> {
    if v.is_finite() && (0.0..=most).contains(&v) {
        Ok(())
    } else {
        let unit = if unit.is_empty() { String::new() } else { format!(" {unit}") };
        Err(Error::value(key, format!("expected 0 to {most}{unit}, got {v}")))
    }
}

pub(crate) fn unit(key: &str, v: f64) -> Result<(), Error> {
    if v.is_finite() && (0.0..=1.0).contains(&v) {
        Ok(())
    } else {
        Err(Error::value(key, format!("expected a number from 0 to 1, got {v}")))
    }
}

pub(crate) fn positive(key: &str, v: &[f64]) -> Result<(), Error> {
    if v.iter().all(|x| x.is_finite() && (MIN_SIZE_MM..=MAX_DISTANCE_MM).contains(x)) {
        Ok(())
    } else {
        Err(Error::value(key, format!("expected sizes from {MIN_SIZE_MM} to {MAX_DISTANCE_MM} mm, got {v:?}")))
    }
}

/// The smallest size of a table or an item, mm: a tenth of a millimetre is below anything
/// the sensor resolves.
const MIN_SIZE_MM: f64 = 0.1;

pub(crate) fn angle_open(key: &str, v: f64, lo: f64, hi: f64) -> Result<(), Error> {
    if v.is_finite() && v > lo && v < hi {
        Ok(())
    } else {
        Err(Error::value(key, format!("expected an angle between {lo} and {hi} degrees, got {v}")))
    }
}

pub(crate) fn range(key: &str, v: [f64; 2], lo: f64, hi: f64) -> Result<(), Error> {
    if v.iter().all(|x| x.is_finite() && *x >= lo && *x <= hi) && v[0] <= v[1] {
        Ok(())
    } else {
        Err(Error::value(key, format!("expected [min, max] with min <= max within [{lo}, {hi}], got {v:?}")))
    }
}
