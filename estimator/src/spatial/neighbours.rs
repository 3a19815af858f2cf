//! A 3-D neighbour structure over one cloud for radius and k-nearest queries: a hashed
//! uniform grid, rebuilt per frame into buffers it keeps (no allocation once it has seen a
//! cloud as large as the current one). It does not own the cloud; indices refer to the
//! slice given to `build`.

use nalgebra::Point3;

use super::{bucket, pack_cell, table_size, CELL_LIMIT};
use crate::{Error, ErrorKind, Result};

/// A query touching more cells than this scans the whole cloud instead.
const MAX_QUERY_CELLS: usize = 1 << 16;

/// Hashed uniform grid over a cloud: points are counting-sorted by the hash bucket of their
/// cell, so a query reads a few contiguous runs of points. Cells are keyed and hashed as the
/// down-sampling voxels are, but their coordinates are clamped rather than rejected, so a far
/// point lands in an edge cell instead of being dropped.
#[derive(Debug, Clone, Default)]
pub struct Neighbours {
    cell: f32,
    inv_cell: f32,
    /// Bucket b holds sorted entries `starts[b]..starts[b + 1]`.
    starts: Vec<u32>,
    /// Packed cell of each sorted entry, to skip other cells sharing a bucket.
    keys: Vec<u64>,
    points: Vec<Point3<f32>>,
    indices: Vec<u32>,
    /// Bucket of each input point (`u32::MAX` for a non-finite point), kept between passes.
    buckets: Vec<u32>,
    shift: u32,
}

/// Integer cell coordinate of `v`, clamped so it packs into 21 bits.
#[inline]
fn cell_coord(v: f32, inv_cell: f32) -> i64 {
    i64::from(super::floor_i32(v * inv_cell)).clamp(-CELL_LIMIT, CELL_LIMIT - 1)
}

impl Neighbours {
    /// An empty structure; buffers grow on the first `build`.
    pub fn new() -> Self {
        Neighbours::default()
    }

    /// An empty structure with room for clouds of up to `points` points.
    pub fn with_capacity(points: usize) -> Self {
        let (table, _) = table_size(points);
        Neighbours {
            starts: Vec::with_capacity(table + 1),
            keys: Vec::with_capacity(points),
            points: Vec::with_capacity(points),
            indices: Vec::with_capacity(points),
            buckets: Vec::with_capacity(points),
            ..Neighbours::default()
        }
    }

    #[inline]
    fn bucket(&self, key: u64) -> usize {
        bucket(key, self.shift)
    }

    /// Indexes `cloud` with cubic cells of side `cell_size` mm: between half the query
    /// radius and twice it (measured: twice a normal's few-millimetre radius, 8 cells a
    /// query, and half ECSAD's 30 mm are fastest). Non-finite points are left out of every
    /// answer.
    pub fn build(&mut self, cloud: &[Point3<f32>], cell_size: f32) -> Result<()> {
        if !(cell_size.is_finite() && cell_size > 0.0) {
            return Err(Error::new(
                ErrorKind::Input,
                format!("neighbour grid: expected a positive cell size in mm, got {cell_size}"),
            ));
        }
        if cloud.len() >= u32::MAX as usize {
            return Err(Error::new(ErrorKind::Input, "neighbour grid: cloud too large for u32 indices"));
        }
        self.cell = cell_size;
        self.inv_cell = 1.0 / cell_size;
        let (table, shift) = table_size(cloud.len());
        self.shift = shift;
        self.starts.clear();
        self.starts.resize(table + 1, 0);
        self.buckets.clear();
        let mut finite = 0usize;
        for p in cloud {
            if p.x.is_finite() && p.y.is_finite() && p.z.is_finite() {
                let b = self.bucket(self.key_of(p));
                self.starts[b + 1] += 1;
                self.buckets.push(b as u32);
                finite += 1;
            } else {
                self.buckets.push(u32::MAX);
            }
        }
        for b in 0..table {
            self.starts[b + 1] += self.starts[b];
        }
        self.keys.clear();
        self.keys.resize(finite, 0);
        self.points.clear();
        self.points.resize(finite, Point3::origin());
        self.indices.clear();
        self.indices.resize(finite, 0);
        // Scatter in input order, using starts[b] as the cursor, then shift the cursors
        // back so starts[b] is the bucket's beginning again.
        for (i, p) in cloud.iter().enumerate() {
            let b = self.buckets[i];
            if b == u32::MAX {
                continue;
            }
            let slot = self.starts[b as usize] as usize;
            self.starts[b as usize] += 1;
            self.keys[slot] = self.key_of(p);
            self.points[slot] = *p;
            self.indices[slot] = i as u32;
        }
        for b in (1..=table).rev() {
            self.starts[b] = self.starts[b - 1];
        }
        self.starts[0] = 0;
        Ok(())
    }

