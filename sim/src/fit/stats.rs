//! The image statistics the sensor fit measures alike on real and simulated images: the
//! structure function of the difference of two images of one view (the camera noise and
//! its mean filter, the tray's tiles left out), the table's grey level and the projected
//! pattern's contrast and fineness. The fit itself (which key each statistic gives, and
//! the rendering that matches them) lives in the module above.

use camplace_config::GrayImage;

/// Side of the square tiles the difference of two images is judged in, pixels.
pub const TILE: usize = 32;
/// The longest lag of the difference's structure function, pixels (past the widest mean
/// filter the cell file takes, 15).
pub const MAX_LAG: usize = 20;
/// Pixels left out along the image border, where the mean filter repeats edge pixels.
const BORDER: usize = 8;
/// A tile whose difference at [`MAX_LAG`] is above this many times the median tile's is
/// taken to hold something that moved (the tray, its shadow) and is left out.
const CHANGED_TILE: f64 = 1.5;
/// Half side of the window whose mean the contrast is measured against, pixels.
const LOCAL_MEAN_RADIUS: usize = 7;
/// The lags of the pattern's structure function, pixels.
pub const PATTERN_LAGS: usize = 8;

/// The structure function of the difference Δ = a − b of two images of one view over the
/// tiles where nothing moved: `sums[d − 1] / counts[d − 1]` is the mean of (Δ(p + d) − Δ(p))²
/// over horizontal and vertical neighbours d pixels apart.
#[derive(Debug, Clone, PartialEq)]
pub struct DifferenceStats {
    /// Sums of squared differences per lag 1 ..= [`MAX_LAG`].
    pub sums: [f64; MAX_LAG],
    /// Neighbour pairs per lag.
    pub counts: [f64; MAX_LAG],
    /// The tiles kept: their top-left corners.
    pub tiles: Vec<(usize, usize)>,
}

impl Default for DifferenceStats {
    fn default() -> Self {
        DifferenceStats { sums: [0.0; MAX_LAG], counts: [0.0; MAX_LAG], tiles: Vec::new() }
    }
}

impl DifferenceStats {
    /// The structure function, lag 1 first (0 where nothing was counted).
    pub fn structure(&self) -> [f64; MAX_LAG] {
        std::array::from_fn(|i| if self.counts[i] > 0.0 { self.sums[i] / self.counts[i] } else { 0.0 })
    }

    /// Adds `other`'s pairs (its tiles are not kept).
    pub fn add(&mut self, other: &DifferenceStats) {
        for i in 0..MAX_LAG {
            self.sums[i] += other.sums[i];
            self.counts[i] += other.counts[i];
        }
    }
}

/// The tiles of a `width` x `height` image that lie wholly on `mask` (true where the table
/// is seen), away from the border.
fn tiles_on(mask: &[bool], width: usize, height: usize) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut y = BORDER;
    while y + TILE + BORDER <= height {
        let mut x = BORDER;
        while x + TILE + BORDER <= width {
            if (y..y + TILE).all(|yy| mask[yy * width + x..yy * width + x + TILE].iter().all(|&m| m)) {
                out.push((x, y));
            }
            x += TILE;
        }
        y += TILE;
    }
    out
}

/// The structure function of `a − b` over the tiles on `mask` where neither image saturates
/// (a grey level of 0 or 255 cuts the noise short) and nothing moved between the two.
pub fn difference_stats(a: &GrayImage, b: &GrayImage, mask: &[bool]) -> DifferenceStats {
    let (w, h) = (a.width, a.height);
    debug_assert!(b.width == w && b.height == h && mask.len() == w * h);
    // Each tile's own pairs, its corner the one tile it keeps.
    let mut per_tile: Vec<DifferenceStats> = Vec::new();
    for (x0, y0) in tiles_on(mask, w, h) {
        let clipped = (y0..y0 + TILE).any(|y| {
            let span = y * w + x0..y * w + x0 + TILE;
            a.data[span.clone()].iter().chain(&b.data[span]).any(|&v| v == 0 || v == 255)
        });
        if clipped {
            continue;
        }
        let delta = |x: usize, y: usize| a.data[y * w + x] as f64 - b.data[y * w + x] as f64;
        let (mut sums, mut counts) = ([0.0; MAX_LAG], [0.0; MAX_LAG]);
        for d in 1..=MAX_LAG {
            for y in y0..y0 + TILE {
                for x in x0..x0 + TILE {
                    if x + d < x0 + TILE {
                        sums[d - 1] += (delta(x + d, y) - delta(x, y)).powi(2);
                        counts[d - 1] += 1.0;
                    }
                    if y + d < y0 + TILE {
                        sums[d - 1] += (delta(x, y + d) - delta(x, y)).powi(2);
                        counts[d - 1] += 1.0;
                    }
                }
            }
        }
        per_tile.push(DifferenceStats { sums, counts, tiles: vec![(x0, y0)] });
    }
    let far = |t: &DifferenceStats| t.sums[MAX_LAG - 1] / t.counts[MAX_LAG - 1];
    let mut sorted: Vec<f64> = per_tile.iter().map(far).collect();
    sorted.sort_by(f64::total_cmp);
    let mut out = DifferenceStats::default();
    let Some(&median) = sorted.get(sorted.len() / 2) else { return out };
    for tile in per_tile.iter().filter(|t| far(t) <= CHANGED_TILE * median) {
        out.add(tile);
        out.tiles.extend_from_slice(&tile.tiles);
    }
    out
}

