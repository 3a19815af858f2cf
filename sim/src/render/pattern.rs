//! The projector's images as the renderer samples them: a pattern (the estimator's
//! `one_shot` or `fringe_set`) box-filtered, defocused and read at sub-pixel projector
//! coordinates.

use camplace_config::GrayImage;
use camplace_config::Sensor;

use crate::render::defocus::BlurStack;

/// A full white image at a sensor's projector resolution.
pub fn white(sensor: &Sensor) -> GrayImage {
    let [w, h] = sensor.projector_resolution;
    GrayImage::new(w as usize, h as usize, 255)
}

/// A projector image prepared for sampling: brightness 0..1, box-filtered over
/// `footprint` x `footprint` pixels (the projector pixels one camera pixel spans, so the
/// camera sees the pattern without aliasing), bilinear between pixel centres, black
/// outside. An image whose rows are all alike (the fringes) is kept as one row, which is
/// much cheaper to sample. With defocus, copies blurred at the stack's levels let a point
/// read the pattern as the projector's circle of confusion there spreads it.
#[derive(Debug, Clone, PartialEq)]
pub struct ProjectorImage {
    width: usize,
    height: usize,
    one_row: bool,
    /// The filtered value at index i is centred on pixel i + offset.
    offset: f32,
    /// Level 0: the filtered image (or its one row); above it, its defocused copies; level
    /// k at `k * stride`, so that one index reaches any level.
    levels: Vec<f32>,
    /// Values a level holds: `width` times the rows kept.
    stride: usize,
    /// Whether the light goes sixteen pixels a step: this machine runs AVX-512 (detected
    /// once, when the image is prepared) and every index into `levels` fits an i32.
    wide: bool,
}

impl ProjectorImage {
    /// Prepares `image` for sampling, box-filtered over `footprint` pixels (1: not at all),
    /// with defocused copies up to a blur of `max_sigma` projector pixels (0: none).
    pub fn new(image: &GrayImage, footprint: usize, max_sigma: f32) -> ProjectorImage {
        let (w, h) = (image.width, image.height);
        let b = footprint.max(1);
        let one_row = h > 0 && (1..h).all(|y| image.row(y) == image.row(0));
        let rows = if one_row { 1 } else { h };
        let rows_b = if one_row { 1 } else { b };
        let mut values = vec![0.0; w * rows];
        let scale = 1.0 / (255.0 * (b * rows_b) as f32);
        for (y, out) in values.chunks_mut(w.max(1)).enumerate() {
            for (x, o) in out.iter_mut().enumerate() {
                let mut sum = 0u32;
                for dy in 0..rows_b {
                    let row = image.row((y + dy).min(h - 1));
                    for dx in 0..b {
                        sum += row[(x + dx).min(w - 1)] as u32;
                    }
                }
                *o = sum as f32 * scale;
            }
        }
        let mut stack = BlurStack::default();
        stack.build(&values, w.max(1), max_sigma);
        let stride = values.len();
        let levels = stack.levels().concat();
        let wide =
            cfg!(target_arch = "x86_64") && camplace_estimator::avx512_available() && levels.len() <= i32::MAX as usize;
        ProjectorImage { width: w, height: h, one_row, offset: (b as f32 - 1.0) / 2.0, levels, stride, wide }
    }

    /// Level `k` of the stack.
    #[inline(always)]
    fn level(&self, k: usize) -> &[f32] {
        &self.levels[k * self.stride..(k + 1) * self.stride]
    }

    /// The stack's top level.
    fn top(&self) -> usize {
        (self.levels.len() / self.stride.max(1)).saturating_sub(1)
    }

    /// Brightness at projector pixel coordinates (u, v), pixel centres at integers.
    #[inline(always)]
    pub fn sample(&self, u: f32, v: f32) -> f32 {
        match self.taps(u, v) {
            None => 0.0,
            Some(t) => t.read(self.level(0)),
        }
    }

