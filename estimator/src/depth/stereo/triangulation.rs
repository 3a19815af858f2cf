//! The ELAS prior: a triangulation of the support points rasterised into a piecewise-planar
//! disparity per pixel, for the left image and, through the same triangles moved by their
//! disparities, for the right one; plus the candidate grid: the support disparities (+-1)
//! found in and around each grid cell.
//!
//! The triangulation is structured by the support grid instead of Delaunay: every grid
//! square is split into two triangles along its main diagonal. Nodes without a support
//! point are filled first, by linear interpolation between the nearest support points along
//! the row or the column, whichever pair is closer together (a Delaunay triangulation
//! would join those two across the hole too), or from the nearest one where a hole reaches
//! the border. On a plane this reproduces the plane exactly; it needs no point location,
//! no flips and no storage beyond buffers sized with the grid, so it never allocates.
//!
//! Both views are rasterised by pixel row in parallel. A triangle moved into the right view
//! stays within the pixel rows of its grid row, so each pixel row draws only the triangles
//! of the grid rows around it, in the order a whole-image pass would: the result does not
//! depend on the number of threads.

use rayon::prelude::*;

use super::cost::DisparityRange;
use super::support::{SupportGrid, SupportPoint, NONE};

/// The filled support grid and the per-pixel plane priors it gives (NaN where no triangle).
#[derive(Clone, Debug)]
pub struct Prior {
    width: usize,
    height: usize,
    /// Nodes per row and column of the filled grid: the support grid plus a last row and
    /// column on the image border when the grid stops short of it.
    cols: usize,
    rows: usize,
    step: usize,
    /// Disparity per filled-grid node (NaN while unknown).
    node: Vec<f32>,
    /// Per node, the nearest support rows above and below and columns left and right
    /// (`u16::MAX` for none).
    up: Vec<u16>,
    down: Vec<u16>,
    left_of: Vec<u16>,
    right_of: Vec<u16>,
    /// Per pixel column, its position across its grid square (0 on the left node, 1 on
    /// the right one): the same for every frame.
    tx: Vec<f32>,
    /// The triangles moved into the right view, two per grid square, row by row.
    moved: Vec<Moved>,
    /// Dense matching's row step: the priors hold every `row_step`-th row from row 0.
    row_step: usize,
    /// Prior disparity per left pixel, of every `row_step`-th row (row j holding image row
    /// j x `row_step`).
    pub left: Vec<f32>,
    /// Prior disparity per right pixel, the same rows.
    pub right: Vec<f32>,
}

const NO_NODE: u16 = u16::MAX;

impl Prior {
    /// Buffers for `width` x `height` images, support points every `step` px and dense
    /// matching on every `row_step`-th row.
    pub fn new(width: usize, height: usize, step: usize, row_step: usize) -> Self {
        let step = step.max(1);
        let row_step = row_step.max(1);
        let cols = width.div_ceil(step) + usize::from(!(width.max(1) - 1).is_multiple_of(step));
        let rows = height.div_ceil(step) + usize::from(!(height.max(1) - 1).is_multiple_of(step));
        let n = cols * rows;
        let tx = if cols < 2 {
            Vec::new()
        } else {
            (0..width)
                .map(|x| {
                    let gx = (x / step).min(cols - 2);
                    let (x0, x1) = (at(gx, step, width), at(gx + 1, step, width));
                    (x - x0) as f32 / (x1 - x0) as f32
                })
                .collect()
        };
        Prior {
            width,
            height,
            cols,
            rows,
            step,
            node: vec![f32::NAN; n],
            up: vec![NO_NODE; n],
            down: vec![NO_NODE; n],
            left_of: vec![NO_NODE; n],
            right_of: vec![NO_NODE; n],
            tx,
            moved: vec![Moved::EMPTY; 2 * cols.saturating_sub(1) * rows.saturating_sub(1)],
            row_step,
            left: vec![f32::NAN; width * height.div_ceil(row_step)],
            right: vec![f32::NAN; width * height.div_ceil(row_step)],
        }
    }

