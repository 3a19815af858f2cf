//! The cell file: table, tray, items, sensor, placement, lighting, scenario ranges and the
//! estimator's settings. The built-in default cell is `default_cell.toml` (the text that
//! `camplace init` writes, a comment on every key); a user's file is laid over it key by
//! key, so a file names only what differs, and an unknown key is an error.

use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

use crate::formats::mesh;
pub(crate) mod realism;
pub(crate) mod trays;

use crate::{Error, ErrorKind, Placement, RigFile, MAX_DISTANCE_MM};
use realism::{CalibrationError, Effects, Occluder, Optics};
use trays::{parse_trays, validate_trays, TrayEntry};

/// The commented default cell file, as `camplace init` writes it.
pub const DEFAULT_CELL_TOML: &str = include_str!("default_cell.toml");

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
    /// ECSAD support of 10 x SRes, no turn check; Table 1's SRes, k, RIt and ICPIt are the
    /// defaults already.
    Paper,
}

/// The keys the paper preset sets, and to what (the feature radius from SRes).
fn paper_preset_keys(surface_resolution: f64) -> [(&'static str, toml::Value); 6] {
    [
        ("icp_on_table", toml::Value::Boolean(false)),
        ("pose_on_table", toml::Value::Boolean(false)),
        ("ransac_sample", toml::Value::Integer(3)),
        ("feature_radius", toml::Value::Float(10.0 * surface_resolution)),
        ("turn_check", toml::Value::Boolean(false)),
        ("verify", toml::Value::Boolean(false)),
    ]
}

/// Lays the paper preset's keys over the merged `[estimator]` table when the user's asks
/// for it; a key the preset sets given beside it is refused, since one of the two would be
/// ignored.
fn apply_preset(merged: &mut toml::Table, user: &toml::Table) -> Result<(), Error> {
    let user_est = match user.get("estimator") {
        Some(toml::Value::Table(t)) => t,
        _ => return Ok(()),
    };
    if user_est.get("preset").and_then(|v| v.as_str()) != Some("paper") {
        return Ok(());
    }
    let Some(toml::Value::Table(est)) = merged.get_mut("estimator") else { return Ok(()) };
    let sres = est.get("surface_resolution").and_then(|v| v.as_float()).unwrap_or(2.0);
    for (key, value) in paper_preset_keys(sres) {
        // The same value again (a cell written out and read back) is no conflict.
        let same = |given: &toml::Value| match (given, &value) {
            (toml::Value::Integer(a), toml::Value::Float(b)) => *a as f64 == *b,
            (a, b) => a == b,
        };
        if let Some(given) = user_est.get(key).filter(|g| !same(g)) {
            return Err(Error::value(
                format!("estimator.{key}"),
                format!(
                    "given as {given} beside preset = \"paper\", which sets it to {value}; leave it out or use preset = \"ours\""
                ),
            ));
        }
        est.insert(key.to_string(), value);
    }
    Ok(())
}

/// The pose estimator's settings (Table 1 of the paper and the rest).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EstimatorParams {
    /// "ours" (the keys as given) or "paper": the paper's estimator, which sets
    /// `ransac_sample`, `feature_radius`, `turn_check`, `icp_on_table`, `pose_on_table` and
    /// `verify` (see [`EstimatorPreset`]).
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
    /// Matches per RANSAC sample: 3 (a free pose) or 2 (a tray resting on the table).
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

/// The most fill states per viewpoint a model may be built from (a tray with more slots
/// than this takes an evenly spread subset anyway).
const MAX_MODEL_FILL_STATES: u32 = 1000;
/// The most viewpoints a model is built from (a turn of 5°).
const MAX_MODEL_VIEWPOINTS: u32 = 72;

/// How a pose estimate is judged.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Metrics {
    pub correct_match: f64,
    pub success_position: f64,
    pub success_rotation: f64,
}

impl Default for Cell {
    /// The built-in default cell (`default_cell.toml`).
    fn default() -> Self {
        Cell::from_toml_str(DEFAULT_CELL_TOML, Path::new(".")).expect("the built-in cell file is valid")
    }
}

impl Cell {
    /// Reads a cell file, laid over the built-in default, and checks every value.
    pub fn load(path: &Path) -> Result<Cell, Error> {
        let text = crate::formats::read::read_text(path)?;
        let base = path.parent().unwrap_or(Path::new("."));
        Cell::from_toml_str(&text, base).map_err(|e| e.in_file(path))
    }

