//! Every matrix read becomes the rotation it is: random rotations and half turns about
//! random axes, written as each file that stores a transform writes it (`truth.json`, a
//! cell's `[robot]`, a rig's camera, a `poses.jsonl` record) and in every robot pose
//! convention and unit, read back and converted as the commands convert them, against the
//! rotation they were made from.

use camplace_config::splitmix::SplitMix64;
use camplace_config::{
    format_pose_exact, parse_pose, CameraFile, Cell, LengthUnit, LightingTruth, PoseConvention, RobotPoseFormat,
    TruthFile,
};
use camplace_estimator::{
    geometry::isometry_from_rows, geometry::isometry_to_rows, geometry::Camera, scoring::FrameRecord, scoring::Timings,
};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

/// Random rotations drawn uniformly (Shoemake's unit quaternions) and every one's matching
/// translation; then half turns about axes drawn uniformly on the sphere, the axes of the
/// frame among them.
fn poses(random: usize, half_turns: usize) -> Vec<Isometry3<f64>> {
    let mut rng = SplitMix64(0x7F4A_7C15_9E37_79B9);
    let mut uniform = move || (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
    let mut out = Vec::with_capacity(random + half_turns + 3);
    for _ in 0..random {
        let (u1, u2, u3) = (uniform(), uniform(), uniform());
        let (a, b) = ((1.0 - u1).sqrt(), u1.sqrt());
        let tau = std::f64::consts::TAU;
        let q = nalgebra::Quaternion::new(
            a * (tau * u2).sin(),
            a * (tau * u2).cos(),
            b * (tau * u3).sin(),
            b * (tau * u3).cos(),
        );
        let t = Translation3::new(2000.0 * uniform() - 1000.0, 2000.0 * uniform() - 1000.0, 1500.0 * uniform());
        out.push(Isometry3::from_parts(t, UnitQuaternion::from_quaternion(q)));
    }
    let mut axes: Vec<Vector3<f64>> = vec![Vector3::x(), Vector3::y(), Vector3::z(), Vector3::new(0.26, -0.97, 0.0)];
    while axes.len() < half_turns {
        let z: f64 = 2.0 * uniform() - 1.0;
        let phi = std::f64::consts::TAU * uniform();
        let s = (1.0 - z * z).sqrt();
        axes.push(Vector3::new(s * phi.cos(), s * phi.sin(), z));
    }
    for axis in axes {
        // As a file writes a half turn: R = 2·n·nᵀ − I, exactly 0 and ±1 about an axis of
        // the frame (where an iteration started at the identity finds no way out).
        let n = axis.normalize();
        let r = nalgebra::Rotation3::from_matrix_unchecked(2.0 * n * n.transpose() - nalgebra::Matrix3::identity());
        let turn = UnitQuaternion::from_rotation_matrix(&r);
        out.push(Isometry3::from_parts(Translation3::new(450.0, -120.0, 800.0), turn));
    }
    out
}

/// The largest difference between two transforms' rotation entries and translations.
fn difference(a: &Isometry3<f64>, b: &Isometry3<f64>) -> (f64, f64) {
    let ra = a.rotation.to_rotation_matrix().into_inner();
    let rb = b.rotation.to_rotation_matrix().into_inner();
    let rotation = (ra - rb).abs().max();
    let translation = (a.translation.vector - b.translation.vector).abs().max();
    (rotation, translation)
}

fn assert_same(what: &str, read: &Isometry3<f64>, made: &Isometry3<f64>, rotation_tol: f64, translation_tol: f64) {
    let (r, t) = difference(read, made);
    assert!(
        r <= rotation_tol && t <= translation_tol,
        "{what}: read back {} (angle {:.9} rad) as {} (angle {:.9} rad): rotation entries {r:e} off, translation {t:e} mm",
        made.rotation.axis().map_or(Vector3::zeros(), |a| a.into_inner()),
        made.rotation.angle(),
        read.rotation.axis().map_or(Vector3::zeros(), |a| a.into_inner()),
        read.rotation.angle(),
    );
}

#[test]
fn matrices_become_the_rotations_they_are_half_turns_included() {
    let all = poses(10_000, 1_000);
    let half_turns = all.iter().filter(|p| (p.rotation.angle() - std::f64::consts::PI).abs() < 1e-9).count();
    assert!(half_turns >= 1_000, "{half_turns} half turns");
    for (i, made) in all.iter().enumerate() {
        let rows = isometry_to_rows(made);
        assert_same(&format!("pose {i} as a matrix"), &isometry_from_rows(&rows), made, 1e-12, 1e-9);
        // A matrix typed with six decimals (inside the files' orthonormality tolerance) reads
        // as the nearest rotation, which is within those digits of the one it was.
        let typed = rows.map(|r| r.map(|v| (v * 1e6).round() / 1e6));
        if camplace_config::check_rigid(&typed).is_ok() {
            assert_same(&format!("pose {i} to six decimals"), &isometry_from_rows(&typed), made, 3e-6, 1e-6);
        }
    }
}

#[test]
fn every_file_and_robot_convention_round_trips_a_transform() {
    let all = poses(10_000, 1_000);
    let formats: Vec<RobotPoseFormat> = PoseConvention::ALL
        .into_iter()
        .flat_map(|convention| [LengthUnit::Mm, LengthUnit::M].map(|unit| RobotPoseFormat { convention, unit }))
        .collect();
    let truth = TruthFile {
        t_world_tray: isometry_to_rows(&Isometry3::identity()),
        filled: vec![0, 2],
        lighting: LightingTruth { ambient: 0.3, lamp_strength: 0.8, lamp_position: [100.0, 50.0, 900.0] },
        seed: 1,
        scenario: 0,
        symmetries: vec![],
        placement: None,
        method: None,
    };
    let camera = Camera::ideal(640, 480, 800.0, Isometry3::identity()).to_file();
    let record: FrameRecord = serde_json::from_value(serde_json::json!({
        "frame": "0000", "T_world_tray": isometry_to_rows(&Isometry3::identity()), "found": true,
        "inliers": 0, "scene_points": 0, "keypoints": 0, "matches": 0, "icp_iterations": 0,
        "timings_ms": Timings::default(), "ms": 0.0
    }))
    .expect("a minimal poses.jsonl record");
    for (i, made) in all.iter().enumerate() {
        let rows = isometry_to_rows(made);
        for format in &formats {
            let line = format_pose_exact(&rows, *format);
            let read = parse_pose(&line, *format).unwrap_or_else(|e| panic!("pose {i} as {format}: {line}: {e}"));
            // Euler angles and rotation vectors carry their own rounding: 1e-9 of an entry.
            assert_same(&format!("pose {i} as {format}: {line}"), &isometry_from_rows(&read), made, 1e-9, 1e-9);
        }
        let t = TruthFile { t_world_tray: rows, ..truth.clone() };
        let back = TruthFile::from_json(&serde_json::to_string_pretty(&t).unwrap()).unwrap();
        assert_same(&format!("pose {i} in truth.json"), &isometry_from_rows(&back.t_world_tray), made, 1e-12, 1e-9);

        let robot_rows: Vec<String> = rows.iter().map(|r| format!("{r:?}")).collect();
        let cell = format!("[robot]\nT_robot_world = [{}]\n", robot_rows.join(", "));
        match Cell::from_toml_str(&cell, std::path::Path::new(".")) {
            Ok(c) => {
                let r = &c.robot.expect("the [robot] table read").t_robot_world;
                assert_same(&format!("pose {i} as [robot]"), &isometry_from_rows(r), made, 1e-12, 1e-9);
            }
            // The cell's own limits (where the robot's base may be) may refuse a random
            // pose; never a half turn, which these tests are for.
            Err(e) => assert!(i < 10_000 && !e.to_string().contains("rotation"), "pose {i} as [robot]: {e}"),
        }

        let camera_file = CameraFile { t_world_camera: rows, ..camera.clone() };
        let json = serde_json::to_string(&camera_file).unwrap();
        let back = Camera::from_file(&serde_json::from_str::<CameraFile>(&json).unwrap());
        assert_same(&format!("pose {i} as a rig camera"), &back.t_world_camera, made, 1e-12, 1e-9);

        let r = FrameRecord { t_world_tray: rows, ..record.clone() };
        let back: FrameRecord = serde_json::from_str(&serde_json::to_string(&r).unwrap()).unwrap();
        assert_same(&format!("pose {i} in poses.jsonl"), &isometry_from_rows(&back.t_world_tray), made, 1e-12, 1e-9);
    }
}
