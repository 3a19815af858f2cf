//! The drift watch: after each trigger, the table around the tray is found in the frame's
//! disparity, fitted with a plane through the calibrated rig, and compared with the table the
//! calibration puts at world z = 0. A rig that turned shows the table tilted by the same angle;
//! a rig that moved along the table's normal shows it nearer or farther. When the median of
//! the last checks leaves the limits (the study's mounting tolerances, or the flags'), the
//! watch warns. Turns about the table's normal and slides along it leave the plane as it
//! was and are not seen. The limits come from a tolerance measurement (alpha's and r's) or
//! are given.

use std::collections::VecDeque;

use std::path::Path;

use camplace_config::{FloatImage, PlacementParam, ToleranceReport};
use camplace_estimator::depth::RectifiedCamera;
use nalgebra::{Matrix3, Point3, Vector3};
use serde::Serialize;

use crate::{Error, ErrorKind, Result};

/// Checks the warning looks at: the median of this many, so one noisy frame never warns and
/// a real move warns by the third trigger after it.
pub const DRIFT_WINDOW: usize = 5;

/// A frame matched only around the tray (it looks as the background elsewhere, so the rig has
/// not moved since the background was captured) is matched again whole for the watch, after
/// the reply, on the first [`DRIFT_WINDOW`] triggers and on every this many after: a move made
/// before the background capture is slow news, and the re-match costs a whole-image match.
/// A frame that differs from the background everywhere (a move since) is matched whole
/// anyway and checked on every trigger.
pub const REMATCH_EVERY: u64 = 10;

/// Disparity samples per check (a grid over the image), so a check costs well under 1 ms.
const SAMPLES: usize = 6000;

/// How far from the calibrated table a point may lie to be taken as table, mm: wider than
/// the height change of the table across the view for a rig turned 5°.
const TABLE_BAND_MM: f64 = 40.0;

/// Fewest table points a check needs.
const MIN_TABLE_POINTS: usize = 200;

/// How far the rig may have moved before the watch warns.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DriftLimits {
    /// Largest turn of the rig (the table's apparent tilt), deg.
    pub rotation_deg: f64,
    /// Largest move of the rig along the table's normal, mm.
    pub translation_mm: f64,
    /// Where the limits come from (a tolerance.json, or the flags), for the page.
    pub from: String,
}

impl DriftLimits {
    /// The turn allowed when none is given, deg: the tolerance walk's resolution for alpha,
    /// below which a study does not tell placements apart.
    pub const DEFAULT_ROTATION_DEG: f64 = 1.0;
    /// The move allowed when none is given, mm: the walk's resolution for r.
    pub const DEFAULT_TRANSLATION_MM: f64 = 5.0;

    /// The limits of a tolerance measurement (`tolerance.json` read from `path`): alpha's
    /// tolerance for the turn and r's for the move, the smaller side of each. An error naming
    /// the file when either was not measured.
    pub fn from_tolerance(t: &ToleranceReport, path: &Path) -> Result<DriftLimits> {
        let axis = |param: PlacementParam| {
            t.axis(param).map(|x| x.minus.min(x.plus)).ok_or_else(|| {
                Error::new(ErrorKind::Setting, format!("{}: axes: expected a tolerance of {param}", path.display()))
            })
        };
        Ok(DriftLimits {
            rotation_deg: axis(PlacementParam::Alpha)?,
            translation_mm: axis(PlacementParam::R)?,
            from: path.display().to_string(),
        })
    }

    /// The limits given (`--drift-deg`, `--drift-mm`), each above 0, the defaults for those
    /// not given.
    pub fn given(rotation_deg: Option<f64>, translation_mm: Option<f64>) -> Result<DriftLimits> {
        let positive = |v: f64, flag: &str| {
            if v.is_finite() && v > 0.0 {
                Ok(v)
            } else {
                Err(Error::new(ErrorKind::Setting, format!("{flag} {v}: expected a number above 0")))
            }
        };
        Ok(DriftLimits {
            rotation_deg: positive(rotation_deg.unwrap_or(Self::DEFAULT_ROTATION_DEG), "--drift-deg")?,
            translation_mm: positive(translation_mm.unwrap_or(Self::DEFAULT_TRANSLATION_MM), "--drift-mm")?,
            from: if rotation_deg.is_some() || translation_mm.is_some() { "flags" } else { "defaults" }.to_string(),
        })
    }
}

