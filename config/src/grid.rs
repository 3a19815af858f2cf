//! A grid of placements as written: two axes over placement parameters (`r=400:900:5` is r
//! from 400 to 900 mm in 5 steps) and the placements they span, x fastest. A sweep's flags
//! and a trial plan's `grid` hold one.

use std::str::FromStr;

use crate::{Placement, PlacementParam};
use serde::{Deserialize, Serialize};

/// One axis of a sweep: a parameter from `lo` to `hi` in `steps` values.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Axis {
    /// One of r, alpha, baseline, vergence.
    pub name: PlacementParam,
    /// First value.
    pub lo: f64,
    /// Last value.
    pub hi: f64,
    /// Number of values (at least 1).
    pub steps: usize,
}

impl Axis {
    /// The values, evenly spaced from `lo` to `hi`.
    pub fn values(&self) -> Vec<f64> {
        if self.steps == 1 {
            return vec![self.lo];
        }
        (0..self.steps).map(|i| self.lo + (self.hi - self.lo) * i as f64 / (self.steps - 1) as f64).collect()
    }
}

/// The most values one sweep axis may take (a 100 x 100 grid is already 10 000 placements).
pub const MAX_AXIS_STEPS: usize = 100;

impl FromStr for Axis {
    type Err = String;

    /// `name=lo:hi:steps`.
    fn from_str(s: &str) -> Result<Axis, String> {
        let bad = || {
            format!("expected name=lo:hi:steps with name one of {} (e.g. r=400:900:5), got \"{s}\"", studied_names())
        };
        let (name, range) = s.split_once('=').ok_or_else(bad)?;
        let name =
            PlacementParam::from_name(name.trim()).filter(|p| PlacementParam::STUDIED.contains(p)).ok_or_else(bad)?;
        let parts: Vec<&str> = range.split(':').collect();
        let [lo, hi, steps] = parts[..] else { return Err(bad()) };
        let lo: f64 = lo.trim().parse().map_err(|_| bad())?;
        let hi: f64 = hi.trim().parse().map_err(|_| bad())?;
        let steps: usize = steps.trim().parse().map_err(|_| bad())?;
        if !(lo.is_finite() && hi.is_finite()) || steps == 0 || (steps > 1 && lo == hi) {
            return Err(bad());
        }
        if steps > MAX_AXIS_STEPS {
            return Err(format!("{steps} steps along {name}: expected 1 to {MAX_AXIS_STEPS}"));
        }
        Ok(Axis { name, lo, hi, steps })
    }
}

/// The study's parameters' names, as an error lists them.
pub fn studied_names() -> String {
    PlacementParam::STUDIED.map(PlacementParam::name).join(", ")
}

/// A two-axis grid over a base placement.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Grid {
    /// The horizontal axis.
    pub x: Axis,
    /// The vertical axis.
    pub y: Axis,
}

impl Grid {
    /// The placements, x fastest: index = iy·nx + ix. Each is checked like a user's
    /// placement, so a grid reaching alpha = 90 is an error naming the key.
    pub fn placements(&self, base: &Placement) -> Result<Vec<Placement>, crate::Error> {
        if self.x.name == self.y.name {
            return Err(crate::Error::value(
                "y",
                format!(
                    "expected a parameter other than the x axis's ({}): one parameter cannot span both axes",
                    self.x.name
                ),
            ));
        }
        let mut out = Vec::with_capacity(self.x.steps * self.y.steps);
        for y in self.y.values() {
            for x in self.x.values() {
                let p = self.x.name.set(&self.y.name.set(base, y), x);
                p.validate("placement")?;
                out.push(p);
            }
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axes_parse_and_span() {
        let a: Axis = "r=400:900:5".parse().unwrap();
        assert_eq!(a.values(), vec![400.0, 525.0, 650.0, 775.0, 900.0]);
        for bad in ["foo=1:2:3", "r=1:2", "r=1:2:0", "r=a:2:3", "r400:900:5"] {
            assert!(bad.parse::<Axis>().is_err(), "{bad}");
        }
        let g = Grid { x: a, y: "alpha=0:60:3".parse().unwrap() };
        let ps = g.placements(&crate::Cell::default().placement).unwrap();
        assert_eq!(ps.len(), 15);
        assert_eq!((ps[6].r, ps[6].alpha), (525.0, 30.0));
    }
}
