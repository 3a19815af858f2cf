//! The cell file's schema: the serde structs of every table (table, tray, items, sensor,
//! lighting, scenarios, work volume, stereo, phase, reconstruction, estimator, metrics,
//! robot), as a cell file holds them. Reading them is `load.rs`'s, checking `check.rs`'s.

use serde::{Deserialize, Serialize};
use std::path::PathBuf;

use super::realism::{CalibrationError, Effects, Occluder, Optics};
use super::trays::TrayEntry;
use crate::{Error, Placement, RigFile};

/// A whole robot cell.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Cell {
    pub table: Table,
    pub tray: Tray,
    pub items: Items,
    pub sensor: Sensor,
    pub placement: Placement,
    pub lighting: Lighting,
    pub scenarios: Scenarios,
    pub work_volume: WorkVolume,
    pub stereo: StereoParams,
    pub phase: PhaseParams,
    pub reconstruction: ReconstructionParams,
    pub estimator: EstimatorParams,
    pub metrics: Metrics,
    /// The lenses' focal lengths, f-numbers and focus (thin-lens defocus).
    pub optics: Optics,
    /// The error of the rig the estimator uses, drawn per scenario.
    pub calibration_error: CalibrationError,
    /// A box above the tray in some scenarios.
    pub occluder: Occluder,
    /// Which of the effects above (and the materials' gloss) are rendered.
    pub effects: Effects,
    /// Where the world frame lies in the robot's base frame (`[robot]`, optional), so that
    /// `run` can give each pose in the frame the robot moves in.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub robot: Option<Robot>,
    /// The trays of a cell that handles several products (empty: the one `tray`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub trays: Vec<TrayEntry>,
    /// The rig as installed (`[rig]`, a calibrated `rig.json`, usually given with `--rig`):
    /// when set, scenes are rendered by these cameras, with the projector where the
    /// placement puts it relative to the left camera, instead of by the placement's rig.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rig: Option<RigFile>,
}

/// The robot the poses are for.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Robot {
    /// World frame to robot base frame, row-major 4 × 4, mm (from a hand-eye calibration,
    /// or by touching the table's centre and axes with the tool centre point).
    #[serde(rename = "T_robot_world")]
    pub t_robot_world: [[f64; 4]; 4],
    /// For a rig carried by the robot: the rig's frame (its left camera's) in the flange's,
    /// row-major 4 × 4, mm (from `calibrate --hand-eye --eye-in-hand`).
    #[serde(rename = "T_flange_rig", default, skip_serializing_if = "Option::is_none")]
    pub t_flange_rig: Option<[[f64; 4]; 4]>,
    /// How `serve` writes a pose for this robot's controller: `"CONVENTION UNIT"` (see
    /// `RobotPoseFormat::from_text`); `"matrix mm"` when not given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pose_format: Option<String>,
}

impl Robot {
    /// The `[robot]` table as a cell file takes it, after `comment` (each of its lines
    /// written as a `#` line), every number in full; it is read back through the cell's own
    /// checks, so a table that a cell file would refuse is refused here, never written.
    pub fn to_toml(&self, comment: &str) -> Result<String, Error> {
        let matrix = |rows: &[[f64; 4]; 4]| {
            let row = |r: &[f64; 4]| format!("[{}]", r.iter().map(|v| format!("{v:?}")).collect::<Vec<_>>().join(", "));
            format!("[{}]", rows.iter().map(row).collect::<Vec<_>>().join(", "))
        };
        let mut text: String = comment.lines().map(|l| format!("# {l}\n")).collect();
        text.push_str(&format!("[robot]\nT_robot_world = {}\n", matrix(&self.t_robot_world)));
        if let Some(t) = &self.t_flange_rig {
            text.push_str(&format!("T_flange_rig = {}\n", matrix(t)));
        }
        if let Some(f) = &self.pose_format {
            text.push_str(&format!("pose_format = {f:?}\n"));
        }
        let read = crate::Cell::from_toml_str(&text, std::path::Path::new("."))?;
        if read.robot.as_ref() != Some(self) {
            return Err(Error::value("robot", "expected a table that reads back as written"));
        }
        Ok(text)
    }

    /// The pose format of `serve`'s replies (`"matrix mm"` when the cell names none).
    pub fn reply_format(&self) -> Result<crate::RobotPoseFormat, Error> {
        match &self.pose_format {
            Some(text) => crate::RobotPoseFormat::from_text(text).map_err(|m| Error::value("robot.pose_format", m)),
            None => {
                Ok(crate::RobotPoseFormat { convention: crate::PoseConvention::Matrix, unit: crate::LengthUnit::Mm })
            }
        }
    }
}

