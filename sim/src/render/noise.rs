//! The paper's camera noise: uniform integer noise in [-A, A] per pixel, then a BxB mean
//! filter, rounding and clamping to 8 bits. The noise of a pixel is a pure function of
//! (noise key, camera, pixel index), a counter-based hash, so images are the same for any
//! thread count and any order of work.

use rayon::prelude::*;

use crate::seeds::pixel_hash;

/// Rows per chunk of parallel work.
const CHUNK_ROWS: usize = 16;

/// The noise of `pixel` in the image of `key`: uniform over the integers -A ..= A.
#[inline(always)]
pub fn pixel_noise(key: u64, pixel: u64, amplitude: u32) -> i32 {
    let h = pixel_hash(key, pixel);
    let n = 2 * amplitude as u64 + 1;
    // Multiply-shift maps the top 32 bits onto 0..n with a bias below 2^-32 * n.
    (((h >> 32) * n) >> 32) as i32 - amplitude as i32
}

/// Adds the noise of image key `key` at `amplitude` to every pixel of `image` (pixel `i`
/// gets the noise [`ShadingTerms::shade`](crate::render::shade::ShadingTerms::shade) gives it).
pub fn add_noise(image: &mut [f32], key: u64, amplitude: u32) {
    if amplitude == 0 {
        return;
    }
    let band = 4096;
    image.par_chunks_mut(band).enumerate().for_each(|(chunk, values)| {
        let first = (chunk * band) as u64;
        for (x, v) in values.iter_mut().enumerate() {
            *v += pixel_noise(key, first + x as u64, amplitude) as f32;
        }
    });
}

/// What the sensor reads of the light `light` (less `less`, pixel by pixel, when given:
/// one shot of a complementary pair from the pair's sum), into `out`: saturated to 0..255,
/// plus the noise of image key `noise.0` at amplitude `noise.1` if given.
pub fn sense(light: &[f32], less: Option<&[f32]>, noise: Option<(u64, u32)>, out: &mut [f32]) {
    let band = 4096;
    out.par_chunks_mut(band).enumerate().for_each(|(chunk, out)| {
        let span = chunk * band..chunk * band + out.len();
        sense_band(&light[span.clone()], less.map(|l| &l[span]), noise, (chunk * band) as u64, out);
    });
}

camplace_estimator::multiversion! {
    /// [`sense`] of one band, the first of whose pixels is pixel `first` of the image.
    fn sense_band(light: &[f32], less: Option<&[f32]>, noise: Option<(u64, u32)>, first: u64, out: &mut [f32]) => sense_band_body
}

#[inline(always)]
fn sense_band_body(light: &[f32], less: Option<&[f32]>, noise: Option<(u64, u32)>, first: u64, out: &mut [f32]) {
    match less {
        Some(less) => {
            for ((o, &a), &b) in out.iter_mut().zip(light).zip(less) {
                *o = a - b;
            }
        }
        None => out.copy_from_slice(light),
    }
    read_out(out, first, noise);
}

/// The sensor's reading of a run of light, in place: saturated to 0..255, plus the noise
/// of image key `noise.0` at amplitude `noise.1` if given; `first` is the run's first
/// pixel in the image.
#[inline(always)]
pub(crate) fn read_out(values: &mut [f32], first: u64, noise: Option<(u64, u32)>) {
    for v in values.iter_mut() {
        *v = v.clamp(0.0, 255.0);
    }
    if let Some((key, amplitude)) = noise.filter(|n| n.1 > 0) {
        for (x, v) in values.iter_mut().enumerate() {
            *v += pixel_noise(key, first + x as u64, amplitude) as f32;
        }
    }
}

