//! `camplace sweep`: a grid over two placement parameters (the paper's Figures 5 and 6)
//! into a study folder: results.jsonl, summary.csv/json and the four heat-map panels.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Context;
use camplace_config::formats::write_atomic;
use camplace_config::{Cell, Placement};
use camplace_sim::report::sweep_panels::{write_sweep_outputs, SweepResult};
use camplace_sim::study::grid::{Axis, Grid};
use camplace_sim::study::run::{shard_jobs, SceneRunner};
use camplace_sim::study::shard::Shard;
use camplace_sim::Method;

use super::cell_args::CellArgs;
use super::run_args::{check_scenarios, open_folder, RunArgs};

/// Flags of `camplace sweep`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    cell: CellArgs,
    #[command(flatten)]
    run: RunArgs,
    /// Horizontal axis: name=lo:hi:steps over r, alpha, baseline or vergence.
    #[arg(long, default_value = "r=400:900:5", value_parser = parse_axis)]
    x: Axis,
    /// Vertical axis, as --x.
    #[arg(long, default_value = "alpha=0:60:5", value_parser = parse_axis)]
    y: Axis,
    /// Scenarios per grid cell.
    #[arg(long, default_value_t = 250)]
    scenarios: u64,
    /// Study folder.
    #[arg(long)]
    out: PathBuf,
}

fn parse_axis(s: &str) -> Result<Axis, String> {
    s.parse()
}

/// Runs `camplace sweep`.
pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let (cell, base) = a.cell.load()?;
    let seed = a.run.seed(&cell);
    let scenarios = check_scenarios(a.scenarios)?;
    let grid = Grid { x: a.x.clone(), y: a.y.clone() };
    let shard = a.run.shard()?;
    let r = sweep(&a.out, &cell, &base, a.run.method, seed, &grid, scenarios, shard, "sweep")?;
    report(&a.out, &r, shard);
    Ok(ExitCode::SUCCESS)
}

/// Prints where the sweep stands and its best cell.
pub fn report(dir: &Path, r: &SweepResult, shard: Shard) {
    match (r.best, r.complete) {
        (Some(b), true) => {
            println!("best cell {}: {}; wrote {}", r.rows[b].placement, r.rows[b].summary.line(), dir.display())
        }
        _ if !shard.is_whole() => {
            println!("shard {shard} done into {}; join the parts with camplace merge", dir.display())
        }
        _ => println!("sweep incomplete in {}", dir.display()),
    }
}

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
) -> anyhow::Result<SweepResult> {
    let placements = grid.placements(base).context("--x/--y")?;
    let store = open_folder(dir, cell, method, seed)?;
    let grid_text = serde_json::to_string_pretty(&(grid, scenarios, base)).expect("a grid is plain data");
    write_atomic(&dir.join("sweep.json"), grid_text.as_bytes())?;
    let jobs = shard_jobs(&placements, seed, scenarios, shard);
    SceneRunner::new(cell, method, &store).run(&jobs, label)?;
    Ok(write_sweep_outputs(dir, grid, &placements, &store, method, seed, scenarios)?)
}

/// The grid, scenario count and base placement of a sweep folder, if it holds one.
pub fn load_sweep(dir: &Path) -> anyhow::Result<Option<(Grid, u64, Placement)>> {
    let path = dir.join("sweep.json");
    if !path.exists() {
        return Ok(None);
    }
    let text = std::fs::read_to_string(&path).with_context(|| format!("{}: cannot read", path.display()))?;
    let v = serde_json::from_str(&text)
        .with_context(|| format!("{}: expected a sweep's grid, scenario count and base placement", path.display()))?;
    Ok(Some(v))
}
