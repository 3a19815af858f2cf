//! `camplace calibrate --hand-eye`: where the rig sits in the robot's frame, from board
//! images paired by index with the robot's flange poses. Reads the pose file, has hwio
//! list the views and find their corners, hands the frames and the pose lines to the
//! estimator's paired hand-eye calibration (which refuses poses that do not fit, naming the
//! likely cause), prints each pose's fit and writes the `[robot]` table the cell reads. Also the
//! pose-format flags `render` shares.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Context};
use camplace_config::{read_robot_poses, LengthUnit, PoseConvention, RigFile, RobotPoseFormat, RobotPoses};
use camplace_estimator::{
    calibration::calibrate_hand_eye_paired, calibration::BoardView, calibration::CalibrationBoard,
    calibration::FoundBoardPair, calibration::HandEyeCalibration, calibration::HandEyeSetup,
    calibration::PairedHandEye, geometry::isometry_to_rows, Rig,
};
use camplace_hwio::{board_view_folders, find_board_views};
use nalgebra::Isometry3;

/// The flags naming a robot pose file's convention and unit.
#[derive(clap::Args, Debug, Clone)]
pub struct PoseFormatArgs {
    /// The pose file's convention when it has no `format` line: matrix, quat-wxyz,
    /// quat-xyzw, ur, kuka, abb or fanuc (docs/formats.md).
    #[arg(long, value_name = "CONVENTION")]
    pub pose_format: Option<String>,
    /// The pose file's translation unit when it has no `format` line: mm or m.
    #[arg(long, value_name = "mm|m")]
    pub pose_unit: Option<String>,
}

impl PoseFormatArgs {
    /// The format the flags name: `None` when neither is given; both or neither.
    pub fn format(&self) -> anyhow::Result<Option<RobotPoseFormat>> {
        let convention = match &self.pose_format {
            Some(name) => Some(
                PoseConvention::from_name(name)
                    .with_context(|| format!("--pose-format {name:?}: expected one of {}", PoseConvention::names()))?,
            ),
            None => None,
        };
        let unit = match &self.pose_unit {
            Some(name) => {
                Some(LengthUnit::from_name(name).with_context(|| format!("--pose-unit {name:?}: expected mm or m"))?)
            }
            None => None,
        };
        match (convention, unit) {
            (Some(convention), Some(unit)) => Ok(Some(RobotPoseFormat { convention, unit })),
            (None, None) => Ok(None),
            (Some(_), None) => bail!("--pose-format without --pose-unit: expected both (the unit: mm or m)"),
            (None, Some(_)) => bail!("--pose-unit without --pose-format: expected both (the convention too)"),
        }
    }
}

/// What `calibrate --hand-eye` needs besides the board.
pub struct HandEyeArgs<'a> {
    pub images: &'a Path,
    pub robot_poses: &'a Path,
    pub formats: &'a PoseFormatArgs,
    pub setup: HandEyeSetup,
    /// The calibrated rig and the file it came from.
    pub rig: Rig,
    pub rig_path: PathBuf,
    /// Eye-in-hand: the fixed board's pose in the world.
    pub t_world_board: Isometry3<f64>,
    pub out: &'a Path,
    /// The robot's accuracy per axis (1 σ): mm ...
    pub robot_accuracy_mm: f64,
    /// ... and degrees.
    pub robot_accuracy_deg: f64,
}

/// The rig of a `rig.json`.
pub fn load_rig(path: &Path) -> anyhow::Result<Rig> {
    let file = RigFile::load(path)?;
    file.check().map_err(|e| e.in_file(path))?;
    Ok(Rig::from_file(&file))
}

