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
    /// Per column, 1 / (2 x the box window's column count there): both components are
    /// summed, hence the 2.
    inv_cols: Vec<f32>,
}

impl DescriptorImage {
    /// Buffers for `width` x `height` images.
    pub fn new(width: usize, height: usize) -> Self {
        let n = width * height;
        let inv_cols = (0..width)
            .map(|x| 1.0 / (2 * (x.min(NORM_RADIUS) + (width - 1 - x).min(NORM_RADIUS) + 1)) as f32)
            .collect();
        DescriptorImage {
            width,
            height,
            data: vec![[NEUTRAL; LEN]; n],
            du: vec![NEUTRAL; n],
            dv: vec![NEUTRAL; n],
            gx: vec![0; n],
            gy: vec![0; n],
            row_sum: vec![0; n],
            inv_cols,
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
            let (gxr, gyr) = (&mut gxr[1..w - 1], &mut gyr[1..w - 1]);
            for (x, (ox, oy)) in gxr.iter_mut().zip(gyr.iter_mut()).enumerate() {
                // Pixel x + 1 of the row; its neighbours are x and x + 2.
                let p = |r: &[u8], i: usize| r[i] as i16;
                let gx = (p(a, x + 2) - p(a, x)) + 2 * (p(b, x + 2) - p(b, x)) + (p(c, x + 2) - p(c, x));
                let gy = (p(c, x) + 2 * p(c, x + 1) + p(c, x + 2)) - (p(a, x) + 2 * p(a, x + 1) + p(a, x + 2));
                *ox = gx;
                *oy = gy;
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
        let (row_sum, inv_cols) = (&self.row_sum, &self.inv_cols[..]);
        self.du.par_chunks_mut(w).zip(self.dv.par_chunks_mut(w)).enumerate().for_each(|(y, (du, dv))| {
            let (y0, y1) = (y.saturating_sub(NORM_RADIUS), (y + NORM_RADIUS).min(h - 1));
            let inv_rows = 1.0 / (y1 - y0 + 1) as f32;
            let (gxr, gyr) = (&gx[y * w..(y + 1) * w], &gy[y * w..(y + 1) * w]);
            // Columns in blocks, the vertical sum of each block kept on the stack.
            const BLOCK: usize = 64;
            let mut sum = [0u32; BLOCK];
            for start in (0..w).step_by(BLOCK) {
                let len = BLOCK.min(w - start);
                let sum = &mut sum[..len];
                sum.fill(0);
                for yy in y0..=y1 {
                    for (s, &r) in sum.iter_mut().zip(&row_sum[yy * w + start..yy * w + start + len]) {
                        *s += r;
                    }
                }
                let range = start..start + len;
                for ((((s, &ic), &gxv), &gyv), (ou, ov)) in sum
                    .iter()
                    .zip(&inv_cols[range.clone()])
                    .zip(&gxr[range.clone()])
                    .zip(&gyr[range.clone()])
                    .zip(du[range.clone()].iter_mut().zip(dv[range].iter_mut()))
                {
                    let mean = *s as f32 * (ic * inv_rows);
                    let scale = NORM_TARGET / mean.max(NORM_FLOOR);
                    *ou = sobel_byte(gxv as f32 * scale);
                    *ov = sobel_byte(gyv as f32 * scale);
                }
            }
        });
        let (du, dv) = (&self.du, &self.dv);
        self.data.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
            if y < BORDER || y + BORDER >= h {
                row.fill([NEUTRAL; LEN]);
                return;
            }
            row[..BORDER].fill([NEUTRAL; LEN]);
            row[w - BORDER..].fill([NEUTRAL; LEN]);
            // Rows y - 4 ..= y + 4 of both planes; a sample (dx, dy) of pixel x is
            // rows[dy + 4][x + dx].
            let du_rows: [&[u8]; 9] = std::array::from_fn(|k| &du[(y + k - 4) * w..(y + k - 3) * w]);
            let dv_rows: [&[u8]; 9] = std::array::from_fn(|k| &dv[(y + k - 4) * w..(y + k - 3) * w]);
            for (x, d) in row.iter_mut().enumerate().take(w - BORDER).skip(BORDER) {
                // 9-wide windows centred on x: constant indices below, checked once here.
                let wu: [&[u8; 9]; 9] = du_rows.map(|r| r[x - 4..x + 5].try_into().expect("9 columns"));
                let wv: [&[u8; 9]; 9] = dv_rows.map(|r| r[x - 4..x + 5].try_into().expect("9 columns"));
                let at = |win: &[&[u8; 9]; 9], (dx, dy): (isize, isize)| win[(dy + 4) as usize][(dx + 4) as usize];
                let mut out = [NEUTRAL; LEN];
                for (k, &o) in DU_PATTERN.iter().enumerate() {
                    out[k] = at(&wu, o);
                }
                for (k, &o) in DV_PATTERN.iter().enumerate() {
                    out[DU_PATTERN.len() + k] = at(&wv, o);
                }
                for (k, &o) in DU_OUTER.iter().enumerate() {
                    out[16 + k] = at(&wu, o);
                }
                for (k, &o) in DV_OUTER.iter().enumerate() {
                    out[16 + DU_OUTER.len() + k] = at(&wv, o);
                }
                *d = out;
            }
        });
    }
}

