//! The boundary between cameras and the estimator: the `FrameSource` trait every camera and
//! recording implements, filling a stereo frame (config's `Frames`) in caller-owned buffers.

pub use camplace_config::{FrameInfo, Frames};

use crate::Result;

/// A source of stereo frames: a recording, or cameras.
pub trait FrameSource {
    /// Fills `frames` with the next frame (resizing its images if needed) and says which
    /// it was; `Ok(None)` at the end of the stream.
    fn next(&mut self, frames: &mut Frames) -> Result<Option<FrameInfo>>;

    /// Images per side in every frame of this source.
    fn shots(&self) -> usize;
}

#[cfg(any(test, feature = "v4l", feature = "dc1394"))]
pub(crate) use camplace_config::frame_name;
