//! Zhang's closed-form start for one camera: a normalised-DLT homography per view, the
//! intrinsic matrix (zero skew) from all homographies, and each view's board pose from its
//! homography. Distortion is ignored here; the refinement estimates it.

use nalgebra::{DMatrix, DVector, Isometry3, Matrix3, Point2, Point3, Rotation3, Translation3, UnitQuaternion};

use crate::error::{Error, ErrorKind, Result};

/// Below this ratio of the second-smallest to the largest singular value, Zhang's system has
/// more than one solution: the boards are parallel to the image, which leaves the focal
/// length undetermined. Boards tilted at random by up to 10° give ratios above 4e-3, up to 40°
/// near 0.1; boards parallel to an undistorted image give rounding-level ratios. Distortion
/// makes parallel boards look slightly tilted (ratios near 2e-3): those fail the focal-length
/// check instead.
const MIN_ZHANG_CONDITION: f64 = 1e-3;

/// Below this ratio of the second-smallest to the largest singular value, a view's corners
/// do not fix a homography (they are collinear or coincide).
const MIN_DLT_CONDITION: f64 = 1e-9;

/// A camera's closed-form intrinsic matrix and the board pose of each view (board frame ->
/// camera frame).
pub(super) struct ZhangStart {
    pub k: Matrix3<f64>,
    pub t_camera_board: Vec<Isometry3<f64>>,
}

/// The closed-form start of one camera from its corners in every view it saw; `view_indices`
/// holds those views' input indices and `camera` names the camera, both for messages.
pub(super) fn zhang_start(
    object: &[Point3<f64>],
    corners: &[&[Point2<f64>]],
    view_indices: &[usize],
    width: usize,
    height: usize,
    camera: &str,
) -> Result<ZhangStart> {
    let board_xy: Vec<Point2<f64>> = object.iter().map(|p| Point2::new(p.x, p.y)).collect();
    let homographies = corners
        .iter()
        .zip(view_indices)
        .map(|(pixels, index)| {
            homography(&board_xy, pixels).ok_or_else(|| {
                Error::new(
                    ErrorKind::Calibration,
                    format!(
                        "calibration view {index} {camera}: the corners do not fix a homography; expected corners \
                         spread over the image as a chessboard's are"
                    ),
                )
            })
        })
        .collect::<Result<Vec<_>>>()?;
    let k = intrinsics(&homographies, width, height, camera)?;
    let t_camera_board = homographies.iter().map(|h| board_pose(&k, h)).collect();
    Ok(ZhangStart { k, t_camera_board })
}

/// The similarity that moves `points` to their centroid and scales their mean distance from
/// it to √2 (Hartley's normalisation, which makes the DLT well conditioned).
fn normalising_transform(points: &[Point2<f64>]) -> Matrix3<f64> {
    let n = points.len() as f64;
    let centroid = points.iter().fold(nalgebra::Vector2::zeros(), |acc, p| acc + p.coords) / n;
    let mean_distance = points.iter().map(|p| (p.coords - centroid).norm()).sum::<f64>() / n;
    let s = if mean_distance > 0.0 { std::f64::consts::SQRT_2 / mean_distance } else { 1.0 };
    Matrix3::new(s, 0.0, -s * centroid.x, 0.0, s, -s * centroid.y, 0.0, 0.0, 1.0)
}

/// The right singular vector of `a`'s smallest singular value and the ratio of the
/// second-smallest singular value to the largest (how well that vector is determined).
fn null_vector(a: DMatrix<f64>) -> Option<(DVector<f64>, f64)> {
    let cols = a.ncols();
    // A thin SVD of a wide matrix leaves the null space out: pad to square.
    let a = if a.nrows() < cols { a.resize_vertically(cols, 0.0) } else { a };
    let svd = nalgebra::SVD::try_new(a, false, true, f64::EPSILON, 0)?;
    let v_t = svd.v_t?;
    let s = &svd.singular_values;
    let (largest, second_smallest) = (s[0], s[cols - 2]);
    if !(largest > 0.0 && largest.is_finite()) {
        return None;
    }
    Some((v_t.row(cols - 1).transpose(), second_smallest / largest))
}

/// The homography from board-plane points (mm) to pixels by the normalised DLT.
pub(super) fn homography(board_xy: &[Point2<f64>], pixels: &[Point2<f64>]) -> Option<Matrix3<f64>> {
    let t_board = normalising_transform(board_xy);
    let t_pixel = normalising_transform(pixels);
    let mut a = DMatrix::zeros(2 * board_xy.len(), 9);
    for (i, (b, p)) in board_xy.iter().zip(pixels).enumerate() {
        let b = t_board.transform_point(b);
        let p = t_pixel.transform_point(p);
        let (x, y, u, v) = (b.x, b.y, p.x, p.y);
        a.row_mut(2 * i).copy_from_slice(&[x, y, 1.0, 0.0, 0.0, 0.0, -u * x, -u * y, -u]);
        a.row_mut(2 * i + 1).copy_from_slice(&[0.0, 0.0, 0.0, x, y, 1.0, -v * x, -v * y, -v]);
    }
    let (h, condition) = null_vector(a)?;
    if condition < MIN_DLT_CONDITION {
        return None;
    }
    let normalised = Matrix3::from_row_slice(h.as_slice());
    let h = t_pixel.try_inverse()? * normalised * t_board;
    h.iter().all(|v| v.is_finite()).then_some(h)
}

