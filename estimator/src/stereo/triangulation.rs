//! The ELAS prior: a Delaunay triangulation of the support points (spade) rasterised into a
//! piecewise-planar disparity per pixel, for the left image and, through the same triangles
//! moved by their disparities, for the right one; plus the candidate grid: the support
//! disparities (+-1) found in and around each grid cell.

use spade::{DelaunayTriangulation, HasPosition, Point2, Triangulation};

use super::support::SupportPoint;

/// A support point as a triangulation vertex.
#[derive(Debug, Clone, Copy)]
pub struct SupportVertex {
    position: Point2<f64>,
    d: f64,
}

impl HasPosition for SupportVertex {
    type Scalar = f64;

    fn position(&self) -> Point2<f64> {
        self.position
    }
}

/// The triangulation and the per-pixel plane priors it gives (NaN where no triangle).
#[derive(Debug)]
pub struct Prior {
    width: usize,
    height: usize,
    triangulation: DelaunayTriangulation<SupportVertex>,
    /// Prior disparity per left pixel.
    pub left: Vec<f32>,
    /// Prior disparity per right pixel.
    pub right: Vec<f32>,
}

impl Prior {
    /// Buffers for `width` x `height` images and up to `max_points` support points.
    pub fn new(width: usize, height: usize, max_points: usize) -> Self {
        let mut triangulation = DelaunayTriangulation::new();
        // Warm the triangulation's storage so later frames reuse it.
        for i in 0..max_points.min(width * height) {
            let (u, v) = (i % width, i / width);
            let _ = triangulation.insert(SupportVertex { position: Point2::new(u as f64, v as f64), d: 0.0 });
        }
        triangulation.clear();
        Prior {
            width,
            height,
            triangulation,
            left: vec![f32::NAN; width * height],
            right: vec![f32::NAN; width * height],
        }
    }

    /// Triangulates `points` (left pixels) and rasterises both priors. The four image
    /// corners join with the disparity of their nearest support point so the planes cover
    /// the whole image.
    pub fn compute(&mut self, points: &[SupportPoint]) {
        self.left.fill(f32::NAN);
        self.right.fill(f32::NAN);
        self.triangulation.clear();
        if points.len() < 3 {
            return;
        }
        let (w, h) = (self.width as i32, self.height as i32);
        for p in points {
            let _ = self
                .triangulation
                .insert(SupportVertex { position: Point2::new(p.u as f64, p.v as f64), d: p.d as f64 });
        }
        for (cu, cv) in [(0, 0), (w - 1, 0), (0, h - 1), (w - 1, h - 1)] {
            let near =
                points.iter().min_by_key(|p| (p.u - cu).pow(2) + (p.v - cv).pow(2)).expect("three or more points");
            if (near.u, near.v) != (cu, cv) {
                let _ = self
                    .triangulation
                    .insert(SupportVertex { position: Point2::new(cu as f64, cv as f64), d: near.d as f64 });
            }
        }
        let (width, height) = (self.width, self.height);
        for face in self.triangulation.inner_faces() {
            let vs = face.vertices().map(|v| *v.data());
            let left = vs.map(|v| [v.position.x, v.position.y, v.d]);
            rasterise(&left, width, height, &mut self.left, false);
            // The same surface seen from the right: vertex columns move by their disparity.
            let right = vs.map(|v| [v.position.x - v.d, v.position.y, v.d]);
            rasterise(&right, width, height, &mut self.right, true);
        }
    }
}

/// Writes the plane through the triangle's three (u, v, d) corners into the pixels it
/// covers. With `nearest`, a pixel already holding a larger disparity keeps it (triangles
/// moved into the right view may overlap where the nearer surface hides the farther).
fn rasterise(t: &[[f64; 3]; 3], width: usize, height: usize, out: &mut [f32], nearest: bool) {
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
        for x in x_lo as usize..=x_hi as usize {
            let d = (a * x as f64 + b * yf + c) as f32;
            let o = &mut row[x];
            if !nearest || o.is_nan() || d > *o {
                *o = d;
            }
        }
    }
}

/// Per grid cell, the disparities its own and its eight neighbour cells' support points
/// suggest (each +-1), as sorted lists in fixed-size slots.
#[derive(Debug, Clone)]
pub struct CandidateGrid {
    pub cell: usize,
    pub cols: usize,
    rows: usize,
    /// Capacity of one cell's list: the largest disparity span + 1.
    slot: usize,
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
        CandidateGrid {
            cell,
            cols,
            rows,
            slot,
            words,
            bits: vec![0; cols * rows * words],
            counts: vec![0; cols * rows],
            lists: vec![0; cols * rows * slot],
        }
    }

    /// Fills the lists from `points`; `right` places each point at its right-image column.
    pub fn compute(&mut self, points: &[SupportPoint], d_min: i32, d_max: i32, right: bool) {
        self.bits.fill(0);
        let span = (d_max - d_min).min(self.slot as i32 - 1);
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
                let list = &mut self.lists[(cy * self.cols + cx) * self.slot..][..self.slot];
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
                self.counts[cy * self.cols + cx] = n as u16;
            }
        }
    }

    /// The candidate disparities of the cell holding pixel (x, y).
    #[inline]
    pub fn at(&self, x: usize, y: usize) -> &[u16] {
        let c = (y / self.cell).min(self.rows - 1) * self.cols + (x / self.cell).min(self.cols - 1);
        &self.lists[c * self.slot..c * self.slot + self.counts[c] as usize]
    }
}
