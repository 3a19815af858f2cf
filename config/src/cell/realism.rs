//! The optics and disturbances that set placements apart: the lenses' defocus (`[optics]`),
//! the calibration error the estimator's rig carries (`[calibration_error]`), a box standing
//! for the gripper above the tray (`[occluder]`), and the switches that turn each effect off
//! (`[effects]`). The gloss of each material is a pair of keys of `[table]`, `[tray]` and
//! `[items]` (`specular`, `roughness`), checked here too.

use serde::{de, Deserialize, Deserializer, Serialize, Serializer};
use std::fmt;

use super::values::{at_most, pos, range, unit};
use crate::{Cell, Error, MAX_DISTANCE_MM};

/// Where a lens is focused.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Focus {
    /// At the depth of the table's centre (the world origin), as set once at installation.
    Table,
    /// At this distance along the optical axis, mm.
    Distance(f64),
}

impl fmt::Display for Focus {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Focus::Table => f.write_str("table"),
            Focus::Distance(d) => write!(f, "{d}"),
        }
    }
}

impl Serialize for Focus {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            Focus::Table => s.serialize_str("table"),
            Focus::Distance(d) => s.serialize_f64(*d),
        }
    }
}

impl<'de> Deserialize<'de> for Focus {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Raw {
            Number(f64),
            Text(String),
        }
        const EXPECTED: &str = "expected a distance in mm or \"table\"";
        match Raw::deserialize(d).map_err(|_| de::Error::custom(EXPECTED))? {
            Raw::Number(v) => Ok(Focus::Distance(v)),
            Raw::Text(t) if t == "table" => Ok(Focus::Table),
            Raw::Text(t) => Err(de::Error::custom(format!("{EXPECTED}, got \"{t}\""))),
        }
    }
}

/// The thin lenses of the cameras and the projector.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Optics {
    /// Focal length of the camera lenses, mm.
    pub camera_focal_length: f64,
    /// f-number of the camera lenses (focal length over aperture diameter).
    pub camera_f_number: f64,
    /// Where the cameras are focused.
    pub camera_focus: Focus,
    /// Focal length of the projector's lens, mm.
    pub projector_focal_length: f64,
    /// f-number of the projector's lens.
    pub projector_f_number: f64,
    /// Where the projector is focused.
    pub projector_focus: Focus,
}

/// How far the rig the estimator uses may lie from the rig that took the images: each
/// scenario draws its own error, normal with these standard deviations per axis.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CalibrationError {
    /// Rotation of the whole rig in the world, deg per axis.
    pub rotation: f64,
    /// Translation of the whole rig in the world, mm per axis.
    pub translation: f64,
    /// Rotation of the right camera relative to the left, deg per axis.
    pub stereo_rotation: f64,
    /// Translation of the right camera relative to the left, mm per axis.
    pub stereo_translation: f64,
}

impl CalibrationError {
    /// Whether every deviation is zero.
    pub fn is_zero(&self) -> bool {
        [self.rotation, self.translation, self.stereo_rotation, self.stereo_translation].iter().all(|&v| v == 0.0)
    }
}

/// A box standing for the gripper or the robot's wrist above the tray.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Occluder {
    /// Probability that a scenario has it.
    pub probability: f64,
    /// Its size [x, y, z], mm.
    pub size: [f64; 3],
    /// Range of its bottom's height above the table, mm.
    pub height: [f64; 2],
    /// Largest offset of its centre from the tray's centre along world x and y, mm.
    pub offset: f64,
    /// Lambertian albedo.
    pub albedo: f64,
}

/// Which effects the simulation renders: each can be switched off on its own.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Effects {
    /// Thin-lens defocus of the cameras and the projector (`[optics]`).
    pub defocus: bool,
    /// The glossy lobe of each material (`specular`, `roughness`).
    pub specular: bool,
    /// The estimator's rig perturbed per scenario (`[calibration_error]`).
    pub calibration_error: bool,
    /// The box above the tray (`[occluder]`).
    pub occluder: bool,
}

/// One effect, as `study --ablate` and the report name them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Effect {
    Defocus,
    Specular,
    CalibrationError,
    Occluder,
}

impl Effect {
    /// Every effect, in the order the report lists them.
    pub const ALL: [Effect; 4] = [Effect::Defocus, Effect::Specular, Effect::CalibrationError, Effect::Occluder];

    /// Its key in `[effects]`.
    pub fn key(self) -> &'static str {
        match self {
            Effect::Defocus => "defocus",
            Effect::Specular => "specular",
            Effect::CalibrationError => "calibration_error",
            Effect::Occluder => "occluder",
        }
    }
}