/// Runs the hand-eye calibration.
pub fn run(a: HandEyeArgs<'_>, board: &CalibrationBoard) -> anyhow::Result<ExitCode> {
    let poses: RobotPoses = read_robot_poses(a.robot_poses, a.formats.format()?)?;
    let frames = a.images.join("frames");
    let folders = board_view_folders(a.images)?;
    if folders.len() != poses.poses.len() {
        bail!(
            "{}: {} poses, but {} holds {} frames; expected one pose a frame, in the frames' order",
            a.robot_poses.display(),
            poses.poses.len(),
            frames.display(),
            folders.len()
        );
    }
    let found = find_board_views(a.images, &folders, board, (a.rig.left.width, a.rig.left.height))?;
    let names: Vec<String> =
        folders.iter().map(|f| f.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default()).collect();
    let mut views = Vec::with_capacity(found.len());
    for (i, FoundBoardPair { left, right, .. }) in found.into_iter().enumerate() {
        if left.is_err() && right.is_err() {
            outln!(
                "left out: pose {i} ({}:{}), frames/{}: the whole board is in neither image",
                a.robot_poses.display(),
                poses.lines[i],
                names[i]
            );
            views.push(None);
        } else {
            views.push(Some(BoardView { left: left.ok(), right: right.ok() }));
        }
    }
    let job = PairedHandEye {
        setup: a.setup,
        board,
        left: &a.rig.left,
        right: &a.rig.right,
        frames: &views,
        poses: &poses,
        robot_sigma_mm: a.robot_accuracy_mm,
        robot_sigma_deg: a.robot_accuracy_deg,
    };
    let started = std::time::Instant::now();
    let cal = calibrate_hand_eye_paired(&job).with_context(|| a.robot_poses.display().to_string())?;
    let seconds = started.elapsed().as_secs_f64();
    print_poses(&cal, &names, &poses, a.robot_poses);
    let s = &cal.spread;
    let kept = cal.poses.iter().filter(|p| !p.dropped).count();
    outln!(
        "rotation spread: {kept} poses, turns between them up to {:.1}°, their axes up to {:.1}° apart ({} pairs \
         turned 5° or more)",
        s.max_rotation_deg,
        s.max_axis_angle_deg,
        s.informative_pairs
    );
    let e = &cal.expected;
    outln!(
        "expected error (1 σ, from the residuals): rig ±{:.3} mm ±{:.4}°, board ±{:.3} mm ±{:.4}°",
        e.rig_translation_mm,
        e.rig_rotation_deg,
        e.board_translation_mm,
        e.board_rotation_deg
    );
    for w in &cal.warnings {
        outln!("warning: {w}");
    }
    let (t_robot_world, t_flange_rig) = match a.setup {
        HandEyeSetup::EyeToHand => (cal.t_mount_rig * a.rig.left.t_world_camera.inverse(), None),
        HandEyeSetup::EyeInHand => (cal.t_mount_board * a.t_world_board.inverse(), Some(cal.t_mount_rig)),
    };
    let robot = camplace_config::Robot {
        t_robot_world: isometry_to_rows(&t_robot_world),
        t_flange_rig: t_flange_rig.as_ref().map(isometry_to_rows),
        pose_format: None,
    };
    let comment = format!(
        "camplace calibrate --hand-eye ({}): {kept} poses ({}), reprojection RMS {:.3} px, expected error ±{:.3} mm \
         ±{:.4}° (1 σ);\nthe world frame is {}'s",
        cal.setup.name(),
        poses.format,
        cal.rms_px,
        cal.expected.rig_translation_mm,
        cal.expected.rig_rotation_deg,
        a.rig_path.display()
    );
    let text = robot.to_toml(&comment).map_err(|e| anyhow::anyhow!("the calibrated [robot] table: {e}"))?;
    camplace_config::write_atomic(a.out, text.as_bytes())?;
    outln!(
        "{} from {kept} poses in {seconds:.3} s: reprojection RMS {:.3} px; wrote {}",
        a.setup.name(),
        cal.rms_px,
        a.out.display()
    );
    out!("{text}");
    Ok(ExitCode::SUCCESS)
}

/// Each pose's fit; a dropped pose named on a line of its own.
fn print_poses(cal: &HandEyeCalibration, names: &[String], poses: &RobotPoses, file: &Path) {
    outln!(
        "{:<6} {:<8} {:>5} {:>9} {:>7} {:>9} {:>9}   (mm, deg: the correction of the robot's pose the fit took)",
        "pose",
        "frame",
        "line",
        "px",
        "score",
        "mm",
        "deg"
    );
    let kept: Vec<f64> = cal.poses.iter().filter(|p| !p.dropped).map(|p| p.score).collect();
    let median = camplace_estimator::scoring::median(&kept).unwrap_or(0.0);
    for p in &cal.poses {
        let (index, name) = (p.index, &names[p.index]);
        let line = poses.lines[index];
        let mark = if p.dropped { "  dropped" } else { "" };
        outln!(
            "{index:<6} {name:<8} {line:>5} {:>9.3} {:>7.2} {:>9.3} {:>9.4}{mark}",
            p.rms_px,
            p.score,
            p.translation_mm,
            p.rotation_deg
        );
    }
    for p in cal.poses.iter().filter(|p| p.dropped) {
        let (index, name) = (p.index, &names[p.index]);
        outln!(
            "dropped pose {index} (frames/{name}, {}:{}): score {:.1} against a median of {median:.1} (the robot's \
             pose {:.1} mm, {:.2}° off to fit); its image and robot pose do not match (mis-paired, or the robot moved \
             while the images were taken)",
            file.display(),
            poses.lines[index],
            p.score,
            p.translation_mm,
            p.rotation_deg
        );
    }
}
