//! The flags every simulation command shares: the cell file and a placement override.

use anyhow::Context;
use camplace_config::{Cell, Placement};
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
        let cell = self.one_tray(self.read()?)?;
        let placement = self.placement(&cell)?;
        Ok((cell, placement))
    }

    /// Every tray the cell serves as a cell of its own with its name (only `--tray`'s when
    /// given), and the placement: for the commands that judge a placement over all trays.
    pub fn load_trays(&self) -> anyhow::Result<(Vec<(String, Cell)>, Placement)> {
        let cell = self.read()?;
        let trays = match &self.tray {
            Some(name) => vec![(name.clone(), self.one_tray(cell)?)],
            None => cell.tray_cells(),
        };
        let placement = self.placement(&trays[0].1)?;
        Ok((trays, placement))
    }

    fn read(&self) -> anyhow::Result<Cell> {
        Ok(match &self.cell {
            Some(path) => Cell::load(path)?,
            None => Cell::default(),
        })
    }

    fn one_tray(&self, cell: Cell) -> anyhow::Result<Cell> {
        cell.one_tray(self.tray.as_deref()).map_err(|e| match &self.cell {
            Some(path) => anyhow::Error::new(e.in_file(path)),
            None => anyhow::Error::new(e),
        })
    }

    fn placement(&self, cell: &Cell) -> anyhow::Result<Placement> {
        Ok(match &self.placement {
            Some(text) => cell.placement.with_overrides(text).context("--placement")?,
            None => cell.placement,
        })
    }
}