    /// Brightness at (u, v) where the projector's defocus blurs by the blur whose level
    /// and weight are `blur` ([`crate::render::defocus::level_weight`] with the top level of
    /// the stack, that of the largest blur the image was prepared for).
    #[inline(always)]
    pub fn sample_defocused(&self, u: f32, v: f32, blur: (u32, f32)) -> f32 {
        let Some(t) = self.taps(u, v) else { return 0.0 };
        let (k, w) = (blur.0 as usize, blur.1);
        let a = t.read(self.level(k));
        if w == 0.0 {
            a
        } else {
            a + w * (t.read(self.level(k + 1)) - a)
        }
    }

    /// The light of a run of pixels, one at a time: `out[i] = scale * base[i] + proj[i] *
    /// sample_defocused(uv[i], blur[i])` (`sample` when `blur` is empty) wherever `proj[i]`
    /// is positive, else `scale * base[i]`.
    #[inline(always)]
    pub fn add_light(&self, scale: f32, run: LightRun<'_>, out: &mut [f32]) {
        let n = out.len();
        let LightRun { base, proj, uv, blur } = run;
        let (base, proj, uv) = (&base[..n], &proj[..n], &uv[..n]);
        if blur.len() >= n {
            for x in 0..n {
                let mut g = scale * base[x];
                let p = proj[x];
                if p > 0.0 {
                    g += p * self.sample_defocused(uv[x][0], uv[x][1], blur[x]);
                }
                out[x] = g;
            }
        } else {
            for x in 0..n {
                let mut g = scale * base[x];
                let p = proj[x];
                if p > 0.0 {
                    g += p * self.sample(uv[x][0], uv[x][1]);
                }
                out[x] = g;
            }
        }
    }

    /// Hints the cache with the values that the lit pixels of `run` will read, one pixel in
    /// [`PREFETCH_EVERY`] (neighbours read the same cache lines), so that they are at hand
    /// when the run is lit: a run of the next row, prefetched while this row is lit. For a
    /// one-row image (the fringes), whose row stays in the cache, it does nothing. It
    /// changes no value.
    #[inline(always)]
    pub fn prefetch(&self, run: LightRun<'_>) {
        if self.one_row {
            return;
        }
        let LightRun { proj, uv, blur, .. } = run;
        let top = self.top();
        let n = proj.len().min(uv.len());
        for x in (0..n).step_by(PREFETCH_EVERY) {
            // Unlit pixels (gain 0) read nothing.
            let Some(t) = self.taps(uv[x][0], uv[x][1]).filter(|_| proj[x] > 0.0) else { continue };
            let k = blur.get(x).map_or(0, |b| (b.0 as usize).min(top));
            for level in k..=(k + 1).min(top) {
                for row in [t.r0, t.r1] {
                    prefetch(self.levels.as_ptr().wrapping_add(level * self.stride + row + t.x0));
                }
            }
        }
    }

    /// [`ProjectorImage::add_light`] on the first pixels of a run, sixteen at a time with
    /// AVX-512 where this machine has it, with the same bits (oracle test). Returns how many
    /// pixels it did (a multiple of sixteen, 0 without AVX-512); the caller does the rest
    /// one at a time. For an image of many rows the gathers wait on memory unless the
    /// values were asked of the cache ahead ([`ProjectorImage::prefetch`]).
    #[inline(always)]
    pub fn add_light_wide(&self, scale: f32, run: LightRun<'_>, out: &mut [f32]) -> usize {
        #[cfg(target_arch = "x86_64")]
        if self.wide {
            // SAFETY: `wide` says AVX-512 F, BW, DQ and VL were detected and the indices fit
            // an i32; the variant is the image's own.
            return unsafe {
                if self.one_row {
                    self.add_light_avx512::<true>(scale, run, out)
                } else {
                    self.add_light_avx512::<false>(scale, run, out)
                }
            };
        }
        let _ = (scale, run, out);
        0
    }

