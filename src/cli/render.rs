//! `camplace render`: one simulated scene with its ground truth, or (`--dataset`) a
//! recorded-dataset folder of scenarios 0..N-1 that `evaluate` and `replay` read alike.

use camplace_sim::{render_dataset, render_scene};
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
    /// Output folder.
    #[arg(long)]
    out: PathBuf,
}

/// Runs `camplace render`.
pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let (cell, placement) = a.cell.load()?;
    let seed = a.scene.seed(&cell);
    if !a.dataset {
        render_scene(&a.out, &cell, &placement, a.scene.method, seed, a.scenario)?;
        println!(
            "rendered scenario {} of seed {seed} at {placement} ({}) into {}",
            a.scenario,
            a.scene.method,
            a.out.display()
        );
        return Ok(ExitCode::SUCCESS);
    }
    render_dataset(&a.out, &cell, &placement, a.scene.method, seed, a.count)?;
    println!(
        "rendered {} scenarios of seed {seed} at {placement} ({}) into {}",
        a.count,
        a.scene.method,
        a.out.display()
    );
    Ok(ExitCode::SUCCESS)
}