/// What the watch last found.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct DriftState {
    /// Checks run (triggers whose frame had enough table in view).
    pub checks: u64,
    /// The table's apparent tilt, median of the last checks, deg.
    pub rotation_deg: Option<f64>,
    /// The rig's apparent move along the table's normal, median of the last checks, mm.
    pub translation_mm: Option<f64>,
    /// Table points in the last check.
    pub table_points: usize,
    /// The rig left the limits.
    pub warning: bool,
}

/// The drift watch over the frames of one rig.
pub struct DriftWatch {
    limits: DriftLimits,
    /// Triggers seen ([`DriftWatch::due`]).
    triggers: u64,
    recent: VecDeque<(f64, f64)>,
    points: Vec<Point3<f64>>,
    state: DriftState,
}

impl DriftWatch {
    /// A watch warning past `limits`, with no check made yet.
    pub fn new(limits: DriftLimits) -> DriftWatch {
        DriftWatch {
            limits,
            triggers: 0,
            recent: VecDeque::with_capacity(DRIFT_WINDOW),
            points: Vec::with_capacity(SAMPLES),
            state: DriftState::default(),
        }
    }

    /// Counts a trigger and says whether its frame is to be checked: always when it was
    /// `matched_whole`, else on the first [`DRIFT_WINDOW`] triggers and every
    /// [`REMATCH_EVERY`]-th after (the frame then matched again whole).
    pub fn due(&mut self, matched_whole: bool) -> bool {
        let n = self.triggers;
        self.triggers += 1;
        matched_whole || n < DRIFT_WINDOW as u64 || n.is_multiple_of(REMATCH_EVERY)
    }

    /// What the watch last found.
    pub fn state(&self) -> &DriftState {
        &self.state
    }

    /// Checks the frame whose rectified-left `disparity` (over the whole image: the table
    /// far from the tray) the estimator just computed.
    pub fn check(&mut self, disparity: &FloatImage, camera: &RectifiedCamera) -> &DriftState {
        let Some((rotation_deg, translation_mm)) = self.implied_motion(disparity, camera) else {
            return &self.state;
        };
        if self.recent.len() == DRIFT_WINDOW {
            self.recent.pop_front();
        }
        self.recent.push_back((rotation_deg, translation_mm));
        let rot = median(self.recent.iter().map(|r| r.0));
        let tr = median(self.recent.iter().map(|r| r.1));
        self.state.checks += 1;
        self.state.rotation_deg = Some(rot);
        self.state.translation_mm = Some(tr);
        self.state.warning = rot > self.limits.rotation_deg || tr.abs() > self.limits.translation_mm;
        &self.state
    }

