//! camplace's files: the cell file (with the paper's defaults), `rig.json`, the recorded
//! dataset (read and written), and the interchange formats of docs/design/interchange-formats.md. This crate is the leaf: it knows
//! nothing of the estimator or the simulator, only what the user writes and reads.

mod camera_checks;
mod cell;
mod cell_hash;
mod error;
mod formats;
mod grid;
mod placement;
mod pose;
mod raster;
mod rig;
mod robot_pose;
#[cfg(test)]
mod same_checks_tests;
pub mod splitmix;
#[cfg(test)]
mod test_draw;
mod text;
mod tolerance_file;
mod trial_plan;
mod truth;

pub use camera_checks::{
    check_distortion, check_focal_px, check_image_size, check_mounting, distortion_fold, DistortionFold,
    BYTES_PER_CAMERA_PIXEL, BYTES_PER_PROJECTOR_PIXEL, DISTORTION_MARGIN, MEMORY_BUDGET_BYTES, MIN_IMAGE_SIDE,
};
pub use cell::realism::{CalibrationError, Effect, Effects, Focus, Occluder, Optics, MAX_ROUGHNESS, MIN_ROUGHNESS};
pub use cell::trays::{reserved_tray_name, TrayEntry, MAX_TRAYS, STUDY_FILE_ENDINGS, STUDY_FOLDER_NAMES};
pub use cell::{
    Cell, EstimatorParams, EstimatorPreset, Items, ItemsKind, Lighting, Metrics, PhaseParams, ReconstructionParams,
    Robot, Scenarios, Sensor, StereoParams, Table, Tray, TrayKind, WorkVolume, DEFAULT_CELL_TOML, MAX_ITERATIONS,
    MAX_TEXTURE,
};
pub use cell_hash::{CellHashes, ContentHash, MeshHash};
pub use error::{Error, ErrorKind};
pub use formats::dataset::{
    frame_folders, frame_name, image_name, is_image_name, DATASET_FILES, DATASET_SUMMARY, FRAME_FILES, SCENE_CLOUD,
    SCENE_CLOUD_POINTS,
};
pub use formats::dataset_read::{read_background, truth_path, RecordedDataset};
pub use formats::dataset_write::{
    append_frame, write_background, write_shots, write_table_view, DatasetLayout, MAX_FRAME_NUMBER,
};
pub use formats::frames::{FrameInfo, Frames};
pub use formats::mesh::{decode_obj, decode_stl, load_mesh, Mesh};
pub use formats::pfm::{decode_pfm, encode_pfm, read_pfm, write_pfm};
pub use formats::ply::{decode_ply, encode_cloud, read_cloud, read_ply, thinned, write_cloud, PlyCloud, PlyData};
pub use formats::png::{decode_gray, read_gray, read_image_size, write_gray, write_rgb};
pub use formats::read::{
    open_checked, read_bounded, read_text, FileKind, MAX_DATA_BYTES, MAX_IMAGE_FILE_BYTES, MAX_IMAGE_PIXELS,
    MAX_MODEL_BYTES, MAX_TEXT_BYTES,
};
pub use formats::robot_poses::{parse_robot_poses, read_robot_poses, robot_poses_text, RobotPoses};
pub use formats::{
    check_output_file, is_temp_file_name, remove_stale_temp_files, temp_path_for, write_atomic, write_atomic_all,
};
pub use grid::{studied_names, Axis, Grid, MAX_AXIS_STEPS};
pub use placement::{Placement, PlacementParam, Vergence, MAX_DISTANCE_MM};
pub use pose::{check_rigid, ROTATION_TOLERANCE};
pub use raster::{AsImageView, FloatImage, GrayImage, Image, ImageView};
pub use rig::{CameraFile, RectifiedFile, RigFile, MAX_IMAGE_SIDE};
pub use robot_pose::{
    format_pose, format_pose_exact, parse_pose, LengthUnit, PoseConvention, RobotPoseFormat, QUATERNION_NORM_TOLERANCE,
};
pub use text::pct;
pub use tolerance_file::{
    end_text, offset_text, AxisTolerance, SideView, ToleranceCorner, TolerancePoint, ToleranceReport, WalkEnd,
};
pub use trial_plan::{
    parse_placement, placement_dir, placement_folder_name, PlannedPlacement, TrialPlan, MAX_PLACEMENTS, PLAN_CSV,
    PLAN_FILE,
};
pub use truth::{LightingTruth, TruthFile};
