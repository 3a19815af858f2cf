//! Stereo calibration from start to finish: each camera alone from every view it saw (Zhang's
//! closed form, then refined with distortion), the pose between them from the views both saw,
//! one joint refinement of everything, and the dropping of views whose error stands out.

use std::collections::BTreeMap;

use nalgebra::{DVector, Isometry3, Point2, Point3, Translation3, Vector3};

use super::board::{check_inputs, BoardView, CalibrationBoard, Side, MIN_CALIBRATION_VIEWS};
use super::lm;
use super::refine::{degrees_of_freedom, refine_camera, refine_stereo, CameraFit, StereoFit, StereoProblem};
use super::zhang::zhang_start;
use crate::camera::Camera;
use crate::error::{Error, ErrorKind, Result};
use crate::scoring::median_or_nan as median;

/// A view stands out when the larger RMS error of the cameras that saw it exceeds this
/// multiple of the median view's. With detection noise alone a view's RMS, an average over all its corners, stays
/// within a few tens of percent of the median: three times the median is not reached by
/// chance.
const OUTLIER_MEDIAN_FACTOR: f64 = 3.0;
/// A view stands out only above this RMS error as well, pixels: a very clean calibration
/// (median 0.05 px) would otherwise drop views that are only a little blurrier than the rest
/// yet far more accurate than any use of the rig needs, and lose the board poses they add.
const OUTLIER_MIN_RMS_PX: f64 = 1.0;

/// The χ² value with two degrees of freedom (both cameras' k3) that chance exceeds once in
/// a thousand fits: a drop in the squared error beyond it, in units of the noise, is k3's.
const K3_CHI2: f64 = 13.82;

/// A calibrated stereo pair in the left camera's frame.
#[derive(Debug, Clone, PartialEq)]
pub struct StereoCalibration {
    /// The left camera; its frame is the calibration's (`t_world_camera` is the identity).
    pub left: Camera,
    /// The right camera; `t_world_camera` is T_left_right (right camera -> left frame).
    pub right: Camera,
    /// Board frame -> left camera frame, one per kept view in input order, also for a view
    /// only the right camera saw.
    pub t_left_board: Vec<Isometry3<f64>>,
    /// Every input view's reprojection error, in input order.
    pub views: Vec<ViewResidual>,
    /// RMS reprojection distance over every corner the cameras saw in the kept views, pixels.
    pub rms_px: f64,
    /// Whether k3 was refined: only when freeing it lowers the error beyond what noise
    /// explains (else it is held at zero).
    pub k3_estimated: bool,
}

/// One view's reprojection error: the RMS distance between the detected corners and the
/// calibrated model's projections, as OpenCV reports it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ViewResidual {
    /// The view's index in the input.
    pub index: usize,
    /// RMS reprojection distance in the left image, pixels; `None` if the left camera did not
    /// see the view.
    pub rms_left_px: Option<f64>,
    /// RMS reprojection distance in the right image, pixels; `None` if the right camera did
    /// not see the view.
    pub rms_right_px: Option<f64>,
    /// Whether the view's error stood out and it was left out of the calibration; its errors
    /// are then those of the last refinement that held it.
    pub dropped: bool,
}

impl ViewResidual {
    /// The larger RMS error of the cameras that saw the view.
    fn worse_px(&self) -> f64 {
        self.rms_left_px.into_iter().chain(self.rms_right_px).fold(0.0, f64::max)
    }
}

