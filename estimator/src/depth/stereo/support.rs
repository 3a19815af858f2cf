//! ELAS support points: robust sparse matches on a regular grid (full-range search, a
//! uniqueness ratio, a left-right check), then removal of points that disagree with their
//! neighbourhood. They seed the triangulated prior in `triangulation`.

use rayon::prelude::*;

use super::cost::{run_costs, DisparityRange, Kernel};
use super::descriptor::{sad, texture, DescriptorImage, BORDER};
use crate::depth::PixelRegion;

/// Marks a grid node without a support point.
pub const NONE: i16 = -1;
/// A point needs this many neighbours agreeing within `INCONSISTENCY_PX` ...
const CONSISTENT_NEIGHBOURS: usize = 5;
/// ... in a window of this many grid steps either side.
const CONSISTENCY_WINDOW: usize = 5;
const INCONSISTENCY_PX: i32 = 5;

/// One support point: pixel (u, v) of the left image and its integer disparity.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SupportPoint {
    pub u: i32,
    pub v: i32,
    pub d: i32,
}

/// The support-point grid and its scratch.
#[derive(Debug, Clone)]
pub struct SupportGrid {
    pub step: usize,
    pub cols: usize,
    pub rows: usize,
    /// Disparity per grid node (`NONE` where none).
    pub d: Vec<i16>,
    scratch: Vec<i16>,
}

/// What support matching needs to know.
#[derive(Debug, Clone, Copy)]
pub struct SupportParams {
    pub range: DisparityRange,
    pub uniqueness: f32,
    pub min_texture: i32,
    pub lr_tolerance: i32,
    /// The SAD kernel for the full-range searches.
    pub kernel: Kernel,
}

impl SupportGrid {
    /// A grid of nodes every `step` px over a `width` x `height` image.
    pub fn new(width: usize, height: usize, step: usize) -> Self {
        let cols = width.div_ceil(step);
        let rows = height.div_ceil(step);
        SupportGrid { step, cols, rows, d: vec![NONE; cols * rows], scratch: vec![NONE; cols * rows] }
    }

    /// Matches every grid node inside `region` (the others have none) and drops the points
    /// that disagree with their neighbourhood.
    pub fn compute(&mut self, left: &DescriptorImage, right: &DescriptorImage, p: &SupportParams, region: PixelRegion) {
        let step = self.step;
        self.d.par_chunks_mut(self.cols).enumerate().for_each(|(gy, row)| {
            for (gx, out) in row.iter_mut().enumerate() {
                let (u, v) = (gx * step, gy * step);
                *out = if region.contains(u, v) {
                    support_match(left, right, u, v, p).map_or(NONE, |d| d as i16)
                } else {
                    NONE
                };
            }
        });
        self.remove_inconsistent();
    }

    fn remove_inconsistent(&mut self) {
        let (cols, rows) = (self.cols, self.rows);
        let d = &self.d;
        self.scratch.par_chunks_mut(cols).enumerate().for_each(|(gy, out)| {
            for (gx, o) in out.iter_mut().enumerate() {
                let di = d[gy * cols + gx];
                *o = di;
                if di == NONE {
                    continue;
                }
                let mut agree = 0;
                'window: for y in gy.saturating_sub(CONSISTENCY_WINDOW)..(gy + CONSISTENCY_WINDOW + 1).min(rows) {
                    for x in gx.saturating_sub(CONSISTENCY_WINDOW)..(gx + CONSISTENCY_WINDOW + 1).min(cols) {
                        let dj = d[y * cols + x];
                        if dj != NONE && (dj as i32 - di as i32).abs() <= INCONSISTENCY_PX {
                            agree += 1;
                            if agree > CONSISTENT_NEIGHBOURS {
                                break 'window;
                            }
                        }
                    }
                }
                // `agree` counts the point itself.
                if agree <= CONSISTENT_NEIGHBOURS {
                    *o = NONE;
                }
            }
        });
        std::mem::swap(&mut self.d, &mut self.scratch);
    }

    /// Appends the surviving points to `out` (cleared first).
    pub fn points(&self, out: &mut Vec<SupportPoint>) {
        out.clear();
        for gy in 0..self.rows {
            for gx in 0..self.cols {
                let d = self.d[gy * self.cols + gx];
                if d != NONE {
                    out.push(SupportPoint { u: (gx * self.step) as i32, v: (gy * self.step) as i32, d: d as i32 });
                }
            }
        }
    }
}

