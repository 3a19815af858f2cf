//! `camplace model`: builds the tray model at a placement in simulation and writes it (and,
//! on request, its ICP points as a PLY cloud).

use anyhow::Context;
use camplace_config::write_atomic;
use camplace_sim::{build_model, model_points};
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
}

/// Runs `camplace model`.
pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let (mut cell, mut placement) = a.cell.load()?;
    a.installed.apply(&mut cell, &mut placement)?;
    let seed = a.scene.seed(&cell);
    let model = build_model(&cell, &placement, a.scene.method, seed)?;
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
    Ok(ExitCode::SUCCESS)
}
