//! ELAS-style pixel descriptors, widened to 32 bytes: 3x3 Sobel responses (horizontal and
//! vertical) of a rectified image, contrast-normalised, offset to 128 and clamped to u8,
//! sampled at a fixed pattern (ELAS's 5x5 plus a sparse 9x9 ring); their SAD is the
//! matching cost. The matcher that uses them is `elas`.
//!
//! Contrast normalisation: the projected dots on dark items (albedo ~0.08) give Sobel
//! responses a few times weaker than on the bright tray, which a fixed byte scale quantises
//! to a few levels and which the plane prior then overrules. Each response is divided by
//! the local mean gradient magnitude (a box window), floored near the sensor noise so flat
//! or shadowed areas are not blown up into confident-looking noise.

use rayon::prelude::*;

use crate::image::GrayImage;

/// One pixel's descriptor.
pub type Descriptor = [u8; LEN];
/// Bytes per descriptor.
pub const LEN: usize = 32;

/// Zero response: what borders and flat areas hold.
const NEUTRAL: u8 = 128;
/// Pixels this close to the border have no full descriptor window (Sobel 1 + pattern 4).
pub const BORDER: usize = 5;

/// The sampling pattern (dx, dy): 11 horizontal-gradient samples, which carry the
/// disparity along rows, then 5 vertical-gradient ones, which tell vertical texture apart.
const DU_PATTERN: [(isize, isize); 11] =
    [(0, -2), (-2, -1), (0, -1), (2, -1), (-1, 0), (0, 0), (1, 0), (-2, 1), (0, 1), (2, 1), (0, 2)];
const DV_PATTERN: [(isize, isize); 5] = [(0, -1), (-1, 0), (0, 0), (1, 0), (0, 1)];
/// A sparse outer ring out to 4 px: ELAS's 5x5 window alone averages too little noise on
/// dark items, where the dots are a few grey levels; a second 16 bytes doubles the cost of
/// a SAD but widens the support to 9x9.
const DU_OUTER: [(isize, isize); 12] =
    [(-4, 0), (4, 0), (0, -4), (0, 4), (-3, -3), (3, -3), (-3, 3), (3, 3), (-4, -2), (4, -2), (-4, 2), (4, 2)];
const DV_OUTER: [(isize, isize); 4] = [(0, -3), (-3, 0), (3, 0), (0, 3)];

/// Half side of the box window whose mean gradient magnitude normalises the responses, px.
const NORM_RADIUS: usize = 4;
/// Mean |Sobel| (raw, per component) the normalisation maps every textured area to, in
/// descriptor units times 4: a bright random-dot area keeps roughly its old amplitude.
const NORM_TARGET: f32 = 64.0;
/// Local mean |Sobel| below which responses are no longer amplified: a few times the
/// response of the simulated sensor noise (std ~2 grey levels after its 3x3 mean).
const NORM_FLOOR: f32 = 12.0;

/// Descriptors of one image, with the Sobel planes they are sampled from.
#[derive(Debug, Clone)]
pub struct DescriptorImage {
    pub width: usize,
    pub height: usize,
    pub data: Vec<Descriptor>,
    du: Vec<u8>,
    dv: Vec<u8>,
    /// Raw Sobel responses (x, y) per pixel.
    gx: Vec<i16>,
    gy: Vec<i16>,
    /// Row-wise box sums of |gx| + |gy|.
    row_sum: Vec<u32>,
}

impl DescriptorImage {
    /// Buffers for `width` x `height` images.
    pub fn new(width: usize, height: usize) -> Self {
        let n = width * height;
        DescriptorImage {
            width,
            height,
            data: vec![[NEUTRAL; LEN]; n],
            du: vec![NEUTRAL; n],
            dv: vec![NEUTRAL; n],
            gx: vec![0; n],
            gy: vec![0; n],
            row_sum: vec![0; n],
        }
    }

