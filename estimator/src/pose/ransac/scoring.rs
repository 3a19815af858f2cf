//! Scoring RANSAC's hypotheses: inliers of the closest viewpoint's ICP cloud against the
//! scene index, on a fixed random prefix of the view with an early exit once a hypothesis
//! cannot win, the count on the whole view, and the consensus re-fit of the winner.

use nalgebra::{Isometry3, Matrix3, Point3, Vector3};
use rayon::prelude::*;

use super::super::kabsch::RigidFit;
use super::Ransac;

/// The lowest share of a view's scoring sample a bar may stand for when a score against it
/// stands in for the score against a higher bar (see `Ransac::monotone_bar`).
const MONOTONE_RATE: f64 = 0.1;
/// Points scored between two early-exit checks.
const SCORE_BLOCK: usize = 32;
/// Hypotheses are compared on this many points of the view (a random sample: the view is
/// shuffled); the winner is then counted on every point. Inlier shares on 8 192 points
/// differ from the whole view's by about half a percent (one standard deviation at a share
/// of 0.5), far below the gap between the right pose and a wrong one, and the sample costs a
/// fifth of a 40 000-point view.
pub(super) const SCORE_SAMPLE: usize = 8192;
/// A hypothesis is dropped once its inliers on the points scored so far fall this many
/// standard deviations below what a hypothesis with exactly the count to beat would show.
/// The points come in a random order, so a truly better hypothesis is dropped with about the
/// one-sided normal tail at this level (0.1 %) per check; a hypothesis near the truth is
/// drawn many times over, so losing one costs nothing.
const EARLY_EXIT_SIGMAS: f32 = 3.0;
/// Sample points per part of the consensus fit (8 parts of a full sample).
pub(super) const CONSENSUS_CHUNK: usize = 1024;

impl Ransac {
    /// The inliers a hypothesis scored on `view` must beat: the best so far, and at least
    /// one short of the fewest it needs to be kept (reaching the minimum exactly is enough).
    pub(super) fn to_beat(&self, best_inliers: u32, view: usize) -> u32 {
        best_inliers.max(self.required_in_sample(view).saturating_sub(1))
    }

    /// Whether [`Ransac::score`] against the lowest bar of `view` tells its outcome against
    /// any higher bar: a hypothesis dropped against a bar is dropped against every higher
    /// one. Both early exits are then monotone in the bar: the count left to reach it
    /// trivially, and the 3-sigma test because `rate n - 3 sqrt(n rate (1 - rate))` rises
    /// with the rate for rates of at least [`MONOTONE_RATE`] at every count n it checks at
    /// (at least [`SCORE_BLOCK`] points): its slope in the rate is n - 3 sqrt(n) (1 - 2 rate)
    /// / (2 sqrt(rate (1 - rate))), at least 9 there, so the steps between whole bars stay
    /// far above f32 rounding.
    pub(super) fn monotone_bar(&self, view: usize) -> bool {
        let len = self.sample_len(view);
        len >= SCORE_BLOCK && self.to_beat(0, view) as f64 >= MONOTONE_RATE * len as f64
    }

    /// The fewest inliers among `view`'s scoring sample a hypothesis needs to be kept.
    pub(super) fn required_in_sample(&self, view: usize) -> u32 {
        (self.min_inlier_share * self.sample_len(view) as f32).ceil() as u32
    }

    /// Points in `view`'s scoring sample: [`SCORE_SAMPLE`], or the whole of a smaller view.
    pub(super) fn sample_len(&self, view: usize) -> usize {
        self.views[view].len()
    }

    /// The fewest inliers a pose scored on all of `view` needs to be returned.
    pub(super) fn required(&self, view: usize) -> u32 {
        (self.min_inlier_share * self.model.views[view].points.len() as f32).ceil() as u32
    }

    /// Inliers of `pose` among the first [`SCORE_SAMPLE`] points of `view`, or `None` as
    /// soon as the points scored so far show it will not reach `to_beat`.
    pub(super) fn score(&self, pose: &Isometry3<f64>, view: usize, to_beat: u32) -> Option<u32> {
        let (r, t) = split(pose);
        let points = &self.views[view][..self.sample_len(view)];
        let total = points.len();
        let r2 = self.inlier_distance * self.inlier_distance;
        let mut inliers = 0u32;
        let mut moved = [Point3::origin(); SCORE_BLOCK];
        for (b, block) in points.chunks(SCORE_BLOCK).enumerate() {
            for (m, p) in moved.iter_mut().zip(block) {
                *m = r * p + t;
            }
            inliers += self.grid.count_within(&moved[..block.len()], r2);
            let scored = (b * SCORE_BLOCK + block.len()) as u32;
            let left = total as u32 - scored;
            if inliers + left <= to_beat && to_beat > 0 {
                return None;
            }
            let rate = to_beat as f32 / total as f32;
            let expected = rate * scored as f32;
            let sigma = (expected * (1.0 - rate)).max(0.0).sqrt();
            if (inliers as f32) < expected - EARLY_EXIT_SIGMAS * sigma {
                return None;
            }
        }
        Some(inliers)
    }

    /// Inliers of `pose` on `view`, every point counted.
    pub(super) fn count(&self, pose: &Isometry3<f64>, view: usize) -> u32 {
        let (r, t) = split(pose);
        let r2 = self.inlier_distance * self.inlier_distance;
        // In fixed chunks, so the count is the same whatever the number of threads.
        self.model.views[view]
            .points
            .par_chunks(4096)
            .map(|chunk| chunk.iter().filter(|p| self.grid.any_within(&(r * *p + t), r2)).count() as u32)
            .sum()
    }

    /// The pose fitted to the inliers of `pose` among the scoring sample of `view` (each
    /// paired with its nearest scene point), and their count, which is [`Ransac::score`]'s
    /// with nothing to beat. The sample is fitted in fixed chunks, summed in order, so the
    /// fit is the same whatever the number of threads.
    pub(super) fn consensus(&mut self, pose: &Isometry3<f64>, view: usize) -> (Option<Isometry3<f64>>, u32) {
        let (r, t) = split(pose);
        let r2 = self.inlier_distance * self.inlier_distance;
        let points = &self.views[view][..self.sample_len(view)];
        let origin = points[0];
        let target_origin = Point3::from(r * origin.coords + t);
        let chunks = points.len().div_ceil(CONSENSUS_CHUNK);
        let mut parts = std::mem::take(&mut self.consensus_parts);
        parts.clear();
        parts.resize(chunks, RigidFit::about(&origin, &target_origin));
        let grid = &self.grid;
        points.par_chunks(CONSENSUS_CHUNK).zip(parts.par_iter_mut()).for_each(|(chunk, fit)| {
            for p in chunk {
                if let Some(s) = grid.nearest_within(&(r * p + t), r2) {
                    fit.add(p, &s);
                }
            }
        });
        let mut fit = RigidFit::about(&origin, &target_origin);
        for part in &parts {
            fit.merge(part);
        }
        self.consensus_parts = parts;
        (fit.solve(), fit.pairs())
    }
}

/// The rotation matrix and translation of `pose` in f32, for transforming many points.
pub(super) fn split(pose: &Isometry3<f64>) -> (Matrix3<f32>, Vector3<f32>) {
    (pose.rotation.to_rotation_matrix().matrix().cast::<f32>(), pose.translation.vector.cast::<f32>())
}
