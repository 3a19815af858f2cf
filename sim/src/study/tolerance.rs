//! Mounting tolerances around a placement: for each parameter (r, alpha, baseline, vergence,
//! azimuth), how far the rig may be off, in each direction, before its success is shown to
//! drop; then the success at the corners of that tolerance box.
//!
//! Every placement is evaluated on the same scenarios of one seed (common random numbers)
//! and compared with the nominal scene by scene: a point is outside the tolerance when the
//! one-sided exact McNemar test on the scenes only one of the two succeeded on shows its
//! success lower at the 5 % level ([`TOLERANCE_LEVEL`]). The scene count is chosen for a
//! margin: a point that truly loses that share of the scenes is put outside with the
//! stated power. Each side is judged at the parameter's range end first, then, when that
//! is outside, walked out in growing steps and bisected to the parameter's resolution
//! ([`super::tolerance_walk`]). As in every
//! other command, a placement's scenes run with the model built at that placement and the
//! rig's true calibration: the rig as installed and commissioned. A toe-in given as "auto"
//! is fixed to its degrees first (to a thousandth of a degree), so moving the rig does not
//! turn the cameras.

use std::path::Path;

use camplace_config::{write_atomic, Cell, Placement, PlacementParam};

use super::findings::{drop_detection_power, Paired};
use super::tolerance_walk::{range_end, walk_to_edge};
use super::tray_set::{lowest, TraySet};
use crate::render::Method;
use crate::{Error, Result};
use camplace_config::{AxisTolerance, ToleranceCorner, TolerancePoint, ToleranceReport};
use camplace_estimator::scoring::Summary;

/// A parameter a bracket can get wrong, and how its tolerance is walked.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ToleranceParameter {
    /// The placement's parameter (its name and unit).
    pub param: PlacementParam,
    /// The resolution the edge is found to; every offset is a whole number of it.
    pub resolution: f64,
    /// The first step out, in resolutions; each further step doubles.
    pub first_steps: u64,
    /// The furthest offset walked on either side: more than a bracket is ever off by (the
    /// placement's own range may end first). A side still inside there is reported as "at
    /// least" this far.
    pub walk_limit: f64,
}

/// The parameters, in the order of [`PlacementParam::ALL`] (every offset array's, and
/// [`tolerance_parameter`] finds one by its index there): r and baseline to 5 mm, alpha and
/// azimuth to 1°, vergence to 0.25°. Each is walked at most ±400 mm (r), ±30° (alpha),
/// ±60 mm (baseline), ±6° (vergence, each camera's toe-in) or ±30° (azimuth): a rig
/// mounted further off than that is plainly wrong, not within a tolerance. The first step
/// is about an eighth of that range (40 mm, 4°, 10 mm, 0.75°, 4°) and is taken only when
/// the range's end is outside (a side inside there costs that one point), so the bisection
/// starts from the first doubling that dropped: beyond an edge success is noisy (a point a little further may lose fewer
/// scenes than one at the edge), and a wider first bracket can land on a further edge.
pub const TOLERANCE_PARAMETERS: [ToleranceParameter; 5] = [
    ToleranceParameter { param: PlacementParam::R, resolution: 5.0, first_steps: 8, walk_limit: 400.0 },
    ToleranceParameter { param: PlacementParam::Alpha, resolution: 1.0, first_steps: 4, walk_limit: 30.0 },
    ToleranceParameter { param: PlacementParam::Baseline, resolution: 5.0, first_steps: 2, walk_limit: 60.0 },
    ToleranceParameter { param: PlacementParam::Vergence, resolution: 0.25, first_steps: 3, walk_limit: 6.0 },
    ToleranceParameter { param: PlacementParam::Azimuth, resolution: 1.0, first_steps: 4, walk_limit: 30.0 },
];

/// The level of the one-sided paired test that puts a point outside.
pub const TOLERANCE_LEVEL: f64 = 0.05;

/// The power the default scene counts give for a drop of the margin.
pub const TOLERANCE_POWER: f64 = 0.8;

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
    /// The drop of success the scene count is to detect (0.1: 10 points); only stated,
    /// with its power, since the paired test decides.
    pub margin: f64,
    /// The share of each found tolerance the corners are placed at (1: at the edges).
    pub corner_fraction: f64,
    /// The parameters to walk, each once; the others stay at their nominal values (also
    /// at the corners). They are walked, and written, in the order of [`PlacementParam::ALL`].
    pub parameters: Vec<PlacementParam>,
}