    /// Fills the grid from `support` (same size and step as at construction) and
    /// rasterises both priors on every `row_step`-th row from row 0 within `rows` (first,
    /// one past the last: the rows dense matching reads; the others keep what they held).
    /// Fewer than three support points give no prior.
    pub fn compute(&mut self, support: &SupportGrid, rows: (usize, usize)) {
        let row_step = self.row_step;
        debug_assert_eq!(support.step, self.step);
        let pixel_rows = rows;
        let (cols, rows) = (self.cols, self.rows);
        let valid = support.d.iter().filter(|&&d| d != NONE).count();
        if valid < 3 || self.width == 0 || self.height == 0 {
            self.clear(pixel_rows);
            return;
        }
        // Border nodes beyond the support grid copy their inner neighbour's support point.
        let source = |gx: usize, gy: usize| -> i16 {
            let (sx, sy) = (gx.min(support.cols - 1), gy.min(support.rows - 1));
            support.d[sy * support.cols + sx]
        };
        for gy in 0..rows {
            for gx in 0..cols {
                let d = source(gx, gy);
                self.node[gy * cols + gx] = if d == NONE { f32::NAN } else { d as f32 };
            }
        }
        // Nearest support nodes along rows and columns, both ways.
        for gy in 0..rows {
            let mut last = NO_NODE;
            for gx in 0..cols {
                let i = gy * cols + gx;
                if self.node[i].is_finite() {
                    last = gx as u16;
                }
                self.left_of[i] = last;
            }
            last = NO_NODE;
            for gx in (0..cols).rev() {
                let i = gy * cols + gx;
                if self.node[i].is_finite() {
                    last = gx as u16;
                }
                self.right_of[i] = last;
            }
        }
        for gx in 0..cols {
            let mut last = NO_NODE;
            for gy in 0..rows {
                let i = gy * cols + gx;
                if self.node[i].is_finite() {
                    last = gy as u16;
                }
                self.up[i] = last;
            }
            last = NO_NODE;
            for gy in (0..rows).rev() {
                let i = gy * cols + gx;
                if self.node[i].is_finite() {
                    last = gy as u16;
                }
                self.down[i] = last;
            }
        }
        // Fill: the closer bracketing pair, else the nearest single support point along a
        // row or column; nodes with none of those wait for the spreading pass below.
        for gy in 0..rows {
            for gx in 0..cols {
                let i = gy * cols + gx;
                if self.node[i].is_finite() {
                    continue;
                }
                let (l, r, u, dn) = (self.left_of[i], self.right_of[i], self.up[i], self.down[i]);
                let span = |a: u16, b: u16| if a != NO_NODE && b != NO_NODE { (b - a) as usize } else { usize::MAX };
                let (row_span, col_span) = (span(l, r), span(u, dn));
                let v = if row_span != usize::MAX && row_span <= col_span {
                    let (a, b) = (self.node[gy * cols + l as usize], self.node[gy * cols + r as usize]);
                    a + (b - a) * (gx - l as usize) as f32 / row_span as f32
                } else if col_span != usize::MAX {
                    let (a, b) = (self.node[u as usize * cols + gx], self.node[dn as usize * cols + gx]);
                    a + (b - a) * (gy - u as usize) as f32 / col_span as f32
                } else {
                    // Nearest of the (at most two) one-sided neighbours.
                    let mut best = (usize::MAX, f32::NAN);
                    for (k, horizontal) in [(l, true), (r, true), (u, false), (dn, false)] {
                        if k == NO_NODE {
                            continue;
                        }
                        let (dist, j) = if horizontal {
                            (gx.abs_diff(k as usize), gy * cols + k as usize)
                        } else {
                            (gy.abs_diff(k as usize), k as usize * cols + gx)
                        };
                        if dist < best.0 {
                            best = (dist, self.node[j]);
                        }
                    }
                    best.1
                };
                // Interpolants read only support nodes, which this pass never writes, so
                // filling in place does not depend on the order.
                self.node[i] = v;
            }
        }
        // Nodes whose row and column both lack support: copy the nearest filled node of the
        // same column, then of the same row (every row or column with any support is full).
        for gx in 0..cols {
            let filled = (0..rows).find(|&gy| self.node[gy * cols + gx].is_finite());
            if let Some(first) = filled {
                let mut last = self.node[first * cols + gx];
                for gy in 0..rows {
                    let i = gy * cols + gx;
                    if self.node[i].is_finite() {
                        last = self.node[i];
                    } else {
                        self.node[i] = last;
                    }
                }
            }
        }
        for gy in 0..rows {
            let filled = (0..cols).find(|&gx| self.node[gy * cols + gx].is_finite());
            if let Some(first) = filled {
                let mut last = self.node[gy * cols + first];
                for gx in 0..cols {
                    let i = gy * cols + gx;
                    if self.node[i].is_finite() {
                        last = self.node[i];
                    } else {
                        self.node[i] = last;
                    }
                }
            }
        }
        if cols < 2 || rows < 2 {
            self.clear(pixel_rows);
            return;
        }
        let (width, height, step) = (self.width, self.height, self.step);
        let node = &self.node;
        // The triangles of the right view: those of the left with their corners moved by
        // their disparities.
        let per_row = 2 * (cols - 1);
        self.moved.par_chunks_mut(per_row).enumerate().for_each(|(gy, moved)| {
            let pixel_rows = (at(gy, step, height), at(gy + 1, step, height));
            let (y0, y1) = (pixel_rows.0 as f64, pixel_rows.1 as f64);
            for (gx, pair) in moved.chunks_exact_mut(2).enumerate() {
                let (x0, x1) = (at(gx, step, width) as f64, at(gx + 1, step, width) as f64);
                let d = |i: usize, j: usize| node[(gy + j) * cols + gx + i] as f64;
                let (d00, d10, d01, d11) = (d(0, 0), d(1, 0), d(0, 1), d(1, 1));
                let corners =
                    [[[x0, y0, d00], [x1, y0, d10], [x1, y1, d11]], [[x0, y0, d00], [x1, y1, d11], [x0, y1, d01]]];
                for (m, t) in pair.iter_mut().zip(corners) {
                    *m = Moved::new(&t.map(|[x, y, d]| [x - d, y, d]), pixel_rows);
                }
            }
        });
        let (tx, moved) = (&self.tx, &self.moved);
        let grid = (cols, rows, step, width, height);
        self.left
            .par_chunks_mut(width)
            .zip(self.right.par_chunks_mut(width))
            .enumerate()
            .map(|(j, rows)| (j * row_step, rows))
            .filter(|(y, _)| (pixel_rows.0..pixel_rows.1).contains(y))
            .for_each(|(y, (left, right))| rasterise_row(node, tx, moved, grid, y, left, right));
    }

