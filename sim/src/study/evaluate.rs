//! One placement's scenes through the simulated sensor and the deployed estimator: the model
//! built at the placement, the background captured once, then scenario after scenario
//! rendered, estimated and scored, its slots' states against the scene's filled slots. Each scene's result depends only on (cell, placement,
//! method, seed, scenario index), never on which worker ran it or in what order.

use camplace_config::frame_name;
use camplace_config::{Cell, Placement};
use camplace_estimator::{geometry::isometry_from_rows, geometry::isometry_to_rows};
use camplace_estimator::{Estimator, EstimatorConfig, Model, PoseEstimate};

use super::negatives::weigh_negatives;
use crate::model_builder::build_model;
use crate::render::{Frame, Method, Simulator};
use crate::scene::rig_error::draw_rig_error;
use crate::scene::scenario::background_scene;
use crate::scene::scenario::draw_scenario;
use crate::seeds::noise_key;
use crate::Result;
use camplace_estimator::{scoring::score, scoring::FrameRecord, scoring::SlotScore};

/// What every worker of one placement's evaluation shares: the settings, the background
/// capture and an estimator set up for the model and the background (its model indexes
/// built once, copied for each worker).
pub struct Evaluator {
    cell: Cell,
    placement: Placement,
    method: Method,
    seed: u64,
    background: Frame,
    estimator: Estimator,
    /// The simulator of the placement, each worker's copied from it (its projector
    /// patterns are dear to prepare; a render depends on nothing a render before left).
    sim: Simulator,
    /// Whether each scene's hard negatives are weighed beside its pose
    /// ([`super::negatives`]).
    negatives: bool,
}

impl std::fmt::Debug for Evaluator {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Evaluator")
            .field("placement", &self.placement)
            .field("method", &self.method)
            .field("seed", &self.seed)
            .finish()
    }
}

impl Evaluator {
    /// Builds the model at `placement` with `seed` (as `camplace model --seed` does).
    pub fn new(cell: &Cell, placement: &Placement, method: Method, seed: u64) -> Result<Evaluator> {
        let model = build_model(cell, placement, method, seed)?;
        Self::with_model(cell, placement, method, seed, model)
    }

    /// Uses a model built before (or loaded from a file); captures the background once.
    pub fn with_model(
        cell: &Cell,
        placement: &Placement,
        method: Method,
        seed: u64,
        model: Model,
    ) -> Result<Evaluator> {
        let mut sim = Simulator::new(cell, placement, seed)?;
        let mut background = Frame::default();
        sim.render(&background_scene(cell, seed), method, noise_key(seed, 0, true), &mut background);
        let mut estimator = Estimator::new(&EstimatorConfig::from(cell), sim.rig(), model, method)?;
        estimator.set_background(&background.shots.left, &background.shots.right)?;
        Ok(Evaluator {
            cell: cell.clone(),
            placement: *placement,
            method,
            seed,
            background,
            estimator,
            sim,
            negatives: false,
        })
    }

    /// The evaluator weighing each scene's hard negatives too, when `negatives`.
    pub fn with_negatives(mut self, negatives: bool) -> Self {
        self.negatives = negatives;
        self
    }

    /// A worker with its own simulator and estimator (each owns its buffers), the
    /// background already set.
    pub fn worker(&self) -> Result<Worker<'_>> {
        let sim = self.sim.clone();
        let estimator = self.estimator.clone();
        Ok(Worker { sim, estimator, frame: Frame::default(), pose: PoseEstimate::default(), evaluator: self })
    }
}

/// Renders, estimates and scores scenes of one placement, one at a time.
pub struct Worker<'a> {
    sim: Simulator,
    estimator: Estimator,
    frame: Frame,
    pose: PoseEstimate,
    evaluator: &'a Evaluator,
}

impl std::fmt::Debug for Worker<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Worker").field("estimator", &self.estimator).finish()
    }
}