    /// Parses cell text laid over the default; mesh paths are resolved against `base`.
    pub fn from_toml_str(text: &str, base: &Path) -> Result<Cell, Error> {
        let mut user: toml::Table = text.parse().map_err(|e: toml::de::Error| {
            let (key, line) = toml_error_place(text, e.span().map_or(0, |s| s.start));
            let msg = e.message().to_string();
            Error::new(ErrorKind::Format, key, format!("line {line}: not valid TOML: {msg}")).with_source(e)
        })?;
        let listed = user.remove("trays");
        let mut merged: toml::Table = DEFAULT_CELL_TOML.parse().expect("built-in cell parses");
        let asked = user.clone();
        merge(&mut merged, user);
        apply_preset(&mut merged, &asked)?;
        let section = |name: &str| match merged.get(name) {
            Some(toml::Value::Table(t)) => t.clone(),
            _ => toml::Table::new(),
        };
        let (tray_table, items_table) = (section("tray"), section("items"));
        let mut cell: Cell = serde_path_to_error::deserialize(toml::Value::Table(merged)).map_err(|e| {
            let key = e.path().to_string();
            let inner = e.into_inner();
            Error::value(key, explain(&inner.to_string())).with_source(inner)
        })?;
        for p in [&mut cell.tray.mesh, &mut cell.items.mesh] {
            if !p.as_os_str().is_empty() && p.is_relative() {
                *p = base.join(&*p);
            }
        }
        if let Some(list) = listed {
            cell.trays = parse_trays(list, &tray_table, &items_table, base)?;
        }
        cell.validate()?;
        Ok(cell)
    }

    /// This cell with the cell text `fragment` laid over it key by key, as a cell file is
    /// laid over the default (a fragment from `camplace fit-sensor`, say); mesh paths of the
    /// fragment are resolved against `base`, and every value is checked again.
    pub fn overlaid(&self, fragment: &str, base: &Path) -> Result<Cell, Error> {
        let fragment: toml::Table = fragment.parse().map_err(|e: toml::de::Error| {
            let (key, line) = toml_error_place(fragment, e.span().map_or(0, |s| s.start));
            let msg = e.message().to_string();
            Error::new(ErrorKind::Format, key, format!("line {line}: not valid TOML: {msg}")).with_source(e)
        })?;
        let mut merged: toml::Table = self.to_toml_string().parse().expect("a cell's own text parses");
        merge(&mut merged, fragment);
        Cell::from_toml_str(&toml::to_string(&merged).expect("a table serialises"), base)
    }

    /// The cell as TOML text (no comments; `camplace init` writes the commented file).
    pub fn to_toml_string(&self) -> String {
        toml::to_string(self).expect("a cell always serialises")
    }

    /// Checks every value's range and that meshes load.
    pub fn validate(&self) -> Result<(), Error> {
        let t = &self.table;
        positive("table.size", &t.size)?;
        unit("table.albedo", t.albedo)?;
        if self.trays.is_empty() {
            self.validate_tray()?;
        } else {
            // The listed trays replace [tray] and [items], which only lend them defaults.
            validate_trays(self)?;
        }
        if let Some(rig) = &self.rig {
            rig.check().map_err(|e| e.under_key("rig"))?;
        }
        self.validate_realism()?;
        self.validate_rest()
    }

    /// Checks `tray` and `items`.
    pub(crate) fn validate_tray(&self) -> Result<(), Error> {
        let tr = &self.tray;
        unit("tray.albedo", tr.albedo)?;
        realism::check_gloss("tray", tr.specular, tr.roughness)?;
        if tr.kind == TrayKind::Mesh {
            // A mesh tray with no slots is allowed: it is found empty.
            load_mesh_checked("tray.mesh", &tr.mesh)?;
        } else if !tr.mesh.as_os_str().is_empty() || !tr.slots.is_empty() {
            // A built-in tray has its own shape and slots: a mesh or slots given beside
            // one would be ignored, which is never what was meant.
            let key = if tr.slots.is_empty() { "tray.mesh" } else { "tray.slots" };
            return Err(Error::value(
                key,
                "given with a built-in tray.kind; set kind = \"mesh\" to use the mesh and its slots",
            ));
        }
        for (i, s) in tr.slots.iter().enumerate() {
            if s.iter().any(|v| !(v.is_finite() && v.abs() <= MAX_DISTANCE_MM)) {
                return Err(Error::value(
                    format!("tray.slots[{i}]"),
                    format!("expected four numbers [x, y, z, yaw] within ±{MAX_DISTANCE_MM} (mm and degrees)"),
                ));
            }
        }
        for (i, &s) in tr.symmetries.iter().enumerate() {
            // A rotation that maps the tray onto itself is a fraction of a turn: n of them
            // make whole turns for some n up to 360.
            let fraction_of_a_turn = s.is_finite()
                && s > 0.0
                && s < 360.0
                && (1..=360).any(|n| {
                    let turns = s * n as f64 / 360.0;
                    turns.round() >= 1.0 && (turns - turns.round()).abs() < 1e-6
                });
            if !fraction_of_a_turn {
                return Err(Error::value(
                    format!("tray.symmetries[{i}]"),
                    format!("expected an angle between 0 and 360 degrees that is a fraction of a turn (e.g. 90, 180), got {s}"),
                ));
            }
        }
        let it = &self.items;
        unit("items.albedo", it.albedo)?;
        realism::check_gloss("items", it.specular, it.roughness)?;
        positive("items.size", &it.size)?;
        if it.kind == ItemsKind::Mesh {
            load_mesh_checked("items.mesh", &it.mesh)?;
        } else if !it.mesh.as_os_str().is_empty() {
            return Err(Error::value("items.mesh", "given with items.kind = \"box\"; set kind = \"mesh\" to use it"));
        }
        Ok(())
    }

