//! Hand-eye calibration data in simulation: a robot moves the board in front of the fixed rig
//! (eye-to-hand) or the rig over a board lying on the table (eye-in-hand); each pose's
//! stereo pair is rendered as `render --board` renders boards, and the robot's poses are
//! written as its controller reports them (with the robot's own error), beside the truth.
//!
//! The robot's base sits beside the table: `T_world_robot` is a turn of 20° about z and
//! a shift to (-600, 150, -20) mm. Eye-to-hand the board is held 60 mm in front of the
//! flange, turned 10° about its axis; eye-in-hand the rig (its left camera's frame) is
//! mounted 60 mm beside the flange's axis and 90 mm along it. Only the relative pose of rig
//! and board decides an image, so an eye-in-hand view is rendered by the placement's rig
//! with the board where it lies relative to the moved rig.

use std::path::Path;

use camplace_config::{frame_name, robot_poses_text, Cell, Placement, RobotPoseFormat};
use camplace_estimator::{
    calibration::CalibrationBoard, calibration::HandEyeSetup, geometry::isometry_from_rows, geometry::isometry_to_rows,
    Rig,
};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::board::{board_extent, fits, render_board_pairs};
use super::frame_files::write_rig;
use crate::{Error, Result};
use camplace_estimator::{calibration::table_board_pose, geometry::rig_for};

/// Candidate poses drawn per pose kept, of which the best spread are chosen.
const CANDIDATES_PER_POSE: usize = 30;
/// The most draws for one candidate before giving up on fitting the board in both images.
const MAX_ATTEMPTS: usize = 10_000;
/// The board's tilt from facing the rig, at most, degrees: large tilts turn the flange about
/// axes across its own, which is what fixes the translation.
const MAX_TILT_DEG: f64 = 45.0;
/// The board's turn about its normal, at most either way, degrees.
const MAX_SPIN_DEG: f64 = 90.0;

/// The pose file `render --hand-eye` writes beside the images.
pub const ROBOT_POSES_FILE: &str = "robot_poses.txt";
/// The truth file `render --hand-eye` writes.
pub const HAND_EYE_TRUTH_FILE: &str = "hand_eye.json";

/// What robot poses to render.
#[derive(Debug, Clone)]
pub enum HandEyePoses {
    /// This many poses chosen from the seed, spread in rotation.
    Chosen(usize),
    /// These flange poses (base ← flange, mm), as a pose file gives them.
    Given(Vec<[[f64; 4]; 4]>),
}

/// How to simulate a hand-eye calibration.
#[derive(Debug, Clone)]
pub struct HandEyeOptions {
    /// Eye-to-hand or eye-in-hand.
    pub setup: HandEyeSetup,
    /// The poses.
    pub poses: HandEyePoses,
    /// The robot's error per axis of its reported translation, mm (1 σ).
    pub noise_mm: f64,
    /// The robot's error per axis of its reported rotation, degrees (1 σ).
    pub noise_deg: f64,
    /// How the pose file is written.
    pub format: RobotPoseFormat,
}

/// The truth of a hand-eye render (`hand_eye.json`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HandEyeTruth {
    /// `eye-to-hand` or `eye-in-hand`.
    pub setup: String,
    /// Inner corners along the board's x axis.
    pub cols: usize,
    /// Inner corners along its y axis.
    pub rows: usize,
    /// Side of a square, mm.
    pub square_mm: f64,
    /// World frame -> robot base frame.
    #[serde(rename = "T_robot_world")]
    pub t_robot_world: [[f64; 4]; 4],
    /// Eye-to-hand: board frame -> flange frame.
    #[serde(rename = "T_flange_board", default, skip_serializing_if = "Option::is_none")]
    pub t_flange_board: Option<[[f64; 4]; 4]>,
    /// Eye-in-hand: rig frame (the left camera's) -> flange frame.
    #[serde(rename = "T_flange_rig", default, skip_serializing_if = "Option::is_none")]
    pub t_flange_rig: Option<[[f64; 4]; 4]>,
    /// Eye-in-hand: the board lying on the table, board frame -> world.
    #[serde(rename = "T_world_board", default, skip_serializing_if = "Option::is_none")]
    pub t_world_board: Option<[[f64; 4]; 4]>,
    /// The true flange pose of each view, base ← flange (the file's poses carry the
    /// robot's error).
    #[serde(rename = "T_robot_flange")]
    pub t_robot_flange: Vec<[[f64; 4]; 4]>,
}

/// Where the robot's base lies in the world.
pub fn simulated_robot_base() -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(-600.0, 150.0, -20.0),
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 20f64.to_radians()),
    )
}

