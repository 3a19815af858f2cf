//! One frame's result as a JSON line: the pose, the counts of each stage, the stage timings,
//! each slot's state and grasp frame and, where the truth is known, the paper's metrics and
//! the slots' accuracy.

use crate::{correct_matches, pose_errors};
use crate::{isometry_from_rows, isometry_to_rows};
use crate::{Estimator, PoseEstimate, SlotReading, SlotState, StageTimings, Verdict};
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
    /// Of the model's sensor-facing points at the pose that fell on a measured pixel, the
    /// share the sensor saw past (measured well behind them); absent when the pose came
    /// from a cloud without its depth map, or from files written before it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub see_through: Option<f32>,
    /// The same share at the pose moved by one slot's pitch that the camera saw past least
    /// (absent where `see_through` is, where the tray has fewer than two slots, and where
    /// the pose's own share is below the excess that could reject it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub see_through_shifted: Option<f32>,
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
    /// Each slot as judged under the pose, in slot order; absent when the model carries no
    /// slots (a file older than format 5) or no pose was found.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub slots: Option<Vec<SlotRecord>>,
    /// The slots' states against the truth, where it is known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub slot_score: Option<SlotScore>,
    /// Hard negatives of the scene (a study's `evaluate` only): wrong poses made from the
    /// truth, each refined and verified against the frame as the pipeline would have.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub negatives: Option<Vec<NegativeRecord>>,
}

/// One hard negative of a frame: a wrong pose made from the truth (a turn the tray's
/// symmetries do not list, a turn laying the slot grid onto itself, a slot's pitch off, a
/// tilt off the table), refined by ICP against the frame and verified.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NegativeRecord {
    /// What the negative is: `turn`, `grid turn`, `shift` or `tilt`.
    pub kind: String,
    /// The verification's verdict of the refined pose.
    pub verdict: String,
    /// The verification's score of the refined pose.
    pub score: f32,
    /// The refined pose's errors against the truth (symmetries undone), mm and deg.
    pub position_error_mm: f64,
    pub rotation_error_deg: f64,
    /// The refined pose came back within the success limits: no negative after all.
    pub correct: bool,
    /// The refined pose is off by more than `GROSS_FACTOR` times a success limit (a turn,
    /// a slot away); a wrong pose within it is a near miss, the rig's calibration error's
    /// scale, which no score of a frame tells from the correct poses.
    #[serde(default)]
    pub gross: bool,
}

impl NegativeRecord {
    /// Whether the verification accepted it.
    pub fn accepted(&self) -> bool {
        self.verdict == Verdict::Accepted.as_str()
    }
}

/// One slot of one frame, as `poses.jsonl` holds it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SlotRecord {
    /// `filled`, `empty` or `unseen`.
    pub state: String,
    /// Filled with something that is not an upright item (tilted, another size).
    pub askew: bool,
    /// Measured points in the footprint above the raise height.
    pub points_above: u32,
    /// The share of the footprint measured, in [0, 1].
    pub seen_share: f32,
    /// The slot's frame (where its item's bottom centre sits) -> world frame, row-major 4 × 4.
    #[serde(rename = "T_world_slot")]
    pub t_world_slot: [[f64; 4]; 4],
    /// The slot's frame in the robot's base frame, for a filled slot of an accepted pose when
    /// the cell has a `[robot]`.
    #[serde(rename = "T_robot_slot", default, skip_serializing_if = "Option::is_none")]
    pub t_robot_slot: Option<[[f64; 4]; 4]>,
}

impl SlotRecord {
    /// The record of one reading.
    pub fn of(r: &SlotReading) -> SlotRecord {
        SlotRecord {
            state: r.state.as_str().to_string(),
            askew: r.askew,
            points_above: r.points_above,
            seen_share: r.seen_share,
            t_world_slot: isometry_to_rows(&r.t_world_slot),
            t_robot_slot: None,
        }
    }

    /// Whether the slot was judged filled.
    pub fn filled(&self) -> bool {
        self.state == SlotState::Filled.as_str()
    }
}

/// A frame's slot states against the truth's filled slots.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct SlotScore {
    /// Slots judged.
    pub slots: u32,
    /// Slots holding an item judged empty.
    pub filled_called_empty: u32,
    /// Empty slots judged filled.
    pub empty_called_filled: u32,
    /// Slots judged unseen, whatever they held.
    pub unseen: u32,
    /// The largest distance of a truly filled slot's frame from its true place, mm.
    #[serde(default)]
    pub grasp_error_mm: f64,
    /// The largest angle of a truly filled slot's frame from its true orientation, deg.
    #[serde(default)]
    pub grasp_error_deg: f64,
    /// Each truly filled slot's frame error (mm, deg), in the slots' order.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub grasp_errors: Vec<[f64; 2]>,
}

