//! The trays one placement must serve. A cell that handles several products needs one
//! bracket for all of them, so a placement's success over the set is its lowest success
//! over the trays. Each tray keeps its own study folder (its own results file, models and
//! resume), and every evaluation runs the same scenarios on each tray.

use std::cmp::Ordering;
use std::path::PathBuf;

use camplace_config::{Cell, Placement};

use super::folder::open_folder;
use super::jobs::{shard_jobs, JobEvaluator};
use super::results::ResultsStore;
use super::shard::Shard;
use crate::render::Method;
use crate::Result;
use camplace_estimator::scoring::FrameRecord;
use camplace_estimator::scoring::Summary;

/// One tray of the set and its open study folder.
pub struct TrayFolder {
    /// The tray's name (a folder name).
    pub name: String,
    /// The cell with this tray.
    pub cell: Cell,
    /// Its study folder.
    pub dir: PathBuf,
    store: ResultsStore,
}

/// The trays a placement is judged on, for one method and seed.
pub struct TraySet {
    /// The trays, in the cell's order.
    pub trays: Vec<TrayFolder>,
    /// The sensor method.
    pub method: Method,
}

impl TraySet {
    /// Opens each tray's folder (`(name, cell, folder)`), refusing one of another cell,
    /// method or seed.
    pub fn open(trays: Vec<(String, Cell, PathBuf)>, method: Method, seed: u64) -> Result<TraySet> {
        let mut out = Vec::with_capacity(trays.len());
        for (name, cell, dir) in trays {
            let store = open_folder(&dir, &cell, method, seed)?;
            out.push(TrayFolder { name, cell, dir, store });
        }
        Ok(TraySet { trays: out, method })
    }

    /// Runs the scenes of `placement` (scenarios `0..n` of `seed`) that each tray's folder
    /// lacks, and returns each tray's summary, in order.
    pub fn evaluate(&self, placement: &Placement, seed: u64, n: u64, label: &str) -> Result<Vec<Summary>> {
        let jobs = shard_jobs(&[*placement], seed, n, Shard::WHOLE);
        let mut out = Vec::with_capacity(self.trays.len());
        for t in &self.trays {
            let label = if self.trays.len() > 1 { format!("{label} {}", t.name) } else { label.to_string() };
            JobEvaluator::new(&t.cell, self.method, &t.store).evaluate(&jobs, &label)?;
            let records = t.store.records(placement, self.method, seed, n);
            out.push(Summary::from_records(&records).verified(
                &records,
                t.cell.estimator.verify_max_wrong,
                &t.cell.metrics,
            ));
        }
        Ok(out)
    }

    /// Runs scenarios `0..n` of `seed` at `placement` on tray `tray` in order, `part` at a
    /// time, until `enough(m)` says the first `m` settle it (see
    /// [`JobEvaluator::evaluate_until`]); returns that `m`.
    #[allow(clippy::too_many_arguments)]
    pub fn evaluate_until(
        &self,
        tray: usize,
        placement: &Placement,
        seed: u64,
        n: u64,
        part: usize,
        label: &str,
        enough: impl FnMut(usize) -> bool,
    ) -> Result<usize> {
        let t = &self.trays[tray];
        let jobs = shard_jobs(&[*placement], seed, n, Shard::WHOLE);
        let label = if self.trays.len() > 1 { format!("{label} {}", t.name) } else { label.to_string() };
        let Some(job) = jobs.first() else { return Ok(0) };
        JobEvaluator::new(&t.cell, self.method, &t.store).evaluate_until(job, part, &label, enough)
    }

    /// The summary of the first `n` scenarios of `seed` at `placement` on tray `tray`.
    pub fn summary(&self, tray: usize, placement: &Placement, seed: u64, n: u64) -> Summary {
        Summary::from_records(&self.trays[tray].store.records(placement, self.method, seed, n))
    }

    /// Whether each of scenarios `0..n` of `seed` succeeded at `placement` for tray `tray`,
    /// by scenario (`None`: not in the folder or not scored), for comparisons paired by scene.
    pub fn outcomes(&self, tray: usize, placement: &Placement, seed: u64, n: u64) -> Vec<Option<bool>> {
        self.trays[tray].store.outcomes(placement, self.method, seed, n)
    }

    /// The records of `placement` (scenarios `0..n` of `seed`) already in tray `tray`'s
    /// folder.
    pub fn tray_records(&self, tray: usize, placement: &Placement, seed: u64, n: u64) -> Vec<FrameRecord> {
        self.trays[tray].store.records(placement, self.method, seed, n)
    }