    /// Checks everything but the table, the tray and the items.
    fn validate_rest(&self) -> Result<(), Error> {
        if let Some(robot) = &self.robot {
            let t = &robot.t_robot_world;
            crate::check_rigid(t).map_err(|m| Error::value("robot.T_robot_world", m))?;
            if (0..3).any(|i| t[i][3].abs() > MAX_DISTANCE_MM) {
                return Err(Error::value(
                    "robot.T_robot_world",
                    format!("expected a translation within ±{MAX_DISTANCE_MM} mm"),
                ));
            }
            robot.reply_format()?;
            if let Some(t) = &robot.t_flange_rig {
                crate::check_rigid(t).map_err(|m| Error::value("robot.T_flange_rig", m))?;
                if (0..3).any(|i| t[i][3].abs() > MAX_DISTANCE_MM) {
                    return Err(Error::value(
                        "robot.T_flange_rig",
                        format!("expected a translation within ±{MAX_DISTANCE_MM} mm"),
                    ));
                }
            }
        }
        let s = &self.sensor;
        let [cw, ch] = s.camera_resolution;
        crate::check_image_size("sensor.camera_resolution", cw, ch, crate::BYTES_PER_CAMERA_PIXEL, 1)?;
        angle_open("sensor.camera_hfov", s.camera_hfov, 1.0, 170.0)?;
        if !s.camera_k.is_empty() {
            let k = &s.camera_k;
            let ok = k.len() == 3
                && k[0][0] > 0.0
                && k[1][1] > 0.0
                && k[0][1] == 0.0
                && k[1][0] == 0.0
                && k[2] == [0.0, 0.0, 1.0];
            if !ok {
                return Err(Error::value(
                    "sensor.camera_k",
                    "expected [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] with fx, fy > 0, or [] for one from camera_hfov",
                ));
            }
            crate::check_focal_px("sensor.camera_k", "fx", k[0][0], cw)?;
            crate::check_focal_px("sensor.camera_k", "fy", k[1][1], ch)?;
        }
        check_camera_dist(s)?;
        let [pw, ph] = s.projector_resolution;
        crate::check_image_size("sensor.projector_resolution", pw, ph, crate::BYTES_PER_PROJECTOR_PIXEL, 1)?;
        angle_open("sensor.projector_hfov", s.projector_hfov, 1.0, 170.0)?;
        if !(s.projector_gain.is_finite() && (0.0..=10.0).contains(&s.projector_gain)) {
            return Err(Error::value(
                "sensor.projector_gain",
                format!("expected 0 to 10 (1 lights a white surface to full scale), got {}", s.projector_gain),
            ));
        }
        if s.noise_amplitude > 127 {
            return Err(Error::value("sensor.noise_amplitude", "expected 0 to 127 grey levels"));
        }
        if s.blur == 0 || s.blur.is_multiple_of(2) || s.blur > 15 {
            return Err(Error::value(
                "sensor.blur",
                format!("expected an odd filter side from 1 to 15, got {}", s.blur),
            ));
        }
        if s.dot_size == 0 {
            return Err(Error::value("sensor.dot_size", "expected at least 1 projector pixel"));
        }
        unit("sensor.dot_density", s.dot_density)?;
        if s.fringe_periods.is_empty() || s.fringe_periods.iter().any(|&p| !(p.is_finite() && p >= 1.0)) {
            return Err(Error::value("sensor.fringe_periods", "expected one or more periods >= 1"));
        }
        if s.fringe_periods.windows(2).any(|w| w[1] <= w[0]) {
            return Err(Error::value("sensor.fringe_periods", "expected periods in increasing order, coarse to fine"));
        }
        self.placement.validate("placement")?;
        let l = &self.lighting;
        range("lighting.ambient", l.ambient, 0.0, 10.0)?;
        range("lighting.lamp_strength", l.lamp_strength, 0.0, 10.0)?;
        range("lighting.lamp_polar", l.lamp_polar, 0.0, 89.9)?;
        // The lamp stands outside the work volume: not closer than 100 mm to the origin.
        if !(l.lamp_distance.is_finite() && (100.0..=MAX_DISTANCE_MM).contains(&l.lamp_distance)) {
            return Err(Error::value(
                "lighting.lamp_distance",
                format!("expected 100 to {MAX_DISTANCE_MM} mm, got {}", l.lamp_distance),
            ));
        }
        let sc = &self.scenarios;
        if sc.count == 0 {
            return Err(Error::value("scenarios.count", "expected at least 1 scenario"));
        }
        range("scenarios.tray_x", sc.tray_x, -1e5, 1e5)?;
        range("scenarios.tray_y", sc.tray_y, -1e5, 1e5)?;
        range("scenarios.tray_yaw", sc.tray_yaw, -720.0, 720.0)?;
        unit("scenarios.fill_probability", sc.fill_probability)?;
        let w = &self.work_volume;
        for (key, v) in [("work_volume.x", w.x), ("work_volume.y", w.y), ("work_volume.z", w.z)] {
            range(key, v, -1e5, 1e5)?;
            // The estimator crops the cloud to this box: one that is not a millimetre deep
            // along an axis keeps nothing.
            if v[1] - v[0] < 1.0 {
                return Err(Error::value(key, format!("expected max at least 1 mm above min, got {v:?}")));
            }
        }
        let st = &self.stereo;
        if !(1..=64).contains(&st.support_step) {
            return Err(Error::value(
                "stereo.support_step",
                format!("expected 1 to 64 pixels, got {}", st.support_step),
            ));
        }
        // A descriptor is 16 bytes, so its texture (sum of absolute Sobel bytes) is at most 16 x 255.
        if st.min_texture > MAX_TEXTURE {
            return Err(Error::value(
                "stereo.min_texture",
                format!("expected 0 to {MAX_TEXTURE} (16 descriptor bytes x 255), got {}", st.min_texture),
            ));
        }
        if !(1..=8).contains(&st.row_step) {
            return Err(Error::value("stereo.row_step", format!("expected 1 to 8 rows, got {}", st.row_step)));
        }
        if st.gap_width > 1000 {
            return Err(Error::value("stereo.gap_width", format!("expected 0 to 1000 pixels, got {}", st.gap_width)));
        }
        unit("stereo.support_uniqueness", st.support_uniqueness)?;
        at_most("stereo.lr_tolerance", st.lr_tolerance, 100.0, "pixels")?;
        at_most("stereo.speckle_similarity", st.speckle_similarity, 100.0, "pixels")?;
        if !(1..=1000).contains(&st.grid_size) {
            return Err(Error::value("stereo.grid_size", "expected a cell side from 1 to 1000 pixels"));
        }
        for (key, v) in [
            ("stereo.prior_sigma", st.prior_sigma),
            ("stereo.prior_gamma", st.prior_gamma),
            ("stereo.prior_beta", st.prior_beta),
        ] {
            pos(key, v)?;
            at_most(key, v, 1000.0, "")?;
        }
        if st.prior_radius > 64 {
            return Err(Error::value("stereo.prior_radius", "expected 0 to 64 pixels"));
        }
        if st.subpixel_radius > 8 {
            return Err(Error::value("stereo.subpixel_radius", "expected 0 to 8 pixels"));
        }
        at_most("phase.min_modulation", self.phase.min_modulation, 255.0, "grey levels")?;
        at_most("phase.lr_tolerance", self.phase.lr_tolerance, 100.0, "pixels")?;
        at_most("reconstruction.background_margin", self.reconstruction.background_margin, 1000.0, "mm")?;
        if self.reconstruction.background_dilation > 64 {
            return Err(Error::value("reconstruction.background_dilation", "expected 0 to 64 pixels"));
        }
        let e = &self.estimator;
        if !(e.surface_resolution.is_finite() && (0.1..=50.0).contains(&e.surface_resolution)) {
            return Err(Error::value(
                "estimator.surface_resolution",
                format!("expected 0.1 to 50 mm, got {}", e.surface_resolution),
            ));
        }
        pos("estimator.normal_radius", e.normal_radius)?;
        // Radii are counted in voxels of the down-sampled cloud: far beyond these a stage
        // gathers the whole cloud for every point and a frame takes minutes.
        if e.normal_radius > 20.0 * e.surface_resolution {
            return Err(Error::value(
                "estimator.normal_radius",
                format!(
                    "expected at most 20 x surface_resolution ({} mm), got {}",
                    20.0 * e.surface_resolution,
                    e.normal_radius
                ),
            ));
        }
        if e.normal_radius < e.surface_resolution {
            return Err(Error::value(
                "estimator.normal_radius",
                "expected at least surface_resolution, or a normal has too few points to fit",
            ));
        }
        if !(1..=MAX_MODEL_FILL_STATES).contains(&e.model_fill_states) {
            return Err(Error::value(
                "estimator.model_fill_states",
                format!(
                    "expected a whole number of fill states from 1 (the full tray only) to {MAX_MODEL_FILL_STATES}, got {}",
                    e.model_fill_states
                ),
            ));
        }
        if !(1..=MAX_MODEL_VIEWPOINTS).contains(&e.model_viewpoints) {
            return Err(Error::value(
                "estimator.model_viewpoints",
                format!(
                    "expected a whole number of turns about z from 1 to {MAX_MODEL_VIEWPOINTS}, got {}",
                    e.model_viewpoints
                ),
            ));
        }
        pos("estimator.keypoint_spacing", e.keypoint_spacing)?;
        if e.keypoint_spacing > 1000.0 {
            return Err(Error::value(
                "estimator.keypoint_spacing",
                format!("expected at most 1000 mm, got {}", e.keypoint_spacing),
            ));
        }
        if !(e.min_relief.is_finite() && (0.0..90.0).contains(&e.min_relief)) {
            return Err(Error::value(
                "estimator.min_relief",
                format!("expected an angle from 0 to below 90 deg, got {}", e.min_relief),
            ));
        }
        pos("estimator.feature_radius", e.feature_radius)?;
        if e.feature_radius > 50.0 * e.surface_resolution {
            return Err(Error::value(
                "estimator.feature_radius",
                format!(
                    "expected at most 50 x surface_resolution ({} mm), got {}",
                    50.0 * e.surface_resolution,
                    e.feature_radius
                ),
            ));
        }
        if e.k == 0 || e.k > 64 {
            return Err(Error::value("estimator.k", format!("expected 1 to 64 nearest neighbours, got {}", e.k)));
        }
        pos("estimator.height_band", e.height_band)?;
        at_most("estimator.height_band", e.height_band, MAX_DISTANCE_MM, "mm")?;
        if !(1..=MAX_ITERATIONS).contains(&e.ransac_iterations) {
            return Err(Error::value(
                "estimator.ransac_iterations",
                format!("expected 1 to {MAX_ITERATIONS} iterations, got {}", e.ransac_iterations),
            ));
        }
        if e.icp_iterations > 10_000 {
            return Err(Error::value(
                "estimator.icp_iterations",
                format!("expected 0 to 10000 iterations, got {}", e.icp_iterations),
            ));
        }
        if !(2..=3).contains(&e.ransac_sample) {
            return Err(Error::value(
                "estimator.ransac_sample",
                format!("expected 2 or 3 matches per sample, got {}", e.ransac_sample),
            ));
        }
        unit("estimator.edge_similarity", e.edge_similarity)?;
        angle_open("estimator.table_tilt", e.table_tilt, 0.0, 90.0)?;
        unit("estimator.min_inlier_share", e.min_inlier_share)?;
        unit("estimator.verify_threshold", e.verify_threshold)?;
        if !(e.verify_max_wrong.is_finite() && e.verify_max_wrong > 0.0 && e.verify_max_wrong < 1.0) {
            return Err(Error::value(
                "estimator.verify_max_wrong",
                format!("expected a share above 0 and below 1, got {}", e.verify_max_wrong),
            ));
        }
        // Distances a spatial index is built with: far beyond the tray they gather the whole
        // cloud in one cell and a frame takes minutes.
        for (key, v) in [
            ("estimator.table_height", e.table_height),
            ("estimator.inlier_distance", e.inlier_distance),
            ("estimator.icp_max_distance", e.icp_max_distance),
        ] {
            pos(key, v)?;
            at_most(key, v, 1000.0, "mm")?;
        }
        if !(e.icp_trim.is_finite() && (0.0..=0.9).contains(&e.icp_trim)) {
            return Err(Error::value(
                "estimator.icp_trim",
                format!("expected a share from 0 to 0.9, got {}", e.icp_trim),
            ));
        }
        let m = &self.metrics;
        for (key, v, most, unit) in [
            ("metrics.correct_match", m.correct_match, MAX_DISTANCE_MM, "mm"),
            ("metrics.success_position", m.success_position, MAX_DISTANCE_MM, "mm"),
            ("metrics.success_rotation", m.success_rotation, 180.0, "degrees"),
        ] {
            pos(key, v)?;
            at_most(key, v, most, unit)?;
        }
        Ok(())
    }
}