impl SlotScore {
    /// `readings`, judged under the pose `t_world_tray`, against the truth's filled slots
    /// `filled` and its pose `truth`: each grasp frame is compared with the same slot's frame
    /// under the true pose (no symmetry is undone: a turned tray holds its slots elsewhere).
    pub fn of(
        readings: &[SlotReading],
        filled: &[usize],
        t_world_tray: &Isometry3<f64>,
        truth: &Isometry3<f64>,
    ) -> SlotScore {
        let mut s = SlotScore { slots: readings.len() as u32, ..SlotScore::default() };
        let to_truth = truth * t_world_tray.inverse();
        for &n in filled {
            let Some(r) = readings.get(n) else { continue };
            let want = to_truth * r.t_world_slot;
            let d = want.inverse() * r.t_world_slot;
            let (mm, deg) = (d.translation.vector.norm(), d.rotation.angle().to_degrees());
            s.grasp_error_mm = s.grasp_error_mm.max(mm);
            s.grasp_error_deg = s.grasp_error_deg.max(deg);
            s.grasp_errors.push([mm, deg]);
        }
        for (n, r) in readings.iter().enumerate() {
            match (r.state, filled.contains(&n)) {
                (SlotState::Unseen, _) => s.unseen += 1,
                (SlotState::Empty, true) => s.filled_called_empty += 1,
                (SlotState::Filled, false) => s.empty_called_filled += 1,
                _ => {}
            }
        }
        s
    }

    /// Slots called filled when empty or empty when filled.
    pub fn wrong(&self) -> u32 {
        self.filled_called_empty + self.empty_called_filled
    }
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
            see_through: (pose.found && pose.verification.see_through.tested > 0)
                .then(|| pose.verification.see_through.share()),
            see_through_shifted: (pose.found && pose.verification.see_through_shifted.tested > 0)
                .then(|| pose.verification.see_through_shifted.share()),
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
            slots: None,
            slot_score: None,
            negatives: None,
        }
    }

    /// Adds each slot's state and frame (`estimator.slots()` of the frame); nothing when
    /// there are none.
    pub fn with_slots(mut self, readings: &[SlotReading]) -> Self {
        self.slots = (!readings.is_empty()).then(|| readings.iter().map(SlotRecord::of).collect());
        self
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
        if let (Some(robot), true, Some(slots)) = (&cell.robot, self.accepted(), self.slots.as_mut()) {
            let t_robot_world = isometry_from_rows(&robot.t_robot_world);
            for slot in slots.iter_mut().filter(|s| s.filled()) {
                slot.t_robot_slot = Some(isometry_to_rows(&(t_robot_world * isometry_from_rows(&slot.t_world_slot))));
            }
        }
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

    /// Slot states are scored against the truth: each wrong call counted on its side, unseen
    /// slots apart; a record's slots survive its line and reach the robot's frame only when
    /// filled and accepted.
    #[test]
    fn slots_are_scored_and_recorded() {
        let reading = |state| SlotReading { state, ..SlotReading::default() };
        let r = [
            reading(SlotState::Filled),
            reading(SlotState::Empty),
            reading(SlotState::Unseen),
            reading(SlotState::Empty),
            reading(SlotState::Filled),
        ];
        let same = Isometry3::identity();
        let s = SlotScore::of(&r, &[0, 2, 3], &same, &same);
        assert_eq!(
            s,
            SlotScore {
                slots: 5,
                filled_called_empty: 1,
                empty_called_filled: 1,
                unseen: 1,
                grasp_errors: vec![[0.0, 0.0]; 3],
                ..SlotScore::default()
            },
            "slot 3 is filled but called empty, slot 4 empty but called filled"
        );
        assert_eq!(s.wrong(), 2);
        // A pose 3 mm off along x and turned 0.5° about z moves slot 0's frame, 40 mm from the
        // tray's origin along y, by its translation and the turn's lever.
        let mut r = r;
        r[0].t_world_slot = Isometry3::translation(0.0, 40.0, 0.0);
        let truth = Isometry3::new(nalgebra::Vector3::new(3.0, 0.0, 0.0), nalgebra::Vector3::z() * 0.5f64.to_radians());
        let s = SlotScore::of(&r, &[0], &same, &truth);
        let want = (truth * nalgebra::Point3::new(0.0, 40.0, 0.0) - nalgebra::Point3::new(0.0, 40.0, 0.0)).norm();
        assert!((s.grasp_error_mm - want).abs() < 1e-9 && (s.grasp_error_deg - 0.5).abs() < 1e-9, "{s:?}");
        assert_eq!(s.grasp_errors, [[s.grasp_error_mm, s.grasp_error_deg]]);
        let pose = PoseEstimate { found: true, ..Default::default() };
        let record = FrameRecord::new("0001", &pose).with_slots(&r);
        let back: FrameRecord = serde_json::from_str(&record.to_line()).unwrap();
        assert_eq!(back, record);
        assert!(record.to_line().contains("\"state\":\"unseen\""), "{}", record.to_line());
        assert!(FrameRecord::new("0001", &pose).with_slots(&[]).slots.is_none());
    }

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
