//! The paper's quality metrics of one pose estimate against the truth: position error, rotation
//! error, correct feature matches and success. Symmetry-aware, as the BOP benchmark is: a tray
//! that maps onto itself under a turn about its z axis is judged against the closest of its
//! equivalent poses. Collecting these over many scenes is the simulator's business.

use camplace_config::Metrics;
use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector3};

use crate::Correspondence;

/// How far an estimate is from the truth, and whether that counts as a success.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseErrors {
    /// Distance between the estimated and true tray origins, mm.
    pub position_mm: f64,
    /// Geodesic angle between the estimated rotation and the closest symmetric equivalent of
    /// the true one, deg.
    pub rotation_deg: f64,
    /// Position below `success_position` and rotation below `success_rotation`.
    pub success: bool,
}

/// Errors of `estimate` against `truth` (both `T_world_tray`), with the tray's symmetries
/// (turns about tray z, deg; the identity is implied).
pub fn pose_errors(
    estimate: &Isometry3<f64>,
    truth: &Isometry3<f64>,
    symmetries_deg: &[f32],
    metrics: &Metrics,
) -> PoseErrors {
    // The symmetry axis passes through the tray origin, so the position error needs no minimum.
    let position_mm = (estimate.translation.vector - truth.translation.vector).norm();
    let rotation_deg = rotation_error_deg(&estimate.rotation, &truth.rotation, symmetries_deg);
    let success = position_mm < metrics.success_position && rotation_deg < metrics.success_rotation;
    PoseErrors { position_mm, rotation_deg, success }
}

/// The smallest geodesic angle (deg) between `estimate` and `truth` turned by the identity or
/// any of `symmetries_deg` about the tray's z axis.
pub fn rotation_error_deg(estimate: &UnitQuaternion<f64>, truth: &UnitQuaternion<f64>, symmetries_deg: &[f32]) -> f64 {
    let gap = estimate.inverse() * truth;
    let mut best = gap.angle();
    for s in symmetries_deg {
        let turn = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), (*s as f64).to_radians());
        best = best.min((gap * turn).angle());
    }
    best.to_degrees()
}

/// Matches whose model feature, placed by the true pose (or a symmetric equivalent), lies
/// within `correct_match_mm` of its scene key point. Matches with out-of-range indices count
/// as wrong.
pub fn correct_matches(
    scene_keypoints: &[Point3<f32>],
    feature_points: &[Point3<f32>],
    correspondences: &[Correspondence],
    truth: &Isometry3<f64>,
    symmetries_deg: &[f32],
    correct_match_mm: f64,
) -> u32 {
    let limit2 = correct_match_mm * correct_match_mm;
    let mut truths = Vec::with_capacity(1 + symmetries_deg.len());
    truths.push(*truth);
    for s in symmetries_deg {
        truths.push(truth * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), (*s as f64).to_radians()));
    }
    let mut correct = 0;
    for c in correspondences {
        let (Some(scene), Some(feature)) =
            (scene_keypoints.get(c.scene as usize), feature_points.get(c.model as usize))
        else {
            continue;
        };
        let (scene, feature) = (scene.cast::<f64>(), feature.cast::<f64>());
        if truths.iter().any(|t| (t * feature - scene).norm_squared() <= limit2) {
            correct += 1;
        }
    }
    correct
}

#[cfg(test)]
mod tests {
    use super::*;
    use camplace_config::Cell;
    use nalgebra::{Matrix3, Rotation3};
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn random_pose(rng: &mut ChaCha8Rng) -> Isometry3<f64> {
        Isometry3::new(
            Vector3::new(rng.random_range(-200.0..200.0), rng.random_range(-200.0..200.0), rng.random_range(-5.0..5.0)),
            Vector3::new(rng.random_range(-0.2..0.2), rng.random_range(-0.2..0.2), rng.random_range(-3.1..3.1)),
        )
    }

    /// The angle of a rotation matrix from its trace, the textbook way.
    fn trace_angle_deg(r: &Matrix3<f64>) -> f64 {
        ((r.trace() - 1.0) / 2.0).clamp(-1.0, 1.0).acos().to_degrees()
    }

