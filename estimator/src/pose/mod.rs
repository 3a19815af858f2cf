//! From feature matches to the tray's pose: the tray model, prerejective RANSAC for the
//! coarse pose, point-to-plane ICP to refine it, the rigid fit both use, and the quality
//! metrics of an estimate against the truth.

mod icp;
mod kabsch;
mod metrics;
mod model;
mod ransac;

pub use icp::{Icp, IcpResult};
pub use metrics::{correct_matches, pose_errors, PoseErrors};
#[cfg(any(test, feature = "testing"))]
pub(crate) use model::DESCRIPTOR_LEN;
pub use model::{Model, ModelOrigin, ModelView, MODEL_FORMAT_VERSION};
pub use ransac::{Ransac, RansacResult};
