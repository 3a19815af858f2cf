//! The calibration's least-squares refinements: one camera with its board poses, and the
//! stereo pair with one board pose per view and the pose between the cameras. Each
//! owns its parameter layout; `lm` does the minimising.

use nalgebra::{DVector, Isometry3, Matrix3, Point2, Point3, Translation3, UnitQuaternion, Vector3};

use super::board::BoardView;
use super::lm::{self, ViewProblem};
use crate::camera::Camera;
use crate::error::Result;

/// fx fy cx cy (pixels) and k1 k2 p1 p2 k3.
const INTRINSICS_LEN: usize = 9;
/// A rotation vector (axis times angle, radians) and a translation (mm).
pub(super) const POSE_LEN: usize = 6;

/// One camera's intrinsics as parameters (its skew is zero).
fn intrinsics_params(camera: &Camera) -> [f64; INTRINSICS_LEN] {
    let (k, d) = (&camera.k, &camera.dist);
    [k[(0, 0)], k[(1, 1)], k[(0, 2)], k[(1, 2)], d[0], d[1], d[2], d[3], d[4]]
}

/// The camera (at the identity pose) of intrinsic parameters `p`; k3 is held at zero unless
/// `k3_free` (its parameter then has no effect, so the refinement leaves it where it is).
fn camera_from_params(p: &[f64], width: usize, height: usize, k3_free: bool) -> Camera {
    Camera {
        width,
        height,
        k: Matrix3::new(p[0], 0.0, p[2], 0.0, p[1], p[3], 0.0, 0.0, 1.0),
        dist: [p[4], p[5], p[6], p[7], if k3_free { p[8] } else { 0.0 }],
        t_world_camera: Isometry3::identity(),
    }
}

pub(super) fn pose_params(pose: &Isometry3<f64>) -> [f64; POSE_LEN] {
    let (r, t) = (pose.rotation.scaled_axis(), pose.translation.vector);
    [r.x, r.y, r.z, t.x, t.y, t.z]
}

pub(super) fn pose_from_params(p: &[f64]) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(p[3], p[4], p[5]),
        UnitQuaternion::from_scaled_axis(Vector3::new(p[0], p[1], p[2])),
    )
}

/// Typical magnitudes of a camera's parameters: the focal length for the pixel ones, one for
/// the distortion coefficients.
fn intrinsics_typical(p: &[f64], out: &mut [f64]) {
    let focal = p[0].abs().max(p[1].abs()).max(1.0);
    out[..4].fill(focal);
    out[4..INTRINSICS_LEN].fill(1.0);
}

/// Typical magnitudes of a pose's parameters: a radian for the rotation, the distance for the
/// translation.
pub(super) fn pose_typical(p: &[f64], out: &mut [f64]) {
    out[..3].fill(1.0);
    out[3..POSE_LEN].fill(Vector3::new(p[3], p[4], p[5]).norm().max(1.0));
}

/// Wraps a rotation vector longer than π to the same rotation's shorter vector, which keeps
/// the parameterisation away from its singularity at 2π.
pub(super) fn wrap_rotation(p: &mut [f64]) {
    let r = Vector3::new(p[0], p[1], p[2]);
    let angle = r.norm();
    if angle > std::f64::consts::PI {
        let wrapped = r * (1.0 - 2.0 * std::f64::consts::PI / angle);
        p[..3].copy_from_slice(wrapped.as_slice());
    }
}

/// Writes the reprojection residuals (pixel minus observed, x then y per corner) of
/// `object` seen by `camera` at `t_camera_board`; NaN for a point behind the camera.
pub(super) fn reprojection_residuals(
    camera: &Camera,
    t_camera_board: &Isometry3<f64>,
    object: &[Point3<f64>],
    observed: &[Point2<f64>],
    out: &mut [f64],
) {
    for ((p, seen), r) in object.iter().zip(observed).zip(out.chunks_exact_mut(2)) {
        match camera.project_camera(&t_camera_board.transform_point(p)) {
            Some(pixel) => {
                r[0] = pixel.x - seen.x;
                r[1] = pixel.y - seen.y;
            }
            None => r.fill(f64::NAN),
        }
    }
}

/// One camera and the poses of the board in its views.
#[derive(Debug, Clone)]
pub(super) struct CameraFit {
    pub camera: Camera,
    /// Board frame -> camera frame, one per view.
    pub t_camera_board: Vec<Isometry3<f64>>,
}

struct CameraProblem<'a> {
    object: &'a [Point3<f64>],
    corners: &'a [&'a [Point2<f64>]],
    width: usize,
    height: usize,
    k3_free: bool,
}

