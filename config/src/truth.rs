//! `truth.json`: what the simulator knows of one scene (docs/architecture.md §3): the
//! tray's pose, the filled slots, the lighting and the seed, so any tool can score an
//! estimate.

use serde::{Deserialize, Serialize};
use std::path::Path;

use crate::{Error, ErrorKind, Placement};

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
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, &e))?;
        let de = &mut serde_json::Deserializer::from_str(&text);
        serde_path_to_error::deserialize(de)
            .map_err(|e| {
                let key = e.path().to_string();
                let inner = e.into_inner();
                let msg = inner.to_string();
                let msg = msg.split(" at line").next().unwrap_or(&msg).to_string();
                Error::new(ErrorKind::Value, if key == "." { String::new() } else { key }, msg).with_source(inner)
            })
            .map_err(|e| e.in_file(path))
    }

    /// Writes it atomically as pretty JSON.
    pub fn save(&self, path: &Path) -> Result<(), Error> {
        let text = serde_json::to_string_pretty(self).expect("truth always serialises");
        crate::formats::write_atomic(path, text.as_bytes())
    }
}
