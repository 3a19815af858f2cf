//! Drawing RANSAC's samples: the matches grouped by scene key point, a key point's match
//! drawn by its rank (nearer descriptors more often), and the 3-, 2- and 1-match samples
//! put through the pre-rejection checks (`checks.rs`) at each stage, the random draws in the
//! same order whatever the checks reject.

use nalgebra::{Isometry3, Matrix3, Point3, Translation3, UnitQuaternion, Vector3};
use rand::RngExt;
use rand_chacha::ChaCha8Rng;

use super::super::kabsch::RigidFit;
#[cfg(doc)]
use super::checks::RansacCheck;
use super::scoring::split;
use super::{Keys, Ransac};
use crate::features::MAX_K;
use crate::{Correspondence, Model};

impl Ransac {
    /// One 3-match hypothesis, or `None` when the sample is rejected before scoring: three
    /// distinct key points that pass the scene checks, one match of each that pass the match
    /// checks, and a fitted pose that passes the pose checks ([`RansacCheck::paper`]'s: a good
    /// triangle, edges that agree in length, a pose that rests on the table).
    pub(super) fn triple(&self, rng: &mut ChaCha8Rng, keys: Keys<'_>, model: &Model) -> Option<Isometry3<f64>> {
        let n = self.matched.len() as u32;
        let k = [
            self.matched[rng.random_range(0..n) as usize] as usize,
            self.matched[rng.random_range(0..n) as usize] as usize,
            self.matched[rng.random_range(0..n) as usize] as usize,
        ];
        if k[0] == k[1] || k[0] == k[2] || k[1] == k[2] {
            return None;
        }
        let s = k.map(|i| keys.points[i]);
        if !self.checks.iter().all(|c| c.scene(&s)) {
            return None;
        }
        let f = k.map(|i| self.draw_match(rng, i));
        if f[0] == f[1] || f[0] == f[2] || f[1] == f[2] {
            return None;
        }
        let m = f.map(|j| model.feature_points[j as usize]);
        if !self.checks.iter().all(|c| c.matched(&s, &m)) {
            return None;
        }
        let mut fit = RigidFit::new();
        for k in 0..3 {
            fit.add(&m[k], &s[k]);
        }
        let pose = fit.solve()?;
        self.pose_passes(&pose).then_some(pose)
    }

    /// One 2-match hypothesis of a tray resting on the table, or `None` when the sample is
    /// rejected before scoring. Two key points and one match of each that pass the checks
    /// ([`RansacCheck::table_pair`]'s: at least `feature_radius` apart horizontally, agreeing in
    /// horizontal length to `edge_similarity` and in height difference to twice the inlier
    /// distance, as a level tray's would), and a pose under which each match's normals agree.
    /// Yaw is the turn between the horizontal directions, x and y the mean offset, z the mean
    /// height offset, which the table check bounds.
    pub(super) fn table_pair(&self, rng: &mut ChaCha8Rng, keys: Keys<'_>, model: &Model) -> Option<Isometry3<f64>> {
        let n = self.matched.len() as u32;
        let first = self.matched[rng.random_range(0..n) as usize] as usize;
        self.pair_with(rng, first, keys, model)
    }

    /// The 2-match hypothesis of [`Ransac::table_pair`] whose first key point is `first`.
    fn pair_with(&self, rng: &mut ChaCha8Rng, first: usize, keys: Keys<'_>, model: &Model) -> Option<Isometry3<f64>> {
        let n = self.matched.len() as u32;
        let k = [first, self.matched[rng.random_range(0..n) as usize] as usize];
        if k[0] == k[1] {
            return None;
        }
        let s = k.map(|i| keys.points[i]);
        if !self.checks.iter().all(|c| c.scene(&s)) {
            return None;
        }
        let f = k.map(|i| self.draw_match(rng, i));
        if f[0] == f[1] {
            return None;
        }
        let m = f.map(|j| model.feature_points[j as usize]);
        if !self.checks.iter().all(|c| c.matched(&s, &m)) {
            return None;
        }
        let mean = |p: &[Point3<f32>; 2]| Point3::from((p[0].coords.cast::<f64>() + p[1].coords.cast::<f64>()) * 0.5);
        let pose = level_pose(&mean(&s), &(s[1] - s[0]), &mean(&m), &(m[1] - m[0]));
        (self.pose_passes(&pose) && self.normals_agree(&pose, keys, &k, &f, model)).then_some(pose)
    }

    /// Whether each match of the sample (key points `k`, their model features `f`) passes
    /// the checks of its normals under `pose` (unread where no check reads normals).
    fn normals_agree(&self, pose: &Isometry3<f64>, keys: Keys<'_>, k: &[usize], f: &[u32], model: &Model) -> bool {
        if !self.posed_normals {
            return true;
        }
        let (r, _) = split(pose);
        k.iter().zip(f).all(|(&k, &f)| self.normal_agrees(&r, &keys.normals[k], &model.feature_normals[f as usize]))
    }

    /// Whether a match's scene key point normal `ns` and its model feature's normal `nm`,
    /// turned by the fitted pose's rotation `r`, pass the checks of posed normals.
    #[inline]
    pub(super) fn normal_agrees(&self, r: &Matrix3<f32>, ns: &Vector3<f32>, nm: &Vector3<f32>) -> bool {
        let nm = r * nm;
        self.checks.iter().all(|c| c.posed_normal(ns, &nm))
    }

