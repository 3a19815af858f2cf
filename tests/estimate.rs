//! End to end: the model built in simulation, scenes rendered with the study's scenarios, the
//! estimator's poses scored against the truth; and frames without a tray, and a bad model
//! file through the CLI.

use camplace_config::{Cell, TrayKind};
use camplace_estimator::{Estimator, EstimatorConfig};
use camplace_sim::{background_scene, build_model, noise_key, Evaluator, Frame, Method, Simulator};

use crate::camplace_cmd::{camplace, stderr};

const OPTIMUM: &str = "r=605,alpha=32,baseline=81,vergence=3.5";

/// Successes among scenarios 0..n of seed 1 at the optimum, one shot, through the study's
/// evaluator (the path `camplace evaluate` takes).
fn successes_at_the_optimum(cell: &Cell, n: u64) -> usize {
    let placement = cell.placement.with_overrides(OPTIMUM).unwrap();
    let evaluator = Evaluator::new(cell, &placement, Method::OneShot, 1).unwrap();
    let mut worker = evaluator.worker().unwrap();
    (0..n).filter(|&i| worker.scene(i).unwrap().score.is_some_and(|s| s.success)).count()
}

#[test]
fn one_shot_at_the_optimum_finds_trays() {
    let successes = successes_at_the_optimum(&Cell::default(), 50);
    // Measured: 50 of these 50 with the default settings (49 before the stereo gap fill
    // widened); the acceptance figure is 90 %.
    assert!(successes >= 46, "{successes} of 50 trays found within the success limits");
}

#[test]
fn the_square_tray_is_not_taken_a_quarter_turn_off() {
    // The 4-slot tray is square: only its tab tells quarter turns apart. Measured: 20 of 20
    // (15 of 20, every miss a 90° turn, when only the half turn was checked).
    let mut cell = Cell::default();
    cell.tray.kind = TrayKind::Tray4;
    let successes = successes_at_the_optimum(&cell, 20);
    assert!(successes >= 18, "{successes} of 20 square trays found within the success limits");
}

#[test]
fn scenes_without_a_tray_give_no_error() {
    let cell = Cell::default();
    let placement = cell.placement.with_overrides(OPTIMUM).unwrap();
    let seed = 2;
    let model = build_model(&cell, &placement, Method::OneShot, seed).unwrap();
    let mut sim = Simulator::new(&cell, &placement, seed).unwrap();
    let mut frame = Frame::default();
    let background = background_scene(&cell, seed);
    sim.render(&background, Method::OneShot, noise_key(seed, 0, true), &mut frame);
    let mut estimator = Estimator::new(&EstimatorConfig::from(&cell), sim.rig(), model, Method::OneShot).unwrap();
    estimator.set_background(&frame.shots.left, &frame.shots.right).unwrap();
    // The background itself, freshly captured. Background removal leaves much of the table
    // in a new capture, and a table patch can pass RANSAC's inlier share of a view (the
    // tray's base plate is flat too), so a wrong pose is possible here; an error is not.
    sim.render(&background, Method::OneShot, noise_key(seed, 1, true), &mut frame);
    // Whatever pose RANSAC finds there, the verification hands none on.
    let pose = estimator.process(&frame.shots.left, &frame.shots.right).unwrap();
    assert!(pose.t_world_tray.to_homogeneous().iter().all(|v| v.is_finite()), "{pose:?}");
    assert!(!pose.accepted(), "a tray accepted in the empty cell: {:?}", pose.verification);
    // Without a background, the bare table is all the estimator sees.
    let mut bare =
        Estimator::new(&EstimatorConfig::from(&cell), sim.rig(), estimator.model().clone(), Method::OneShot).unwrap();
    let pose = bare.process(&frame.shots.left, &frame.shots.right).unwrap();
    assert!(pose.t_world_tray.to_homogeneous().iter().all(|v| v.is_finite()), "{pose:?}");
    assert!(!pose.accepted(), "a tray accepted on the bare table: {:?}", pose.verification);
}

#[test]
fn a_corrupt_model_file_is_a_one_line_error() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("scene.ply"), b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n").unwrap();
    let mut bytes = b"CPLMODEL".to_vec();
    bytes.extend_from_slice(&[1, 0, 0, 0, 255, 0, 0, 0, 0, 0, 0, 0, 1, 2, 3]);
    std::fs::write(dir.path().join("tray.model"), &bytes).unwrap();
    std::fs::write(dir.path().join("other.model"), b"not a model at all").unwrap();
    for name in ["tray.model", "other.model", "missing.model"] {
        let o = camplace(dir.path(), &["estimate", "--cloud", "scene.ply", "--model", name]);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert_eq!(err.trim_end().lines().count(), 1, "one line: {err}");
        assert!(err.contains(name), "{name} missing from: {err}");
    }
}
