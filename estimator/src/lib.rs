//! camplace's estimator: the pipeline that runs on the cell PC, from a stereo frame to the
//! tray's pose. Pure compute: it never opens a file or a device; the crate that owns a
//! format loads it and hands the estimator plain values.

#[macro_use]
pub mod multiversion;

pub mod background;
pub mod camera;
pub mod cloud;
pub mod correspondence;
pub mod downsample;
pub mod ecsad;
mod error;
pub mod features;
pub mod icp;
pub mod image;
pub mod kabsch;
pub mod keypoints;
pub mod matching;
pub mod method;
pub mod metrics;
pub mod model;
pub mod neighbours;
pub mod normals;
pub mod phase;
#[cfg(test)]
mod phase_fixture;
pub mod pipeline;
pub mod ransac;
pub mod reconstruct;
pub mod rectified;
pub mod rectify;
pub mod rig;
pub mod stereo;
#[cfg(any(test, feature = "testing"))]
pub mod testing;

pub use background::Background;
pub use camera::Camera;
pub use cloud::{Cloud, CloudBuilder};
pub use correspondence::Correspondence;
pub use downsample::Downsampler;
pub use ecsad::{Descriptor, Ecsad, ECSAD_DIM};
pub use error::{Error, ErrorKind, Result};
pub use features::{FeatureExtractor, FeatureTimings};
pub use icp::{Icp, IcpResult};
pub use image::{FloatImage, GrayImage, Image};
pub use keypoints::KeypointSelector;
pub use matching::FeatureMatcher;
pub use method::Method;
pub use metrics::PoseErrors;
pub use model::{Model, ModelView, MODEL_FORMAT_VERSION};
pub use neighbours::Neighbours;
pub use normals::NormalEstimator;
pub use phase::PhaseDecoder;
pub use pipeline::{Estimator, PoseEstimate, StageTimings};
pub use ransac::{Ransac, RansacResult};
pub use reconstruct::{ReconstructTimings, Reconstruction, Reconstructor};
pub use rectified::RectifiedCamera;
pub use rectify::Rectification;
pub use rig::Rig;
pub use stereo::{DisparityMatcher, Elas};
