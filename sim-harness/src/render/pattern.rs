//! The projector's images: the seeded random-dot pattern of the one-shot method and the
//! 12-shot phase-shift fringes, as the 8-bit images a real projector would show, and
//! their sampling at sub-pixel projector coordinates.

use camplace_config::GrayImage;
use camplace_config::Sensor;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::f64::consts::PI;

use crate::render::defocus::BlurStack;

/// Phase steps per fringe frequency.
pub const PHASE_STEPS: usize = 4;

/// A random-dot pattern: square dots of `dot_size` pixels on a grid, each lit with
/// probability `density`, drawn from `seed`.
pub fn random_dots(width: usize, height: usize, dot_size: usize, density: f64, seed: u64) -> GrayImage {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let s = dot_size.max(1);
    let (cols, rows) = (width.div_ceil(s), height.div_ceil(s));
    let lit: Vec<bool> = (0..cols * rows).map(|_| rng.random::<f64>() < density).collect();
    let mut img = GrayImage::new(width, height, 0);
    for y in 0..height {
        for (x, p) in img.row_mut(y).iter_mut().enumerate() {
            *p = if lit[(y / s) * cols + x / s] { 255 } else { 0 };
        }
    }
    img
}

/// Fringe image of `periods` periods across the width at phase step `step` (0 to 3):
/// I = 0.5 + 0.5 cos(phi - step pi/2) with phi = 2 pi periods x / width, x the column.
/// Steps 2 and 3 are the exact complements (255 - value) of steps 0 and 1, as the cosine
/// has them, so that rounding to grey levels keeps each pair summing to full white.
pub fn fringe(width: usize, height: usize, periods: f64, step: usize) -> GrayImage {
    let row: Vec<u8> = (0..width)
        .map(|x| {
            let phi = 2.0 * PI * periods * x as f64 / width as f64;
            let half = (step % 2) as f64 * PI / 2.0;
            let v = (255.0 * (0.5 + 0.5 * (phi - half).cos())).round() as u8;
            if step % 4 >= 2 {
                255 - v
            } else {
                v
            }
        })
        .collect();
    let mut img = GrayImage::new(width, height, 0);
    for y in 0..height {
        img.row_mut(y).copy_from_slice(&row);
    }
    img
}

/// A full white image at a sensor's projector resolution.
pub fn white(sensor: &Sensor) -> GrayImage {
    let [w, h] = sensor.projector_resolution;
    GrayImage::new(w as usize, h as usize, 255)
}

/// The one-shot pattern of a sensor at its projector resolution.
pub fn one_shot(sensor: &Sensor, seed: u64) -> GrayImage {
    let [w, h] = sensor.projector_resolution;
    random_dots(w as usize, h as usize, sensor.dot_size as usize, sensor.dot_density, seed)
}

/// The 12-shot set (3 frequencies by default), frequency-major: image 4 fi + k shows
/// period count `fringe_periods[fi]` at phase step k.
pub fn fringe_set(sensor: &Sensor) -> Vec<GrayImage> {
    let [w, h] = sensor.projector_resolution;
    let mut set = Vec::with_capacity(sensor.fringe_periods.len() * PHASE_STEPS);
    for &f in &sensor.fringe_periods {
        for k in 0..PHASE_STEPS {
            set.push(fringe(w as usize, h as usize, f, k));
        }
    }
    set
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
    /// Level 0: the filtered image (or its one row); above it, its defocused copies.
    stack: BlurStack,
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
        ProjectorImage { width: w, height: h, one_row, offset: (b as f32 - 1.0) / 2.0, stack }
    }

    /// Brightness at projector pixel coordinates (u, v), pixel centres at integers.
    #[inline(always)]
    pub fn sample(&self, u: f32, v: f32) -> f32 {
        match self.taps(u, v) {
            None => 0.0,
            Some(t) => t.read(&self.stack.levels()[0]),
        }
    }

    /// Brightness at (u, v) where the projector's defocus blurs by the blur whose level
    /// and weight are `blur` ([`crate::render::defocus::level_weight`] with the top level of
    /// the stack, that of the largest blur the image was prepared for).
    #[inline(always)]
    pub fn sample_defocused(&self, u: f32, v: f32, blur: (u32, f32)) -> f32 {
        let Some(t) = self.taps(u, v) else { return 0.0 };
        let levels = self.stack.levels();
        let (k, w) = (blur.0 as usize, blur.1);
        let a = t.read(&levels[k]);
        if w == 0.0 {
            a
        } else {
            a + w * (t.read(&levels[k + 1]) - a)
        }
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
    use camplace_config::Cell;

    #[test]
    fn dots_follow_their_seed_and_density() {
        let a = random_dots(320, 200, 4, 0.5, 1);
        assert_eq!(a, random_dots(320, 200, 4, 0.5, 1));
        let b = random_dots(320, 200, 4, 0.5, 2);
        let differ = a.data.iter().zip(&b.data).filter(|(x, y)| x != y).count();
        assert!(differ > a.data.len() / 3, "{differ}");
        let lit = a.data.iter().filter(|&&v| v == 255).count() as f64 / a.data.len() as f64;
        assert!((lit - 0.5).abs() < 0.03, "{lit}");
        // Dots are whole cells.
        assert!((0..200).step_by(4).all(|y| a.row(y) == a.row(y + 3)));
    }

    #[test]
    fn fringes_are_frequency_major_cosines() {
        let cell = Cell::default();
        let set = fringe_set(&cell.sensor);
        assert_eq!(set.len(), 12);
        let w = cell.sensor.projector_resolution[0] as f64;
        for (fi, &f) in cell.sensor.fringe_periods.iter().enumerate() {
            for k in 0..4 {
                let img = &set[4 * fi + k];
                for x in [0usize, 17, 333, 1000] {
                    let want = 255.0 * (0.5 + 0.5 * (2.0 * PI * f * x as f64 / w - k as f64 * PI / 2.0).cos());
                    assert!((img.get(x, 0) as f64 - want).abs() <= 0.5 && img.get(x, 0) == img.get(x, 799));
                }
            }
            // Opposite steps are complements, so the renderer may draw one from the other.
            for k in 0..2 {
                let (a, b) = (&set[4 * fi + k], &set[4 * fi + k + 2]);
                assert!(a.data.iter().zip(&b.data).all(|(&p, &q)| p as u16 + q as u16 == 255));
            }
        }
    }

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
}