/// The board on the flange (eye-to-hand), board frame -> flange frame.
fn flange_board(board: &CalibrationBoard) -> Isometry3<f64> {
    let (w, h) = board_extent(board);
    let turn = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 10f64.to_radians());
    Isometry3::from_parts(
        Translation3::from(Vector3::new(5.0, -8.0, 60.0) - turn * Vector3::new(w / 2.0, h / 2.0, 0.0)),
        turn,
    )
}

/// The rig on the flange (eye-in-hand), rig frame -> flange frame: looking along the
/// flange's axis, turned a quarter about it.
fn flange_rig() -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(60.0, 0.0, 90.0),
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 90f64.to_radians()),
    )
}

fn normal(rng: &mut ChaCha8Rng) -> f64 {
    // Box–Muller.
    let (u, v): (f64, f64) = (rng.random_range(1e-12..1.0), rng.random_range(0.0..1.0));
    (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

/// Renders a hand-eye calibration's views into `out`: `frames/NNNN/left.png` + `right.png`
/// per robot pose, `robot_poses.txt` (the poses as the controller reports them),
/// `rig.json` (the rig at the placement: for eye-in-hand its cameras and the pose between
/// them matter, not where it stands), `hand_eye.json` (the truth), and eye-to-hand a
/// `table/` view that fixes the world frame for a calibration of the rig in the same run.
pub fn render_hand_eye_views(
    out: &Path,
    cell: &Cell,
    placement: &Placement,
    board: &CalibrationBoard,
    options: &HandEyeOptions,
    seed: u64,
) -> Result<HandEyeTruth> {
    let rig = rig_for(placement, &cell.sensor);
    let t_world_robot = simulated_robot_base();
    let t_robot_world = t_world_robot.inverse();
    let table = table_board_pose(board);
    let t_world_left = rig.left.t_world_camera;
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x4A4D_E7E0_0000_0038);
    // The board's pose in the world as the placement's rig renders it, and the flange's
    // true pose, per view.
    let (world_boards, flanges): (Vec<Isometry3<f64>>, Vec<Isometry3<f64>>) = match (&options.poses, options.setup) {
        (HandEyePoses::Chosen(n), setup) => {
            let candidates =
                draw_candidates(&rig, board, setup, n * CANDIDATES_PER_POSE, &mut rng).ok_or_else(|| {
                    Error::Other(format!(
                        "board {}x{}@{}: no robot pose shows the whole board to both cameras; use a smaller board",
                        board.cols, board.rows, board.square_mm
                    ))
                })?;
            spread_out(&candidates, *n)
                .into_iter()
                .map(|(board_pose, moved)| {
                    let flange = match setup {
                        HandEyeSetup::EyeToHand => t_robot_world * board_pose * flange_board(board).inverse(),
                        HandEyeSetup::EyeInHand => t_robot_world * moved * flange_rig().inverse(),
                    };
                    (board_pose, flange)
                })
                .unzip()
        }
        (HandEyePoses::Given(poses), setup) => poses
            .iter()
            .map(|rows| {
                let flange = isometry_from_rows(rows);
                let world_flange = t_world_robot * flange;
                let board_pose = match setup {
                    HandEyeSetup::EyeToHand => world_flange * flange_board(board),
                    HandEyeSetup::EyeInHand => t_world_left * (world_flange * flange_rig()).inverse() * table,
                };
                (board_pose, flange)
            })
            .unzip(),
    };
    std::fs::create_dir_all(out).map_err(|e| camplace_config::Error::io(out, &e))?;
    let mut jobs: Vec<(std::path::PathBuf, Isometry3<f64>, u64)> = world_boards
        .iter()
        .enumerate()
        .map(|(i, p)| (out.join("frames").join(frame_name(i as u64)), *p, i as u64))
        .collect();
    if options.setup == HandEyeSetup::EyeToHand {
        jobs.push((out.join("table"), table, world_boards.len() as u64));
    }
    render_board_pairs(&rig, &cell.sensor, board, &jobs, seed)?;
    write_rig(&out.join("rig.json"), &rig)?;
    // The controller's report: the true pose with the robot's error, drawn after the
    // poses so the poses do not depend on the noise's size.
    let reported: Vec<[[f64; 4]; 4]> = flanges
        .iter()
        .map(|f| {
            let dt = Vector3::new(normal(&mut rng), normal(&mut rng), normal(&mut rng)) * options.noise_mm;
            let dr =
                Vector3::new(normal(&mut rng), normal(&mut rng), normal(&mut rng)) * options.noise_deg.to_radians();
            let noisy = Isometry3::from_parts(
                Translation3::from(f.translation.vector + dt),
                f.rotation * UnitQuaternion::from_scaled_axis(dr),
            );
            isometry_to_rows(&noisy)
        })
        .collect();
    let comment = format!(
        "robot flange poses (base <- flange) of a simulated {} calibration, seed {seed},\n\
         robot error {} mm / {} deg per axis; line k goes with frames/k",
        options.setup.name(),
        options.noise_mm,
        options.noise_deg
    );
    let text = robot_poses_text(&reported, options.format, &comment);
    camplace_config::write_atomic(&out.join(ROBOT_POSES_FILE), text.as_bytes())?;
    let truth = HandEyeTruth {
        setup: options.setup.name().to_string(),
        cols: board.cols,
        rows: board.rows,
        square_mm: board.square_mm,
        t_robot_world: isometry_to_rows(&t_robot_world),
        t_flange_board: (options.setup == HandEyeSetup::EyeToHand).then(|| isometry_to_rows(&flange_board(board))),
        t_flange_rig: (options.setup == HandEyeSetup::EyeInHand).then(|| isometry_to_rows(&flange_rig())),
        t_world_board: (options.setup == HandEyeSetup::EyeInHand).then(|| isometry_to_rows(&table)),
        t_robot_flange: flanges.iter().map(isometry_to_rows).collect(),
    };
    let json = serde_json::to_string_pretty(&truth).map_err(|e| Error::Other(e.to_string()))?;
    camplace_config::write_atomic(&out.join(HAND_EYE_TRUTH_FILE), json.as_bytes())?;
    Ok(truth)
}

/// `count` candidate views, each as (the board's pose in the world for the placement's
/// rig, the moved rig's left camera in the world for eye-in-hand), every one showing the
/// whole board to both cameras.
fn draw_candidates(
    rig: &Rig,
    board: &CalibrationBoard,
    setup: HandEyeSetup,
    count: usize,
    rng: &mut ChaCha8Rng,
) -> Option<Vec<(Isometry3<f64>, Isometry3<f64>)>> {
    let (w, h) = board_extent(board);
    let t_world_left = rig.left.t_world_camera;
    let reach = rig.left.centre().coords.norm();
    let table = table_board_pose(board);
    let mut out = Vec::with_capacity(count);
    for _ in 0..count {
        let mut found = None;
        for _ in 0..MAX_ATTEMPTS {
            // The board relative to the left camera: ahead at 55 to 90 % of the distance to
            // the table, facing it, tilted and spun.
            let distance = rng.random_range(0.55..0.9) * reach;
            let centre = Vector3::new(
                rng.random_range(-0.25..0.25) * distance + 0.5 * rig.baseline(),
                rng.random_range(-0.2..0.2) * distance,
                distance,
            );
            let tilt_axis = rng.random_range(0.0..std::f64::consts::TAU);
            let tilt = UnitQuaternion::from_axis_angle(
                &nalgebra::Unit::new_normalize(Vector3::new(tilt_axis.cos(), tilt_axis.sin(), 0.0)),
                rng.random_range(0.0..MAX_TILT_DEG).to_radians(),
            );
            let spin = UnitQuaternion::from_axis_angle(
                &Vector3::z_axis(),
                rng.random_range(-MAX_SPIN_DEG..MAX_SPIN_DEG).to_radians(),
            );
            // Facing the camera: the board's z axis along the camera's -z.
            let facing = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI);
            let rotation = facing * tilt * spin;
            let t_left_board = Isometry3::from_parts(
                Translation3::from(centre - rotation * Vector3::new(w / 2.0, h / 2.0, 0.0)),
                rotation,
            );
            let board_pose = t_world_left * t_left_board;
            if !fits(rig, board, &board_pose) {
                continue;
            }
            // Eye-in-hand the board stays on the table and the rig moves: the left camera
            // where it sees the table's board as it sees this one.
            let moved = table * t_left_board.inverse();
            // A rig carried below the table or upside down is no pose a robot takes.
            if setup == HandEyeSetup::EyeInHand && moved.transform_point(&Point3::origin()).z < 150.0 {
                continue;
            }
            found = Some((board_pose, moved));
            break;
        }
        out.push(found?);
    }
    Some(out)
}

/// `n` of `candidates` spread in rotation: the first, then each time the one whose rotation
/// is farthest from all chosen so far.
fn spread_out(candidates: &[(Isometry3<f64>, Isometry3<f64>)], n: usize) -> Vec<(Isometry3<f64>, Isometry3<f64>)> {
    let mut chosen = vec![0];
    let mut nearest: Vec<f64> = candidates.iter().map(|c| c.0.rotation.angle_to(&candidates[0].0.rotation)).collect();
    while chosen.len() < n.min(candidates.len()) {
        let (next, _) = nearest
            .iter()
            .enumerate()
            .filter(|(i, _)| !chosen.contains(i))
            .max_by(|a, b| a.1.total_cmp(b.1))
            .expect("candidates left");
        chosen.push(next);
        for (d, c) in nearest.iter_mut().zip(candidates) {
            *d = d.min(c.0.rotation.angle_to(&candidates[next].0.rotation));
        }
    }
    chosen.into_iter().map(|i| candidates[i]).collect()
}
