//! Thin-lens defocus: how wide a point off the focus distance spreads, and the blur that
//! spreads it.
//!
//! A thin lens of focal length f and aperture diameter A = f / N focused at distance s
//! images a point at distance z (both along the optical axis) as a disc, the circle of
//! confusion, of diameter c = A f |z - s| / (z (s - f)) on the sensor, or
//! c_px = A fx |z - s| / (z (s - f)) pixels for a focal length of fx pixels. The renderer
//! blurs with the Gaussian of the disc's variance: a uniform disc of diameter c has a
//! standard deviation of c / 4 along any axis, so σ = c / 4 and the blur's second moment
//! is the disc's exactly, while its smooth tails keep the blurred dots free of ringing.
//!
//! A blur that changes from pixel to pixel is drawn from a stack of images blurred at fixed
//! σ levels: a pixel of blur σ between levels σ_k and σ_{k+1} mixes them with the weight
//! that makes the mixture's variance σ², (σ² - σ_k²) / (σ_{k+1}² - σ_k²). Each level's
//! kernel is a sampled Gaussian whose width is tuned until its discrete variance is the
//! level's, so the variances add exactly as levels build on each other.
//!
//! The camera's blur gathers: a pixel is blurred by its own depth's circle, which is the
//! scatter of real defocus wherever the depth is smooth and differs from it only in a
//! strip one circle wide along depth edges.

use std::sync::LazyLock;

use rayon::prelude::*;

use crate::render::noise::read_out;

/// The blur levels of a stack, σ in pixels; beyond the last, a blur is clamped to it. Halves
/// up to 2, then 2^e and 1.5 2^e: [`level_weight`] reads a level from the bits of σ.
pub const LEVELS: [f32; 13] = [0.0, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0, 12.0, 16.0, 24.0, 32.0];

/// Rows per task of parallel work.
const ROWS_PER_TASK: usize = 16;

/// A thin lens in a camera or projector of known focal length in pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ThinLens {
    /// A fx / (s - f): the circle of confusion far away, pixels.
    far_circle: f64,
    /// The focus distance s, mm.
    focus: f64,
}

impl ThinLens {
    /// A lens of `focal_length` mm at `f_number`, focused at `focus` mm (above the focal
    /// length), in a view whose focal length is `fx` pixels.
    pub fn new(focal_length: f64, f_number: f64, focus: f64, fx: f64) -> ThinLens {
        let aperture = focal_length / f_number;
        ThinLens { far_circle: aperture * fx / (focus - focal_length), focus }
    }

    /// The diameter of the circle of confusion of a point at distance `z` mm along the
    /// axis, pixels (that of a point infinitely far for `z` = +inf).
    #[inline(always)]
    pub fn circle_px(&self, z: f64) -> f64 {
        self.far_circle * (1.0 - self.focus / z).abs()
    }

    /// [`ThinLens::sigma_px`] at the distance whose inverse is `inv_z` (no division).
    #[inline(always)]
    pub fn sigma_px_at_inverse(&self, inv_z: f64) -> f32 {
        (self.far_circle * (1.0 - self.focus * inv_z).abs() / 4.0) as f32
    }

    /// The blur's standard deviation at distance `z`: a quarter of the circle's diameter.
    #[inline(always)]
    pub fn sigma_px(&self, z: f64) -> f32 {
        (self.circle_px(z) / 4.0) as f32
    }
}

/// The symmetric kernel (taps from the centre out, normalised over both sides) of a sampled
/// Gaussian whose discrete variance is `sigma`² exactly.
pub fn gaussian_kernel(sigma: f32) -> Vec<f32> {
    let target = sigma as f64 * sigma as f64;
    if target <= 0.0 {
        return vec![1.0];
    }
    let radius = (3.0 * sigma).ceil() as usize + 1;
    let taps = |s: f64| -> Vec<f64> { (0..=radius).map(|i| (-((i * i) as f64) / (2.0 * s * s)).exp()).collect() };
    let variance = |t: &[f64]| {
        let sum = t[0] + 2.0 * t[1..].iter().sum::<f64>();
        2.0 * t.iter().enumerate().map(|(i, w)| (i * i) as f64 * w).sum::<f64>() / sum
    };
    // The discrete variance grows with the width; bisect for the one that gives σ².
    let (mut lo, mut hi) = (1e-3, 2.0 * sigma as f64 + 1.0);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if variance(&taps(mid)) < target {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let t = taps(0.5 * (lo + hi));
    let sum = t[0] + 2.0 * t[1..].iter().sum::<f64>();
    t.iter().map(|w| (w / sum) as f32).collect()
}

/// The kernel that blurs level k - 1 of a stack into level k, for each k (entry 0 unused):
/// the Gaussian of σ² = σ_k² - σ_{k-1}², found once.
static STEP_KERNELS: LazyLock<Vec<Vec<f32>>> = LazyLock::new(|| {
    (0..LEVELS.len())
        .map(|k| {
            if k == 0 {
                vec![1.0]
            } else {
                gaussian_kernel((LEVELS[k] * LEVELS[k] - LEVELS[k - 1] * LEVELS[k - 1]).sqrt())
            }
        })
        .collect()
});

/// The kernel that blurs a stack's level k - 1 into level k.
fn step_kernel(k: usize) -> &'static [f32] {
    &STEP_KERNELS[k]
}

