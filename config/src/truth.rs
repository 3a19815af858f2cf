//! `truth.json`: what the simulator knows of one scene (docs/design/interchange-formats.md): the
//! tray's pose, the filled slots, the lighting and the seed, so any tool can score an
//! estimate.

use serde::{Deserialize, Serialize};
use std::path::Path;

use crate::{Error, Placement};

/// The lighting of one scene.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LightingTruth {
    /// Ambient level (units of full white).
    pub ambient: f64,
    /// Background lamp strength.
    pub lamp_strength: f64,
    /// Background lamp position in the world, mm.
    pub lamp_position: [f64; 3],
}

/// A whole `truth.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TruthFile {
    /// Tray frame -> world, row-major 4x4.
    #[serde(rename = "T_world_tray")]
    pub t_world_tray: [[f64; 4]; 4],
    /// Indices of the slots that hold an item.
    pub filled: Vec<usize>,
    pub lighting: LightingTruth,
    /// Study seed.
    pub seed: u64,
    /// Scenario index within the seed.
    pub scenario: u64,
    /// Rotations about the tray's z axis (deg) that map it onto itself.
    #[serde(default)]
    pub symmetries: Vec<f64>,
    /// The placement the scene was rendered at, when simulated.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub placement: Option<Placement>,
    /// "one-shot" or "phase-12", when simulated.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub method: Option<String>,
}

impl TruthFile {
    /// Reads a `truth.json`.
    pub fn load(path: &Path) -> Result<TruthFile, Error> {
        let text = crate::formats::read::read_text(path)?;
        Self::from_json(&text).map_err(|e| e.in_file(path))
    }

    /// Parses and checks truth JSON text: the tray pose must be rigid, every number finite.
    pub fn from_json(text: &str) -> Result<TruthFile, Error> {
        let truth: TruthFile = crate::formats::json::decode(text)?;
        crate::pose::check_rigid(&truth.t_world_tray).map_err(|m| Error::value("T_world_tray", m))?;
        let l = &truth.lighting;
        if !(l.ambient.is_finite() && l.lamp_strength.is_finite() && l.lamp_position.iter().all(|v| v.is_finite())) {
            return Err(Error::value("lighting", "expected finite numbers"));
        }
        if let Some(i) = truth.symmetries.iter().position(|v| !v.is_finite()) {
            return Err(Error::value(format!("symmetries[{i}]"), "expected an angle in degrees"));
        }
        if let Some(p) = &truth.placement {
            p.validate("placement")?;
        }
        Ok(truth)
    }

    /// Writes it atomically as pretty JSON.
    pub fn save(&self, path: &Path) -> Result<(), Error> {
        let text = serde_json::to_string_pretty(self).expect("truth always serialises");
        crate::formats::write_atomic(path, text.as_bytes())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn truth() -> TruthFile {
        TruthFile {
            t_world_tray: [[0.0, -1.0, 0.0, 5.0], [1.0, 0.0, 0.0, -3.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]],
            filled: vec![0, 2],
            lighting: LightingTruth { ambient: 0.3, lamp_strength: 0.5, lamp_position: [100.0, 0.0, 900.0] },
            seed: 1,
            scenario: 4,
            symmetries: vec![],
            placement: None,
            method: None,
        }
    }

    #[test]
    fn round_trip() {
        let t = truth();
        assert_eq!(TruthFile::from_json(&serde_json::to_string(&t).unwrap()).unwrap(), t);
    }

    #[test]
    fn reflected_scaled_and_zero_tray_poses_are_refused() {
        let mut reflected = truth();
        for row in reflected.t_world_tray.iter_mut().take(3) {
            row[1] = -row[1];
        }
        let mut scaled = truth();
        scaled.t_world_tray[2][2] = 3.0;
        let mut zero = truth();
        for row in zero.t_world_tray.iter_mut().take(3) {
            row[..3].fill(0.0);
        }
        for t in [reflected, scaled, zero] {
            let e = TruthFile::from_json(&serde_json::to_string(&t).unwrap()).unwrap_err().to_string();
            assert!(e.starts_with("T_world_tray: expected"), "{e}");
        }
    }
}
