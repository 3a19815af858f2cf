//! camplace's simulator and placement study: the scene, a CPU renderer of the stereo
//! camera and projector, scenarios with common random numbers, model building, evaluation,
//! search and reports. It feeds rendered frames to the same estimator the cell PC runs.

mod error;
pub mod placement_rig;
pub mod search;

pub use error::{Error, Result};