/// Blurs the `width`-wide image `src` into `dst` with the separable kernel `kernel` (from
/// the centre out), edges repeated; `scratch` holds the horizontal pass. One-row images
/// are blurred along the row only (their rows stand for identical ones).
pub fn blur(src: &[f32], width: usize, kernel: &[f32], scratch: &mut Vec<f32>, dst: &mut [f32]) {
    scratch.resize(src.len(), 0.0);
    let band = width * ROWS_PER_TASK;
    scratch.par_chunks_mut(band).zip(src.par_chunks(band)).for_each(|(out, rows)| blur_rows(rows, width, kernel, out));
    let tmp = &scratch[..];
    dst.par_chunks_mut(band).enumerate().for_each(|(chunk, out)| {
        blur_columns(tmp, width, chunk * ROWS_PER_TASK, kernel, out);
    });
}

camplace_estimator::multiversion! {
    /// The `width`-wide rows `rows` each blurred along itself with `kernel`, into `out`.
    fn blur_rows(rows: &[f32], width: usize, kernel: &[f32], out: &mut [f32]) => blur_rows_body
}

#[inline(always)]
fn blur_rows_body(rows: &[f32], width: usize, kernel: &[f32], out: &mut [f32]) {
    for (o, row) in out.chunks_mut(width).zip(rows.chunks(width)) {
        blur_row(row, kernel, o);
    }
}

camplace_estimator::multiversion! {
    /// Rows `y0..` of the `width`-wide image `rows` blurred along its columns with `kernel`,
    /// edges repeated, into `out`.
    fn blur_columns(rows: &[f32], width: usize, y0: usize, kernel: &[f32], out: &mut [f32]) => blur_columns_body
}

#[inline(always)]
fn blur_columns_body(rows: &[f32], width: usize, y0: usize, kernel: &[f32], out: &mut [f32]) {
    let height = rows.len() / width;
    for (dy, o) in out.chunks_mut(width).enumerate() {
        column_sums(rows, width, height, y0 + dy, 0, kernel, o);
    }
}

/// One row blurred along itself, edges repeated.
#[inline(always)]
fn blur_row(row: &[f32], kernel: &[f32], out: &mut [f32]) {
    let n = row.len();
    let r = kernel.len() - 1;
    let at = |i: isize| row[i.clamp(0, n as isize - 1) as usize];
    let edge = |x: usize| {
        let mut v = kernel[0] * row[x];
        for (i, &w) in kernel.iter().enumerate().skip(1) {
            v += w * (at(x as isize - i as isize) + at((x + i) as isize));
        }
        v
    };
    if n <= 2 * r {
        for (x, o) in out.iter_mut().enumerate() {
            *o = edge(x);
        }
        return;
    }
    // Pixels r .. n - r read no clamped index: tap by tap over the whole run, which runs in
    // vector lanes.
    let inner = &mut out[r..n - r];
    for (o, &c) in inner.iter_mut().zip(&row[r..n - r]) {
        *o = kernel[0] * c;
    }
    for (i, &w) in kernel.iter().enumerate().skip(1) {
        let (left, right) = (&row[r - i..n - r - i], &row[r + i..n - r + i]);
        for ((o, &a), &b) in inner.iter_mut().zip(left).zip(right) {
            *o += w * (a + b);
        }
    }
    for x in (0..r).chain(n - r..n) {
        out[x] = edge(x);
    }
}

