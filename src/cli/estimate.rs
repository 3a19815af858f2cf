//! `camplace estimate`: the tray's pose in every frame of a recorded dataset (scored against
//! its truth where there is one), or in one point cloud.

use anyhow::Context;
use camplace_config::RigFile;
use camplace_estimator::{depth::Method, scoring::FrameRecord, Estimator, EstimatorConfig, Model, Rig};
use camplace_hwio::estimate_dataset;
use nalgebra::Point3;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use super::cell_args::CellArgs;

/// Flags of `camplace estimate`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    cell: CellArgs,
    /// A recorded dataset: writes DIR/poses.jsonl, one line per frame.
    #[arg(long, value_name = "DIR", conflicts_with_all = ["cloud", "rig"], required_unless_present = "cloud")]
    dataset: Option<PathBuf>,
    /// One world point cloud (PLY, mm): prints one JSON line.
    #[arg(long, value_name = "FILE")]
    cloud: Option<PathBuf>,
    /// Calibration of the sensor that saw --cloud (default: the cell's sensor at its placement).
    #[arg(long, value_name = "FILE", requires = "cloud")]
    rig: Option<PathBuf>,
    /// The tray model (from `camplace model`); with --cell, it must have been built for that
    /// cell's tray.
    #[arg(long, value_name = "FILE")]
    model: PathBuf,
}

/// Runs `camplace estimate`.
pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let (cell, placement) = a.cell.load()?;
    let model = Model::load_checked(&a.model, &cell, a.cell.cell.as_deref())?;
    if let Some(dir) = &a.dataset {
        return dataset(&cell, model, dir);
    }
    let path = a.cloud.as_ref().context("give --dataset DIR or --cloud FILE")?;
    let rig = match &a.rig {
        Some(p) => Rig::from_file(&RigFile::load(p)?),
        None => camplace_estimator::geometry::rig_for(&placement, &cell.sensor),
    };
    let cloud = camplace_config::read_cloud(path)?;
    let points: Vec<Point3<f32>> = cloud.points.iter().map(|p| Point3::from(*p)).collect();
    let mut estimator = Estimator::new(&EstimatorConfig::from(&cell), &rig, model, Method::OneShot)?;
    let pose = estimator.process_cloud(&points).with_context(|| path.display().to_string())?;
    let record = FrameRecord::new(path.display().to_string(), &pose).with_slots(estimator.slots()).with_robot(&cell);
    outln!("{}", record.to_line());
    Ok(ExitCode::SUCCESS)
}

fn dataset(cell: &camplace_config::Cell, model: Model, dir: &Path) -> anyhow::Result<ExitCode> {
    // Marks made on the poses about to be replaced keep saying which poses they judged. Marks
    // carry their pose's fingerprint since they are made; this ties older ones, and only the
    // default build (with the review page, the simulator's) reads marks at all.
    #[cfg(feature = "sim")]
    camplace_sim::tie_marks_to_poses(dir)?;
    let d = estimate_dataset(cell, model, dir)?;
    outln!(
        "{} frames ({}): {}; wrote {}",
        d.records.len(),
        d.method,
        d.summary.line(),
        dir.join("poses.jsonl").display()
    );
    Ok(ExitCode::SUCCESS)
}