    /// The summaries of `placement` already in the folders, without running anything.
    pub fn stored(&self, placement: &Placement, seed: u64, n: u64) -> Vec<Summary> {
        self.trays
            .iter()
            .map(|t| {
                let records = t.store.records(placement, self.method, seed, n);
                Summary::from_records(&records).verified(&records, t.cell.estimator.verify_max_wrong, &t.cell.metrics)
            })
            .collect()
    }
}

/// The summary that decides a placement over several trays: the tray of the lowest ranked
/// rate (of two equally low, the one of lower success, then of fewer correct matches).
pub fn lowest(summaries: &[Summary]) -> Summary {
    summaries.iter().min_by(|a, b| margin_order(a, b)).cloned().unwrap_or_else(|| Summary::from_records(&[]))
}

/// What the study ranks placements by, as `recommended.json`'s `ranked_by` names it.
pub const RANKED_BY: &str = "verified_success_rate";

/// The rate a placement is ranked by ([`RANKED_BY`]): its verified success, the share of
/// scenes whose pose is correct and accepted at the threshold its own scenes set (what the
/// robot is handed), where the summary carries the verification's figures; its success
/// rate where it carries none (no scene scored).
pub fn ranked_rate(s: &Summary) -> f64 {
    s.verification.as_ref().map_or(s.success_rate, |v| v.verified_success_rate)
}

/// Orders two summaries by the ranked rate ([`ranked_rate`]), then by success rate, then by
/// the secondary measure of margin that breaks ties at the same rates (most often at
/// 100 %): the mean number of correct feature matches per scene. More correct matches
/// leave RANSAC more room before a scene fails.
pub fn margin_order(a: &Summary, b: &Summary) -> Ordering {
    ranked_rate(a)
        .total_cmp(&ranked_rate(b))
        .then(a.success_rate.total_cmp(&b.success_rate))
        .then(a.mean_correct_matches.unwrap_or(0.0).total_cmp(&b.mean_correct_matches.unwrap_or(0.0)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn summary(k: usize, n: usize, matches: f64) -> Summary {
        let mut s = Summary::from_records(&[]);
        s.scored = n;
        s.successes = k;
        s.success_rate = k as f64 / n as f64;
        s.mean_correct_matches = Some(matches);
        s
    }

    /// A summary of `k` correct of `n` whose first `verified` correct poses score 0.9 and
    /// the rest 0.1 (wrong poses 0.05): the verification's figures at the threshold 0.5.
    fn verified_summary(k: usize, n: usize, verified: usize) -> Summary {
        use camplace_estimator::scoring::{Scored, VerifiedSummary};
        let frames: Vec<Scored> = (0..n)
            .map(|i| Scored {
                score: if i < verified {
                    0.9
                } else if i < k {
                    0.1
                } else {
                    0.05
                },
                eligible: true,
                correct: i < k,
                gross: false,
            })
            .collect();
        Summary { verification: Some(VerifiedSummary::at(&frames, 0.5, 0.01)), ..summary(k, n, 100.0) }
    }

    /// Placements rank by verified success, not raw success: a placement whose poses are
    /// found more often but handed on less often ranks lower; at equal verified success,
    /// success decides; without the verification's figures, success alone.
    #[test]
    fn placements_rank_by_verified_success() {
        let found_often = verified_summary(95, 100, 40);
        let handed_on = verified_summary(90, 100, 88);
        assert_eq!((ranked_rate(&found_often), ranked_rate(&handed_on)), (0.40, 0.88));
        assert_eq!(margin_order(&found_often, &handed_on), Ordering::Less);
        assert_eq!(lowest(&[handed_on.clone(), found_often.clone()]).successes, 95);
        let same_verified = verified_summary(97, 100, 88);
        assert_eq!(margin_order(&same_verified, &handed_on), Ordering::Greater);
        assert_eq!(ranked_rate(&summary(7, 10, 1.0)), 0.7);
    }

    #[test]
    fn the_lowest_tray_decides_and_fewer_matches_break_a_tie() {
        let set = [summary(9, 10, 300.0), summary(7, 10, 500.0), summary(10, 10, 50.0)];
        assert_eq!(lowest(&set).successes, 7);
        let tied = [summary(10, 10, 300.0), summary(10, 10, 120.0), summary(10, 10, 250.0)];
        assert_eq!(lowest(&tied).mean_correct_matches, Some(120.0));
        // The slow obvious version over many sets: no other summary is below the lowest.
        for seed in 0..200u64 {
            let set: Vec<Summary> = (0..1 + seed % 5)
                .map(|i| summary(((seed * 7 + i * 3) % 11) as usize, 10, ((seed * 13 + i * 29) % 97) as f64))
                .collect();
            let low = lowest(&set);
            assert!(set.iter().all(|s| margin_order(s, &low) != Ordering::Less), "set {seed}");
            assert!(set.contains(&low));
        }
    }
}