    /// Fills the descriptors of `img` (same size as the buffers).
    pub fn compute(&mut self, img: &GrayImage) {
        let (w, h) = (self.width, self.height);
        debug_assert!(img.width == w && img.height == h);
        if w < 2 * BORDER + 1 || h < 2 * BORDER + 1 {
            self.data.iter_mut().for_each(|d| *d = [NEUTRAL; LEN]);
            return;
        }
        let src = &img.data;
        self.gx.par_chunks_mut(w).zip(self.gy.par_chunks_mut(w)).enumerate().for_each(|(y, (gxr, gyr))| {
            gxr.fill(0);
            gyr.fill(0);
            if y == 0 || y + 1 >= h {
                return;
            }
            let (a, b, c) = (&src[(y - 1) * w..y * w], &src[y * w..(y + 1) * w], &src[(y + 1) * w..(y + 2) * w]);
            for x in 1..w - 1 {
                let p = |r: &[u8], i: usize| r[i] as i32;
                let gx = (p(a, x + 1) - p(a, x - 1)) + 2 * (p(b, x + 1) - p(b, x - 1)) + (p(c, x + 1) - p(c, x - 1));
                let gy = (p(c, x - 1) + 2 * p(c, x) + p(c, x + 1)) - (p(a, x - 1) + 2 * p(a, x) + p(a, x + 1));
                gxr[x] = gx as i16;
                gyr[x] = gy as i16;
            }
        });
        let (gx, gy) = (&self.gx, &self.gy);
        self.row_sum.par_chunks_mut(w).enumerate().for_each(|(y, out)| {
            let (gxr, gyr) = (&gx[y * w..(y + 1) * w], &gy[y * w..(y + 1) * w]);
            let mag = |x: usize| gxr[x].unsigned_abs() as u32 + gyr[x].unsigned_abs() as u32;
            // A running window sum, clamped at the borders (the count is divided out later).
            let mut acc: u32 = (0..=NORM_RADIUS.min(w - 1)).map(mag).sum();
            for (x, o) in out.iter_mut().enumerate() {
                *o = acc;
                if x + NORM_RADIUS + 1 < w {
                    acc += mag(x + NORM_RADIUS + 1);
                }
                if x >= NORM_RADIUS {
                    acc -= mag(x - NORM_RADIUS);
                }
            }
        });
        let row_sum = &self.row_sum;
        self.du.par_chunks_mut(w).zip(self.dv.par_chunks_mut(w)).enumerate().for_each(|(y, (du, dv))| {
            let (y0, y1) = (y.saturating_sub(NORM_RADIUS), (y + NORM_RADIUS).min(h - 1));
            let rows = (y1 - y0 + 1) as f32;
            for x in 0..w {
                let cols = (x.min(NORM_RADIUS) + (w - 1 - x).min(NORM_RADIUS) + 1) as f32;
                let mut sum = 0u32;
                for yy in y0..=y1 {
                    sum += row_sum[yy * w + x];
                }
                // Both components are summed, hence the 2.
                let mean = sum as f32 / (2.0 * rows * cols);
                let scale = NORM_TARGET / mean.max(NORM_FLOOR);
                du[x] = sobel_byte(gx[y * w + x] as f32 * scale);
                dv[x] = sobel_byte(gy[y * w + x] as f32 * scale);
            }
        });
        let (du, dv) = (&self.du, &self.dv);
        self.data.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
            if y < BORDER || y + BORDER >= h {
                row.fill([NEUTRAL; LEN]);
                return;
            }
            for (x, d) in row.iter_mut().enumerate() {
                if x < BORDER || x + BORDER >= w {
                    *d = [NEUTRAL; LEN];
                    continue;
                }
                let at = |(dx, dy): (isize, isize)| ((y as isize + dy) as usize) * w + (x as isize + dx) as usize;
                for (k, &o) in DU_PATTERN.iter().enumerate() {
                    d[k] = du[at(o)];
                }
                for (k, &o) in DV_PATTERN.iter().enumerate() {
                    d[DU_PATTERN.len() + k] = dv[at(o)];
                }
                for (k, &o) in DU_OUTER.iter().enumerate() {
                    d[16 + k] = du[at(o)];
                }
                for (k, &o) in DV_OUTER.iter().enumerate() {
                    d[16 + DU_OUTER.len() + k] = dv[at(o)];
                }
            }
        });
    }
}

/// A normalised Sobel response scaled by 1/4 around 128.
#[inline]
fn sobel_byte(g: f32) -> u8 {
    (g * 0.25 + NEUTRAL as f32).round().clamp(0.0, 255.0) as u8
}