/// The largest `stereo.min_texture`: 16 descriptor bytes of at most 255 each.
pub const MAX_TEXTURE: u32 = 16 * 255;

/// The most RANSAC iterations a cell may ask for (the paper's RIt is 100 000).
pub const MAX_ITERATIONS: u32 = 10_000_000;

/// Where a TOML syntax error sits: the dotted key being written there (the table header
/// above it and the key on its line, as far as they can be read) and the 1-based line.
fn toml_error_place(text: &str, at: usize) -> (String, usize) {
    let before = text.get(..at.min(text.len())).unwrap_or(text);
    let line_no = before.matches('\n').count() + 1;
    let line = text.lines().nth(line_no - 1).unwrap_or("").trim();
    let table = before
        .lines()
        .rev()
        // The last piece of `before` is the start of the error's own line, unless the error
        // sits at a line's first byte.
        .skip(usize::from(!before.is_empty() && !before.ends_with('\n')))
        .map(str::trim)
        .find(|l| l.starts_with('['))
        .map(|l| l.trim_matches(|c| c == '[' || c == ']').trim().to_string());
    let on_line = line
        .split('=')
        .next()
        .map(str::trim)
        .filter(|k| line.contains('=') && !k.is_empty() && !k.starts_with('[') && !k.starts_with('#'));
    let key = match (line.starts_with('['), table, on_line) {
        (true, _, _) => line.trim_matches(|c| c == '[' || c == ']').trim().to_string(),
        (false, Some(t), Some(k)) => format!("{t}.{k}"),
        (false, None, Some(k)) => k.to_string(),
        (false, Some(t), None) => t,
        (false, None, None) => String::new(),
    };
    (key, line_no)
}