/// The mean filter's side and the noise's variance before it, from a difference's structure
/// function `structure` (lag 1 first).
#[derive(Debug, Clone, PartialEq)]
pub struct BoxNoiseFit {
    /// The odd mean filter side that fits best.
    pub blur: u32,
    /// The variance of one image's noise before the mean filter, grey levels².
    pub noise_variance: f64,
    /// The squared residual of the fit of each odd side 1, 3, … 15.
    pub residuals: Vec<(u32, f64)>,
}

/// What rounding to whole grey levels adds to the difference's structure function: each
/// image's rounding error has a variance of 1/12, independent from pixel to pixel.
pub const ROUNDING_STRUCTURE: f64 = 4.0 / 12.0;

/// The model of the difference's structure function at lag `d` for uniform white noise of
/// variance `v` per image before a `blur`-wide mean filter: after the filter each image's
/// noise has variance v / blur² and correlation 1 − d / blur at lag d < blur, so the
/// difference of two images gives 4 (v / blur²) min(d, blur) / blur, plus the rounding.
pub fn box_noise_structure(v: f64, blur: u32, d: usize) -> f64 {
    let b = blur as f64;
    4.0 * v / (b * b) * (d as f64).min(b) / b + ROUNDING_STRUCTURE
}

/// Fits [`box_noise_structure`] to `structure` by least squares over lags 1 ..= [`MAX_LAG`]
/// for every odd side 1 … 15 (the variance in closed form for each), and keeps the best.
pub fn fit_box_noise(structure: &[f64; MAX_LAG]) -> BoxNoiseFit {
    let mut residuals = Vec::new();
    let mut best = (1, 0.0, f64::INFINITY);
    for blur in (1..=15u32).step_by(2) {
        let (v, r) = variance_at(structure, blur);
        residuals.push((blur, r));
        if r < best.2 {
            best = (blur, v, r);
        }
    }
    BoxNoiseFit { blur: best.0, noise_variance: best.1, residuals }
}

/// The noise variance before a `blur`-wide mean filter that fits `structure` best (least
/// squares, in closed form), and the squared residual.
pub fn variance_at(structure: &[f64; MAX_LAG], blur: u32) -> (f64, f64) {
    // structure(d) − rounding = v · m(d).
    let m: Vec<f64> = (1..=MAX_LAG).map(|d| box_noise_structure(1.0, blur, d) - ROUNDING_STRUCTURE).collect();
    let y: Vec<f64> = structure.iter().map(|s| s - ROUNDING_STRUCTURE).collect();
    let v = (m.iter().zip(&y).map(|(m, y)| m * y).sum::<f64>() / m.iter().map(|m| m * m).sum::<f64>()).max(0.0);
    let r: f64 = m.iter().zip(&y).map(|(m, y)| (y - v * m).powi(2)).sum();
    (v, r)
}

/// The noise amplitude A whose uniform integer noise on −A ..= A has variance `v`:
/// ((2A + 1)² − 1) / 12 = v.
pub fn amplitude_of_variance(v: f64) -> f64 {
    (((12.0 * v.max(0.0) + 1.0).sqrt()) - 1.0) / 2.0
}

/// The projected pattern as one image shows it on the table.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct PatternStats {
    /// Mean grey level over the table.
    pub mean: f64,
    /// Root mean square of the grey level less its local mean (a 15 × 15 window): the
    /// pattern's contrast with the noise's share.
    pub contrast: f64,
    /// The mean of (I(p + d) − I(p))² over horizontal and vertical neighbours for lags
    /// 1 ..= [`PATTERN_LAGS`], each divided by the last: the pattern's fineness.
    pub shape: [f64; PATTERN_LAGS],
    /// The contrast's relative standard error from its spread over tiles.
    pub contrast_rel_se: f64,
    /// Pixels measured.
    pub pixels: usize,
}