    #[inline]
    fn key_of(&self, p: &Point3<f32>) -> u64 {
        pack_cell([cell_coord(p.x, self.inv_cell), cell_coord(p.y, self.inv_cell), cell_coord(p.z, self.inv_cell)])
    }

    /// Side of a grid cell, mm.
    pub fn cell_size(&self) -> f32 {
        self.cell
    }

    /// Number of indexed (finite) points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether no point is indexed.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Calls `visit(index, point, distance2)` for every indexed point within `radius` of
    /// `centre` (the centre itself included), in an order fixed by the cloud and the query.
    #[inline]
    pub fn for_each_within(&self, centre: &Point3<f32>, radius: f32, mut visit: impl FnMut(u32, &Point3<f32>, f32)) {
        if self.points.is_empty() || radius.is_nan() || radius < 0.0 {
            return;
        }
        let r2 = radius * radius;
        let lo = [
            cell_coord(centre.x - radius, self.inv_cell),
            cell_coord(centre.y - radius, self.inv_cell),
            cell_coord(centre.z - radius, self.inv_cell),
        ];
        let hi = [
            cell_coord(centre.x + radius, self.inv_cell),
            cell_coord(centre.y + radius, self.inv_cell),
            cell_coord(centre.z + radius, self.inv_cell),
        ];
        let cells = (0..3).map(|a| (hi[a] - lo[a] + 1) as usize).product::<usize>();
        if cells > MAX_QUERY_CELLS.min(self.points.len().max(64)) {
            // A query box spanning many empty cells is cheaper as a scan of the cloud.
            for (p, &i) in self.points.iter().zip(&self.indices) {
                let d2 = (p - centre).norm_squared();
                if d2 <= r2 {
                    visit(i, p, d2);
                }
            }
            return;
        }
        for cz in lo[2]..=hi[2] {
            for cy in lo[1]..=hi[1] {
                for cx in lo[0]..=hi[0] {
                    let key = pack_cell([cx, cy, cz]);
                    let b = self.bucket(key);
                    let (s, e) = (self.starts[b] as usize, self.starts[b + 1] as usize);
                    for j in s..e {
                        if self.keys[j] != key {
                            continue;
                        }
                        let p = &self.points[j];
                        let d2 = (p - centre).norm_squared();
                        if d2 <= r2 {
                            visit(self.indices[j], p, d2);
                        }
                    }
                }
            }
        }
    }

    /// Indices of the points within `radius` of `centre`, into `out` (cleared first).
    pub fn within(&self, centre: &Point3<f32>, radius: f32, out: &mut Vec<u32>) {
        out.clear();
        self.for_each_within(centre, radius, |i, _, _| out.push(i));
    }

