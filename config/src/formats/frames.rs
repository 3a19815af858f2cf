//! A stereo frame in memory: `shots` images per side in buffers the caller owns and hands back
//! for every frame, and what its source says about it. A recorded dataset reads into it and
//! is written from it; hwio's cameras fill it too.

use crate::GrayImage;

/// One stereo frame: `shots` images per side (1 for one shot, 12 for phase-12), in
/// buffers the caller owns and hands back for every frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Frames {
    /// The left camera's shots, in pattern order.
    pub left: Vec<GrayImage>,
    /// The right camera's shots, in pattern order.
    pub right: Vec<GrayImage>,
}

impl Frames {
    /// Empty buffers for `shots` images per side; sources size them on the first frame.
    pub fn new(shots: usize) -> Self {
        Frames { left: vec![GrayImage::default(); shots], right: vec![GrayImage::default(); shots] }
    }

    /// Buffers of `shots` images per side, each `width` x `height`, zero-filled.
    pub fn with_size(shots: usize, width: usize, height: usize) -> Self {
        let image = GrayImage::new(width, height, 0);
        Frames { left: vec![image.clone(); shots], right: vec![image; shots] }
    }

    /// Images per side.
    pub fn shots(&self) -> usize {
        self.left.len()
    }

    /// Makes room for `shots` images per side, keeping the buffers already there; allocates
    /// only when the count grows.
    pub fn set_shots(&mut self, shots: usize) {
        self.left.resize_with(shots, GrayImage::default);
        self.right.resize_with(shots, GrayImage::default);
    }
}

/// What a source says about the frame it just filled.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct FrameInfo {
    /// Position in the stream, from 0.
    pub index: u64,
    /// The frame's folder name in a recording (`"0007"`); live sources number frames the
    /// same way, so a recording of them sorts.
    pub name: String,
    /// Capture time, microseconds (a recording: the left image's modification time since
    /// the Unix epoch; a camera: the driver's timestamp).
    pub timestamp_us: u64,
}