/// An image and copies of it blurred at the [`LEVELS`] up to a largest blur, from which any
/// pixel can be read at any blur up to it.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BlurStack {
    /// Level k is the image blurred at `LEVELS[k]`; level 0 is the image itself.
    levels: Vec<Vec<f32>>,
    scratch: Vec<f32>,
}

impl BlurStack {
    /// Fills the stack from `image` (`width` wide) with every level up to the first at or
    /// above `max_sigma`; buffers are kept from call to call.
    pub fn build(&mut self, image: &[f32], width: usize, max_sigma: f32) {
        let top = LEVELS.iter().position(|&s| s >= max_sigma).unwrap_or(LEVELS.len() - 1);
        self.levels.resize_with(top + 1, Vec::new);
        self.levels[0].clear();
        self.levels[0].extend_from_slice(image);
        for k in 1..=top {
            let (done, rest) = self.levels.split_at_mut(k);
            rest[0].resize(image.len(), 0.0);
            blur(&done[k - 1], width, step_kernel(k), &mut self.scratch, &mut rest[0]);
        }
    }

    /// Fills levels 1 to `top` from `image` (level 0 left empty: the image is it).
    pub fn build_above(&mut self, image: &[f32], width: usize, top: usize) {
        self.levels.resize_with(top + 1, Vec::new);
        for k in 1..=top {
            let (done, rest) = self.levels.split_at_mut(k);
            rest[0].resize(image.len(), 0.0);
            let src = if k == 1 { image } else { &done[k - 1][..] };
            blur(src, width, step_kernel(k), &mut self.scratch, &mut rest[0]);
        }
    }

    /// Pixel `i` blurred at `sigma` (clamped to the stack's top level).
    #[cfg(test)]
    pub fn sample(&self, i: usize, sigma: f32) -> f32 {
        let (k, w) = level_weight(sigma, self.levels.len() - 1);
        if w == 0.0 {
            self.levels[k][i]
        } else {
            let (a, b) = (self.levels[k][i], self.levels[k + 1][i]);
            a + w * (b - a)
        }
    }

    /// The stack's levels (level 0 first).
    pub fn levels(&self) -> &[Vec<f32>] {
        &self.levels
    }
}

/// For a blur `sigma` and a stack whose top level is `top`: the level k below it and the
/// weight of level k + 1 that gives the mixture the variance `sigma`² (0 at or past the top).
#[inline(always)]
pub fn level_weight(sigma: f32, top: usize) -> (usize, f32) {
    // Without branches or table reads, so that a pass over many pixels runs in vector lanes
    // (a table read per lane would be a gather): NaN and blurs of 0 or less read level 0
    // (max drops a NaN), blurs at or past the top read the top; the level is the last at or
    // below the blur, and at a level's own blur the weight is 0.
    let c = sigma.max(0.0).min(LEVELS[top]);
    // Below 2 the levels step by a half; from 2 on they are 2^e and 1.5 2^e (k = 2e + 2
    // and 2e + 3), which the exponent and the first mantissa bit of c tell, and which c's
    // bits keep when the rest of its mantissa is cleared.
    let bits = c.to_bits();
    let octave = 2 * ((bits >> 23) as i32 - 127) + 2 + ((bits >> 22) & 1) as i32;
    // SAFETY: c is finite and within 0..=32 (the last level), which i32 holds.
    let halves = unsafe { (2.0 * c).to_int_unchecked::<i32>() };
    // A select and a clamp the vectoriser keeps in lanes (k is at most 12 already: the
    // octave of 32 is 2 * 5 + 2).
    let k = (if c < 2.0 { halves } else { octave }).clamp(0, LEVELS.len() as i32 - 1) as usize;
    // Level k's blur and the next one up, exactly LEVELS[k] and LEVELS[k + 1] (past the
    // last level, 48, whose weight multiplies 0 as c is then the last level's blur).
    let (level, next) = if c < 2.0 {
        (halves as f32 * 0.5, (halves + 1) as f32 * 0.5)
    } else {
        let octave_start = bits & 0xFF80_0000;
        let next = if bits & 0x0040_0000 != 0 { octave_start + 0x0080_0000 } else { octave_start | 0x0040_0000 };
        (f32::from_bits(bits & 0xFFC0_0000), f32::from_bits(next))
    };
    (k, (c * c - level * level) * (1.0 / (next * next - level * level)))
}