    /// No prior on the rows [`Prior::compute`] would rasterise.
    fn clear(&mut self, rows: (usize, usize)) {
        let (width, row_step) = (self.width.max(1), self.row_step);
        self.left
            .chunks_mut(width)
            .zip(self.right.chunks_mut(width))
            .enumerate()
            .filter(|(j, _)| (rows.0..rows.1).contains(&(j * row_step)))
            .for_each(|(_, (left, right))| {
                left.fill(f32::NAN);
                right.fill(f32::NAN);
            });
    }
}

multiversion! {
    /// Row `y` of both priors: `left` interpolates the triangles of the filled grid `node`
    /// (`grid` = cols, rows, step, width, height; `tx` the columns' fractions), `right`
    /// draws the `moved` triangles.
    fn rasterise_row(
        node: &[f32],
        tx: &[f32],
        moved: &[Moved],
        grid: (usize, usize, usize, usize, usize),
        y: usize,
        left: &mut [f32],
        right: &mut [f32],
    ) => rasterise_row_body
}

#[inline(always)]
fn rasterise_row_body(
    node: &[f32],
    tx: &[f32],
    moved: &[Moved],
    (cols, rows, step, width, height): (usize, usize, usize, usize, usize),
    y: usize,
    left: &mut [f32],
    right: &mut [f32],
) {
    let per_row = 2 * (cols - 1);
    // Left view: each pixel interpolates the triangle of its grid square. The
    // terms that depend only on the row and the square are formed once per
    // square, from the same operands in the same order as per pixel.
    let gy = (y / step).min(rows - 2);
    let (y0, y1) = (at(gy, step, height), at(gy + 1, step, height));
    let ty = (y - y0) as f32 / (y1 - y0) as f32;
    let (top, bottom) = (&node[gy * cols..(gy + 1) * cols], &node[(gy + 1) * cols..(gy + 2) * cols]);
    for gx in 0..cols - 1 {
        // The last square also takes the columns past its right node's clamp.
        let span = gx * step..if gx + 2 == cols { width } else { (gx + 1) * step };
        let (d00, d10, d01, d11) = (top[gx], top[gx + 1], bottom[gx], bottom[gx + 1]);
        let (upper_slope, upper_offset) = (d10 - d00, ty * (d11 - d10));
        let (lower_base, lower_slope) = (d00 + ty * (d01 - d00), d11 - d01);
        // The square's two triangles share the diagonal (x0, y0)-(x1, y1).
        for (o, &tx) in left[span.clone()].iter_mut().zip(&tx[span]) {
            *o = if tx >= ty { d00 + tx * upper_slope + upper_offset } else { lower_base + tx * lower_slope };
        }
    }
    // Right view: moving is along x only, so a pixel row meets the triangles of
    // at most the two grid rows whose node rows bracket it. They are drawn in
    // the order of a whole-image pass (grid rows, squares, then the pair), so
    // every pixel sees the same sequence of writes and ties resolve the same way.
    right.fill(f32::NAN);
    let g = y / step;
    for gy in g.saturating_sub(1)..=g.min(rows - 2) {
        if y < at(gy, step, height) || y > at(gy + 1, step, height) {
            continue;
        }
        // Spans first, a batch at a time, so that their divisions overlap
        // instead of each waiting on the previous triangle's pixels.
        for batch in moved[gy * per_row..(gy + 1) * per_row].chunks(BATCH) {
            let mut spans = [(1, 0); BATCH];
            for (m, s) in batch.iter().zip(&mut spans) {
                *s = m.span(y, width);
            }
            for (m, &s) in batch.iter().zip(&spans) {
                m.draw(y, s, right);
            }
        }
    }
}