/// Lays `user` over `base`, table by table.
pub(crate) fn merge(base: &mut toml::Table, user: toml::Table) {
    for (key, value) in user {
        match (base.get_mut(&key), value) {
            (Some(toml::Value::Table(b)), toml::Value::Table(u)) => merge(b, u),
            (_, v) => {
                base.insert(key, v);
            }
        }
    }
}

/// Rewords serde's messages into "expected ..." one-liners.
pub(crate) fn explain(inner: &str) -> String {
    if let Some(rest) = inner.strip_prefix("unknown field ") {
        return format!("unknown key {rest}");
    }
    inner.to_string()
}

fn load_mesh_checked(key: &str, path: &Path) -> Result<(), Error> {
    if path.as_os_str().is_empty() {
        return Err(Error::value(key, "expected the path of an STL, OBJ or PLY mesh"));
    }
    let m = mesh::load_mesh(path).map_err(|e| {
        let file = e.file().map(|f| f.display().to_string()).unwrap_or_else(|| path.display().to_string());
        Error::value(key, format!("{file}: {}", e.message()))
    })?;
    if m.triangles.is_empty() {
        return Err(Error::value(key, format!("{}: expected a mesh with triangles, found none", path.display())));
    }
    Ok(())
}

pub(crate) fn pos(key: &str, v: f64) -> Result<(), Error> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(Error::value(key, format!("expected a positive number, got {v}")))
    }
}

