//! The calibration error of a scenario: the rig the estimator is given is the rig that took
//! the images moved by a small rigid error drawn per scenario — the whole rig in the world
//! (the table calibration: a rotation about the midpoint of the camera centres and a
//! translation) and the right camera relative to the left (the stereo calibration: a
//! rotation about the right camera's centre and a translation in its frame). Each component
//! is normal with the cell's standard deviation per axis, drawn from a stream of its own.

use camplace_config::{Cell, Effect};
use camplace_estimator::Rig;
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::seeds::calibration_key;

/// One scenario's calibration error.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigError {
    /// Rotation vector of the whole rig about the midpoint of its camera centres, rad.
    pub world_rotation: Vector3<f64>,
    /// Translation of the whole rig, world mm.
    pub world_translation: Vector3<f64>,
    /// Rotation vector of the right camera about its centre, in its own frame, rad.
    pub stereo_rotation: Vector3<f64>,
    /// Translation of the right camera, in its own frame, mm.
    pub stereo_translation: Vector3<f64>,
}

/// The calibration error of scenario `index` of `seed`, `None` when the cell has none.
pub fn draw_rig_error(cell: &Cell, seed: u64, index: u64) -> Option<RigError> {
    if !cell.effect_active(Effect::CalibrationError) {
        return None;
    }
    let c = &cell.calibration_error;
    let mut rng = ChaCha8Rng::seed_from_u64(calibration_key(seed, index));
    let mut normal3 = |sigma: f64| Vector3::from_fn(|_, _| sigma * standard_normal(&mut rng));
    Some(RigError {
        world_rotation: normal3(c.rotation.to_radians()),
        world_translation: normal3(c.translation),
        stereo_rotation: normal3(c.stereo_rotation.to_radians()),
        stereo_translation: normal3(c.stereo_translation),
    })
}

/// A standard normal draw (Box–Muller).
fn standard_normal(rng: &mut ChaCha8Rng) -> f64 {
    // 1 - u lies in (0, 1], so its logarithm is finite.
    let u: f64 = 1.0 - rng.random::<f64>();
    let v: f64 = rng.random::<f64>();
    (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
}

impl RigError {
    /// `rig` moved by this error: what a calibration this far off would report.
    pub fn apply(&self, rig: &Rig) -> Rig {
        let centre = (rig.left.centre().coords + rig.right.centre().coords) / 2.0;
        let world = Translation3::from(centre + self.world_translation)
            * UnitQuaternion::from_scaled_axis(self.world_rotation)
            * Translation3::from(-centre);
        let stereo = Isometry3::new(self.stereo_translation, self.stereo_rotation);
        let mut out = rig.clone();
        out.left.t_world_camera = world * rig.left.t_world_camera;
        out.right.t_world_camera = world * rig.right.t_world_camera * stereo;
        if let (Some(p), Some(q)) = (&mut out.projector, &rig.projector) {
            p.t_world_camera = world * q.t_world_camera;
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use camplace_estimator::geometry::sensor_rig;
    use nalgebra::Point3;

    /// The RMS displacement, pixels, of `point`'s projection in the left (or right) camera
    /// between the true rig and the rigs of `n` scenarios' errors.
    fn rms_shift(cell: &Cell, point: Point3<f64>, right: bool, n: u64) -> f64 {
        let rig = sensor_rig(cell, &cell.placement);
        let cam = |r: &Rig| if right { r.right.clone() } else { r.left.clone() };
        let truth = cam(&rig).project(&point).unwrap();
        let sum: f64 = (0..n)
            .map(|i| {
                let believed = draw_rig_error(cell, 3, i).unwrap().apply(&rig);
                (cam(&believed).project(&point).unwrap() - truth).norm_squared()
            })
            .sum();
        (sum / n as f64).sqrt()
    }

    fn cell_with(rotation: f64, translation: f64, stereo_rotation: f64, stereo_translation: f64) -> Cell {
        Cell {
            calibration_error: camplace_config::CalibrationError {
                rotation,
                translation,
                stereo_rotation,
                stereo_translation,
            },
            ..Cell::default()
        }
    }

    #[test]
    fn perturbed_rigs_move_reprojected_points_by_the_expected_amount() {
        let origin = Point3::origin();
        let n = 3000;
        let base = Cell::default();
        let rig = sensor_rig(&base, &base.placement);
        let fx = rig.left.k[(0, 0)];
        let left_in_cam = rig.left.t_world_camera.inverse() * origin;
        let z = left_in_cam.z;
        // A rotation ω about the rigs' midpoint c moves a point p seen near the axis by
        // |ω x (p - c)| across the view: fx |p - c| / z pixels per radian of ω across the
        // ray, two axes of σ each.
        let c = (rig.left.centre().coords + rig.right.centre().coords) / 2.0;
        let sigma = 0.1f64.to_radians();
        let want = fx * (origin.coords - c).norm() / z * sigma * 2f64.sqrt();
        let got = rms_shift(&cell_with(0.1, 0.0, 0.0, 0.0), origin, false, n);
        assert!((got / want - 1.0).abs() < 0.05, "rig rotation: {got:.3} px vs {want:.3} px");
        // A translation t moves it by fx |t across| / z.
        let want = fx * 2.0 / z * 2f64.sqrt();
        let got = rms_shift(&cell_with(0.0, 2.0, 0.0, 0.0), origin, false, n);
        assert!((got / want - 1.0).abs() < 0.05, "rig translation: {got:.3} px vs {want:.3} px");
        // The stereo error leaves the left camera alone and turns the right one about its
        // centre: fx per radian.
        assert_eq!(rms_shift(&cell_with(0.0, 0.0, 0.1, 0.0), origin, false, 20), 0.0);
        let want = fx * sigma * 2f64.sqrt();
        let got = rms_shift(&cell_with(0.0, 0.0, 0.1, 0.0), origin, true, n);
        assert!((got / want - 1.0).abs() < 0.05, "stereo rotation: {got:.3} px vs {want:.3} px");
    }

    #[test]
    fn no_error_when_off_and_the_same_error_for_the_same_scenario() {
        let mut cell = Cell::default();
        assert_eq!(draw_rig_error(&cell, 1, 4), draw_rig_error(&cell, 1, 4));
        assert_ne!(draw_rig_error(&cell, 1, 4), draw_rig_error(&cell, 1, 5));
        cell.effects.calibration_error = false;
        assert_eq!(draw_rig_error(&cell, 1, 4), None);
    }
}
