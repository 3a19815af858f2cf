//! Mounting tolerances around a placement: for each parameter (r, alpha, baseline, vergence,
//! azimuth), how far the rig may be off, in each direction, before the success rate drops
//! by more than a margin; then the success rate at the corners of that tolerance box.
//!
//! Every placement is evaluated on the same scenarios of one seed (common random numbers),
//! so a difference in success between two placements comes from the placement, not from
//! other scenes. Each offset is walked out in whole steps from the nominal placement; the
//! walk stops at the first step whose success falls more than the margin below the
//! nominal's, at the end of the parameter's valid range, or after the last step. As in
//! every other command, a placement's scenes run with the model built at that placement
//! and the rig's true calibration: the rig as installed and commissioned. A toe-in given
//! as "auto" is fixed to its degrees first (to a thousandth of a degree), so moving the
//! rig does not turn the cameras.

use std::path::Path;

use camplace_config::{write_atomic, Cell, Placement};
use serde::{Deserialize, Serialize};

use super::summary::Summary;
use super::tray_set::{lowest, TraySet};
use crate::render::Method;
use crate::{Error, Result};

/// The parameters a bracket can get wrong, with the step each is walked out in and its unit.
pub const TOLERANCE_STEPS: [(&str, f64, &str); 5] = [
    ("r", 10.0, "mm"),
    ("alpha", 2.0, "deg"),
    ("baseline", 5.0, "mm"),
    ("vergence", 0.5, "deg"),
    ("azimuth", 5.0, "deg"),
];

/// What to measure.
#[derive(Debug, Clone, PartialEq)]
pub struct ToleranceRequest {
    /// The nominal placement.
    pub placement: Placement,
    /// Sensor method.
    pub method: Method,
    /// Seed of the scenarios.
    pub seed: u64,
    /// Scenarios `0..scenarios` at every placement.
    pub scenarios: u64,
    /// Largest drop of the success rate that is still within tolerance (0.02: 2 points).
    pub margin: f64,
    /// Steps walked out at most in each direction.
    pub max_steps: u32,
    /// The parameters to walk, as indices into [`TOLERANCE_STEPS`]; the others stay at
    /// their nominal values (also at the corners).
    pub parameters: Vec<usize>,
}

/// One evaluated offset of one parameter.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TolerancePoint {
    /// Offset from the nominal value, mm or deg.
    pub offset: f64,
    /// Success rate there.
    pub success_rate: f64,
    /// Its Wilson 95 % interval.
    pub success_interval: [f64; 2],
}

/// Why a walk in one direction stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum WalkEnd {
    /// The next step dropped the success by more than the margin.
    Drop,
    /// The next step left the parameter's valid range.
    RangeEnd,
    /// Every step stayed within the margin.
    LastStep,
}

/// One parameter's tolerance.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AxisTolerance {
    /// The parameter's name.
    pub parameter: String,
    /// mm or deg.
    pub unit: String,
    /// The step it was walked out in.
    pub step: f64,
    /// How far below the nominal value it may be (0 or more).
    pub minus: f64,
    /// Why the walk downwards stopped.
    pub minus_end: WalkEnd,
    /// How far above the nominal value it may be.
    pub plus: f64,
    /// Why the walk upwards stopped.
    pub plus_end: WalkEnd,
    /// Every evaluated offset, ascending, the nominal (0) included.
    pub points: Vec<TolerancePoint>,
}

/// One corner of the tolerance box.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ToleranceCorner {
    /// The placement there.
    pub placement: String,
    /// Each parameter's offset, in [`TOLERANCE_STEPS`] order.
    pub offsets: [f64; 5],
    /// Success rate there.
    pub success_rate: f64,
    /// Its Wilson 95 % interval.
    pub success_interval: [f64; 2],
}

/// The whole measurement (`tolerance.json`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ToleranceReport {
    /// The nominal placement (toe-in in degrees).
    pub placement: String,
    /// Sensor method.
    pub method: String,
    /// Seed of the scenarios.
    pub seed: u64,
    /// Scenarios per placement.
    pub scenarios: u64,
    /// The margin.
    pub margin: f64,
    /// Success at the nominal placement.
    pub nominal: TolerancePoint,
    /// Each walked parameter's tolerance, in [`TOLERANCE_STEPS`] order.
    pub axes: Vec<AxisTolerance>,
    /// The distinct corners of the tolerance box.
    pub corners: Vec<ToleranceCorner>,
}

