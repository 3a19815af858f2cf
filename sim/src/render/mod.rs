//! The render stage: the simulated sensor turning a scene into the frames a real one would
//! capture — rasterizing, shading, the projector's patterns and the camera noise — and the
//! frame files written from them; calibration boards, held by hand or by a robot.

mod board;
pub mod defocus;
pub mod frame_files;
mod hand_eye;
mod lens;
pub mod noise;
pub mod pattern;
pub mod raster;
pub mod render_files;
pub mod shade;
mod simulator;
mod terms;

pub use board::{render_board_views, BoardTruth};
pub use hand_eye::{
    render_hand_eye_views, simulated_robot_base, HandEyeOptions, HandEyePoses, HandEyeTruth, HAND_EYE_TRUTH_FILE,
    ROBOT_POSES_FILE,
};
pub use simulator::{Frame, Method, Simulator};

#[cfg(test)]
mod realism_tests;