    /// The table's tilt (deg) and the rig's move along its normal (mm) this frame shows,
    /// when enough table is in view.
    fn implied_motion(&mut self, disparity: &FloatImage, camera: &RectifiedCamera) -> Option<(f64, f64)> {
        let (w, h) = (disparity.width, disparity.height);
        if w == 0 || h == 0 || disparity.data.len() != w * h {
            return None;
        }
        let stride = (((w * h) as f64 / SAMPLES as f64).sqrt().floor() as usize).max(1);
        let (f, cx, cy) = (camera.focal(), camera.k[(0, 2)], camera.k[(1, 2)]);
        let to_world = camera.t_world_rectified;
        self.points.clear();
        for v in (stride / 2..h).step_by(stride) {
            for u in (stride / 2..w).step_by(stride) {
                let d = disparity.data[v * w + u];
                if !(d.is_finite() && d > 0.0) {
                    continue;
                }
                let z = f64::from(camera.depth_from_disparity(d));
                let p = to_world * Point3::new((u as f64 - cx) * z / f, (v as f64 - cy) * z / f, z);
                if p.z.abs() < TABLE_BAND_MM {
                    self.points.push(p);
                }
            }
        }
        let mut keep = vec![true; self.points.len()];
        let mut plane = None;
        // A least-squares plane, refitted twice without the points far from it (the tray's
        // foot, the items, mismatches).
        for _ in 0..3 {
            let fitted = fit_plane(&self.points, &keep)?;
            let residuals: Vec<f64> = self.points.iter().map(|p| (p.z - fitted.height_at(p.x, p.y)).abs()).collect();
            let kept: Vec<f64> = residuals.iter().zip(&keep).filter(|(_, k)| **k).map(|(r, _)| *r).collect();
            let limit = (3.0 * 1.4826 * median(kept.iter().copied())).max(1.0);
            for (k, r) in keep.iter_mut().zip(&residuals) {
                *k = *r <= limit;
            }
            plane = Some(fitted);
        }
        let plane = plane?;
        self.state.table_points = keep.iter().filter(|k| **k).count();
        if self.state.table_points < MIN_TABLE_POINTS {
            return None;
        }
        let normal = Vector3::new(-plane.a, -plane.b, 1.0).normalize();
        let tilt_deg = normal.z.clamp(-1.0, 1.0).acos().to_degrees();
        let c = to_world.translation.vector;
        let distance = (c.z - plane.height_at(c.x, c.y)) * normal.z;
        Some((tilt_deg, distance - c.z))
    }
}

/// The plane z = a x + b y + c.
#[derive(Debug, Clone, Copy)]
struct Plane {
    a: f64,
    b: f64,
    c: f64,
}

impl Plane {
    fn height_at(&self, x: f64, y: f64) -> f64 {
        self.a * x + self.b * y + self.c
    }
}

/// The least-squares plane z = a x + b y + c through the kept points.
fn fit_plane(points: &[Point3<f64>], keep: &[bool]) -> Option<Plane> {
    let kept = || points.iter().zip(keep).filter(|(_, k)| **k).map(|(p, _)| p);
    let n = kept().count();
    if n < MIN_TABLE_POINTS {
        return None;
    }
    let mean = kept().fold(Vector3::zeros(), |s, p| s + p.coords) / n as f64;
    let mut m = Matrix3::zeros();
    let mut rhs = Vector3::zeros();
    for p in kept() {
        let (x, y, z) = (p.x - mean.x, p.y - mean.y, p.z - mean.z);
        let row = Vector3::new(x, y, 1.0);
        m += row * row.transpose();
        rhs += row * z;
    }
    let s = m.lu().solve(&rhs)?;
    Some(Plane { a: s.x, b: s.y, c: mean.z + s.z - s.x * mean.x - s.y * mean.y })
}

