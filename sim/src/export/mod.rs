//! The cell as a 3D scene for tools outside camplace and for the report's 3D view: its
//! named parts in the world frame (`cell_parts.rs`) and their glTF 2.0 binary encoding
//! (`gltf.rs`). What a report draws of them is the report's business.

pub mod cell_parts;
pub mod gltf;

pub use cell_parts::{cell_parts, table_footprint, CellPart, Primitive};
pub use gltf::{glb_bytes, write_cell_glb, GlbSummary};
