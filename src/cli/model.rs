//! `camplace model`: builds the tray model at a placement in simulation and writes it (and,
//! on request, its ICP points as a PLY cloud).

use camplace_config::{check_output_file, encode_cloud, write_atomic_all};
use camplace_estimator::scoring::VerifiedSummary;
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
    // Both outputs checked before the model is built, and written together after: a command
    // whose outputs cannot all be written writes none of them.
    check_output_file(&a.out)?;
    if let Some(path) = &a.ply {
        check_output_file(path)?;
    }
    let (mut cell, mut placement) = a.cell.load()?;
    a.installed.apply(&mut cell, &mut placement)?;
    let seed = a.scene.seed(&cell);
    let mut model = build_model(&cell, &placement, a.scene.method, seed)?;
    let verified = measure_verification(&cell, &placement, a.scene.method, seed, &model, a.verify_scenes)?;
    model.verification = verified.as_ref().map(VerifiedSummary::to_model);
    let model_bytes = model.to_bytes();
    let cloud = a.ply.as_ref().map(|path| (path, encode_cloud(&model_points(&model), None)));
    let mut files = vec![(a.out.as_path(), model_bytes.as_slice())];
    if let Some((path, bytes)) = &cloud {
        files.push((path.as_path(), bytes.as_slice()));
    }
    write_atomic_all(&files)?;
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