/// The median of `values` (the mean of the middle two for an even count); 0 when empty.
fn median(values: impl Iterator<Item = f64>) -> f64 {
    camplace_estimator::scoring::median_in_place(&mut values.collect::<Vec<_>>()).unwrap_or(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Isometry3, Translation3, UnitQuaternion};

    /// A tolerance report with `(parameter, minus, plus)` measured.
    fn tolerances(axes: &[(PlacementParam, f64, f64)]) -> ToleranceReport {
        camplace_testing::tolerance_report("r=605,alpha=32,baseline=81,vergence=3.5", axes)
    }

    #[test]
    fn frames_matched_around_the_tray_are_checked_at_first_then_every_tenth() {
        let limits = DriftLimits::given(None, None).unwrap();
        let mut watch = DriftWatch::new(limits.clone());
        let due: Vec<u64> = (0..40).filter(|_| watch.due(false)).collect();
        assert_eq!(due, [0, 1, 2, 3, 4, 10, 20, 30]);
        let mut watch = DriftWatch::new(limits);
        assert!((0..40).all(|_| watch.due(true)), "a frame matched whole is always checked");
    }

    #[test]
    fn the_limits_are_the_smaller_side_of_alpha_and_r_or_given() {
        let path = Path::new("t/tolerance.json");
        let t = tolerances(&[(PlacementParam::R, 35.0, 20.0), (PlacementParam::Alpha, 3.0, 4.0)]);
        let l = DriftLimits::from_tolerance(&t, path).unwrap();
        assert_eq!((l.rotation_deg, l.translation_mm, l.from.as_str()), (3.0, 20.0, "t/tolerance.json"));
        let t = tolerances(&[(PlacementParam::Alpha, 3.0, 4.0)]);
        let e = DriftLimits::from_tolerance(&t, path).unwrap_err();
        assert_eq!(e.to_string(), "t/tolerance.json: axes: expected a tolerance of r");
        let l = DriftLimits::given(None, None).unwrap();
        assert_eq!((l.rotation_deg, l.translation_mm, l.from.as_str()), (1.0, 5.0, "defaults"));
        let l = DriftLimits::given(None, Some(2.5)).unwrap();
        assert_eq!((l.rotation_deg, l.translation_mm, l.from.as_str()), (1.0, 2.5, "flags"));
        let e = DriftLimits::given(Some(0.0), None).unwrap_err();
        assert_eq!(e.to_string(), "--drift-deg 0: expected a number above 0");
    }

    /// A rectified camera 600 mm above the table looking straight down, turned by `tilt_deg`
    /// about its x axis as the calibration does not know.
    fn seen_table(tilt_deg: f64, lift_mm: f64) -> (FloatImage, RectifiedCamera) {
        let (w, h, f, baseline) = (320usize, 240usize, 300.0, 80.0);
        let k = Matrix3::new(f, 0.0, 160.0, 0.0, f, 120.0, 0.0, 0.0, 1.0);
        let down = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI);
        let nominal = Isometry3::from_parts(Translation3::new(10.0, -20.0, 600.0), down);
        let turn = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), tilt_deg.to_radians());
        let truth = Isometry3::from_parts(Translation3::new(10.0, -20.0, 600.0 + lift_mm), down * turn);
        let camera = RectifiedCamera { width: w, height: h, k, baseline, t_world_rectified: nominal };
        // Each pixel's ray through the true camera meets the table z = 0.
        let mut disparity = FloatImage::new(w, h, f32::INFINITY);
        for v in 0..h {
            for u in 0..w {
                let ray = truth.rotation * Vector3::new((u as f64 - 160.0) / f, (v as f64 - 120.0) / f, 1.0);
                let t = -truth.translation.vector.z / ray.z;
                let depth = t; // the ray's z in the camera frame is 1
                disparity.data[v * w + u] = (f * baseline / depth) as f32;
            }
        }
        (disparity, camera)
    }

    #[test]
    fn a_turned_rig_shows_its_turn_and_a_lifted_one_its_lift() {
        let limits = DriftLimits { rotation_deg: 1.0, translation_mm: 5.0, from: "test".into() };
        for (tilt, lift) in [(0.0, 0.0), (3.0, 0.0), (0.5, 0.0), (0.0, 12.0)] {
            let (disparity, camera) = seen_table(tilt, lift);
            let mut watch = DriftWatch::new(limits.clone());
            let s = watch.check(&disparity, &camera).clone();
            let (rot, tr) = (s.rotation_deg.unwrap(), s.translation_mm.unwrap());
            assert!((rot - tilt).abs() < 0.02, "tilt {tilt}: {rot}");
            assert!((tr - lift).abs() < 0.5 + 600.0 * (1.0 - tilt.to_radians().cos()), "lift {lift}: {tr}");
            assert_eq!(s.warning, tilt > 1.0 || lift > 5.0, "{tilt} {lift}: {s:?}");
        }
    }
}
