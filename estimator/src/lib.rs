//! camplace's estimator: the pipeline that runs on the cell PC, from a stereo frame to the
//! tray's pose. Pure compute: it never opens a file or a device; the crate that owns a
//! format loads it and hands the estimator plain values.

pub mod camera;
pub mod correspondence;
mod error;
pub mod icp;
pub mod image;
pub mod kabsch;
pub mod metrics;
pub mod model;
pub mod ransac;
pub mod rectified;
pub mod rig;

pub use camera::Camera;
pub use correspondence::Correspondence;
pub use error::{Error, ErrorKind, Result};
pub use icp::{Icp, IcpResult};
pub use image::{FloatImage, GrayImage, Image};
pub use metrics::PoseErrors;
pub use model::{Model, ModelView, MODEL_FORMAT_VERSION};
pub use ransac::{Ransac, RansacResult};
pub use rectified::RectifiedCamera;
pub use rig::Rig;
