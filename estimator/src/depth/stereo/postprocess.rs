//! What follows dense matching on a disparity image (+inf = invalid): speckle removal and
//! small-gap interpolation. Sub-pixel refinement is `subpixel`.

use std::ops::Range;

use rayon::prelude::*;

/// Disparities differing by more than this (px) across a gap are an edge, not a surface.
const GAP_SURFACE_PX: f32 = 1.0;

/// Rows a task finds and joins runs in by itself: enough work to be worth a fork.
const BLOCK_ROWS: usize = 32;

/// A run of one row's pixels that are valid and each similar to the previous, as a
/// union-find node.
#[derive(Debug, Clone, Copy, Default)]
struct Run {
    /// Columns `start..end`.
    start: u32,
    end: u32,
    /// The parent run's slot; at a root, `size` is the component's pixel count.
    parent: u32,
    size: u32,
}

// SAFETY: `Run` is four `u32`s, for which all zero bits are a valid value.
unsafe impl bytemuck::Zeroable for Run {}

/// Scratch of the connected-component pass, sized once.
#[derive(Debug, Clone)]
pub struct SpeckleScratch {
    /// Row y's runs, left to right, in slots `y * width..`: a row has at most `width`.
    runs: Vec<Run>,
    /// Runs per row.
    count: Vec<u32>,
}

impl SpeckleScratch {
    /// Buffers for `width` x `height` images. The run slots are allocated zeroed, which the
    /// allocator does by mapping pages on first use: a row's slots are written only as far
    /// as its runs reach (a few dozen of `width`), so most of them never take memory.
    pub fn new(width: usize, height: usize) -> Self {
        SpeckleScratch { runs: bytemuck::zeroed_vec(width * height), count: vec![0; height] }
    }
}

/// The disparity image and the similarity that joins neighbours.
#[derive(Clone, Copy)]
struct Similar<'a> {
    disp: &'a [f32],
    width: usize,
    similarity: f32,
}

/// Invalidates 4-connected regions of fewer than `min_size` pixels whose neighbours differ
/// by at most `similarity` px.
///
/// Components are unions of row runs. Blocks of rows find their runs and join each with
/// the overlapping runs of the row above, wherever one pair of pixels is similar, in
/// parallel; neighbouring blocks are then joined across their boundary row, and the runs
/// of small components cleared per row in parallel. Which pixels go depends only on the
/// components, not on the order they are joined in.
pub fn remove_speckles(disp: &mut [f32], width: usize, min_size: usize, similarity: f32, s: &mut SpeckleScratch) {
    if min_size <= 1 {
        return;
    }
    let n = disp.len();
    let height = n / width;
    debug_assert_eq!(n, width * height, "a whole number of rows");
    if s.runs.len() < n || s.count.len() < height {
        *s = SpeckleScratch::new(width, height);
    }
    let image = Similar { disp, width, similarity };
    components(image, 0..height, &mut s.runs[..n], &mut s.count[..height]);
    let runs = &s.runs[..n];
    disp.par_chunks_mut(width).zip(&s.count[..height]).enumerate().for_each(|(y, (row, &count))| {
        for (slot, run) in (y * width..).zip(&runs[y * width..y * width + count as usize]) {
            let mut root = slot;
            while runs[root].parent as usize != root {
                root = runs[root].parent as usize;
            }
            if (runs[root].size as usize) < min_size {
                row[run.start as usize..run.end as usize].fill(f32::INFINITY);
            }
        }
    });
}