    /// [`ProjectorImage::add_light_wide`]'s vector path, made for a one-row image (the
    /// fringes: two taps a level, from a row that stays in the cache) or for one of many
    /// rows (`ONE_ROW` false: four taps a level); it does nothing for the other kind.
    ///
    /// # Safety
    ///
    /// The machine runs AVX-512 F, BW, DQ and VL, and every index into `levels` fits an i32.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,avx512f,avx512bw,avx512dq,avx512vl")]
    unsafe fn add_light_avx512<const ONE_ROW: bool>(&self, scale: f32, run: LightRun<'_>, out: &mut [f32]) -> usize {
        use std::arch::x86_64::*;
        const LANES: usize = 16;
        let LightRun { base, proj, uv, blur } = run;
        let n = out.len().min(base.len()).min(proj.len()).min(uv.len());
        let defocused = !blur.is_empty();
        let n = if defocused { n.min(blur.len()) } else { n };
        if ONE_ROW != self.one_row || self.width < 2 || self.height == 0 || self.levels.is_empty() {
            return 0;
        }
        let (w, h) = (self.width as f32, self.height as f32);
        let (scale_v, zero) = (_mm512_set1_ps(scale), _mm512_setzero_ps());
        let (low, u_end, v_end) = (_mm512_set1_ps(-0.5), _mm512_set1_ps(w - 0.5), _mm512_set1_ps(h - 0.5));
        let u_off = _mm512_set1_ps(self.offset);
        let v_off = _mm512_set1_ps(if ONE_ROW { 0.0 } else { self.offset });
        let (u_max, v_max) = (_mm512_set1_ps(w - 1.0), _mm512_set1_ps(h - 1.0));
        let x0_max = _mm512_set1_epi32(self.width.saturating_sub(2) as i32);
        let y0_max = _mm512_set1_epi32(self.height.saturating_sub(2) as i32);
        let (x_last, y_last) = (_mm512_set1_epi32(self.width as i32 - 1), _mm512_set1_epi32(self.height as i32 - 1));
        let (one, row_len) = (_mm512_set1_epi32(1), _mm512_set1_epi32(self.width as i32));
        let (top, stride) = (_mm512_set1_epi32(self.top() as i32), _mm512_set1_epi32(self.stride as i32));
        let data = self.levels.as_ptr();
        // The bilinear value at offsets `r0`/`r1` (row starts) and columns `x0`/`x1` of
        // the level starting at `at`, in lanes `m`; Taps::read's operations in its order.
        let read = |m: __mmask16, at: __m512i, r0: __m512i, r1: __m512i, x0: __m512i, x1: __m512i, fx, fy| {
            let gather = |row: __m512i, col: __m512i| {
                let index = _mm512_add_epi32(at, _mm512_add_epi32(row, col));
                // SAFETY: in lanes `m` the index lies inside `levels` (rows, columns and
                // levels clamped to the image and the stack); the others read nothing.
                unsafe { _mm512_mask_i32gather_ps::<4>(zero, m, index, data.cast()) }
            };
            let (a, b) = (gather(r0, x0), gather(r0, x1));
            let upper = _mm512_add_ps(a, _mm512_mul_ps(fx, _mm512_sub_ps(b, a)));
            if ONE_ROW {
                return upper;
            }
            let (c, d) = (gather(r1, x0), gather(r1, x1));
            let lower = _mm512_add_ps(c, _mm512_mul_ps(fx, _mm512_sub_ps(d, c)));
            _mm512_add_ps(upper, _mm512_mul_ps(fy, _mm512_sub_ps(lower, upper)))
        };
        let mut x = 0;
        while x + LANES <= n {
            let (mut us, mut vs) = ([0.0f32; LANES], [0.0f32; LANES]);
            for (j, q) in uv[x..x + LANES].iter().enumerate() {
                (us[j], vs[j]) = (q[0], q[1]);
            }
            // SAFETY: 16 values from x, inside every slice as x + 16 <= n.
            let (b, p, u, v) = unsafe {
                (
                    _mm512_loadu_ps(base.as_ptr().add(x)),
                    _mm512_loadu_ps(proj.as_ptr().add(x)),
                    _mm512_loadu_ps(us.as_ptr()),
                    _mm512_loadu_ps(vs.as_ptr()),
                )
            };
            let g = _mm512_mul_ps(scale_v, b);
            // Lit and inside the image, as `taps` decides (NaN fails every comparison).
            let mut m = _mm512_cmp_ps_mask::<_CMP_GT_OQ>(p, zero);
            m &= _mm512_cmp_ps_mask::<_CMP_GE_OQ>(u, low) & _mm512_cmp_ps_mask::<_CMP_GE_OQ>(v, low);
            m &= _mm512_cmp_ps_mask::<_CMP_LT_OQ>(u, u_end) & _mm512_cmp_ps_mask::<_CMP_LT_OQ>(v, v_end);
            if m == 0 {
                // No lane samples the pattern (the empty background of a model capture,
                // a shadow): the pattern-independent light alone.
                // SAFETY: 16 values into out[x .. x + 16], inside as x + 16 <= n.
                unsafe { _mm512_storeu_ps(out.as_mut_ptr().add(x), g) };
                x += LANES;
                continue;
            }
            // f32::clamp: below the least the least, above the most the most, else itself.
            let clamp = |a: __m512, most: __m512| _mm512_min_ps(most, _mm512_max_ps(zero, a));
            let uc = clamp(_mm512_sub_ps(u, u_off), u_max);
            let x0 = _mm512_min_epi32(_mm512_cvttps_epi32(uc), x0_max);
            let fx = _mm512_sub_ps(uc, _mm512_cvtepi32_ps(x0));
            let x1 = _mm512_min_epi32(_mm512_add_epi32(x0, one), x_last);
            let (r0, r1, fy) = if ONE_ROW {
                (_mm512_setzero_si512(), _mm512_setzero_si512(), zero)
            } else {
                let vc = clamp(_mm512_sub_ps(v, v_off), v_max);
                let y0 = _mm512_min_epi32(_mm512_cvttps_epi32(vc), y0_max);
                let fy = _mm512_sub_ps(vc, _mm512_cvtepi32_ps(y0));
                let y1 = _mm512_min_epi32(_mm512_add_epi32(y0, one), y_last);
                (_mm512_mullo_epi32(y0, row_len), _mm512_mullo_epi32(y1, row_len), fy)
            };
            let sample = if defocused {
                let (mut ks, mut ws) = ([0i32; LANES], [0.0f32; LANES]);
                for (j, &(k, wt)) in blur[x..x + LANES].iter().enumerate() {
                    (ks[j], ws[j]) = (k.min(i32::MAX as u32) as i32, wt);
                }
                // SAFETY: two 16-value local arrays.
                let (k, wt) = unsafe { (_mm512_loadu_si512(ks.as_ptr().cast()), _mm512_loadu_ps(ws.as_ptr())) };
                let k = _mm512_min_epi32(k, top);
                let above = _mm512_min_epi32(_mm512_add_epi32(k, one), top);
                let a = read(m, _mm512_mullo_epi32(k, stride), r0, r1, x0, x1, fx, fy);
                // Where the weight is 0 the level above is not read, and the value is `a`.
                let m_above = m & _mm512_cmp_ps_mask::<_CMP_NEQ_UQ>(wt, zero);
                let b = read(m_above, _mm512_mullo_epi32(above, stride), r0, r1, x0, x1, fx, fy);
                let mixed = _mm512_add_ps(a, _mm512_mul_ps(wt, _mm512_sub_ps(b, a)));
                _mm512_mask_blend_ps(m_above, a, mixed)
            } else {
                read(m, _mm512_setzero_si512(), r0, r1, x0, x1, fx, fy)
            };
            let lit = _mm512_add_ps(g, _mm512_mul_ps(p, sample));
            let value = _mm512_mask_blend_ps(m, g, lit);
            // SAFETY: 16 values into out[x .. x + 16], inside as x + 16 <= n.
            unsafe { _mm512_storeu_ps(out.as_mut_ptr().add(x), value) };
            x += LANES;
        }
        x
    }

