//! One placement over scenarios `0..N` of a seed: into a study folder with its summaries
//! (`evaluate`, resumable and shardable), for the acceptance test into a folder or memory
//! only, or to measure the verification threshold a model carries.

use std::path::Path;

use camplace_config::{Cell, Placement};

use super::evaluate::Evaluator;
use super::folder::{open_folder, MODELS_FOLDER};
use super::jobs::{shard_jobs, JobEvaluator};
use super::results::ResultsStore;
use super::shard::Shard;
use crate::render::Method;
use crate::report::table::{write_summary_csv, write_summary_json, SummaryRow};
use crate::workers::each_index;
use crate::Result;
use camplace_estimator::scoring::Summary;
use camplace_estimator::scoring::VerifiedSummary;
use camplace_estimator::Model;

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
    JobEvaluator::new(cell, method, &store)
        .with_model_cache(&dir.join(MODELS_FOLDER))
        .with_negatives()
        .evaluate(&jobs, "evaluate")?;
    let records = store.records(placement, method, seed, scenarios);
    let summary = Summary::from_records(&records).verified(&records, cell.estimator.verify_max_wrong, &cell.metrics);
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
    let records = store.records(placement, method, seed, scenarios);
    Ok(Summary::from_records(&records).verified(&records, cell.estimator.verify_max_wrong, &cell.metrics))
}

/// The verification threshold of `model` at `placement`, measured on scenarios
/// `0..scenarios` of `seed` and their hard negatives as `evaluate` with the same seed runs
/// them (a model built with
/// that seed is the one `evaluate` builds, so the two choose the same threshold), and the
/// figures at it; `None` when no scene was run.
pub fn measure_verification(
    cell: &Cell,
    placement: &Placement,
    method: Method,
    seed: u64,
    model: &Model,
    scenarios: u64,
) -> Result<Option<VerifiedSummary>> {
    if scenarios == 0 {
        return Ok(None);
    }
    let evaluator = Evaluator::with_model(cell, placement, method, seed, model.clone())?.with_negatives(true);
    let records = each_index(scenarios as usize, || evaluator.worker(), |worker, i| worker.scene(i as u64))?;
    Ok(VerifiedSummary::of_records(&records, cell.estimator.verify_max_wrong, &cell.metrics))
}
