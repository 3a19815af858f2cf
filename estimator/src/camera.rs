//! The pinhole camera with OpenCV's distortion (k1 k2 p1 p2 k3) and its pose in the world:
//! projection of world points to pixels and back-projection of pixels to rays.

use camplace_config::CameraFile;
use nalgebra::{Isometry3, Matrix3, Matrix4, Point2, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};

/// One calibrated camera (or the projector, which is a camera run backwards).
#[derive(Debug, Clone, PartialEq)]
pub struct Camera {
    pub width: usize,
    pub height: usize,
    /// Intrinsic matrix K.
    pub k: Matrix3<f64>,
    /// k1 k2 p1 p2 k3 (OpenCV order).
    pub dist: [f64; 5],
    /// Camera frame -> world frame.
    pub t_world_camera: Isometry3<f64>,
}

impl Camera {
    /// A distortion-free camera from its size, focal length in pixels and pose; the
    /// principal point sits at the image centre (pixel centres are at integer coordinates).
    pub fn ideal(width: usize, height: usize, focal_px: f64, t_world_camera: Isometry3<f64>) -> Self {
        let k = Matrix3::new(
            focal_px,
            0.0,
            (width as f64 - 1.0) / 2.0,
            0.0,
            focal_px,
            (height as f64 - 1.0) / 2.0,
            0.0,
            0.0,
            1.0,
        );
        Camera { width, height, k, dist: [0.0; 5], t_world_camera }
    }

    /// Focal length in pixels from a horizontal field of view in degrees.
    pub fn focal_from_hfov(width: usize, hfov_deg: f64) -> f64 {
        (width as f64 / 2.0) / (hfov_deg.to_radians() / 2.0).tan()
    }

    /// The camera of a `rig.json` entry.
    pub fn from_file(f: &CameraFile) -> Self {
        let k = Matrix3::from_fn(|r, c| f.k[r][c]);
        let m = Matrix4::from_fn(|r, c| f.t_world_camera[r][c]);
        Camera {
            width: f.width as usize,
            height: f.height as usize,
            k,
            dist: f.dist,
            t_world_camera: isometry_from_matrix(&m),
        }
    }

    /// The `rig.json` entry of this camera.
    pub fn to_file(&self) -> CameraFile {
        let m = self.t_world_camera.to_homogeneous();
        CameraFile {
            width: self.width as u32,
            height: self.height as u32,
            k: std::array::from_fn(|r| std::array::from_fn(|c| self.k[(r, c)])),
            dist: self.dist,
            t_world_camera: std::array::from_fn(|r| std::array::from_fn(|c| m[(r, c)])),
        }
    }

    /// Whether the distortion is zero.
    pub fn is_ideal(&self) -> bool {
        self.dist.iter().all(|&d| d == 0.0)
    }

    /// Applies the distortion to normalised coordinates (x/z, y/z).
    pub fn distort(&self, x: f64, y: f64) -> (f64, f64) {
        let [k1, k2, p1, p2, k3] = self.dist;
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
        let xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
        let yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
        (xd, yd)
    }

    /// Removes the distortion from normalised coordinates (fixed-point iteration, as
    /// OpenCV's undistortPoints does).
    pub fn undistort(&self, xd: f64, yd: f64) -> (f64, f64) {
        if self.is_ideal() {
            return (xd, yd);
        }
        let (mut x, mut y) = (xd, yd);
        for _ in 0..20 {
            let (dx, dy) = self.distort(x, y);
            x -= dx - xd;
            y -= dy - yd;
        }
        (x, y)
    }

    /// Pixel of a point given in this camera's frame; `None` behind the camera.
    pub fn project_camera(&self, p: &Point3<f64>) -> Option<Point2<f64>> {
        if p.z <= 1e-9 {
            return None;
        }
        let (x, y) = self.distort(p.x / p.z, p.y / p.z);
        let k = &self.k;
        Some(Point2::new(k[(0, 0)] * x + k[(0, 1)] * y + k[(0, 2)], k[(1, 1)] * y + k[(1, 2)]))
    }

    /// Pixel of a world point; `None` behind the camera.
    pub fn project(&self, p_world: &Point3<f64>) -> Option<Point2<f64>> {
        self.project_camera(&self.t_world_camera.inverse_transform_point(p_world))
    }

    /// Unit-depth ray (x, y, 1) in the camera frame through pixel (u, v).
    pub fn ray(&self, u: f64, v: f64) -> Vector3<f64> {
        let k = &self.k;
        let yd = (v - k[(1, 2)]) / k[(1, 1)];
        let xd = (u - k[(0, 2)] - k[(0, 1)] * yd) / k[(0, 0)];
        let (x, y) = self.undistort(xd, yd);
        Vector3::new(x, y, 1.0)
    }

    /// World point at depth `z_mm` (along the camera's z axis) behind pixel (u, v).
    pub fn back_project(&self, u: f64, v: f64, z_mm: f64) -> Point3<f64> {
        let p = self.ray(u, v) * z_mm;
        self.t_world_camera.transform_point(&Point3::from(p))
    }

    /// Camera centre in the world.
    pub fn centre(&self) -> Point3<f64> {
        Point3::from(self.t_world_camera.translation.vector)
    }
}

