//! The background depth map used to remove the table and the fixed scene from each cloud:
//! built once per placement from a disparity map of the empty cell (same sensor), dilated
//! and hole-filled. Pure compute; capturing and storing it is the caller's business.
//!
//! Choices, all made in disparity space (where a plane is linear in the image, so filling
//! by linear interpolation keeps a flat table flat):
//! - **Dilation keeps the nearest surface.** Each pixel takes the largest disparity (the
//!   nearest depth) within a `(2 * background_dilation + 1)` square. A point counts as
//!   background when it is not in front of this depth by more than `background_margin`, so
//!   the nearest neighbour is the conservative choice: a one-pixel shift of a background
//!   edge or noise in the background capture then makes the scene's own background points
//!   fall behind the threshold instead of surviving as a fringe of false object points.
//!   The cost is that objects must rise above the nearest background within the window.
//! - **Holes are filled from their neighbours.** A pixel with no background measurement
//!   left after dilation (a projector shadow, a dark patch) takes the linear interpolation
//!   along its row between the nearest measured pixels either side (the one side's value
//!   at an image border); rows with no measurement at all are then filled along columns
//!   the same way. Only an all-empty map is refused.

use camplace_config::ReconstructionParams;

use crate::{Error, ErrorKind, FloatImage, RectifiedCamera, Result};

/// A dilated, hole-filled background depth map in rectified-left pixels (mm along the
/// rectified z axis).
#[derive(Debug, Clone, PartialEq)]
pub struct Background {
    depth: FloatImage,
}

impl Background {
    /// Builds the background from a rectified-left disparity map of the empty cell (+inf or
    /// non-positive where unmeasured), dilated by `params.background_dilation` pixels.
    pub fn from_disparity(
        camera: &RectifiedCamera,
        disparity: &FloatImage,
        params: &ReconstructionParams,
    ) -> Result<Self> {
        if disparity.width != camera.width || disparity.height != camera.height {
            return Err(Error::new(
                ErrorKind::Input,
                format!(
                    "background: expected a {} x {} disparity map, got {} x {}",
                    camera.width, camera.height, disparity.width, disparity.height
                ),
            ));
        }
        let (w, h) = (disparity.width, disparity.height);
        // Unmeasured pixels become 0, which every max filter ignores.
        let measured: Vec<f32> =
            disparity.data.iter().map(|&d| if d.is_finite() && d > 0.0 { d } else { 0.0 }).collect();
        if measured.iter().all(|&d| d == 0.0) {
            return Err(Error::new(ErrorKind::Input, "background: the disparity map has no valid pixel"));
        }
        let r = params.background_dilation as usize;
        let mut along_rows = vec![0.0f32; w * h];
        for y in 0..h {
            max_filter(&measured[y * w..(y + 1) * w], r, &mut along_rows[y * w..(y + 1) * w]);
        }
        let mut dilated = vec![0.0f32; w * h];
        for x in 0..w {
            max_filter_strided(&along_rows, x, w, h, r, &mut dilated);
        }
        for y in 0..h {
            fill_line(&mut dilated[y * w..(y + 1) * w], 1);
        }
        for x in 0..w {
            fill_line(&mut dilated[x..], w);
        }
        let focal_baseline = (camera.focal() * camera.baseline) as f32;
        let depth = dilated.iter().map(|&d| if d > 0.0 { focal_baseline / d } else { f32::INFINITY }).collect();
        Ok(Background { depth: FloatImage { width: w, height: h, data: depth } })
    }

    /// The dilated background depth, mm (+inf only where nothing could be filled).
    pub fn depth(&self) -> &FloatImage {
        &self.depth
    }

    /// Whether a point at pixel (x, y) and depth `z` (mm) is background: not in front of
    /// the background depth there by more than `margin` (mm).
    #[inline]
    pub fn is_background(&self, x: usize, y: usize, z: f32, margin: f32) -> bool {
        z >= self.depth.get(x, y) - margin
    }
}

/// Running maximum of `src` over `[i - r, i + r]`.
fn max_filter(src: &[f32], r: usize, dst: &mut [f32]) {
    let n = src.len();
    for (i, d) in dst.iter_mut().enumerate() {
        let lo = i.saturating_sub(r);
        let hi = (i + r + 1).min(n);
        *d = src[lo..hi].iter().copied().fold(0.0, f32::max);
    }
}

/// Running maximum along column `x` of a `w`-wide image.
fn max_filter_strided(src: &[f32], x: usize, w: usize, h: usize, r: usize, dst: &mut [f32]) {
    for y in 0..h {
        let lo = y.saturating_sub(r);
        let hi = (y + r + 1).min(h);
        dst[y * w + x] = (lo..hi).map(|yy| src[yy * w + x]).fold(0.0, f32::max);
    }
}

