//! ICP's model index: a grid over one fixed model view whose cells store their nearest
//! model point, an approximate nearest-neighbour lookup in O(1). The cells are kept in
//! blocks of 4 × 4 × 4, and only blocks with a point within reach are stored: most of a
//! tray's bounding box lies far from its surface.

use nalgebra::{Point3, Vector3};

/// A dense grid over one view (tray frame) whose cells hold the model point nearest to the
/// cell's centre: an O(1) approximate nearest neighbour, off by at most half a cell diagonal,
/// which the point-to-plane residual hardly feels on the tray's flat faces.
///
/// Why not a hash: the model view is fixed and small, so the answer is computed once per
/// cell when the model loads, and a query is two array reads instead of a search.
#[derive(Debug, Clone)]
pub(crate) struct NearestGrid {
    origin: Point3<f32>,
    cell: f32,
    dims: [usize; 3],
    /// Blocks along each axis (`dims` over [`BLOCK`], rounded up).
    blocks: [usize; 3],
    /// Per block, its first cell in `cells`, or `u32::MAX` when no cell of it holds a point.
    block_start: Vec<u32>,
    /// The stored blocks' cells, [`BLOCK_CELLS`] a block (x fastest, then y, then z): the
    /// model point index, or none where no point lies within reach.
    cells: Cells,
}

/// The stored cells: two bytes a cell when the view has fewer than `u16::MAX` points (a
/// tray's view at the surface resolution usually has), four otherwise; the largest value
/// marks a cell without a point.
#[derive(Debug, Clone)]
enum Cells {
    Narrow(Vec<u16>),
    Wide(Vec<u32>),
}

impl Cells {
    fn get(&self, k: usize) -> Option<u32> {
        match self {
            Cells::Narrow(c) => (c[k] != u16::MAX).then_some(c[k] as u32),
            Cells::Wide(c) => (c[k] != u32::MAX).then_some(c[k]),
        }
    }

    #[cfg(test)]
    fn len(&self) -> usize {
        match self {
            Cells::Narrow(c) => c.len(),
            Cells::Wide(c) => c.len(),
        }
    }
}

/// Cells along each edge of a block.
const BLOCK: usize = 4;
const BLOCK_CELLS: usize = BLOCK * BLOCK * BLOCK;

/// Cells per view above which the grid coarsens, bounding memory (4 bytes a cell while it is
/// built) on big trays.
const MAX_GRID_CELLS: usize = 1 << 23;

impl NearestGrid {
    /// A grid of cells about `surface_resolution` wide covering every query within
    /// `max_distance` of `points`.
    pub(crate) fn new(points: &[Point3<f32>], surface_resolution: f32, max_distance: f32) -> Self {
        NearestGrid::with_narrow_below(points, surface_resolution, max_distance, u16::MAX as usize)
    }

