//! `recommended.json`, the study's answer as data: the one type that the study report writes
//! and that `placement --study`, `ablate --study`, `trial plan --study` and the commissioning
//! steps read back, checked on read. How the report shows it is the report's business.

use std::path::Path;

use camplace_config::{write_atomic, Placement, Vergence};
use camplace_estimator::{depth::Method, geometry::rig_for, geometry::Camera, scoring::VerifiedSummary};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

use crate::study::optimize::recheck_seed;
use crate::study::placement_study::{Preset, Recommendation};
use crate::study::tray_set::RANKED_BY;
use crate::{Error, Result};

/// What a study recommends, as `recommended.json` holds it (docs/formats.md). The fields
/// are in the file's key order (alphabetical, as the file has always been written).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Recommended {
    /// Polar angle, deg (the placement's).
    pub alpha: f64,
    /// Azimuth, deg (the placement's).
    pub azimuth: f64,
    /// Baseline, mm (the placement's).
    pub baseline: f64,
    /// Where the placement came from: "search" or "grid".
    pub chosen_from: String,
    /// Mean correct feature matches per scene on the lowest tray (what breaks ties).
    pub mean_correct_matches: Option<f64>,
    /// The sensor method it was measured with.
    #[serde(serialize_with = "method_text", deserialize_with = "method_parsed")]
    pub method: Method,
    /// The placement, every parameter given (as `--placement` takes it).
    #[serde(serialize_with = "placement_text", deserialize_with = "placement_parsed")]
    pub placement: Placement,
    /// The study preset's name ("full", "quick", "paper").
    pub preset: String,
    /// Distance from the world origin, mm (the placement's).
    pub r: f64,
    /// The rate the placements were ranked by: `verified_success_rate` (the lowest tray's
    /// `verification`), or `success_rate` in a file written before the study ranked by
    /// what the robot is handed.
    #[serde(default = "ranked_by_success")]
    pub ranked_by: String,
    /// Fresh scenes it was judged on (its lowest tray's).
    pub scenes: usize,
    /// What breaks ties between placements of equal success.
    pub secondary_measure: String,
    /// The seed of the fresh scenes.
    pub seed: u64,
    /// Wilson 95 % interval of the success rate.
    pub success_interval: [f64; 2],
    /// `successes / scenes`.
    pub success_rate: f64,
    /// Scenes within the success limits.
    pub successes: usize,
    /// How many checked candidates reached the same success rate.
    pub tied_candidates: usize,
    /// Each part's optical axis from straight down, deg.
    pub tilt_deg: RecommendedTilts,
    /// Each tray's figures on the fresh scenes.
    pub trays: Vec<RecommendedTray>,
    /// The toe-in per camera, deg (the placement's, `auto` resolved).
    pub vergence_deg: f64,
    /// The lowest tray's verification figures, as in `summary.json`.
    #[serde(serialize_with = "verification_value")]
    pub verification: Option<VerifiedSummary>,
    /// Where the rig's parts are in the world, mm.
    pub world_mm: RecommendedWorld,
}

/// `ranked_by` of a file that names none: the study then ranked by success.
fn ranked_by_success() -> String {
    "success_rate".to_string()
}

/// One tray's figures in `recommended.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RecommendedTray {
    /// The tray's name.
    pub name: String,
    /// Fresh scenes.
    pub scenes: usize,
    /// Wilson 95 % interval of the success rate.
    pub success_interval: [f64; 2],
    /// `successes / scenes`.
    pub success_rate: f64,
    /// Scenes within the success limits.
    pub successes: usize,
}

/// Each part's tilt from straight down, deg.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RecommendedTilts {
    /// The left camera's.
    pub left_camera: f64,
    /// The projector's (none without one).
    pub projector: Option<f64>,
    /// The right camera's.
    pub right_camera: f64,
}

/// The centres of the rig's parts and the point it looks at, world frame, mm.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RecommendedWorld {
    /// The left camera's centre.
    pub left_camera: [f64; 3],
    /// The point the rig looks at (the world origin).
    pub look_at: [f64; 3],
    /// The projector's centre (none without one).
    pub projector: Option<[f64; 3]>,
    /// The right camera's centre.
    pub right_camera: [f64; 3],
}

