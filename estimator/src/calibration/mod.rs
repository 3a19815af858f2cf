//! Stereo and hand-eye calibration from detected chessboard corners: the cameras' intrinsics and
//! distortion, the pose between them and the board's pose in every view, each camera started
//! by Zhang's closed form and everything refined jointly by Levenberg–Marquardt. Finding the
//! corners in an image is `corners.rs`'s; the rest takes their pixels. The installed rig in
//! the world frame is `rig_calibration.rs`'s; where the rig sits in the robot's frame is
//! `hand_eye/`'s.

mod board;
mod corners;
mod hand_eye;
mod lm;
mod refine;
mod rig_calibration;
mod stereo;
mod zhang;

pub use board::{table_board_pose, BoardView, CalibrationBoard, MIN_CALIBRATION_VIEWS};
pub use corners::find_board_corners;
pub use hand_eye::{
    calibrate_hand_eye, calibrate_hand_eye_paired, ExpectedError, HandEyeCalibration, HandEyeError, HandEyeInput,
    HandEyeSetup, PairedHandEye, PoseReading, PoseResidual, RotationSpread, MIN_HAND_EYE_POSES,
};
pub use rig_calibration::{calibrate_rig, FoundBoardPair, RigCalibration};
pub use stereo::{calibrate_stereo, StereoCalibration, ViewResidual};

#[cfg(test)]
mod tests;
