//! `camplace replay`: a recorded dataset (real or rendered) through the deployed estimator,
//! frame by frame: `poses.jsonl` as `estimate` writes it and, where frames carry a
//! `truth.json`, `summary.json` with the numbers `evaluate` gives for the same scenes (a
//! summary of an earlier replay is removed when these frames carry no truth).

use anyhow::Context;
use camplace_config::write_atomic;
use camplace_config::{Cell, DATASET_SUMMARY};
use camplace_estimator::Model;
use camplace_hwio::{estimate_dataset, DatasetEstimate};
use std::path::PathBuf;
use std::process::ExitCode;

/// Flags of `camplace replay`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The recorded dataset folder (rig.json, optional background/, frames/NNNN/).
    #[arg(value_name = "DATASET")]
    dataset: PathBuf,
    /// The tray model (from `camplace model`).
    #[arg(long, value_name = "FILE")]
    model: PathBuf,
    /// Cell file (TOML) with the estimator settings and metrics; the built-in default when not
    /// given. The model must have been built for its tray.
    #[arg(long, value_name = "FILE")]
    cell: Option<PathBuf>,
    /// Which of the cell's listed trays (`[[trays]]` name) when it lists several.
    #[arg(long, value_name = "NAME")]
    tray: Option<String>,
}

/// Runs `camplace replay`.
pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let cell = Cell::load_one(a.cell.as_deref(), a.tray.as_deref())?;
    let model = match &a.cell {
        Some(path) => Model::load_for(&a.model, &cell, path)?,
        None => Model::load(&a.model)?,
    };
    // Marks made on the poses about to be replaced keep saying which poses they judged. Marks
    // carry their pose's fingerprint since they are made; this ties older ones, and only the
    // default build (with the review page, the simulator's) reads marks at all.
    #[cfg(feature = "sim")]
    camplace_sim::tie_marks_to_poses(&a.dataset)?;
    let DatasetEstimate { records, method, summary } = estimate_dataset(&cell, model, &a.dataset)?;
    let poses = a.dataset.join("poses.jsonl");
    if summary.scored == 0 {
        outln!("{} frames ({method}): {}; wrote {}", records.len(), summary.line(), poses.display());
        return Ok(ExitCode::SUCCESS);
    }
    let path = a.dataset.join(DATASET_SUMMARY);
    let json = serde_json::to_string_pretty(&summary).context("summary")?;
    write_atomic(&path, format!("{json}\n").as_bytes())?;
    outln!("{} frames ({method}): {}; wrote {} and {}", records.len(), summary.line(), poses.display(), path.display());
    Ok(ExitCode::SUCCESS)
}
