//! `camplace estimate`: the tray's pose in every frame of a recorded dataset (scored against
//! its truth where there is one), or in one point cloud.

use anyhow::{bail, Context};
use camplace_config::formats::{ply, write_atomic};
use camplace_config::{RigFile, TruthFile};
use camplace_estimator::camera::{isometry_from_rows, isometry_to_rows};
use camplace_estimator::metrics::{correct_matches, pose_errors};
use camplace_estimator::{Estimator, Method, Model, PoseEstimate, Rig, StageTimings};
use camplace_hwio::{FrameSource, Frames, RecordedSource};
use nalgebra::Point3;
use serde_json::{json, Map, Value};
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
    println!("{}", Value::Object(pose_line(&pose)));
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
    let mut pose = PoseEstimate::default();
    let (mut scored, mut successes) = (0usize, 0usize);
    let mut frame_ms = Vec::with_capacity(source.frame_dirs().len());
    for i in 0..source.frame_dirs().len() {
        let info = source.read_into(i, &mut frames)?;
        estimator.process(&frames.left, &frames.right, &mut pose).with_context(|| format!("frame {}", info.name))?;
        frame_ms.push(pose.timings.total_ms);
        let mut line = Map::new();
        line.insert("frame".into(), json!(info.name));
        line.extend(pose_line(&pose));
        if let Some(path) = source.truth_path(i) {
            let truth = TruthFile::load(&path)?;
            let t = isometry_from_rows(&truth.t_world_tray);
            let symmetries: Vec<f32> = truth.symmetries.iter().map(|&s| s as f32).collect();
            let errors = pose_errors(&pose.t_world_tray, &t, &symmetries, &cell.metrics);
            let success = pose.found && errors.success;
            let correct = correct_matches(
                estimator.scene_keypoints(),
                &estimator.model().feature_points,
                estimator.correspondences(),
                &t,
                &symmetries,
                cell.metrics.correct_match,
            );
            line.insert("position_error_mm".into(), json!(errors.position_mm));
            line.insert("rotation_error_deg".into(), json!(errors.rotation_deg));
            line.insert("correct_matches".into(), json!(correct));
            line.insert("success".into(), json!(success));
            scored += 1;
            successes += usize::from(success);
        }
        lines.push_str(&Value::Object(line).to_string());
        lines.push('\n');
    }
    let out = dir.join("poses.jsonl");
    write_atomic(&out, lines.as_bytes())?;
    let n = frame_ms.len();
    if n == 0 {
        bail!("{}: the dataset has no frames", dir.display());
    }
    frame_ms.sort_by(f64::total_cmp);
    let rate = if scored > 0 { format!("{:.1} %", 100.0 * successes as f64 / scored as f64) } else { "n/a".into() };
    println!(
        "{n} frames ({method}), success {rate} ({successes} of {scored} with truth), median {:.1} ms per frame; wrote {}",
        frame_ms[n / 2],
        out.display()
    );
    Ok(ExitCode::SUCCESS)
}

/// The fields every pose line carries.
fn pose_line(pose: &PoseEstimate) -> Map<String, Value> {
    let StageTimings {
        rectify_ms,
        disparity_ms,
        cloud_ms,
        downsample_ms,
        normals_ms,
        features_ms,
        matching_ms,
        ransac_ms,
        icp_ms,
        total_ms,
    } = pose.timings;
    let mut m = Map::new();
    m.insert("T_world_tray".into(), json!(isometry_to_rows(&pose.t_world_tray)));
    m.insert("found".into(), json!(pose.found));
    m.insert("inliers".into(), json!(pose.inliers));
    m.insert("scene_points".into(), json!(pose.scene_points));
    m.insert("keypoints".into(), json!(pose.keypoints));
    m.insert("matches".into(), json!(pose.matches));
    m.insert("icp_iterations".into(), json!(pose.icp.iterations));
    m.insert(
        "timings_ms".into(),
        json!({
            "rectify": rectify_ms, "disparity": disparity_ms, "cloud": cloud_ms,
            "downsample": downsample_ms, "normals": normals_ms, "features": features_ms,
            "matching": matching_ms, "ransac": ransac_ms, "icp": icp_ms,
        }),
    );
    m.insert("ms".into(), json!(total_ms));
    m
}
