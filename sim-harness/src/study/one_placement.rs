//! One placement over scenarios `0..N` of a seed: into a study folder with its summaries
//! (`evaluate`, resumable and shardable), or for the acceptance test, into a folder or
//! memory only.

use std::path::Path;

use camplace_config::{Cell, Placement};

use super::folder::{open_folder, MODELS_FOLDER};
use super::jobs::{shard_jobs, JobEvaluator};
use super::results::ResultsStore;
use super::shard::Shard;
use super::summary::Summary;
use crate::render::Method;
use crate::report::table::{write_summary_csv, write_summary_json, SummaryRow};
use crate::Result;

/// Runs shard `shard` of the scenes into the study folder `dir` (models cached in
/// `dir/models`), writes `summary.json` and `summary.csv`, and returns the summary of the
/// scenes the folder holds.
#[allow(clippy::too_many_arguments)]
pub fn evaluate_placement(
    dir: &Path,
    cell: &Cell,
    placement: &Placement,
    method: Method,
    seed: u64,
    scenarios: u64,
    shard: Shard,
) -> Result<Summary> {
    let store = open_folder(dir, cell, method, seed)?;
    let jobs = shard_jobs(&[*placement], seed, scenarios, shard);
    JobEvaluator::new(cell, method, &store).with_model_cache(&dir.join(MODELS_FOLDER)).evaluate(&jobs, "evaluate")?;
    let summary = Summary::from_records(&store.records(placement, method, seed, scenarios));
    let rows =
        [SummaryRow { placement: placement.to_string(), method: method.to_string(), seed, summary: summary.clone() }];
    write_summary_json(&dir.join("summary.json"), &rows)?;
    write_summary_csv(&dir.join("summary.csv"), &rows)?;
    Ok(summary)
}

/// Runs every scene for the acceptance test, keeping the results in the study folder `dir`
/// (resumable, models cached) when given, else in memory; returns their summary.
pub fn acceptance_summary(
    dir: Option<&Path>,
    cell: &Cell,
    placement: &Placement,
    method: Method,
    seed: u64,
    scenarios: u64,
) -> Result<Summary> {
    let store = match dir {
        Some(dir) => open_folder(dir, cell, method, seed)?,
        None => ResultsStore::in_memory(),
    };
    let jobs = shard_jobs(&[*placement], seed, scenarios, Shard::WHOLE);
    let mut runner = JobEvaluator::new(cell, method, &store);
    if let Some(dir) = dir {
        runner = runner.with_model_cache(&dir.join(MODELS_FOLDER));
    }
    runner.evaluate(&jobs, "accept")?;
    Ok(Summary::from_records(&store.records(placement, method, seed, scenarios)))
}
