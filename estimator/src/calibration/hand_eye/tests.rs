//! Hand-eye calibration against a synthetic cell: a known rig, board and robot, the board's
//! corners projected at every robot pose with seeded pixel noise and the robot's reported
//! poses with seeded pose noise; the result is compared with the truth.

use nalgebra::{Isometry3, Matrix3, Point2, Translation3, UnitQuaternion, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use super::*;
use crate::camera::Camera;

fn board() -> CalibrationBoard {
    CalibrationBoard { cols: 9, rows: 6, square_mm: 25.0 }
}

fn rig() -> (Camera, Camera) {
    let left = Camera {
        width: 640,
        height: 480,
        k: Matrix3::new(700.0, 0.0, 321.0, 0.0, 701.0, 238.0, 0.0, 0.0, 1.0),
        dist: [-0.1, 0.03, 0.0005, -0.0003, 0.0],
        t_world_camera: Isometry3::identity(),
    };
    let right = Camera {
        t_world_camera: Isometry3::from_parts(
            Translation3::new(81.0, 0.0, 0.0),
            UnitQuaternion::from_axis_angle(&Vector3::y_axis(), -3.5f64.to_radians()),
        ),
        ..left.clone()
    };
    (left, right)
}

fn normal(rng: &mut ChaCha8Rng) -> f64 {
    // Box–Muller.
    let (u, v): (f64, f64) = (rng.random_range(1e-12..1.0), rng.random_range(0.0..1.0));
    (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

fn small_turn(rng: &mut ChaCha8Rng, sigma_deg: f64) -> UnitQuaternion<f64> {
    let v = Vector3::new(normal(rng), normal(rng), normal(rng)) * sigma_deg.to_radians();
    UnitQuaternion::from_scaled_axis(v)
}

/// The truth and the data of a synthetic calibration.
struct Scene {
    x: Isometry3<f64>,
    z: Isometry3<f64>,
    views: Vec<BoardView>,
    a: Vec<Isometry3<f64>>,
}

/// `n` poses of `setup` with pixel noise `pixel_sigma` and robot noise 0.1 mm / 0.02° per
/// axis; `max_tilt_deg` of turn about the board's x and y axes (0: turns about its normal
/// only).
fn scene(setup: HandEyeSetup, n: usize, seed: u64, pixel_sigma: f64, max_tilt_deg: f64) -> Scene {
    scene_with_robot(setup, n, seed, pixel_sigma, max_tilt_deg, (0.1, 0.02))
}

/// [`scene`] with the robot's noise per axis `(mm, deg)`.
fn scene_with_robot(
    setup: HandEyeSetup,
    n: usize,
    seed: u64,
    pixel_sigma: f64,
    max_tilt_deg: f64,
    robot: (f64, f64),
) -> Scene {
    let (left, right) = rig();
    let board = board();
    let object = board.object_points();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (x, z) = match setup {
        // X = T_flange_board, Z = T_base_rig.
        HandEyeSetup::EyeToHand => (
            Isometry3::from_parts(
                Translation3::new(-100.0, -62.5, 40.0),
                UnitQuaternion::from_euler_angles(0.1, -0.05, 0.3),
            ),
            Isometry3::from_parts(
                Translation3::new(650.0, -120.0, 900.0),
                UnitQuaternion::from_euler_angles(3.0, 0.2, 1.2),
            ),
        ),
        // X = T_flange_rig, Z = T_base_board.
        HandEyeSetup::EyeInHand => (
            Isometry3::from_parts(
                Translation3::new(-40.0, 60.0, 80.0),
                UnitQuaternion::from_euler_angles(0.05, 0.1, 1.5),
            ),
            Isometry3::from_parts(
                Translation3::new(700.0, 50.0, -20.0),
                UnitQuaternion::from_euler_angles(0.0, 0.0, 0.4),
            ),
        ),
    };
    let mut views = Vec::new();
    let mut a = Vec::new();
    while views.len() < n {
        // The board in the rig's frame: ahead at 450 to 700 mm, facing the rig, tilted.
        let turn = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI)
            * UnitQuaternion::from_euler_angles(
                rng.random_range(-max_tilt_deg..=max_tilt_deg).to_radians(),
                rng.random_range(-max_tilt_deg..=max_tilt_deg).to_radians(),
                rng.random_range(-60f64..60.0).to_radians(),
            );
        let centre =
            Vector3::new(rng.random_range(-60.0..100.0), rng.random_range(-60.0..60.0), rng.random_range(450.0..700.0));
        let t_rig_board =
            Isometry3::from_parts(Translation3::from(centre - turn * Vector3::new(100.0, 62.5, 0.0)), turn);
        let t_base_flange = match setup {
            HandEyeSetup::EyeToHand => z * t_rig_board * x.inverse(),
            HandEyeSetup::EyeInHand => z * t_rig_board.inverse() * x.inverse(),
        };
        let project = |camera: &Camera| -> Option<Vec<Point2<f64>>> {
            let t = camera.t_world_camera.inverse() * t_rig_board;
            object
                .iter()
                .map(|p| {
                    camera.project_camera(&(t * p)).filter(|q| q.x > 5.0 && q.y > 5.0 && q.x < 634.0 && q.y < 474.0)
                })
                .collect()
        };
        let (Some(mut l), Some(mut r)) = (project(&left), project(&right)) else { continue };
        for q in l.iter_mut().chain(r.iter_mut()) {
            q.x += pixel_sigma * normal(&mut rng);
            q.y += pixel_sigma * normal(&mut rng);
        }
        views.push(BoardView { left: Some(l), right: Some(r) });
        let noise_t = Vector3::new(normal(&mut rng), normal(&mut rng), normal(&mut rng)) * robot.0;
        let reported = Isometry3::from_parts(
            Translation3::from(t_base_flange.translation.vector + noise_t),
            t_base_flange.rotation * small_turn(&mut rng, robot.1),
        );
        a.push(reported);
    }
    Scene { x, z, views, a }
}

fn calibrate(setup: HandEyeSetup, s: &Scene) -> Result<HandEyeCalibration> {
    calibrate_stated(setup, s, (0.1, 0.02))
}

/// [`calibrate`] with the robot's accuracy stated as `(mm, deg)`.
fn calibrate_stated(setup: HandEyeSetup, s: &Scene, robot: (f64, f64)) -> Result<HandEyeCalibration> {
    let (left, right) = rig();
    let board = board();
    calibrate_hand_eye(&HandEyeInput {
        setup,
        board: &board,
        left: &left,
        right: &right,
        views: &s.views,
        t_base_flange: &s.a,
        robot_sigma_mm: robot.0,
        robot_sigma_deg: robot.1,
    })
}

fn errors(found: &Isometry3<f64>, truth: &Isometry3<f64>) -> (f64, f64) {
    let d = truth.inverse() * found;
    (d.translation.vector.norm(), d.rotation.angle().to_degrees())
}

#[test]
fn both_setups_recover_the_mounting_from_noisy_poses() {
    for setup in [HandEyeSetup::EyeToHand, HandEyeSetup::EyeInHand] {
        for seed in 0..3 {
            let s = scene(setup, 15, seed, 0.05, 35.0);
            let cal = calibrate(setup, &s).unwrap();
            let (rig_truth, board_truth) = match setup {
                HandEyeSetup::EyeToHand => (s.z, s.x),
                HandEyeSetup::EyeInHand => (s.x, s.z),
            };
            let (t, r) = errors(&cal.t_mount_rig, &rig_truth);
            let (bt, br) = errors(&cal.t_mount_board, &board_truth);
            eprintln!("{setup:?} seed {seed}: rig {t:.3} mm {r:.4}°, board {bt:.3} mm {br:.4}°, {:.3} px", cal.rms_px);
            assert!(t < 0.5 && r < 0.05, "{setup:?} seed {seed}: rig off by {t} mm, {r}°");
            assert!(cal.poses.iter().all(|p| !p.dropped), "{setup:?} seed {seed}: {:?}", cal.poses);
            // The expected error is of the size of the real one, not orders away.
            assert!(
                cal.expected.rig_translation_mm < 1.0 && cal.expected.rig_translation_mm > t / 10.0,
                "{:?}",
                cal.expected
            );
        }
    }
}

#[test]
fn a_swapped_pair_of_poses_is_dropped_and_named() {
    for setup in [HandEyeSetup::EyeToHand, HandEyeSetup::EyeInHand] {
        let mut s = scene(setup, 15, 7, 0.05, 35.0);
        s.views.swap(3, 9);
        let cal = calibrate(setup, &s).unwrap();
        let dropped: Vec<usize> = cal.poses.iter().filter(|p| p.dropped).map(|p| p.index).collect();
        assert_eq!(dropped.len(), 2, "{setup:?}: {:?}", cal.poses);
        assert!(dropped.contains(&3) && dropped.contains(&9), "{setup:?}: {dropped:?}");
        let truth = if setup == HandEyeSetup::EyeToHand { s.z } else { s.x };
        let (t, r) = errors(&cal.t_mount_rig, &truth);
        assert!(t < 0.5 && r < 0.05, "{setup:?}: rig off by {t} mm, {r}°");
    }
}

#[test]
fn poses_in_metres_read_as_millimetres_are_said_so() {
    let s = scene(HandEyeSetup::EyeToHand, 12, 3, 0.05, 35.0);
    let mut metres = Scene { a: s.a.clone(), ..s };
    for a in &mut metres.a {
        a.translation.vector /= 1000.0;
    }
    let e = calibrate(HandEyeSetup::EyeToHand, &metres).unwrap_err();
    assert!(e.to_string().contains("in m but were read as mm"), "{e}");
}

#[test]
fn turns_about_one_axis_and_too_few_poses_are_refused() {
    let s = scene(HandEyeSetup::EyeToHand, 10, 5, 0.05, 0.0);
    // Turns about the board's normal only: one axis in the flange.
    let e = calibrate(HandEyeSetup::EyeToHand, &s).unwrap_err();
    assert!(e.to_string().contains("about one axis"), "{e}");
    let s = scene(HandEyeSetup::EyeInHand, 4, 5, 0.05, 35.0);
    let e = calibrate(HandEyeSetup::EyeInHand, &s).unwrap_err();
    assert!(e.to_string().contains("expected at least 5"), "{e}");
}

/// Seeds per configuration of the coverage test.
const COVERAGE_SEEDS: u64 = 300;

#[test]
fn the_expected_error_covers_the_true_one_about_as_often_as_one_sigma_should() {
    // The printed 1 σ is the RMS length of the error; a 3-D error stays within it 61 % of
    // the time when its axes are alike, 68 % when one axis dominates. At 100 seeds a
    // configuration's share wandered by ±4 % (one fell to 52 % while its mean squared error
    // matched the expected to 5 %), so 300 seeds: measured 57 % to 67 % per configuration,
    // 61 % over all, the mean squared true error 0.94 to 1.07 times the expected; with one
    // variance for all residuals the median true / expected was 2 to 2.8.
    let mut failures = Vec::new();
    let (mut all_covered, mut all_total) = (0, 0);
    for setup in [HandEyeSetup::EyeToHand, HandEyeSetup::EyeInHand] {
        for n in [8, 15] {
            for robot in [(0.1, 0.02), (0.5, 0.1)] {
                let (mut covered, mut total, mut ratios) = (0, 0, Vec::new());
                // Sums of the squared true and expected errors: translation, rotation.
                let (mut true_sq, mut expected_sq) = ([0.0; 2], [0.0; 2]);
                // Each seed's calibration on its own (in parallel), then summed in seed order.
                let solved: Vec<(f64, f64, ExpectedError)> = (0..COVERAGE_SEEDS)
                    .into_par_iter()
                    .map(|seed| {
                        let s = scene_with_robot(setup, n, 1000 + seed, 0.05, 35.0, robot);
                        let cal = calibrate_stated(setup, &s, robot).unwrap();
                        let truth = if setup == HandEyeSetup::EyeToHand { s.z } else { s.x };
                        let (t, r) = errors(&cal.t_mount_rig, &truth);
                        (t, r, cal.expected)
                    })
                    .collect();
                for (t, r, e) in &solved {
                    let (t, r) = (*t, *r);
                    covered += (t <= e.rig_translation_mm) as usize + (r <= e.rig_rotation_deg) as usize;
                    total += 2;
                    ratios.push(t / e.rig_translation_mm);
                    true_sq[0] += t * t;
                    true_sq[1] += r * r;
                    expected_sq[0] += e.rig_translation_mm * e.rig_translation_mm;
                    expected_sq[1] += e.rig_rotation_deg * e.rig_rotation_deg;
                    ratios.push(r / e.rig_rotation_deg);
                }
                ratios.sort_by(f64::total_cmp);
                let share = covered as f64 / total as f64;
                let rms_ratio = [0, 1].map(|k| (true_sq[k] / expected_sq[k]).sqrt());
                eprintln!(
                    "{setup:?}, {n} poses, robot {} mm / {}°: the 1 σ covers {covered} of {total} ({:.0} %), true / \
                     expected median {:.2}, largest {:.2}, RMS {:.2} (translation) {:.2} (rotation)",
                    robot.0,
                    robot.1,
                    100.0 * share,
                    ratios[ratios.len() / 2],
                    ratios[ratios.len() - 1],
                    rms_ratio[0],
                    rms_ratio[1]
                );
                if rms_ratio.iter().any(|r| !(0.85..=1.15).contains(r)) {
                    failures.push(format!("{setup:?} {n} {robot:?}: RMS true / expected {rms_ratio:?}"));
                }
                all_covered += covered;
                all_total += total;
                if !(0.55..=0.80).contains(&share) {
                    failures.push(format!("{setup:?} {n} {robot:?}: {covered} of {total}"));
                }
            }
        }
    }
    let share = all_covered as f64 / all_total as f64;
    eprintln!("over all: {all_covered} of {all_total} ({:.0} %)", 100.0 * share);
    assert!((0.55..=0.80).contains(&share), "over all: {all_covered} of {all_total}");
    assert!(failures.is_empty(), "{failures:?}");
}

#[test]
fn poses_that_cannot_belong_to_the_views_are_refused_with_the_reading_that_fits() {
    use camplace_config::{parse_robot_poses, robot_poses_text, LengthUnit, PoseConvention, RobotPoseFormat};
    let s = scene(HandEyeSetup::EyeToHand, 10, 11, 0.05, 35.0);
    let refusal = |a: Vec<Isometry3<f64>>, views: Vec<BoardView>, setup: HandEyeSetup| {
        let scene = Scene { x: s.x, z: s.z, views, a };
        calibrate(setup, &scene).unwrap_err().to_string()
    };
    let inverted = refusal(s.a.iter().map(|t| t.inverse()).collect(), s.views.clone(), HandEyeSetup::EyeToHand);
    assert!(inverted.contains("do not fit") && inverted.contains("inverted ("), "{inverted}");
    let setup = refusal(s.a.clone(), s.views.clone(), HandEyeSetup::EyeInHand);
    assert!(setup.contains("inverted") && setup.contains("eye-in-hand"), "{setup}");
    // Each view paired with the pose before its own: frame k belongs with pose k + 1.
    let shifted = refusal(s.a[..9].to_vec(), s.views[1..].to_vec(), HandEyeSetup::EyeToHand);
    assert!(shifted.contains("paired one frame off (frame k with pose k + 1)"), "{shifted}");

    // Through a pose file: quaternions written w first, labelled w last; a line far off.
    let (left, right) = rig();
    let board = board();
    let rows: Vec<[[f64; 4]; 4]> = s.a.iter().map(crate::camera::isometry_to_rows).collect();
    let wxyz = RobotPoseFormat { convention: PoseConvention::QuatWxyz, unit: LengthUnit::Mm };
    let text = robot_poses_text(&rows, wxyz, "w first").replace("quat-wxyz", "quat-xyzw");
    let poses = parse_robot_poses(&text, None).unwrap();
    let frames: Vec<Option<BoardView>> = s.views.iter().cloned().map(Some).collect();
    let job = PairedHandEye {
        setup: HandEyeSetup::EyeToHand,
        board: &board,
        left: &left,
        right: &right,
        frames: &frames,
        poses: &poses,
        robot_sigma_mm: 0.1,
        robot_sigma_deg: 0.02,
    };
    let e = calibrate_hand_eye_paired(&job).unwrap_err();
    assert!(matches!(
        e,
        HandEyeError::Misfit {
            fits: Some((PoseReading::Convention { read: PoseConvention::QuatXyzw, fits: PoseConvention::QuatWxyz }, _)),
            ..
        }
    ));
    let mut far = rows.clone();
    far[4][0][3] = 1e15;
    let poses = parse_robot_poses(&robot_poses_text(&far, wxyz, "far"), None).unwrap();
    let e = calibrate_hand_eye_paired(&PairedHandEye { poses: &poses, ..job }).unwrap_err();
    assert!(e.to_string().starts_with("line 7: the flange 1.000e15 mm"), "{e}");
    // As written they fit, every pose named by its frame.
    let poses = parse_robot_poses(&robot_poses_text(&rows, wxyz, "right"), None).unwrap();
    let cal = calibrate_hand_eye_paired(&PairedHandEye { poses: &poses, ..job }).unwrap();
    assert_eq!(cal.poses.iter().map(|p| p.index).collect::<Vec<_>>(), (0..10).collect::<Vec<_>>());

    // Made by hand, not parsed: without texts the numbers are read again; line numbers or
    // texts that do not match the poses are refused, not indexed past.
    let mut bare = parse_robot_poses(&robot_poses_text(&rows, wxyz, "bare"), None).unwrap();
    bare.texts.clear();
    let cal = calibrate_hand_eye_paired(&PairedHandEye { poses: &bare, ..job }).unwrap();
    assert_eq!(cal.poses.len(), 10);
    let mut short = bare.clone();
    short.texts = vec![String::new(); 3];
    let e = calibrate_hand_eye_paired(&PairedHandEye { poses: &short, ..job }).unwrap_err();
    assert!(e.to_string().contains("10 poses with 10 line numbers and 3 texts"), "{e}");
    let mut lines = bare.clone();
    lines.lines.truncate(2);
    let e = calibrate_hand_eye_paired(&PairedHandEye { poses: &lines, ..job }).unwrap_err();
    assert!(e.to_string().contains("2 line numbers"), "{e}");
}
