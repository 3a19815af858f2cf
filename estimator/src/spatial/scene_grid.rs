//! RANSAC's scene index: a spatial hash with cells twice the query reach, answering "is
//! any scene point within reach" and "which is nearest" by reading exactly 8 cells.

use nalgebra::Point3;

/// A spatial hash of the scene cloud with cells twice the query radius, so a radius query
/// visits 8 cells. Rebuilt every frame into buffers that only grow when a scene is larger
/// than any before; hash collisions only add candidates, which the distance test removes.
///
/// Why not [`super::Neighbours`]: a query here is always "within half a cell", so it reads
/// 8 fixed cells without comparing keys, and it keeps its own bucket hash because its
/// nearest query keeps the last of equally distant points in visiting order, which the
/// hash sets.
#[derive(Debug, Clone)]
pub(crate) struct SceneGrid {
    inv_cell: f32,
    /// Bucket count − 1 (a power of two).
    mask: u32,
    /// `starts[b]..starts[b + 1]` are bucket b's points in `points`.
    starts: Vec<u32>,
    points: Vec<Point3<f32>>,
    bucket_of: Vec<u32>,
}

impl SceneGrid {
    pub(crate) fn new(cell: f32, capacity: usize) -> Self {
        let buckets = (2 * capacity).next_power_of_two();
        SceneGrid {
            inv_cell: 1.0 / cell,
            mask: buckets as u32 - 1,
            starts: vec![0; buckets + 1],
            points: Vec::with_capacity(capacity),
            bucket_of: Vec::with_capacity(capacity),
        }
    }

    fn cell(&self, p: &Point3<f32>) -> [i32; 3] {
        [
            (p.x * self.inv_cell).floor() as i32,
            (p.y * self.inv_cell).floor() as i32,
            (p.z * self.inv_cell).floor() as i32,
        ]
    }

    fn bucket(&self, c: [i32; 3]) -> usize {
        let h = (c[0] as u32).wrapping_mul(73_856_093)
            ^ (c[1] as u32).wrapping_mul(19_349_663)
            ^ (c[2] as u32).wrapping_mul(83_492_791);
        (h & self.mask) as usize
    }

    pub(crate) fn rebuild(&mut self, scene: &[Point3<f32>]) {
        if 2 * scene.len() > self.starts.len() - 1 {
            let buckets = (2 * scene.len()).next_power_of_two();
            self.mask = buckets as u32 - 1;
            self.starts.resize(buckets + 1, 0);
        }
        self.starts.fill(0);
        self.bucket_of.clear();
        for p in scene {
            let b = self.bucket(self.cell(p));
            self.bucket_of.push(b as u32);
            self.starts[b + 1] += 1;
        }
        for b in 1..self.starts.len() {
            self.starts[b] += self.starts[b - 1];
        }
        self.points.clear();
        self.points.resize(scene.len(), Point3::origin());
        // Scatter from the back so each bucket's points keep their input order.
        for (p, &b) in scene.iter().zip(&self.bucket_of).rev() {
            let slot = &mut self.starts[b as usize + 1];
            *slot -= 1;
            self.points[*slot as usize] = *p;
        }
        // Each `starts[b + 1]` now holds bucket b's start; shift back into place.
        let n = self.starts.len();
        self.starts.copy_within(1..n, 0);
        self.starts[n - 1] = scene.len() as u32;
    }

    /// The 8 cells that hold every point within half a cell of `q`, starting with q's own.
    fn neighbour_buckets(&self, q: &Point3<f32>) -> [usize; 8] {
        let c = self.cell(q);
        let mut step = [0i32; 3];
        for a in 0..3 {
            let f = q[a] * self.inv_cell - c[a] as f32;
            step[a] = if f < 0.5 { -1 } else { 1 };
        }
        let mut out = [0; 8];
        for (k, slot) in out.iter_mut().enumerate() {
            let mut cc = c;
            for a in 0..3 {
                if k & (1 << a) != 0 {
                    cc[a] += step[a];
                }
            }
            *slot = self.bucket(cc);
        }
        out
    }

    pub(crate) fn any_within(&self, q: &Point3<f32>, r2: f32) -> bool {
        for b in self.neighbour_buckets(q) {
            let (lo, hi) = (self.starts[b] as usize, self.starts[b + 1] as usize);
            if self.points[lo..hi].iter().any(|p| (p - q).norm_squared() <= r2) {
                return true;
            }
        }
        false
    }

    pub(crate) fn nearest_within(&self, q: &Point3<f32>, r2: f32) -> Option<Point3<f32>> {
        let mut best = (r2, None);
        for b in self.neighbour_buckets(q) {
            let (lo, hi) = (self.starts[b] as usize, self.starts[b + 1] as usize);
            for p in &self.points[lo..hi] {
                let d2 = (p - q).norm_squared();
                if d2 <= best.0 {
                    best = (d2, Some(*p));
                }
            }
        }
        best.1
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn grid_queries_match_brute_force() {
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let mut grid = SceneGrid::new(6.0, 16);
        for round in 0..4 {
            let n = [10, 500, 3000, 40_000][round];
            let scene: Vec<Point3<f32>> = (0..n)
                .map(|_| {
                    Point3::new(
                        rng.random_range(-80.0..80.0),
                        rng.random_range(-80.0..80.0),
                        rng.random_range(-5.0..20.0),
                    )
                })
                .collect();
            grid.rebuild(&scene);
            for _ in 0..2000 {
                let q = Point3::new(
                    rng.random_range(-90.0..90.0),
                    rng.random_range(-90.0..90.0),
                    rng.random_range(-8.0..25.0),
                );
                let nearest = scene.iter().map(|p| (p - q).norm_squared()).fold(f32::INFINITY, f32::min);
                assert_eq!(grid.any_within(&q, 9.0), nearest <= 9.0);
                let got = grid.nearest_within(&q, 9.0).map(|p| (p - q).norm_squared());
                assert_eq!(got, (nearest <= 9.0).then_some(nearest));
            }
        }
    }
}
