//! `camplace evaluate`: one placement over N scenarios into a study folder (resumable,
//! shardable), then its summary.

use std::path::PathBuf;
use std::process::ExitCode;

use camplace_sim::evaluate_placement;

use super::cell_args::{CellArgs, InstalledRigArg};
use super::study_args::{check_scenarios, StudyArgs};

/// Flags of `camplace evaluate`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    cell: CellArgs,
    #[command(flatten)]
    installed: InstalledRigArg,
    #[command(flatten)]
    run: StudyArgs,
    /// Scenarios 0..N-1 of the seed.
    #[arg(long, default_value_t = 250)]
    scenarios: u64,
    /// Study folder: results.jsonl (appended as scenes finish), summary.json, summary.csv, models/.
    #[arg(long)]
    out: PathBuf,
}

/// Runs `camplace evaluate`.
pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let (mut cell, mut placement) = a.cell.load()?;
    a.installed.apply(&mut cell, &mut placement)?;
    let seed = a.run.seed(&cell);
    let method = a.run.method();
    let scenarios = check_scenarios(a.scenarios)?;
    let shard = a.run.shard()?;
    // The whole run holds the folder: a second run on it is refused naming this one.
    let _lock = camplace_sim::lock_folder(&a.out)?;
    let summary = evaluate_placement(&a.out, &cell, &placement, method, seed, scenarios, shard)?;
    let part =
        if shard.is_whole() { String::new() } else { format!(" (shard {shard}: {} scenes here)", summary.frames) };
    outln!("{placement} ({method}, seed {seed}){part}: {}", summary.line());
    Ok(ExitCode::SUCCESS)
}