    /// [`NearestGrid::new`], its cells two bytes wide when there are fewer than
    /// `narrow_below` points.
    fn with_narrow_below(
        points: &[Point3<f32>],
        surface_resolution: f32,
        max_distance: f32,
        narrow_below: usize,
    ) -> Self {
        let (mut lo, mut hi) = (points[0], points[0]);
        for p in points {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        let mut cell = surface_resolution;
        let (mut reach, mut dims, mut origin);
        loop {
            // A query within max_distance of a point has its cell centre within this of it.
            reach = max_distance + cell * 0.87;
            origin = lo - Vector3::repeat(reach);
            let extent = hi - lo + Vector3::repeat(2.0 * reach);
            dims = [0, 1, 2].map(|a| (extent[a] / cell).ceil() as usize + 1);
            if dims.iter().product::<usize>() <= MAX_GRID_CELLS {
                break;
            }
            cell *= 1.25;
        }
        let n = dims.iter().product::<usize>();
        let mut dense = vec![u32::MAX; n];
        let mut best = vec![f32::INFINITY; n];
        let splat = Splat { origin, cell, dims, reach };
        splat_points(&splat, points, &mut best, &mut dense);
        drop(best);
        let (block_start, stored, blocks) = into_blocks(&dense, dims);
        drop(dense);
        let cells = if points.len() < narrow_below.min(u16::MAX as usize) {
            Cells::Narrow(stored.iter().map(|&i| if i == u32::MAX { u16::MAX } else { i as u16 }).collect())
        } else {
            Cells::Wide(stored)
        };
        NearestGrid { origin, cell, dims, blocks, block_start, cells }
    }

    pub(crate) fn lookup(&self, q: &Point3<f32>) -> Option<u32> {
        let mut c = [0usize; 3];
        for a in 0..3 {
            // Truncation is the floor of a value not below zero (and costs no call to libm's
            // floorf on a CPU without SSE4.1's rounding instructions).
            let v = (q[a] - self.origin[a]) / self.cell;
            if !(v >= 0.0 && (v as usize) < self.dims[a]) {
                return None;
            }
            c[a] = v as usize;
        }
        self.cell_at(c)
    }

    /// The point cell `c` (x, y, z) holds, if any.
    fn cell_at(&self, c: [usize; 3]) -> Option<u32> {
        let [bx, by, bz] = c.map(|v| v / BLOCK);
        let start = self.block_start[(bz * self.blocks[1] + by) * self.blocks[0] + bx];
        if start == u32::MAX {
            return None;
        }
        let [x, y, z] = c.map(|v| v % BLOCK);
        self.cells.get(start as usize + (z * BLOCK + y) * BLOCK + x)
    }
}

/// The dense grid `dense` (x fastest) of `dims` cells kept as blocks: each block's start in
/// the stored cells (`u32::MAX` for a block with no point), the stored cells, and the
/// blocks along each axis.
fn into_blocks(dense: &[u32], dims: [usize; 3]) -> (Vec<u32>, Vec<u32>, [usize; 3]) {
    let blocks = dims.map(|d| d.div_ceil(BLOCK));
    let mut block_start = vec![u32::MAX; blocks.iter().product()];
    let mut cells = Vec::new();
    let mut block = [u32::MAX; BLOCK_CELLS];
    for bz in 0..blocks[2] {
        for by in 0..blocks[1] {
            for bx in 0..blocks[0] {
                block.fill(u32::MAX);
                let mut any = false;
                for z in 0..BLOCK {
                    for y in 0..BLOCK {
                        for x in 0..BLOCK {
                            let (gx, gy, gz) = (bx * BLOCK + x, by * BLOCK + y, bz * BLOCK + z);
                            if gx < dims[0] && gy < dims[1] && gz < dims[2] {
                                let item = dense[(gz * dims[1] + gy) * dims[0] + gx];
                                block[(z * BLOCK + y) * BLOCK + x] = item;
                                any |= item != u32::MAX;
                            }
                        }
                    }
                }
                if any {
                    block_start[(bz * blocks[1] + by) * blocks[0] + bx] = cells.len() as u32;
                    cells.extend_from_slice(&block);
                }
            }
        }
    }
    cells.shrink_to_fit();
    (block_start, cells, blocks)
}

/// The grid's layout, as [`splat_points`] walks it.
struct Splat {
    origin: Point3<f32>,
    cell: f32,
    dims: [usize; 3],
    reach: f32,
}

multiversion! {
    /// Offers each point to every cell whose centre lies within `reach` of it: a cell keeps
    /// the nearest (the earlier on ties) in `cells`, its squared distance in `best`.
    fn splat_points(g: &Splat, points: &[Point3<f32>], best: &mut [f32], cells: &mut [u32]) => splat_points_with
}

#[inline(always)]
fn splat_points_with(g: &Splat, points: &[Point3<f32>], best: &mut [f32], cells: &mut [u32]) {
    let Splat { origin, cell, dims, reach } = *g;
    let reach2 = reach * reach;
    let span = (reach / cell).ceil() as isize;
    let centre_of = |c: isize, a: usize| origin[a] + (c as f32 + 0.5) * cell;
    for (i, p) in points.iter().enumerate() {
        // Every point lies above the origin, where truncation is the floor.
        let c = [0, 1, 2].map(|a| ((p[a] - origin[a]) / cell) as isize);
        for dz in -span..=span {
            let z = c[2] + dz;
            if z < 0 || z >= dims[2] as isize {
                continue;
            }
            let ez = centre_of(z, 2) - p.z;
            for dy in -span..=span {
                let y = c[1] + dy;
                if y < 0 || y >= dims[1] as isize {
                    continue;
                }
                // Only the cells of this row whose centres can lie within reach: the
                // sphere's chord, widened by a cell for rounding (the test below decides).
                let ey = centre_of(y, 1) - p.y;
                let left = reach2 - ez * ez - ey * ey;
                if left < -(cell * cell) {
                    continue;
                }
                // Truncation plus two: at least the ceiling plus one, without libm.
                let chord = (left.max(0.0).sqrt() / cell) as isize + 2;
                let (from, to) = ((-chord).max(-span), chord.min(span));
                let (x_lo, x_hi) = ((c[0] + from).max(0), (c[0] + to).min(dims[0] as isize - 1));
                if x_lo > x_hi {
                    continue;
                }
                let row = (z as usize * dims[1] + y as usize) * dims[0];
                let (x_lo, x_hi) = (x_lo as usize, x_hi as usize);
                let (ey2, ez2) = (ey * ey, ez * ez);
                let run = row + x_lo..row + x_hi + 1;
                for (k, (b, slot)) in best[run.clone()].iter_mut().zip(&mut cells[run]).enumerate() {
                    // (centre - p).norm_squared(), summed in nalgebra's order.
                    let ex = origin.x + ((x_lo + k) as f32 + 0.5) * cell - p.x;
                    let d2 = ex * ex + ey2 + ez2;
                    let nearer = d2 < *b && d2 <= reach2;
                    *b = if nearer { d2 } else { *b };
                    *slot = if nearer { i as u32 } else { *slot };
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Every cell of the grid `new` lays out, each given the nearest point within reach by
    /// a search of all points (the earlier on ties).
    fn cells_by_search(points: &[Point3<f32>], grid: &NearestGrid, reach: f32) -> Vec<u32> {
        let [nx, ny, nz] = grid.dims;
        let mut cells = vec![u32::MAX; nx * ny * nz];
        for z in 0..nz {
            for y in 0..ny {
                for x in 0..nx {
                    let centre = grid.origin + Vector3::new(x as f32 + 0.5, y as f32 + 0.5, z as f32 + 0.5) * grid.cell;
                    let mut best = f32::INFINITY;
                    for (i, p) in points.iter().enumerate() {
                        let d2 = (centre - p).norm_squared();
                        if d2 < best && d2 <= reach * reach {
                            best = d2;
                            cells[(z * ny + y) * nx + x] = i as u32;
                        }
                    }
                }
            }
        }
        cells
    }

    #[test]
    fn every_cell_holds_the_nearest_point_within_reach() {
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        for (n, sres, max_distance) in [(200, 2.0f32, 6.0f32), (60, 1.5, 3.0), (1, 2.0, 6.0), (120, 3.0, 1.0)] {
            let points: Vec<Point3<f32>> = (0..n)
                .map(|_| {
                    Point3::new(
                        rng.random_range(-20.0..20.0),
                        rng.random_range(-15.0..15.0),
                        rng.random_range(0.0..8.0),
                    )
                })
                .collect();
            let grid = NearestGrid::new(&points, sres, max_distance);
            let reach = max_distance + grid.cell * 0.87;
            let [nx, ny, nz] = grid.dims;
            let mut stored = Vec::with_capacity(nx * ny * nz);
            for z in 0..nz {
                for y in 0..ny {
                    for x in 0..nx {
                        stored.push(grid.cell_at([x, y, z]).unwrap_or(u32::MAX));
                    }
                }
            }
            let expected = cells_by_search(&points, &grid, reach);
            assert_eq!(stored, expected, "{n} points, {sres} mm cells");
            // Exactly the blocks holding a point are stored.
            let mut holding = std::collections::HashSet::new();
            for (k, _) in expected.iter().enumerate().filter(|(_, &c)| c != u32::MAX) {
                let (x, y, z) = (k % nx, k / nx % ny, k / (nx * ny));
                holding.insert((x / BLOCK, y / BLOCK, z / BLOCK));
            }
            assert_eq!(grid.cells.len(), holding.len() * BLOCK_CELLS, "{n} points, {sres} mm cells");
            // Four-byte cells (a view of 65 535 points or more) hold the same.
            let wide = NearestGrid::with_narrow_below(&points, sres, max_distance, 0);
            assert!(matches!((&grid.cells, &wide.cells), (Cells::Narrow(_), Cells::Wide(_))));
            for z in 0..nz {
                for y in 0..ny {
                    for x in 0..nx {
                        assert_eq!(wide.cell_at([x, y, z]), grid.cell_at([x, y, z]));
                    }
                }
            }
        }
    }

    #[test]
    fn grid_lookup_is_within_a_cell_diagonal_of_brute_force() {
        let model = testing::tray(false, 1);
        let points = &model.views[2].points;
        let grid = NearestGrid::new(points, 2.0, 6.0);
        let mut rng = ChaCha8Rng::seed_from_u64(8);
        for _ in 0..3000 {
            let base = points[rng.random_range(0..points.len())];
            let q = base
                + Vector3::new(rng.random_range(-8.0..8.0), rng.random_range(-8.0..8.0), rng.random_range(-8.0..8.0));
            let exact = points.iter().map(|p| (p - q).norm()).fold(f32::INFINITY, f32::min);
            match grid.lookup(&q) {
                Some(i) => assert!((points[i as usize] - q).norm() <= exact + 2.0 * 3f32.sqrt() + 1e-4),
                None => assert!(exact > 6.0, "missed a point {exact} mm away"),
            }
        }
    }
}