impl ToleranceReport {
    /// The corner with the lowest success rate (the first of equals), if any.
    pub fn worst_corner(&self) -> Option<&ToleranceCorner> {
        self.corners.iter().fold(None, |worst: Option<&ToleranceCorner>, c| match worst {
            Some(w) if w.success_rate <= c.success_rate => Some(w),
            _ => Some(c),
        })
    }

    /// A table for a terminal: one row per parameter, then the worst corner.
    pub fn table(&self) -> String {
        let mut text = format!(
            "tolerance of {} ({}, seed {}, {} scenarios; nominal success {}; margin {:.1} points)\n",
            self.placement,
            self.method,
            self.seed,
            self.scenarios,
            pct(self.nominal.success_rate),
            100.0 * self.margin
        );
        text.push_str(&format!("  {:<9} {:>10} {:>10}  {}\n", "parameter", "minus", "plus", "walk ended by"));
        for a in &self.axes {
            text.push_str(&format!(
                "  {:<9} {:>7} {:<3}{:>7} {:<3} {} / {}\n",
                a.parameter,
                a.minus,
                a.unit,
                a.plus,
                a.unit,
                end_text(a.minus_end),
                end_text(a.plus_end)
            ));
        }
        if self.nominal.success_rate <= self.margin {
            text.push_str("  note: the nominal placement itself succeeds on (almost) no scene, so no offset can lose much; measure around a placement that works\n");
        }
        if let Some(w) = self.worst_corner() {
            text.push_str(&format!(
                "  worst of {} corners: {} at {} (95 % interval {}–{})",
                self.corners.len(),
                pct(w.success_rate),
                w.placement,
                pct(w.success_interval[0]),
                pct(w.success_interval[1])
            ));
        }
        text
    }
}

fn pct(r: f64) -> String {
    format!("{:.1} %", 100.0 * r)
}

/// How a walk ended, in words.
pub fn end_text(end: WalkEnd) -> &'static str {
    match end {
        WalkEnd::Drop => "drop",
        WalkEnd::RangeEnd => "range end",
        WalkEnd::LastStep => "last step",
    }
}

/// The outcome of walking one parameter out in one direction.
#[derive(Debug, Clone, PartialEq)]
struct Walk {
    /// The largest offset (absolute) still within the margin.
    tolerance: f64,
    end: WalkEnd,
    /// (offset, success) of every step evaluated, in walking order.
    points: Vec<(f64, Summary)>,
}

/// Walks from 0 in steps of `step` (signed) up to `max_steps`: `at(offset)` is the
/// placement there (`None` past the valid range), `success` evaluates it. Stops at the first
/// step whose success is more than `margin` below `nominal`.
fn walk<P>(
    step: f64,
    max_steps: u32,
    nominal: f64,
    margin: f64,
    at: impl Fn(f64) -> Option<P>,
    mut success: impl FnMut(P) -> Result<Summary>,
) -> Result<Walk> {
    let mut out = Walk { tolerance: 0.0, end: WalkEnd::LastStep, points: Vec::new() };
    for k in 1..=max_steps {
        let offset = step * f64::from(k);
        let Some(place) = at(offset) else {
            out.end = WalkEnd::RangeEnd;
            return Ok(out);
        };
        let summary = success(place)?;
        let rate = summary.success_rate;
        out.points.push((offset, summary));
        // A small tolerance keeps a rate exactly at the margin (in whole scenes) inside it.
        if rate < nominal - margin - 1e-12 {
            out.end = WalkEnd::Drop;
            return Ok(out);
        }
        out.tolerance = offset.abs();
    }
    Ok(out)
}

/// The placement `offsets` (in [`TOLERANCE_STEPS`] order) away from `nominal`, if valid.
/// Values are rounded to a millionth of a mm or degree, so a placement prints as written.
fn offset_placement(nominal: &Placement, offsets: &[f64; 5]) -> Option<Placement> {
    let mut p = *nominal;
    for ((name, _, _), &d) in TOLERANCE_STEPS.iter().zip(offsets) {
        p = p.set(name, round6(nominal.get(name)? + d))?;
    }
    p.validate("").ok().map(|_| p)
}

fn round6(v: f64) -> f64 {
    (v * 1e6).round() / 1e6
}

fn point(offset: f64, s: &Summary) -> TolerancePoint {
    TolerancePoint { offset, success_rate: s.success_rate, success_interval: s.success_interval }
}