/// `v.round().clamp(0.0, 255.0) as u8` (halves away from zero, NaN to 0) without the
/// library call `round` becomes on x86-64 without SSE4.1.
#[inline(always)]
fn round_to_u8(v: f32) -> u8 {
    // Without branches, so that a row rounds in vector lanes (the choice is a select): a
    // NaN fails the comparison and reads 0; within 0..255 truncation is the floor and the
    // fraction is exact.
    let c = if v >= 0.0 { v.min(255.0) } else { 0.0 };
    // SAFETY: c is finite and within 0..=255, which i32 holds.
    let i = unsafe { c.to_int_unchecked::<i32>() };
    (i + (c - i as f32 >= 0.5) as i32) as u8
}

/// The `blur` x `blur` mean of `image` (edge pixels repeated beyond the border), rounded
/// and clamped into `out`; `scratch` holds the row sums and is resized as needed. `blur`
/// is odd and at most 15 (the cell file's range).
pub fn mean_filter_to_u8(image: &[f32], width: usize, blur: usize, scratch: &mut Vec<f32>, out: &mut [u8]) {
    if blur <= 1 {
        out.par_chunks_mut(width * CHUNK_ROWS).zip(image.par_chunks(width * CHUNK_ROWS)).for_each(|(o, i)| {
            round_band(i, o);
        });
        return;
    }
    scratch.clear();
    scratch.resize(image.len(), 0.0);
    let band = width * CHUNK_ROWS;
    scratch.par_chunks_mut(band).zip(image.par_chunks(band)).for_each(|(s, rows)| {
        row_sums(rows, width, blur, s);
    });
    let sums = &scratch[..];
    out.par_chunks_mut(band).enumerate().for_each(|(chunk, o)| {
        column_means(sums, width, blur, chunk * CHUNK_ROWS, o);
    });
}

camplace_estimator::multiversion! {
    /// Rounds and clamps `values` into `out`.
    fn round_band(values: &[f32], out: &mut [u8]) => round_band_body
}

#[inline(always)]
fn round_band_body(values: &[f32], out: &mut [u8]) {
    for (o, &v) in out.iter_mut().zip(values) {
        *o = round_to_u8(v);
    }
}

camplace_estimator::multiversion! {
    /// The `blur`-wide horizontal sums of the rows of `rows` (`width` px each) into `out`.
    fn row_sums(rows: &[f32], width: usize, blur: usize, out: &mut [f32]) => row_sums_body
}

#[inline(always)]
fn row_sums_body(rows: &[f32], width: usize, blur: usize, out: &mut [f32]) {
    let r = blur / 2;
    for (s, row) in out.chunks_mut(width).zip(rows.chunks(width)) {
        if blur == 3 && width >= 3 {
            // The paper's filter: three slices added, which runs in vector lanes.
            let n = width;
            for (((s, &a), &b), &c) in s[1..n - 1].iter_mut().zip(&row[..n - 2]).zip(&row[1..n - 1]).zip(&row[2..]) {
                *s = a + b + c;
            }
            s[0] = row[0] + row[0] + row[1];
            s[n - 1] = row[n - 2] + row[n - 1] + row[n - 1];
            continue;
        }
        for (x, s) in s.iter_mut().enumerate() {
            *s = if x >= r && x + r < width {
                // Away from the borders: no index clamping, which lets the loop vectorise.
                row[x - r..=x + r].iter().sum()
            } else {
                (0..blur).map(|dx| row[(x + dx).saturating_sub(r).min(width - 1)]).sum()
            };
        }
    }
}

camplace_estimator::multiversion! {
    /// The `blur` x `blur` means of the rows from `y0` on, from the row sums `sums`,
    /// rounded and clamped into `out`.
    fn column_means(sums: &[f32], width: usize, blur: usize, y0: usize, out: &mut [u8]) => column_means_body
}

