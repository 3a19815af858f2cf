//! `camplace render`: one simulated scene with its ground truth, or (`--dataset`) a
//! recorded-dataset folder of scenarios 0..N-1 that `evaluate` and `replay` read alike,
//! into an empty folder (or, with `--force`, one emptied of an earlier dataset first), or
//! (`--board`) the calibration images of a chessboard, held by hand or (`--hand-eye`,
//! `--robot-poses`) by a robot.

use camplace_sim::{clear_dataset, render_board_views, render_dataset, render_scene};
use std::path::PathBuf;
use std::process::ExitCode;

use super::cell_args::CellArgs;
use super::study_args::SceneArgs;

/// Flags of `camplace render`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    cell: CellArgs,
    #[command(flatten)]
    scene: SceneArgs,
    /// Scenario index within the seed.
    #[arg(long, default_value_t = 0)]
    scenario: u64,
    /// Write a recorded-dataset folder of scenarios 0..count-1 instead of one scene.
    #[arg(long)]
    dataset: bool,
    /// Number of scenarios with --dataset, 1 to 1000000.
    #[arg(long, default_value_t = 10, requires = "dataset", value_parser = clap::value_parser!(u64).range(1..=1_000_000))]
    count: u64,
    /// With --dataset: first remove the dataset already in the output folder (only files
    /// camplace writes into a dataset; a folder holding anything else is refused).
    #[arg(long, requires = "dataset")]
    force: bool,
    /// Render calibration images instead of a scene: stereo pairs of a chessboard of
    /// COLSxROWS inner corners and SQUARE_MM squares (e.g. 9x6@25) in random poses, one lying
    /// on the table, with the true rig.json and board.json; what `calibrate` reads.
    #[arg(long, value_name = "COLSxROWS@MM", conflicts_with = "dataset")]
    board: Option<String>,
    /// Board poses with --board (besides the table view), 3 to 1000.
    #[arg(long, default_value_t = 15, requires = "board", value_parser = clap::value_parser!(u64).range(3..=1000))]
    views: u64,
    /// With --board: N robot poses chosen from the seed, spread in rotation, for a hand-eye
    /// calibration (the board on the flange seen by the fixed rig, or with --eye-in-hand
    /// the rig on the flange over the board on the table), 3 to 1000.
    #[arg(long, value_name = "N", requires = "board", conflicts_with_all = ["views", "robot_poses"],
          value_parser = clap::value_parser!(u64).range(3..=1000))]
    hand_eye: Option<u64>,
    /// With --board: the robot's flange poses to render (a pose file, docs/formats.md),
    /// for a hand-eye calibration.
    #[arg(long, value_name = "FILE", requires = "board", conflicts_with = "views")]
    robot_poses: Option<PathBuf>,
    /// With --hand-eye or --robot-poses: the rig on the flange, the board fixed on the table.
    #[arg(long)]
    eye_in_hand: bool,
    /// The robot's error per axis of each reported translation, mm (1 σ), 0 to 10.
    #[arg(long, value_name = "MM", default_value_t = 0.1)]
    robot_noise_mm: f64,
    /// The robot's error per axis of each reported rotation, degrees (1 σ), 0 to 5.
    #[arg(long, value_name = "DEG", default_value_t = 0.02)]
    robot_noise_deg: f64,
    /// How the robot poses are written (and a --robot-poses file without a `format` line is
    /// read); default kuka mm.
    #[command(flatten)]
    pose_format: super::hand_eye::PoseFormatArgs,
    /// Output folder.
    #[arg(long)]
    out: PathBuf,
}