/// The table top.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Table {
    /// Extent along world x and y, mm.
    pub size: [f64; 2],
    pub albedo: f64,
    /// Specular albedo of the glossy lobe (0: matte).
    pub specular: f64,
    /// Roughness of the glossy lobe, from 0.02 (mirror-like) to 1 (broad).
    pub roughness: f64,
}

/// Built-in tray or a mesh.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum TrayKind {
    #[serde(rename = "tray-4")]
    Tray4,
    #[serde(rename = "tray-8")]
    Tray8,
    #[serde(rename = "mesh")]
    Mesh,
}

/// The tray to be found.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Tray {
    pub kind: TrayKind,
    /// Mesh file when `kind` is `mesh` (resolved against the cell file's folder on load).
    pub mesh: PathBuf,
    /// Slot poses `[x, y, z, yaw]` in the tray frame, mm and deg (mesh trays only).
    pub slots: Vec<[f64; 4]>,
    /// Rotations about tray z (deg) that map the tray onto itself.
    pub symmetries: Vec<f64>,
    pub albedo: f64,
    /// Specular albedo of the glossy lobe (0: matte).
    pub specular: f64,
    /// Roughness of the glossy lobe.
    pub roughness: f64,
}

/// Built-in box item or a mesh.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ItemsKind {
    Box,
    Mesh,
}

/// The items placed in the tray's slots.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Items {
    pub kind: ItemsKind,
    pub mesh: PathBuf,
    /// Size of the built-in box `[x, y, z]`, mm.
    pub size: [f64; 3],
    pub albedo: f64,
    /// Specular albedo of the glossy lobe (0: matte).
    pub specular: f64,
    /// Roughness of the glossy lobe.
    pub roughness: f64,
}

/// The stereo camera pair and the projector.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Sensor {
    pub camera_resolution: [u32; 2],
    pub camera_hfov: f64,
    /// Full camera matrix, empty for one made from `camera_hfov`.
    pub camera_k: Vec<[f64; 3]>,
    /// Lens distortion of both cameras, k1 k2 p1 p2 k3 (OpenCV order); all zero (the
    /// default, left out of the cell's canonical text) renders distortion-free images.
    #[serde(default, skip_serializing_if = "is_distortion_free")]
    pub camera_dist: [f64; 5],
    pub projector_resolution: [u32; 2],
    pub projector_hfov: f64,
    pub projector_offset: [f64; 3],
    pub projector_gain: f64,
    pub noise_amplitude: u32,
    pub blur: u32,
    pub dot_size: u32,
    pub dot_density: f64,
    pub fringe_periods: Vec<f64>,
}

/// Ranges of the light drawn per scenario.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Lighting {
    pub ambient: [f64; 2],
    pub lamp_strength: [f64; 2],
    pub lamp_polar: [f64; 2],
    pub lamp_distance: f64,
}

/// Ranges of the scenes drawn per scenario.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenarios {
    pub seed: u64,
    pub count: u32,
    pub tray_x: [f64; 2],
    pub tray_y: [f64; 2],
    pub tray_yaw: [f64; 2],
    pub fill_probability: f64,
}

/// The box of the world that can hold the tray.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WorkVolume {
    pub x: [f64; 2],
    pub y: [f64; 2],
    pub z: [f64; 2],
}

/// The one-shot (ELAS-class) matcher's settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StereoParams {
    pub support_step: u32,
    pub support_uniqueness: f64,
    pub min_texture: u32,
    pub lr_tolerance: f64,
    pub prior_radius: u32,
    pub speckle_size: u32,
    pub speckle_similarity: f64,
    pub gap_width: u32,
    /// Side of the candidate grid cells, px.
    pub grid_size: u32,
    /// Spread of the plane prior, px.
    pub prior_sigma: f64,
    /// Uniform outlier weight of the prior.
    pub prior_gamma: f64,
    /// Descriptor cost per unit of prior log-likelihood.
    pub prior_beta: f64,
    /// Half side of the sub-pixel refinement window, px.
    pub subpixel_radius: u32,
    /// Dense matching runs on every `row_step`-th row (1: every row).
    pub row_step: u32,
}

/// The 12-shot phase decoder's settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PhaseParams {
    pub min_modulation: f64,
    pub lr_tolerance: f64,
}

/// Cloud and background removal settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReconstructionParams {
    pub background_margin: f64,
    pub background_dilation: u32,
}

/// Which estimator a cell runs: ours, or the paper's as a preset.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum EstimatorPreset {
    /// The keys of `[estimator]` as given.
    Ours,
    /// The paper's estimator (Buch et al.'s RANSAC as the paper ran it): 3-match samples,
    /// ECSAD support of 10 x SRes, no turn check, an untrimmed ICP, a model of 6 viewpoints;
    /// Table 1's SRes, k, RIt and ICPIt are the defaults already.
    Paper,
}