    /// The bilinear taps of (u, v), `None` outside the image.
    #[inline(always)]
    fn taps(&self, u: f32, v: f32) -> Option<Taps> {
        let (w, h) = (self.width as f32, self.height as f32);
        if !(u >= -0.5 && v >= -0.5 && u < w - 0.5 && v < h - 0.5) {
            return None;
        }
        let (u, v) = (u - self.offset, if self.one_row { v } else { v - self.offset });
        let uc = u.clamp(0.0, w - 1.0);
        let x0 = (uc as usize).min(self.width.saturating_sub(2));
        let fx = uc - x0 as f32;
        let x1 = (x0 + 1).min(self.width - 1);
        if self.one_row {
            return Some(Taps { r0: 0, r1: 0, x0, x1, fx, fy: 0.0 });
        }
        let vc = v.clamp(0.0, h - 1.0);
        let y0 = (vc as usize).min(self.height.saturating_sub(2));
        let fy = vc - y0 as f32;
        let y1 = (y0 + 1).min(self.height - 1);
        Some(Taps { r0: y0 * self.width, r1: y1 * self.width, x0, x1, fx, fy })
    }
}

/// Pixels of a run per cache hint of [`ProjectorImage::prefetch`]: at about two projector
/// pixels a camera pixel, six pixels span most of a 64-byte line of a level's row.
const PREFETCH_EVERY: usize = 6;

