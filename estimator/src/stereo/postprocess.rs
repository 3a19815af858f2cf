//! What follows dense matching on a disparity image (+inf = invalid): speckle removal,
//! sub-pixel refinement on the rectified intensities, and small-gap interpolation.

use rayon::prelude::*;

use crate::image::GrayImage;

/// Disparities differing by more than this (px) across a gap are an edge, not a surface.
const GAP_SURFACE_PX: f32 = 1.0;
/// Gauss-Newton steps of the sub-pixel refinement (the second removes the bias of the first
/// on curved cost).
const SUBPIXEL_STEPS: usize = 2;

/// Scratch of the connected-component pass, sized once.
#[derive(Debug, Clone)]
pub struct SpeckleScratch {
    seen: Vec<bool>,
    segment: Vec<u32>,
}

impl SpeckleScratch {
    /// Buffers for images of `n` pixels.
    pub fn new(n: usize) -> Self {
        SpeckleScratch { seen: vec![false; n], segment: Vec::with_capacity(n) }
    }
}

/// Invalidates 4-connected regions of fewer than `min_size` pixels whose neighbours differ
/// by at most `similarity` px.
pub fn remove_speckles(disp: &mut [f32], width: usize, min_size: usize, similarity: f32, s: &mut SpeckleScratch) {
    if min_size <= 1 {
        return;
    }
    let n = disp.len();
    let height = n / width;
    s.seen.clear();
    s.seen.resize(n, false);
    for start in 0..n {
        if s.seen[start] || !disp[start].is_finite() {
            continue;
        }
        s.segment.clear();
        s.segment.push(start as u32);
        s.seen[start] = true;
        let mut next = 0;
        while next < s.segment.len() {
            let i = s.segment[next] as usize;
            next += 1;
            let (x, y) = (i % width, i / width);
            let d = disp[i];
            let mut visit = |j: usize| {
                if !s.seen[j] && disp[j].is_finite() && (disp[j] - d).abs() <= similarity {
                    s.seen[j] = true;
                    s.segment.push(j as u32);
                }
            };
            if x > 0 {
                visit(i - 1);
            }
            if x + 1 < width {
                visit(i + 1);
            }
            if y > 0 {
                visit(i - width);
            }
            if y + 1 < height {
                visit(i + width);
            }
        }
        if s.segment.len() < min_size {
            for &i in &s.segment {
                disp[i as usize] = f32::INFINITY;
            }
        }
    }
}

/// Fills runs of at most `max_gap` invalid pixels between two valid ones, along rows and
/// then columns: linearly across a surface, with the farther (smaller) disparity across an
/// edge, so a gap never invents a surface in front of both sides.
pub fn interpolate_gaps(disp: &mut [f32], width: usize, max_gap: usize) {
    if max_gap == 0 {
        return;
    }
    let height = disp.len() / width;
    disp.par_chunks_mut(width).for_each(|row| fill_line(row, max_gap));
    for x in 0..width {
        let mut run_start: Option<usize> = None;
        let mut last_valid: Option<usize> = None;
        for y in 0..height {
            let d = disp[y * width + x];
            if d.is_finite() {
                if let (Some(s), Some(lv)) = (run_start, last_valid) {
                    let gap = y - s;
                    if gap <= max_gap {
                        let (d0, d1) = (disp[lv * width + x], d);
                        for k in s..y {
                            disp[k * width + x] = gap_value(d0, d1, (k - lv) as f32 / (y - lv) as f32);
                        }
                    }
                }
                run_start = None;
                last_valid = Some(y);
            } else if run_start.is_none() {
                run_start = Some(y);
            }
        }
    }
}

fn fill_line(row: &mut [f32], max_gap: usize) {
    let mut run_start: Option<usize> = None;
    let mut last_valid: Option<usize> = None;
    for i in 0..row.len() {
        let d = row[i];
        if d.is_finite() {
            if let (Some(s), Some(lv)) = (run_start, last_valid) {
                if i - s <= max_gap {
                    let d0 = row[lv];
                    for k in s..i {
                        row[k] = gap_value(d0, d, (k - lv) as f32 / (i - lv) as f32);
                    }
                }
            }
            run_start = None;
            last_valid = Some(i);
        } else if run_start.is_none() {
            run_start = Some(i);
        }
    }
}

#[inline]
fn gap_value(d0: f32, d1: f32, t: f32) -> f32 {
    if (d0 - d1).abs() <= GAP_SURFACE_PX {
        d0 + (d1 - d0) * t
    } else {
        d0.min(d1)
    }
}