/// Calibrates a stereo pair of `width` x `height` cameras from views of `board`, each with the
/// whole board detected in one image or both. Each camera needs `MIN_CALIBRATION_VIEWS`
/// views, and at least one view must be seen by both: those fix the pose between the cameras,
/// while a view seen by one camera alone adds to that camera's intrinsics and distortion,
/// which is how the parts of an image the other camera does not share get corners.
pub fn calibrate_stereo(
    board: &CalibrationBoard,
    views: &[BoardView],
    width: usize,
    height: usize,
) -> Result<StereoCalibration> {
    check_inputs(board, views, width, height)?;
    let object = board.object_points();
    let left = calibrate_camera(&object, views, Side::Left, width, height)?;
    let right = calibrate_camera(&object, views, Side::Right, width, height)?;
    let stereo_views: Vec<usize> =
        (0..views.len()).filter(|&i| views[i].left.is_some() && views[i].right.is_some()).collect();
    let t_right_left = stereo_start(
        &stereo_views.iter().map(|&i| left.t_camera_board[&i]).collect::<Vec<_>>(),
        &stereo_views.iter().map(|&i| right.t_camera_board[&i]).collect::<Vec<_>>(),
    );
    let t_left_right = t_right_left.inverse();
    // Each view starts from the left camera's own refinement where it saw the view.
    let t_left_board: Vec<Isometry3<f64>> = (0..views.len())
        .map(|i| match left.t_camera_board.get(&i) {
            Some(&pose) => pose,
            None => t_left_right * right.t_camera_board[&i],
        })
        .collect();
    let mut fit = StereoFit { left: left.camera, right: right.camera, t_right_left, t_left_board };

    let mut kept: Vec<usize> = (0..views.len()).collect();
    let mut residuals: Vec<Option<ViewResidual>> = vec![None; views.len()];
    loop {
        let kept_views: Vec<&BoardView> = kept.iter().map(|&i| &views[i]).collect();
        let problem = StereoProblem { object: &object, views: &kept_views, width, height, k3_free: false };
        fit = refine_stereo(&problem, &fit)?.0;
        check_cameras(&fit)?;
        let view_rms = view_rms_px(&problem, &fit);
        for (&index, &(rms_left_px, rms_right_px)) in kept.iter().zip(&view_rms) {
            residuals[index] = Some(ViewResidual { index, rms_left_px, rms_right_px, dropped: false });
        }
        let worse: Vec<f64> = kept.iter().map(|&i| residuals[i].expect("refined just now").worse_px()).collect();
        let threshold = (OUTLIER_MEDIAN_FACTOR * median(&worse)).max(OUTLIER_MIN_RMS_PX);
        let (worst, &worst_rms) =
            worse.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1)).expect("at least the minimum view count");
        // A worst view that cannot go ends the dropping: judging the others while its error
        // still leaks into them could drop good views in its place.
        if worst_rms <= threshold || !can_drop(views, &kept, worst) {
            break;
        }
        // Only the worst view goes: its error leaks into the others' through the shared
        // parameters, so they are judged again without it.
        if let Some(r) = residuals[kept[worst]].as_mut() {
            r.dropped = true;
        }
        kept.remove(worst);
        fit.t_left_board.remove(worst);
    }

    // k3 only where the data call for it: it trades off against k2 and is pinned down only
    // near the image's corners, so freeing it without need moves the distortion out there by
    // tenths of a pixel. A likelihood-ratio test of the fit with both cameras' k3 free against
    // the one without decides.
    let kept_views: Vec<&BoardView> = kept.iter().map(|&i| &views[i]).collect();
    let fixed = StereoProblem { object: &object, views: &kept_views, width, height, k3_free: false };
    let free = StereoProblem { k3_free: true, ..fixed };
    let (_, cost_fixed) = refine_stereo(&fixed, &fit)?;
    let (fit_free, cost_free) = refine_stereo(&free, &fit)?;
    let (residual_count, param_count) = degrees_of_freedom(&free);
    let sigma2 = cost_free / residual_count.saturating_sub(param_count).max(1) as f64;
    let k3_estimated = check_cameras(&fit_free).is_ok() && (cost_fixed - cost_free) / sigma2 > K3_CHI2;
    if k3_estimated {
        fit = fit_free;
        for (&index, &(rms_left_px, rms_right_px)) in kept.iter().zip(&view_rms_px(&free, &fit)) {
            residuals[index] = Some(ViewResidual { index, rms_left_px, rms_right_px, dropped: false });
        }
    }
    let views_out: Vec<ViewResidual> = residuals.into_iter().map(|r| r.expect("every view was refined once")).collect();
    // Every side holds the board's corner count, so the mean of the sides' squared RMS is
    // the mean over their corners.
    let kept_sides: Vec<f64> =
        views_out.iter().filter(|r| !r.dropped).flat_map(|r| r.rms_left_px.into_iter().chain(r.rms_right_px)).collect();
    let rms_px = (kept_sides.iter().map(|r| r * r).sum::<f64>() / kept_sides.len() as f64).sqrt();
    let mut left = fit.left;
    left.t_world_camera = Isometry3::identity();
    let mut right = fit.right;
    right.t_world_camera = fit.t_right_left.inverse();
    Ok(StereoCalibration { left, right, t_left_board: fit.t_left_board, views: views_out, rms_px, k3_estimated })
}

/// Whether the kept view at position `position` of `kept` can be left out: each camera keeps
/// `MIN_CALIBRATION_VIEWS` views and one view seen by both remains.
fn can_drop(views: &[BoardView], kept: &[usize], position: usize) -> bool {
    let rest = || kept.iter().enumerate().filter(move |&(p, _)| p != position).map(|(_, &i)| &views[i]);
    let left = rest().filter(|v| v.left.is_some()).count();
    let right = rest().filter(|v| v.right.is_some()).count();
    let both = rest().filter(|v| v.left.is_some() && v.right.is_some()).count();
    left >= MIN_CALIBRATION_VIEWS && right >= MIN_CALIBRATION_VIEWS && both >= 1
}