/// Asks the cache for the line holding `p`; a hint, which reads nothing and cannot fault.
#[inline(always)]
fn prefetch(p: *const f32) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        // SAFETY: a prefetch is a hint: it dereferences nothing, whatever the address.
        unsafe { _mm_prefetch::<_MM_HINT_T0>(p.cast()) };
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = p;
}

/// A run of pixels' pattern-independent light and projector terms (`blur` empty without
/// the projector's defocus), as [`ProjectorImage::add_light_wide`] reads them.
#[derive(Debug, Clone, Copy)]
pub struct LightRun<'a> {
    /// The pattern-independent grey level.
    pub base: &'a [f32],
    /// The projector's gain (0 where it does not light the pixel).
    pub proj: &'a [f32],
    /// The projector image coordinates.
    pub uv: &'a [[f32; 2]],
    /// The projector's blur level and weight.
    pub blur: &'a [(u32, f32)],
}

impl<'a> LightRun<'a> {
    /// The run from pixel `k` on.
    pub fn from(self, k: usize) -> LightRun<'a> {
        self.span(k..self.base.len())
    }

    /// The pixels `span` of the run.
    pub fn span(self, span: std::ops::Range<usize>) -> LightRun<'a> {
        let blur = if self.blur.is_empty() { self.blur } else { &self.blur[span.clone()] };
        LightRun { base: &self.base[span.clone()], proj: &self.proj[span.clone()], uv: &self.uv[span], blur }
    }
}

/// Where a bilinear sample reads: two row starts, two columns and the fractions.
#[derive(Debug, Clone, Copy)]
struct Taps {
    r0: usize,
    r1: usize,
    x0: usize,
    x1: usize,
    fx: f32,
    fy: f32,
}

impl Taps {
    #[inline(always)]
    fn read(&self, values: &[f32]) -> f32 {
        let (r0, r1, x0, x1) = (self.r0, self.r1, self.x0, self.x1);
        let top = values[r0 + x0] + self.fx * (values[r0 + x1] - values[r0 + x0]);
        if r0 == r1 && self.fy == 0.0 {
            return top;
        }
        let bottom = values[r1 + x0] + self.fx * (values[r1 + x1] - values[r1 + x0]);
        top + self.fy * (bottom - top)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::defocus::LEVELS;
    use camplace_estimator::{depth::fringe, depth::random_dots};
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn sampling_is_bilinear_and_black_outside() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for img in [random_dots(50, 30, 1, 0.5, 9), fringe(50, 30, 3.0, 1)] {
            let p = ProjectorImage::new(&img, 1, 0.0);
            for _ in 0..500 {
                let u: f32 = rng.random_range(0.0..49.0);
                let v: f32 = rng.random_range(0.0..29.0);
                let (x0, y0) = (u.floor() as usize, v.floor() as usize);
                let (fx, fy) = (u - x0 as f32, v - y0 as f32);
                let g = |x: usize, y: usize| img.get(x.min(49), y.min(29)) as f32 / 255.0;
                let want = (1.0 - fy) * ((1.0 - fx) * g(x0, y0) + fx * g(x0 + 1, y0))
                    + fy * ((1.0 - fx) * g(x0, y0 + 1) + fx * g(x0 + 1, y0 + 1));
                assert!((p.sample(u, v) - want).abs() < 1e-5);
            }
            assert_eq!(p.sample(-0.6, 3.0), 0.0);
            assert_eq!(p.sample(3.0, 29.6), 0.0);
        }
    }