/// A camera's centre in the world, mm.
fn centre(c: &Camera) -> [f64; 3] {
    let t = c.t_world_camera.translation.vector;
    [t.x, t.y, t.z]
}

/// A camera's optical axis from straight down, deg.
fn tilt(c: &Camera) -> f64 {
    let axis = c.t_world_camera.rotation * nalgebra::Vector3::z();
    (-axis.z).clamp(-1.0, 1.0).acos().to_degrees()
}

impl Recommended {
    /// The record of a study's recommendation, judged on the fresh scenes of `seed`'s re-check.
    pub fn new(r: &Recommendation, preset: &Preset, seed: u64) -> Recommended {
        let p = r.placement;
        let s = &r.summary;
        let rig = rig_for(&p, &r.cells[0].1.sensor);
        Recommended {
            alpha: p.alpha,
            azimuth: p.azimuth,
            baseline: p.baseline,
            chosen_from: r.source.to_string(),
            mean_correct_matches: s.mean_correct_matches,
            method: r.method,
            placement: p,
            preset: preset.name.to_string(),
            r: p.r,
            ranked_by: RANKED_BY.to_string(),
            scenes: s.scored,
            secondary_measure: "mean correct feature matches per scene".to_string(),
            seed: recheck_seed(seed),
            success_interval: s.success_interval,
            success_rate: s.success_rate,
            successes: s.successes,
            tied_candidates: r.tied_candidates,
            tilt_deg: RecommendedTilts {
                left_camera: tilt(&rig.left),
                projector: rig.projector.as_ref().map(tilt),
                right_camera: tilt(&rig.right),
            },
            trays: r
                .cells
                .iter()
                .zip(&r.per_tray)
                .map(|((name, _), t)| RecommendedTray {
                    name: name.clone(),
                    scenes: t.scored,
                    success_interval: t.success_interval,
                    success_rate: t.success_rate,
                    successes: t.successes,
                })
                .collect(),
            vergence_deg: p.vergence.degrees(p.r, p.baseline),
            verification: s.verification,
            world_mm: RecommendedWorld {
                left_camera: centre(&rig.left),
                look_at: [0.0, 0.0, 0.0],
                projector: rig.projector.as_ref().map(centre),
                right_camera: centre(&rig.right),
            },
        }
    }

    /// Writes `dir/recommended.json` (pretty JSON, atomically).
    pub fn write(&self, dir: &Path) -> Result<()> {
        write_atomic(&dir.join("recommended.json"), self.to_json().as_bytes())?;
        Ok(())
    }

    /// Reads `dir/recommended.json` through the bounded text reader (a device or a file past
    /// the text budget is refused before reading).
    pub fn load(dir: &Path) -> Result<Recommended> {
        let path = dir.join("recommended.json");
        let bytes = camplace_config::read_bounded(&path, camplace_config::FileKind::Text)?;
        Self::from_json(&bytes).map_err(|what| Error::Other(format!("{}: {what}", path.display())))
    }

    /// Decodes and checks the bytes of a `recommended.json`; the error names the key.
    pub fn from_json(bytes: &[u8]) -> std::result::Result<Recommended, String> {
        // serde_json refuses anything but white space after the value.
        let r: Recommended = serde_json::from_slice(bytes)
            .map_err(|e| format!("expected the recommended.json a study writes (one JSON object): {e}"))?;
        let p = r.placement;
        // The figures written beside the placement must be its own.
        for (key, got, want) in [
            ("r", r.r, p.r),
            ("alpha", r.alpha, p.alpha),
            ("baseline", r.baseline, p.baseline),
            ("vergence_deg", r.vergence_deg, p.vergence.degrees(p.r, p.baseline)),
            ("azimuth", r.azimuth, p.azimuth),
        ] {
            if (got - want).abs() > 1e-9 * want.abs().max(1.0) {
                return Err(format!("{key}: expected the placement's value {want}, got {got}"));
            }
        }
        Ok(r)
    }

    /// The file's text: pretty JSON, keys in the order above.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("plain data")
    }
}

/// The method as its name.
fn method_text<S: Serializer>(m: &Method, s: S) -> std::result::Result<S::Ok, S::Error> {
    s.collect_str(m)
}

