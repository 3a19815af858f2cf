//! A sweep: a grid over two placement parameters (the paper's Figures 5 and 6) run into a
//! study folder, with `sweep.json` saying which grid it holds.

use std::path::Path;

use camplace_config::write_atomic;
use camplace_config::{Cell, Placement};

use super::folder::open_folder;
use super::jobs::{shard_jobs, JobEvaluator};
use super::shard::Shard;
use crate::render::Method;
use crate::report::sweep_panels::{write_sweep_outputs, SweepResult};
use crate::{Error, Result};
use camplace_config::Grid;

/// Runs (this shard of) the grid into `dir` and writes its outputs.
#[allow(clippy::too_many_arguments)]
pub fn sweep(
    dir: &Path,
    cell: &Cell,
    base: &Placement,
    method: Method,
    seed: u64,
    grid: &Grid,
    scenarios: u64,
    shard: Shard,
    label: &str,
) -> Result<SweepResult> {
    let placements = grid.placements(base).map_err(|e| Error::Other(format!("--x/--y: {e}")))?;
    let store = open_folder(dir, cell, method, seed)?;
    let grid_text = serde_json::to_string_pretty(&(grid, scenarios, base)).expect("a grid is plain data");
    write_atomic(&dir.join("sweep.json"), grid_text.as_bytes())?;
    let jobs = shard_jobs(&placements, seed, scenarios, shard);
    JobEvaluator::new(cell, method, &store).evaluate(&jobs, label)?;
    write_sweep_outputs(dir, cell, grid, &placements, &store, method, seed, scenarios)
}

/// The grid, scenario count and base placement of a sweep folder, if it holds one.
pub fn load_sweep(dir: &Path) -> Result<Option<(Grid, u64, Placement)>> {
    let path = dir.join("sweep.json");
    if !path.exists() {
        return Ok(None);
    }
    let text = camplace_config::read_text(&path)?;
    let v = serde_json::from_str(&text).map_err(|e| {
        Error::Other(format!("{}: expected a sweep's grid, scenario count and base placement: {e}", path.display()))
    })?;
    Ok(Some(v))
}
