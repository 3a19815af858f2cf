//! `camplace accept`: the acceptance test of one placement. It passes when the lower
//! Wilson bound of the success rate reaches the required rate: exit 0 on pass, 1 on fail.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::bail;
use camplace_sim::acceptance_summary;

use super::cell_args::{CellArgs, InstalledRigArg};
use super::study_args::check_scenarios;
use super::study_args::SceneArgs;

/// Flags of `camplace accept`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    cell: CellArgs,
    #[command(flatten)]
    installed: InstalledRigArg,
    #[command(flatten)]
    scene: SceneArgs,
    /// Required success rate, 0..1: the lower end of the 95 % interval must reach it.
    #[arg(long)]
    min_success: f64,
    /// Scenarios 0..N-1 of the seed.
    #[arg(long, default_value_t = 250)]
    scenarios: u64,
    /// Keep the results in this study folder (resumable); in memory only when not given.
    #[arg(long)]
    out: Option<PathBuf>,
}

/// Runs `camplace accept`.
pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    if !(0.0..=1.0).contains(&a.min_success) {
        bail!("--min-success: expected a rate between 0 and 1 (e.g. 0.95), got {}", a.min_success);
    }
    let (mut cell, mut placement) = a.cell.load()?;
    a.installed.apply(&mut cell, &mut placement)?;
    let seed = a.scene.seed(&cell);
    let scenarios = check_scenarios(a.scenarios)?;
    let s = acceptance_summary(a.out.as_deref(), &cell, &placement, a.scene.method, seed, scenarios)?;
    let low = s.success_interval[0];
    let pass = low >= a.min_success;
    outln!("{placement} ({}, seed {seed}): {}", a.scene.method, s.line());
    outln!(
        "{}: lower 95 % bound {:.1} % {} the required {:.1} %",
        if pass { "PASS" } else { "FAIL" },
        100.0 * low,
        if pass { "reaches" } else { "is below" },
        100.0 * a.min_success
    );
    Ok(if pass { ExitCode::SUCCESS } else { ExitCode::from(1) })
}