    #[test]
    fn filtering_averages_the_footprint() {
        // Box filter then bilinear equals the mean of bilinear samples over the box.
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        for b in [2usize, 3] {
            for img in [random_dots(60, 40, 1, 0.5, 8), fringe(60, 40, 5.0, 2)] {
                let plain = ProjectorImage::new(&img, 1, 0.0);
                let filtered = ProjectorImage::new(&img, b, 0.0);
                let off = (b as f32 - 1.0) / 2.0;
                for _ in 0..300 {
                    let u: f32 = rng.random_range(4.0..50.0);
                    let v: f32 = rng.random_range(4.0..30.0);
                    let mut want = 0.0;
                    for dy in 0..b {
                        for dx in 0..b {
                            want += plain.sample(u - off + dx as f32, v - off + dy as f32);
                        }
                    }
                    want /= (b * b) as f32;
                    assert!((filtered.sample(u, v) - want).abs() < 1e-4, "b {b} at ({u}, {v})");
                }
            }
        }
    }

    #[test]
    fn light_sixteen_at_a_time_is_the_light_one_by_one() {
        let mut rng = ChaCha8Rng::seed_from_u64(12);
        let n = 16 * 40 + 5;
        let mut ran_wide = false;
        for (img, footprint, max_sigma) in [
            (random_dots(90, 60, 2, 0.5, 3), 2, 5.0),
            (random_dots(90, 60, 1, 0.5, 4), 1, 0.0),
            (fringe(90, 60, 4.0, 1), 3, 2.5),
            (fringe(90, 60, 4.0, 3), 1, 0.0),
            (random_dots(2, 1, 1, 0.5, 5), 1, 1.0),
        ] {
            let p = ProjectorImage::new(&img, footprint, max_sigma);
            let (w, h) = (img.width as f32, img.height as f32);
            let top = p.top();
            let base: Vec<f32> = (0..n).map(|_| rng.random_range(0.0..200.0)).collect();
            // Unlit pixels (0 or less) and lit ones; coordinates inside, on and past every
            // edge, and NaN (what a buffer may hold where no projector coordinates were ever
            // stored).
            let proj: Vec<f32> = (0..n)
                .map(|i| {
                    if i % 7 == 3 {
                        0.0
                    } else if i % 11 == 5 {
                        -1.0
                    } else {
                        rng.random_range(0.0..90.0)
                    }
                })
                .collect();
            let uv: Vec<[f32; 2]> = (0..n)
                .map(|i| match i % 13 {
                    0 => [f32::NAN, 2.0],
                    1 => [-0.5, -0.5],
                    2 => [w - 0.5, 1.0],
                    3 => [w - 0.51, h - 0.51],
                    4 => [-0.6, 3.0],
                    _ => [rng.random_range(-2.0..w + 2.0), rng.random_range(-2.0..h + 2.0)],
                })
                .collect();
            let blurs: Vec<(u32, f32)> = (0..n)
                .map(|i| {
                    let sigma = if i % 5 == 0 { LEVELS[rng.random_range(0..=top)] } else { rng.random_range(0.0..8.0) };
                    let (k, wt) = crate::render::defocus::level_weight(sigma, top);
                    (k as u32, wt)
                })
                .collect();
            for blur in [&blurs[..], &[]] {
                let run = LightRun { base: &base, proj: &proj, uv: &uv, blur };
                let mut want = vec![0.0; n];
                p.add_light(1.5, run, &mut want);
                let mut got = vec![f32::NAN; n];
                let done = p.add_light_wide(1.5, run, &mut got);
                assert_eq!(done % 16, 0);
                ran_wide |= done > 0;
                p.add_light(1.5, run.from(done), &mut got[done..]);
                for i in 0..n {
                    assert_eq!(
                        got[i].to_bits(),
                        want[i].to_bits(),
                        "pixel {i} at {:?}: {} vs {}",
                        uv[i],
                        got[i],
                        want[i]
                    );
                }
            }
        }
        assert_eq!(ran_wide, camplace_estimator::avx512_available(), "the vector path runs where AVX-512 is");
    }
}