/// One camera's start: its intrinsics and distortion, and the board's pose in each view it saw.
struct CameraStart {
    camera: Camera,
    /// Board frame -> camera frame, by input view index.
    t_camera_board: BTreeMap<usize, Isometry3<f64>>,
}

/// One camera alone from every view it saw: Zhang's closed form, then refined with its
/// distortion from zero.
fn calibrate_camera(
    object: &[Point3<f64>],
    views: &[BoardView],
    side: Side,
    width: usize,
    height: usize,
) -> Result<CameraStart> {
    let (indices, corners): (Vec<usize>, Vec<&[Point2<f64>]>) =
        views.iter().enumerate().filter_map(|(i, v)| Some((i, side.corners(v)?))).unzip();
    let start = zhang_start(object, &corners, &indices, width, height, side.name())?;
    let camera = Camera { width, height, k: start.k, dist: [0.0; 5], t_world_camera: Isometry3::identity() };
    let start = CameraFit { camera, t_camera_board: start.t_camera_board };
    let fit = refine_camera(object, &corners, &start, &format!("{} camera", side.name()))?;
    Ok(CameraStart { camera: fit.camera, t_camera_board: indices.into_iter().zip(fit.t_camera_board).collect() })
}

/// T_right_left from the board poses of the views both cameras saw (T_right_board ·
/// T_left_board⁻¹): the per-axis median translation and the medoid rotation (the one with the
/// least total angle to the others), so one badly posed view does not pull the start.
fn stereo_start(t_left_board: &[Isometry3<f64>], t_right_board: &[Isometry3<f64>]) -> Isometry3<f64> {
    let candidates: Vec<Isometry3<f64>> =
        t_left_board.iter().zip(t_right_board).map(|(l, r)| r * l.inverse()).collect();
    let axis_median = |axis: usize| median(&candidates.iter().map(|t| t.translation.vector[axis]).collect::<Vec<_>>());
    let translation = Vector3::new(axis_median(0), axis_median(1), axis_median(2));
    let total_angle = |t: &Isometry3<f64>| candidates.iter().map(|o| t.rotation.angle_to(&o.rotation)).sum::<f64>();
    let rotation = candidates
        .iter()
        .min_by(|a, b| total_angle(a).total_cmp(&total_angle(b)))
        .expect("at least one view seen by both cameras")
        .rotation;
    Isometry3::from_parts(Translation3::from(translation), rotation)
}

/// Each view's RMS reprojection distance (left, right) under `fit`, `None` for a camera that
/// did not see it.
fn view_rms_px(problem: &StereoProblem<'_>, fit: &StereoFit) -> Vec<(Option<f64>, Option<f64>)> {
    let corner_count = problem.object.len();
    let mut residuals = DVector::zeros(4 * corner_count * fit.t_left_board.len());
    lm::evaluate(problem, &problem.params(fit), &mut residuals);
    let rms = |r: &[f64]| (r.iter().map(|v| v * v).sum::<f64>() / corner_count as f64).sqrt();
    residuals
        .as_slice()
        .chunks_exact(4 * corner_count)
        .zip(problem.views)
        .map(|(residuals, view)| {
            let (left, right) = residuals.split_at(2 * corner_count);
            (view.left.as_ref().map(|_| rms(left)), view.right.as_ref().map(|_| rms(right)))
        })
        .collect()
}

/// Rejects a refinement that ended on an unusable camera.
fn check_cameras(fit: &StereoFit) -> Result<()> {
    for (name, camera) in [("left", &fit.left), ("right", &fit.right)] {
        let finite = camera.k.iter().chain(&camera.dist).all(|v| v.is_finite());
        if !(finite && camera.k[(0, 0)] > 0.0 && camera.k[(1, 1)] > 0.0) {
            return Err(Error::new(
                ErrorKind::Calibration,
                format!(
                    "calibration {name} camera: the refinement ended with focal lengths {} and {}; expected positive \
                     finite ones",
                    camera.k[(0, 0)],
                    camera.k[(1, 1)]
                ),
            ));
        }
    }
    let finite_pose = fit.t_right_left.to_homogeneous().iter().all(|v| v.is_finite());
    if !finite_pose {
        return Err(Error::new(
            ErrorKind::Calibration,
            "calibration: the refinement ended with a non-finite stereo pose; expected a finite one",
        ));
    }
    Ok(())
}