/// Fills the zeros of the line `line[0], line[stride], ...` by linear interpolation
/// between the measured values either side, or the one measured side at an end.
fn fill_line(line: &mut [f32], stride: usize) {
    let n = line.len().div_ceil(stride);
    let mut last: Option<usize> = None;
    let mut i = 0;
    while i < n {
        if line[i * stride] > 0.0 {
            last = Some(i);
            i += 1;
            continue;
        }
        let start = i;
        while i < n && line[i * stride] == 0.0 {
            i += 1;
        }
        let next = (i < n).then_some(i);
        match (last, next) {
            (Some(a), Some(b)) => {
                let (va, vb) = (line[a * stride], line[b * stride]);
                for j in start..b {
                    let t = (j - a) as f32 / (b - a) as f32;
                    line[j * stride] = va + t * (vb - va);
                }
            }
            (Some(a), None) => {
                let va = line[a * stride];
                for j in start..n {
                    line[j * stride] = va;
                }
            }
            (None, Some(b)) => {
                let vb = line[b * stride];
                for j in start..b {
                    line[j * stride] = vb;
                }
            }
            (None, None) => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Isometry3, Matrix3};
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn camera(w: usize, h: usize) -> RectifiedCamera {
        RectifiedCamera {
            width: w,
            height: h,
            k: Matrix3::new(500.0, 0.0, w as f64 / 2.0, 0.0, 500.0, h as f64 / 2.0, 0.0, 0.0, 1.0),
            baseline: 100.0,
            t_world_rectified: Isometry3::identity(),
        }
    }

    fn params(dilation: u32) -> ReconstructionParams {
        ReconstructionParams { background_margin: 4.0, background_dilation: dilation }
    }

    #[test]
    fn dilation_is_the_nearest_depth_in_the_window() {
        let (w, h) = (37, 23);
        let cam = camera(w, h);
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let disp: Vec<f32> = (0..w * h).map(|_| rng.random_range(40.0..90.0f32)).collect();
        let disp = FloatImage::from_vec(w, h, disp).unwrap();
        for r in [0u32, 1, 3] {
            let bg = Background::from_disparity(&cam, &disp, &params(r)).unwrap();
            let r = r as i64;
            for y in 0..h as i64 {
                for x in 0..w as i64 {
                    let mut best = 0.0f32;
                    for yy in (y - r).max(0)..=(y + r).min(h as i64 - 1) {
                        for xx in (x - r).max(0)..=(x + r).min(w as i64 - 1) {
                            best = best.max(disp.get(xx as usize, yy as usize));
                        }
                    }
                    let want = cam.depth_from_disparity(best);
                    let got = bg.depth().get(x as usize, y as usize);
                    assert!((got - want).abs() <= want * 1e-6, "({x}, {y}) r {r}: {got} vs {want}");
                }
            }
        }
    }

    #[test]
    fn holes_in_a_plane_are_filled_with_the_plane() {
        let (w, h) = (64, 48);
        let cam = camera(w, h);
        // A plane is linear in disparity: d = a x + b y + c.
        let plane = |x: usize, y: usize| 60.0 + 0.1 * x as f32 - 0.2 * y as f32;
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let mut disp = FloatImage::new(w, h, 0.0);
        for y in 0..h {
            for x in 0..w {
                disp.set(x, y, plane(x, y));
            }
        }
        // Random rectangular holes, one touching the border, and a whole empty row.
        for _ in 0..6 {
            let (x0, y0) = (rng.random_range(1..w - 10), rng.random_range(0..h - 8));
            for y in y0..y0 + rng.random_range(1..8) {
                for x in x0..x0 + rng.random_range(1..10) {
                    disp.set(x, y, f32::INFINITY);
                }
            }
        }
        for x in 0..w {
            disp.set(x, 20, f32::NAN);
        }
        for y in 0..5 {
            disp.set(w - 1, y, -1.0);
        }
        let bg = Background::from_disparity(&cam, &disp, &params(0)).unwrap();
        for y in 0..h {
            for x in 0..w {
                let want = cam.depth_from_disparity(plane(x, y));
                let got = bg.depth().get(x, y);
                // Border holes take the edge value: one pixel of slope at most.
                let tol = if x == w - 1 { cam.depth_from_disparity(plane(x, y) - 0.2) - want } else { 1e-3 * want };
                assert!((got - want).abs() <= tol + 1e-3, "({x}, {y}): {got} vs {want}");
            }
        }
    }

    #[test]
    fn refuses_an_empty_map_and_a_wrong_size() {
        let cam = camera(8, 6);
        let empty = FloatImage::new(8, 6, f32::INFINITY);
        assert!(Background::from_disparity(&cam, &empty, &params(1)).is_err());
        let small = FloatImage::new(7, 6, 50.0);
        assert!(Background::from_disparity(&cam, &small, &params(1)).is_err());
    }
}
