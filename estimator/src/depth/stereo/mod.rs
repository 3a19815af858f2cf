//! Dense stereo on rectified image pairs: the matcher trait the pipeline calls and the
//! one-shot ELAS-class matcher behind it. Rectification itself lives in `rectify`.

mod cost;
mod dense;
mod descriptor;
mod elas;
mod postprocess;
mod subpixel;
mod support;
mod triangulation;

#[cfg(test)]
mod tests;

pub use elas::Elas;

use crate::error::Result;
use crate::{FloatImage, GrayImage};

/// Computes a disparity image from a rectified pair.
pub trait DisparityMatcher {
    /// Fills `out` (resized to the left image) with disparities in rectified-left pixels,
    /// d = x_left - x_right, searched within `range` (px); +inf where no match is trusted.
    fn compute(&mut self, left: &GrayImage, right: &GrayImage, range: (f32, f32), out: &mut FloatImage) -> Result<()>;
}
