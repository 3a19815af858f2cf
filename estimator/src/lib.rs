//! camplace's estimator: the pipeline that runs on the cell PC, from a stereo frame to the
//! tray's pose. Pure compute: it never opens a file or a device; the crate that owns a
//! format loads it and hands the estimator plain values.

pub mod camera;
pub mod image;
pub mod rig;

pub use camera::Camera;
pub use image::{FloatImage, GrayImage, Image};
pub use rig::Rig;
