//! Evaluating placement jobs: for each placement of a plan, the model (built, or read from the
//! folder's model cache), then one [`Worker`](super::Worker) per rayon thread pulling the
//! placement's unfinished scenario indices; each finished scene goes to the results file at
//! once. Which thread ran a scene never changes its result.

use std::path::{Path, PathBuf};

use camplace_config::write_atomic;
use camplace_config::{Cell, Placement};
use camplace_estimator::{pose::ModelOrigin, Model};

use super::evaluate::Evaluator;
use super::results::{ResultLine, ResultsStore, SceneKey};
use super::shard::Shard;
use crate::model_builder::{build_model, model_origin};
use crate::progress::{report, ProgressEvent};
use crate::render::Method;
use crate::workers::each_index;
use crate::{Error, Result};

/// Scenes of one placement to run.
#[derive(Debug, Clone, PartialEq)]
pub struct PlacementJob {
    /// Where the rig sits.
    pub placement: Placement,
    /// The seed the scenarios are drawn with.
    pub seed: u64,
    /// Scenario indices.
    pub scenarios: Vec<u64>,
}

/// Shard `shard`'s part of scenarios `0..count` of `seed` at every placement: the pairs are
/// numbered placement by placement and cut into contiguous parts.
pub fn shard_jobs(placements: &[Placement], seed: u64, count: u64, shard: Shard) -> Vec<PlacementJob> {
    let range = shard.range(placements.len() * count as usize);
    let mut jobs: Vec<PlacementJob> = Vec::new();
    for pair in range {
        let (p, s) = (pair / count as usize, (pair % count as usize) as u64);
        match jobs.last_mut() {
            Some(job) if job.placement == placements[p] => job.scenarios.push(s),
            _ => jobs.push(PlacementJob { placement: placements[p], seed, scenarios: vec![s] }),
        }
    }
    jobs
}

/// Evaluates the scenes of placement jobs for one cell and method into a results store.
#[derive(Debug)]
pub struct JobEvaluator<'a> {
    cell: &'a Cell,
    method: Method,
    store: &'a ResultsStore,
    model_cache: Option<PathBuf>,
    negatives: bool,
}