    /// One 1-match hypothesis of a tray resting on the table, or `None` when the sample is
    /// rejected before scoring. A key point whose normal leans far enough from vertical to
    /// fix a turn, and one of its matches whose normal does too and leans alike
    /// ([`RansacCheck::table_point`]'s normal checks). Yaw turns the model normal's
    /// horizontal direction onto the scene normal's; the match's offset is x, y and z, which
    /// the table check bounds. A key point whose normal does not fix the turn (a key point
    /// on a floor, or every key point under a camera looking straight down) starts a 2-match
    /// sample instead, through the pair checks of the same list.
    pub(super) fn table_point(&self, rng: &mut ChaCha8Rng, keys: Keys<'_>, model: &Model) -> Option<Isometry3<f64>> {
        let n = self.matched.len() as u32;
        let k = self.matched[rng.random_range(0..n) as usize] as usize;
        let ns = keys.normals[k];
        if !self.checks.iter().all(|c| c.scene_normal(&ns)) {
            return self.pair_with(rng, k, keys, model);
        }
        let f = self.draw_match(rng, k) as usize;
        let nm = model.feature_normals[f];
        if !self.checks.iter().all(|c| c.matched_normal(&ns, &nm)) {
            return None;
        }
        let pose = level_pose(&keys.points[k].cast(), &ns, &model.feature_points[f].cast(), &nm);
        self.pose_passes(&pose).then_some(pose)
    }

    /// One of key point `k`'s model features, drawn by [`RankWeights`].
    #[inline]
    fn draw_match(&self, rng: &mut ChaCha8Rng, k: usize) -> u32 {
        let (lo, hi) = (self.match_start[k] as usize, self.match_start[k + 1] as usize);
        let u = rng.random_range(0..self.ranks.total(hi - lo));
        self.match_model[lo + self.ranks.rank_of(u)]
    }

    /// Groups the matches by key point (a counting sort into the match buffers).
    pub(super) fn group_matches(&mut self, keypoints: usize, correspondences: &[Correspondence]) {
        self.match_start.clear();
        self.match_start.resize(keypoints + 1, 0);
        for c in correspondences {
            self.match_start[c.scene as usize + 1] += 1;
        }
        self.matched.clear();
        for k in 0..keypoints {
            if self.match_start[k + 1] > 0 {
                self.matched.push(k as u32);
            }
            self.match_start[k + 1] += self.match_start[k];
        }
        self.match_model.clear();
        self.match_model.resize(correspondences.len(), 0);
        // Filling from the back leaves each `match_start[k + 1]` at key point k's start.
        for c in correspondences.iter().rev() {
            let slot = &mut self.match_start[c.scene as usize + 1];
            *slot -= 1;
            self.match_model[*slot as usize] = c.model;
        }
        self.match_start.copy_within(1..keypoints + 1, 0);
        self.match_start[keypoints] = correspondences.len() as u32;
    }
}

/// The pose of a level tray that turns the horizontal part of model direction `dm` onto that
/// of scene direction `ds` and puts model point `m` on scene point `s`: a pair's offsets and
/// midpoints, or one match's normals and points.
pub(super) fn level_pose(s: &Point3<f64>, ds: &Vector3<f32>, m: &Point3<f64>, dm: &Vector3<f32>) -> Isometry3<f64> {
    let yaw = (ds.y as f64).atan2(ds.x as f64) - (dm.y as f64).atan2(dm.x as f64);
    let rotation = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw);
    let translation = s.coords - rotation * m.coords;
    Isometry3::from_parts(Translation3::from(translation), rotation)
}

/// How often a key point's matches are drawn by their rank (0 = the nearest descriptor):
/// weight 1 / (1 + rank / 2), in whole units so draws are exact and alike on every machine.
/// A right match is most often the nearest and less often the farther it ranks (measured at
/// the optimum over 20 scenes: 519 right matches at rank 0, 254 at rank 6, 65 at rank 24), so
/// favouring near ranks raises the chance of an all-right sample, as PROSAC (Chum and Matas,
/// 2005) does by ordering, while every match keeps a fair chance: the 25th is drawn 13 times
/// less often than the first. The stopping rule counts right matches with the same weights.
#[derive(Debug, Clone)]
pub(super) struct RankWeights {
    /// `cumulative[n]`: the summed weight of ranks 0..n.
    cumulative: [u32; MAX_K + 1],
}

impl RankWeights {
    /// Weight of rank 0; rank r weighs `UNIT / (1 + r / 2)`.
    pub(super) const UNIT: u32 = 1 << 16;

    pub(super) fn new() -> Self {
        let mut cumulative = [0u32; MAX_K + 1];
        for rank in 0..MAX_K {
            cumulative[rank + 1] = cumulative[rank] + Self::UNIT * 2 / (2 + rank as u32);
        }
        RankWeights { cumulative }
    }

    pub(super) fn weight(&self, rank: usize) -> u32 {
        self.cumulative[rank + 1] - self.cumulative[rank]
    }

    /// Summed weight of a key point with `n` matches (1 to [`MAX_K`]).
    pub(super) fn total(&self, n: usize) -> u32 {
        self.cumulative[n]
    }

    /// The rank whose share of the cumulative weight holds `u` (below `total(n)`).
    pub(super) fn rank_of(&self, u: u32) -> usize {
        self.cumulative[1..].partition_point(|&c| c <= u)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Draws land on each rank in proportion to its weight, and the weights fall with rank.
    #[test]
    fn match_draws_follow_the_rank_weights() {
        let w = RankWeights::new();
        assert_eq!(w.weight(0), RankWeights::UNIT);
        assert!((1..MAX_K).all(|r| w.weight(r) < w.weight(r - 1)));
        for n in [1, 2, 7, 25, MAX_K] {
            let mut hits = vec![0u32; n];
            for u in 0..w.total(n) {
                hits[w.rank_of(u)] += 1;
            }
            for (r, &h) in hits.iter().enumerate() {
                assert_eq!(h, w.weight(r), "n {n} rank {r}");
            }
        }
    }
}