/// Measures the tolerances of `request` for one placement serving every tray of `trays`
/// (`(name, cell)`; a placement's success is its lowest over the trays; results appended
/// as scenes finish to the study folder `dir`, or with several trays to `dir/NAME`, so a stopped run resumes), writes `tolerance.json` into `dir`
/// and returns it.
pub fn measure_tolerance(
    dir: &Path,
    trays: Vec<(String, Cell)>,
    request: &ToleranceRequest,
) -> Result<ToleranceReport> {
    let r = request;
    if !(r.margin.is_finite() && r.margin > 0.0 && r.margin < 1.0) {
        return Err(Error::Other(format!(
            "--margin: expected a share of scenes between 0 and 1 (0.02 is 2 points), got {}",
            r.margin
        )));
    }
    // To a thousandth of a degree, so placements print short.
    let verged = (r.placement.vergence.degrees(r.placement.r, r.placement.baseline) * 1e3).round() / 1e3;
    let nominal = r
        .placement
        .set("vergence", verged)
        .filter(|p| p.validate("").is_ok())
        .ok_or_else(|| Error::Other(format!("--placement: {} is not a valid placement", r.placement)))?;
    // One tray's scenes in `dir` itself; several trays' each in `dir/NAME`.
    let one = trays.len() == 1;
    let folders = trays
        .into_iter()
        .map(|(name, cell)| {
            let folder = if one { dir.to_path_buf() } else { dir.join(&name) };
            (name, cell, folder)
        })
        .collect();
    let set = TraySet::open(folders, r.method, r.seed)?;
    let evaluate =
        |p: &Placement| -> Result<Summary> { Ok(lowest(&set.evaluate(p, r.seed, r.scenarios, "tolerance")?)) };

    let base = evaluate(&nominal)?;
    let mut axes = Vec::new();
    for &i in &r.parameters {
        let Some(&(name, step, unit)) = TOLERANCE_STEPS.get(i) else {
            return Err(Error::Other(format!("tolerance: no parameter number {i}")));
        };
        let along = |offset: f64| {
            let mut offsets = [0.0; 5];
            offsets[i] = offset;
            offset_placement(&nominal, &offsets)
        };
        let mut ends = [(0.0, WalkEnd::LastStep); 2];
        let mut points = vec![point(0.0, &base)];
        for (side, sign) in [-1.0, 1.0].into_iter().enumerate() {
            let w = walk(sign * step, r.max_steps, base.success_rate, r.margin, along, |p| evaluate(&p))?;
            points.extend(w.points.iter().map(|(o, s)| point(*o, s)));
            ends[side] = (w.tolerance, w.end);
        }
        points.sort_by(|a, b| a.offset.total_cmp(&b.offset));
        axes.push(AxisTolerance {
            parameter: name.to_string(),
            unit: unit.to_string(),
            step,
            minus: ends[0].0,
            minus_end: ends[0].1,
            plus: ends[1].0,
            plus_end: ends[1].1,
            points,
        });
    }

    let mut corners: Vec<ToleranceCorner> = Vec::new();
    for mask in 0..(1u32 << axes.len()) {
        let mut offsets = [0.0; 5];
        for (bit, (axis, &i)) in axes.iter().zip(&r.parameters).enumerate() {
            offsets[i] = if mask & (1 << bit) == 0 { -axis.minus } else { axis.plus };
        }
        if corners.iter().any(|c| c.offsets == offsets) {
            continue; // a parameter with no tolerance on one side folds corners together
        }
        let Some(p) = offset_placement(&nominal, &offsets) else { continue };
        let s = evaluate(&p)?;
        corners.push(ToleranceCorner {
            placement: p.to_string(),
            offsets,
            success_rate: s.success_rate,
            success_interval: s.success_interval,
        });
    }

    let report = ToleranceReport {
        placement: nominal.to_string(),
        method: r.method.to_string(),
        seed: r.seed,
        scenarios: r.scenarios,
        margin: r.margin,
        nominal: point(0.0, &base),
        axes,
        corners,
    };
    let json = serde_json::to_string_pretty(&report).map_err(|e| Error::Other(format!("tolerance.json: {e}")))?;
    write_atomic(&dir.join("tolerance.json"), json.as_bytes())?;
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A summary of `n` scored frames with `k` successes.
    fn rate(k: usize, n: usize) -> Summary {
        let mut s = Summary::from_records(&[]);
        s.scored = n;
        s.successes = k;
        s.success_rate = k as f64 / n as f64;
        s
    }

    /// The tolerance by its definition: the largest |offset| on the grid such that every
    /// step up to it (and it) stays within the margin, with nothing invalid before it.
    fn slow_tolerance(step: f64, max_steps: u32, nominal: f64, margin: f64, f: &dyn Fn(f64) -> Option<f64>) -> f64 {
        let mut best = 0.0;
        for k in 1..=max_steps {
            let ok = (1..=k).all(|j| f(step * f64::from(j)).is_some_and(|s| s >= nominal - margin - 1e-12));
            if ok {
                best = (step * f64::from(k)).abs();
            }
        }
        best
    }

    #[test]
    fn walks_match_the_definition_on_many_shapes() {
        // Success profiles in whole scenes of 50: peaks, plateaus, dips, cliffs and range ends.
        let n = 50usize;
        for shape in 0..40u32 {
            let width = 1.0 + f64::from(shape % 7) * 3.0;
            let dip_at = f64::from(shape % 5) * 2.0;
            let limit = if shape % 3 == 0 { 9.0 } else { 1e9 };
            let f = move |x: f64| -> Option<f64> {
                if x.abs() > limit {
                    return None;
                }
                let mut s = (1.0 - (x / width).powi(2) * 0.1).clamp(0.0, 1.0);
                if dip_at > 0.0 && (x.abs() - dip_at).abs() < 0.5 {
                    s -= 0.05;
                }
                Some((s * n as f64).round() / n as f64)
            };
            for step in [-1.0, 1.0, -2.5, 2.5] {
                let nominal = f(0.0).unwrap();
                let margin = 0.02 * f64::from(1 + shape % 3);
                let w = walk(step, 8, nominal, margin, f, |s| Ok(rate((s * n as f64).round() as usize, n))).unwrap();
                let slow = slow_tolerance(step, 8, nominal, margin, &f);
                assert_eq!(w.tolerance, slow, "shape {shape} step {step}");
                // Each step evaluated once, in order, and nothing after the one that ended it.
                let offsets: Vec<f64> = w.points.iter().map(|p| p.0).collect();
                let expected: Vec<f64> = (1..=offsets.len() as u32).map(|k| step * f64::from(k)).collect();
                assert_eq!(offsets, expected, "shape {shape} step {step}");
                match w.end {
                    WalkEnd::Drop => {
                        assert!(w.points.last().unwrap().1.success_rate < nominal - margin, "shape {shape}")
                    }
                    WalkEnd::RangeEnd => assert!(f(step * (offsets.len() + 1) as f64).is_none(), "shape {shape}"),
                    WalkEnd::LastStep => assert_eq!(offsets.len(), 8, "shape {shape}"),
                }
            }
        }
    }

    #[test]
    fn offsets_keep_the_toe_in_and_refuse_invalid_placements() {
        let nominal = Placement {
            r: 605.0,
            alpha: 32.0,
            baseline: 81.0,
            vergence: camplace_config::Vergence::Degrees(3.5),
            azimuth: 0.0,
        };
        let p = offset_placement(&nominal, &[10.0, -2.0, 5.0, 0.5, -5.0]).unwrap();
        assert_eq!((p.r, p.alpha, p.baseline, p.azimuth), (615.0, 30.0, 86.0, -5.0));
        assert_eq!(p.vergence, camplace_config::Vergence::Degrees(4.0));
        assert!(offset_placement(&nominal, &[0.0, 60.0, 0.0, 0.0, 0.0]).is_none(), "alpha 92 is no placement");
        assert!(offset_placement(&nominal, &[0.0, 0.0, -81.0, 0.0, 0.0]).is_none(), "baseline 0 is no placement");
    }

    #[test]
    fn the_worst_corner_is_the_lowest() {
        let corner = |rate: f64| ToleranceCorner {
            placement: format!("{rate}"),
            offsets: [rate; 5],
            success_rate: rate,
            success_interval: [0.0, 1.0],
        };
        let report = ToleranceReport {
            placement: String::new(),
            method: String::new(),
            seed: 0,
            scenarios: 1,
            margin: 0.02,
            nominal: TolerancePoint { offset: 0.0, success_rate: 1.0, success_interval: [0.0, 1.0] },
            axes: Vec::new(),
            corners: vec![corner(0.9), corner(0.7), corner(0.8), corner(0.7)],
        };
        assert_eq!(report.worst_corner().unwrap().success_rate, 0.7);
        assert!(report.table().contains("worst of 4 corners: 70.0 %"), "{}", report.table());
    }
}
