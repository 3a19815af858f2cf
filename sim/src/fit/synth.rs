//! The empty cell rendered at a recorded dataset's rig with candidate sensor keys: the
//! simulated side of the sensor fit. The table's geometry and albedo come from the cell
//! file, the cameras from the dataset's `rig.json`; the light is ambient only (the level
//! the fit measures on the real table), so every statistic is measured on images made by
//! the renderer itself, whatever it does between the light and the pixel.

use camplace_config::{Cell, Placement, RigFile};

use crate::render::{Frame, Method, Simulator};
use crate::scene::scenario::background_scene;
use crate::scene::{SceneSpec, ID_TABLE};
use crate::Result;

/// The sensor keys the fit varies.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorKeys {
    /// `sensor.noise_amplitude`, grey levels.
    pub noise_amplitude: u32,
    /// `sensor.blur`, the mean filter's odd side.
    pub blur: u32,
    /// `sensor.projector_gain`.
    pub projector_gain: f64,
    /// `sensor.dot_size`, projector pixels.
    pub dot_size: u32,
}

impl SensorKeys {
    /// The keys as `cell` has them.
    pub fn of(cell: &Cell) -> SensorKeys {
        let s = &cell.sensor;
        SensorKeys {
            noise_amplitude: s.noise_amplitude,
            blur: s.blur,
            projector_gain: s.projector_gain,
            dot_size: s.dot_size,
        }
    }
}

/// The empty cell at the dataset's rig, ready to render with any keys.
pub struct EmptyCell {
    cell: Cell,
    placement: Placement,
    method: Method,
    scene: SceneSpec,
    /// The simulator and the dot size its pattern was drawn with.
    sim: Option<(Simulator, u32)>,
    frame: Frame,
}

impl EmptyCell {
    /// `cell`'s empty table seen by the cameras of `rig` (the projector where the rig file
    /// puts it, else where `placement` puts it relative to the left camera).
    pub fn new(cell: &Cell, rig: &RigFile, placement: Placement, method: Method) -> EmptyCell {
        let mut cell = cell.clone();
        cell.rig = Some(rig.clone());
        let mut scene = background_scene(&cell, cell.scenarios.seed);
        scene.lamp_strength = 0.0;
        EmptyCell { cell, placement, method, scene, sim: None, frame: Frame::default() }
    }

    /// Renders the empty table under `ambient` (units of full white) with `keys`, with the
    /// camera noise of `noise_key` (none, and no mean filter, without one).
    pub fn render(&mut self, keys: &SensorKeys, ambient: f64, noise_key: Option<u64>) -> Result<&Frame> {
        if self.sim.as_ref().is_none_or(|(_, dots)| *dots != keys.dot_size) {
            let mut cell = self.cell.clone();
            cell.sensor.dot_size = keys.dot_size;
            self.sim = Some((Simulator::new(&cell, &self.placement, cell.scenarios.seed)?, keys.dot_size));
        }
        let (sim, _) = self.sim.as_mut().expect("made above");
        sim.set_levels(keys.projector_gain, keys.noise_amplitude, keys.blur);
        self.scene.ambient = ambient;
        match noise_key {
            Some(key) => sim.render(&self.scene, self.method, key, &mut self.frame),
            None => sim.render_clean(&self.scene, self.method, &mut self.frame),
        }
        Ok(&self.frame)
    }

    /// Per camera (left, right), the pixels that see the table.
    pub fn table_masks(&mut self) -> Result<[Vec<bool>; 2]> {
        let keys = SensorKeys::of(&self.cell);
        let frame = self.render(&keys, 0.2, None)?;
        let mask = |depth: &camplace_config::FloatImage, ids: &camplace_config::GrayImage| -> Vec<bool> {
            depth.data.iter().zip(&ids.data).map(|(d, &id)| d.is_finite() && id == ID_TABLE).collect()
        };
        Ok([mask(&frame.depth_left, &frame.ids_left), mask(&frame.depth_right, &frame.ids_right)])
    }
}
