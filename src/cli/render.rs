//! `camplace render`: one simulated scene with its ground truth, or (`--dataset`) a
//! recorded-dataset folder of scenarios 0..N-1 that `evaluate` and `replay` read alike,
//! into an empty folder (or, with `--force`, one emptied of an earlier dataset first), or
//! (`--board`) the calibration images of a chessboard.

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
    /// Output folder.
    #[arg(long)]
    out: PathBuf,
}

/// Runs `camplace render`.
pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let (cell, placement) = a.cell.load()?;
    let seed = a.scene.seed(&cell);
    if let Some(text) = &a.board {
        let board = super::calibrate::parse_board(text)?;
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
