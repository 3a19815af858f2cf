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
    /// The cell (file or built-in) and the placement with overrides applied.
    pub fn load(&self) -> anyhow::Result<(Cell, Placement)> {
        let cell = match &self.cell {
            Some(path) => {
                Cell::load(path)?.one_tray(self.tray.as_deref()).map_err(|e| anyhow::Error::new(e.in_file(path)))?
            }
            None => Cell::default().one_tray(self.tray.as_deref())?,
        };
        let placement = match &self.placement {
            Some(text) => cell.placement.with_overrides(text).context("--placement")?,
            None => cell.placement,
        };
        Ok((cell, placement))
    }
}
