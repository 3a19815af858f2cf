//! Where the tray can be: the box of the rectified left image that differs from the empty
//! cell's, so that the one-shot matcher computes depth there only.
//!
//! The image is cut into blocks of [`BLOCK`] px; a block's difference is the mean absolute
//! grey-level difference between the frame and the background capture over its pixels. With
//! the projector's pattern on every surface, anything standing in the cell moves the
//! pattern's dots and so changes its blocks by tens of grey levels, while camera noise
//! changes them by a few. The noise floor is read from the frame itself (a low quantile of
//! all blocks' differences, so a global change of light raises it everywhere), and a block is
//! foreground when its difference clearly exceeds it. A foreground block with no foreground
//! neighbour is noise. The region is the box around the rest, grown by [`GROW`] px so that
//! descriptor windows and support points at the tray's edge see the table beside it.
//!
//! The region only ever saves work: where it is wrong the error is a larger box (a shifted
//! camera or a change of light makes every block foreground, and the whole image is matched).
//! What it must never do is cut the tray: tested on rendered scenes against their truth.

use crate::GrayImage;

/// Side of a block, px.
const BLOCK: usize = 8;
/// A block whose pattern correlates with the background's below this has changed.
const MIN_CORRELATION: f32 = 0.6;
/// Grey-level variance below which a block holds no pattern to correlate (a shadow, a dark
/// item, the black beyond the rectified view): a block unchanged when neither side reaches
/// it.
const MIN_VARIANCE: f32 = 12.0;
/// How far the box around the foreground blocks is grown on each side, px: two support-grid
/// steps and a descriptor window.
const GROW: usize = 24;

/// A box of pixels, columns `x0 .. x1` and rows `y0 .. y1`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PixelRegion {
    pub x0: usize,
    pub x1: usize,
    pub y0: usize,
    pub y1: usize,
}

impl PixelRegion {
    /// Every pixel of a `width` x `height` image.
    pub fn whole(width: usize, height: usize) -> PixelRegion {
        PixelRegion { x0: 0, x1: width, y0: 0, y1: height }
    }

    /// No pixel at all.
    pub fn none() -> PixelRegion {
        PixelRegion { x0: 0, x1: 0, y0: 0, y1: 0 }
    }

    /// Whether pixel (x, y) lies in the box.
    pub fn contains(&self, x: usize, y: usize) -> bool {
        (self.x0..self.x1).contains(&x) && (self.y0..self.y1).contains(&y)
    }

    /// Pixels in the box.
    pub fn area(&self) -> usize {
        self.x1.saturating_sub(self.x0) * self.y1.saturating_sub(self.y0)
    }
}

/// Finds the foreground box of frames against one background capture, with its buffers.
#[derive(Debug, Clone)]
pub struct Foreground {
    background: GrayImage,
    cols: usize,
    rows: usize,
    /// Whether each block changed.
    changed: Vec<bool>,
}

impl Foreground {
    /// The finder for frames of the size of `background` (the rectified left image of the
    /// empty cell).
    pub fn new(background: GrayImage) -> Foreground {
        let (cols, rows) = (background.width / BLOCK, background.height / BLOCK);
        Foreground { background, cols, rows, changed: vec![false; cols * rows] }
    }

    /// The box of `frame` (the rectified left image, the background's size) that differs from
    /// the background: the whole image when the sizes differ or the image is too small to
    /// judge; no pixel when nothing differs.
    pub fn region(&mut self, frame: &GrayImage) -> PixelRegion {
        let (w, h) = (frame.width, frame.height);
        if !frame.same_size(&self.background) || self.cols < 3 || self.rows < 3 {
            return PixelRegion::whole(w, h);
        }
        self.compare_blocks(frame);
        let (cols, rows) = (self.cols, self.rows);
        let on = |c: usize, r: usize| self.changed[r * cols + c];
        let (mut c0, mut c1, mut r0, mut r1) = (usize::MAX, 0, usize::MAX, 0);
        for r in 0..rows {
            for c in 0..cols {
                if !on(c, r) {
                    continue;
                }
                let neighbour = (r.saturating_sub(1)..(r + 2).min(rows))
                    .any(|rr| (c.saturating_sub(1)..(c + 2).min(cols)).any(|cc| (rr, cc) != (r, c) && on(cc, rr)));
                if neighbour {
                    (c0, c1, r0, r1) = (c0.min(c), c1.max(c + 1), r0.min(r), r1.max(r + 1));
                }
            }
        }
        if c0 == usize::MAX {
            return PixelRegion::none();
        }
        // The last partial block column and row belong to the box when it reaches them.
        let x1 = if c1 == cols { w } else { (c1 * BLOCK + GROW).min(w) };
        let y1 = if r1 == rows { h } else { (r1 * BLOCK + GROW).min(h) };
        PixelRegion { x0: (c0 * BLOCK).saturating_sub(GROW), x1, y0: (r0 * BLOCK).saturating_sub(GROW), y1 }
    }