/// How `param`'s tolerance is walked.
pub fn tolerance_parameter(param: PlacementParam) -> &'static ToleranceParameter {
    &TOLERANCE_PARAMETERS[param.index()]
}

/// The placement `offsets` (in [`PlacementParam::ALL`] order) away from `nominal`, if valid.
/// Values are rounded to a millionth of a mm or degree, so a placement prints as written.
fn offset_placement(nominal: &Placement, offsets: &[f64; 5]) -> Option<Placement> {
    let mut p = *nominal;
    for (param, &d) in PlacementParam::ALL.into_iter().zip(offsets) {
        p = param.set(&p, round6(param.get(nominal) + d));
    }
    p.validate("").ok().map(|_| p)
}

fn round6(v: f64) -> f64 {
    (v * 1e6).round() / 1e6
}

/// Scenes a point runs at a time before it is asked whether its verdict is settled.
pub const TOLERANCE_PART: usize = 6;

/// Whether the outcomes of a point's first scenes (`prefix`, paired with the same scenes of
/// `nominal`) already settle the verdict over all of `nominal`'s scenes: outside even if
/// every scene left the nominal failed were gained, or inside even if every scene left it
/// succeeded were lost. The verdict over the prefix is then the verdict over them all.
pub fn verdict_settled(prefix: &[Option<bool>], nominal: &[Option<bool>]) -> bool {
    let m = prefix.len().min(nominal.len());
    let p = Paired::from_outcomes(&prefix[..m], &nominal[..m]);
    let rest = &nominal[m..];
    let could_lose = rest.iter().filter(|o| **o == Some(true)).count();
    let could_gain = rest.iter().filter(|o| **o == Some(false)).count();
    let surely_outside = Paired { only_a: p.only_a + could_gain, ..p }.mcnemar_p_a_lower() < TOLERANCE_LEVEL;
    let surely_inside = Paired { only_b: p.only_b + could_lose, ..p }.mcnemar_p_a_lower() >= TOLERANCE_LEVEL;
    surely_outside || surely_inside
}

/// Whether `e` says the estimator cannot run at a placement (its cameras share no view of
/// the work volume, see no tray to model, or reconstruct no background), rather than that
/// a file or the cell is wrong: every error the estimator raises on simulated captures.
fn rig_unusable(e: &Error) -> bool {
    match e {
        Error::Estimator(_) => true,
        Error::TrayNotSeen(_) => true,
        Error::In(_, inner) => rig_unusable(inner),
        _ => false,
    }
}

/// Judges placements against the nominal on the same scenes.
struct Judge<'a> {
    set: &'a TraySet,
    seed: u64,
    scenarios: u64,
    /// The nominal's outcomes, per tray, by scenario.
    nominal: Vec<Vec<Option<bool>>>,
}

impl Judge<'_> {
    /// Evaluates `p` tray by tray, each [`TOLERANCE_PART`] scenes at a time in scenario
    /// order until its verdict is settled (running only the scenes its folder lacks), and
    /// pairs it with the nominal: the point at `offset` over the scenes that settled it, and
    /// whether it is inside. A tray that shows a drop settles the point outside and the
    /// trays after it are not run.
    fn point(&self, p: &Placement, offset: f64) -> Result<(TolerancePoint, bool)> {
        self.point_over(p, offset, self.scenarios, true)
    }

    /// [`Judge::point`] over the first `n` scenes (fewer than the nominal's) without
    /// stopping early: a corner's screening.
    fn screen(&self, p: &Placement, n: u64) -> Result<TolerancePoint> {
        Ok(self.point_over(p, 0.0, n, false)?.0)
    }

    /// [`Judge::point`] over at most `n` scenes, stopped once settled when `settle`.
    fn point_over(&self, p: &Placement, offset: f64, n: u64, settle: bool) -> Result<(TolerancePoint, bool)> {
        let mut summaries = Vec::new();
        let mut worst: Option<(f64, Paired)> = None;
        for (t, nominal) in self.nominal.iter().enumerate() {
            let run = self.set.evaluate_until(t, p, self.seed, n, TOLERANCE_PART, "tolerance", |m| {
                settle && verdict_settled(&self.set.outcomes(t, p, self.seed, m as u64), nominal)
            });
            let (paired, summary) = match run {
                Ok(m) => {
                    let outcomes = self.set.outcomes(t, p, self.seed, m as u64);
                    let paired = Paired::from_outcomes(&outcomes, &nominal[..m.min(nominal.len())]);
                    (paired, self.set.summary(t, p, self.seed, m as u64))
                }
                // Cameras that see no common part of the work volume, or no tray to model:
                // the estimator cannot run there, so every scene fails.
                Err(e) if rig_unusable(&e) => {
                    let nominal = &nominal[..(n as usize).min(nominal.len())];
                    let failed: Vec<Option<bool>> = nominal.iter().map(|o| o.map(|_| false)).collect();
                    let mut summary = Summary::from_records(&[]);
                    summary.scored = failed.iter().flatten().count();
                    summary.success_interval = camplace_estimator::scoring::wilson_interval(0, summary.scored);
                    (Paired::from_outcomes(&failed, nominal), summary)
                }
                Err(e) => return Err(e),
            };
            let p_lower = paired.mcnemar_p_a_lower();
            summaries.push(summary);
            if worst.is_none_or(|(w, _)| p_lower < w) {
                worst = Some((p_lower, paired));
            }
            if p_lower < TOLERANCE_LEVEL {
                break;
            }
        }
        let (p_lower, paired) = worst.unwrap_or((1.0, Paired::default()));
        let low: Summary = lowest(&summaries);
        let point = TolerancePoint {
            offset,
            success_rate: low.success_rate,
            success_interval: low.success_interval,
            scenes: low.scored,
            lost: paired.only_b,
            gained: paired.only_a,
            p_lower,
        };
        Ok((point, p_lower >= TOLERANCE_LEVEL))
    }
}