/// A normalised Sobel response scaled by 1/4 around 128, rounded half up and clamped;
/// plain float-to-int conversions, so the per-pixel loop vectorises (`round` would be a
/// library call per sample on baseline x86_64).
#[inline(always)]
fn sobel_byte(g: f32) -> u8 {
    ((g * 0.25 + (NEUTRAL as f32 + 0.5)) as i32).clamp(0, 255) as u8
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
    fn descriptors_match_a_per_pixel_definition() {
        // Every byte from its definition: Sobel at the sample, divided by the window's mean
        // magnitude (clamped to the image), on random images of awkward sizes.
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        for (w, h) in [(11, 11), (37, 19), (70, 23)] {
            let img = GrayImage::from_vec(w, h, (0..w * h).map(|_| rng.random_range(0..=255u8)).collect()).unwrap();
            let mut d = DescriptorImage::new(w, h);
            d.compute(&img);
            let px = |x: usize, y: usize| img.get(x, y) as i32;
            let sobel = |x: usize, y: usize| -> (i32, i32) {
                if x == 0 || y == 0 || x + 1 >= w || y + 1 >= h {
                    return (0, 0);
                }
                let gx = px(x + 1, y - 1) - px(x - 1, y - 1) + 2 * (px(x + 1, y) - px(x - 1, y)) + px(x + 1, y + 1)
                    - px(x - 1, y + 1);
                let gy = px(x - 1, y + 1) + 2 * px(x, y + 1) + px(x + 1, y + 1)
                    - (px(x - 1, y - 1) + 2 * px(x, y - 1) + px(x + 1, y - 1));
                (gx, gy)
            };
            let bytes = |x: usize, y: usize| -> (u8, u8) {
                let (mut sum, mut count) = (0, 0);
                for yy in y.saturating_sub(NORM_RADIUS)..=(y + NORM_RADIUS).min(h - 1) {
                    for xx in x.saturating_sub(NORM_RADIUS)..=(x + NORM_RADIUS).min(w - 1) {
                        let (gx, gy) = sobel(xx, yy);
                        sum += gx.abs() + gy.abs();
                        count += 2;
                    }
                }
                let scale = NORM_TARGET / (sum as f32 / count as f32).max(NORM_FLOOR);
                let (gx, gy) = sobel(x, y);
                (sobel_byte(gx as f32 * scale), sobel_byte(gy as f32 * scale))
            };
            let mut differ = 0;
            for y in BORDER..h - BORDER {
                for x in BORDER..w - BORDER {
                    let at = |(dx, dy): (isize, isize)| ((x as isize + dx) as usize, (y as isize + dy) as usize);
                    let mut expect = [NEUTRAL; LEN];
                    for (k, &o) in DU_PATTERN.iter().enumerate() {
                        expect[k] = bytes(at(o).0, at(o).1).0;
                    }
                    for (k, &o) in DV_PATTERN.iter().enumerate() {
                        expect[DU_PATTERN.len() + k] = bytes(at(o).0, at(o).1).1;
                    }
                    for (k, &o) in DU_OUTER.iter().enumerate() {
                        expect[16 + k] = bytes(at(o).0, at(o).1).0;
                    }
                    for (k, &o) in DV_OUTER.iter().enumerate() {
                        expect[16 + DU_OUTER.len() + k] = bytes(at(o).0, at(o).1).1;
                    }
                    // The fast path multiplies by reciprocals: a byte may round the other way.
                    let got = &d.data[y * w + x];
                    assert!(got.iter().zip(&expect).all(|(a, b)| a.abs_diff(*b) <= 1), "({x}, {y})");
                    differ += got.iter().zip(&expect).filter(|(a, b)| a != b).count();
                }
            }
            assert!(differ * 100 < (w - 2 * BORDER) * (h - 2 * BORDER) * LEN, "{differ} bytes off by one");
        }
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