/// Refines integer disparities to sub-pixel ones by Gauss-Newton on the sum of squared
/// intensity differences over a (2 `radius` + 1)^2 window: the right image is sampled
/// linearly at x - d and the gradient is the mean of both images' central differences.
/// Unlike a parabola through three SAD costs this has no pull towards integers. Pixels whose
/// window leaves the image, that lack gradient, or whose step exceeds one pixel keep their
/// integer disparity.
pub fn refine_subpixel(left: &GrayImage, right: &GrayImage, disp: &mut [f32], radius: usize) {
    let (w, h) = (left.width, left.height);
    let r = radius as isize;
    disp.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        if y < radius || y + radius >= h {
            return;
        }
        for x in radius + 1..w.saturating_sub(radius + 1) {
            let d0 = row[x];
            if !d0.is_finite() {
                continue;
            }
            let mut s = d0;
            let mut ok = true;
            for _ in 0..SUBPIXEL_STEPS {
                // Right samples at x + i - s - 1 .. x + i - s + 2 must exist.
                let lo = x as f32 - r as f32 - s - 1.0;
                let hi = x as f32 + r as f32 - s + 2.0;
                if lo < 0.0 || hi > (w - 1) as f32 {
                    ok = false;
                    break;
                }
                let (mut eg, mut gg) = (0.0f32, 0.0f32);
                for j in -r..=r {
                    let yy = (y as isize + j) as usize;
                    let lrow = left.row(yy);
                    let rrow = right.row(yy);
                    for i in -r..=r {
                        let xl = (x as isize + i) as usize;
                        let xr = xl as f32 - s;
                        let x0 = xr.floor();
                        let f = xr - x0;
                        let x0 = x0 as usize;
                        let rv = |k: usize| rrow[k] as f32;
                        let rval = rv(x0) + f * (rv(x0 + 1) - rv(x0));
                        let g0 = rv(x0 + 1) - rv(x0 - 1);
                        let g1 = rv(x0 + 2) - rv(x0);
                        let gr = 0.5 * (g0 + f * (g1 - g0));
                        let gl = 0.5 * (lrow[xl + 1] as f32 - lrow[xl - 1] as f32);
                        let g = 0.5 * (gl + gr);
                        let e = lrow[xl] as f32 - rval;
                        eg += e * g;
                        gg += g * g;
                    }
                }
                if gg < 1e-3 {
                    ok = false;
                    break;
                }
                s -= eg / gg;
            }
            if ok && (s - d0).abs() <= 1.0 {
                row[x] = s;
            }
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn small_speckles_go_large_regions_stay() {
        let (w, h) = (40, 30);
        let mut d = vec![f32::INFINITY; w * h];
        for y in 5..25 {
            for x in 5..30 {
                d[y * w + x] = 20.0 + 0.1 * x as f32;
            }
        }
        for y in 2..4 {
            for x in 33..36 {
                d[y * w + x] = 50.0;
            }
        }
        let mut s = SpeckleScratch::new(w * h);
        remove_speckles(&mut d, w, 20, 1.0, &mut s);
        assert!(d[3 * w + 34].is_infinite());
        assert_eq!(d.iter().filter(|v| v.is_finite()).count(), 20 * 25);
    }

    #[test]
    fn gaps_fill_linearly_on_surfaces_and_with_the_far_side_at_edges() {
        let w = 12;
        let mut d = vec![f32::INFINITY; w * 3];
        d[w + 1] = 10.0;
        d[w + 4] = 10.6;
        d[w + 5] = 30.0;
        d[w + 9] = 20.0;
        interpolate_gaps(&mut d, w, 3);
        assert!((d[w + 2] - 10.2).abs() < 1e-5 && (d[w + 3] - 10.4).abs() < 1e-5);
        assert_eq!(&d[w + 6..w + 9], &[20.0; 3]);
        assert!(d[w].is_infinite() && d[w + 10].is_infinite());
    }

    #[test]
    fn subpixel_recovers_a_fractional_shift() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let (w, h) = (64, 16);
        // A smooth random texture sampled at x (left) and x - shift (right).
        let freqs: Vec<(f32, f32, f32)> = (0..6)
            .map(|_| (rng.random_range(0.2..0.9), rng.random_range(0.0..6.0), rng.random_range(10.0..30.0)))
            .collect();
        let tex = |x: f32, y: f32| {
            let v: f32 = freqs.iter().map(|&(f, p, a)| a * (f * x + p + 0.3 * f * y).sin()).sum();
            (128.0 + v).clamp(0.0, 255.0)
        };
        let shift = 7.3f32;
        let left =
            GrayImage::from_vec(w, h, (0..w * h).map(|i| tex((i % w) as f32, (i / w) as f32).round() as u8).collect())
                .unwrap();
        let right = GrayImage::from_vec(
            w,
            h,
            (0..w * h).map(|i| tex((i % w) as f32 + shift, (i / w) as f32).round() as u8).collect(),
        )
        .unwrap();
        let mut d = vec![7.0f32; w * h];
        refine_subpixel(&left, &right, &mut d, 2);
        let mut errs: Vec<f32> = (4..h - 4)
            .flat_map(|y| (14..w - 6).map(move |x| (y, x)))
            .map(|(y, x)| (d[y * w + x] - shift).abs())
            .collect();
        errs.sort_by(f32::total_cmp);
        assert!(errs[errs.len() / 2] < 0.05, "median error {}", errs[errs.len() / 2]);
    }
}