/// Measures the tolerances of `request` for one placement serving every tray of `trays`
/// (`(name, cell)`; a placement's success is its lowest over the trays, and it is outside
/// when any tray's paired test shows a drop; results appended as scenes finish to the
/// study folder `dir`, or with several trays to `dir/NAME`, so a stopped run resumes and
/// a placement met again is not run again), writes `tolerance.json` into `dir` and
/// returns it.
pub fn measure_tolerance(
    dir: &Path,
    trays: Vec<(String, Cell)>,
    request: &ToleranceRequest,
) -> Result<ToleranceReport> {
    let r = request;
    if !(r.margin.is_finite() && r.margin > 0.0 && r.margin < 1.0) {
        return Err(Error::Other(format!(
            "--margin: expected a share of scenes between 0 and 1 (0.1 is 10 points), got {}",
            r.margin
        )));
    }
    if !(r.corner_fraction.is_finite() && r.corner_fraction > 0.0 && r.corner_fraction <= 1.0) {
        return Err(Error::Other(format!(
            "--corner-fraction: expected a share of each tolerance above 0 and at most 1, got {}",
            r.corner_fraction
        )));
    }
    // To a thousandth of a degree, so placements print short.
    let verged = (r.placement.vergence.degrees(r.placement.r, r.placement.baseline) * 1e3).round() / 1e3;
    let nominal = Some(PlacementParam::Vergence.set(&r.placement, verged))
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
    let base = lowest(&set.evaluate(&nominal, r.seed, r.scenarios, "tolerance")?);
    let judge = Judge {
        set: &set,
        seed: r.seed,
        scenarios: r.scenarios,
        nominal: (0..set.trays.len()).map(|t| set.outcomes(t, &nominal, r.seed, r.scenarios)).collect(),
    };
    let nominal_point = TolerancePoint {
        offset: 0.0,
        success_rate: base.success_rate,
        success_interval: base.success_interval,
        scenes: base.scored,
        lost: 0,
        gained: 0,
        p_lower: 1.0,
    };

    let mut walked = r.parameters.clone();
    walked.sort_unstable();
    if walked.is_empty() || walked.windows(2).any(|w| w[0] == w[1]) {
        return Err(Error::Other(format!(
            "tolerance: expected each parameter to walk once, at least one, got [{}]",
            r.parameters.iter().map(|p| p.name()).collect::<Vec<_>>().join(", ")
        )));
    }
    let mut axes = Vec::new();
    for &walked_param in &walked {
        let param = tolerance_parameter(walked_param);
        let i = walked_param.index();
        let along = |offset: f64| {
            let mut offsets = [0.0; 5];
            offsets[i] = offset;
            offset_placement(&nominal, &offsets)
        };
        let mut points = vec![nominal_point.clone()];
        let mut sides = Vec::new();
        for sign in [-1.0, 1.0] {
            // + 0.0 writes the nominal as 0, not -0.
            let offset = |k: u64| sign * round6(k as f64 * param.resolution) + 0.0;
            let cap = (param.walk_limit / param.resolution).floor() as u64;
            let range = range_end(cap, |k| along(offset(k)).is_some());
            let walk = walk_to_edge(param.first_steps, range, |k| {
                let p = along(offset(k)).ok_or_else(|| {
                    Error::Other(format!("tolerance: {} {:+} is outside its range", param.param, offset(k)))
                })?;
                let (point, inside) = judge.point(&p, offset(k))?;
                points.push(point);
                Ok(inside)
            })?;
            let find = |k: u64| points.iter().find(|p| p.offset == offset(k)).cloned();
            let inside = if walk.inside == 0 { nominal_point.clone() } else { find(walk.inside).expect("judged") };
            let outside = walk.outside.map(|k| find(k).expect("judged"));
            sides.push((offset(walk.inside).abs(), walk.end, inside, outside, offset(range)));
        }
        points.sort_by(|a, b| a.offset.total_cmp(&b.offset));
        let [(minus, minus_end, minus_inside, minus_outside, minus_range), (plus, plus_end, plus_inside, plus_outside, plus_range)] =
            <[_; 2]>::try_from(sides).expect("two sides");
        axes.push(AxisTolerance {
            parameter: param.param.name().to_string(),
            unit: param.param.unit().to_string(),
            resolution: param.resolution,
            limit: param.walk_limit,
            minus,
            minus_end,
            minus_inside,
            minus_outside,
            minus_range,
            plus,
            plus_end,
            plus_inside,
            plus_outside,
            plus_range,
            points,
        });
    }

    let mut boxed: Vec<([f64; 5], Placement)> = Vec::new();
    for mask in 0..(1u32 << axes.len()) {
        let mut offsets = [0.0; 5];
        for (bit, (axis, &param)) in axes.iter().zip(&walked).enumerate() {
            let (i, res) = (param.index(), tolerance_parameter(param).resolution);
            // A share of the tolerance, down to the resolution's grid.
            let share = |t: f64| round6((r.corner_fraction * t / res + 1e-9).floor() * res);
            offsets[i] = if mask & (1 << bit) == 0 { -share(axis.minus) } else { share(axis.plus) };
        }
        if boxed.iter().any(|(o, _)| *o == offsets) {
            continue; // a parameter with no tolerance on one side folds corners together
        }
        let Some(p) = offset_placement(&nominal, &offsets) else { continue };
        boxed.push((offsets, p));
    }
    let screen = (boxed.len() > CORNER_FINALISTS && judge.scenarios > CORNER_SCREEN).then_some(CORNER_SCREEN);
    let corners =
        judge_corners(&boxed, screen, |p, n| judge.screen(p, n), |p| judge.point(p, 0.0).map(|(point, _)| point))?;

    let report = ToleranceReport {
        placement: nominal.to_string(),
        method: r.method.to_string(),
        seed: r.seed,
        scenarios: r.scenarios,
        margin: r.margin,
        level: TOLERANCE_LEVEL,
        power: drop_detection_power(r.scenarios as usize, r.margin, TOLERANCE_LEVEL),
        nominal: nominal_point,
        axes,
        corner_fraction: r.corner_fraction,
        corner_screen: screen.unwrap_or(0),
        corners,
    };
    let json = serde_json::to_string_pretty(&report).map_err(|e| Error::Other(format!("tolerance.json: {e}")))?;
    write_atomic(&dir.join("tolerance.json"), json.as_bytes())?;
    Ok(report)
}