/// The method from its name.
fn method_parsed<'de, D: Deserializer<'de>>(d: D) -> std::result::Result<Method, D::Error> {
    let text = String::deserialize(d).map_err(|_| serde::de::Error::custom(METHOD_EXPECTED))?;
    text.parse().map_err(|_| serde::de::Error::custom(METHOD_EXPECTED))
}

/// What `method` must be.
const METHOD_EXPECTED: &str = "method: expected \"one-shot\" or \"phase-12\"";

/// The placement as `--placement` takes it.
fn placement_text<S: Serializer>(p: &Placement, s: S) -> std::result::Result<S::Ok, S::Error> {
    s.collect_str(p)
}

/// What `placement` must be.
const PLACEMENT_EXPECTED: &str = "placement: expected a placement such as \"r=605,alpha=32,baseline=81,vergence=3.5\"";

/// The placement from its text, every parameter but the azimuth given.
fn placement_parsed<'de, D: Deserializer<'de>>(d: D) -> std::result::Result<Placement, D::Error> {
    let text = String::deserialize(d).map_err(|_| serde::de::Error::custom(PLACEMENT_EXPECTED))?;
    // Every parameter but the azimuth is written out, so the base's values never show
    // through; a study's placements have azimuth 0 unless they say otherwise.
    let base = Placement { r: 0.0, alpha: 0.0, baseline: 0.0, vergence: Vergence::Auto, azimuth: 0.0 };
    base.with_overrides(&text)
        .and_then(|p| p.validate("placement").map(|()| p))
        .map_err(|e| serde::de::Error::custom(format!("{PLACEMENT_EXPECTED}: {e}")))
}

/// The verification's figures as the file has always held them: through a JSON value, so
/// its keys are in alphabetical order and the f32 threshold is written widened to f64.
fn verification_value<S: Serializer>(v: &Option<VerifiedSummary>, s: S) -> std::result::Result<S::Ok, S::Error> {
    serde_json::to_value(v).map_err(serde::ser::Error::custom)?.serialize(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A file as a study writes it, with `placement` and `method` given.
    fn file(placement: &str, method: &str, r: f64) -> String {
        format!(
            r#"{{"alpha": 32.0, "azimuth": 0.0, "baseline": 81.0, "chosen_from": "grid", "mean_correct_matches": 9.5,
                "method": "{method}", "placement": "{placement}", "preset": "quick", "r": {r}, "scenes": 20,
                "secondary_measure": "mean correct feature matches per scene", "seed": 2,
                "success_interval": [0.8, 1.0], "success_rate": 1.0, "successes": 20, "tied_candidates": 1,
                "tilt_deg": {{"left_camera": 32.0, "projector": 32.0, "right_camera": 32.0}},
                "trays": [{{"name": "tray-8", "scenes": 20, "success_interval": [0.8, 1.0], "success_rate": 1.0,
                            "successes": 20}}],
                "vergence_deg": 3.5, "verification": null,
                "world_mm": {{"left_camera": [1.0, 2.0, 3.0], "look_at": [0.0, 0.0, 0.0], "projector": null,
                             "right_camera": [4.0, 5.0, 6.0]}}}}"#
        )
    }

    #[test]
    fn reads_what_it_writes_and_names_the_bad_key() {
        let good = "r=605,alpha=32,baseline=81,vergence=3.5";
        let r = Recommended::from_json(file(good, "phase-12", 605.0).as_bytes()).unwrap();
        assert_eq!(r.placement.r, 605.0);
        assert_eq!(r.method, Method::Phase12);
        // A file written before the study ranked by verified success says what it ranked by.
        assert_eq!(r.ranked_by, "success_rate");
        assert_eq!(Recommended::from_json(r.to_json().as_bytes()).unwrap(), r);
        let trailing = file(good, "one-shot", 605.0) + " 7";
        for (bad, key) in [
            (file("r=605", "one-shot", 605.0), "placement"),
            (file(good, "two-shot", 605.0), "method"),
            (file(good, "one-shot", 600.0), "r:"),
            (trailing, "one JSON object"),
            ("[1]".to_string(), "one JSON object"),
            (r#"{"placement": "r=605,alpha=32,baseline=81,vergence=3.5", "method": "one-shot"}"#.to_string(), "alpha"),
        ] {
            let e = Recommended::from_json(bad.as_bytes()).unwrap_err();
            assert!(e.contains(key), "{e}");
        }
    }
}