impl Effects {
    /// Whether `effect` is on.
    pub fn get(&self, effect: Effect) -> bool {
        match effect {
            Effect::Defocus => self.defocus,
            Effect::Specular => self.specular,
            Effect::CalibrationError => self.calibration_error,
            Effect::Occluder => self.occluder,
        }
    }

    /// Turns `effect` on or off.
    pub fn set(&mut self, effect: Effect, on: bool) {
        match effect {
            Effect::Defocus => self.defocus = on,
            Effect::Specular => self.specular = on,
            Effect::CalibrationError => self.calibration_error = on,
            Effect::Occluder => self.occluder = on,
        }
    }
}

impl Cell {
    /// Whether `effect` does anything in this cell: switched on and with settings that are
    /// not nothing (an occluder that never appears, a calibration error of zero).
    pub fn effect_active(&self, effect: Effect) -> bool {
        self.effects.get(effect)
            && match effect {
                Effect::Defocus => true,
                Effect::Specular => self.materials().iter().any(|&(_, specular, _)| specular > 0.0),
                Effect::CalibrationError => !self.calibration_error.is_zero(),
                Effect::Occluder => self.occluder.probability > 0.0,
            }
    }

    /// Each material's name, specular albedo and roughness.
    fn materials(&self) -> [(&'static str, f64, f64); 3] {
        [
            ("table", self.table.specular, self.table.roughness),
            ("tray", self.tray.specular, self.tray.roughness),
            ("items", self.items.specular, self.items.roughness),
        ]
    }

    /// Checks `[optics]`, `[calibration_error]`, `[occluder]` and the table's gloss (the
    /// tray's and the items' are checked with the rest of each tray, listed or not).
    pub(crate) fn validate_realism(&self) -> Result<(), Error> {
        check_gloss("table", self.table.specular, self.table.roughness)?;
        let o = &self.optics;
        for (key, f) in [
            ("optics.camera_focal_length", o.camera_focal_length),
            ("optics.projector_focal_length", o.projector_focal_length),
        ] {
            pos(key, f)?;
            at_most(key, f, MAX_FOCAL_LENGTH_MM, "mm")?;
        }
        for (key, n) in
            [("optics.camera_f_number", o.camera_f_number), ("optics.projector_f_number", o.projector_f_number)]
        {
            if !(n.is_finite() && (MIN_F_NUMBER..=MAX_F_NUMBER).contains(&n)) {
                return Err(Error::value(
                    key,
                    format!("expected an f-number from {MIN_F_NUMBER} to {MAX_F_NUMBER}, got {n}"),
                ));
            }
        }
        for (key, focus, focal) in [
            ("optics.camera_focus", o.camera_focus, o.camera_focal_length),
            ("optics.projector_focus", o.projector_focus, o.projector_focal_length),
        ] {
            if let Focus::Distance(d) = focus {
                // A lens cannot focus nearer than its focal length.
                if !(d.is_finite() && d > focal && d <= MAX_DISTANCE_MM) {
                    return Err(Error::value(
                        key,
                        format!("expected \"table\" or a distance above the focal length ({focal} mm) up to {MAX_DISTANCE_MM} mm, got {d}"),
                    ));
                }
            }
        }
        let c = &self.calibration_error;
        for (key, v, most, unit_name) in [
            ("calibration_error.rotation", c.rotation, 10.0, "degrees"),
            ("calibration_error.translation", c.translation, 100.0, "mm"),
            ("calibration_error.stereo_rotation", c.stereo_rotation, 10.0, "degrees"),
            ("calibration_error.stereo_translation", c.stereo_translation, 100.0, "mm"),
        ] {
            at_most(key, v, most, unit_name)?;
        }
        let oc = &self.occluder;
        unit("occluder.probability", oc.probability)?;
        unit("occluder.albedo", oc.albedo)?;
        if !oc.size.iter().all(|v| v.is_finite() && (1.0..=MAX_DISTANCE_MM).contains(v)) {
            return Err(Error::value(
                "occluder.size",
                format!("expected [x, y, z] from 1 to {MAX_DISTANCE_MM} mm, got {:?}", oc.size),
            ));
        }
        range("occluder.height", oc.height, 0.0, MAX_DISTANCE_MM)?;
        at_most("occluder.offset", oc.offset, MAX_DISTANCE_MM, "mm")?;
        Ok(())
    }
}

/// The longest focal length a cell may give, mm.
const MAX_FOCAL_LENGTH_MM: f64 = 1000.0;
/// The range of f-numbers a cell may give.
const MIN_F_NUMBER: f64 = 0.5;
const MAX_F_NUMBER: f64 = 64.0;
/// The smoothest and the roughest surface the glossy lobe models.
pub const MIN_ROUGHNESS: f64 = 0.02;
pub const MAX_ROUGHNESS: f64 = 1.0;

/// Checks a material's `specular` and `roughness`, naming them under `name`.
pub(crate) fn check_gloss(name: &str, specular: f64, roughness: f64) -> Result<(), Error> {
    unit(&format!("{name}.specular"), specular)?;
    if !(roughness.is_finite() && (MIN_ROUGHNESS..=MAX_ROUGHNESS).contains(&roughness)) {
        return Err(Error::value(
            format!("{name}.roughness"),
            format!("expected {MIN_ROUGHNESS} (mirror-like) to {MAX_ROUGHNESS} (matte), got {roughness}"),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    #[test]
    fn each_key_is_checked_and_named() {
        for (text, key) in [
            ("[optics]\ncamera_f_number = 0.1", "optics.camera_f_number"),
            ("[optics]\nprojector_focal_length = -3.0", "optics.projector_focal_length"),
            ("[optics]\ncamera_focus = 4.0", "optics.camera_focus"),
            ("[optics]\ncamera_focus = \"near\"", "optics.camera_focus"),
            ("[calibration_error]\nrotation = -0.1", "calibration_error.rotation"),
            ("[occluder]\nprobability = 1.5", "occluder.probability"),
            ("[occluder]\nheight = [300.0, 100.0]", "occluder.height"),
            ("[tray]\nroughness = 0.0", "tray.roughness"),
            ("[table]\nspecular = 2.0", "table.specular"),
            ("[effects]\nglare = true", "effects"),
        ] {
            let e = Cell::from_toml_str(text, Path::new(".")).expect_err(text);
            assert!(e.to_string().contains(key), "{text}: {e}");
        }
    }

    #[test]
    fn the_paper_preset_sets_its_keys_and_refuses_them_beside_it() {
        let c =
            Cell::from_toml_str("[estimator]\npreset = \"paper\"\nsurface_resolution = 2.5", Path::new(".")).unwrap();
        assert_eq!(c.estimator.preset, crate::EstimatorPreset::Paper);
        assert_eq!((c.estimator.ransac_sample, c.estimator.feature_radius, c.estimator.turn_check), (3, 25.0, false));
        assert!(!c.estimator.pose_on_table, "the paper hands the fit on as it is");
        assert_eq!((c.estimator.model_viewpoints, c.estimator.icp_trim), (6, 0.0), "the paper's 60° steps, no trim");
        let ours = Cell::default();
        assert_eq!((ours.estimator.ransac_sample, ours.estimator.turn_check), (2, true));
        assert!(ours.estimator.pose_on_table);
        let e = Cell::from_toml_str("[estimator]\npreset = \"paper\"\nransac_sample = 2", Path::new(".")).unwrap_err();
        assert!(e.to_string().contains("estimator.ransac_sample"), "{e}");
        assert!(Cell::from_toml_str("[estimator]\npreset = \"buch\"", Path::new(".")).is_err());
        // Written out and read back, it is the same cell.
        assert_eq!(Cell::from_toml_str(&c.to_toml_string(), Path::new(".")).unwrap(), c);
    }

    #[test]
    fn focus_reads_a_distance_or_the_table() {
        let c =
            Cell::from_toml_str("[optics]\ncamera_focus = 700.0\nprojector_focus = \"table\"", Path::new(".")).unwrap();
        assert_eq!(c.optics.camera_focus, Focus::Distance(700.0));
        assert_eq!(c.optics.projector_focus, Focus::Table);
        let again = Cell::from_toml_str(&c.to_toml_string(), Path::new(".")).unwrap();
        assert_eq!(again, c);
    }

    #[test]
    fn an_effect_with_nothing_to_do_is_not_active() {
        let mut c = Cell::default();
        assert!(c.effect_active(Effect::Defocus) && c.effect_active(Effect::Specular));
        c.effects.set(Effect::Specular, false);
        assert!(!c.effect_active(Effect::Specular));
        c.calibration_error =
            CalibrationError { rotation: 0.0, translation: 0.0, stereo_rotation: 0.0, stereo_translation: 0.0 };
        assert!(!c.effect_active(Effect::CalibrationError));
        c.occluder.probability = 0.0;
        assert!(!c.effect_active(Effect::Occluder));
    }
}