/// Pixel column (row) of filled-grid column (row) `i` on a side of `size` px.
#[inline]
fn at(i: usize, step: usize, size: usize) -> usize {
    (i * step).min(size - 1)
}

/// Triangles whose spans on a row are found together.
const BATCH: usize = 64;

/// One triangle moved into the right view, ready to draw row by row. Its corners lie on
/// two pixel rows (moving is along rows), so it has one edge along a row, its base, and two
/// slanted edges that span every row it covers.
#[derive(Debug, Clone, Copy)]
struct Moved {
    /// The slanted edges in corner order: their first corners' u and v and the steps in u
    /// and v to their second corners, both edges side by side.
    slanted: [[f64; 2]; 4],
    /// The base's row and its smaller and larger u.
    base: [f64; 3],
    /// d = a u + b v + c through the three corners.
    plane: [f64; 3],
    /// The pixel rows it covers, inclusive; empty (first > last) when it has collapsed.
    rows: (usize, usize),
}

impl Moved {
    const EMPTY: Moved = Moved { slanted: [[0.0; 2]; 4], base: [0.0; 3], plane: [0.0; 3], rows: (1, 0) };

    /// The triangle through the (u, v, d) corners `t`, two on pixel row `rows.0` and one
    /// on `rows.1` or the other way round.
    fn new(t: &[[f64; 3]; 3], rows: (usize, usize)) -> Moved {
        let e1 = [t[1][0] - t[0][0], t[1][1] - t[0][1], t[1][2] - t[0][2]];
        let e2 = [t[2][0] - t[0][0], t[2][1] - t[0][1], t[2][2] - t[0][2]];
        let nz = e1[0] * e2[1] - e1[1] * e2[0];
        if nz.abs() < 1e-9 {
            return Moved::EMPTY;
        }
        let nx = e1[1] * e2[2] - e1[2] * e2[1];
        let ny = e1[2] * e2[0] - e1[0] * e2[2];
        let (a, b) = (-nx / nz, -ny / nz);
        let c = t[0][2] - a * t[0][0] - b * t[0][1];
        let edge = |i: usize| (t[i], t[(i + 1) % 3]);
        let base = (0..3).find(|&i| t[i][1] == t[(i + 1) % 3][1]);
        let on_rows = |p: &[f64; 3]| p[1] == rows.0 as f64 || p[1] == rows.1 as f64;
        debug_assert!(base.is_some() && rows.0 < rows.1 && t.iter().all(on_rows), "corners on {rows:?}: {t:?}");
        let base = base.unwrap_or(0);
        let (p, q) = edge(base);
        let [(p1, q1), (p2, q2)] = [1, 2].map(|k| edge((base + k) % 3));
        let slanted = [[p1[0], p2[0]], [p1[1], p2[1]], [q1[0] - p1[0], q2[0] - p2[0]], [q1[1] - p1[1], q2[1] - p2[1]]];
        Moved { slanted, base: [p[1], p[0].min(q[0]), p[0].max(q[0])], plane: [a, b, c], rows }
    }