/// The top level a stack needs for blurs up to `max_sigma`: the first at or above it.
pub fn top_level(max_sigma: f32) -> usize {
    LEVELS.iter().position(|&s| s >= max_sigma).unwrap_or(LEVELS.len() - 1)
}

/// Each pixel's blur level and weight ([`level_weight`]) under `lens` at its depth in
/// `depth` (mm along the axis), into `levels`; returns the stack's top level, the first at
/// or above the largest blur. The blur grows away from the focus distance on either side,
/// so the nearest and the farthest depth bound it.
pub fn blur_levels(lens: &ThinLens, depth: &[f32], levels: &mut Vec<(u32, f32)>) -> usize {
    let (near, far) = depth
        .par_chunks(CHUNK)
        .map(|c| {
            let mut range = (f32::INFINITY, f32::NEG_INFINITY);
            depth_range(c, &mut range);
            range
        })
        .reduce(|| (f32::INFINITY, f32::NEG_INFINITY), |a, b| (a.0.min(b.0), a.1.max(b.1)));
    let max_sigma = if near <= far { lens.sigma_px(near as f64).max(lens.sigma_px(far as f64)) } else { 0.0 };
    let top = top_level(max_sigma);
    levels.resize(depth.len(), (0, 0.0));
    levels.par_chunks_mut(CHUNK).zip(depth.par_chunks(CHUNK)).for_each(|(out, z)| chunk_levels(lens, top, z, out));
    top
}

camplace_estimator::multiversion! {
    /// The nearest and farthest of `depth` and `range`, into `range`.
    fn depth_range(depth: &[f32], range: &mut (f32, f32)) => depth_range_body
}

#[inline(always)]
fn depth_range_body(depth: &[f32], range: &mut (f32, f32)) {
    *range = depth.iter().fold(*range, |(lo, hi), &z| (lo.min(z), hi.max(z)));
}

camplace_estimator::multiversion! {
    /// [`blur_levels`] of one chunk of pixels.
    fn chunk_levels(lens: &ThinLens, top: usize, depth: &[f32], out: &mut [(u32, f32)]) => chunk_levels_body
}

#[inline(always)]
fn chunk_levels_body(lens: &ThinLens, top: usize, depth: &[f32], out: &mut [(u32, f32)]) {
    for (o, &z) in out.iter_mut().zip(depth) {
        let (k, w) = level_weight(lens.sigma_px(z as f64), top);
        *o = (k as u32, w);
    }
}

/// Pixels per task of [`blur_levels`].
const CHUNK: usize = 1 << 14;

/// Blurs `image` in place, pixel i by the blur whose level and weight
/// ([`level_weight`] with `top`) are `levels[i]`, through `stack` (its buffers reused from
/// call to call; level 0 is the image itself). With `sense` given, the sensor then
/// saturates the blurred light to 0..255 and adds the noise `sense` holds (image key and
/// amplitude), if any; without, the blurred light is left as it is. The top level is never
/// stored: its rows are blurred ahead and its columns summed in the pass that mixes, a run
/// of pixels at a time.
pub fn defocus_image(
    image: &mut [f32],
    width: usize,
    levels: &[(u32, f32)],
    top: usize,
    stack: &mut BlurStack,
    sense: Option<Option<(u64, u32)>>,
) {
    let height = image.len() / width.max(1);
    let kernel = step_kernel(top);
    if top > 0 {
        stack.build_above(image, width, top - 1);
        let BlurStack { levels, scratch } = stack;
        let src = if top == 1 { &*image } else { &levels[top - 1][..] };
        scratch.resize(src.len(), 0.0);
        let band = width * ROWS_PER_TASK;
        scratch
            .par_chunks_mut(band)
            .zip(src.par_chunks(band))
            .for_each(|(out, rows)| blur_rows(rows, width, kernel, out));
    }
    let mix = Mix { levels: &stack.levels, rows: &stack.scratch, kernel, width, height, top, sense };
    let band = width * ROWS_PER_TASK;
    image.par_chunks_mut(band).zip(levels.par_chunks(band)).enumerate().for_each(|(chunk, (out, lv))| {
        mix_band(&mix, chunk * ROWS_PER_TASK, lv, out);
    });
}

