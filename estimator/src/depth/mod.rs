//! Depth reconstruction, steps 1-3 of the pipeline (docs/design/estimator-stages.md): raw shots are
//! rectified, turned into a disparity map (one-shot stereo or 12-shot phase decoding), and
//! back-projected into a world cloud with the background removed.

mod background;
mod cloud;
#[cfg(test)]
mod fixture;
mod foreground;
mod pattern;
mod phase;
mod reconstruct;
mod rectify;
mod stereo;

pub use background::Background;
pub use cloud::{Cloud, CloudBuilder};
pub use foreground::{Foreground, PixelRegion};
pub use pattern::{fringe, fringe_set, one_shot, random_dots, PHASE_STEPS};
pub use phase::PhaseDecoder;
pub use reconstruct::{ReconstructTimings, Reconstruction, Reconstructor};
pub use rectify::{Rectification, RectifiedCamera};
pub use stereo::{DisparityMatcher, Elas};
// How a frame's shots are decoded, and the frames' pixels.
pub use crate::method::{method_for, Method};
pub use camplace_config::AsImageView;