/// Scenes every corner is screened on when the box has more than [`CORNER_FINALISTS`]
/// corners: two parts.
pub const CORNER_SCREEN: u64 = 2 * TOLERANCE_PART as u64;

/// Corners run on to their verdict after the screening: the lowest screened.
pub const CORNER_FINALISTS: usize = 4;

/// Success at each corner of the box. With `screen`, every corner is screened on its first
/// `screen` scenes (`screened`), then the [`CORNER_FINALISTS`] lowest (the earlier on ties)
/// run on, as a walk's point does, until their verdict is settled (`settled`), so the worst
/// corner is one of them; without, every corner runs to its verdict.
fn judge_corners(
    boxed: &[([f64; 5], Placement)],
    screen: Option<u64>,
    mut screened: impl FnMut(&Placement, u64) -> Result<TolerancePoint>,
    mut settled: impl FnMut(&Placement) -> Result<TolerancePoint>,
) -> Result<Vec<ToleranceCorner>> {
    let mut corners = Vec::with_capacity(boxed.len());
    for (offsets, p) in boxed {
        let point = match screen {
            Some(n) => screened(p, n)?,
            None => settled(p)?,
        };
        corners.push(ToleranceCorner { placement: p.to_string(), offsets: *offsets, point });
    }
    if screen.is_some() {
        for k in lowest_corners(&corners, CORNER_FINALISTS) {
            corners[k].point = settled(&boxed[k].1)?;
        }
    }
    Ok(corners)
}

