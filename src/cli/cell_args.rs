//! The flags every simulation command shares: the cell file and a placement override, and
//! for the commands that judge one sensor, the rig as installed.

use anyhow::Context;
use camplace_config::{Cell, Placement};
#[cfg(feature = "sim")]
use camplace_config::{RigFile, Vergence};
#[cfg(feature = "sim")]
use camplace_estimator::{geometry::as_built, Rig};
use std::path::PathBuf;

/// `--cell FILE` and `--placement r=..,alpha=..,baseline=..,vergence=..`.
#[derive(clap::Args, Debug, Clone)]
pub struct CellArgs {
    /// Cell file (TOML); the built-in default cell when not given.
    #[arg(long, value_name = "FILE")]
    pub cell: Option<PathBuf>,
    /// Placement overrides, e.g. r=605,alpha=32,baseline=81,vergence=3.5 (vergence may be "auto").
    #[arg(long, value_name = "P")]
    pub placement: Option<String>,
    /// Which of the cell's listed trays (`[[trays]]` name) when it lists several.
    #[arg(long, value_name = "NAME")]
    pub tray: Option<String>,
}

impl CellArgs {
    /// The cell (file or built-in) with its one tray (`--tray` picks one of a listed cell),
    /// and the placement with overrides applied.
    pub fn load(&self) -> anyhow::Result<(Cell, Placement)> {
        let cell = Cell::load_one(self.cell.as_deref(), self.tray.as_deref())?;
        let placement = self.placement(&cell)?;
        Ok((cell, placement))
    }

    /// Every tray the cell serves as a cell of its own with its name (only `--tray`'s when
    /// given), and the placement: for the commands that judge a placement over all trays.
    #[cfg(feature = "sim")]
    pub fn load_trays(&self) -> anyhow::Result<(Vec<(String, Cell)>, Placement)> {
        let trays = match &self.tray {
            Some(name) => vec![(name.clone(), Cell::load_one(self.cell.as_deref(), Some(name))?)],
            None => Cell::load_or_default(self.cell.as_deref())?.tray_cells(),
        };
        let placement = self.placement(&trays[0].1)?;
        Ok((trays, placement))
    }

    fn placement(&self, cell: &Cell) -> anyhow::Result<Placement> {
        Ok(match &self.placement {
            Some(text) => cell.placement.with_overrides(text).context("--placement")?,
            None => cell.placement,
        })
    }
}

/// `--rig FILE`, for the commands that judge one sensor: simulate the rig as installed.
#[cfg(feature = "sim")]
#[derive(clap::Args, Debug, Clone)]
pub struct InstalledRigArg {
    /// The rig as installed (a calibrated rig.json): scenes are rendered by its cameras, with
    /// the cell's projector where the placement puts it relative to the left camera, instead
    /// of by a planned placement's rig. The placement is then the rig's as built.
    #[arg(long, value_name = "FILE", conflicts_with = "placement")]
    pub rig: Option<PathBuf>,
}

#[cfg(feature = "sim")]
impl InstalledRigArg {
    /// Sets the cell's installed rig from `--rig` and the placement to where it is mounted.
    pub fn apply(&self, cell: &mut Cell, placement: &mut Placement) -> anyhow::Result<()> {
        let Some(path) = &self.rig else { return Ok(()) };
        let file = RigFile::load(path)?;
        let built = as_built(&Rig::from_file(&file)).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
        cell.rig = Some(file);
        // The placement labels results and places the projector: a micrometre and a
        // micro-degree are far below what a calibration resolves, and keep labels short.
        let round = |v: f64| (v * 1e6).round() / 1e6;
        let p = built.placement;
        *placement = Placement {
            r: round(p.r),
            alpha: round(p.alpha),
            baseline: round(p.baseline),
            vergence: Vergence::Degrees(round(p.vergence.degrees(p.r, p.baseline))),
            azimuth: round(p.azimuth),
        };
        Ok(())
    }
}

/// A cell with an installed rig (`[rig]`) fixes the cameras, so a command that varies the
/// placement cannot use it.
#[cfg(feature = "sim")]
pub fn refuse_installed_rig(cell: &Cell, command: &str) -> anyhow::Result<()> {
    if cell.rig.is_some() {
        anyhow::bail!(
            "--cell: its [rig] fixes the cameras where they are installed, but {command} varies the placement; remove [rig] (use it with evaluate, accept and model)"
        );
    }
    Ok(())
}
