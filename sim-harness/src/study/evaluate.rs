//! One placement's scenes through the simulated sensor and the deployed estimator: the model
//! built at the placement, the background captured once, then scenario after scenario
//! rendered, estimated and scored. Each scene's result depends only on (cell, placement,
//! method, seed, scenario index), never on which worker ran it or in what order.

use camplace_config::formats::dataset::frame_name;
use camplace_config::{Cell, Placement};
use camplace_estimator::camera::{isometry_from_rows, isometry_to_rows};
use camplace_estimator::{Estimator, Model, PoseEstimate};

use super::record::{score, FrameRecord};
use crate::capture::{background_scene, noise_key};
use crate::model_builder::build_model;
use crate::render::{Frame, Method, Simulator};
use crate::scenario::draw_scenario;
use crate::Result;

/// What every worker of one placement's evaluation shares: the settings and the model.
#[derive(Debug, Clone)]
pub struct Evaluator {
    cell: Cell,
    placement: Placement,
    method: Method,
    seed: u64,
    model: Model,
}

impl Evaluator {
    /// Builds the model at `placement` with `seed` (as `camplace model --seed` does).
    pub fn new(cell: &Cell, placement: &Placement, method: Method, seed: u64) -> Result<Evaluator> {
        let model = build_model(cell, placement, method, seed)?;
        Ok(Self::with_model(cell, placement, method, seed, model))
    }

    /// Uses a model built before (or loaded from a file).
    pub fn with_model(cell: &Cell, placement: &Placement, method: Method, seed: u64, model: Model) -> Evaluator {
        Evaluator { cell: cell.clone(), placement: *placement, method, seed, model }
    }

    /// The model scenes are estimated with.
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// A worker with its own simulator and estimator (each owns its buffers), the
    /// background already captured.
    pub fn worker(&self) -> Result<Worker> {
        let mut sim = Simulator::new(&self.cell, &self.placement, self.seed)?;
        let mut frame = Frame::default();
        sim.render(&background_scene(&self.cell, self.seed), self.method, noise_key(self.seed, 0, true), &mut frame);
        let mut estimator = Estimator::new(&self.cell, sim.rig(), self.model.clone(), self.method)?;
        estimator.set_background(&frame.left, &frame.right)?;
        Ok(Worker { sim, estimator, frame, pose: PoseEstimate::default(), settings: self.settings() })
    }

    fn settings(&self) -> Settings {
        Settings { cell: self.cell.clone(), method: self.method, seed: self.seed }
    }
}

/// The settings a worker needs of its evaluator.
#[derive(Debug)]
struct Settings {
    cell: Cell,
    method: Method,
    seed: u64,
}

/// Renders, estimates and scores scenes of one placement, one at a time.
pub struct Worker {
    sim: Simulator,
    estimator: Estimator,
    frame: Frame,
    pose: PoseEstimate,
    settings: Settings,
}

impl std::fmt::Debug for Worker {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Worker").field("estimator", &self.estimator).finish()
    }
}

impl Worker {
    /// Scenario `index` of the study seed: rendered, estimated and scored. The record's
    /// `frame` is the folder name `render --dataset` gives the same scene.
    pub fn scene(&mut self, index: u64) -> Result<FrameRecord> {
        let Settings { cell, method, seed } = &self.settings;
        let scenario = draw_scenario(cell, *seed, index);
        self.sim.render(&scenario.scene(), *method, noise_key(*seed, index, false), &mut self.frame);
        self.estimator.process(&self.frame.left, &self.frame.right, &mut self.pose)?;
        let mut record = FrameRecord::new(frame_name(index), &self.pose);
        let symmetries = self.estimator.model().symmetries_deg.clone();
        // The truth as a dataset's truth.json carries it (a 4x4 matrix, not a quaternion),
        // so replaying the rendered dataset scores to the last bit alike.
        let truth = isometry_from_rows(&isometry_to_rows(&scenario.t_world_tray));
        record.score = Some(score(&self.pose, &self.estimator, &truth, &symmetries, &cell.metrics));
        Ok(record)
    }
}