impl Worker<'_> {
    /// The pose of the last scene, with every count and the verification's evidence, for
    /// diagnosis.
    pub fn last_pose(&self) -> &PoseEstimate {
        &self.pose
    }

    /// Scenario `index` of the study seed: rendered, estimated and scored. The record's
    /// `frame` is the folder name `render --dataset` gives the same scene.
    pub fn scene(&mut self, index: u64) -> Result<FrameRecord> {
        let Evaluator { cell, method, seed, .. } = self.evaluator;
        let scenario = draw_scenario(cell, *seed, index);
        // Each scenario's estimator believes in its own miscalibrated rig, through which the
        // background is reconstructed again, as a cell calibrated that way would.
        if let Some(error) = draw_rig_error(cell, *seed, index) {
            self.estimator.set_rig(&EstimatorConfig::from(cell), &error.apply(self.sim.rig()))?;
            let background = &self.evaluator.background;
            self.estimator.set_background(&background.shots.left, &background.shots.right)?;
        }
        self.sim.render(&scenario.scene(), *method, noise_key(*seed, index, false), &mut self.frame);
        self.pose = self.estimator.process(&self.frame.shots.left, &self.frame.shots.right)?;
        let mut record = FrameRecord::new(frame_name(index), &self.pose).with_slots(self.estimator.slots());
        // The truth as a dataset's truth.json carries it (a 4x4 matrix, not a quaternion),
        // so replaying the rendered dataset scores to the last bit alike.
        let truth = isometry_from_rows(&isometry_to_rows(&scenario.t_world_tray));
        let symmetries = &self.estimator.model().symmetries_deg;
        record.score = Some(score(&self.pose, &self.estimator, &truth, symmetries, &cell.metrics));
        if !self.estimator.slots().is_empty() {
            record.slot_score =
                Some(SlotScore::of(self.estimator.slots(), &scenario.filled, &self.pose.t_world_tray, &truth));
        }
        if self.evaluator.negatives {
            record.negatives = Some(weigh_negatives(&mut self.estimator, &truth, &cell.metrics)?);
        }
        Ok(record)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A worker moves its estimator to each scenario's miscalibrated rig, keeping its
    /// buffers; an estimator built for that rig from nothing must give the very same pose.
    #[test]
    fn a_re_rigged_worker_matches_an_estimator_built_for_the_believed_rig() {
        let cell = Cell::default();
        let placement = cell.placement.with_overrides("r=605,alpha=32,baseline=81,vergence=3.5").unwrap();
        let (method, seed) = (Method::OneShot, 3);
        let evaluator = Evaluator::new(&cell, &placement, method, seed).unwrap();
        let mut worker = evaluator.worker().unwrap();
        let mut sim = Simulator::new(&cell, &placement, seed).unwrap();
        let mut frame = Frame::default();
        let mut found = 0;
        for index in 0..3 {
            worker.scene(index).unwrap();
            let error = draw_rig_error(&cell, seed, index).expect("the default cell draws rig errors");
            let model = worker.estimator.model().clone();
            let mut fresh =
                Estimator::new(&EstimatorConfig::from(&cell), &error.apply(sim.rig()), model, method).unwrap();
            fresh.set_background(&evaluator.background.shots.left, &evaluator.background.shots.right).unwrap();
            let scenario = draw_scenario(&cell, seed, index);
            sim.render(&scenario.scene(), method, noise_key(seed, index, false), &mut frame);
            let pose = fresh.process(&frame.shots.left, &frame.shots.right).unwrap();
            let got = &worker.pose;
            assert_eq!(got.t_world_tray, pose.t_world_tray, "scene {index}");
            assert_eq!(
                (got.found, got.inliers, got.scene_points, got.keypoints, got.matches, got.ransac.iterations),
                (pose.found, pose.inliers, pose.scene_points, pose.keypoints, pose.matches, pose.ransac.iterations),
                "scene {index}"
            );
            found += usize::from(pose.found);
        }
        assert!(found > 0, "no scene gave a pose to compare");
    }
}
