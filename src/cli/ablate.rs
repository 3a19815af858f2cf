//! `camplace ablate`: what each effect of the simulation costs, at the recommended placement
//! (a study's, or the cell's) and at a weak one, on the same scenarios; a table on screen and
//! in `ablation.md`.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use camplace_sim::{ablate, ablation_markdown};

use super::cell_args::CellArgs;
use super::study_args::{check_scenarios, recommended, SceneArgs};

/// Flags of `camplace ablate`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The cell, and with --placement the recommended placement (default: the cell's).
    #[command(flatten)]
    cell: CellArgs,
    #[command(flatten)]
    scene: SceneArgs,
    /// A study folder: its recommended placement and method (`recommended.json`) instead of
    /// --placement and --method.
    #[arg(long, value_name = "DIR", conflicts_with_all = ["placement", "method"])]
    study: Option<PathBuf>,
    /// The weak placement to set beside it, as placement overrides.
    #[arg(long, value_name = "P", default_value = "r=1000,alpha=60")]
    weak: String,
    /// Scenarios 0..N-1 of the seed, per effect and placement.
    #[arg(long, default_value_t = 100)]
    scenarios: u64,
    /// Folder: one study folder per variant (resumable), and ablation.md.
    #[arg(long)]
    out: PathBuf,
}

/// Runs `camplace ablate`.
pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let (cell, placement) = a.cell.load()?;
    let weak = cell.placement.with_overrides(&a.weak).context("--weak")?;
    let scenarios = check_scenarios(a.scenarios)?;
    let (placement, method) = match &a.study {
        Some(dir) => recommended(dir)?,
        None => (placement, a.scene.method),
    };
    let seed = a.scene.seed(&cell);
    let placements = [("recommended".to_string(), placement), ("weak".to_string(), weak)];
    // The whole run holds the folder: a second run on it is refused naming this one.
    let _lock = camplace_sim::lock_folder(&a.out)?;
    let rows = ablate(&a.out, &cell, &placements, method, seed, scenarios)?;
    let text = ablation_markdown(&rows);
    let path = a.out.join("ablation.md");
    camplace_config::write_atomic(&path, text.as_bytes())?;
    outln!("{method}, seed {seed}, {scenarios} scenarios per row\n\n{text}\nwritten to {}", path.display());
    Ok(ExitCode::SUCCESS)
}