/// Finds the runs of `rows` and joins them into components; `runs` and `count` hold the
/// slots and run counts of those rows, from the first one on.
fn components(image: Similar<'_>, rows: Range<usize>, runs: &mut [Run], count: &mut [u32]) {
    let width = image.width;
    if rows.len() <= BLOCK_ROWS {
        for y in rows.clone() {
            let row = &image.disp[y * width..(y + 1) * width];
            let slots = &mut runs[(y - rows.start) * width..][..width];
            let (mut k, mut x) = (0, 0);
            while x < width {
                if !row[x].is_finite() {
                    x += 1;
                    continue;
                }
                let start = x;
                x += 1;
                while x < width && row[x].is_finite() && (row[x] - row[x - 1]).abs() <= image.similarity {
                    x += 1;
                }
                let parent = (y * width + k) as u32;
                slots[k] = Run { start: start as u32, end: x as u32, parent, size: (x - start) as u32 };
                k += 1;
            }
            count[y - rows.start] = k as u32;
            if y > rows.start {
                join_rows(image, rows.start, runs, count, y);
            }
        }
        return;
    }
    let mid = rows.start + rows.len() / 2;
    let (runs_above, runs_below) = runs.split_at_mut((mid - rows.start) * width);
    let (count_above, count_below) = count.split_at_mut(mid - rows.start);
    rayon::join(
        || components(image, rows.start..mid, runs_above, count_above),
        || components(image, mid..rows.end, runs_below, count_below),
    );
    join_rows(image, rows.start, runs, count, mid);
}

/// Joins the runs of row `y` with those of the row above that they touch through a pair
/// of similar pixels; `runs` and `count` start at row `first`.
fn join_rows(image: Similar<'_>, first: usize, runs: &mut [Run], count: &[u32], y: usize) {
    let width = image.width;
    let (up, down) = (&image.disp[(y - 1) * width..y * width], &image.disp[y * width..(y + 1) * width]);
    let (above, below) = ((y - 1 - first) * width, (y - first) * width);
    let (mut i, mut j) = (above, below);
    let (i_end, j_end) = (above + count[y - 1 - first] as usize, below + count[y - first] as usize);
    let base = first * width;
    while i < i_end && j < j_end {
        let (a, b) = (runs[i], runs[j]);
        let overlap = a.start.max(b.start) as usize..a.end.min(b.end) as usize;
        if overlap.clone().any(|x| (down[x] - up[x]).abs() <= image.similarity) {
            join(runs, base, i, j);
        }
        // The run ending first overlaps nothing further on in the other row.
        if a.end <= b.end {
            i += 1;
        } else {
            j += 1;
        }
    }
}

/// The root of the run at index `r` of `runs`, whose slots start at `base`, halving the
/// path there.
#[inline]
fn find(runs: &mut [Run], base: usize, mut r: usize) -> usize {
    loop {
        let parent = runs[r].parent as usize - base;
        if parent == r {
            return r;
        }
        let grandparent = runs[parent].parent;
        runs[r].parent = grandparent;
        r = grandparent as usize - base;
    }
}

/// Merges the components of the runs at indices `a` and `b`, the smaller under the larger
/// to keep paths short.
#[inline]
fn join(runs: &mut [Run], base: usize, a: usize, b: usize) {
    let (a, b) = (find(runs, base, a), find(runs, base, b));
    if a == b {
        return;
    }
    let (big, small) = if runs[a].size >= runs[b].size { (a, b) } else { (b, a) };
    runs[small].parent = (base + big) as u32;
    runs[big].size += runs[small].size;
}

