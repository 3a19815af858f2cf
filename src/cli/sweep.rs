//! `camplace sweep`: a grid over two placement parameters (the paper's Figures 5 and 6)
//! into a study folder: results.jsonl, summary.csv/json and the four heat-map panels.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use camplace_config::{Axis, Grid};
use camplace_sim::{sweep, Shard, SweepResult};

use super::cell_args::{refuse_installed_rig, CellArgs};
use super::study_args::{check_scenarios, StudyArgs};

/// Flags of `camplace sweep`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    cell: CellArgs,
    #[command(flatten)]
    run: StudyArgs,
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
    refuse_installed_rig(&cell, "sweep")?;
    let seed = a.run.seed(&cell);
    let scenarios = check_scenarios(a.scenarios)?;
    let grid = Grid { x: a.x.clone(), y: a.y.clone() };
    let shard = a.run.shard()?;
    // The whole run holds the folder: a second run on it is refused naming this one.
    let _lock = camplace_sim::lock_folder(&a.out)?;
    let r = sweep(&a.out, &cell, &base, a.run.method(), seed, &grid, scenarios, shard, "sweep")?;
    report(&a.out, &r, shard);
    Ok(ExitCode::SUCCESS)
}

/// Prints where the sweep stands and its best cell.
pub fn report(dir: &Path, r: &SweepResult, shard: Shard) {
    match (r.best, r.complete) {
        (Some(b), true) => {
            outln!("best cell {}: {}; wrote {}", r.rows[b].placement, r.rows[b].summary.line(), dir.display())
        }
        _ if !shard.is_whole() => {
            outln!("shard {shard} done into {}; join the parts with camplace merge", dir.display())
        }
        _ => outln!("sweep incomplete in {}", dir.display()),
    }
}
