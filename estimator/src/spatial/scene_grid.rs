//! RANSAC's scene index: a spatial hash with cells twice the query reach, answering "is
//! any scene point within reach" and "which is nearest" by reading exactly 8 cells, behind a
//! bitmap that answers "no" at once far from the scene.

use nalgebra::Point3;

use super::floor_i32;

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
    near: NearMask,
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
            near: NearMask::new(0.25 * cell),
        }
    }

    fn cell(&self, p: &Point3<f32>) -> [i32; 3] {
        [floor_i32(p.x * self.inv_cell), floor_i32(p.y * self.inv_cell), floor_i32(p.z * self.inv_cell)]
    }

    fn bucket(&self, c: [i32; 3]) -> usize {
        let h = (c[0] as u32).wrapping_mul(73_856_093)
            ^ (c[1] as u32).wrapping_mul(19_349_663)
            ^ (c[2] as u32).wrapping_mul(83_492_791);
        (h & self.mask) as usize
    }

    /// Whether the grid holds no scene point (as built, or after an empty scene).
    pub(crate) fn is_empty(&self) -> bool {
        self.points.is_empty()
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
        self.near.rebuild(scene);
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

    /// Whether a scene point lies within `sqrt(r2)` of `q`; `r2` at most (half a cell)².
    pub(crate) fn any_within(&self, q: &Point3<f32>, r2: f32) -> bool {
        match self.near.classify(q) {
            Reach::None => return false,
            Reach::Surely if r2 >= self.near.inner_reach2 => return true,
            _ => {}
        }
        self.search_within(q, r2)
    }

    /// How many of `queries` have a scene point within `sqrt(r2)`: [`SceneGrid::any_within`]
    /// of each, counted, with the mask words of all of them read before any is decided,
    /// so their cache misses overlap instead of queueing one behind the other's branch.
    /// `r2` at most (half a cell)².
    pub(crate) fn count_within(&self, queries: &[Point3<f32>], r2: f32) -> u32 {
        let mut count = 0;
        self.each_within(queries, r2, |_, within| count += u32::from(within));
        count
    }

    /// [`SceneGrid::count_within`] that hands `visit` each query with whether a scene point
    /// lies within `sqrt(r2)` of it, in order.
    pub(crate) fn each_within(&self, queries: &[Point3<f32>], r2: f32, mut visit: impl FnMut(&Point3<f32>, bool)) {
        for block in queries.chunks(MASK_BATCH) {
            let mut reach = [Reach::Maybe; MASK_BATCH];
            self.near.classify_batch(block, &mut reach[..block.len()]);
            for (q, &reach) in block.iter().zip(&reach) {
                let within = match reach {
                    Reach::None => false,
                    Reach::Surely if r2 >= self.near.inner_reach2 => true,
                    _ => self.search_within(q, r2),
                };
                visit(q, within);
            }
        }
    }

    /// The search behind [`SceneGrid::any_within`]: the 8 cells around `q`.
    fn search_within(&self, q: &Point3<f32>, r2: f32) -> bool {
        for b in self.neighbour_buckets(q) {
            let (lo, hi) = (self.starts[b] as usize, self.starts[b + 1] as usize);
            if self.points[lo..hi].iter().any(|p| (p - q).norm_squared() <= r2) {
                return true;
            }
        }
        false
    }

    /// The nearest scene point within `sqrt(r2)` of `q` (the last of equally near ones in
    /// visiting order); `r2` at most (half a cell)².
    pub(crate) fn nearest_within(&self, q: &Point3<f32>, r2: f32) -> Option<Point3<f32>> {
        if self.near.classify(q) == Reach::None {
            return None;
        }
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

/// Queries [`SceneGrid::count_within`] classifies together.
const MASK_BATCH: usize = 32;

/// Voxels a point reaches along each axis in [`NearMask`]: the reach is two voxels.
const REACH_VOXELS: i32 = 2;

/// How far, in voxels, a point's own voxel is widened before the dilation: f32 rounding
/// can put a point a hair inside a voxel boundary and a query on the far boundary at
/// exactly the reach, three voxel indices apart. The products and differences behind that
/// err by a few units in the last place of the voxel coordinate, far below this margin
/// while coordinates stay below [`MAX_VOXEL_INDEX`] voxels.
const ROUNDING_VOXELS: f32 = 0.01;

/// Scenes with a point farther out than this many voxels get no mask.
const MAX_VOXEL_INDEX: f32 = 100_000.0;

/// The largest mask kept, in 64-bit words (4 MiB); a scene whose box needs more is queried
/// without one.
const MAX_MASK_WORDS: usize = 1 << 19;

/// A bitmap over the scene's box in voxels of half the reach: a voxel's bit is set when some
/// finite scene point lies within [`REACH_VOXELS`] voxels of it along every axis (the point's
/// voxel widened by [`ROUNDING_VOXELS`] for rounding). A query
/// within reach of a scene point is at most that many voxels from it along each axis, so a
/// clear bit (or a query outside the box) means no point is within reach, and only set bits
/// go on to the exact search: the answers are exactly those of the search alone (points
/// that are not finite are never within reach of anything). Built each frame by setting
/// each point's voxel and dilating along x, y and z in turn.
#[derive(Debug, Clone)]
struct NearMask {
    inv_voxel: f32,
    /// Lowest voxel index of the box along each axis.
    origin: [i32; 3],
    /// Voxels along y and z, and 64-bit words per row along x.
    dims: [usize; 3],
    words: Vec<u64>,
    spare: Vec<u64>,
    /// Both masks word by word, `[near, inner]`, so one cache line answers a query: the
    /// near mask is `words` once dilated; the inner mask's bit is set when the whole voxel
    /// lies within [`REACH_VOXELS`] voxels (Euclidean) of one scene point, with a margin for
    /// f32 rounding, so a query there has a point within reach without a search.
    masks: Vec<[u64; 2]>,
    /// The squared reach the inner mask answers for, mm²: a query with a smaller one is
    /// searched.
    inner_reach2: f32,
    /// Whether the mask holds this frame's scene (false: every query goes to the search).
    active: bool,
}

/// What [`NearMask`] says of a query.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Reach {
    /// No scene point within reach.
    None,
    /// A scene point within reach, for certain.
    Surely,
    /// The search must tell.
    Maybe,
}

/// Relative f32 rounding the inner mask allows for, in the voxel a query falls in and in
/// the distance the search would compute: a few units in the last place of the largest
/// coordinate involved.
const INNER_ROUNDING: f32 = 4.0 * f32::EPSILON;

impl NearMask {
    fn new(voxel: f32) -> Self {
        NearMask {
            inv_voxel: 1.0 / voxel,
            origin: [0; 3],
            dims: [0; 3],
            // Reserved once, so a larger scene box in a later frame does not allocate; only
            // the words a box uses are ever touched.
            words: Vec::with_capacity(MAX_MASK_WORDS),
            spare: Vec::with_capacity(MAX_MASK_WORDS),
            masks: Vec::with_capacity(MAX_MASK_WORDS),
            inner_reach2: (REACH_VOXELS as f32 * voxel).powi(2),
            active: false,
        }
    }

    fn voxel(&self, p: &Point3<f32>) -> [i32; 3] {
        [floor_i32(p.x * self.inv_voxel), floor_i32(p.y * self.inv_voxel), floor_i32(p.z * self.inv_voxel)]
    }

    /// The voxels of `p` along each axis, widened by [`ROUNDING_VOXELS`] (one or two each).
    fn voxel_span(&self, p: &Point3<f32>) -> [[i32; 2]; 3] {
        std::array::from_fn(|a| {
            let c = p[a] * self.inv_voxel;
            [floor_i32(c - ROUNDING_VOXELS), floor_i32(c + ROUNDING_VOXELS)]
        })
    }

    fn rebuild(&mut self, scene: &[Point3<f32>]) {
        self.active = false;
        let mut lo = [i32::MAX; 3];
        let mut hi = [i32::MIN; 3];
        for p in scene.iter().filter(|p| is_finite(p)) {
            // Far out: no mask (the search alone answers).
            if p.coords.iter().any(|c| (c * self.inv_voxel).abs() >= MAX_VOXEL_INDEX) {
                return;
            }
            for (a, [first, last]) in self.voxel_span(p).into_iter().enumerate() {
                lo[a] = lo[a].min(first);
                hi[a] = hi[a].max(last);
            }
        }
        if lo[0] > hi[0] {
            return;
        }
        let origin = lo.map(|c| c - REACH_VOXELS);
        let extent: [usize; 3] = std::array::from_fn(|a| (hi[a] - lo[a] + 2 * REACH_VOXELS + 1) as usize);
        let row = extent[0].div_ceil(64);
        let Some(len) = row.checked_mul(extent[1]).and_then(|n| n.checked_mul(extent[2])) else { return };
        if len > MAX_MASK_WORDS {
            return;
        }
        self.origin = origin;
        self.dims = [row, extent[1], extent[2]];
        self.words.clear();
        self.words.resize(len, 0);
        self.masks.clear();
        self.masks.resize(len, [0; 2]);
        for p in scene.iter().filter(|p| is_finite(p)) {
            let [sx, sy, sz] = self.voxel_span(p).map(|[first, last]| first..=last);
            for z in sz {
                for y in sy.clone() {
                    for x in sx.clone() {
                        let [x, y, z] = [x - origin[0], y - origin[1], z - origin[2]].map(|c| c as usize);
                        self.words[(z * extent[1] + y) * row + x / 64] |= 1 << (x % 64);
                    }
                }
            }
            self.mark_inner(p);
        }
        self.dilate_x();
        self.dilate_rows(1);
        self.dilate_rows(extent[1]);
        for (pair, &near) in self.masks.iter_mut().zip(&self.words) {
            pair[0] = near;
        }
        self.active = true;
    }

    /// Sets the inner mask's bit of every voxel that lies wholly within reach of the finite
    /// scene point `p`: its own voxel and its 26 neighbours are the only candidates (any
    /// other is two voxels away along an axis already).
    fn mark_inner(&mut self, p: &Point3<f32>) {
        let [row, ny, _] = self.dims;
        let voxel = 1.0 / self.inv_voxel;
        let reach = REACH_VOXELS as f32 * voxel;
        let c = self.voxel(p);
        // Slack for the rounding of voxel bounds and distances at this magnitude.
        let slack = INNER_ROUNDING * (p.coords.amax() + 4.0 * voxel) * 4.0;
        let limit = reach - slack;
        if limit <= 0.0 {
            return;
        }
        let limit2 = limit * limit;
        // Per axis and offset -1, 0, 1: the squared distance to the voxel's far side.
        let far: [[f32; 3]; 3] = std::array::from_fn(|a| {
            std::array::from_fn(|k| {
                let lo = (c[a] + k as i32 - 1) as f32 * voxel;
                let (d0, d1) = (p[a] - lo, p[a] - (lo + voxel));
                (d0 * d0).max(d1 * d1)
            })
        });
        for (kz, fz) in far[2].iter().enumerate() {
            for (ky, fy) in far[1].iter().enumerate() {
                for (kx, fx) in far[0].iter().enumerate() {
                    if fx + fy + fz > limit2 {
                        continue;
                    }
                    let v = [c[0] + kx as i32 - 1, c[1] + ky as i32 - 1, c[2] + kz as i32 - 1];
                    let [x, y, z] = [0, 1, 2].map(|a| (v[a] - self.origin[a]) as usize);
                    self.masks[(z * ny + y) * row + x / 64][1] |= 1 << (x % 64);
                }
            }
        }
    }

    /// Sets every bit within [`REACH_VOXELS`] of a set bit along its row.
    fn dilate_x(&mut self) {
        let row = self.dims[0];
        for r in self.words.chunks_exact_mut(row) {
            // Upwards first (towards higher x), carrying the top bits into the next word...
            let mut carry = 0u64;
            for w in r.iter_mut() {
                let v = *w;
                let mut up = v;
                for s in 1..=REACH_VOXELS {
                    up |= v << s;
                }
                *w = up | carry;
                carry = (1..=REACH_VOXELS).fold(0, |c, s| c | v >> (64 - s));
            }
            // ...then downwards: grown by 0..=2 up and then 0..=2 down, a bit covers 2 voxels
            // either side.
            let mut carry = 0u64;
            for w in r.iter_mut().rev() {
                let v = *w;
                let mut down = v;
                for s in 1..=REACH_VOXELS {
                    down |= v >> s;
                }
                *w = down | carry;
                carry = (1..=REACH_VOXELS).fold(0, |c, s| c | v << (64 - s));
            }
        }
    }

    /// Sets every row within [`REACH_VOXELS`] rows of a row with the bit set, rows `stride`
    /// rows apart being neighbours (1: along y; voxels along y: along z).
    fn dilate_rows(&mut self, stride: usize) {
        let [row, ny, nz] = self.dims;
        self.spare.clear();
        self.spare.resize(self.words.len(), 0);
        let count = if stride == 1 { ny } else { nz };
        for r in 0..ny * nz {
            let (z, y) = (r / ny, r % ny);
            let at = if stride == 1 { y } else { z };
            let lo = at.saturating_sub(REACH_VOXELS as usize);
            let hi = (at + REACH_VOXELS as usize).min(count - 1);
            let out = &mut self.spare[r * row..(r + 1) * row];
            for n in lo..=hi {
                let other = r - at * stride + n * stride;
                for (o, w) in out.iter_mut().zip(&self.words[other * row..(other + 1) * row]) {
                    *o |= w;
                }
            }
        }
        std::mem::swap(&mut self.words, &mut self.spare);
    }

    /// Whether a scene point lies within the reach of `q`: none, surely one, or maybe.
    #[inline]
    fn classify(&self, q: &Point3<f32>) -> Reach {
        if !self.active {
            return Reach::Maybe;
        }
        match self.word_of(q) {
            None => Reach::None,
            Some((word, bit)) => Self::reach(self.masks[word], bit),
        }
    }

    /// [`NearMask::classify`] of each query into `out`: first every query's word (so the
    /// loads are independent of each other), then the answers.
    #[inline]
    fn classify_batch(&self, queries: &[Point3<f32>], out: &mut [Reach]) {
        if !self.active {
            out.fill(Reach::Maybe);
            return;
        }
        let mut masks = [[0u64; 2]; MASK_BATCH];
        let mut bits = [0u32; MASK_BATCH];
        for (k, q) in queries.iter().enumerate() {
            // A query outside the box reads clear stand-in words: no point within reach.
            let (word, bit) = self.word_of(q).map_or((None, 0), |(w, b)| (Some(w), b));
            masks[k] = word.map_or([0; 2], |w| self.masks[w]);
            bits[k] = bit;
        }
        for (k, o) in out.iter_mut().enumerate() {
            *o = Self::reach(masks[k], bits[k]);
        }
    }

    /// The word and bit of `q`'s voxel, `None` outside the box.
    #[inline]
    fn word_of(&self, q: &Point3<f32>) -> Option<(usize, u32)> {
        let v = self.voxel(q);
        let [row, ny, nz] = self.dims;
        let x = v[0].wrapping_sub(self.origin[0]) as u32 as usize;
        let y = v[1].wrapping_sub(self.origin[1]) as u32 as usize;
        let z = v[2].wrapping_sub(self.origin[2]) as u32 as usize;
        if x >= 64 * row || y >= ny || z >= nz {
            return None;
        }
        Some(((z * ny + y) * row + x / 64, (x % 64) as u32))
    }

    #[inline]
    fn reach([near, inner]: [u64; 2], bit: u32) -> Reach {
        if near >> bit & 1 == 0 {
            Reach::None
        } else if inner >> bit & 1 != 0 {
            Reach::Surely
        } else {
            Reach::Maybe
        }
    }
}

fn is_finite(p: &Point3<f32>) -> bool {
    p.x.is_finite() && p.y.is_finite() && p.z.is_finite()
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
            let mut queries = Vec::new();
            let mut within = 0;
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
                queries.push(q);
                within += u32::from(nearest <= 9.0);
            }
            // The batched count, over runs of every length (a batch and its remainder).
            assert_eq!(grid.count_within(&queries, 9.0), within, "round {round}");
            for len in [0, 1, 31, 32, 33, 95] {
                let brute = queries[..len].iter().filter(|q| grid.any_within(q, 9.0)).count() as u32;
                assert_eq!(grid.count_within(&queries[..len], 9.0), brute, "round {round}, {len} queries");
            }
        }
    }

    /// Queries near a surface of points, as a right pose's are: the inner mask answers
    /// most of them without a search, and every one it answers has a point within reach.
    #[test]
    fn the_inner_mask_answers_near_queries_and_only_right() {
        let mut rng = ChaCha8Rng::seed_from_u64(31);
        for (cell, offset) in [(6.0f32, 0.0f32), (6.0, 1234.5), (8.0, -700.25)] {
            let reach2 = (cell / 2.0) * (cell / 2.0);
            let scene: Vec<Point3<f32>> = (0..4000)
                .map(|_| {
                    let (x, y) = (rng.random_range(-60.0..60.0f32), rng.random_range(-60.0..60.0f32));
                    Point3::new(x + offset, y - offset, 0.1 * x + rng.random_range(-0.3..0.3) + offset)
                })
                .collect();
            let mut grid = SceneGrid::new(cell, 16);
            grid.rebuild(&scene);
            let mut surely = 0;
            for _ in 0..3000 {
                let p = scene[rng.random_range(0..scene.len())];
                let q = p + nalgebra::Vector3::new(
                    rng.random_range(-1.5..1.5),
                    rng.random_range(-1.5..1.5),
                    rng.random_range(-1.5..1.5),
                );
                let nearest = scene.iter().map(|s| (s - q).norm_squared()).fold(f32::INFINITY, f32::min);
                if grid.near.classify(&q) == Reach::Surely {
                    surely += 1;
                    assert!(nearest <= reach2, "cell {cell}: {q} has no point within reach");
                }
                assert_eq!(grid.any_within(&q, reach2), nearest <= reach2);
                assert_eq!(grid.count_within(&[q], reach2), u32::from(nearest <= reach2));
            }
            assert!(surely > 1500, "cell {cell}: only {surely} of 3000 answered by the inner mask");
        }
    }

    /// Points that f32 rounding puts at exactly the reach, three voxel indices apart, and
    /// points that are not finite: the mask answers as the search does.
    #[test]
    fn the_mask_keeps_rounded_boundary_pairs_and_skips_points_that_are_not_finite() {
        for (cell, p, q) in [(6.0f32, 1.4999999f32, 4.5f32), (8.0, 1.9999999, 6.0)] {
            let reach2 = (cell / 2.0) * (cell / 2.0);
            let mut grid = SceneGrid::new(cell, 16);
            grid.rebuild(&[Point3::new(p, 0.0, 0.0)]);
            let q = Point3::new(q, 0.0, 0.0);
            assert_eq!((Point3::new(p, 0.0, 0.0) - q).norm_squared(), reach2);
            assert!(grid.any_within(&q, reach2), "cell {cell}: {p} and {q}");
            assert!(grid.nearest_within(&q, reach2).is_some());
        }
        let mut grid = SceneGrid::new(6.0, 16);
        let scene =
            [Point3::new(f32::NAN, 0.0, 0.0), Point3::new(10.0, 10.0, 1.0), Point3::new(f32::INFINITY, 1e30, 0.0)];
        grid.rebuild(&scene);
        assert!(grid.near.active);
        assert!(grid.any_within(&Point3::new(11.0, 10.0, 1.0), 9.0));
        assert!(!grid.any_within(&Point3::new(0.0, 0.0, 0.0), 9.0));
    }

    /// Scene points on voxel boundaries (give or take a few units in the last place) and
    /// queries at about the reach from them, in every direction: the mask never hides a
    /// point the search finds.
    #[test]
    fn boundary_points_at_the_reach_agree_with_brute_force() {
        let mut rng = ChaCha8Rng::seed_from_u64(21);
        for cell in [6.0f32, 8.0, 5.0, 2.4] {
            let reach = cell / 2.0;
            let voxel = cell / 4.0;
            let mut grid = SceneGrid::new(cell, 16);
            for _ in 0..2000 {
                let on_boundary = |rng: &mut ChaCha8Rng| {
                    let c = rng.random_range(-400i32..400) as f32 * voxel;
                    f32::from_bits((c.to_bits() as i64 + rng.random_range(-3i64..=3)).max(0) as u32)
                };
                let p = Point3::new(on_boundary(&mut rng), on_boundary(&mut rng), on_boundary(&mut rng));
                grid.rebuild(&[p, Point3::new(p.x + 50.0, p.y, p.z)]);
                let dir = nalgebra::Vector3::new(
                    rng.random_range(-1.0f32..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                );
                let Some(mut dir) = dir.try_normalize(1e-3) else { continue };
                // Along an axis half the time: there the rounding lands on voxel boundaries.
                if rng.random_bool(0.5) {
                    let axis = rng.random_range(0..3);
                    dir = nalgebra::Vector3::zeros();
                    dir[axis] = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
                }
                let q = (p + dir * reach).map(|c| {
                    f32::from_bits((c.to_bits() as i64 + rng.random_range(-3i64..=3)).clamp(0, u32::MAX as i64) as u32)
                });
                let r2 = reach * reach;
                assert_eq!(grid.any_within(&q, r2), (p - q).norm_squared() <= r2, "cell {cell}: {p} {q}");
            }
        }
    }
}
