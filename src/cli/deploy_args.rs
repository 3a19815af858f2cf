//! The flags of the commands that run the deployed estimator on a frame source, `run` and
//! `serve`: the source, the model, the cell with its tray, and the rig and background a
//! camera needs.

use camplace_config::Cell;
use std::path::PathBuf;

/// `--source`, `--model`, `--cell`, `--tray`, `--rig` and `--background`.
#[derive(clap::Args, Debug)]
pub struct DeployArgs {
    /// Where frames come from: dir:PATH (a recorded dataset), v4l2:LEFT,RIGHT, v4l2-sbs:DEV,
    /// v4l2-16:DEV or dc1394[:GUID] (see docs/hardware.md).
    #[arg(long, value_name = "SPEC")]
    pub source: String,
    /// The tray model (from `camplace model`).
    #[arg(long, value_name = "FILE")]
    pub model: PathBuf,
    /// Cell file (TOML) with the estimator settings (and `[robot]` for poses in the robot's
    /// frame); the built-in default when not given. The model must have been built for its
    /// tray.
    #[arg(long, value_name = "FILE")]
    pub cell: Option<PathBuf>,
    /// Which of the cell's listed trays (`[[trays]]` name) when it lists several.
    #[arg(long, value_name = "NAME")]
    pub tray: Option<String>,
    /// Calibration of the cameras (needed for cameras; a dataset's own rig.json otherwise).
    #[arg(long, value_name = "FILE")]
    pub rig: Option<PathBuf>,
    /// A folder with the empty cell's images, named as a frame's (left.png, right.png; a
    /// shot per pattern, left_00.png … right_11.png, for phase-12); a dataset's own
    /// background/ otherwise.
    #[arg(long, value_name = "DIR")]
    pub background: Option<PathBuf>,
}

impl DeployArgs {
    /// The cell (the file, or the built-in one) with its one tray (`--tray` picks one of a
    /// listed cell).
    pub fn cell(&self) -> anyhow::Result<Cell> {
        Ok(Cell::load_one(self.cell.as_deref(), self.tray.as_deref())?)
    }
}
