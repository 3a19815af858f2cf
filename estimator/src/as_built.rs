//! The placement a rig is really mounted at, read back from its camera poses (a calibrated
//! `rig.json`): the inverse of [`rig_for`](super::placement_rig::rig_for). The rig origin
//! is the midpoint of the camera centres; r, alpha and azimuth place it, the baseline is
//! the distance between the centres, and each camera's toe-in is its optical axis turned
//! towards the other camera. What a placement cannot express — the rig not aimed at the
//! table's centre, a baseline not level, unequal toe-ins — is measured beside it.

use crate::Rig;
use camplace_config::{Placement, Vergence};
use nalgebra::Vector3;

/// A rig's pose as a placement, and how it departs from what a placement can express.
#[derive(Debug, Clone, PartialEq)]
pub struct AsBuilt {
    /// r, alpha, baseline, azimuth, and the vergence as the mean of the two toe-ins.
    pub placement: Placement,
    /// Each camera's toe-in, left and right, deg (positive: turned towards the other).
    pub toe_in: [f64; 2],
    /// Angle between where the rig looks (the mean of its optical axes) and the table's
    /// centre, seen from the rig origin, deg.
    pub aim_error: f64,
    /// Where the rig's viewing direction meets the table plane, mm (none if it looks up).
    pub aim_point: Option<[f64; 2]>,
    /// The baseline's slope against the horizontal, deg.
    pub baseline_tilt: f64,
}

/// Reads the placement back from `rig`'s cameras; an error when the cameras coincide or
/// the rig sits at the world origin.
pub fn as_built(rig: &Rig) -> Result<AsBuilt, String> {
    let (cl, cr) = (rig.left.t_world_camera.translation.vector, rig.right.t_world_camera.translation.vector);
    let origin = (cl + cr) / 2.0;
    let baseline = (cr - cl).norm();
    let r = origin.norm();
    if !(baseline > 1e-6 && r > 1e-6) {
        return Err(format!(
            "expected two cameras apart and away from the world origin; their centres are {baseline:.3} mm apart, their midpoint {r:.3} mm from the origin"
        ));
    }
    let x = (cr - cl) / baseline;
    let alpha = origin.xy().norm().atan2(origin.z).to_degrees();
    // The rig frame's x axis is (-sin φ, cos φ, 0): straight above the table that alone
    // gives the azimuth.
    let azimuth = if origin.xy().norm() > 1e-9 * r { origin.y.atan2(origin.x) } else { (-x.x).atan2(x.y) }.to_degrees();
    let axis = |t: &nalgebra::Isometry3<f64>| t.rotation * Vector3::z();
    let (al, ar) = (axis(&rig.left.t_world_camera), axis(&rig.right.t_world_camera));
    let toe_in = [al.dot(&x).clamp(-1.0, 1.0).asin().to_degrees(), -ar.dot(&x).clamp(-1.0, 1.0).asin().to_degrees()];
    let mean = al + ar;
    let looking = (mean - x * mean.dot(&x)).normalize();
    // atan2 of sine and cosine: exact near zero, where acos is not.
    let to_centre = -origin / r;
    let aim_error = looking.cross(&to_centre).norm().atan2(looking.dot(&to_centre)).to_degrees();
    let aim_point = (looking.z < -1e-9).then(|| {
        let t = -origin.z / looking.z;
        [origin.x + t * looking.x, origin.y + t * looking.y]
    });
    let placement =
        Placement { r, alpha, baseline, vergence: Vergence::Degrees((toe_in[0] + toe_in[1]) / 2.0), azimuth };
    Ok(AsBuilt { placement, toe_in, aim_error, aim_point, baseline_tilt: x.z.clamp(-1.0, 1.0).asin().to_degrees() })
}

