//! The geometry of a placement (docs/design/units-and-frames.md): where the two cameras and the projector
//! sit and look for given (r, alpha, baseline, vergence, azimuth), as a calibrated rig.

use crate::{Camera, Rig};
use camplace_config::{Cell, Placement, Sensor};
use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};

/// The rig frame in the world: origin at the midpoint of the camera centres, z towards
/// the world origin, x (the baseline) horizontal, y = z × x.
pub fn rig_pose(p: &Placement) -> Isometry3<f64> {
    let (a, phi) = (p.alpha.to_radians(), p.azimuth.to_radians());
    let eye = Point3::new(p.r * a.sin() * phi.cos(), p.r * a.sin() * phi.sin(), p.r * a.cos());
    let z = -eye.coords.normalize();
    // Horizontal x chosen so that image "down" points towards the near side of the table;
    // it is also well defined straight above (alpha = 0).
    let x = Vector3::new(-phi.sin(), phi.cos(), 0.0);
    let y = z.cross(&x);
    frame(eye, x, y, z)
}

/// A camera frame looking from `eye` at `target` with a horizontal x axis.
pub fn look_at(eye: Point3<f64>, target: Point3<f64>, azimuth_deg: f64) -> Isometry3<f64> {
    let z = (target - eye).normalize();
    let up = Vector3::z();
    let mut x = z.cross(&up);
    if x.norm() < 1e-9 {
        let phi = azimuth_deg.to_radians();
        x = Vector3::new(-phi.sin(), phi.cos(), 0.0);
    }
    let x = x.normalize();
    let y = z.cross(&x);
    frame(eye, x, y, z)
}

fn frame(origin: Point3<f64>, x: Vector3<f64>, y: Vector3<f64>, z: Vector3<f64>) -> Isometry3<f64> {
    let r = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x, y, z]));
    Isometry3::from_parts(Translation3::from(origin.coords), UnitQuaternion::from_rotation_matrix(&r))
}

/// Camera matrix of the sensor's cameras (the full K if given, else from the field of view).
pub fn camera_k(sensor: &Sensor) -> Matrix3<f64> {
    let [w, h] = sensor.camera_resolution;
    if sensor.camera_k.len() == 3 {
        let k = &sensor.camera_k;
        return Matrix3::from_fn(|r, c| k[r][c]);
    }
    let f = Camera::focal_from_hfov(w as usize, sensor.camera_hfov);
    Matrix3::new(f, 0.0, (w as f64 - 1.0) / 2.0, 0.0, f, (h as f64 - 1.0) / 2.0, 0.0, 0.0, 1.0)
}

/// The rig a simulation of `cell` at `placement` renders with: the cell's installed rig
/// (`[rig]`, a calibration) when it has one — its projector, when the calibration has none,
/// where `placement` puts it relative to the left camera — else the placement's own.
pub fn sensor_rig(cell: &Cell, placement: &Placement) -> Rig {
    let planned = rig_for(placement, &cell.sensor);
    let Some(file) = &cell.rig else { return planned };
    let mut rig = Rig::from_file(file);
    if rig.projector.is_none() {
        if let Some(projector) = planned.projector {
            let t_left_projector = planned.left.t_world_camera.inverse() * projector.t_world_camera;
            rig.projector = Some(Camera { t_world_camera: rig.left.t_world_camera * t_left_projector, ..projector });
        }
    }
    rig
}

/// The calibrated rig (cameras and projector) of a placement.
pub fn rig_for(p: &Placement, sensor: &Sensor) -> Rig {
    let t_world_rig = rig_pose(p);
    let verg = p.vergence.degrees(p.r, p.baseline).to_radians();
    let [w, h] = sensor.camera_resolution;
    let k = camera_k(sensor);
    let camera = |side: f64| {
        // Toe-in: the left camera (side -1) turns towards +x, the right one towards -x,
        // each about its own y axis.
        let t_rig_cam = Isometry3::from_parts(
            Translation3::new(side * p.baseline / 2.0, 0.0, 0.0),
            UnitQuaternion::from_axis_angle(&Vector3::y_axis(), -side * verg),
        );
        Camera {
            width: w as usize,
            height: h as usize,
            k,
            dist: sensor.camera_dist,
            t_world_camera: t_world_rig * t_rig_cam,
        }
    };
    let off = Vector3::from(sensor.projector_offset);
    let proj_eye = t_world_rig.transform_point(&Point3::from(off));
    let t_world_proj = look_at(proj_eye, Point3::origin(), p.azimuth);
    let [pw, ph] = sensor.projector_resolution;
    let pf = Camera::focal_from_hfov(pw as usize, sensor.projector_hfov);
    Rig {
        left: camera(-1.0),
        right: camera(1.0),
        projector: Some(Camera::ideal(pw as usize, ph as usize, pf, t_world_proj)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use camplace_config::{Cell, Vergence};

    fn placement(alpha: f64, verg: Vergence) -> Placement {
        Placement { r: 605.0, alpha, baseline: 81.0, vergence: verg, azimuth: 20.0 }
    }

    #[test]
    fn rig_looks_at_origin_with_horizontal_baseline() {
        for alpha in [0.0, 32.0, 60.0] {
            let t = rig_pose(&placement(alpha, Vergence::Auto));
            let z = t.rotation * Vector3::z();
            let x = t.rotation * Vector3::x();
            let to_origin = -t.translation.vector.normalize();
            assert!((z - to_origin).norm() < 1e-12);
            assert!(x.z.abs() < 1e-12);
            assert!((t.translation.vector.norm() - 605.0).abs() < 1e-9);
            // Image down is towards the table (world -z) or horizontal straight above.
            assert!((t.rotation * Vector3::y()).z <= 1e-12);
        }
    }

    #[test]
    fn auto_vergence_axes_meet_at_origin() {
        let cell = Cell::default();
        let rig = rig_for(&placement(32.0, Vergence::Auto), &cell.sensor);
        for cam in [&rig.left, &rig.right] {
            let c = cam.t_world_camera.inverse_transform_point(&Point3::origin());
            assert!(c.x.abs() < 1e-9 && c.y.abs() < 1e-9 && c.z > 0.0, "{c}");
        }
        assert!((rig.baseline() - 81.0).abs() < 1e-9);
    }

    #[test]
    fn vergence_turns_cameras_inward() {
        let cell = Cell::default();
        let rig = rig_for(&placement(32.0, Vergence::Degrees(3.5)), &cell.sensor);
        let zl = rig.left.t_world_camera.rotation * Vector3::z();
        let zr = rig.right.t_world_camera.rotation * Vector3::z();
        assert!((zl.angle(&zr).to_degrees() - 7.0).abs() < 1e-9);
        // The left camera's axis passes the rig's centre line to the right.
        let o = rig.left.t_world_camera.inverse_transform_point(&rig.right.centre());
        assert!(o.x > 0.0);
    }
}
