//! camplace's estimator: the pipeline that runs on the cell PC, from a stereo frame to the
//! tray's pose. Pure compute: it opens no device, and no file but a model file (read
//! through camplace-config's bounded reader by `Model::load`, so an embedder needs nothing
//! else); the crate that owns any other format loads it and hands the estimator plain
//! values. Frames arrive as borrowed `ImageView`s (or owned images), settings as an
//! `EstimatorConfig`.
//!
//! The root holds what an embedder needs: an [`Estimator`] made from an [`EstimatorConfig`],
//! a [`Rig`] and a [`Model`], fed frames as [`ImageView`]s, answering a [`PoseEstimate`]
//! (its [`PoseEstimate::accepted`] says whether the robot may use it). Everything else is in
//! a public module by pipeline step: [`depth`] (rectification, stereo or phase decoding,
//! background, world cloud), [`features`] (down-sampling, normals, key points, descriptors,
//! matching), [`pose`] (model, RANSAC, ICP, verification, slots, metrics), [`calibration`]
//! (run once per rig, before any of them: chessboard corners to cameras, hand-eye),
//! [`geometry`] (cameras, transforms, planned placements and the checks of a built rig) and
//! [`scoring`] (records and summaries of many frames).
//!
//! ```no_run
//! use camplace_estimator::{depth::Method, Estimator, EstimatorConfig, ImageView, Model, Rig};
//! # fn run(rig: Rig, left: &[u8], right: &[u8]) -> Result<(), Box<dyn std::error::Error>> {
//! let model = Model::load(std::path::Path::new("tray.model"))?;
//! let mut estimator = Estimator::new(&EstimatorConfig::default(), &rig, model, Method::OneShot)?;
//! let (l, r) = (ImageView::new(left, 640, 480, 640)?, ImageView::new(right, 640, 480, 640)?);
//! let estimate = estimator.process(&[l], &[r])?;
//! if estimate.accepted() {
//!     println!("T_world_tray = {}", estimate.t_world_tray);
//! }
//! # Ok(()) }
//! ```

#[macro_use]
mod cpu;

mod as_built;
pub mod calibration;
mod camera;
pub mod depth;
mod error;
mod estimator_config;
pub mod features;
mod method;
mod mounting_check;
mod pipeline;
mod placement_rig;
pub mod pose;
mod rig;
pub mod scoring;
mod spatial;

pub use error::{Error, ErrorKind};
pub use estimator_config::EstimatorConfig;
pub use pipeline::{Estimator, PoseEstimate, StageTimings};
pub use pose::Model;
pub use rig::Rig;
// Frames reach the estimator as owned images or borrowed views of the caller's pixels.
pub use camplace_config::ImageView;

/// The rig's geometry: the pinhole [`Camera`], rigid transforms read from matrices (each
/// the rotation it is, half turns included), planned placements of a rig above the cell, and
/// the checks of a built rig against its plan.
pub mod geometry {
    pub use crate::as_built::{as_built, azimuth_difference, AsBuilt};
    pub use crate::camera::{isometry_from_matrix, isometry_from_rows, isometry_to_rows, Camera};
    pub use crate::mounting_check::{mounting_check, MountingCheck, MountingLimit, MountingVerdict, ParamCheck};
    pub use crate::placement_rig::{camera_k, look_at, rig_for, rig_pose, sensor_rig};
    pub use crate::spatial::Neighbours;
}

// Inside the crate every stage is named at the root, one path each.
pub(crate) use depth::*;
pub(crate) use error::Result;
pub(crate) use features::*;
pub(crate) use geometry::*;
pub(crate) use pose::*;
// The image buffers are camplace-config's (image files hold them too); callers name them
// there, the stages here as `crate::GrayImage`.
use camplace_config::{FloatImage, GrayImage};

// The test fixtures are camplace-testing's; this crate's unit tests compile the same module
// (a dev-dependency on that crate would give them a second copy of this crate's types).
#[cfg(test)]
#[path = "../../testing/src/fixtures.rs"]
pub mod testing;

/// Instruction-set checks the [`multiversion!`] expansions in other crates call.
#[doc(hidden)]
pub use cpu::{avx2_available, avx512_available};
