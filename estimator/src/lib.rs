//! camplace's estimator: the pipeline that runs on the cell PC, from a stereo frame to the
//! tray's pose. Pure compute: it never opens a file or a device; the crate that owns a
//! format loads it and hands the estimator plain values.

pub mod camera;
pub mod correspondence;
pub mod downsample;
pub mod ecsad;
mod error;
pub mod image;
pub mod keypoints;
pub mod matching;
pub mod neighbours;
pub mod normals;
pub mod rectified;
pub mod rig;

pub use camera::Camera;
pub use correspondence::Correspondence;
pub use downsample::Downsampler;
pub use ecsad::{Descriptor, Ecsad, ECSAD_DIM};
pub use error::{Error, ErrorKind, Result};
pub use image::{FloatImage, GrayImage, Image};
pub use keypoints::KeypointSelector;
pub use matching::FeatureMatcher;
pub use neighbours::Neighbours;
pub use normals::NormalEstimator;
pub use rectified::RectifiedCamera;
pub use rig::Rig;