impl<'a> JobEvaluator<'a> {
    /// An evaluator writing to `store`.
    pub fn new(cell: &'a Cell, method: Method, store: &'a ResultsStore) -> JobEvaluator<'a> {
        JobEvaluator { cell, method, store, model_cache: None, negatives: false }
    }

    /// Weighs each scene's hard negatives beside its pose (`evaluate`'s; a sweep's cells
    /// do without, at half the cost).
    pub fn with_negatives(mut self) -> Self {
        self.negatives = true;
        self
    }

    /// Keeps built models in `dir` and reads them from there, so a resumed run of one
    /// placement does not build its model again (a model is tens of MB: worth it for
    /// `evaluate`, not for a sweep's every cell).
    pub fn with_model_cache(mut self, dir: &Path) -> Self {
        self.model_cache = Some(dir.to_path_buf());
        self
    }

    /// Scenes of `jobs` that are not in the store yet.
    pub fn pending(&self, jobs: &[PlacementJob]) -> usize {
        jobs.iter()
            .map(|j| {
                j.scenarios
                    .iter()
                    .filter(|&&i| !self.store.contains(&SceneKey::new(&j.placement, self.method, j.seed, i)))
                    .count()
            })
            .sum()
    }

    /// Runs every unfinished scene of `jobs`, `label` naming the run in its progress
    /// (`crate::set_progress`).
    pub fn evaluate(&self, jobs: &[PlacementJob], label: &str) -> Result<()> {
        let total = self.pending(jobs);
        if total == 0 {
            return Ok(());
        }
        report(ProgressEvent::Start { label, scenes: total as u64 });
        let result = jobs.iter().try_for_each(|job| self.evaluate_job(job));
        report(ProgressEvent::Finish);
        result
    }

    /// Runs `job`'s scenes in scenario order, `part` at a time, building its model at most
    /// once: before each part after the first, `enough(m)` is asked whether the first `m`
    /// scenes (a whole number of parts) settle what the caller needs; returns the `m` it
    /// stopped at, or every scene's count. The stopping point depends on the outcomes
    /// only, never on which scenes were already in the store.
    pub fn evaluate_until(
        &self,
        job: &PlacementJob,
        part: usize,
        label: &str,
        mut enough: impl FnMut(usize) -> bool,
    ) -> Result<usize> {
        let part = part.max(1);
        report(ProgressEvent::Start { label, scenes: self.pending(std::slice::from_ref(job)) as u64 });
        let done = self.run_until(job, part, &mut enough);
        report(ProgressEvent::Finish);
        done
    }

    fn run_until(&self, job: &PlacementJob, part: usize, enough: &mut impl FnMut(usize) -> bool) -> Result<usize> {
        let mut evaluator: Option<Evaluator> = None;
        let mut done = 0;
        for chunk in job.scenarios.chunks(part) {
            if done > 0 && enough(done) {
                break;
            }
            let todo = self.todo(&job.placement, job.seed, chunk);
            if !todo.is_empty() {
                if evaluator.is_none() {
                    report(ProgressEvent::Doing(&format!("{} (model)", job.placement)));
                    let model = self.model(&job.placement, job.seed)?;
                    evaluator = Some(
                        Evaluator::with_model(self.cell, &job.placement, self.method, job.seed, model)?
                            .with_negatives(self.negatives),
                    );
                    report(ProgressEvent::Doing(&job.placement.to_string()));
                }
                self.run_scenes(evaluator.as_ref().expect("built above"), job, &todo)?;
            }
            done += chunk.len();
        }
        Ok(done)
    }

    /// The scenario indices of `scenarios` the store lacks at `placement`.
    fn todo(&self, placement: &Placement, seed: u64, scenarios: &[u64]) -> Vec<u64> {
        scenarios
            .iter()
            .copied()
            .filter(|&i| !self.store.contains(&SceneKey::new(placement, self.method, seed, i)))
            .collect()
    }

    fn evaluate_job(&self, job: &PlacementJob) -> Result<()> {
        let todo = self.todo(&job.placement, job.seed, &job.scenarios);
        if todo.is_empty() {
            return Ok(());
        }
        report(ProgressEvent::Doing(&format!("{} (model)", job.placement)));
        let model = self.model(&job.placement, job.seed)?;
        let evaluator = Evaluator::with_model(self.cell, &job.placement, self.method, job.seed, model)?
            .with_negatives(self.negatives);
        report(ProgressEvent::Doing(&job.placement.to_string()));
        self.run_scenes(&evaluator, job, &todo)
    }

    /// Runs scenarios `todo` of `job` with `evaluator`, one worker per thread, each scene
    /// to the store as it finishes.
    fn run_scenes(&self, evaluator: &Evaluator, job: &PlacementJob, todo: &[u64]) -> Result<()> {
        each_index(
            todo.len(),
            || evaluator.worker(),
            |worker, n| {
                let index = todo[n];
                let record = worker.scene(index)?;
                self.store.add(ResultLine {
                    placement: job.placement.to_string(),
                    method: self.method.to_string(),
                    seed: job.seed,
                    scenario: index,
                    record,
                })?;
                report(ProgressEvent::Scene);
                Ok(())
            },
        )?;
        Ok(())
    }

    /// The model of `placement`: from the cache when it holds one built from this cell,
    /// method, seed and placement; built (and cached) when it holds none, or one that does not
    /// decode or records no origin. One built from anything else is refused: the cache belongs
    /// to another cell.
    fn model(&self, placement: &Placement, seed: u64) -> Result<Model> {
        let Some(dir) = &self.model_cache else { return build_model(self.cell, placement, self.method, seed) };
        let name: String = format!("{}-seed{seed}-{placement}.model", self.method)
            .chars()
            .map(|c| if c.is_ascii_alphanumeric() || "-.=".contains(c) { c } else { '_' })
            .collect();
        let path = dir.join(name);
        let origin = model_origin(self.cell, placement, self.method, seed)?;
        if let Ok(bytes) = camplace_config::read_bounded(&path, camplace_config::FileKind::Model) {
            if let Ok(model) = Model::from_bytes(&bytes) {
                // A model cached before models carried the tray's slots is built again, so
                // every scene's slots are judged.
                let has_slots = model.slots.is_some() || crate::scene::tray::slot_count(self.cell) == 0;
                match &model.origin {
                    Some(o) if *o == origin && has_slots => return Ok(model),
                    Some(o) if *o == origin => {}
                    Some(o) => return Err(Error::Other(format!("{}: {}", path.display(), cache_mismatch(o, &origin)))),
                    None => {}
                }
            }
        }
        let model = build_model(self.cell, placement, self.method, seed)?;
        std::fs::create_dir_all(dir).map_err(|e| Error::Other(format!("{}: cannot create: {e}", dir.display())))?;
        write_atomic(&path, &model.to_bytes())?;
        Ok(model)
    }
}

/// What differs between a cached model's origin and the one wanted, in words.
fn cache_mismatch(cached: &ModelOrigin, wanted: &ModelOrigin) -> String {
    if cached.cell_hash != wanted.cell_hash {
        return format!(
            "built for a cell with hash {} (tray {}); this cell hashes to {} — use a new folder",
            cached.cell_hash.short(),
            cached.tray,
            wanted.cell_hash.short()
        );
    }
    format!(
        "built for {} seed {} at {}, wanted {} seed {} at {} — use a new folder",
        cached.method, cached.seed, cached.placement, wanted.method, wanted.seed, wanted.placement
    )
}
