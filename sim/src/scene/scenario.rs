//! The scenarios of a study: tray pose, filled slots and light drawn from the cell's
//! ranges. Scenario i of seed S depends on nothing else, so every placement sees the same
//! scenes (common random numbers) and differences between placements are not noise.

use camplace_config::{Cell, Effect};
use camplace_estimator::{geometry::isometry_from_rows, geometry::isometry_to_rows};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::scene::tray::slot_count;
use crate::scene::{OccluderBox, SceneSpec};
use crate::seeds::{occluder_key, scenario_key};

/// One drawn scene, as `truth.json` stores it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Scenario {
    /// The study seed it was drawn with.
    pub seed: u64,
    /// Its index in the study.
    pub index: u64,
    /// Tray frame -> world frame, stored as a row-major 4x4 matrix.
    #[serde(rename = "T_world_tray", with = "pose_rows")]
    pub t_world_tray: Isometry3<f64>,
    /// Indices of the slots holding an item, ascending.
    pub filled: Vec<usize>,
    /// Ambient light, in units of full white.
    pub ambient: f64,
    /// Lamp strength, in units of full white on a surface facing it.
    pub lamp_strength: f64,
    /// Lamp position, world mm.
    pub lamp_position: Point3<f64>,
    /// The box above the tray, when the cell's occluder is on and this scenario drew it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub occluder: Option<OccluderBox>,
}

impl Scenario {
    /// The full scene: table, tray and the filled slots' items.
    pub fn scene(&self) -> SceneSpec {
        SceneSpec {
            t_world_tray: self.t_world_tray,
            filled: self.filled.clone(),
            table: true,
            tray: true,
            ambient: self.ambient,
            lamp_strength: self.lamp_strength,
            lamp_position: self.lamp_position,
            occluder: self.occluder,
        }
    }
}

/// Draws scenario `index` of study `seed` from the cell's scenario and lighting ranges.
pub fn draw_scenario(cell: &Cell, seed: u64, index: u64) -> Scenario {
    let mut rng = ChaCha8Rng::seed_from_u64(scenario_key(seed, index));
    let mut uniform = |[lo, hi]: [f64; 2]| lo + (hi - lo) * rng.random::<f64>();
    let sc = &cell.scenarios;
    let l = &cell.lighting;
    // A fixed order of draws, lighting before the slots, so a tray with another slot count
    // still sees the same poses and light.
    let x = uniform(sc.tray_x);
    let y = uniform(sc.tray_y);
    let yaw = uniform(sc.tray_yaw).to_radians();
    let ambient = uniform(l.ambient);
    let lamp_strength = uniform(l.lamp_strength);
    let polar = uniform(l.lamp_polar).to_radians();
    let azimuth = uniform([0.0, 360.0]).to_radians();
    let filled = (0..slot_count(cell)).filter(|_| rng.random::<f64>() < sc.fill_probability).collect();
    let d = l.lamp_distance;
    Scenario {
        seed,
        index,
        t_world_tray: Isometry3::from_parts(
            Translation3::new(x, y, 0.0),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw),
        ),
        filled,
        ambient,
        lamp_strength,
        lamp_position: Point3::new(d * polar.sin() * azimuth.cos(), d * polar.sin() * azimuth.sin(), d * polar.cos()),
        occluder: draw_occluder(cell, seed, index, [x, y]),
    }
}

/// The occluder of scenario `index`, drawn from a stream of its own so that switching it
/// on or off leaves every other draw of the scenario as it was.
fn draw_occluder(cell: &Cell, seed: u64, index: u64, tray_centre: [f64; 2]) -> Option<OccluderBox> {
    if !cell.effect_active(Effect::Occluder) {
        return None;
    }
    let o = &cell.occluder;
    let mut rng = ChaCha8Rng::seed_from_u64(occluder_key(seed, index));
    let mut uniform = |[lo, hi]: [f64; 2]| lo + (hi - lo) * rng.random::<f64>();
    let present = uniform([0.0, 1.0]) < o.probability;
    let cx = tray_centre[0] + uniform([-o.offset, o.offset]);
    let cy = tray_centre[1] + uniform([-o.offset, o.offset]);
    let bottom = uniform(o.height);
    let [sx, sy, sz] = o.size;
    present.then_some(OccluderBox {
        min: [cx - sx / 2.0, cy - sy / 2.0, bottom],
        max: [cx + sx / 2.0, cy + sy / 2.0, bottom + sz],
    })
}

