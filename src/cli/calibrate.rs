//! `camplace calibrate`: the installed rig's `rig.json` from stereo pairs of a chessboard —
//! each camera's K and distortion and the pose between them from every view, the world frame
//! from the view of the board lying flat on the table. hwio reads the folder `capture` writes
//! (`frames/NNNN/left.png` + `right.png`, and `table/`; `render --board` writes the same) and
//! finds the corners, the estimator calibrates; this prints.
//! With `--hand-eye`, then where the rig sits in the robot's frame (`hand_eye.rs`).

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Context};
use camplace_estimator::{
    calibration::CalibrationBoard, calibration::HandEyeSetup, calibration::RigCalibration,
    calibration::StereoCalibration, Rig,
};
use camplace_hwio::find_board_pairs;
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

/// Flags of `camplace calibrate`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Folder of board images: frames/NNNN/left.png + right.png, and table/ with the board
    /// lying flat on the table (as `capture` and `capture --table` write them).
    #[arg(long, value_name = "DIR")]
    images: PathBuf,
    /// The board: inner corners across x down, and the square side, as COLSxROWS@SQUARE_MM.
    #[arg(long, value_name = "COLSxROWS@MM")]
    board: String,
    /// Where the table view's board lies in the world: its first corner's x, y, z (mm) and the
    /// turn of its x axis from the world's x about z (deg). Default: the board centred on the
    /// world origin with its axes along the world's.
    #[arg(long, value_name = "X,Y,Z,YAW", allow_hyphen_values = true)]
    board_in_world: Option<String>,
    /// The file to write: the rig.json (default `rig.json`), or with --hand-eye the `[robot]`
    /// table (default `robot.toml`).
    #[arg(long, value_name = "FILE")]
    out: Option<PathBuf>,
    /// Hand-eye calibration: where the rig sits in the robot's frame, from the board images
    /// paired by index with --robot-poses; writes the `[robot]` table the cell reads.
    #[arg(long, requires = "robot_poses")]
    hand_eye: bool,
    /// The robot's flange poses, one a line, line k with frames/k (docs/formats.md).
    #[arg(long, value_name = "FILE", requires = "hand_eye")]
    robot_poses: Option<PathBuf>,
    /// The rig on the robot's flange looking at a board fixed on the table (its pose in the
    /// world: --board-in-world); without it the rig is fixed and the board on the flange.
    #[arg(long, requires = "hand_eye")]
    eye_in_hand: bool,
    /// The calibrated rig for --hand-eye; without it the rig is calibrated from the same
    /// images first (with table/, as `calibrate` alone) and written to rig.json beside --out.
    #[arg(long, value_name = "FILE", requires = "hand_eye")]
    rig: Option<PathBuf>,
    #[command(flatten)]
    pose_format: super::hand_eye::PoseFormatArgs,
    /// With --hand-eye: the robot's accuracy, 1 σ per axis of a reported translation, mm;
    /// each pose's correction is held to it.
    #[arg(long, value_name = "MM", default_value_t = 0.1, requires = "hand_eye")]
    robot_accuracy_mm: f64,
    /// With --hand-eye: the robot's accuracy, 1 σ per axis of a reported rotation, degrees.
    #[arg(long, value_name = "DEG", default_value_t = 0.02, requires = "hand_eye")]
    robot_accuracy_deg: f64,
}

/// Parses `COLSxROWS@SQUARE_MM`, e.g. `9x6@25` (`--board`).
pub fn parse_board(text: &str) -> anyhow::Result<CalibrationBoard> {
    text.parse().map_err(|e| anyhow::anyhow!("--board {text:?}: {e}"))
}

/// The table board's pose in the world from `X,Y,Z,YAW`.
fn parse_board_in_world(text: &str) -> anyhow::Result<Isometry3<f64>> {
    let v: Vec<f64> = text.split(',').map(|s| s.trim().parse::<f64>()).collect::<Result<_, _>>().unwrap_or_default();
    if v.len() != 4 || !v.iter().all(|x| x.is_finite()) {
        bail!("--board-in-world {text:?}: expected X,Y,Z,YAW (mm, mm, mm, deg), four numbers");
    }
    Ok(Isometry3::from_parts(
        Translation3::new(v[0], v[1], v[2]),
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), v[3].to_radians()),
    ))
}

