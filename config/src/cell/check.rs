//! Checking a cell: every value's range, the meshes it names, the rig and the robot, each
//! fault a one-line error naming its key. The range checks themselves are `values.rs`'s.

use std::path::Path;

use super::realism;
use super::schema::{Cell, ItemsKind, Sensor, TrayKind};
use super::trays::validate_trays;
use super::values::{angle_open, at_most, pos, positive, range, unit};
use crate::formats::mesh;
use crate::{Error, MAX_DISTANCE_MM};

impl Cell {
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
        self.check_robot()?;
        self.check_sensor()?;
        self.check_lighting()?;
        self.check_scenarios()?;
        self.check_work_volume()?;
        self.check_stereo()?;
        self.check_estimator()?;
        self.check_estimator_search()?;
        self.check_metrics()?;
        Ok(())
    }

    /// The robot's frames and its replies' format.
    fn check_robot(&self) -> Result<(), Error> {
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
        Ok(())
    }

    /// The sensor: cameras, projector, noise, blur and fringes.
    fn check_sensor(&self) -> Result<(), Error> {
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
        Ok(())
    }

    /// The lamp.
    fn check_lighting(&self) -> Result<(), Error> {
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
        Ok(())
    }

    /// The scenarios' counts.
    fn check_scenarios(&self) -> Result<(), Error> {
        let sc = &self.scenarios;
        if sc.count == 0 {
            return Err(Error::value("scenarios.count", "expected at least 1 scenario"));
        }
        range("scenarios.tray_x", sc.tray_x, -1e5, 1e5)?;
        range("scenarios.tray_y", sc.tray_y, -1e5, 1e5)?;
        range("scenarios.tray_yaw", sc.tray_yaw, -720.0, 720.0)?;
        unit("scenarios.fill_probability", sc.fill_probability)?;
        Ok(())
    }

    /// The work volume's extent.
    fn check_work_volume(&self) -> Result<(), Error> {
        let w = &self.work_volume;
        for (key, v) in [("work_volume.x", w.x), ("work_volume.y", w.y), ("work_volume.z", w.z)] {
            range(key, v, -1e5, 1e5)?;
            // The estimator crops the cloud to this box: one that is not a millimetre deep
            // along an axis keeps nothing.
            if v[1] - v[0] < 1.0 {
                return Err(Error::value(key, format!("expected max at least 1 mm above min, got {v:?}")));
            }
        }
        Ok(())
    }

    /// The stereo matcher and the reconstruction.
    fn check_stereo(&self) -> Result<(), Error> {
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
        Ok(())
    }

    /// The estimator's model and features: resolution, radii, counts.
    fn check_estimator(&self) -> Result<(), Error> {
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
        Ok(())
    }

    /// The estimator's search: matching, RANSAC, ICP and the verification.
    fn check_estimator_search(&self) -> Result<(), Error> {
        let e = &self.estimator;
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
        if !(1..=3).contains(&e.ransac_sample) {
            return Err(Error::value(
                "estimator.ransac_sample",
                format!("expected 1, 2 or 3 matches per sample, got {}", e.ransac_sample),
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
        Ok(())
    }

    /// What counts as a correct match and a success.
    fn check_metrics(&self) -> Result<(), Error> {
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

/// The most fill states per viewpoint a model may be built from (a tray with more slots
/// than this takes an evenly spread subset anyway).
const MAX_MODEL_FILL_STATES: u32 = 1000;
/// The most viewpoints a model is built from (a turn of 5°).
const MAX_MODEL_VIEWPOINTS: u32 = 72;
/// The largest `stereo.min_texture`: 16 descriptor bytes of at most 255 each.
pub const MAX_TEXTURE: u32 = 16 * 255;

/// The most RANSAC iterations a cell may ask for (the paper's RIt is 100 000).
pub const MAX_ITERATIONS: u32 = 10_000_000;
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

/// `camera_dist`, checked as every camera's distortion is (finite, one-to-one over the image).
fn check_camera_dist(s: &Sensor) -> Result<(), Error> {
    let [w, h] = s.camera_resolution;
    let k = if s.camera_k.len() == 3 {
        [s.camera_k[0], s.camera_k[1], s.camera_k[2]]
    } else {
        // The cell's own K from the field of view: square pixels, centred.
        let f = (f64::from(w) / 2.0) / (s.camera_hfov.to_radians() / 2.0).tan();
        [[f, 0.0, f64::from(w) / 2.0], [0.0, f, f64::from(h) / 2.0], [0.0, 0.0, 1.0]]
    };
    crate::check_distortion("sensor.camera_dist", &s.camera_dist, w, h, &k)
}