/// `v` from 0 to `most` (in `unit`).
pub(crate) fn at_most(key: &str, v: f64, most: f64, unit: &str) -> Result<(), Error> {
    if v.is_finite() && (0.0..=most).contains(&v) {
        Ok(())
    } else {
        let unit = if unit.is_empty() { String::new() } else { format!(" {unit}") };
        Err(Error::value(key, format!("expected 0 to {most}{unit}, got {v}")))
    }
}

pub(crate) fn unit(key: &str, v: f64) -> Result<(), Error> {
    if v.is_finite() && (0.0..=1.0).contains(&v) {
        Ok(())
    } else {
        Err(Error::value(key, format!("expected a number from 0 to 1, got {v}")))
    }
}

fn positive(key: &str, v: &[f64]) -> Result<(), Error> {
    if v.iter().all(|x| x.is_finite() && (MIN_SIZE_MM..=MAX_DISTANCE_MM).contains(x)) {
        Ok(())
    } else {
        Err(Error::value(key, format!("expected sizes from {MIN_SIZE_MM} to {MAX_DISTANCE_MM} mm, got {v:?}")))
    }
}

/// The smallest size of a table or an item, mm: a tenth of a millimetre is below anything
/// the sensor resolves.
const MIN_SIZE_MM: f64 = 0.1;

