//! `camplace model`: builds the tray model at a placement in simulation and writes it (and,
//! on request, its ICP points as a PLY cloud).

use anyhow::Context;
use camplace_config::write_atomic;
use camplace_estimator::VerifiedSummary;
use camplace_sim::{build_model, measure_verification, model_points};
use std::path::PathBuf;
use std::process::ExitCode;

use super::cell_args::{CellArgs, InstalledRigArg};
use super::study_args::SceneArgs;

/// Flags of `camplace model`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    cell: CellArgs,
    #[command(flatten)]
    installed: InstalledRigArg,
    #[command(flatten)]
    scene: SceneArgs,
    /// The model file to write.
    #[arg(long, value_name = "FILE")]
    out: PathBuf,
    /// Also write every ICP point of the model (tray frame) as a PLY cloud.
    #[arg(long, value_name = "FILE")]
    ply: Option<PathBuf>,
    /// Scenes simulated at the placement (scenarios 0..N of the seed, as `evaluate` runs
    /// them) to measure the verification threshold the model carries; 0 carries none (the
    /// cell's `estimator.verify_threshold` then applies).
    #[arg(long, value_name = "N", default_value_t = 200)]
    verify_scenes: u64,
}

/// Runs `camplace model`.
pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let (mut cell, mut placement) = a.cell.load()?;
    a.installed.apply(&mut cell, &mut placement)?;
    let seed = a.scene.seed(&cell);
    let mut model = build_model(&cell, &placement, a.scene.method, seed)?;
    let verified = measure_verification(&cell, &placement, a.scene.method, seed, &model, a.verify_scenes)?;
    model.verification = verified.as_ref().map(VerifiedSummary::to_model);
    write_atomic(&a.out, &model.to_bytes())?;
    if let Some(path) = &a.ply {
        camplace_config::write_cloud(path, &model_points(&model), None).with_context(|| path.display().to_string())?;
    }
    let points: usize = model.views.iter().map(|v| v.points.len()).sum();
    outln!(
        "model at {placement} ({}): {} features, {} views, {points} ICP points; wrote {}",
        a.scene.method,
        model.feature_points.len(),
        model.views.len(),
        a.out.display()
    );
    match &verified {
        Some(v) => outln!("verification on {} scenes (seed {seed}): {}", v.scored, v.line()),
        None => outln!(
            "no verification threshold measured: the cell's estimator.verify_threshold ({}) applies",
            cell.estimator.verify_threshold
        ),
    }
    Ok(ExitCode::SUCCESS)
}