/// The background capture of a study: scenario 0's lighting without tray and items. The
/// background is captured once per placement, as on a real cell before the first tray.
pub fn background_scene(cell: &Cell, seed: u64) -> SceneSpec {
    draw_scenario(cell, seed, 0).scene().background()
}

mod pose_rows {
    use super::*;
    use serde::{Deserializer, Serializer};

    pub fn serialize<S: Serializer>(t: &Isometry3<f64>, s: S) -> Result<S::Ok, S::Error> {
        isometry_to_rows(t).serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Isometry3<f64>, D::Error> {
        let rows = <[[f64; 4]; 4]>::deserialize(d)?;
        if rows.iter().flatten().any(|v| !v.is_finite()) {
            return Err(serde::de::Error::custom("expected a 4x4 matrix of finite numbers"));
        }
        Ok(isometry_from_rows(&rows))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn draws_depend_only_on_seed_and_index() {
        let cell = Cell::default();
        let a = draw_scenario(&cell, 3, 17);
        assert_eq!(a, draw_scenario(&cell, 3, 17));
        // Another placement does not change the scene.
        let mut moved = cell.clone();
        moved.placement.r = 800.0;
        moved.placement.alpha = 10.0;
        assert_eq!(a, draw_scenario(&moved, 3, 17));
        assert_ne!(a.t_world_tray, draw_scenario(&cell, 3, 18).t_world_tray);
        assert_ne!(a.t_world_tray, draw_scenario(&cell, 4, 17).t_world_tray);
    }

    #[test]
    fn draws_stay_in_their_ranges_and_fill_at_the_rate() {
        let cell = Cell::default();
        let (sc, l) = (&cell.scenarios, &cell.lighting);
        let n = 2000;
        let mut filled = 0;
        for i in 0..n {
            let s = draw_scenario(&cell, 1, i);
            let t = s.t_world_tray.translation.vector;
            assert!(t.x >= sc.tray_x[0] && t.x <= sc.tray_x[1] && t.y >= sc.tray_y[0] && t.y <= sc.tray_y[1]);
            assert_eq!(t.z, 0.0);
            let up = s.t_world_tray.rotation * Vector3::z();
            assert!((up - Vector3::z()).norm() < 1e-12);
            assert!(s.ambient >= l.ambient[0] && s.ambient <= l.ambient[1]);
            assert!(s.lamp_strength >= l.lamp_strength[0] && s.lamp_strength <= l.lamp_strength[1]);
            assert!((s.lamp_position.coords.norm() - l.lamp_distance).abs() < 1e-6);
            let polar = (s.lamp_position.z / l.lamp_distance).acos().to_degrees();
            assert!(polar >= l.lamp_polar[0] - 1e-9 && polar <= l.lamp_polar[1] + 1e-9);
            assert!(s.filled.windows(2).all(|w| w[0] < w[1]) && s.filled.iter().all(|&k| k < 8));
            filled += s.filled.len();
        }
        // Binomial: 16000 slots at p = 0.5 have a standard deviation of about 63.
        let rate = filled as f64 / (8 * n) as f64;
        assert!((rate - sc.fill_probability).abs() < 0.02, "{rate}");
    }

    #[test]
    fn truth_json_round_trips() {
        let s = draw_scenario(&Cell::default(), 9, 2);
        let text = serde_json::to_string(&s).unwrap();
        assert!(text.contains("\"T_world_tray\":[["), "{text}");
        let back: Scenario = serde_json::from_str(&text).unwrap();
        assert!((back.t_world_tray.to_homogeneous() - s.t_world_tray.to_homogeneous()).norm() < 1e-12);
        assert_eq!(back.filled, s.filled);
        assert_eq!(back.lamp_position, s.lamp_position);
    }
}