/// Runs `camplace calibrate`.
pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let board = parse_board(&a.board)?;
    let t_world_table_board = match &a.board_in_world {
        Some(text) => parse_board_in_world(text)?,
        None => camplace_estimator::calibration::table_board_pose(&board),
    };
    if !a.hand_eye {
        let out = a.out.clone().unwrap_or_else(|| PathBuf::from("rig.json"));
        calibrate_rig(&a, &board, &t_world_table_board, &out)?;
        return Ok(ExitCode::SUCCESS);
    }
    let out = a.out.clone().unwrap_or_else(|| PathBuf::from("robot.toml"));
    let (rig, rig_path) = match &a.rig {
        Some(path) => (super::hand_eye::load_rig(path)?, path.clone()),
        None => {
            let path = out.parent().unwrap_or(Path::new("")).join("rig.json");
            (calibrate_rig(&a, &board, &t_world_table_board, &path)?, path)
        }
    };
    let setup = if a.eye_in_hand { HandEyeSetup::EyeInHand } else { HandEyeSetup::EyeToHand };
    let args = super::hand_eye::HandEyeArgs {
        images: &a.images,
        robot_poses: a.robot_poses.as_deref().context("--hand-eye needs --robot-poses FILE")?,
        formats: &a.pose_format,
        setup,
        rig,
        rig_path,
        t_world_board: t_world_table_board,
        out: &out,
        robot_accuracy_mm: a.robot_accuracy_mm,
        robot_accuracy_deg: a.robot_accuracy_deg,
    };
    if !(a.robot_accuracy_mm.is_finite() && a.robot_accuracy_mm > 0.0 && a.robot_accuracy_mm <= 100.0) {
        bail!("--robot-accuracy-mm {}: expected a positive accuracy up to 100 mm", a.robot_accuracy_mm);
    }
    if !(a.robot_accuracy_deg.is_finite() && a.robot_accuracy_deg > 0.0 && a.robot_accuracy_deg <= 10.0) {
        bail!("--robot-accuracy-deg {}: expected a positive accuracy up to 10 degrees", a.robot_accuracy_deg);
    }
    super::hand_eye::run(args, &board)
}

/// The stereo calibration from the board images: prints each view's error and the
/// cameras, writes the rig to `out` and returns it.
fn calibrate_rig(
    a: &Args,
    board: &CalibrationBoard,
    t_world_table_board: &Isometry3<f64>,
    out: &Path,
) -> anyhow::Result<Rig> {
    let found = find_board_pairs(&a.images, board)?;
    let RigCalibration { rig, stereo: cal, names, not_in_view, seconds } =
        camplace_estimator::calibration::calibrate_rig(
            found.pairs,
            board,
            found.width,
            found.height,
            t_world_table_board,
        )
        .with_context(|| a.images.display().to_string())?;
    let file = rig.to_file();
    file.check().map_err(|e| anyhow::anyhow!("the calibrated rig: {e}"))?;
    file.save(out)?;
    // Printed once rig.json is written: a reader that stops early loses nothing.
    for line in &not_in_view {
        outln!("not in view: {line}");
    }
    print_views(&cal, &names);
    warn_of_folds_past_the_corners(&file);
    let b = rig.baseline();
    outln!(
        "calibrated from {} views in {seconds:.3} s: reprojection RMS {:.3} px, baseline {b:.2} mm; wrote {}",
        cal.views.iter().filter(|v| !v.dropped).count(),
        cal.rms_px,
        out.display()
    );
    outln!(
        "k3: {}",
        if cal.k3_estimated {
            "refined (freeing it lowered the error beyond what noise explains)"
        } else {
            "held at 0 (freeing it did not lower the error beyond what noise explains)"
        }
    );
    for (side, c) in [("left", &rig.left), ("right", &rig.right)] {
        let d = c.dist;
        outln!(
            "{side:<5} fx {:.2} fy {:.2} cx {:.2} cy {:.2}  k1 {:.5} k2 {:.5} p1 {:.6} p2 {:.6} k3 {:.5}",
            c.k[(0, 0)],
            c.k[(1, 1)],
            c.k[(0, 2)],
            c.k[(1, 2)],
            d[0],
            d[1],
            d[2],
            d[3],
            d[4]
        );
    }
    Ok(rig)
}

/// How far past the image's farthest corner a fold is still worth a warning, in corner radii:
/// farther out no pixel comes near it.
const FOLD_WARNING_HORIZON: f64 = 1.5;

/// A warning for each camera whose distortion folds back outside the image but near it: the
/// check holds the lens one-to-one over the image only, and a real lens's polynomial, fitted
/// to corners inside the image, may turn over just past them; whoever extrapolates the model
/// beyond the corners (a wider canvas, another crop) should know where it stops holding.
fn warn_of_folds_past_the_corners(file: &camplace_config::RigFile) {
    for (side, c) in [("left", &file.left), ("right", &file.right)] {
        if let Some(fold) = camplace_config::distortion_fold(&c.dist, c.width, c.height, &c.k, FOLD_WARNING_HORIZON) {
            outln!(
                "warning: {side}.dist folds back at {:.0} % of the way from the principal point to the farthest image corner, beyond the {} corner: one-to-one over the image, but the lens model does not hold past the fold",
                100.0 * fold.fraction_of_corner,
                fold.corner
            );
        }
    }
}

/// Each view's reprojection error, the dropped ones marked.
fn print_views(cal: &StereoCalibration, names: &[String]) {
    outln!("{:<14} {:>9} {:>9}", "view", "left px", "right px");
    let px = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.3}"));
    for v in &cal.views {
        let mark = if v.dropped { "  dropped: its error stands out" } else { "" };
        outln!("{:<14} {:>9} {:>9}{mark}", names[v.index], px(v.rms_left_px), px(v.rms_right_px));
    }
}