    /// The columns `lo..=hi` of row `y` the triangle covers, `lo > hi` for none.
    #[inline(always)]
    fn span(&self, y: usize, width: usize) -> (usize, usize) {
        if y < self.rows.0 || y > self.rows.1 {
            return (1, 0);
        }
        let yf = y as f64;
        // The span is the extent of the edges crossing the row, each intersection formed
        // as in corner order. Taking the base last changes nothing: a minimum or maximum
        // does not depend on the order, up to the sign of a zero, which the conversion to a
        // column drops.
        let [u, v, du, dv] = self.slanted;
        let x: [f64; 2] = std::array::from_fn(|i| u[i] + (yf - v[i]) * du[i] / dv[i]);
        let mut x_lo = f64::INFINITY.min(x[0]).min(x[1]);
        let mut x_hi = f64::NEG_INFINITY.max(x[0]).max(x[1]);
        let [base_v, base_lo, base_hi] = self.base;
        if yf == base_v {
            x_lo = x_lo.min(base_lo);
            x_hi = x_hi.max(base_hi);
        }
        let x_lo = x_lo.ceil().max(0.0);
        let x_hi = x_hi.floor().min(width as f64 - 1.0);
        if x_lo > x_hi {
            return (1, 0);
        }
        (x_lo as usize, x_hi as usize)
    }

    /// Writes the plane into columns `lo..=hi` of row `y` where no larger disparity is
    /// already written: triangles moved into the right view overlap where the nearer
    /// surface hides the farther.
    #[inline(always)]
    fn draw(&self, y: usize, (lo, hi): (usize, usize), row: &mut [f32]) {
        if lo > hi {
            return;
        }
        let ([a, b, c], yf) = (self.plane, y as f64);
        for (x, o) in (lo..=hi).zip(&mut row[lo..=hi]) {
            // Through i64, one instruction and the same value as from usize.
            let d = (a * x as i64 as f64 + b * yf + c) as f32;
            if o.is_nan() || d > *o {
                *o = d;
            }
        }
    }
}

/// Entries after each candidate list that hold the range's lowest disparity.
pub const LIST_PAD: usize = 3;

/// Per grid cell, the disparities its own and its eight neighbour cells' support points
/// suggest (each +-1), as sorted lists in fixed-size slots.
#[derive(Debug, Clone)]
pub struct CandidateGrid {
    pub cell: usize,
    pub cols: usize,
    rows: usize,
    /// Capacity of one cell's list: the largest disparity span + 1.
    slot: usize,
    /// Distance between two cells' lists: `slot` + [`LIST_PAD`].
    stride: usize,
    words: usize,
    bits: Vec<u64>,
    counts: Vec<u16>,
    lists: Vec<u16>,
}

impl CandidateGrid {
    /// A grid of `cell`-px cells over `width` x `height` for spans up to `max_span`.
    pub fn new(width: usize, height: usize, cell: usize, max_span: usize) -> Self {
        let cols = width.div_ceil(cell);
        let rows = height.div_ceil(cell);
        let slot = max_span + 1;
        let words = slot.div_ceil(64);
        let stride = slot + LIST_PAD;
        CandidateGrid {
            cell,
            cols,
            rows,
            slot,
            stride,
            words,
            bits: vec![0; cols * rows * words],
            counts: vec![0; cols * rows],
            lists: vec![0; cols * rows * stride],
        }
    }

    /// Fills the lists from `points` within `range`; `right` places each point at its
    /// right-image column. The lists hold u16, so disparities above u16::MAX (far wider
    /// than any image a rig file allows) are left out.
    pub fn compute(&mut self, points: &[SupportPoint], range: DisparityRange, right: bool) {
        let (d_min, d_max) = (range.d_min(), range.d_max());
        self.bits.fill(0);
        let span = (d_max - d_min).min(self.slot as i32 - 1).min(u16::MAX as i32 - d_min);
        for p in points {
            let u = if right { p.u - p.d } else { p.u };
            if u < 0 || p.v < 0 {
                continue;
            }
            let (cx, cy) = (u as usize / self.cell, p.v as usize / self.cell);
            if cx >= self.cols || cy >= self.rows {
                continue;
            }
            let cell_bits = &mut self.bits[(cy * self.cols + cx) * self.words..][..self.words];
            for d in p.d - 1..=p.d + 1 {
                let k = d - d_min;
                if (0..=span).contains(&k) {
                    cell_bits[k as usize / 64] |= 1 << (k as usize % 64);
                }
            }
        }
        for cy in 0..self.rows {
            for cx in 0..self.cols {
                let list = &mut self.lists[(cy * self.cols + cx) * self.stride..][..self.stride];
                let mut n = 0;
                for word in 0..self.words {
                    let mut m = 0u64;
                    for ny in cy.saturating_sub(1)..(cy + 2).min(self.rows) {
                        for nx in cx.saturating_sub(1)..(cx + 2).min(self.cols) {
                            m |= self.bits[(ny * self.cols + nx) * self.words + word];
                        }
                    }
                    while m != 0 {
                        let b = m.trailing_zeros() as usize;
                        m &= m - 1;
                        list[n] = (word * 64 + b) as u16 + d_min as u16;
                        n += 1;
                    }
                }
                list[n..n + LIST_PAD].fill(d_min.min(u16::MAX as i32) as u16);
                self.counts[cy * self.cols + cx] = n as u16;
            }
        }
    }