/// What every band of [`defocus_image`]'s mixing pass reads.
struct Mix<'a> {
    /// The stack's levels below the top (level 0 unused: the image is it).
    levels: &'a [Vec<f32>],
    /// The source of the top level blurred along its rows.
    rows: &'a [f32],
    /// The step from the level below the top to the top, from the centre out.
    kernel: &'a [f32],
    width: usize,
    height: usize,
    top: usize,
    /// Whether the sensor saturates the light, and its noise.
    sense: Option<Option<(u64, u32)>>,
}

camplace_estimator::multiversion! {
    /// The rows from `y0` on of [`defocus_image`]'s image, `out`, mixed from their levels
    /// `lv`, with the noise added.
    fn mix_band(mix: &Mix<'_>, y0: usize, lv: &[(u32, f32)], out: &mut [f32]) => mix_band_body
}

#[inline(always)]
fn mix_band_body(mix: &Mix<'_>, y0: usize, lv: &[(u32, f32)], out: &mut [f32]) {
    let Mix { levels: st, rows, kernel, width, height, top, sense } = *mix;
    let mut run = [0.0f32; RUN];
    for (r, (o, lv)) in out.chunks_mut(width).zip(lv.chunks(width)).enumerate() {
        let y = y0 + r;
        let start = y * width;
        for x0 in (0..width).step_by(RUN) {
            let n = RUN.min(width - x0);
            let top_run = &mut run[..n];
            if top > 0 {
                column_sums(rows, width, height, y, x0, kernel, top_run);
            }
            for (j, (o, &(k, w))) in o[x0..x0 + n].iter_mut().zip(&lv[x0..x0 + n]).enumerate() {
                let i = start + x0 + j;
                let read = |l: usize, own: f32| match l {
                    0 => own,
                    l if l == top => top_run[j],
                    l => st[l][i],
                };
                let a = read(k as usize, *o);
                *o = if w == 0.0 { a } else { a + w * (read(k as usize + 1, *o) - a) };
            }
        }
        if let Some(noise) = sense {
            read_out(o, start as u64, noise);
        }
    }
}

/// Pixels a run of [`defocus_image`] blurs at once along its columns.
const RUN: usize = 64;

/// Row `y`'s pixels `x0..x0 + out.len()` of the `width`-wide, `height`-tall image `rows`
/// blurred along its columns with `kernel` (from the centre out), edges repeated. A one-row
/// image stands for identical rows, which the blur leaves as they are.
#[inline(always)]
fn column_sums(rows: &[f32], width: usize, height: usize, y: usize, x0: usize, kernel: &[f32], out: &mut [f32]) {
    let n = out.len();
    let centre = &rows[y * width + x0..][..n];
    if height <= 1 {
        out.copy_from_slice(centre);
        return;
    }
    for (v, &c) in out.iter_mut().zip(centre) {
        *v = kernel[0] * c;
    }
    for (i, &w) in kernel.iter().enumerate().skip(1) {
        let up = &rows[y.saturating_sub(i) * width + x0..][..n];
        let down = &rows[(y + i).min(height - 1) * width + x0..][..n];
        for ((v, &a), &b) in out.iter_mut().zip(up).zip(down) {
            *v += w * (a + b);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The discrete variance of a centre-out kernel.
    fn variance(k: &[f32]) -> f64 {
        let sum = k[0] as f64 + 2.0 * k[1..].iter().map(|&w| w as f64).sum::<f64>();
        2.0 * k.iter().enumerate().map(|(i, &w)| (i * i) as f64 * w as f64).sum::<f64>() / sum
    }

    #[test]
    fn kernels_have_the_variance_asked_for() {
        for sigma in [0.1f32, 0.3, 0.5, 0.87, 1.7, 3.46, 6.93, 13.9] {
            let k = gaussian_kernel(sigma);
            let sum = k[0] + 2.0 * k[1..].iter().sum::<f32>();
            assert!((sum - 1.0).abs() < 1e-5);
            let v = variance(&k);
            assert!((v.sqrt() - sigma as f64).abs() < 1e-3 * sigma as f64, "σ {sigma}: {}", v.sqrt());
        }
    }

    #[test]
    fn level_weights_are_the_obvious_search_and_mix() {
        for (top, &top_sigma) in LEVELS.iter().enumerate() {
            for i in -10..=4000 {
                let sigma = i as f32 * 0.0091;
                let (k, w) = level_weight(sigma, top);
                if sigma <= 0.0 {
                    assert_eq!((k, w), (0, 0.0));
                } else if sigma >= top_sigma {
                    assert_eq!((k, w), (top, 0.0), "σ {sigma}, top {top}");
                } else {
                    let want = (0..top).rev().find(|&j| LEVELS[j] <= sigma).unwrap();
                    assert_eq!(k, want, "σ {sigma}, top {top}");
                    let (a, b) = (LEVELS[k] * LEVELS[k], LEVELS[k + 1] * LEVELS[k + 1]);
                    let mix = (sigma * sigma - a) / (b - a);
                    assert!((w - mix).abs() < 1e-5 && (0.0..1.0).contains(&w), "σ {sigma}, top {top}: {w} vs {mix}");
                }
            }
        }
        assert_eq!(level_weight(f32::NAN, 5), (0, 0.0));
        assert_eq!(level_weight(f32::INFINITY, 5), (5, 0.0));
    }

    /// 1 / (σ_{k+1}² - σ_k²) for each level k below the last, and 0 for the last, worked
    /// out when compiling.
    const INV_STEP: [f32; LEVELS.len()] = {
        let mut inv = [0.0; LEVELS.len()];
        let mut k = 0;
        while k + 1 < inv.len() {
            inv[k] = 1.0 / (LEVELS[k + 1] * LEVELS[k + 1] - LEVELS[k] * LEVELS[k]);
            k += 1;
        }
        inv
    };

    /// [`level_weight`] the obvious way: the level found by search, the weight through the
    /// table of the reciprocal steps between levels.
    fn level_weight_by_table(sigma: f32, top: usize) -> (usize, f32) {
        let c = sigma.max(0.0).min(LEVELS[top]);
        let k = (0..LEVELS.len()).rev().find(|&j| LEVELS[j] <= c).unwrap();
        (k, (c * c - LEVELS[k] * LEVELS[k]) * INV_STEP[k])
    }

    #[test]
    fn level_weights_are_bit_for_bit_the_table_reads() {
        // Every 331st float from 0 to past the last level, every level and its neighbours
        // a few ulps away, and what lies outside the levels.
        let mut sigmas: Vec<f32> = (0..=40f32.to_bits()).step_by(331).map(f32::from_bits).collect();
        for &level in &LEVELS {
            let b = level.to_bits() as i64;
            sigmas.extend((b - 4..=b + 4).filter(|&v| v >= 0).map(|v| f32::from_bits(v as u32)));
        }
        sigmas.extend([-0.0, -1.0, -f32::MIN_POSITIVE, f32::NAN, f32::INFINITY, f32::NEG_INFINITY, f32::MAX, 1e-40]);
        for top in 0..LEVELS.len() {
            for &sigma in &sigmas {
                let (k, w) = level_weight(sigma, top);
                let (want_k, want_w) = level_weight_by_table(sigma, top);
                assert_eq!((k, w.to_bits()), (want_k, want_w.to_bits()), "σ {sigma:e}, top {top}: {w} vs {want_w}");
            }
        }
        assert!(sigmas.len() > 3_000_000, "{} blurs compared", sigmas.len());
    }

    #[test]
    fn blur_equals_the_direct_two_dimensional_sum() {
        // Rows wider than the kernel, and rows the kernel overhangs on both sides.
        for (w, h, sigma) in [(23, 17, 1.3), (7, 5, 2.5), (11, 3, 1.7), (12, 12, 0.4)] {
            blur_is_the_direct_sum(w, h, sigma);
        }
    }

    fn blur_is_the_direct_sum(w: usize, h: usize, sigma: f32) {
        let img: Vec<f32> = (0..w * h).map(|i| ((i * 7919) % 251) as f32).collect();
        let k = gaussian_kernel(sigma);
        let mut out = vec![0.0; w * h];
        blur(&img, w, &k, &mut Vec::new(), &mut out);
        let r = k.len() as isize - 1;
        for y in 0..h as isize {
            for x in 0..w as isize {
                let mut want = 0.0f64;
                for dy in -r..=r {
                    for dx in -r..=r {
                        let (xx, yy) = ((x + dx).clamp(0, w as isize - 1), (y + dy).clamp(0, h as isize - 1));
                        want += (k[dx.unsigned_abs()] * k[dy.unsigned_abs()]) as f64
                            * img[yy as usize * w + xx as usize] as f64;
                    }
                }
                let got = out[y as usize * w + x as usize] as f64;
                assert!((got - want).abs() < 1e-3, "({x}, {y}): {got} vs {want}");
            }
        }
    }

    #[test]
    fn a_stack_sample_has_the_variance_asked_for() {
        // A single bright pixel: the variance of the blurred image along x is the blur's.
        let (w, h) = (161, 161);
        let mut img = vec![0.0f32; w * h];
        img[80 * w + 80] = 1.0;
        let mut stack = BlurStack::default();
        stack.build(&img, w, 9.0);
        for sigma in [0.3f32, 0.8, 1.2, 2.5, 5.0, 7.0, 9.0] {
            let (mut sum, mut m2) = (0.0f64, 0.0f64);
            for y in 0..h {
                for x in 0..w {
                    let v = stack.sample(y * w + x, sigma) as f64;
                    sum += v;
                    m2 += v * (x as f64 - 80.0).powi(2);
                }
            }
            let s = (m2 / sum).sqrt();
            assert!((s - sigma as f64).abs() < 0.01 * sigma as f64 + 1e-3, "σ {sigma}: {s}");
        }
    }

    #[test]
    fn defocus_by_levels_matches_the_stack_and_clamps_at_the_top() {
        // Narrower and wider than a run, one row, and tops from the first level to high ones.
        for (w, h, max) in [(40, 30, 2.5f32), (150, 20, 0.5), (150, 20, 7.0), (97, 1, 3.0), (70, 90, 20.0)] {
            let img: Vec<f32> = (0..w * h).map(|i| ((i * 7919) % 251) as f32).collect();
            let sigmas: Vec<f32> = (0..w * h).map(|i| (i % 13) as f32 * max / 10.0).collect();
            let top = top_level(max);
            let levels: Vec<(u32, f32)> =
                sigmas.iter().map(|&s| level_weight(s, top)).map(|(k, w)| (k as u32, w)).collect();
            let mut out = img.clone();
            defocus_image(&mut out, w, &levels, top, &mut BlurStack::default(), None);
            let mut stack = BlurStack::default();
            stack.build(&img, w, max);
            for i in 0..w * h {
                assert_eq!(out[i], stack.sample(i, sigmas[i]), "{w}x{h} up to σ {max}: pixel {i}");
            }
        }
    }

    #[test]
    fn blur_levels_are_each_pixels_own_and_the_top_bounds_them_all() {
        let lens = ThinLens::new(6.0, 2.0, 600.0, 800.0);
        for depth in [
            (0..5000).map(|i| 300.0 + (i * 37 % 1000) as f32).collect::<Vec<_>>(),
            (0..5000).map(|i| if i % 7 == 0 { f32::INFINITY } else { 590.0 + (i % 20) as f32 }).collect(),
            vec![600.0; 100],
        ] {
            let max = depth.iter().fold(0.0f32, |m, &z| m.max(lens.sigma_px(z as f64)));
            let mut levels = Vec::new();
            let top = blur_levels(&lens, &depth, &mut levels);
            assert_eq!(top, top_level(max));
            for (&z, &(k, w)) in depth.iter().zip(&levels) {
                let (k0, w0) = level_weight(lens.sigma_px(z as f64), top);
                assert_eq!((k, w), (k0 as u32, w0), "depth {z}");
            }
        }
    }

    #[test]
    fn the_circle_of_confusion_is_the_thin_lens_one() {
        // 6 mm at f/2 (A = 3 mm), 800 px focal length, focused at 600 mm.
        let lens = ThinLens::new(6.0, 2.0, 600.0, 800.0);
        assert_eq!(lens.circle_px(600.0), 0.0);
        for z in [100.0, 599.0, 601.0, 5000.0] {
            let (a, b) = (lens.sigma_px(z), lens.sigma_px_at_inverse(1.0 / z));
            assert!((a - b).abs() <= 1e-6 * a, "z {z}: {a} vs {b}");
        }
        for z in [400.0, 500.0, 700.0, 1000.0] {
            // The image distances of focus and point, and the disc on the sensor by similar
            // triangles, in pixels of 6 mm / 800.
            let v = |d: f64| 1.0 / (1.0 / 6.0 - 1.0 / d);
            let (vs, vz) = (v(600.0), v(z));
            let c_mm = 3.0 * (vz - vs).abs() / vz;
            let want = c_mm * 800.0 / 6.0;
            assert!((lens.circle_px(z) - want).abs() < 1e-9 * want.max(1.0), "z {z}");
        }
    }
}