    #[test]
    fn rotation_error_agrees_with_the_trace_formula() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let symmetries = [90.0f32, 180.0, 270.0];
        for _ in 0..500 {
            let (a, b) = (random_pose(&mut rng), random_pose(&mut rng));
            let ra = a.rotation.to_rotation_matrix();
            let rb = b.rotation.to_rotation_matrix();
            let slow = std::iter::once(0.0)
                .chain(symmetries.iter().map(|s| *s as f64))
                .map(|s| {
                    let turn = Rotation3::from_axis_angle(&Vector3::z_axis(), s.to_radians());
                    trace_angle_deg((ra.inverse() * rb * turn).matrix())
                })
                .fold(f64::INFINITY, f64::min);
            let fast = rotation_error_deg(&a.rotation, &b.rotation, &symmetries);
            assert!((fast - slow).abs() < 1e-6, "{fast} vs {slow}");
            let plain = trace_angle_deg((ra.inverse() * rb).matrix());
            assert!((rotation_error_deg(&a.rotation, &b.rotation, &[]) - plain).abs() < 1e-6);
        }
    }

    #[test]
    fn half_turn_symmetric_tray_forgives_a_half_turn() {
        let metrics = Cell::default().metrics;
        let mut rng = ChaCha8Rng::seed_from_u64(12);
        for _ in 0..100 {
            let truth = random_pose(&mut rng);
            let wobble_deg: f64 = rng.random_range(0.0..20.0);
            let axis =
                Vector3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
            let wobble = UnitQuaternion::from_axis_angle(&nalgebra::Unit::new_normalize(axis), wobble_deg.to_radians());
            let flipped = truth * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::PI);
            let e = pose_errors(&flipped, &truth, &[180.0], &metrics);
            assert!(e.rotation_deg < 1e-6 && e.position_mm < 1e-9 && e.success, "{e:?}");
            let e = pose_errors(&flipped, &truth, &[], &metrics);
            assert!((e.rotation_deg - 180.0).abs() < 1e-6 && !e.success, "{e:?}");
            let estimate = flipped * wobble;
            let e = pose_errors(&estimate, &truth, &[180.0], &metrics);
            assert!((e.rotation_deg - wobble_deg).abs() < 1e-6, "{e:?} vs {wobble_deg}");
            assert_eq!(e.success, wobble_deg < metrics.success_rotation);
        }
    }

    #[test]
    fn success_needs_both_errors_below_their_limits() {
        let metrics = Cell::default().metrics;
        let mut rng = ChaCha8Rng::seed_from_u64(13);
        for _ in 0..200 {
            let truth = random_pose(&mut rng);
            let shift = Vector3::new(rng.random_range(-4.0..4.0), rng.random_range(-4.0..4.0), 0.0);
            let turn_deg: f64 = rng.random_range(-8.0..8.0);
            let estimate = Isometry3::from_parts(
                (truth.translation.vector + shift).into(),
                UnitQuaternion::from_axis_angle(&Vector3::x_axis(), turn_deg.to_radians()) * truth.rotation,
            );
            let e = pose_errors(&estimate, &truth, &[], &metrics);
            assert!((e.position_mm - shift.norm()).abs() < 1e-9);
            assert!((e.rotation_deg - turn_deg.abs()).abs() < 1e-6);
            assert_eq!(e.success, shift.norm() < 3.0 && turn_deg.abs() < 5.0);
        }
    }

    #[test]
    fn correct_matches_counts_features_near_their_scene_points() {
        let mut rng = ChaCha8Rng::seed_from_u64(14);
        let truth = random_pose(&mut rng);
        let features: Vec<Point3<f32>> = (0..300)
            .map(|_| {
                Point3::new(rng.random_range(-100.0..100.0), rng.random_range(-60.0..60.0), rng.random_range(0.0..30.0))
            })
            .collect();
        let mut keypoints = Vec::new();
        let mut matches = Vec::new();
        let mut expected = 0;
        for (i, f) in features.iter().enumerate() {
            let offset =
                Vector3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0))
                    .normalize()
                    * rng.random_range(0.0..9.0);
            if offset.norm() <= 4.5 {
                expected += 1;
            }
            keypoints.push((truth * f.cast::<f64>() + offset).cast::<f32>());
            matches.push(Correspondence { scene: i as u32, model: i as u32, distance2: 0.0 });
        }
        matches.push(Correspondence { scene: 9999, model: 0, distance2: 0.0 });
        assert_eq!(correct_matches(&keypoints, &features, &matches, &truth, &[], 4.5), expected);

        // A match to the feature a half turn away is right for a half-turn symmetric tray.
        let mirrored: Vec<Point3<f32>> = features.iter().map(|f| Point3::new(-f.x, -f.y, f.z)).collect();
        let exact: Vec<Point3<f32>> = features.iter().map(|f| (truth * f.cast::<f64>()).cast::<f32>()).collect();
        let all: Vec<Correspondence> =
            (0..300).map(|i| Correspondence { scene: i as u32, model: i as u32, distance2: 0.0 }).collect();
        assert_eq!(correct_matches(&exact, &mirrored, &all, &truth, &[180.0], 4.5), 300);
        assert!(correct_matches(&exact, &mirrored, &all, &truth, &[], 4.5) < 30);
    }
}
