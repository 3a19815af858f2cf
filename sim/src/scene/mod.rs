//! The scene stage: what stands in front of the sensor (the scene and its triangles), the
//! trays and items, the scenarios a study draws, and how a rig is mounted wrong (the rig of a placement is the estimator's `rig_for`).

pub mod rig_error;
pub mod scenario;
mod spec;
pub mod tray;

pub use spec::{Gloss, Objects, OccluderBox, SceneSpec, SceneTriangle, ID_FIRST_ITEM, ID_OCCLUDER, ID_TABLE, ID_TRAY};
