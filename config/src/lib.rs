//! camplace's files: the cell file (with the paper's defaults), `rig.json`, and the
//! interchange formats of docs/architecture.md §3. This crate is the leaf: it knows
//! nothing of the estimator or the simulator, only what the user writes and reads.

mod cell;
mod cell_hash;
mod error;
mod formats;
mod placement;
mod pose;
mod raster;
mod realism;
mod rig;
mod robot_pose;
mod trays;
mod truth;

pub use cell::{
    Cell, EstimatorParams, EstimatorPreset, Items, ItemsKind, Lighting, Metrics, PhaseParams, ReconstructionParams,
    Robot, Scenarios, Sensor, StereoParams, Table, Tray, TrayKind, WorkVolume, DEFAULT_CELL_TOML, MAX_ITERATIONS,
    MAX_TEXTURE,
};
pub use cell_hash::{CellHashes, ContentHash, MeshHash};
pub use error::{Error, ErrorKind};
pub use formats::dataset::{frame_name, image_name, is_image_name, DATASET_FILES, FRAME_FILES};
pub use formats::mesh::{decode_obj, decode_stl, load_mesh, Mesh};
pub use formats::pfm::{decode_pfm, encode_pfm, read_pfm, write_pfm};
pub use formats::ply::{decode_ply, encode_cloud, read_cloud, read_ply, write_cloud, PlyCloud, PlyData};
pub use formats::png::{read_gray, write_gray, write_rgb, Gray};
pub use formats::robot_poses::{parse_robot_poses, read_robot_poses, robot_poses_text, RobotPoses};
pub use formats::{is_temp_file_name, remove_stale_temp_files, write_atomic};
pub use placement::{Placement, Vergence, MAX_DISTANCE_MM, PARAMETERS};
pub use pose::{check_rigid, ROTATION_TOLERANCE};
pub use raster::{FloatImage, GrayImage, Image};
pub use realism::{CalibrationError, Effect, Effects, Focus, Occluder, Optics, MAX_ROUGHNESS, MIN_ROUGHNESS};
pub use rig::{CameraFile, RectifiedFile, RigFile, MAX_IMAGE_SIDE};
pub use robot_pose::{format_pose, parse_pose, LengthUnit, PoseConvention, RobotPoseFormat, QUATERNION_NORM_TOLERANCE};
pub use trays::{TrayEntry, MAX_TRAYS};
pub use truth::{LightingTruth, TruthFile};
