//! The board's pose in one view seen by a calibrated stereo pair: a homography on the
//! undistorted corners of one camera for the start, then the pose that best reprojects the
//! corners of every camera that saw it. The cameras stay as they are; calibrating them is
//! `stereo.rs`'s.

use nalgebra::{DVector, Isometry3, Matrix3, Point2, Point3};

use super::super::board::BoardView;
use super::super::lm::{self, ViewProblem};
use super::super::refine::{pose_from_params, pose_params, pose_typical, reprojection_residuals, wrap_rotation};
use super::super::zhang::{board_pose, homography};
use crate::camera::Camera;
use crate::error::{Error, ErrorKind, Result};

/// A calibrated pair in the left camera's frame: what every board pose is expressed in.
#[derive(Debug, Clone)]
pub(super) struct StereoPair<'a> {
    pub left: &'a Camera,
    pub right: &'a Camera,
    /// Left camera frame -> right camera frame.
    pub t_right_left: Isometry3<f64>,
}

impl StereoPair<'_> {
    /// The reprojection residuals (left image, then right, x then y per corner; zero for a
    /// camera that did not see the view) of `object` at `t_left_board`.
    pub fn residuals(&self, object: &[Point3<f64>], view: &BoardView, t_left_board: &Isometry3<f64>, out: &mut [f64]) {
        let (left_out, right_out) = out.split_at_mut(2 * object.len());
        match &view.left {
            Some(corners) => reprojection_residuals(self.left, t_left_board, object, corners, left_out),
            None => left_out.fill(0.0),
        }
        match &view.right {
            Some(corners) => {
                reprojection_residuals(self.right, &(self.t_right_left * t_left_board), object, corners, right_out)
            }
            None => right_out.fill(0.0),
        }
    }
}

/// One view's board pose as a least-squares problem of six parameters.
struct PoseProblem<'a> {
    pair: &'a StereoPair<'a>,
    object: &'a [Point3<f64>],
    view: &'a BoardView,
}

impl ViewProblem for PoseProblem<'_> {
    fn shared_len(&self) -> usize {
        6
    }
    fn view_len(&self) -> usize {
        0
    }
    fn view_count(&self) -> usize {
        1
    }
    fn residual_len(&self) -> usize {
        4 * self.object.len()
    }
    fn residuals(&self, shared: &[f64], _own: &[f64], _view: usize, out: &mut [f64]) {
        self.pair.residuals(self.object, self.view, &pose_from_params(shared), out);
    }
    fn typical_magnitudes(&self, x: &DVector<f64>) -> DVector<f64> {
        let mut typical = DVector::zeros(6);
        pose_typical(x.as_slice(), typical.as_mut_slice());
        typical
    }
    fn canonicalise(&self, x: &mut DVector<f64>) {
        wrap_rotation(x.as_mut_slice());
    }
}

/// The board's pose in the left camera's frame in `view` (`index` names it in messages).
pub(super) fn board_pose_in_view(
    pair: &StereoPair<'_>,
    object: &[Point3<f64>],
    view: &BoardView,
    index: usize,
) -> Result<Isometry3<f64>> {
    let (camera, corners, t_left_camera) = match (&view.left, &view.right) {
        (Some(c), _) => (pair.left, c, Isometry3::identity()),
        (None, Some(c)) => (pair.right, c, pair.t_right_left.inverse()),
        (None, None) => {
            return Err(Error::new(
                ErrorKind::Input,
                format!("hand-eye pose {index}: no corners in either image; expected the board seen by a camera"),
            ))
        }
    };
    let board_xy: Vec<Point2<f64>> = object.iter().map(|p| Point2::new(p.x, p.y)).collect();
    let normalised: Vec<Point2<f64>> = corners
        .iter()
        .map(|p| {
            let r = camera.ray(p.x, p.y);
            Point2::new(r.x, r.y)
        })
        .collect();
    let h = homography(&board_xy, &normalised).ok_or_else(|| {
        Error::new(
            ErrorKind::Calibration,
            format!("hand-eye pose {index}: the corners do not fix the board's pose; expected a chessboard's corners"),
        )
    })?;
    let start = t_left_camera * board_pose(&Matrix3::identity(), &h);
    let problem = PoseProblem { pair, object, view };
    let mut x = DVector::from_row_slice(&pose_params(&start));
    lm::minimise(&problem, &mut x, &format!("board pose of hand-eye pose {index}"))?;
    Ok(pose_from_params(x.as_slice()))
}