/// Zhang's constraint row for columns `i`, `j` of a homography, over the zero-skew unknowns
/// b = (B11, B22, B13, B23, B33) of B = K^-T K^-1.
fn zhang_row(h: &Matrix3<f64>, i: usize, j: usize) -> [f64; 5] {
    let (hi, hj) = (h.column(i), h.column(j));
    [hi[0] * hj[0], hi[1] * hj[1], hi[2] * hj[0] + hi[0] * hj[2], hi[2] * hj[1] + hi[1] * hj[2], hi[2] * hj[2]]
}

/// The zero-skew intrinsic matrix from all views' homographies (Zhang's closed form).
fn intrinsics(homographies: &[Matrix3<f64>], width: usize, height: usize, camera: &str) -> Result<Matrix3<f64>> {
    // Solve for K' with K = K0 K' and a rough K0: homographies in pixels have entries from 1
    // to 1e6, which leaves the system badly conditioned. K0's zero skew keeps K' zero-skew.
    let f0 = (width + height) as f64 / 2.0;
    let k0 = Matrix3::new(f0, 0.0, (width as f64 - 1.0) / 2.0, 0.0, f0, (height as f64 - 1.0) / 2.0, 0.0, 0.0, 1.0);
    let k0_inv = k0.try_inverse().expect("K0 has a positive focal length");
    let mut v = DMatrix::zeros(2 * homographies.len(), 5);
    for (i, h) in homographies.iter().enumerate() {
        let h = k0_inv * h;
        let h = h / h.norm();
        let (v12, v11, v22) = (zhang_row(&h, 0, 1), zhang_row(&h, 0, 0), zhang_row(&h, 1, 1));
        v.row_mut(2 * i).copy_from_slice(&v12);
        v.row_mut(2 * i + 1).copy_from_slice(&std::array::from_fn::<f64, 5, _>(|c| v11[c] - v22[c]));
    }
    let degenerate = |symptom: &str| {
        Error::new(
            ErrorKind::Calibration,
            format!(
                "calibration {camera} camera: {symptom}, as boards parallel to the image give; expected boards \
                 tilted by 10° or more in different directions"
            ),
        )
    };
    let undetermined = || degenerate("the views do not determine the focal length");
    let (b, condition) = null_vector(v).ok_or_else(undetermined)?;
    if condition < MIN_ZHANG_CONDITION {
        return Err(undetermined());
    }
    let [b11, b22, b13, b23, b33] = [b[0], b[1], b[2], b[3], b[4]];
    let (u0, v0) = (-b13 / b11, -b23 / b22);
    // b is K'^-T K'^-1 up to a scale of unknown sign; `scale` recovers it.
    let scale = b33 - b13 * b13 / b11 - b23 * b23 / b22;
    let (alpha_sq, beta_sq) = (scale / b11, scale / b22);
    if !(alpha_sq > 0.0 && beta_sq > 0.0 && alpha_sq.is_finite() && beta_sq.is_finite()) {
        return Err(degenerate("the closed form gives a non-positive focal length"));
    }
    let k_prime = Matrix3::new(alpha_sq.sqrt(), 0.0, u0, 0.0, beta_sq.sqrt(), v0, 0.0, 0.0, 1.0);
    Ok(k0 * k_prime)
}

/// The board pose (board frame -> camera frame) of homography `h` under intrinsics `k`, its
/// rotation the nearest one to the homography's columns.
pub(super) fn board_pose(k: &Matrix3<f64>, h: &Matrix3<f64>) -> Isometry3<f64> {
    let m = k.try_inverse().expect("K has positive focal lengths") * h;
    let mut s = 2.0 / (m.column(0).norm() + m.column(1).norm());
    // The board lies in front of the camera.
    if m[(2, 2)] < 0.0 {
        s = -s;
    }
    let r1 = m.column(0) * s;
    let r2 = m.column(1) * s;
    let r3 = r1.cross(&r2);
    let r = Matrix3::from_columns(&[r1, r2, r3]);
    let svd = r.svd(true, true);
    let (u, v_t) = (svd.u.expect("u requested"), svd.v_t.expect("v_t requested"));
    let mut rotation = u * v_t;
    if rotation.determinant() < 0.0 {
        rotation = u * Matrix3::from_diagonal(&nalgebra::Vector3::new(1.0, 1.0, -1.0)) * v_t;
    }
    let translation = m.column(2) * s;
    Isometry3::from_parts(
        Translation3::from(translation),
        UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(rotation)),
    )
}