/// Fills runs of at most `max_gap` invalid pixels between two valid ones along rows, then
/// of at most `max_gap_down` along columns: linearly across a surface, with the farther
/// (smaller) disparity across an edge, so a gap never invents a surface in front of both
/// sides. (The two differ when `disp` holds every other row or fewer.)
pub fn interpolate_gaps(disp: &mut [f32], width: usize, max_gap: usize, max_gap_down: usize) {
    if max_gap == 0 {
        return;
    }
    let height = disp.len() / width;
    disp.par_chunks_mut(width).for_each(|row| fill_line(row, max_gap));
    if max_gap_down == 0 {
        return;
    }
    for x in 0..width {
        let mut run_start: Option<usize> = None;
        let mut last_valid: Option<usize> = None;
        for y in 0..height {
            let d = disp[y * width + x];
            if d.is_finite() {
                if let (Some(s), Some(lv)) = (run_start, last_valid) {
                    let gap = y - s;
                    if gap <= max_gap_down {
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
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Speckle removal by definition: a breadth-first flood fill from every valid pixel
    /// not yet reached, invalidating the regions that stay small.
    fn flood_fill_speckles(disp: &mut [f32], width: usize, min_size: usize, similarity: f32) {
        if min_size <= 1 {
            return;
        }
        let n = disp.len();
        let height = n / width;
        let mut seen = vec![false; n];
        let mut segment = Vec::new();
        for start in 0..n {
            if seen[start] || !disp[start].is_finite() {
                continue;
            }
            segment.clear();
            segment.push(start);
            seen[start] = true;
            let mut next = 0;
            while next < segment.len() {
                let i = segment[next];
                next += 1;
                let (x, y) = (i % width, i / width);
                let d = disp[i];
                let mut visit = |j: usize| {
                    if !seen[j] && disp[j].is_finite() && (disp[j] - d).abs() <= similarity {
                        seen[j] = true;
                        segment.push(j);
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
            if segment.len() < min_size {
                for &i in &segment {
                    disp[i] = f32::INFINITY;
                }
            }
        }
    }

    #[test]
    fn run_components_remove_exactly_what_a_flood_fill_removes() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        // One scratch for all sizes: smaller images reuse it, larger ones regrow it.
        let mut s = SpeckleScratch::new(40, 30);
        let sizes = [(1, 1), (1, 23), (23, 1), (5, 7), (40, 30), (64, 64), (123, 77), (640, 48), (17, 200)];
        let mut removed = 0;
        for &(w, h) in &sizes {
            for trial in 0..16 {
                let invalid = [0.0, 0.1, 0.35, 0.7][trial % 4];
                let (min_size, similarity) = ([0, 1, 2, 5, 20, 150][trial % 6], [0.0, 0.5, 1.0, 2.0][trial / 4]);
                // Blocky surfaces at a few levels with noise: regions join, split and touch
                // across similar and dissimilar edges; a few NaN and -inf stay as they are.
                let (bw, bh) = (rng.random_range(1..12), rng.random_range(1..12));
                let disp: Vec<f32> = (0..w * h)
                    .map(|i| {
                        let (x, y) = (i % w, i / w);
                        match rng.random_range(0..1000) {
                            0 => f32::NAN,
                            1 => f32::NEG_INFINITY,
                            _ if rng.random_bool(invalid) => f32::INFINITY,
                            _ => ((x / bw + 2 * (y / bh)) % 5) as f32 * 1.5 + rng.random_range(0..4) as f32 * 0.25,
                        }
                    })
                    .collect();
                let (mut fast, mut slow) = (disp.clone(), disp.clone());
                remove_speckles(&mut fast, w, min_size, similarity, &mut s);
                flood_fill_speckles(&mut slow, w, min_size, similarity);
                let same = fast.iter().zip(&slow).all(|(a, b)| a.to_bits() == b.to_bits());
                assert!(same, "{w}x{h}, trial {trial}: min size {min_size}, similarity {similarity}");
                removed += disp.iter().zip(&fast).filter(|(a, b)| a.is_finite() && !b.is_finite()).count();
            }
        }
        assert!(removed > 10_000, "{removed}");
    }

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
        let mut s = SpeckleScratch::new(w, h);
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
        interpolate_gaps(&mut d, w, 3, 3);
        assert!((d[w + 2] - 10.2).abs() < 1e-5 && (d[w + 3] - 10.4).abs() < 1e-5);
        assert_eq!(&d[w + 6..w + 9], &[20.0; 3]);
        assert!(d[w].is_infinite() && d[w + 10].is_infinite());
    }
}
