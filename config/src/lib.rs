//! camplace's files: the cell file (with the paper's defaults), `rig.json`, and the
//! interchange formats of docs/architecture.md §3. This crate is the leaf: it knows
//! nothing of the estimator or the simulator, only what the user writes and reads.

pub mod cell;
mod error;
pub mod formats;
pub mod placement;
pub mod pose;
mod raster;
pub mod rig;
pub mod truth;

pub use cell::{
    Cell, EstimatorParams, Items, ItemsKind, Lighting, Metrics, PhaseParams, ReconstructionParams, Scenarios, Sensor,
    StereoParams, Table, Tray, TrayKind, WorkVolume,
};
pub use error::{Error, ErrorKind};
pub use placement::{Placement, Vergence};
pub use raster::{FloatImage, GrayImage, Image};
pub use rig::{CameraFile, RectifiedFile, RigFile};
pub use truth::{LightingTruth, TruthFile};
