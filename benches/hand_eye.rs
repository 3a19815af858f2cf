//! Bench of the hand-eye calibration on synthetic corners: a 640 × 480 pair, a 9 × 6 board
//! on the flange at 15 robot poses spread in tilt and spin, the corners projected exactly
//! (the solver's work does not depend on the noise).

use camplace_estimator::{
    calibration::calibrate_hand_eye, calibration::BoardView, calibration::CalibrationBoard, calibration::HandEyeInput,
    calibration::HandEyeSetup, geometry::Camera,
};
use criterion::{criterion_group, Criterion};
use nalgebra::{Isometry3, Matrix3, Point2, Translation3, UnitQuaternion, Vector3};

fn hand_eye(c: &mut Criterion) {
    let left = Camera {
        width: 640,
        height: 480,
        k: Matrix3::new(812.4, 0.0, 319.5, 0.0, 812.4, 239.5, 0.0, 0.0, 1.0),
        dist: [0.0; 5],
        t_world_camera: Isometry3::identity(),
    };
    let right = Camera {
        t_world_camera: Isometry3::from_parts(
            Translation3::new(81.0, 0.0, 0.0),
            UnitQuaternion::from_axis_angle(&Vector3::y_axis(), -3.5f64.to_radians()),
        ),
        ..left.clone()
    };
    let board = CalibrationBoard { cols: 9, rows: 6, square_mm: 25.0 };
    let object = board.object_points();
    let x =
        Isometry3::from_parts(Translation3::new(-100.0, -62.5, 40.0), UnitQuaternion::from_euler_angles(0.1, 0.0, 0.2));
    let z =
        Isometry3::from_parts(Translation3::new(600.0, 0.0, 900.0), UnitQuaternion::from_euler_angles(3.0, 0.1, 1.0));
    let mut views = Vec::new();
    let mut a = Vec::new();
    for k in 0..15 {
        let (tilt_x, tilt_y, spin) = ((k as f64 * 1.7).sin() * 0.5, (k as f64 * 2.3).cos() * 0.5, k as f64 * 0.2 - 1.4);
        let turn = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI)
            * UnitQuaternion::from_euler_angles(tilt_x, tilt_y, spin);
        let centre = Vector3::new(40.0, 0.0, 520.0 + 10.0 * k as f64);
        let t_rig_board =
            Isometry3::from_parts(Translation3::from(centre - turn * Vector3::new(100.0, 62.5, 0.0)), turn);
        let project = |camera: &Camera| -> Option<Vec<Point2<f64>>> {
            let t = camera.t_world_camera.inverse() * t_rig_board;
            object.iter().map(|p| camera.project_camera(&(t * p))).collect()
        };
        views.push(BoardView { left: project(&left), right: project(&right) });
        a.push(z * t_rig_board * x.inverse());
    }
    let input = HandEyeInput {
        setup: HandEyeSetup::EyeToHand,
        board: &board,
        left: &left,
        right: &right,
        views: &views,
        t_base_flange: &a,
        robot_sigma_mm: 0.1,
        robot_sigma_deg: 0.02,
    };
    let found = calibrate_hand_eye(&input).expect("the bench poses are solvable");
    assert!((found.t_mount_rig.translation.vector - z.translation.vector).norm() < 1e-3);
    c.bench_function("calibration/hand_eye_15_poses", |b| b.iter(|| calibrate_hand_eye(&input).expect("solvable")));
}

criterion_group!(benches, hand_eye);
