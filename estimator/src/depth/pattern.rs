//! The projector's patterns, beside their decoder (`phase`): the seeded random-dot image of
//! the one-shot method and the 12-shot phase-shift fringes, as the 8-bit images a real
//! projector shows. The simulator renders them and `camplace project` and `serve --project`
//! put them on the projector.

use camplace_config::Sensor;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::f64::consts::PI;

use crate::GrayImage;

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
}