    /// The candidate disparities of the cell holding pixel (x, y), ascending, followed by
    /// [`LIST_PAD`] copies of the lowest disparity of the range: vector code may read whole
    /// groups of four past the list's end.
    #[inline]
    pub fn padded_at(&self, x: usize, y: usize) -> &[u16] {
        let c = (y / self.cell).min(self.rows - 1) * self.cols + (x / self.cell).min(self.cols - 1);
        &self.lists[c * self.stride..c * self.stride + self.counts[c] as usize + LIST_PAD]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A support grid holding the integer disparity plane `d(u, v)` at every node that
    /// `keep` lets through.
    fn grid_of(
        w: usize,
        h: usize,
        step: usize,
        d: impl Fn(f64, f64) -> f64,
        keep: impl Fn(usize, usize) -> bool,
    ) -> SupportGrid {
        let mut g = SupportGrid::new(w, h, step);
        for gy in 0..g.rows {
            for gx in 0..g.cols {
                g.d[gy * g.cols + gx] =
                    if keep(gx, gy) { d((gx * step) as f64, (gy * step) as f64) as i16 } else { NONE };
            }
        }
        g
    }

    /// The priors by the plain definition, from the filled nodes of `p`: per pixel of the
    /// left view, and triangle by triangle over the whole right view.
    fn serial_views(p: &Prior, support: &SupportGrid) -> (Vec<f32>, Vec<f32>) {
        let (width, height, cols, rows) = (p.width, p.height, p.cols, p.rows);
        let mut left = vec![f32::NAN; width * height];
        let mut right = vec![f32::NAN; width * height];
        let valid = support.d.iter().filter(|&&d| d != NONE).count();
        if valid < 3 || width == 0 || height == 0 || cols < 2 || rows < 2 {
            return (left, right);
        }
        let at = |i: usize, size: usize| (i * p.step).min(size - 1);
        for y in 0..height {
            let gy = (y / p.step).min(rows - 2);
            let (y0, y1) = (at(gy, height), at(gy + 1, height));
            let ty = (y - y0) as f32 / (y1 - y0) as f32;
            let (top, bottom) = (&p.node[gy * cols..(gy + 1) * cols], &p.node[(gy + 1) * cols..(gy + 2) * cols]);
            for x in 0..width {
                let gx = (x / p.step).min(cols - 2);
                let (x0, x1) = (at(gx, width), at(gx + 1, width));
                let tx = (x - x0) as f32 / (x1 - x0) as f32;
                let (d00, d10, d01, d11) = (top[gx], top[gx + 1], bottom[gx], bottom[gx + 1]);
                left[y * width + x] = if tx >= ty {
                    d00 + tx * (d10 - d00) + ty * (d11 - d10)
                } else {
                    d00 + ty * (d01 - d00) + tx * (d11 - d01)
                };
            }
        }
        for gy in 0..rows - 1 {
            let (y0, y1) = (at(gy, height) as f64, at(gy + 1, height) as f64);
            for gx in 0..cols - 1 {
                let (x0, x1) = (at(gx, width) as f64, at(gx + 1, width) as f64);
                let d = |i: usize, j: usize| p.node[(gy + j) * cols + gx + i] as f64;
                let (d00, d10, d01, d11) = (d(0, 0), d(1, 0), d(0, 1), d(1, 1));
                for t in [[[x0, y0, d00], [x1, y0, d10], [x1, y1, d11]], [[x0, y0, d00], [x1, y1, d11], [x0, y1, d01]]]
                {
                    rasterise_nearest(&t.map(|[x, y, d]| [x - d, y, d]), width, height, &mut right);
                }
            }
        }
        (left, right)
    }

    /// Writes the plane through the triangle's three (u, v, d) corners into the pixels it
    /// covers, where no larger disparity is already written.
    fn rasterise_nearest(t: &[[f64; 3]; 3], width: usize, height: usize, out: &mut [f32]) {
        let e1 = [t[1][0] - t[0][0], t[1][1] - t[0][1], t[1][2] - t[0][2]];
        let e2 = [t[2][0] - t[0][0], t[2][1] - t[0][1], t[2][2] - t[0][2]];
        let nz = e1[0] * e2[1] - e1[1] * e2[0];
        if nz.abs() < 1e-9 {
            return;
        }
        let nx = e1[1] * e2[2] - e1[2] * e2[1];
        let ny = e1[2] * e2[0] - e1[0] * e2[2];
        let (a, b) = (-nx / nz, -ny / nz);
        let c = t[0][2] - a * t[0][0] - b * t[0][1];
        let y_lo = t.iter().map(|p| p[1]).fold(f64::INFINITY, f64::min).ceil().max(0.0);
        let y_hi = t.iter().map(|p| p[1]).fold(f64::NEG_INFINITY, f64::max).floor().min(height as f64 - 1.0);
        if y_lo > y_hi {
            return;
        }
        for y in y_lo as usize..=y_hi as usize {
            let yf = y as f64;
            let (mut x_lo, mut x_hi) = (f64::INFINITY, f64::NEG_INFINITY);
            for i in 0..3 {
                let (p, q) = (t[i], t[(i + 1) % 3]);
                if (p[1] <= yf && yf <= q[1]) || (q[1] <= yf && yf <= p[1]) {
                    if p[1] == q[1] {
                        x_lo = x_lo.min(p[0].min(q[0]));
                        x_hi = x_hi.max(p[0].max(q[0]));
                    } else {
                        let x = p[0] + (yf - p[1]) * (q[0] - p[0]) / (q[1] - p[1]);
                        x_lo = x_lo.min(x);
                        x_hi = x_hi.max(x);
                    }
                }
            }
            let x_lo = x_lo.ceil().max(0.0);
            let x_hi = x_hi.floor().min(width as f64 - 1.0);
            if x_lo > x_hi {
                continue;
            }
            let row = &mut out[y * width..(y + 1) * width];
            for (x, o) in row.iter_mut().enumerate().take(x_hi as usize + 1).skip(x_lo as usize) {
                let d = (a * x as f64 + b * yf + c) as f32;
                if o.is_nan() || d > *o {
                    *o = d;
                }
            }
        }
    }

    fn same_bits(a: &[f32], b: &[f32]) -> bool {
        a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
    }

    #[test]
    fn the_row_parallel_views_match_the_serial_definition_bit_for_bit() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        // Grids ending on the border and short of it, single squares, thin images.
        let sizes = [
            (101, 61, 5),
            (103, 64, 5),
            (97, 50, 4),
            (64, 48, 7),
            (33, 17, 3),
            (7, 5, 2),
            (2, 2, 1),
            (10, 3, 5),
            (3, 40, 6),
            (1, 9, 2),
            (640, 480, 5),
        ];
        let mut compared = 0;
        for &(w, h, step) in &sizes {
            let mut prior = Prior::new(w, h, step, 1);
            for trial in 0..12 {
                let hole = [0.0, 0.3, 0.7, 0.97][trial % 4];
                // Surfaces from gentle to torn: steep slopes and jumps fold moved triangles
                // over each other and collapse some; disparity 0 gives signed zeros.
                let (slope, jump, base) =
                    ([0.0, 0.3, 2.5][trial % 3], rng.random_range(0..40), rng.random_range(0..30));
                let mut g = SupportGrid::new(w, h, step);
                for gy in 0..g.rows {
                    for gx in 0..g.cols {
                        let noise = rng.random_range(0..3);
                        let box_ = if (gx / 3 + gy / 2) % 4 == 0 { jump } else { 0 };
                        let d = base as f64 + slope * (gx as f64 - gy as f64 * 0.5) + (noise + box_) as f64;
                        g.d[gy * g.cols + gx] = if rng.random_bool(hole) { NONE } else { d.max(0.0) as i16 };
                    }
                }
                prior.compute(&g, (0, usize::MAX));
                let (left, right) = serial_views(&prior, &g);
                assert!(same_bits(&prior.left, &left), "left view differs at {w}x{h}/{step}, trial {trial}");
                assert!(same_bits(&prior.right, &right), "right view differs at {w}x{h}/{step}, trial {trial}");
                // With a row step the rasterised rows are those rows of the full views.
                let row_step = 2 + trial % 3;
                let mut stepped = Prior::new(w, h, step, row_step);
                stepped.compute(&g, (0, usize::MAX));
                assert_eq!(stepped.left.len(), w * h.div_ceil(row_step));
                for (j, y) in (0..h).step_by(row_step).enumerate() {
                    let (row, held) = (y * w..(y + 1) * w, j * w..(j + 1) * w);
                    assert!(same_bits(&stepped.left[held.clone()], &left[row.clone()]), "left row {y} / {row_step}");
                    assert!(same_bits(&stepped.right[held], &right[row]), "right row {y} / {row_step}");
                }
                compared += right.iter().filter(|v| !v.is_nan()).count();
            }
        }
        assert!(compared > 100_000, "{compared}");
    }

