//! A recorded dataset through the estimator, shared by `estimate --dataset`, `replay` and
//! `run --source dir:`: the estimator set up from the dataset's rig and background, each frame's
//! record scored against its `truth.json` (the estimator's scoring), `poses.jsonl` and each
//! frame's scene cloud (`scene.ply`) written,
//! and the records summed up with the verification's figures at the threshold in force.

use std::path::Path;

use camplace_config::{
    remove_stale_temp_files, thinned, write_atomic, write_cloud, DATASET_SUMMARY, SCENE_CLOUD, SCENE_CLOUD_POINTS,
};
use camplace_config::{Cell, TruthFile};
use camplace_estimator::{depth::method_for, depth::Method, Estimator, EstimatorConfig, Model, PoseEstimate, Rig};
use camplace_estimator::{
    geometry::isometry_from_rows, scoring::score, scoring::FrameRecord, scoring::SlotScore, scoring::Summary,
};

use crate::{Error, ErrorKind, FrameSource, Frames, RecordedSource, Result};

/// The estimator for `rig` (read from `rig_path`, named in errors) with the background of
/// `background` when it has one.
pub fn estimator_for(
    cell: &Cell,
    model: Model,
    rig: &Rig,
    rig_path: &Path,
    method: Method,
    background: Option<&Frames>,
) -> Result<Estimator> {
    // Only the rig's own errors belong to its file; a model's name the model.
    let mut estimator =
        Estimator::new(&EstimatorConfig::from(cell), rig, model, method).map_err(|e| match e.kind() {
            camplace_estimator::ErrorKind::Rig => Error::from(e).in_file(rig_path),
            _ => Error::from(e),
        })?;
    if let Some(frames) = background {
        estimator
            .set_background(&frames.left, &frames.right)
            .map_err(|e| Error::new(ErrorKind::Estimate, format!("background: {e}")))?;
    }
    Ok(estimator)
}

/// The record of the frame the estimator just processed, scored against `truth` (a
/// `truth.json`) when there is one, with the pose in the robot's frame when the cell has a
/// `[robot]`.
pub fn record(
    cell: &Cell,
    estimator: &Estimator,
    pose: &PoseEstimate,
    name: &str,
    truth: Option<&Path>,
) -> Result<FrameRecord> {
    let mut record = FrameRecord::new(name, pose).with_slots(estimator.slots()).with_robot(cell);
    if let Some(path) = truth {
        let truth = TruthFile::load(path)?;
        let symmetries: Vec<f32> = truth.symmetries.iter().map(|&s| s as f32).collect();
        let t = isometry_from_rows(&truth.t_world_tray);
        record.score = Some(score(pose, estimator, &t, &symmetries, &cell.metrics));
        if !estimator.slots().is_empty() {
            record.slot_score = Some(SlotScore::of(estimator.slots(), &truth.filled, &pose.t_world_tray, &t));
        }
    }
    Ok(record)
}

/// A recorded dataset's frames through the estimator.
#[derive(Debug, Clone)]
pub struct DatasetEstimate {
    /// Each frame's record, in order.
    pub records: Vec<FrameRecord>,
    /// The method the frames were captured with.
    pub method: Method,
    /// The records summed up, with the verification's figures at the threshold the
    /// estimator applied (the model's, else the cell's) when any frame has its truth.
    pub summary: Summary,
}

/// Every frame of the dataset `dir` estimated in order; writes `dir/poses.jsonl` and
/// returns the records, the method and their summary. A `summary.json` of an earlier run is
/// removed before the new poses are written, so it never stands beside poses it does not
/// describe (`replay` writes a new one when the frames carry their truth).
pub fn estimate_dataset(cell: &Cell, model: Model, dir: &Path) -> Result<DatasetEstimate> {
    let source = RecordedSource::open(dir)?;
    remove_stale_temp_files(dir)?;
    let method = method_for(source.shots());
    let rig = Rig::from_file(source.rig());
    let mut frames = Frames::new(source.shots());
    let background = source.background(&mut frames)?.then_some(&frames);
    let mut estimator = estimator_for(cell, model, &rig, &dir.join("rig.json"), method, background)?;
    let threshold = estimator.verifier().threshold_in_force();
    let mut lines = String::new();
    let mut records = Vec::with_capacity(source.frame_dirs().len());
    let mut clouds = Vec::with_capacity(source.frame_dirs().len());
    for i in 0..source.frame_dirs().len() {
        let info = source.read_into(i, &mut frames)?;
        let pose = estimator
            .process(&frames.left, &frames.right)
            .map_err(|e| Error::new(ErrorKind::Estimate, format!("frame {}: {e}", info.name)))?;
        let record = record(cell, &estimator, &pose, &info.name, source.truth_path(i).as_deref())?;
        lines.push_str(&record.to_line());
        lines.push('\n');
        records.push(record);
        clouds.push(thinned(estimator.scene_cloud(), SCENE_CLOUD_POINTS).map(|p| [p.x, p.y, p.z]).collect::<Vec<_>>());
    }
    if records.is_empty() {
        return Err(Error::format(dir, "the dataset has no frames"));
    }
    let summary = dir.join(DATASET_SUMMARY);
    match std::fs::remove_file(&summary) {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
        Err(e) => {
            return Err(Error::new(
                ErrorKind::Io,
                format!("{}: cannot remove the earlier summary: {e}", summary.display()),
            ))
        }
    }
    write_atomic(&dir.join("poses.jsonl"), lines.as_bytes())?;
    // Each frame's scene cloud once every frame is estimated, so a failed run leaves the
    // earlier clouds beside the earlier poses.
    for (frame, cloud) in source.frame_dirs().iter().zip(&clouds) {
        write_cloud(&frame.join(SCENE_CLOUD), cloud, None)?;
    }
    let summary = Summary::from_records(&records).verified_at(
        &records,
        threshold,
        cell.estimator.verify_max_wrong,
        &cell.metrics,
    );
    Ok(DatasetEstimate { records, method, summary })
}
