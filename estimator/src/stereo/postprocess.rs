//! What follows dense matching on a disparity image (+inf = invalid): speckle removal and
//! small-gap interpolation. Sub-pixel refinement is `subpixel`.

use rayon::prelude::*;

/// Disparities differing by more than this (px) across a gap are an edge, not a surface.
const GAP_SURFACE_PX: f32 = 1.0;

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
                    for (k, o) in row.iter_mut().enumerate().take(i).skip(s) {
                        *o = gap_value(d0, d, (k - lv) as f32 / (i - lv) as f32);
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

#[cfg(test)]
mod tests {
    use super::*;

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
}
