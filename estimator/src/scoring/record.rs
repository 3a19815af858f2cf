//! One frame's result as a JSON line: the pose, the counts of each stage, the stage timings
//! and, where the truth is known, the paper's metrics.

use crate::{correct_matches, pose_errors};
use crate::{isometry_from_rows, isometry_to_rows};
use crate::{Estimator, PoseEstimate, StageTimings, Verdict};
use camplace_config::{Cell, Metrics};
use nalgebra::Isometry3;
use serde::{Deserialize, Serialize};

/// Time spent in each stage of one frame, ms.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Timings {
    /// Rectification of the raw shots.
    pub rectify: f64,
    /// One-shot stereo or 12-shot phase decoding.
    pub disparity: f64,
    /// Disparity to world cloud with background removal.
    pub cloud: f64,
    /// Voxel down-sampling.
    pub downsample: f64,
    /// Normals.
    pub normals: f64,
    /// Key points and descriptors.
    pub features: f64,
    /// Descriptor matching.
    pub matching: f64,
    /// Prerejective RANSAC.
    pub ransac: f64,
    /// ICP.
    pub icp: f64,
    /// The verification (absent from files written before it).
    #[serde(default)]
    pub verify: f64,
}

impl From<&StageTimings> for Timings {
    fn from(t: &StageTimings) -> Self {
        Timings {
            rectify: t.rectify_ms,
            disparity: t.disparity_ms,
            cloud: t.cloud_ms,
            downsample: t.downsample_ms,
            normals: t.normals_ms,
            features: t.features_ms,
            matching: t.matching_ms,
            ransac: t.ransac_ms,
            icp: t.icp_ms,
            verify: t.verify_ms,
        }
    }
}

impl Timings {
    /// The stages by name, in pipeline order.
    pub fn named(&self) -> [(&'static str, f64); 10] {
        [
            ("rectify", self.rectify),
            ("disparity", self.disparity),
            ("cloud", self.cloud),
            ("downsample", self.downsample),
            ("normals", self.normals),
            ("features", self.features),
            ("matching", self.matching),
            ("ransac", self.ransac),
            ("icp", self.icp),
            ("verify", self.verify),
        ]
    }
}

/// A pose scored against the truth with the paper's metrics.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Score {
    /// Distance between the estimated and true tray origins, mm.
    pub position_error_mm: f64,
    /// Symmetry-aware geodesic rotation error, deg.
    pub rotation_error_deg: f64,
    /// Matches whose model feature lies within the correct-match distance of its scene key
    /// point under the true pose.
    pub correct_matches: u32,
    /// A pose was found, and it is within the success limits.
    pub success: bool,
}

/// Scores the estimator's last frame against `truth` (`T_world_tray`) with the tray's
/// symmetries (turns about tray z, deg).
pub fn score(
    pose: &PoseEstimate,
    estimator: &Estimator,
    truth: &Isometry3<f64>,
    symmetries_deg: &[f32],
    metrics: &Metrics,
) -> Score {
    let errors = pose_errors(&pose.t_world_tray, truth, symmetries_deg, metrics);
    let correct = correct_matches(
        estimator.scene_keypoints(),
        &estimator.model().feature_points,
        estimator.correspondences(),
        truth,
        symmetries_deg,
        metrics.correct_match,
    );
    Score {
        position_error_mm: errors.position_mm,
        rotation_error_deg: errors.rotation_deg,
        correct_matches: correct,
        success: pose.found && errors.success,
    }
}

/// One frame's line in `poses.jsonl` and `results.jsonl`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FrameRecord {
    /// The frame's folder name in a dataset, or the scenario index in a study.
    pub frame: String,
    /// Tray frame -> world frame, row-major 4x4 (meaningless when not `found`).
    #[serde(rename = "T_world_tray")]
    pub t_world_tray: [[f64; 4]; 4],
    /// Whether a pose passed RANSAC's checks.
    pub found: bool,
    /// The verification's score in [0, 1]: the share of the tray's visible surface the
    /// sensor saw times the share of points in the tray's box the model explains (0 when no
    /// pose was found). Absent from files written before the verification.
    #[serde(rename = "score", default, skip_serializing_if = "Option::is_none")]
    pub verify_score: Option<f32>,
    /// `accepted` or `rejected: <reason>` (no tray, off the table, poor fit, ambiguous); only
    /// an accepted pose may be handed on. Absent from files written before the verification.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub verdict: Option<String>,
    /// RANSAC inliers of the closest view.
    pub inliers: u32,
    /// Points of the down-sampled scene cloud.
    pub scene_points: u32,
    /// Scene key points described.
    pub keypoints: u32,
    /// Matches after the height filter.
    pub matches: u32,
    /// RANSAC iterations run (samples drawn, rejected ones included).
    #[serde(default)]
    pub ransac_iterations: u32,
    /// ICP iterations run.
    pub icp_iterations: u32,
    /// Per-stage time, ms.
    pub timings_ms: Timings,
    /// The whole frame, ms.
    pub ms: f64,
    /// The metrics, where the truth is known.
    #[serde(flatten, default, skip_serializing_if = "Option::is_none")]
    pub score: Option<Score>,
    /// The tray's pose in the robot's base frame, when the cell has a `[robot]` and a pose
    /// was found (row-major 4 × 4, mm).
    #[serde(rename = "T_robot_tray", default, skip_serializing_if = "Option::is_none")]
    pub t_robot_tray: Option<[[f64; 4]; 4]>,
}