/// The pose estimator's settings (Table 1 of the paper and the rest).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EstimatorParams {
    /// "ours" (the keys as given) or "paper": the paper's estimator, which sets
    /// `ransac_sample`, `feature_radius`, `turn_check`, `icp_on_table`, `icp_trim`,
    /// `pose_on_table`, `verify` and `model_viewpoints` (see [`EstimatorPreset`]).
    pub preset: EstimatorPreset,
    pub surface_resolution: f64,
    /// Radius of the neighbourhood a normal is fitted to, mm.
    pub normal_radius: f64,
    pub keypoint_spacing: f64,
    /// Key points whose descriptor deviates less than this from a plane's (RMS, deg) are
    /// not matched: flat surface looks alike everywhere.
    pub min_relief: f64,
    pub feature_radius: f64,
    pub k: u32,
    pub height_band: f64,
    pub ransac_iterations: u32,
    /// Matches per RANSAC sample: 3 (a free pose), 2 (a tray resting on the table) or 1 (a
    /// tray resting on the table, its turn from the match's normals).
    pub ransac_sample: u32,
    pub edge_similarity: f64,
    pub table_height: f64,
    pub table_tilt: f64,
    pub inlier_distance: f64,
    /// Share of the closest view's ICP points that must be inliers for a pose (0 .. 1).
    pub min_inlier_share: f64,
    pub icp_iterations: u32,
    pub icp_max_distance: f64,
    /// Share of the farthest ICP correspondences dropped each iteration (0 .. 0.9).
    pub icp_trim: f64,
    /// Whether ICP keeps the tray resting on the table (bottom at z = 0, no tilt) and
    /// refines only x, y and the turn about z (beyond the paper).
    pub icp_on_table: bool,
    /// Whether the pose handed on is the fit laid on the table (its x, y and turn about z,
    /// bottom at z = 0, no tilt) when the fit rests on it (beyond the paper).
    pub pose_on_table: bool,
    /// Whether the pose turned by quarter turns is scored too (beyond the paper).
    pub turn_check: bool,
    /// Whether the verification may reject a found pose (beyond the paper; its score is
    /// computed either way).
    pub verify: bool,
    /// The verification threshold of a model that carries none (a model file older than
    /// format 4, or one built without measuring it), in [0, 1].
    pub verify_threshold: f64,
    /// The largest share of wrong poses among the accepted ones the threshold is chosen
    /// for, in (0, 1).
    pub verify_max_wrong: f64,
    pub seed: u64,
    /// Fill states the model builder captures per viewpoint, full to empty evenly apart
    /// (at most slots + 1, every state).
    pub model_fill_states: u32,
    /// Turns of the tray about z the model is built from, 360° / model_viewpoints apart
    /// (each one ICP cloud of the model).
    pub model_viewpoints: u32,
}

/// How a pose estimate is judged.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Metrics {
    pub correct_match: f64,
    pub success_position: f64,
    pub success_rotation: f64,
}
/// Whether a distortion is all zero (serde's skip test for `camera_dist`).
fn is_distortion_free(dist: &[f64; 5]) -> bool {
    dist.iter().all(|&d| d == 0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_robot_table_reads_back_as_written_and_a_bad_one_is_not_written() {
        let half_turn = [[-1.0, 0.0, 0.0, 412.5], [0.0, 1.0, 0.0, -0.1], [0.0, 0.0, -1.0, 1e-17], [0.0, 0.0, 0.0, 1.0]];
        let robot = Robot {
            t_robot_world: half_turn,
            t_flange_rig: Some([
                [0.0, -1.0, 0.0, 1.0],
                [1.0, 0.0, 0.0, 2.0],
                [0.0, 0.0, 1.0, 3.0],
                [0.0, 0.0, 0.0, 1.0],
            ]),
            pose_format: Some("ur m".into()),
        };
        let text = robot.to_toml("made by a test\nsecond line").unwrap();
        assert!(text.starts_with("# made by a test\n# second line\n[robot]\n"), "{text}");
        let read = crate::Cell::from_toml_str(&text, std::path::Path::new(".")).unwrap();
        assert_eq!(read.robot, Some(robot.clone()));
        let mut bad = robot.clone();
        bad.t_robot_world[0][3] = f64::NAN;
        assert!(bad.to_toml("").is_err());
        let mut sheared = robot;
        sheared.t_robot_world[0][1] = 0.5;
        assert!(sheared.to_toml("").unwrap_err().to_string().contains("T_robot_world"));
    }
}