/// A rigid transform from a 4x4 matrix: the translation as it stands, the rotation the
/// nearest proper rotation to the upper-left 3x3 block (its polar factor, `U·diag(1, 1,
/// det(U·Vᵀ))·Vᵀ` from the block's SVD). The polar factor is closed in form, so a half turn
/// is the half turn it is; an iteration started at the identity (nalgebra's
/// `Rotation3::from_matrix`) has no gradient to leave it by for a turn of 180°, and read a
/// robot mounted upside down as a different rotation. Files' matrices are checked
/// orthonormal before they get here (`camplace_config::check_rigid`); the polar factor only
/// takes out their last digits' drift.
pub fn isometry_from_matrix(m: &Matrix4<f64>) -> Isometry3<f64> {
    let block = m.fixed_view::<3, 3>(0, 0).into_owned();
    Isometry3::from_parts(
        Translation3::new(m[(0, 3)], m[(1, 3)], m[(2, 3)]),
        UnitQuaternion::from_rotation_matrix(&nearest_rotation(&block)),
    )
}

/// The proper rotation nearest to `block` in the Frobenius norm (the orthogonal Procrustes
/// solution). A block whose SVD does not converge (not finite: every caller's block was
/// checked finite and orthonormal first) gives a rotation of not-a-numbers, so that the
/// transform is seen to be broken wherever it is used rather than passing for another.
fn nearest_rotation(block: &Matrix3<f64>) -> Rotation3<f64> {
    let finite = block.iter().all(|v| v.is_finite());
    let svd = finite.then(|| block.try_svd(true, true, f64::EPSILON, 1000)).flatten();
    let Some((u, v_t)) = svd.and_then(|s| Some((s.u?, s.v_t?))) else {
        return Rotation3::from_matrix_unchecked(Matrix3::from_element(f64::NAN));
    };
    let mut d = Matrix3::identity();
    if (u * v_t).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    Rotation3::from_matrix_unchecked(u * d * v_t)
}

/// A 4x4 row-major array of a rigid transform, as the JSON files store it.
pub fn isometry_to_rows(t: &Isometry3<f64>) -> [[f64; 4]; 4] {
    let m = t.to_homogeneous();
    std::array::from_fn(|r| std::array::from_fn(|c| m[(r, c)]))
}

/// A rigid transform from a 4x4 row-major array.
///
/// ```
/// use camplace_estimator::geometry::{isometry_from_rows, isometry_to_rows};
/// // A robot mounted upside down: its base turned half a turn about the world's y axis.
/// let rows = [[-1.0, 0.0, 0.0, 400.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, -1.0, 1800.0], [0.0, 0.0, 0.0, 1.0]];
/// let t = isometry_from_rows(&rows);
/// assert!((t.rotation.angle() - std::f64::consts::PI).abs() < 1e-12);
/// assert!((t.rotation.axis().unwrap().y.abs() - 1.0).abs() < 1e-12);
/// assert_eq!(isometry_to_rows(&t), rows);
/// ```
pub fn isometry_from_rows(rows: &[[f64; 4]; 4]) -> Isometry3<f64> {
    isometry_from_matrix(&Matrix4::from_fn(|r, c| rows[r][c]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn project_back_project_round_trip_with_distortion() {
        let mut cam = Camera::ideal(640, 480, 800.0, Isometry3::translation(10.0, -5.0, 600.0));
        cam.dist = [-0.2, 0.05, 0.001, -0.0005, 0.0];
        let p = Point3::new(30.0, -40.0, 0.0);
        // Camera looks along +z, point is in front only if z is larger: flip the pose.
        cam.t_world_camera = Isometry3::face_towards(&Point3::new(10.0, -5.0, 600.0), &Point3::origin(), &Vector3::y());
        let px = cam.project(&p).unwrap();
        let depth = cam.t_world_camera.inverse_transform_point(&p).z;
        let back = cam.back_project(px.x, px.y, depth);
        assert!((back - p).norm() < 1e-6, "{back} vs {p}");
    }

    #[test]
    fn half_turns_read_as_the_half_turns_they_are() {
        // Ry(180°), a robot mounted upside down, and the half turn about (0.26, -0.97, 0),
        // written as a file holds them: R = 2·n·nᵀ − I for the unit axis n, so the
        // entries of an axis's turn are exactly 0 and ±1.
        for axis in [Vector3::y(), Vector3::x(), Vector3::z(), Vector3::new(0.26, -0.97, 0.0)] {
            let n = axis.normalize();
            let mut m = Matrix4::identity();
            m.fixed_view_mut::<3, 3>(0, 0).copy_from(&(2.0 * n * n.transpose() - Matrix3::identity()));
            m.fixed_view_mut::<3, 1>(0, 3).copy_from(&Vector3::new(450.0, -120.0, 1800.0));
            let read = isometry_from_matrix(&m);
            let off = (read.to_homogeneous() - m).abs().max();
            assert!(off < 1e-12, "a half turn about {axis} read {off} off: {read:?}");
        }
    }

    #[test]
    fn a_matrix_off_a_rotation_reads_as_the_nearest_and_a_broken_one_as_broken() {
        let made = UnitQuaternion::from_euler_angles(0.3, -1.1, 2.9).to_rotation_matrix().into_inner();
        let mut m = Matrix4::identity();
        m.fixed_view_mut::<3, 3>(0, 0).copy_from(&(made * 1.000_001));
        let read = isometry_from_matrix(&m).rotation.to_rotation_matrix().into_inner();
        assert!((read - made).abs().max() < 1e-12, "{read} vs {made}");
        m[(1, 1)] = f64::NAN;
        assert!(isometry_from_matrix(&m).rotation.coords.iter().all(|v| v.is_nan()));
    }

    #[test]
    fn file_round_trip() {
        let cam = Camera::ideal(640, 480, 812.4, Isometry3::rotation(Vector3::new(0.1, 0.2, 0.3)));
        let back = Camera::from_file(&cam.to_file());
        assert!((back.t_world_camera.to_homogeneous() - cam.t_world_camera.to_homogeneous()).norm() < 1e-12);
        assert_eq!(back.k, cam.k);
    }
}
