//! camplace's estimator: the pipeline that runs on the cell PC, from a stereo frame to the
//! tray's pose. Pure compute: it opens no device, and no file but a model file (read
//! through camplace-config's bounded reader by `Model::load`, so an embedder needs nothing
//! else); the crate that owns any other format loads it and hands the estimator plain
//! values. Frames arrive as borrowed `ImageView`s (or owned images), settings as an
//! `EstimatorConfig`.
//!
//! The stages live in folders by pipeline step: `depth` (rectification, stereo or phase
//! decoding, background, world cloud), `features` (down-sampling, normals, key points,
//! descriptors, matching), `pose` (model, RANSAC, ICP, metrics) and `spatial` (the point
//! indexes the stages share). `calibration` runs before any of them, once per rig: it turns
//! detected chessboard corners into the cameras. Every public item is re-exported here, at
//! one path.

#[macro_use]
mod cpu;

mod as_built;
mod calibration;
mod camera;
mod depth;
mod error;
mod estimator_config;
mod features;
mod method;
mod mounting_check;
mod pipeline;
mod placement_rig;
mod pose;
mod rig;
mod scoring;
mod spatial;

pub use as_built::{as_built, azimuth_difference, AsBuilt};
pub use calibration::{
    calibrate_hand_eye, calibrate_hand_eye_paired, calibrate_rig, calibrate_stereo, find_board_corners,
    table_board_pose, BoardView, CalibrationBoard, ExpectedError, FoundBoardPair, HandEyeCalibration, HandEyeError,
    HandEyeInput, HandEyeSetup, PairedHandEye, PoseReading, PoseResidual, RigCalibration, RotationSpread,
    StereoCalibration, ViewResidual, MIN_CALIBRATION_VIEWS, MIN_HAND_EYE_POSES,
};
pub use camera::{isometry_from_matrix, isometry_from_rows, isometry_to_rows, Camera};
pub use depth::{
    fringe, fringe_set, one_shot, random_dots, Background, Cloud, CloudBuilder, DisparityMatcher, Elas, PhaseDecoder,
    ReconstructTimings, Reconstruction, Reconstructor, Rectification, RectifiedCamera, PHASE_STEPS,
};
pub use error::{Error, ErrorKind, Result};
pub use estimator_config::EstimatorConfig;
pub use features::{
    is_valid_normal, quantise, Correspondence, Descriptor, Downsampler, Ecsad, FeatureExtractor, FeatureMatcher,
    FeatureTimings, KeypointSelector, NormalEstimator, ECSAD_DIM, MIN_NORMAL_NEIGHBOURS, QUANTISATION_STEPS,
};
pub use method::{method_for, Method};
pub use mounting_check::{mounting_check, MountingCheck, MountingLimit, MountingVerdict, ParamCheck};
pub use pipeline::{Estimator, PoseEstimate, StageTimings};
pub use placement_rig::{camera_k, look_at, rig_for, rig_pose, sensor_rig};
pub use pose::{
    correct_matches, pose_errors, Icp, IcpResult, Model, ModelOrigin, ModelVerification, ModelView, PoseErrors, Ransac,
    RansacCheck, RansacResult, Verdict, Verification, Verifier, AMBIGUOUS_TURN_SIGMAS, MODEL_FORMAT_VERSION,
    RESTING_HEIGHT_MM, RESTING_TILT_DEG,
};
pub use pose::{
    slot_letters, SlotJudge, SlotLayout, SlotReading, SlotState, EDGE_CELL, FLOOR_TOLERANCE_MM, MAX_FOOTPRINT_CELLS,
    MAX_MISMATCH_SHARE, MIN_SEEN_SHARE,
};
pub use rig::Rig;
pub use scoring::{
    choose_threshold, clopper_pearson_upper, median, pct, precision_recall, score, wilson_interval, FrameRecord, Score,
    Scored, SlotRecord, SlotScore, SlotSummary, Summary, Timings, VerifiedSummary,
};
// The image buffers are camplace-config's (image files hold them too); callers name them
// there, the stages here as `crate::GrayImage`.
use camplace_config::{FloatImage, GrayImage};
// Frames reach the estimator as owned images or borrowed views of the caller's pixels.
pub use camplace_config::{AsImageView, ImageView};
pub use spatial::Neighbours;

#[cfg(any(test, feature = "testing"))]
pub mod testing;

/// Instruction-set checks the [`multiversion!`] expansions in other crates call.
#[doc(hidden)]
pub use cpu::{avx2_available, avx512_available};