/// Whether a distortion is all zero (serde's skip test for `camera_dist`).
fn is_distortion_free(dist: &[f64; 5]) -> bool {
    dist.iter().all(|&d| d == 0.0)
}

/// `camera_dist`, checked as every camera's distortion is (finite, one-to-one over the image).
fn check_camera_dist(s: &Sensor) -> Result<(), Error> {
    let [w, h] = s.camera_resolution;
    let fx = if s.camera_k.len() == 3 {
        s.camera_k[0][0]
    } else {
        (f64::from(w) / 2.0) / (s.camera_hfov.to_radians() / 2.0).tan()
    };
    let fy = if s.camera_k.len() == 3 { s.camera_k[1][1] } else { fx };
    crate::check_distortion("sensor.camera_dist", &s.camera_dist, w, h, fx, fy)
}

fn angle_open(key: &str, v: f64, lo: f64, hi: f64) -> Result<(), Error> {
    if v.is_finite() && v > lo && v < hi {
        Ok(())
    } else {
        Err(Error::value(key, format!("expected an angle between {lo} and {hi} degrees, got {v}")))
    }
}

pub(crate) fn range(key: &str, v: [f64; 2], lo: f64, hi: f64) -> Result<(), Error> {
    if v.iter().all(|x| x.is_finite() && *x >= lo && *x <= hi) && v[0] <= v[1] {
        Ok(())
    } else {
        Err(Error::value(key, format!("expected [min, max] with min <= max within [{lo}, {hi}], got {v:?}")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_is_the_papers_table_1() {
        let c = Cell::default();
        assert_eq!(c.estimator.surface_resolution, 2.0);
        assert_eq!(c.estimator.k, 25);
        assert_eq!(c.estimator.ransac_iterations, 100_000);
        assert_eq!(c.estimator.icp_iterations, 100);
    }

    #[test]
    fn every_key_of_the_template_has_a_comment() {
        let lines: Vec<&str> = DEFAULT_CELL_TOML.lines().collect();
        for (i, line) in lines.iter().enumerate() {
            let t = line.trim();
            if t.is_empty() || t.starts_with('#') || t.starts_with('[') {
                continue;
            }
            assert!(i > 0 && lines[i - 1].trim_start().starts_with('#'), "key without a comment: {t}");
        }
    }

    #[test]
    fn values_that_mean_nothing_are_refused_naming_the_key() {
        let cases = [
            ("[table]\nsize = [1e308, 1e308]\n", "table.size"),
            ("[table]\nsize = [1e-300, 900.0]\n", "table.size"),
            ("[items]\nsize = [34.0, 34.0, 1e9]\n", "items.size"),
            ("[tray]\nmesh = \"tray.stl\"\n", "tray.mesh"),
            ("[tray]\nslots = [[0.0, 0.0, 0.0, 0.0]]\n", "tray.slots"),
            ("[items]\nmesh = \"item.stl\"\n", "items.mesh"),
            ("[tray]\nsymmetries = [-90.0]\n", "tray.symmetries[0]"),
            ("[tray]\nsymmetries = [180.0, 360.0]\n", "tray.symmetries[1]"),
            ("[tray]\nsymmetries = [1e-300]\n", "tray.symmetries[0]"),
            ("[tray]\nsymmetries = [0.123456789]\n", "tray.symmetries[0]"),
            ("[sensor]\nprojector_gain = 1e308\n", "sensor.projector_gain"),
            ("[placement]\nazimuth = 1e308\n", "placement.azimuth"),
            ("[lighting]\nlamp_distance = 1e-300\n", "lighting.lamp_distance"),
            ("[lighting]\nlamp_distance = 4294967296\n", "lighting.lamp_distance"),
            ("[work_volume]\nz = [0.0, 0.0]\n", "work_volume.z"),
            ("[stereo]\nspeckle_similarity = 1e308\n", "stereo.speckle_similarity"),
            ("[estimator]\nheight_band = 1e308\n", "estimator.height_band"),
            ("[estimator]\nicp_max_distance = 1e308\n", "estimator.icp_max_distance"),
            ("[estimator]\ninlier_distance = 4294967296\n", "estimator.inlier_distance"),
            ("[metrics]\nsuccess_rotation = 1e9\n", "metrics.success_rotation"),
            ("[stereo]\nlr_tolerance = 4294967296\n", "stereo.lr_tolerance"),
            ("[stereo]\nprior_sigma = 1e308\n", "stereo.prior_sigma"),
            ("[stereo]\nrow_step = 0\n", "stereo.row_step"),
            ("[stereo]\nrow_step = 9\n", "stereo.row_step"),
            ("[phase]\nmin_modulation = 1e9\n", "phase.min_modulation"),
            ("[reconstruction]\nbackground_margin = 1e308\n", "reconstruction.background_margin"),
        ];
        for (text, key) in cases {
            let e = Cell::from_toml_str(text, Path::new(".")).unwrap_err();
            assert!(e.to_string().starts_with(key), "{text}: {e}");
        }
        // Symmetries that are fractions of a turn are kept.
        let c =
            Cell::from_toml_str("[tray]\nsymmetries = [90.0, 180.0, 270.0, 120.0, 72.0]\n", Path::new(".")).unwrap();
        assert_eq!(c.tray.symmetries.len(), 5);
    }

    #[test]
    fn partial_file_lays_over_default() {
        let c = Cell::from_toml_str("[placement]\nr = 700\n", Path::new(".")).unwrap();
        assert_eq!(c.placement.r, 700.0);
        assert_eq!(c.placement.alpha, Cell::default().placement.alpha);
    }

    #[test]
    fn serialised_cell_reads_back() {
        let c = Cell::default();
        let back = Cell::from_toml_str(&c.to_toml_string(), Path::new(".")).unwrap();
        assert_eq!(back, c);
    }

    #[test]
    fn toml_syntax_errors_name_the_line_and_key() {
        let e =
            Cell::from_toml_str("[scenarios]\ncount = 4\n\n[stereo]\nmin_texture = = 3\n", Path::new(".")).unwrap_err();
        assert_eq!(e.key(), "stereo.min_texture", "{e}");
        assert!(e.to_string().contains("line 5"), "{e}");
        let e = Cell::from_toml_str("[stereo\nmin_texture = 3\n", Path::new(".")).unwrap_err();
        assert!(e.to_string().contains("line 1"), "{e}");
    }

    #[test]
    fn unknown_key_is_named() {
        let e = Cell::from_toml_str("[tray]\ncolour = 3\n", Path::new(".")).unwrap_err();
        assert_eq!(e.key(), "tray.colour", "{e}");
        assert!(e.message().contains("unknown key"), "{e}");
    }

    #[test]
    fn wrong_type_is_named() {
        let e = Cell::from_toml_str("[estimator]\nk = \"many\"\n", Path::new(".")).unwrap_err();
        assert_eq!(e.key(), "estimator.k", "{e}");
    }

    #[test]
    fn model_fill_states_out_of_range_are_named() {
        for bad in ["0", "1001", "-3", "2.5"] {
            let text = format!("[estimator]\nmodel_fill_states = {bad}\n");
            let e = Cell::from_toml_str(&text, Path::new(".")).unwrap_err();
            assert_eq!(e.key(), "estimator.model_fill_states", "{bad}: {e}");
        }
        for good in [1, 3, 1000] {
            let text = format!("[estimator]\nmodel_fill_states = {good}\n");
            assert_eq!(Cell::from_toml_str(&text, Path::new(".")).unwrap().estimator.model_fill_states, good);
        }
    }

    #[test]
    fn a_fragment_laid_over_a_cell_replaces_only_its_keys() {
        let mut own = Cell::default();
        own.sensor.camera_resolution = [320, 240];
        own.table.albedo = 0.3;
        let fitted = own
            .overlaid("[sensor]\nblur = 5\nnoise_amplitude = 17\n[lighting]\nambient = [0.1, 0.2]\n", Path::new("."))
            .unwrap();
        assert_eq!((fitted.sensor.blur, fitted.sensor.noise_amplitude), (5, 17));
        assert_eq!(fitted.lighting.ambient, [0.1, 0.2]);
        let mut want = own.clone();
        want.sensor.blur = 5;
        want.sensor.noise_amplitude = 17;
        want.lighting.ambient = [0.1, 0.2];
        assert_eq!(fitted, want);
        let bad = own.overlaid("[sensor]\nblur = 4\n", Path::new(".")).unwrap_err();
        assert!(bad.to_string().contains("sensor.blur"), "{bad}");
        assert!(own.overlaid("[sensor\n", Path::new(".")).is_err());
    }
}
