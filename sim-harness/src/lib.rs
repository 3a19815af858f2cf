//! camplace's simulator and placement study: the scene, a CPU renderer of the stereo
//! camera and projector, scenarios with common random numbers, model building, evaluation,
//! search and reports. It feeds rendered frames to the same estimator the cell PC runs.

mod error;
pub mod frame_files;
pub mod model_builder;
pub mod noise;
pub mod pattern;
pub mod placement_rig;
pub mod raster;
pub mod render;
pub mod report;
pub mod scenario;
pub mod scene;
pub mod search;
mod seeds;
pub mod shade;
pub mod study;
pub mod tray;

pub use error::{Error, Result};
pub use model_builder::{build_model, model_points};
pub use render::{Frame, Method, Simulator};
pub use scenario::{background_scene, draw_scenario, Scenario};
pub use scene::SceneSpec;
pub use seeds::noise_key;
