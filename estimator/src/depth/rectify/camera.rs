//! The rectified stereo camera: the one pinhole camera K' both rectified images share, the
//! baseline along its x axis, and where it sits in the world. Disparity d = x_left -
//! x_right (rectified pixels) relates to depth z by z = fx * baseline / d.

use nalgebra::{Isometry3, Matrix3, Point3};

/// The shared rectified camera of a stereo pair (the rectified-left camera frame).
#[derive(Debug, Clone, PartialEq)]
pub struct RectifiedCamera {
    pub width: usize,
    pub height: usize,
    /// Shared K' (fx = fy, no skew).
    pub k: Matrix3<f64>,
    /// Distance between the camera centres along the rectified x axis, mm.
    pub baseline: f64,
    /// Rectified-left camera frame -> world.
    pub t_world_rectified: Isometry3<f64>,
}

impl RectifiedCamera {
    /// Focal length in pixels.
    #[inline]
    pub fn focal(&self) -> f64 {
        self.k[(0, 0)]
    }

    /// Depth (mm, along the rectified z axis) of disparity `d` (px); +inf for d <= 0.
    #[inline]
    pub fn depth_from_disparity(&self, d: f32) -> f32 {
        if d > 0.0 {
            (self.focal() * self.baseline) as f32 / d
        } else {
            f32::INFINITY
        }
    }

    /// Disparity (px) of a point at depth `z` (mm).
    #[inline]
    pub fn disparity_from_depth(&self, z: f32) -> f32 {
        (self.focal() * self.baseline) as f32 / z
    }

    /// Point in the rectified-left camera frame at pixel (u, v) with disparity `d`.
    #[inline]
    pub fn point_in_camera(&self, u: f64, v: f64, d: f64) -> Point3<f64> {
        let z = self.focal() * self.baseline / d;
        let k = &self.k;
        Point3::new((u - k[(0, 2)]) * z / k[(0, 0)], (v - k[(1, 2)]) * z / k[(1, 1)], z)
    }

    /// Rectified-left pixel (u, v) and disparity of a world point; `None` behind the camera.
    pub fn project(&self, p_world: &Point3<f64>) -> Option<(f64, f64, f64)> {
        let p = self.t_world_rectified.inverse_transform_point(p_world);
        if p.z <= 1e-9 {
            return None;
        }
        let k = &self.k;
        let u = k[(0, 0)] * p.x / p.z + k[(0, 2)];
        let v = k[(1, 1)] * p.y / p.z + k[(1, 2)];
        Some((u, v, self.focal() * self.baseline / p.z))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn project_and_back_agree() {
        let cam = RectifiedCamera {
            width: 640,
            height: 480,
            k: Matrix3::new(800.0, 0.0, 330.0, 0.0, 800.0, 240.0, 0.0, 0.0, 1.0),
            baseline: 81.0,
            t_world_rectified: Isometry3::translation(5.0, 6.0, 7.0),
        };
        let p = Point3::new(20.0, -30.0, 600.0);
        let (u, v, d) = cam.project(&p).unwrap();
        let back = cam.t_world_rectified.transform_point(&cam.point_in_camera(u, v, d));
        assert!((back - p).norm() < 1e-9);
        assert!((cam.depth_from_disparity(d as f32) - 593.0).abs() < 1e-3);
    }
}
