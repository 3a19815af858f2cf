//! ELAS's 16-byte pixel descriptors: 3x3 Sobel responses (horizontal and vertical) of a
//! rectified image, offset to 128 and clamped to u8, sampled at a fixed pattern in a 5x5
//! window; their SAD is the matching cost. The matcher that uses them is `elas`.

use rayon::prelude::*;

use crate::image::GrayImage;

/// One pixel's descriptor.
pub type Descriptor = [u8; 16];

/// Zero response: what borders and flat areas hold.
const NEUTRAL: u8 = 128;
/// Pixels this close to the border have no full descriptor window (Sobel 1 + pattern 2).
pub const BORDER: usize = 3;

/// The sampling pattern (dx, dy): 11 horizontal-gradient samples, which carry the
/// disparity along rows, then 5 vertical-gradient ones, which tell vertical texture apart.
const DU_PATTERN: [(isize, isize); 11] =
    [(0, -2), (-2, -1), (0, -1), (2, -1), (-1, 0), (0, 0), (1, 0), (-2, 1), (0, 1), (2, 1), (0, 2)];
const DV_PATTERN: [(isize, isize); 5] = [(0, -1), (-1, 0), (0, 0), (1, 0), (0, 1)];

/// Descriptors of one image, with the Sobel planes they are sampled from.
#[derive(Debug, Clone)]
pub struct DescriptorImage {
    pub width: usize,
    pub height: usize,
    pub data: Vec<Descriptor>,
    du: Vec<u8>,
    dv: Vec<u8>,
}

impl DescriptorImage {
    /// Buffers for `width` x `height` images.
    pub fn new(width: usize, height: usize) -> Self {
        let n = width * height;
        DescriptorImage { width, height, data: vec![[NEUTRAL; 16]; n], du: vec![NEUTRAL; n], dv: vec![NEUTRAL; n] }
    }

    /// Fills the descriptors of `img` (same size as the buffers).
    pub fn compute(&mut self, img: &GrayImage) {
        let (w, h) = (self.width, self.height);
        debug_assert!(img.width == w && img.height == h);
        if w < 2 * BORDER + 1 || h < 2 * BORDER + 1 {
            self.data.iter_mut().for_each(|d| *d = [NEUTRAL; 16]);
            return;
        }
        let src = &img.data;
        self.du.par_chunks_mut(w).zip(self.dv.par_chunks_mut(w)).enumerate().for_each(|(y, (du, dv))| {
            if y == 0 || y + 1 >= h {
                du.fill(NEUTRAL);
                dv.fill(NEUTRAL);
                return;
            }
            let (a, b, c) = (&src[(y - 1) * w..y * w], &src[y * w..(y + 1) * w], &src[(y + 1) * w..(y + 2) * w]);
            du[0] = NEUTRAL;
            dv[0] = NEUTRAL;
            du[w - 1] = NEUTRAL;
            dv[w - 1] = NEUTRAL;
            for x in 1..w - 1 {
                let p = |r: &[u8], i: usize| r[i] as i32;
                let gx = (p(a, x + 1) - p(a, x - 1)) + 2 * (p(b, x + 1) - p(b, x - 1)) + (p(c, x + 1) - p(c, x - 1));
                let gy = (p(c, x - 1) + 2 * p(c, x) + p(c, x + 1)) - (p(a, x - 1) + 2 * p(a, x) + p(a, x + 1));
                du[x] = sobel_byte(gx);
                dv[x] = sobel_byte(gy);
            }
        });
        let (du, dv) = (&self.du, &self.dv);
        self.data.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
            if y < BORDER || y + BORDER >= h {
                row.fill([NEUTRAL; 16]);
                return;
            }
            for (x, d) in row.iter_mut().enumerate() {
                if x < BORDER || x + BORDER >= w {
                    *d = [NEUTRAL; 16];
                    continue;
                }
                let at = |(dx, dy): (isize, isize)| ((y as isize + dy) as usize) * w + (x as isize + dx) as usize;
                for (k, &o) in DU_PATTERN.iter().enumerate() {
                    d[k] = du[at(o)];
                }
                for (k, &o) in DV_PATTERN.iter().enumerate() {
                    d[DU_PATTERN.len() + k] = dv[at(o)];
                }
            }
        });
    }
}

/// A Sobel response scaled by 1/4 (a full 0-255 step stays within +-255) around 128.
#[inline]
fn sobel_byte(g: i32) -> u8 {
    ((g + 2).div_euclid(4) + NEUTRAL as i32).clamp(0, 255) as u8
}

/// Sum of absolute differences of two descriptors.
#[inline(always)]
pub fn sad(a: &Descriptor, b: &Descriptor) -> i32 {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_add_epi64, _mm_cvtsi128_si32, _mm_loadu_si128, _mm_sad_epu8, _mm_unpackhi_epi64};
        // SAFETY: SSE2 is part of the x86_64 baseline; the loads are unaligned 16-byte reads
        // of two 16-byte arrays.
        unsafe {
            let va = _mm_loadu_si128(a.as_ptr().cast());
            let vb = _mm_loadu_si128(b.as_ptr().cast());
            let s = _mm_sad_epu8(va, vb);
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
    sad(a, &[NEUTRAL; 16])
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
    fn descriptor_samples_sobel_of_a_ramp() {
        // A horizontal ramp of slope 2 has Sobel x response 8 * 2 = 16 -> 128 + 4 everywhere
        // inside, and no vertical response.
        let (w, h) = (20, 12);
        let img = GrayImage::from_vec(w, h, (0..w * h).map(|i| (2 * (i % w)) as u8).collect()).unwrap();
        let mut d = DescriptorImage::new(w, h);
        d.compute(&img);
        let inner = d.data[5 * w + 7];
        assert_eq!(&inner[..11], &[132; 11]);
        assert_eq!(&inner[11..], &[128; 5]);
        assert_eq!(d.data[w + 7], [128; 16], "border rows are neutral");
        assert_eq!(texture(&inner), 44);
    }
}