/// Sum of absolute differences of two descriptors.
#[inline(always)]
pub fn sad(a: &Descriptor, b: &Descriptor) -> i32 {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_add_epi64, _mm_cvtsi128_si32, _mm_loadu_si128, _mm_sad_epu8, _mm_unpackhi_epi64};
        // SAFETY: SSE2 is part of the x86_64 baseline; the loads are unaligned 16-byte reads
        // at offsets 0 and 16 of two 32-byte arrays.
        unsafe {
            let s0 = _mm_sad_epu8(_mm_loadu_si128(a.as_ptr().cast()), _mm_loadu_si128(b.as_ptr().cast()));
            let s1 =
                _mm_sad_epu8(_mm_loadu_si128(a.as_ptr().add(16).cast()), _mm_loadu_si128(b.as_ptr().add(16).cast()));
            let s = _mm_add_epi64(s0, s1);
            _mm_cvtsi128_si32(_mm_add_epi64(s, _mm_unpackhi_epi64(s, s)))
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        a.iter().zip(b).map(|(&x, &y)| x.abs_diff(y) as i32).sum()
    }
}

/// Texture of a descriptor: the summed Sobel magnitude of its samples.
#[inline(always)]
pub fn texture(a: &Descriptor) -> i32 {
    sad(a, &[NEUTRAL; LEN])
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn sad_matches_plain_loop() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for _ in 0..1000 {
            let a: Descriptor = std::array::from_fn(|_| rng.random());
            let b: Descriptor = std::array::from_fn(|_| rng.random());
            let slow: i32 = a.iter().zip(&b).map(|(&x, &y)| (x as i32 - y as i32).abs()).sum();
            assert_eq!(sad(&a, &b), slow);
        }
    }

    #[test]
    fn descriptor_samples_normalised_sobel_of_a_ramp() {
        // A horizontal ramp of slope 2 has Sobel x response 8 * 2 = 16 everywhere inside and
        // no vertical response; its mean magnitude (16 + 0) / 2 sits below the floor.
        let (w, h) = (20, 12);
        let img = GrayImage::from_vec(w, h, (0..w * h).map(|i| (2 * (i % w)) as u8).collect()).unwrap();
        let mut d = DescriptorImage::new(w, h);
        d.compute(&img);
        let inner = d.data[5 * w + 9];
        let expect = sobel_byte(16.0 * NORM_TARGET / 8.0f32.max(NORM_FLOOR));
        assert_eq!(&inner[..11], &[expect; 11]);
        assert_eq!(&inner[11..16], &[128; 5]);
        assert_eq!(&inner[16..28], &[expect; 12]);
        assert_eq!(&inner[28..], &[128; 4]);
        assert_eq!(d.data[w + 7], [128; LEN], "border rows are neutral");
        assert_eq!(texture(&inner), 23 * (expect as i32 - 128));
    }

    #[test]
    fn descriptors_do_not_depend_on_contrast() {
        // A random texture and a copy at a quarter of its contrast (a dark surface under the
        // same pattern) must give nearly the same descriptors wherever the texture is above
        // the noise floor, unlike a fixed byte scale.
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let (w, h) = (48, 32);
        let coarse: Vec<f32> = (0..(w / 2) * (h / 2)).map(|_| rng.random_range(0.0..200.0)).collect();
        let bright: Vec<f32> = (0..w * h).map(|i| coarse[(i / w / 2) * (w / 2) + (i % w) / 2]).collect();
        let to_img = |scale: f32, off: f32| {
            GrayImage::from_vec(w, h, bright.iter().map(|&v| (off + scale * v).round() as u8).collect()).unwrap()
        };
        let (mut a, mut b) = (DescriptorImage::new(w, h), DescriptorImage::new(w, h));
        a.compute(&to_img(1.0, 20.0));
        b.compute(&to_img(0.25, 10.0));
        let mut worst = 0;
        for y in BORDER + NORM_RADIUS..h - BORDER - NORM_RADIUS {
            for x in BORDER + NORM_RADIUS..w - BORDER - NORM_RADIUS {
                let (da, db) = (&a.data[y * w + x], &b.data[y * w + x]);
                assert!(texture(da) > 48, "the test texture is strong");
                worst = worst.max(sad(da, db));
            }
        }
        // Rounding the quarter-contrast image to integers is the only difference.
        assert!(worst < LEN as i32 * 12, "descriptor SAD between contrasts {worst}");
    }
}