/// The disparity of left pixel (u, v) by a full-range search when it is unique and passes
/// the left-right check.
fn support_match(
    left: &DescriptorImage,
    right: &DescriptorImage,
    u: usize,
    v: usize,
    p: &SupportParams,
) -> Option<i32> {
    let w = left.width;
    if u < BORDER || v < BORDER || u + BORDER >= w || v + BORDER >= left.height {
        return None;
    }
    let row = v * w;
    let dl = &left.data[row + u];
    if texture(dl) < p.min_texture {
        return None;
    }
    let (d_min, d_max) = (p.range.d_min(), p.range.d_max());
    // Right pixel u - d must keep its descriptor window.
    let d_hi = d_max.min(u as i32 - BORDER as i32);
    if d_hi < d_min {
        return None;
    }
    let (c1, d1, c2) = if (d_hi - d_min) as usize >= COSTS {
        let mut best = Best4::new();
        for d in d_min..=d_hi {
            best.push(sad(dl, &right.data[row + u - d as usize]), d);
        }
        let (c1, d1) = best.first();
        (c1, d1, best.second_apart(d1))
    } else {
        // All costs first, then the two minima: no data-dependent branch per disparity.
        let mut costs = [0i32; COSTS];
        let costs = &mut costs[..(d_hi - d_min + 1) as usize];
        run_costs::<true>(dl, &right.data, row + u, d_min, costs, p.kernel);
        let (c1, k1) = first_min(costs);
        // The second best excludes the winner's neighbours: on band-limited images they are
        // nearly as good whenever the true disparity falls between two integers.
        let apart = costs.iter().enumerate().filter(|&(k, _)| k.abs_diff(k1) > 1).map(|(_, &c)| c).min();
        (c1, d_min + k1 as i32, apart)
    };
    let c2 = c2?;
    if c1 as f32 >= p.uniqueness * c2 as f32 {
        return None;
    }
    let ur = u - d1 as usize;
    let dr = &right.data[row + ur];
    if texture(dr) < p.min_texture {
        return None;
    }
    let d_hi_r = d_max.min((w - BORDER - 1 - ur) as i32);
    // The first lowest cost, COSTS disparities at a time (a later chunk wins only when
    // strictly lower).
    let mut best_r = (i32::MAX, -1);
    let mut costs = [0i32; COSTS];
    let mut d0 = d_min;
    while d0 <= d_hi_r {
        let chunk = &mut costs[..((d_hi_r - d0 + 1) as usize).min(COSTS)];
        run_costs::<false>(dr, &left.data, row + ur, d0, chunk, p.kernel);
        let (c, k) = first_min(chunk);
        if c < best_r.0 {
            best_r = (c, d0 + k as i32);
        }
        d0 += chunk.len() as i32;
    }
    ((best_r.1 - d1).abs() <= p.lr_tolerance).then_some(d1)
}

/// Disparity ranges up to this many px keep all their costs on the stack; wider ones go
/// through [`Best4`] (the left search) or in chunks (the right one).
const COSTS: usize = 256;

/// The first lowest cost and its index (`costs` not empty).
#[inline]
fn first_min(costs: &[i32]) -> (i32, usize) {
    let mut best = (costs[0], 0);
    for (k, &c) in costs.iter().enumerate().skip(1) {
        if c < best.0 {
            best = (c, k);
        }
    }
    best
}

/// The four lowest costs seen, cheapest first: enough to find the cheapest candidate that
/// is not a neighbour of the winner (at most two entries are).
struct Best4 {
    cost: [i32; 4],
    d: [i32; 4],
}

impl Best4 {
    fn new() -> Self {
        Best4 { cost: [i32::MAX; 4], d: [-1; 4] }
    }

    #[inline(always)]
    fn push(&mut self, c: i32, d: i32) {
        if c >= self.cost[3] {
            return;
        }
        let mut i = 3;
        while i > 0 && self.cost[i - 1] > c {
            self.cost[i] = self.cost[i - 1];
            self.d[i] = self.d[i - 1];
            i -= 1;
        }
        self.cost[i] = c;
        self.d[i] = d;
    }

    fn first(&self) -> (i32, i32) {
        (self.cost[0], self.d[0])
    }

    fn second_apart(&self, d1: i32) -> Option<i32> {
        (1..4).find(|&i| self.d[i] >= 0 && (self.d[i] - d1).abs() > 1).map(|i| self.cost[i])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn best4_finds_cheapest_non_neighbour() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        for _ in 0..500 {
            let costs: Vec<i32> = (0..30).map(|_| rng.random_range(0..50)).collect();
            let mut b = Best4::new();
            for (d, &c) in costs.iter().enumerate() {
                b.push(c, d as i32);
            }
            let (c1, d1) = b.first();
            assert_eq!(c1, *costs.iter().min().unwrap());
            assert_eq!(costs[d1 as usize], c1);
            let slow = costs.iter().enumerate().filter(|(d, _)| (*d as i32 - d1).abs() > 1).map(|(_, &c)| c).min();
            assert_eq!(b.second_apart(d1), slow);
        }
    }
}
