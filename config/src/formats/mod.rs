//! The interchange formats of docs/design/interchange-formats.md: PNG (8-bit grey), PFM (float32),
//! PLY (point clouds, meshes), STL and OBJ (meshes). Readers check what they read and say
//! which file and which field is wrong; writers write atomically where results could be
//! lost.

mod atomic;
#[cfg(test)]
mod corruption_tests;
pub(crate) mod dataset;
pub(crate) mod dataset_read;
pub(crate) mod dataset_write;
pub(crate) mod frames;
pub(crate) mod json;
pub(crate) mod mesh;
pub(crate) mod pfm;
pub(crate) mod ply;
pub(crate) mod png;
pub(crate) mod read;
pub(crate) mod robot_poses;

pub use atomic::{
    check_output_file, is_temp_file_name, remove_stale_temp_files, temp_path_for, write_atomic, write_atomic_all,
};