    #[test]
    fn a_plane_with_holes_comes_back_exactly_in_both_views() {
        // Disparity 40 + 0.2 u + 0.2 v is an integer on every node of a 5 px grid; holes
        // (single nodes and a block) lie inside, so every filled node is interpolated.
        let (w, h, step) = (101, 61, 5);
        let plane = |u: f64, v: f64| 40.0 + 0.2 * u + 0.2 * v;
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let holes: Vec<bool> = (0..21 * 13).map(|_| rng.random_range(0..4) == 0).collect();
        let keep = |gx: usize, gy: usize| {
            let border = gx == 0 || gy == 0 || gx == 20 || gy == 12;
            let block = (6..12).contains(&gx) && (4..9).contains(&gy);
            border || (!block && !holes[gy * 21 + gx])
        };
        let g = grid_of(w, h, step, plane, keep);
        let mut prior = Prior::new(w, h, step, 1);
        prior.compute(&g, (0, usize::MAX));
        for y in 0..h {
            for x in 0..w {
                let expect = plane(x as f64, y as f64);
                let got = prior.left[y * w + x] as f64;
                assert!((got - expect).abs() < 1e-3, "left ({x}, {y}): {got} vs {expect}");
            }
        }
        // Right pixel xr sees the left column x with x - d(x, y) = xr.
        let mut checked = 0;
        for y in 0..h {
            for xr in 0..w {
                let x = (xr as f64 + 40.0 + 0.2 * y as f64) / 0.8;
                if x > (w - 1) as f64 {
                    continue;
                }
                let got = prior.right[y * w + xr] as f64;
                if x >= 0.0 {
                    assert!((got - plane(x, y as f64)).abs() < 1e-3, "right ({xr}, {y}): {got}");
                    checked += 1;
                }
            }
        }
        assert!(checked > w * h / 4);
    }