    /// The `k` nearest points to `centre` no farther than `max_radius`, as (index,
    /// distance2) sorted by distance then index, into `out` (cleared first).
    pub fn nearest(&self, centre: &Point3<f32>, k: usize, max_radius: f32, out: &mut Vec<(u32, f32)>) {
        out.clear();
        if k == 0 || max_radius.is_nan() || max_radius < 0.0 {
            return;
        }
        // Grow the search ball until it holds k points or reaches max_radius: the k
        // nearest within a ball that holds k points are the k nearest overall.
        let mut radius = self.cell.min(max_radius);
        loop {
            out.clear();
            let mut worst = f32::INFINITY;
            self.for_each_within(centre, radius, |i, _, d2| {
                if out.len() == k && (d2, i) >= (worst, out[k - 1].0) {
                    return;
                }
                if out.len() == k {
                    out.pop();
                }
                let at = out.partition_point(|&(j, e)| (e, j) < (d2, i));
                out.insert(at, (i, d2));
                if out.len() == k {
                    worst = out[k - 1].1;
                }
            });
            if out.len() == k || radius >= max_radius || radius >= f32::MAX / 4.0 {
                return;
            }
            radius = (radius * 2.0).min(max_radius);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn random_cloud(rng: &mut ChaCha8Rng, n: usize) -> Vec<Point3<f32>> {
        (0..n)
            .map(|_| {
                Point3::new(rng.random_range(-60.0..60.0), rng.random_range(-40.0..40.0), rng.random_range(-5.0..5.0))
            })
            .collect()
    }

    #[test]
    fn radius_queries_match_a_scan() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let mut grid = Neighbours::new();
        let mut got = Vec::new();
        for &(n, cell, radius) in &[(3000, 5.0, 5.0), (2000, 10.0, 20.0), (500, 2.0, 30.0), (50, 1.0, 3.0)] {
            let cloud = random_cloud(&mut rng, n);
            grid.build(&cloud, cell).unwrap();
            for _ in 0..50 {
                let c = Point3::new(
                    rng.random_range(-70.0..70.0),
                    rng.random_range(-50.0..50.0),
                    rng.random_range(-6.0..6.0),
                );
                grid.within(&c, radius, &mut got);
                got.sort_unstable();
                let want: Vec<u32> =
                    (0..n as u32).filter(|&i| (cloud[i as usize] - c).norm_squared() <= radius * radius).collect();
                assert_eq!(got, want);
            }
        }
    }

    #[test]
    fn non_finite_points_are_left_out() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let mut cloud = random_cloud(&mut rng, 200);
        cloud[5] = Point3::new(f32::NAN, 0.0, 0.0);
        cloud[9] = Point3::new(0.0, f32::INFINITY, 0.0);
        let mut grid = Neighbours::new();
        grid.build(&cloud, 4.0).unwrap();
        assert_eq!(grid.len(), 198);
        let mut got = Vec::new();
        grid.within(&Point3::origin(), 1e6, &mut got);
        assert_eq!(got.len(), 198);
        assert!(!got.contains(&5) && !got.contains(&9));
        assert!(grid.build(&cloud, 0.0).is_err());
    }

    #[test]
    fn nearest_matches_a_sorted_scan() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let cloud = random_cloud(&mut rng, 2000);
        let mut grid = Neighbours::new();
        grid.build(&cloud, 3.0).unwrap();
        let mut got = Vec::new();
        for _ in 0..100 {
            let c =
                Point3::new(rng.random_range(-70.0..70.0), rng.random_range(-50.0..50.0), rng.random_range(-6.0..6.0));
            let k = rng.random_range(1..30);
            let max_radius = rng.random_range(1.0..40.0);
            grid.nearest(&c, k, max_radius, &mut got);
            let mut want: Vec<(u32, f32)> = (0..cloud.len() as u32)
                .map(|i| (i, (cloud[i as usize] - c).norm_squared()))
                .filter(|&(_, d2)| d2 <= max_radius * max_radius)
                .collect();
            want.sort_by(|a, b| (a.1, a.0).partial_cmp(&(b.1, b.0)).unwrap());
            want.truncate(k);
            assert_eq!(got, want);
        }
    }
}