/// The mean, contrast and fineness of `images` (all shots of one view, each `width` wide)
/// over the pixels of `mask` whose local window lies on it.
pub fn pattern_stats(images: &[&GrayImage], mask: &[bool]) -> PatternStats {
    let (mut n, mut sum, mut hp2) = (0usize, 0.0f64, 0.0f64);
    let (mut lag_sum, mut lag_n) = ([0.0f64; PATTERN_LAGS], [0.0f64; PATTERN_LAGS]);
    let mut tile_hp: std::collections::BTreeMap<(usize, usize, usize), (f64, f64)> = Default::default();
    for (k, img) in images.iter().enumerate() {
        let (w, h) = (img.width, img.height);
        let inside = integral(mask.iter().map(|&m| m as u64 as f64), w, h);
        let values = integral(img.data.iter().map(|&v| v as f64), w, h);
        let r = LOCAL_MEAN_RADIUS;
        let full = ((2 * r + 1) * (2 * r + 1)) as f64;
        for y in r..h.saturating_sub(r) {
            for x in r..w.saturating_sub(r) {
                let window = (x - r, y - r, x + r + 1, y + r + 1);
                if box_sum(&inside, w, window) < full {
                    continue;
                }
                let v = img.data[y * w + x] as f64;
                let hp = v - box_sum(&values, w, window) / full;
                n += 1;
                sum += v;
                hp2 += hp * hp;
                let t = tile_hp.entry((k, x / TILE, y / TILE)).or_default();
                t.0 += hp * hp;
                t.1 += 1.0;
                for d in 1..=PATTERN_LAGS {
                    if x + d < w - r && mask[y * w + x + d] {
                        lag_sum[d - 1] += (img.data[y * w + x + d] as f64 - v).powi(2);
                        lag_n[d - 1] += 1.0;
                    }
                    if y + d < h - r && mask[(y + d) * w + x] {
                        lag_sum[d - 1] += (img.data[(y + d) * w + x] as f64 - v).powi(2);
                        lag_n[d - 1] += 1.0;
                    }
                }
            }
        }
    }
    let lag: [f64; PATTERN_LAGS] = std::array::from_fn(|i| lag_sum[i] / lag_n[i].max(1.0));
    let last = lag[PATTERN_LAGS - 1].max(f64::MIN_POSITIVE);
    let tiles: Vec<f64> = tile_hp.values().filter(|t| t.1 >= (TILE * TILE / 2) as f64).map(|t| t.0 / t.1).collect();
    let rel_se = if tiles.len() >= 2 {
        let m = tiles.iter().sum::<f64>() / tiles.len() as f64;
        let var = tiles.iter().map(|t| (t - m).powi(2)).sum::<f64>() / (tiles.len() - 1) as f64;
        // The contrast is the square root of the tiles' mean: half the mean's relative error.
        0.5 * (var / tiles.len() as f64).sqrt() / m.max(f64::MIN_POSITIVE)
    } else {
        f64::NAN
    };
    PatternStats {
        mean: sum / n.max(1) as f64,
        contrast: (hp2 / n.max(1) as f64).sqrt(),
        shape: lag.map(|l| l / last),
        contrast_rel_se: rel_se,
        pixels: n,
    }
}

/// The summed-area table of a `w` x `h` image, (w + 1) x (h + 1) with a zero first row and
/// column.
fn integral(values: impl Iterator<Item = f64>, w: usize, h: usize) -> Vec<f64> {
    let mut out = vec![0.0; (w + 1) * (h + 1)];
    let mut values = values;
    for y in 0..h {
        let mut row = 0.0;
        for x in 0..w {
            row += values.next().unwrap_or(0.0);
            out[(y + 1) * (w + 1) + x + 1] = out[y * (w + 1) + x + 1] + row;
        }
    }
    out
}

/// The sum over the window [x0, x1) × [y0, y1) from a summed-area table of a `w`-wide image.
fn box_sum(table: &[f64], w: usize, (x0, y0, x1, y1): (usize, usize, usize, usize)) -> f64 {
    let s = w + 1;
    table[y1 * s + x1] - table[y0 * s + x1] - table[y1 * s + x0] + table[y0 * s + x0]
}