    #[test]
    fn the_nearer_surface_wins_in_the_right_view_and_sparse_grids_still_cover() {
        // A box 20 px nearer than its background on the left half: in the right view the
        // moved box covers background, which must not show through.
        let (w, h, step) = (120, 40, 5);
        let d = |u: f64, _v: f64| if u < 60.0 { 50.0 } else { 30.0 };
        let g = grid_of(w, h, step, d, |_, _| true);
        let mut prior = Prior::new(w, h, step, 1);
        prior.compute(&g, (0, usize::MAX));
        // Right column 5 sees the box (left column 55, disparity 50) and the background
        // (left column 35 is box territory, so only the box).
        assert!((prior.right[20 * w + 5] - 50.0).abs() < 1e-4, "{}", prior.right[20 * w + 5]);
        // Three support points in one corner cover the whole image.
        let g = grid_of(w, h, step, |_, _| 33.0, |gx, gy| gx + gy <= 1);
        prior.compute(&g, (0, usize::MAX));
        assert!(prior.left.iter().all(|&p| (p - 33.0).abs() < 1e-4));
        // Two are not enough for a plane.
        let g = grid_of(w, h, step, |_, _| 33.0, |gx, gy| gx + gy == 0 || (gx, gy) == (3, 3));
        prior.compute(&g, (0, usize::MAX));
        assert!(prior.left.iter().all(|p| p.is_nan()));
    }
}