/// The smallest difference between two azimuths, deg, in (-180, 180].
pub fn azimuth_difference(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(360.0);
    if d > 180.0 {
        d - 360.0
    } else {
        d
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::placement_rig::rig_for;
    use camplace_config::Cell;
    use nalgebra::{Isometry3, Translation3, UnitQuaternion};

    #[test]
    fn a_rendered_rig_gives_back_its_placement_everywhere() {
        let sensor = Cell::default().sensor;
        // A deterministic walk over the whole placement box, straight above included.
        for i in 0..500u32 {
            let f = |k: u32, lo: f64, hi: f64| lo + (hi - lo) * ((i * k + 7) % 101) as f64 / 100.0;
            let p = Placement {
                r: f(13, 300.0, 1500.0),
                alpha: if i % 25 == 0 { 0.0 } else { f(29, 0.0, 80.0) },
                baseline: f(41, 20.0, 300.0),
                vergence: if i % 3 == 0 { Vergence::Auto } else { Vergence::Degrees(f(53, 0.0, 12.0)) },
                azimuth: f(67, -179.0, 180.0),
            };
            let b = as_built(&rig_for(&p, &sensor)).unwrap();
            let q = b.placement;
            let verg = p.vergence.degrees(p.r, p.baseline);
            assert!((q.r - p.r).abs() < 1e-6 && (q.baseline - p.baseline).abs() < 1e-6, "{p} -> {q}");
            assert!((q.alpha - p.alpha).abs() < 1e-6, "{p} -> {q}");
            assert!(azimuth_difference(q.azimuth, p.azimuth).abs() < 1e-6, "{p} -> {q}");
            assert!((q.vergence.degrees(q.r, q.baseline) - verg).abs() < 1e-6, "{p} -> {q}");
            assert!((b.toe_in[0] - verg).abs() < 1e-6 && (b.toe_in[1] - verg).abs() < 1e-6);
            assert!(b.aim_error < 1e-6 && b.baseline_tilt.abs() < 1e-6, "{p}: {b:?}");
            let [ax, ay] = b.aim_point.unwrap();
            assert!(ax.abs() < 1e-6 && ay.abs() < 1e-6);
        }
    }

    #[test]
    fn a_mis_mounted_rig_shows_what_is_off() {
        let sensor = Cell::default().sensor;
        let p = Placement { r: 605.0, alpha: 32.0, baseline: 81.0, vergence: Vergence::Degrees(3.5), azimuth: 0.0 };
        // The whole rig turned 2° about its own baseline (its x axis), as a loose bracket would.
        let mut rig = rig_for(&p, &sensor);
        let mid = (rig.left.centre().coords + rig.right.centre().coords) / 2.0;
        let x = (rig.right.centre() - rig.left.centre()).normalize();
        let turn = UnitQuaternion::from_axis_angle(&nalgebra::Unit::new_normalize(x), 2f64.to_radians());
        let about_mid =
            Translation3::from(mid) * Isometry3::from_parts(Translation3::identity(), turn) * Translation3::from(-mid);
        for cam in [&mut rig.left, &mut rig.right] {
            cam.t_world_camera = about_mid * cam.t_world_camera;
        }
        let b = as_built(&rig).unwrap();
        assert!((b.aim_error - 2.0).abs() < 1e-6, "{b:?}");
        assert!((b.placement.alpha - 32.0).abs() < 1e-9 && (b.placement.r - 605.0).abs() < 1e-9);
        // Seen from 605 mm at 32°, 2° off aims about 605·tan 2° / cos 32° ≈ 25 mm along the table.
        let [ax, ay] = b.aim_point.unwrap();
        let along = (ax * ax + ay * ay).sqrt();
        assert!((20.0..30.0).contains(&along), "{along}");
        // One camera turned alone: unequal toe-ins, their mean the vergence.
        let mut rig = rig_for(&p, &sensor);
        let y = rig.left.t_world_camera.rotation * Vector3::y_axis();
        rig.left.t_world_camera.rotation =
            UnitQuaternion::from_axis_angle(&y, 1f64.to_radians()) * rig.left.t_world_camera.rotation;
        let b = as_built(&rig).unwrap();
        assert!((b.toe_in[0] - 4.5).abs() < 1e-6 && (b.toe_in[1] - 3.5).abs() < 1e-6, "{b:?}");
        assert!((b.placement.vergence.degrees(605.0, 81.0) - 4.0).abs() < 1e-6);
        assert!(as_built(&Rig { right: rig.left.clone(), ..rig.clone() }).is_err());
    }

    #[test]
    fn azimuths_differ_by_the_short_way_round() {
        assert_eq!(azimuth_difference(170.0, -170.0), -20.0);
        assert_eq!(azimuth_difference(-170.0, 170.0), 20.0);
        assert_eq!(azimuth_difference(10.0, 370.0), 0.0);
    }
}
