//! Test fixtures for the crates' tests and benches: a box tray made of cuboids and scenes of
//! it with known poses, built analytically so tests and benches can check the pose stages
//! against ground truth without rendering. A dev-dependency only, so no product links it.
//!
//! The estimator's own unit tests compile the same module (`fixtures.rs`) inside the
//! estimator: a dev-dependency on this crate would hand them a second copy of the
//! estimator's types. The module names the estimator's types through its parent, which is
//! the estimator's root there and the imports below here.

use camplace_estimator::features::{Correspondence, ECSAD_DIM};
use camplace_estimator::pose::{Model, ModelView};

mod fixtures;

pub use fixtures::*;