impl ViewProblem for CameraProblem<'_> {
    fn shared_len(&self) -> usize {
        INTRINSICS_LEN
    }

    fn view_len(&self) -> usize {
        POSE_LEN
    }

    fn view_count(&self) -> usize {
        self.corners.len()
    }

    fn residual_len(&self) -> usize {
        2 * self.object.len()
    }

    fn residuals(&self, shared: &[f64], own: &[f64], view: usize, out: &mut [f64]) {
        let camera = camera_from_params(shared, self.width, self.height, self.k3_free);
        reprojection_residuals(&camera, &pose_from_params(own), self.object, self.corners[view], out);
    }

    fn typical_magnitudes(&self, x: &DVector<f64>) -> DVector<f64> {
        let mut typical = DVector::zeros(x.len());
        intrinsics_typical(&x.as_slice()[..INTRINSICS_LEN], &mut typical.as_mut_slice()[..INTRINSICS_LEN]);
        for (p, out) in x.as_slice()[INTRINSICS_LEN..]
            .chunks_exact(POSE_LEN)
            .zip(typical.as_mut_slice()[INTRINSICS_LEN..].chunks_exact_mut(POSE_LEN))
        {
            pose_typical(p, out);
        }
        typical
    }

    fn canonicalise(&self, x: &mut DVector<f64>) {
        x.as_mut_slice()[INTRINSICS_LEN..].chunks_exact_mut(POSE_LEN).for_each(wrap_rotation);
    }
}

/// Refines one camera's intrinsics and distortion (k3 held at zero) with its board poses from
/// `start`, by the reprojection error of `corners` (one slice per view); `what` names it in
/// messages.
pub(super) fn refine_camera(
    object: &[Point3<f64>],
    corners: &[&[Point2<f64>]],
    start: &CameraFit,
    what: &str,
) -> Result<CameraFit> {
    let (width, height) = (start.camera.width, start.camera.height);
    let problem = CameraProblem { object, corners, width, height, k3_free: false };
    let mut x = DVector::from_iterator(
        INTRINSICS_LEN + POSE_LEN * corners.len(),
        intrinsics_params(&start.camera).into_iter().chain(start.t_camera_board.iter().flat_map(pose_params)),
    );
    lm::minimise(&problem, &mut x, what)?;
    let x = x.as_slice();
    Ok(CameraFit {
        camera: camera_from_params(&x[..INTRINSICS_LEN], width, height, false),
        t_camera_board: x[INTRINSICS_LEN..].chunks_exact(POSE_LEN).map(pose_from_params).collect(),
    })
}

/// Both cameras, the pose between them and the board's pose in the left camera per view.
#[derive(Debug, Clone)]
pub(super) struct StereoFit {
    /// The left camera at the identity pose.
    pub left: Camera,
    /// The right camera at the identity pose.
    pub right: Camera,
    /// Left camera frame -> right camera frame.
    pub t_right_left: Isometry3<f64>,
    /// Board frame -> left camera frame, one per view, also for a view only the right camera
    /// saw.
    pub t_left_board: Vec<Isometry3<f64>>,
}

/// The reprojection residuals of every view of the pair: per view the left image's corners,
/// then the right's, zero for a camera that did not see the view.
///
/// A view's board pose is a parameter in the left camera's frame if the left camera saw it,
/// else in the right camera's. A right-only view then does not depend on the stereo pose,
/// which it cannot inform (its own pose absorbs any change of it): parameterised in the left
/// frame, every step of the stereo pose would have to be undone by its pose, coupling the two
/// for nothing.
pub(super) struct StereoProblem<'a> {
    pub object: &'a [Point3<f64>],
    pub views: &'a [&'a BoardView],
    pub width: usize,
    pub height: usize,
    /// Whether k3 is refined (else held at zero).
    pub k3_free: bool,
}

/// Shared parameters of the stereo problem: left intrinsics, right intrinsics, T_right_left.
const STEREO_SHARED_LEN: usize = 2 * INTRINSICS_LEN + POSE_LEN;