    /// Marks each block whose pattern differs from the background's: correlated below
    /// [`MIN_CORRELATION`] (a pattern on one side only correlates near zero). The correlation ignores a change of
    /// the light's gain and offset over the block (the lamp and the ambient light of each
    /// frame are not the background's).
    fn compare_blocks(&mut self, frame: &GrayImage) {
        let w = frame.width;
        let n = (BLOCK * BLOCK) as f32;
        for r in 0..self.rows {
            for c in 0..self.cols {
                let (mut sa, mut sb, mut saa, mut sbb, mut sab) = (0u32, 0u32, 0u32, 0u32, 0u32);
                for y in r * BLOCK..(r + 1) * BLOCK {
                    let at = y * w + c * BLOCK;
                    for (&a, &b) in frame.data[at..at + BLOCK].iter().zip(&self.background.data[at..at + BLOCK]) {
                        let (a, b) = (u32::from(a), u32::from(b));
                        sa += a;
                        sb += b;
                        saa += a * a;
                        sbb += b * b;
                        sab += a * b;
                    }
                }
                let (ma, mb) = (sa as f32 / n, sb as f32 / n);
                let va = (saa as f32 / n - ma * ma).max(0.0);
                let vb = (sbb as f32 / n - mb * mb).max(0.0);
                let cov = sab as f32 / n - ma * mb;
                // Without a pattern on either side there is nothing to compare; a pattern on one
                // side only correlates with the other's noise near zero.
                let changed = va.max(vb) >= MIN_VARIANCE && cov < MIN_CORRELATION * (va * vb).sqrt();
                self.changed[r * self.cols + c] = changed;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A pattern of pseudo-random dots with a little noise.
    fn dots(w: usize, h: usize, seed: u32, shift: impl Fn(usize, usize) -> usize) -> GrayImage {
        let mut img = GrayImage::new(w, h, 0);
        for y in 0..h {
            for x in 0..w {
                let sx = x + shift(x, y);
                let hash = (sx as u32).wrapping_mul(2_654_435_761) ^ (y as u32).wrapping_mul(40_503);
                let noise = (x as u32 * 31 + y as u32 * 17 + seed).wrapping_mul(2_246_822_519) >> 30;
                img.data[y * w + x] = if hash.is_multiple_of(7) { 200 } else { 40 } + noise as u8;
            }
        }
        img
    }

    #[test]
    fn the_box_holds_the_changed_patch_and_little_else() {
        let (w, h) = (320, 240);
        let background = dots(w, h, 1, |_, _| 0);
        let inside = |x: usize, y: usize| (100..180).contains(&x) && (60..140).contains(&y);
        let frame = dots(w, h, 2, |x, y| if inside(x, y) { 3 } else { 0 });
        let region = Foreground::new(background).region(&frame);
        for y in 0..h {
            for x in 0..w {
                if inside(x, y) {
                    assert!(region.contains(x, y), "({x}, {y}) cut by {region:?}");
                }
            }
        }
        assert!(region.area() <= (80 + 2 * GROW + 2 * BLOCK) * (80 + 2 * GROW + 2 * BLOCK), "{region:?}");
    }

    #[test]
    fn an_unchanged_frame_has_no_region_and_a_moved_camera_the_whole_image() {
        let (w, h) = (160, 120);
        let background = dots(w, h, 1, |_, _| 0);
        assert_eq!(Foreground::new(background.clone()).region(&dots(w, h, 5, |_, _| 0)), PixelRegion::none());
        // Everything shifted.
        let moved = dots(w, h, 5, |_, _| 2);
        assert_eq!(Foreground::new(background.clone()).region(&moved), PixelRegion::whole(w, h));
        // Another size is never judged.
        assert_eq!(Foreground::new(background).region(&GrayImage::new(80, 60, 0)), PixelRegion::whole(80, 60));
    }
}