#[inline(always)]
fn column_means_body(sums: &[f32], width: usize, blur: usize, y0: usize, out: &mut [u8]) {
    let (r, height) = (blur / 2, sums.len() / width);
    let scale = 1.0 / (blur * blur) as f32;
    for (dy0, o) in out.chunks_mut(width).enumerate() {
        let y = y0 + dy0;
        let mut rows: [&[f32]; 15] = [&[]; 15];
        for (dy, row) in rows.iter_mut().take(blur).enumerate() {
            let yy = (y + dy).saturating_sub(r).min(height - 1);
            *row = &sums[yy * width..(yy + 1) * width];
        }
        if blur == 3 {
            let (a, b, c) = (&rows[0][..o.len()], &rows[1][..o.len()], &rows[2][..o.len()]);
            for (((o, &a), &b), &c) in o.iter_mut().zip(a).zip(b).zip(c) {
                *o = round_to_u8((a + b + c) * scale);
            }
            continue;
        }
        for (x, o) in o.iter_mut().enumerate() {
            let mut sum = 0.0;
            for row in &rows[..blur] {
                sum += row[x];
            }
            *o = round_to_u8(sum * scale);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::seeds::image_key;

    #[test]
    fn noise_values_are_pinned() {
        assert_eq!(pixel_noise(0x1234, 0, 4), 2);
        assert_eq!(pixel_noise(0x1234, 1000, 4), -4);
        assert_eq!(pixel_noise(0x1234, 7, 0), 0);
    }

    #[test]
    fn noise_is_uniform_over_its_integers() {
        let a = 10;
        let mut counts = [0u32; 21];
        let n = 210_000u64;
        for p in 0..n {
            let v = pixel_noise(image_key(7, 0, 0), p, a);
            assert!((-10..=10).contains(&v));
            counts[(v + 10) as usize] += 1;
        }
        // Each bin expects 10000 with a standard deviation of about 98.
        assert!(counts.iter().all(|&c| c.abs_diff(10_000) < 500), "{counts:?}");
        let same =
            (0..1000).filter(|&p| pixel_noise(image_key(7, 0, 0), p, a) == pixel_noise(image_key(7, 1, 0), p, a));
        assert!(same.count() < 100);
    }

    #[test]
    fn rounding_matches_the_library_round() {
        let mut values: Vec<f32> = vec![f32::NAN, -0.0, 0.0, -0.5, 0.5, 0.49999997, 254.5, 254.49998, 255.0, 1e9, -1e9];
        values.extend((0..200_000).map(|i| (pixel_noise(5, i, 1 << 20) as f32) / 3000.0 + 128.0));
        values.extend((0..600).map(|i| i as f32 / 2.0 - 20.0));
        for v in values {
            assert_eq!(round_to_u8(v), v.round().clamp(0.0, 255.0) as u8, "{v}");
        }
    }

    #[test]
    fn mean_filter_matches_the_plain_mean() {
        for (w, h) in [(37, 23), (2, 5), (3, 1)] {
            mean_filter_is_the_plain_mean(w, h);
        }
    }

    fn mean_filter_is_the_plain_mean(w: usize, h: usize) {
        let img: Vec<f32> = (0..w * h).map(|i| (pixel_noise(3, i as u64, 100) + 120) as f32).collect();
        for blur in [1, 3, 5] {
            let mut out = vec![0u8; w * h];
            let mut scratch = Vec::new();
            mean_filter_to_u8(&img, w, blur, &mut scratch, &mut out);
            let r = blur as i64 / 2;
            for y in 0..h as i64 {
                for x in 0..w as i64 {
                    let mut sum = 0.0f64;
                    for dy in -r..=r {
                        for dx in -r..=r {
                            let (xx, yy) = ((x + dx).clamp(0, w as i64 - 1), (y + dy).clamp(0, h as i64 - 1));
                            sum += img[(yy * w as i64 + xx) as usize] as f64;
                        }
                    }
                    let want = (sum / (blur * blur) as f64).round().clamp(0.0, 255.0) as u8;
                    assert_eq!(out[(y * w as i64 + x) as usize], want, "blur {blur} at ({x}, {y})");
                }
            }
        }
    }
}