/// The mean grey level of `image` over `tiles` (top-left corners of [`TILE`]-sided squares).
pub fn tiles_mean(image: &GrayImage, tiles: &[(usize, usize)]) -> f64 {
    let (mut sum, mut n) = (0.0, 0.0);
    for &(x0, y0) in tiles {
        for y in y0..y0 + TILE {
            for &v in &image.data[y * image.width + x0..y * image.width + x0 + TILE] {
                sum += v as f64;
                n += 1.0;
            }
        }
    }
    sum / f64::max(n, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::noise::{mean_filter_to_u8, pixel_noise};

    /// The variance of uniform integer noise on −A ..= A.
    fn variance_of_amplitude(a: f64) -> f64 {
        ((2.0 * a + 1.0).powi(2) - 1.0) / 12.0
    }

    /// A flat grey image with uniform integer noise of amplitude `a` under a `blur` mean
    /// filter, as the renderer's sensor makes it.
    fn noisy(level: f32, a: u32, blur: usize, key: u64, w: usize, h: usize) -> GrayImage {
        let light: Vec<f32> = (0..w * h).map(|i| level + pixel_noise(key, i as u64, a) as f32).collect();
        let mut out = GrayImage::new(w, h, 0);
        mean_filter_to_u8(&light, w, blur, &mut Vec::new(), &mut out.data);
        out
    }

    #[test]
    fn the_difference_of_two_noisy_images_gives_back_the_filter_and_the_noise() {
        let (w, h) = (320, 240);
        let mask = vec![true; w * h];
        for (a, blur) in [(4u32, 1usize), (10, 3), (25, 5), (40, 9)] {
            let (x, y) = (noisy(100.3, a, blur, 1, w, h), noisy(90.6, a, blur, 2, w, h));
            let stats = difference_stats(&x, &y, &mask);
            assert!(stats.tiles.len() > 40, "{} tiles", stats.tiles.len());
            let fit = fit_box_noise(&stats.structure());
            assert_eq!(fit.blur, blur as u32, "A {a}: {fit:?}");
            let amplitude = amplitude_of_variance(fit.noise_variance);
            assert!((amplitude / a as f64 - 1.0).abs() < 0.05, "A {a}, B {blur}: fitted {amplitude}");
        }
    }

    #[test]
    fn a_moved_square_is_left_out_of_the_difference() {
        let (w, h) = (320, 240);
        let mask = vec![true; w * h];
        let x = noisy(100.0, 8, 3, 1, w, h);
        let mut y = noisy(100.0, 8, 3, 2, w, h);
        // A bright checkered "tray" over a quarter of the view.
        for yy in 40..140 {
            for xx in 40..200 {
                y.data[yy * w + xx] = if (xx / 3 + yy / 3) % 2 == 0 { 200 } else { 40 };
            }
        }
        let stats = difference_stats(&x, &y, &mask);
        assert!(stats.tiles.iter().all(|&(tx, ty)| tx + TILE <= 40 || tx >= 200 || ty + TILE <= 40 || ty >= 140));
        let fit = fit_box_noise(&stats.structure());
        assert_eq!(fit.blur, 3);
        assert!((amplitude_of_variance(fit.noise_variance) / 8.0 - 1.0).abs() < 0.06);
    }

    #[test]
    fn amplitude_and_variance_are_inverse() {
        for a in [0.0, 1.0, 10.0, 33.0] {
            assert!((amplitude_of_variance(variance_of_amplitude(a)) - a).abs() < 1e-9);
        }
        assert!((variance_of_amplitude(10.0) - 36.666_666_666).abs() < 1e-6);
    }

    #[test]
    fn contrast_is_the_plain_local_mean_residual() {
        let (w, h) = (64, 48);
        let img = noisy(120.0, 30, 1, 5, w, h);
        let mut mask = vec![true; w * h];
        for m in mask.iter_mut().take(w * 10) {
            *m = false;
        }
        let stats = pattern_stats(&[&img], &mask);
        let r = LOCAL_MEAN_RADIUS as i64;
        let (mut n, mut hp2) = (0.0, 0.0);
        for y in r..h as i64 - r {
            for x in r..w as i64 - r {
                let mut on = true;
                let mut s = 0.0;
                for dy in -r..=r {
                    for dx in -r..=r {
                        let i = ((y + dy) * w as i64 + x + dx) as usize;
                        on &= mask[i];
                        s += img.data[i] as f64;
                    }
                }
                if on {
                    let hp = img.data[(y * w as i64 + x) as usize] as f64 - s / ((2 * r + 1) * (2 * r + 1)) as f64;
                    hp2 += hp * hp;
                    n += 1.0;
                }
            }
        }
        assert_eq!(stats.pixels, n as usize);
        assert!((stats.contrast - (hp2 / n).sqrt()).abs() < 1e-9, "{} {}", stats.contrast, (hp2 / n).sqrt());
    }
}
