//! `camplace estimate`: the tray's pose in every frame of a recorded dataset (scored against
//! its truth where there is one), or in one point cloud.

use anyhow::{bail, Context};
use camplace_config::formats::{ply, write_atomic};
use camplace_config::{RigFile, TruthFile};
use camplace_estimator::camera::isometry_from_rows;
use camplace_estimator::{Estimator, Method, Model, PoseEstimate, Rig};
use camplace_hwio::{FrameSource, Frames, RecordedSource};
use camplace_sim::study::{score, FrameRecord, Summary};
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
    /// The tray model (from `camplace model`).
    #[arg(long, value_name = "FILE")]
    model: PathBuf,
}

/// Runs `camplace estimate`.
pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let (cell, placement) = a.cell.load()?;
    let model = load_model(&a.model)?;
    if let Some(dir) = &a.dataset {
        return dataset(&cell, model, dir);
    }
    let path = a.cloud.as_ref().context("give --dataset DIR or --cloud FILE")?;
    let rig = match &a.rig {
        Some(p) => Rig::from_file(&RigFile::load(p)?),
        None => camplace_sim::placement_rig::rig_for(&placement, &cell.sensor),
    };
    let cloud = ply::read_cloud(path)?;
    let points: Vec<Point3<f32>> = cloud.points.iter().map(|p| Point3::from(*p)).collect();
    let mut estimator = Estimator::new(&cell, &rig, model, Method::OneShot)?;
    let mut pose = PoseEstimate::default();
    estimator.process_cloud(&points, &mut pose).with_context(|| path.display().to_string())?;
    println!("{}", FrameRecord::new(path.display().to_string(), &pose).to_line());
    Ok(ExitCode::SUCCESS)
}

fn load_model(path: &Path) -> anyhow::Result<Model> {
    let bytes = std::fs::read(path).with_context(|| format!("{}: cannot read the model", path.display()))?;
    Model::from_bytes(&bytes).with_context(|| format!("{}: not a usable model file", path.display()))
}

fn dataset(cell: &camplace_config::Cell, model: Model, dir: &Path) -> anyhow::Result<ExitCode> {
    let source = RecordedSource::open(dir)?;
    let method = if source.shots() == 1 { Method::OneShot } else { Method::Phase12 };
    let rig = Rig::from_file(source.rig());
    let mut estimator =
        Estimator::new(cell, &rig, model, method).with_context(|| dir.join("rig.json").display().to_string())?;
    let mut frames = Frames::new(source.shots());
    if source.background(&mut frames)? {
        estimator.set_background(&frames.left, &frames.right).context("background")?;
    }
    let mut lines = String::new();
    let mut records = Vec::with_capacity(source.frame_dirs().len());
    let mut pose = PoseEstimate::default();
    for i in 0..source.frame_dirs().len() {
        let info = source.read_into(i, &mut frames)?;
        estimator.process(&frames.left, &frames.right, &mut pose).with_context(|| format!("frame {}", info.name))?;
        let mut record = FrameRecord::new(info.name.clone(), &pose);
        if let Some(path) = source.truth_path(i) {
            let truth = TruthFile::load(&path)?;
            let symmetries: Vec<f32> = truth.symmetries.iter().map(|&s| s as f32).collect();
            let t = isometry_from_rows(&truth.t_world_tray);
            record.score = Some(score(&pose, &estimator, &t, &symmetries, &cell.metrics));
        }
        lines.push_str(&record.to_line());
        lines.push('\n');
        records.push(record);
    }
    if records.is_empty() {
        bail!("{}: the dataset has no frames", dir.display());
    }
    let out = dir.join("poses.jsonl");
    write_atomic(&out, lines.as_bytes())?;
    let summary = Summary::from_records(&records);
    println!("{} frames ({method}): {}; wrote {}", records.len(), summary.line(), out.display());
    Ok(ExitCode::SUCCESS)
}