/// The indices of the `n` corners of lowest success, the earlier on ties.
fn lowest_corners(corners: &[ToleranceCorner], n: usize) -> Vec<usize> {
    let mut order: Vec<usize> = (0..corners.len()).collect();
    order.sort_by(|&a, &b| corners[a].point.success_rate.total_cmp(&corners[b].point.success_rate).then(a.cmp(&b)));
    order.truncate(n);
    order
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_corner_is_screened_and_the_lowest_run_on_to_their_verdict() {
        let nominal = Placement {
            r: 600.0,
            alpha: 30.0,
            baseline: 100.0,
            vergence: camplace_config::Vergence::Degrees(5.0),
            azimuth: 0.0,
        };
        // Ten corners whose screened success is known; the run-on success differs from it.
        let screened_rate = [0.9, 0.5, 0.8, 0.5, 1.0, 0.6, 0.7, 0.95, 0.4, 0.85];
        let boxed: Vec<([f64; 5], Placement)> = (0..10)
            .map(|k| ([k as f64, 0.0, 0.0, 0.0, 0.0], PlacementParam::R.set(&nominal, 600.0 + k as f64)))
            .collect();
        let index = |p: &Placement| (p.r - 600.0).round() as usize;
        let mut screens = Vec::new();
        let mut run_on = Vec::new();
        let corners = judge_corners(
            &boxed,
            Some(12),
            |p, n| {
                screens.push((index(p), n));
                Ok(TolerancePoint { success_rate: screened_rate[index(p)], scenes: 12, ..point(0.0) })
            },
            |p| {
                run_on.push(index(p));
                Ok(TolerancePoint { success_rate: screened_rate[index(p)] - 0.01, scenes: 44, ..point(0.0) })
            },
        )
        .unwrap();
        assert_eq!(screens, (0..10).map(|k| (k, 12)).collect::<Vec<_>>());
        // The four lowest: 0.4 (8), then 0.5 (1 before 3), then 0.6 (5).
        assert_eq!(run_on, vec![8, 1, 3, 5]);
        for (k, c) in corners.iter().enumerate() {
            assert_eq!(c.placement, boxed[k].1.to_string());
            let (rate, scenes) =
                if run_on.contains(&k) { (screened_rate[k] - 0.01, 44) } else { (screened_rate[k], 12) };
            assert_eq!((c.point.success_rate, c.point.scenes), (rate, scenes), "corner {k}");
        }

        // Without screening every corner runs to its verdict once, nothing screened.
        let mut run_on = 0;
        let corners = judge_corners(
            &boxed,
            None,
            |_, _| panic!("no screening"),
            |p| {
                run_on += 1;
                Ok(TolerancePoint { success_rate: screened_rate[index(p)], scenes: 44, ..point(0.0) })
            },
        )
        .unwrap();
        assert_eq!((run_on, corners.len()), (10, 10));
    }
    use camplace_config::WalkEnd;

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
        // The ranges the walks stop at: alpha down to 0, baseline down to 1 mm (80 of 81).
        let along = |i: usize, d: f64| {
            let mut o = [0.0; 5];
            o[i] = d;
            offset_placement(&nominal, &o).is_some()
        };
        assert_eq!(range_end(90, |k| along(1, -(k as f64))), 32);
        assert_eq!(range_end(90, |k| along(1, k as f64)), 57);
        assert_eq!(range_end(20_000, |k| along(2, -5.0 * k as f64)), 16);
    }

    /// A small deterministic generator.
    fn next(state: &mut u64) -> u64 {
        *state ^= *state << 13;
        *state ^= *state >> 7;
        *state ^= *state << 17;
        *state
    }

    #[test]
    fn a_settled_prefix_gives_the_verdict_of_every_scene() {
        // The slow obvious version: the paired test over all the scenes.
        let verdict =
            |a: &[Option<bool>], b: &[Option<bool>]| Paired::from_outcomes(a, b).mcnemar_p_a_lower() >= TOLERANCE_LEVEL;
        let mut state = 0x1234_5678_9abc_def1u64;
        let mut settled_early = 0;
        for case in 0..3000 {
            let n = 1 + (next(&mut state) % 60) as usize;
            let nominal_rate = next(&mut state) % 101;
            let point_rate = next(&mut state) % 101;
            let draw = |state: &mut u64, rate: u64| match next(state) % 100 {
                0 => None,
                x => Some(x <= rate),
            };
            let nominal: Vec<Option<bool>> = (0..n).map(|_| draw(&mut state, nominal_rate)).collect();
            let point: Vec<Option<bool>> = (0..n).map(|_| draw(&mut state, point_rate)).collect();
            let full = verdict(&point, &nominal);
            assert!(verdict_settled(&point, &nominal), "case {case}: every scene settles it");
            for m in 0..n {
                if verdict_settled(&point[..m], &nominal) {
                    assert_eq!(verdict(&point[..m], &nominal[..m]), full, "case {case}: settled at {m} of {n}");
                    settled_early += 1;
                }
            }
        }
        assert!(settled_early > 10_000, "prefixes settle often: {settled_early}");
    }

    fn point(rate: f64) -> TolerancePoint {
        TolerancePoint {
            offset: 0.0,
            success_rate: rate,
            success_interval: [0.0, 1.0],
            scenes: 10,
            lost: 0,
            gained: 0,
            p_lower: 1.0,
        }
    }

    #[test]
    fn a_range_end_names_what_ended_it() {
        let axis = |minus_range: f64, plus_range: f64| AxisTolerance {
            parameter: PlacementParam::Alpha.name().into(),
            unit: PlacementParam::Alpha.unit().into(),
            resolution: 1.0,
            limit: 30.0,
            minus: -minus_range,
            minus_end: WalkEnd::RangeEnd,
            minus_inside: point(1.0),
            minus_outside: None,
            minus_range,
            plus: plus_range,
            plus_end: WalkEnd::RangeEnd,
            plus_inside: point(1.0),
            plus_outside: None,
            plus_range,
            points: Vec::new(),
        };
        let a = axis(-12.0, 30.0);
        let [minus, plus] = a.sides();
        assert!(!minus.at_walk_limit() && plus.at_walk_limit());
        assert_eq!(
            minus.text("alpha", "deg"),
            "at least −12 deg: the placement's range ends there (alpha offset −12); 100.0 % [0.0 %–100.0 %] at 0"
        );
        assert!(
            plus.text("alpha", "deg").starts_with("at least +30 deg: the walk's limit (±30 deg"),
            "{}",
            plus.text("alpha", "deg")
        );
        // The walk's limits are whole resolutions, and the first step about an eighth of
        // them: three or four doublings before the limit.
        for (p, param) in TOLERANCE_PARAMETERS.into_iter().zip(PlacementParam::ALL) {
            assert_eq!(p.param, param);
            assert_eq!(tolerance_parameter(param), &p);
            let cap = p.walk_limit / p.resolution;
            assert_eq!(cap, cap.round(), "{}", p.param);
            let doublings = (cap / p.first_steps as f64).log2();
            assert!((2.5..=4.0).contains(&doublings), "{}: {doublings}", p.param);
        }
    }

    #[test]
    fn the_worst_corner_is_the_lowest() {
        let corner =
            |rate: f64| ToleranceCorner { placement: format!("{rate}"), offsets: [rate; 5], point: point(rate) };
        let report = ToleranceReport {
            placement: "r=605,alpha=32,baseline=81,vergence=3.5".into(),
            method: String::new(),
            seed: 0,
            scenarios: 1,
            margin: 0.1,
            level: 0.05,
            power: 0.8,
            nominal: point(1.0),
            axes: Vec::new(),
            corner_fraction: 1.0,
            corners: vec![corner(0.9), corner(0.7), corner(0.8), corner(0.7)],
            corner_screen: 0,
        };
        assert_eq!(report.worst_corner().unwrap().point.success_rate, 0.7);
        assert!(
            report.table().contains("worst of 4 corners (every parameter at its edge at once): 70.0 %"),
            "{}",
            report.table()
        );
        assert_eq!(report.check(), Ok(()));
        // Screened corners say so, with the scenes of the screen.
        let screened = ToleranceReport { corner_screen: 12, ..report };
        assert!(
            screened.table().contains(
                "worst of 4 corners (every parameter at its edge at once; each screened on 12 scenes, the lowest run \
                 on until their verdict settled): 70.0 %"
            ),
            "{}",
            screened.table()
        );
    }
}