/// Runs `camplace render`.
pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let (cell, placement) = a.cell.load()?;
    let seed = a.scene.seed(&cell);
    if a.board.is_none() && (a.eye_in_hand || a.hand_eye.is_some() || a.robot_poses.is_some()) {
        anyhow::bail!("--eye-in-hand, --hand-eye and --robot-poses: expected with --board COLSxROWS@MM");
    }
    if let Some(text) = &a.board {
        let board = super::calibrate::parse_board(text)?;
        if a.hand_eye.is_some() || a.robot_poses.is_some() {
            return render_hand_eye(&a, &cell, &placement, &board, text, seed);
        }
        if a.eye_in_hand {
            anyhow::bail!("--eye-in-hand: expected with --hand-eye N or --robot-poses FILE");
        }
        render_board_views(&a.out, &cell, &placement, &board, a.views as usize, seed)?;
        outln!(
            "rendered {} views of a {text} board and the table view at {placement} (seed {seed}) into {}",
            a.views,
            a.out.display()
        );
        return Ok(ExitCode::SUCCESS);
    }
    if !a.dataset {
        render_scene(&a.out, &cell, &placement, a.scene.method, seed, a.scenario)?;
        outln!(
            "rendered scenario {} of seed {seed} at {placement} ({}) into {}",
            a.scenario,
            a.scene.method,
            a.out.display()
        );
        return Ok(ExitCode::SUCCESS);
    }
    let removed = if a.force { clear_dataset(&a.out)? } else { 0 };
    render_dataset(&a.out, &cell, &placement, a.scene.method, seed, a.count)?;
    let replaced =
        if removed > 0 { format!(" (the {removed} files of the dataset there removed first)") } else { String::new() };
    outln!(
        "rendered {} scenarios of seed {seed} at {placement} ({}) into {}{replaced}",
        a.count,
        a.scene.method,
        a.out.display()
    );
    Ok(ExitCode::SUCCESS)
}

/// `render --board B --hand-eye N` or `--robot-poses FILE`: a hand-eye calibration's views.
fn render_hand_eye(
    a: &Args,
    cell: &camplace_config::Cell,
    placement: &camplace_config::Placement,
    board: &camplace_estimator::calibration::CalibrationBoard,
    text: &str,
    seed: u64,
) -> anyhow::Result<ExitCode> {
    use camplace_config::{LengthUnit, PoseConvention, RobotPoseFormat};
    use camplace_estimator::calibration::HandEyeSetup;
    use camplace_sim::{render_hand_eye_views, HandEyeOptions, HandEyePoses};
    if !(a.robot_noise_mm.is_finite() && (0.0..=10.0).contains(&a.robot_noise_mm)) {
        anyhow::bail!("--robot-noise-mm {}: expected a robot error from 0 to 10 mm", a.robot_noise_mm);
    }
    if !(a.robot_noise_deg.is_finite() && (0.0..=5.0).contains(&a.robot_noise_deg)) {
        anyhow::bail!("--robot-noise-deg {}: expected a robot error from 0 to 5 degrees", a.robot_noise_deg);
    }
    let flags = a.pose_format.format()?;
    let (poses, format) = match (&a.robot_poses, a.hand_eye) {
        (Some(path), _) => {
            let file = camplace_config::read_robot_poses(path, flags)?;
            (HandEyePoses::Given(file.poses), file.format)
        }
        (None, Some(n)) => (
            HandEyePoses::Chosen(n as usize),
            flags.unwrap_or(RobotPoseFormat { convention: PoseConvention::Kuka, unit: LengthUnit::Mm }),
        ),
        (None, None) => unreachable!("called with --hand-eye or --robot-poses"),
    };
    let setup = if a.eye_in_hand { HandEyeSetup::EyeInHand } else { HandEyeSetup::EyeToHand };
    let options = HandEyeOptions { setup, poses, noise_mm: a.robot_noise_mm, noise_deg: a.robot_noise_deg, format };
    let truth = render_hand_eye_views(&a.out, cell, placement, board, &options, seed)?;
    outln!(
        "rendered {} robot poses ({}) of a {text} board at {placement} (seed {seed}), robot error {} mm / {}°, poses \
         as {format}, into {}",
        truth.t_robot_flange.len(),
        setup.name(),
        a.robot_noise_mm,
        a.robot_noise_deg,
        a.out.display()
    );
    Ok(ExitCode::SUCCESS)
}