impl StereoProblem<'_> {
    /// The parameter vector of `fit`.
    pub fn params(&self, fit: &StereoFit) -> DVector<f64> {
        let shared = intrinsics_params(&fit.left)
            .into_iter()
            .chain(intrinsics_params(&fit.right))
            .chain(pose_params(&fit.t_right_left));
        let poses = self.views.iter().zip(&fit.t_left_board).flat_map(|(view, t_left_board)| {
            if view.left.is_some() {
                pose_params(t_left_board)
            } else {
                pose_params(&(fit.t_right_left * t_left_board))
            }
        });
        DVector::from_iterator(STEREO_SHARED_LEN + POSE_LEN * fit.t_left_board.len(), shared.chain(poses))
    }

    /// The fit of parameter vector `x`.
    pub fn fit(&self, x: &DVector<f64>) -> StereoFit {
        let x = x.as_slice();
        let t_right_left = pose_from_params(&x[2 * INTRINSICS_LEN..STEREO_SHARED_LEN]);
        let t_left_right = t_right_left.inverse();
        StereoFit {
            left: camera_from_params(&x[..INTRINSICS_LEN], self.width, self.height, self.k3_free),
            right: camera_from_params(&x[INTRINSICS_LEN..2 * INTRINSICS_LEN], self.width, self.height, self.k3_free),
            t_right_left,
            t_left_board: self
                .views
                .iter()
                .zip(x[STEREO_SHARED_LEN..].chunks_exact(POSE_LEN))
                .map(
                    |(view, p)| {
                        if view.left.is_some() {
                            pose_from_params(p)
                        } else {
                            t_left_right * pose_from_params(p)
                        }
                    },
                )
                .collect(),
        }
    }
}

impl ViewProblem for StereoProblem<'_> {
    fn shared_len(&self) -> usize {
        STEREO_SHARED_LEN
    }

    fn view_len(&self) -> usize {
        POSE_LEN
    }

    fn view_count(&self) -> usize {
        self.views.len()
    }

    fn residual_len(&self) -> usize {
        4 * self.object.len()
    }

    fn residuals(&self, shared: &[f64], own: &[f64], view: usize, out: &mut [f64]) {
        let left = camera_from_params(&shared[..INTRINSICS_LEN], self.width, self.height, self.k3_free);
        let right =
            camera_from_params(&shared[INTRINSICS_LEN..2 * INTRINSICS_LEN], self.width, self.height, self.k3_free);
        let view = self.views[view];
        let own_pose = pose_from_params(own);
        let (left_out, right_out) = out.split_at_mut(2 * self.object.len());
        match &view.left {
            Some(corners) => reprojection_residuals(&left, &own_pose, self.object, corners, left_out),
            None => left_out.fill(0.0),
        }
        match &view.right {
            // The pose is in the left frame when the left camera saw the view too.
            Some(corners) if view.left.is_some() => {
                let t_right_left = pose_from_params(&shared[2 * INTRINSICS_LEN..]);
                reprojection_residuals(&right, &(t_right_left * own_pose), self.object, corners, right_out);
            }
            Some(corners) => reprojection_residuals(&right, &own_pose, self.object, corners, right_out),
            None => right_out.fill(0.0),
        }
    }

    fn typical_magnitudes(&self, x: &DVector<f64>) -> DVector<f64> {
        let mut typical = DVector::zeros(x.len());
        let (x, out) = (x.as_slice(), typical.as_mut_slice());
        intrinsics_typical(&x[..INTRINSICS_LEN], &mut out[..INTRINSICS_LEN]);
        intrinsics_typical(&x[INTRINSICS_LEN..2 * INTRINSICS_LEN], &mut out[INTRINSICS_LEN..2 * INTRINSICS_LEN]);
        for (p, o) in
            x[2 * INTRINSICS_LEN..].chunks_exact(POSE_LEN).zip(out[2 * INTRINSICS_LEN..].chunks_exact_mut(POSE_LEN))
        {
            pose_typical(p, o);
        }
        typical
    }

    fn canonicalise(&self, x: &mut DVector<f64>) {
        x.as_mut_slice()[2 * INTRINSICS_LEN..].chunks_exact_mut(POSE_LEN).for_each(wrap_rotation);
    }
}

/// Refines both cameras, the stereo pose and the board poses of `start` jointly by the
/// reprojection error of every corner each camera saw; returns the fit and its sum of
/// squared residuals, px².
pub(super) fn refine_stereo(problem: &StereoProblem<'_>, start: &StereoFit) -> Result<(StereoFit, f64)> {
    let mut x = problem.params(start);
    lm::minimise(problem, &mut x, "stereo pair")?;
    let mut residuals = DVector::zeros(problem.residual_len() * problem.view_count());
    let cost = lm::evaluate(problem, &x, &mut residuals);
    Ok((problem.fit(&x), cost))
}

/// Residuals (two per corner and camera seen) and parameters of `problem`: what a test of
/// one model against a richer one needs for its degrees of freedom.
pub(super) fn degrees_of_freedom(problem: &StereoProblem<'_>) -> (usize, usize) {
    let sides: usize = problem.views.iter().map(|v| v.left.is_some() as usize + v.right.is_some() as usize).sum();
    (2 * problem.object.len() * sides, STEREO_SHARED_LEN + POSE_LEN * problem.views.len())
}