impl FrameRecord {
    /// The record of `pose` for the frame called `frame`, without a score.
    pub fn new(frame: impl Into<String>, pose: &PoseEstimate) -> Self {
        FrameRecord {
            frame: frame.into(),
            t_world_tray: isometry_to_rows(&pose.t_world_tray),
            found: pose.found,
            verify_score: Some(pose.verification.score),
            verdict: Some(pose.verification.verdict.as_str().to_string()),
            inliers: pose.inliers,
            scene_points: pose.scene_points,
            keypoints: pose.keypoints,
            matches: pose.matches,
            ransac_iterations: pose.ransac.iterations,
            icp_iterations: pose.icp.iterations,
            timings_ms: Timings::from(&pose.timings),
            ms: pose.timings.total_ms,
            score: None,
            t_robot_tray: None,
        }
    }

    /// Whether the pose was accepted by the verification (false for a record written
    /// before it).
    pub fn accepted(&self) -> bool {
        self.found && self.verdict.as_deref() == Some(Verdict::Accepted.as_str())
    }

    /// Adds the pose in the robot's base frame when `cell` has a `[robot]` and the
    /// verification accepted the pose: the robot is handed no other.
    pub fn with_robot(mut self, cell: &Cell) -> Self {
        self.t_robot_tray = cell.robot.as_ref().filter(|_| self.accepted()).map(|r| {
            isometry_to_rows(&(isometry_from_rows(&r.t_robot_world) * isometry_from_rows(&self.t_world_tray)))
        });
        self
    }

    /// The record as one JSON line (without the newline).
    pub fn to_line(&self) -> String {
        serde_json::to_string(self).expect("a frame record is plain data")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_record_survives_its_json_line_with_and_without_a_score() {
        let mut pose = PoseEstimate { found: true, inliers: 12, ..Default::default() };
        pose.timings.ransac_ms = 3.5;
        let mut r = FrameRecord::new("0007", &pose);
        let back: FrameRecord = serde_json::from_str(&r.to_line()).unwrap();
        assert_eq!(back, r);
        assert!(!r.to_line().contains("success"));
        r.score = Some(Score { position_error_mm: 1.5, rotation_error_deg: 0.25, correct_matches: 40, success: true });
        let line = r.to_line();
        assert!(line.contains("\"success\":true") && line.contains("\"T_world_tray\""), "{line}");
        assert!(line.contains("\"score\":0.0") && line.contains("\"verdict\":\"rejected: no tray\""), "{line}");
        let back: FrameRecord = serde_json::from_str(&line).unwrap();
        assert_eq!(back, r);
    }

    /// A line written before the verification (no score, no verdict) still loads, as a pose
    /// that was not accepted.
    #[test]
    fn a_line_without_score_and_verdict_loads() {
        let pose = PoseEstimate { found: true, inliers: 12, ..Default::default() };
        let mut r = FrameRecord::new("0003", &pose);
        r.score = Some(Score { position_error_mm: 1.5, rotation_error_deg: 0.25, correct_matches: 40, success: true });
        let mut value: serde_json::Value = serde_json::from_str(&r.to_line()).unwrap();
        let object = value.as_object_mut().unwrap();
        assert!(object.remove("score").is_some() && object.remove("verdict").is_some());
        object.get_mut("timings_ms").unwrap().as_object_mut().unwrap().remove("verify");
        let back: FrameRecord = serde_json::from_value(value).unwrap();
        assert_eq!((back.verify_score, back.verdict.as_deref(), back.accepted()), (None, None, false));
        assert_eq!(back.score, r.score);
    }
}
