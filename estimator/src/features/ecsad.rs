//! ECSAD, the Equivalent Circumference Surface Angle Descriptor (Jørgensen, Buch and Kraft,
//! VISAPP 2015): a 30-D description of the surface around a key point, computed in batches
//! into caller-owned buffers. Key point choice and matching live elsewhere.
//!
//! The choices made where the paper leaves room:
//! - **Bins.** The support (radius R) is projected onto the key point's tangent plane and
//!   cut into 4 rings of equal width R/4 holding 3, 6, 9 and 12 sectors: the sector count is
//!   proportional to the ring's outer circumference, so bins have near-equal arc length and
//!   near-equal area (ratios 1 : 1.5 : 1.67 : 1.75), and 3 + 6 + 9 + 12 = 30. Bin
//!   `RING_OFFSET[i] + s` is sector s of ring i (inner ring first); sector 0 of every ring
//!   is centred on the reference axis and sectors run counter-clockwise about the normal.
//! - **Value.** Per bin, the angle (radians, 0 to pi) between the normal n and the
//!   direction from the key point to the 3-D centroid of the bin's points. One angle per
//!   bin from its centroid is less noisy than a mean of per-point angles, whose inner-ring
//!   points at sub-millimetre range swing wildly with depth noise. A flat surface gives
//!   pi/2 everywhere; a step down below the tangent plane gives more, a wall rising gives
//!   less.
//! - **Empty bins** take, in rounds, the mean of their filled neighbours (the sectors either
//!   side in the same ring and the overlapping sectors of the rings inside and outside),
//!   until every bin is filled; a support with no points at all reads as flat (pi/2).
//! - **Azimuth.** The reference axis x is the tangent-plane direction of the largest normal
//!   deviation: x ∝ Σ h_i (1 - r_i/R) û_i over the support, with h_i the point's height
//!   above the tangent plane, r_i its tangent distance and û_i its tangent direction, so it
//!   points towards rising surface and away from falling surface. The taper (1 - r/R)
//!   makes points crossing the support's edge count little. When the deviations cancel
//!   (|sum| below 15% of Σ |h_i| (1 - r_i/R), a symmetric ridge or a plane) the axis is the
//!   dominant direction of the same weights' tangent scatter, signed by the weak sum; a
//!   plane, whose descriptor does not depend on the azimuth, falls through to that too.
//!   y = n × x completes a right-handed frame, so mirror images differ.

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;
use std::f32::consts::{FRAC_PI_2, PI, TAU};

use super::normals::is_valid_normal;
use crate::Neighbours;
use crate::{Error, ErrorKind, Result};

/// Length of an ECSAD descriptor.
pub const ECSAD_DIM: usize = 30;

/// One ECSAD descriptor: per bin, the normal-to-centroid angle in radians (0 to pi).
pub type Descriptor = [f32; ECSAD_DIM];

/// Relief of a descriptor: the RMS deviation of its angles from a plane's (pi/2), deg.
/// Near 0 on flat surface, tens of degrees at edges, steps and corners; a cheap measure of
/// how distinctive a key point can be.
pub fn relief_deg(descriptor: &Descriptor) -> f32 {
    let sum: f32 = descriptor.iter().map(|v| (v - FRAC_PI_2).powi(2)).sum();
    (sum / ECSAD_DIM as f32).sqrt().to_degrees()
}

/// Number of concentric rings of the polar grid.
pub const RINGS: usize = 4;

/// Sectors per ring, inner ring first (proportional to the ring's outer radius).
pub const RING_SECTORS: [usize; RINGS] = [3, 6, 9, 12];

/// Index of each ring's first bin in a descriptor.
pub const RING_OFFSET: [usize; RINGS] = [0, 3, 9, 18];

/// A bin has at most 2 same-ring neighbours and 3 + 3 overlapping ones in the rings either
/// side (4 would need a ring with more than twice its neighbour's sectors).
const MAX_ADJACENT: usize = 8;

/// Key points are described in this many parallel batches, each with its own scratch.
const BATCHES: usize = 32;

/// Share of the total deviation weight the signed deviation sum must reach to fix the
/// reference axis on its own.
const SIGNED_AXIS_SHARE: f32 = 0.15;

/// Computes ECSAD descriptors over a fixed support radius, reusing its scratch buffers.
#[derive(Debug, Clone)]
pub struct Ecsad {
    radius: f32,
    /// Bins that fill an empty bin, per bin (`u8::MAX` pads).
    adjacent: [[u8; MAX_ADJACENT]; ECSAD_DIM],
    /// One support buffer per batch.
    scratch: Vec<Support>,
}

/// Ring and sector of each bin.
fn bin_ring_sector(bin: usize) -> (usize, usize) {
    let ring = (0..RINGS).rev().find(|&r| RING_OFFSET[r] <= bin).unwrap_or(0);
    (ring, bin - RING_OFFSET[ring])
}

/// Whether sector a of a ring with `na` sectors and sector b of one with `nb` overlap in
/// azimuth (sectors centred on k / n turns, half-open, compared on the circle).
fn sectors_overlap(a: usize, na: usize, b: usize, nb: usize) -> bool {
    let (a0, a1) = ((a as f64 - 0.5) / na as f64, (a as f64 + 0.5) / na as f64);
    let (b0, b1) = ((b as f64 - 0.5) / nb as f64, (b as f64 + 0.5) / nb as f64);
    (-1..=1).any(|wrap| {
        let (c0, c1) = (b0 + wrap as f64, b1 + wrap as f64);
        a0.max(c0) + 1e-9 < a1.min(c1)
    })
}

fn adjacency() -> [[u8; MAX_ADJACENT]; ECSAD_DIM] {
    let mut table = [[u8::MAX; MAX_ADJACENT]; ECSAD_DIM];
    for (bin, row) in table.iter_mut().enumerate() {
        let (ring, sector) = bin_ring_sector(bin);
        let n = RING_SECTORS[ring];
        let mut list = heapless::Vec::<u8, MAX_ADJACENT>::new();
        for s in [(sector + n - 1) % n, (sector + 1) % n] {
            let b = (RING_OFFSET[ring] + s) as u8;
            if s != sector && !list.contains(&b) {
                let _ = list.push(b);
            }
        }
        for other in [ring.wrapping_sub(1), ring + 1] {
            if other >= RINGS {
                continue;
            }
            for s in 0..RING_SECTORS[other] {
                if sectors_overlap(sector, n, s, RING_SECTORS[other]) {
                    let _ = list.push((RING_OFFSET[other] + s) as u8);
                }
            }
        }
        row[..list.len()].copy_from_slice(&list);
    }
    table
}

/// Azimuth of (x, y) in turns, [0, 1), by a polynomial arctangent (Abramowitz and Stegun
/// 4.4.47, error below 1e-5 rad,
/// far under a sector's width, and much cheaper than `atan2` for every support point).
#[inline(always)]
fn azimuth_turns(y: f32, x: f32) -> f32 {
    let (ax, ay) = (x.abs(), y.abs());
    let (lo, hi) = (ax.min(ay), ax.max(ay));
    // Written as selects, so the binning pass runs it in vector lanes.
    let a = if hi > 0.0 { lo / hi } else { 0.0 };
    let s = a * a;
    let r = a * (0.999_866 + s * (-0.330_299_5 + s * (0.180_141 + s * (-0.085_133 + s * 0.020_835_1))));
    let r = if ay > ax { FRAC_PI_2 - r } else { r };
    let r = if x < 0.0 { PI - r } else { r };
    let r = if y < 0.0 { -r } else { r };
    let t = r * (1.0 / TAU);
    let t = if t < 0.0 { t + 1.0 } else { t };
    // A NaN or the origin has no azimuth: 0.
    if hi > 0.0 {
        t
    } else {
        0.0
    }
}

/// Any unit vector perpendicular to unit `n`.
fn any_tangent(n: &Vector3<f32>) -> Vector3<f32> {
    let helper = if n.x.abs() < 0.6 { Vector3::x() } else { Vector3::y() };
    (helper - n * n.dot(&helper)).normalize()
}

impl Ecsad {
    /// A describer with support radius `radius` mm (feature_radius, about 10 x SRes).
    pub fn new(radius: f32) -> Result<Self> {
        if !(radius.is_finite() && radius > 0.0) {
            return Err(Error::new(ErrorKind::Input, format!("ECSAD: expected a positive radius in mm, got {radius}")));
        }
        Ok(Ecsad { radius, adjacent: adjacency(), scratch: vec![Support::default(); BATCHES] })
    }

    /// Support radius, mm.
    pub fn radius(&self) -> f32 {
        self.radius
    }

    /// Replaces `out` with one descriptor per key point (indices into `cloud`), its support
    /// taken from `neighbours` (built on `cloud`; a cell of about R/2 is fastest). A key
    /// point without a valid normal gets the flat descriptor (pi/2 in every bin).
    pub fn compute(
        &mut self,
        cloud: &[Point3<f32>],
        normals: &[Vector3<f32>],
        neighbours: &Neighbours,
        keypoints: &[u32],
        out: &mut Vec<Descriptor>,
    ) -> Result<()> {
        if cloud.len() != normals.len() {
            return Err(Error::new(
                ErrorKind::Input,
                format!("ECSAD: {} points but {} normals", cloud.len(), normals.len()),
            ));
        }
        if let Some(&bad) = keypoints.iter().find(|&&k| k as usize >= cloud.len()) {
            return Err(Error::new(
                ErrorKind::Input,
                format!("ECSAD: key point {bad} is outside a cloud of {} points", cloud.len()),
            ));
        }
        out.clear();
        out.resize(keypoints.len(), [FRAC_PI_2; ECSAD_DIM]);
        if keypoints.is_empty() {
            return Ok(());
        }
        let per_batch = keypoints.len().div_ceil(BATCHES);
        let (radius, adjacent) = (self.radius, &self.adjacent);
        out.par_chunks_mut(per_batch).zip(keypoints.par_chunks(per_batch)).zip(self.scratch.par_iter_mut()).for_each(
            |((descriptors, keys), support)| {
                for (d, &k) in descriptors.iter_mut().zip(keys) {
                    describe(radius, adjacent, cloud, normals, neighbours, k as usize, support, d);
                }
            },
        );
        Ok(())
    }
}

/// Lanes of the support passes: each sum is kept in this many partial sums, one per lane,
/// added up in a fixed order at the end, so the compiler runs the passes in vector
/// registers and the descriptor is the same whatever their width.
const SUPPORT_LANES: usize = 16;

/// One key point's support as offsets from it, coordinate by coordinate, with each point's
/// bin: the layout the passes over the support read in vector lanes.
#[derive(Debug, Clone, Default)]
struct Support {
    x: Vec<f32>,
    y: Vec<f32>,
    z: Vec<f32>,
    bin: Vec<u8>,
}

impl Support {
    fn clear(&mut self) {
        self.x.clear();
        self.y.clear();
        self.z.clear();
        self.bin.clear();
    }

    fn push(&mut self, d: Vector3<f32>) {
        self.x.push(d.x);
        self.y.push(d.y);
        self.z.push(d.z);
    }

    fn len(&self) -> usize {
        self.x.len()
    }
}

/// The support's sums that fix the reference axis (see the module docs): the signed
/// deviation sum, the total deviation weight and the weighted tangent scatter (xx, xy, yy)
/// in the frame (t1, t2).
#[derive(Debug, Clone, Copy, Default)]
struct AxisSums {
    signed: [f32; 3],
    total: f32,
    scatter: [f32; 3],
}

crate::multiversion! {
    /// [`axis_sums_body`] in the widest vector lanes the CPU has.
    fn axis_sums(support: &Support, n: &Vector3<f32>, t1: &Vector3<f32>, t2: &Vector3<f32>, inv_r: f32, out: &mut AxisSums) => axis_sums_body
}

/// Sums over the support for the reference axis, each point weighted by its height h above
/// the tangent plane and the taper (1 - r/R) of its tangent distance r; points on the
/// normal (r = 0) add nothing.
#[inline(always)]
fn axis_sums_body(
    support: &Support,
    n: &Vector3<f32>,
    t1: &Vector3<f32>,
    t2: &Vector3<f32>,
    inv_r: f32,
    out: &mut AxisSums,
) {
    const L: usize = SUPPORT_LANES;
    let mut acc = [[0.0f32; L]; 7];
    let len = support.len();
    let whole = len - len % L;
    let lane = |acc: &mut [[f32; L]; 7], l: usize, dx: f32, dy: f32, dz: f32| {
        let h = n.x * dx + n.y * dy + n.z * dz;
        let (ux, uy, uz) = (dx - n.x * h, dy - n.y * h, dz - n.z * h);
        let r = (ux * ux + uy * uy + uz * uz).sqrt();
        let inv = if r > 0.0 { 1.0 / r } else { 0.0 };
        let taper = (1.0 - r * inv_r).max(0.0);
        // w scales u to its signed contribution; |w| r is the point's deviation weight and
        // |w| / r scales the scatter of the unit direction u / r.
        let w = h * taper * inv;
        let aw = w.abs();
        let (a, b) = (t1.x * ux + t1.y * uy + t1.z * uz, t2.x * ux + t2.y * uy + t2.z * uz);
        let sw = aw * inv;
        acc[0][l] += ux * w;
        acc[1][l] += uy * w;
        acc[2][l] += uz * w;
        acc[3][l] += aw * r;
        acc[4][l] += sw * a * a;
        acc[5][l] += sw * a * b;
        acc[6][l] += sw * b * b;
    };
    for start in (0..whole).step_by(L) {
        let (xs, ys, zs) = (&support.x[start..start + L], &support.y[start..start + L], &support.z[start..start + L]);
        for l in 0..L {
            lane(&mut acc, l, xs[l], ys[l], zs[l]);
        }
    }
    for (l, i) in (whole..len).enumerate() {
        lane(&mut acc, l, support.x[i], support.y[i], support.z[i]);
    }
    let total = |k: usize| acc[k].iter().sum::<f32>();
    *out =
        AxisSums { signed: [total(0), total(1), total(2)], total: total(3), scatter: [total(4), total(5), total(6)] };
}

crate::multiversion! {
    /// [`bin_support_body`] in the widest vector lanes the CPU has.
    fn bin_support(support: &mut Support, x_axis: &Vector3<f32>, y_axis: &Vector3<f32>, ring_edge2: &[f32; 3]) => bin_support_body
}

/// Each support point's bin on the polar grid about (x_axis, y_axis): ring by tangent
/// distance, then sector by azimuth, sector 0 of each ring centred on the x axis.
#[inline(always)]
fn bin_support_body(support: &mut Support, x_axis: &Vector3<f32>, y_axis: &Vector3<f32>, ring_edge2: &[f32; 3]) {
    let Support { x, y, z, bin } = support;
    // A plain loop over a sized buffer rather than `extend` with a closure, which a build
    // may leave as a call per point.
    bin.clear();
    bin.resize(x.len(), 0);
    for (b, ((&dx, &dy), &dz)) in bin.iter_mut().zip(x.iter().zip(y.iter()).zip(z.iter())) {
        let u = x_axis.x * dx + x_axis.y * dy + x_axis.z * dz;
        let v = y_axis.x * dx + y_axis.y * dy + y_axis.z * dz;
        let r2 = u * u + v * v;
        let ring = u8::from(r2 >= ring_edge2[0]) + u8::from(r2 >= ring_edge2[1]) + u8::from(r2 >= ring_edge2[2]);
        // Ring i has 3 (i + 1) sectors and starts at bin 3 i (i + 1) / 2.
        let sectors = 3.0 * f32::from(ring + 1);
        let t = azimuth_turns(v, u) + 0.5 / sectors;
        let t = if t >= 1.0 { t - 1.0 } else { t };
        let sector = ((t * sectors) as u8).min(3 * (ring + 1) - 1);
        *b = 3 * ring * (ring + 1) / 2 + sector;
    }
}

/// Describes key point `k` into `out`, gathering its support into `support`.
#[allow(clippy::too_many_arguments)]
fn describe(
    radius: f32,
    adjacent: &[[u8; MAX_ADJACENT]; ECSAD_DIM],
    cloud: &[Point3<f32>],
    normals: &[Vector3<f32>],
    neighbours: &Neighbours,
    k: usize,
    support: &mut Support,
    out: &mut Descriptor,
) {
    *out = [FRAC_PI_2; ECSAD_DIM];
    let (p, n) = (cloud[k], normals[k]);
    if !(is_valid_normal(&n) && p.x.is_finite() && p.y.is_finite() && p.z.is_finite()) {
        return;
    }
    let tiny = 1e-12 * radius * radius;
    support.clear();
    neighbours.for_each_within(&p, radius, |_, q, d2| {
        if d2 > tiny {
            support.push(q - p);
        }
    });

    // Reference axis from the normal deviations (see the module docs).
    let t1 = any_tangent(&n);
    let t2 = n.cross(&t1);
    let mut sums = AxisSums::default();
    axis_sums(support, &n, &t1, &t2, 1.0 / radius, &mut sums);
    let signed = Vector3::from(sums.signed);
    let [sxx, sxy, syy] = sums.scatter;
    let x_axis = if signed.norm() > SIGNED_AXIS_SHARE * sums.total && sums.total > 0.0 {
        signed.normalize()
    } else {
        let theta = 0.5 * (2.0 * sxy).atan2(sxx - syy);
        let axis = t1 * theta.cos() + t2 * theta.sin();
        if axis.dot(&signed) < 0.0 {
            -axis
        } else {
            axis
        }
    };
    let y_axis = n.cross(&x_axis);

    // Bin the support on the polar grid, then each bin's centroid.
    let ring_edge2 = [1.0f32, 2.0, 3.0].map(|i| (i * radius / RINGS as f32).powi(2));
    bin_support(support, &x_axis, &y_axis, &ring_edge2);
    let mut sums = [[0.0f32; 3]; ECSAD_DIM];
    let mut counts = [0u32; ECSAD_DIM];
    for (i, &bin) in support.bin.iter().enumerate() {
        let s = &mut sums[bin as usize];
        s[0] += support.x[i];
        s[1] += support.y[i];
        s[2] += support.z[i];
        counts[bin as usize] += 1;
    }

    let mut filled = [false; ECSAD_DIM];
    for bin in 0..ECSAD_DIM {
        if counts[bin] > 0 {
            let c = Vector3::from(sums[bin]) / counts[bin] as f32;
            out[bin] = c.cross(&n).norm().atan2(c.dot(&n));
            filled[bin] = true;
        }
    }
    fill_empty(out, &mut filled, adjacent);
}

/// Fills empty bins, round by round, with the mean of their filled neighbours.
fn fill_empty(values: &mut Descriptor, filled: &mut [bool; ECSAD_DIM], adjacent: &[[u8; MAX_ADJACENT]; ECSAD_DIM]) {
    if !filled.iter().any(|&f| f) {
        *values = [FRAC_PI_2; ECSAD_DIM];
        return;
    }
    while filled.iter().any(|&f| !f) {
        let mut next = *values;
        let mut next_filled = *filled;
        for bin in (0..ECSAD_DIM).filter(|&b| !filled[b]) {
            let (mut sum, mut count) = (0.0f32, 0u32);
            for &a in adjacent[bin].iter().take_while(|&&a| a != u8::MAX) {
                if filled[a as usize] {
                    sum += values[a as usize];
                    count += 1;
                }
            }
            if count > 0 {
                next[bin] = sum / count as f32;
                next_filled[bin] = true;
            }
        }
        *values = next;
        *filled = next_filled;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{NormalEstimator, MIN_NORMAL_NEIGHBOURS};
    use nalgebra::{Isometry3, Translation3, UnitQuaternion};
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A table with a box on it (40 x 30 x 12 mm), sampled at random with about one point
    /// per `spacing`^2, seen from above: table, box top and the four walls.
    fn box_on_table(rng: &mut ChaCha8Rng, spacing: f32, noise: f32) -> Vec<Point3<f32>> {
        let mut cloud = Vec::new();
        let density = 1.0 / (spacing * spacing);
        let mut patch = |cloud: &mut Vec<Point3<f32>>, area: f32, sample: &dyn Fn(f32, f32) -> Option<Point3<f32>>| {
            let n = (area * density) as usize;
            for _ in 0..n {
                let (a, b) = (rng.random_range(0.0..1.0f32), rng.random_range(0.0..1.0f32));
                if let Some(p) = sample(a, b) {
                    let jitter = Vector3::new(
                        rng.random_range(-noise..=noise),
                        rng.random_range(-noise..=noise),
                        rng.random_range(-noise..=noise),
                    );
                    cloud.push(p + jitter);
                }
            }
        };
        let inside = |x: f32, y: f32| x.abs() <= 20.0 && y.abs() <= 15.0;
        patch(&mut cloud, 120.0 * 120.0, &|a, b| {
            let (x, y) = (a * 120.0 - 60.0, b * 120.0 - 60.0);
            (!inside(x, y)).then(|| Point3::new(x, y, 0.0))
        });
        patch(&mut cloud, 40.0 * 30.0, &|a, b| Some(Point3::new(a * 40.0 - 20.0, b * 30.0 - 15.0, 12.0)));
        for side in [-1.0f32, 1.0] {
            patch(&mut cloud, 40.0 * 12.0, &|a, b| Some(Point3::new(a * 40.0 - 20.0, side * 15.0, b * 12.0)));
            patch(&mut cloud, 30.0 * 12.0, &|a, b| Some(Point3::new(side * 20.0, a * 30.0 - 15.0, b * 12.0)));
        }
        cloud
    }

    struct Described {
        cloud: Vec<Point3<f32>>,
        keypoints: Vec<u32>,
        descriptors: Vec<Descriptor>,
    }

    fn describe_cloud(cloud: Vec<Point3<f32>>, viewpoint: Point3<f32>, keypoints: Option<Vec<u32>>) -> Described {
        let mut grid = Neighbours::new();
        grid.build(&cloud, 5.0).unwrap();
        let mut normals = Vec::new();
        NormalEstimator::new(5.0, MIN_NORMAL_NEIGHBOURS).unwrap().compute(&cloud, &grid, &viewpoint, &mut normals);
        let keypoints = keypoints.unwrap_or_else(|| (0..cloud.len() as u32).collect());
        grid.build(&cloud, 10.0).unwrap();
        let mut descriptors = Vec::new();
        let mut ecsad = Ecsad::new(20.0).unwrap();
        ecsad.compute(&cloud, &normals, &grid, &keypoints, &mut descriptors).unwrap();
        Described { cloud, keypoints, descriptors }
    }

    /// The descriptor computed point by point, each sum in one running total: the oracle
    /// for [`describe`]'s passes in vector lanes.
    #[allow(clippy::too_many_arguments)]
    fn describe_point_by_point(
        radius: f32,
        adjacent: &[[u8; MAX_ADJACENT]; ECSAD_DIM],
        cloud: &[Point3<f32>],
        normals: &[Vector3<f32>],
        neighbours: &Neighbours,
        k: usize,
        offsets: &mut Vec<Vector3<f32>>,
        out: &mut Descriptor,
    ) {
        *out = [FRAC_PI_2; ECSAD_DIM];
        let (p, n) = (cloud[k], normals[k]);
        if !(is_valid_normal(&n) && p.x.is_finite() && p.y.is_finite() && p.z.is_finite()) {
            return;
        }
        let tiny = 1e-12 * radius * radius;
        offsets.clear();
        neighbours.for_each_within(&p, radius, |_, q, d2| {
            if d2 > tiny {
                offsets.push(q - p);
            }
        });

        // Reference axis from the normal deviations (see the module docs).
        let t1 = any_tangent(&n);
        let t2 = n.cross(&t1);
        let inv_r = 1.0 / radius;
        let mut signed = Vector3::zeros();
        let mut total = 0.0f32;
        let (mut sxx, mut sxy, mut syy) = (0.0f32, 0.0f32, 0.0f32);
        for d in offsets.iter() {
            let h = n.dot(d);
            let u = d - n * h;
            let r = u.norm();
            if r <= 0.0 {
                continue;
            }
            let w = h * (1.0 - r * inv_r).max(0.0) / r;
            signed += u * w;
            let aw = w.abs();
            total += aw * r;
            let (a, b) = (t1.dot(&u), t2.dot(&u));
            // Scatter of unit directions weighted by |h| (1 - r/R): aw / r scales u to û.
            let sw = aw / r;
            sxx += sw * a * a;
            sxy += sw * a * b;
            syy += sw * b * b;
        }
        let x_axis = if signed.norm() > SIGNED_AXIS_SHARE * total && total > 0.0 {
            signed.normalize()
        } else {
            let theta = 0.5 * (2.0 * sxy).atan2(sxx - syy);
            let axis = t1 * theta.cos() + t2 * theta.sin();
            if axis.dot(&signed) < 0.0 {
                -axis
            } else {
                axis
            }
        };
        let y_axis = n.cross(&x_axis);

        // Bin the support on the polar grid.
        let mut sums = [Vector3::<f32>::zeros(); ECSAD_DIM];
        let mut counts = [0u32; ECSAD_DIM];
        let ring_edge2 = [1.0f32, 2.0, 3.0].map(|i| (i * radius / RINGS as f32).powi(2));
        for d in offsets.iter() {
            let (x, y) = (x_axis.dot(d), y_axis.dot(d));
            let r2 = x * x + y * y;
            let ring =
                usize::from(r2 >= ring_edge2[0]) + usize::from(r2 >= ring_edge2[1]) + usize::from(r2 >= ring_edge2[2]);
            let sectors = RING_SECTORS[ring];
            let mut t = azimuth_turns(y, x) + 0.5 / sectors as f32;
            if t >= 1.0 {
                t -= 1.0;
            }
            let sector = ((t * sectors as f32) as usize).min(sectors - 1);
            let bin = RING_OFFSET[ring] + sector;
            sums[bin] += d;
            counts[bin] += 1;
        }

        let mut filled = [false; ECSAD_DIM];
        for bin in 0..ECSAD_DIM {
            if counts[bin] > 0 {
                let c = sums[bin] / counts[bin] as f32;
                out[bin] = c.cross(&n).norm().atan2(c.dot(&n));
                filled[bin] = true;
            }
        }
        fill_empty(out, &mut filled, adjacent);
    }

    #[test]
    fn vector_passes_match_the_point_by_point_descriptor() {
        let mut rng = ChaCha8Rng::seed_from_u64(23);
        let cloud = box_on_table(&mut rng, 2.0, 0.1);
        let viewpoint = Point3::new(10.0, -30.0, 600.0);
        let keypoints: Vec<u32> = (0..cloud.len() as u32).step_by(3).collect();
        let fast = describe_cloud(cloud.clone(), viewpoint, Some(keypoints.clone()));
        let mut grid = Neighbours::new();
        grid.build(&cloud, 5.0).unwrap();
        let mut normals = Vec::new();
        NormalEstimator::new(5.0, MIN_NORMAL_NEIGHBOURS).unwrap().compute(&cloud, &grid, &viewpoint, &mut normals);
        grid.build(&cloud, 10.0).unwrap();
        let adjacent = adjacency();
        let mut offsets = Vec::new();
        let mut same = 0;
        for (&k, got) in keypoints.iter().zip(&fast.descriptors) {
            let mut want = [0.0; ECSAD_DIM];
            describe_point_by_point(20.0, &adjacent, &cloud, &normals, &grid, k as usize, &mut offsets, &mut want);
            if distance(got, &want) < 1e-4 {
                same += 1;
            }
        }
        // The sums run in another order, so a point lying on a bin edge to the last bit may
        // fall on the other side: allow a few key points to differ.
        assert!(same * 1000 >= keypoints.len() * 995, "{same} of {} agree", keypoints.len());
    }

    fn distance(a: &Descriptor, b: &Descriptor) -> f32 {
        a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f32>().sqrt()
    }

    #[test]
    fn bin_layout_covers_thirty_bins_with_symmetric_adjacency() {
        assert_eq!(RING_SECTORS.iter().sum::<usize>(), ECSAD_DIM);
        for r in 1..RINGS {
            assert_eq!(RING_OFFSET[r], RING_OFFSET[r - 1] + RING_SECTORS[r - 1]);
        }
        let adj = adjacency();
        for (bin, row) in adj.iter().enumerate() {
            let list: Vec<usize> = row.iter().take_while(|&&a| a != u8::MAX).map(|&a| a as usize).collect();
            assert!(list.len() >= 3 && !list.contains(&bin));
            for &a in &list {
                assert!(adj[a].contains(&(bin as u8)), "{bin} -> {a} but not back");
            }
        }
        for i in 0..1000 {
            let angle = i as f32 / 1000.0 * TAU - PI;
            let want = angle.sin().atan2(angle.cos()).rem_euclid(TAU) / TAU;
            let got = azimuth_turns(angle.sin(), angle.cos());
            let diff = (got - want).abs();
            assert!(diff.min(1.0 - diff) < 3e-6, "{angle}: {got} vs {want}");
        }
    }

    #[test]
    fn descriptors_are_invariant_to_a_rigid_motion() {
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let cloud = box_on_table(&mut rng, 2.0, 0.0);
        let viewpoint = Point3::new(30.0, -20.0, 600.0);
        let keypoints: Vec<u32> = (0..cloud.len() as u32).step_by(7).collect();
        let a = describe_cloud(cloud.clone(), viewpoint, Some(keypoints.clone()));
        for _ in 0..3 {
            let motion = Isometry3::from_parts(
                Translation3::new(rng.random_range(-300.0..300.0), rng.random_range(-300.0..300.0), 500.0),
                UnitQuaternion::from_euler_angles(
                    rng.random_range(-3.0..3.0),
                    rng.random_range(-3.0..3.0),
                    rng.random_range(-3.0..3.0),
                ),
            );
            let moved: Vec<Point3<f32>> = cloud.iter().map(|p| motion * p).collect();
            let b = describe_cloud(moved, motion * viewpoint, Some(keypoints.clone()));
            // Rounding may move a point across a bin edge: allow a few such key points.
            let mut close = 0;
            for (da, db) in a.descriptors.iter().zip(&b.descriptors) {
                if distance(da, db) < 0.01 {
                    close += 1;
                }
            }
            assert!(close * 100 >= keypoints.len() * 97, "{close} of {} unchanged", keypoints.len());
        }
    }

    #[test]
    fn edges_and_corners_differ_from_planes() {
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let cloud = box_on_table(&mut rng, 2.0, 0.05);
        let nearest = |c: &[Point3<f32>], at: Point3<f32>| -> u32 {
            (0..c.len() as u32)
                .min_by(|&i, &j| (c[i as usize] - at).norm().total_cmp(&(c[j as usize] - at).norm()))
                .unwrap()
        };
        let spots = [
            Point3::new(-40.0, 35.0, 0.0),  // table, far from the box
            Point3::new(40.0, -38.0, 0.0),  // table elsewhere
            Point3::new(-40.0, -40.0, 0.0), // table, a third place
            Point3::new(19.0, 0.0, 12.0),   // top, at an edge
            Point3::new(19.0, 14.0, 12.0),  // top, at a corner
            Point3::new(22.0, 0.0, 0.0),    // table, at the foot of a wall
        ];
        let keys: Vec<u32> = spots.iter().map(|&s| nearest(&cloud, s)).collect();
        let d = describe_cloud(cloud, Point3::new(0.0, 0.0, 600.0), Some(keys)).descriptors;
        let flat_spread = distance(&d[0], &d[1]).max(distance(&d[0], &d[2])).max(distance(&d[1], &d[2]));
        assert!(flat_spread < 0.15, "planes differ by {flat_spread}");
        for structured in 3..6 {
            for plane in 0..3 {
                let gap = distance(&d[structured], &d[plane]);
                assert!(gap > 5.0 * flat_spread.max(0.05), "spot {structured} vs plane {plane}: {gap}");
            }
        }
        assert!(distance(&d[3], &d[4]) > 0.3, "edge vs corner");
        assert!(distance(&d[3], &d[5]) > 0.3, "convex vs concave edge");
    }

    #[test]
    fn resampled_noisy_surfaces_match_at_the_same_places() {
        let mut rng = ChaCha8Rng::seed_from_u64(17);
        let viewpoint = Point3::new(0.0, 0.0, 600.0);
        let a = describe_cloud(box_on_table(&mut rng, 2.0, 0.15), viewpoint, None);
        let b = describe_cloud(box_on_table(&mut rng, 2.0, 0.15), viewpoint, None);
        // Places with structure within the support: near the box, away from the table's rim.
        let near_box = |p: &Point3<f32>| p.x.abs() < 35.0 && p.y.abs() < 30.0 && (p.x.abs() > 12.0 || p.y.abs() > 8.0);
        let nearest_in_b = |p: &Point3<f32>| {
            (0..b.cloud.len()).min_by(|&i, &j| (b.cloud[i] - p).norm().total_cmp(&(b.cloud[j] - p).norm())).unwrap()
        };
        let structured_b: Vec<usize> = (0..b.cloud.len()).filter(|&i| near_box(&b.cloud[i])).collect();
        let (mut tried, mut found) = (0, 0);
        let (mut same, mut other) = (Vec::new(), Vec::new());
        for (ia, pa) in a.cloud.iter().enumerate().step_by(5).filter(|(_, p)| near_box(p)) {
            let da = &a.descriptors[a.keypoints[ia] as usize];
            let best = (0..b.descriptors.len())
                .min_by(|&i, &j| distance(da, &b.descriptors[i]).total_cmp(&distance(da, &b.descriptors[j])))
                .unwrap();
            tried += 1;
            if (b.cloud[best] - pa).norm() < 4.5 {
                found += 1;
            }
            same.push(distance(da, &b.descriptors[nearest_in_b(pa)]));
            other.push(distance(da, &b.descriptors[structured_b[rng.random_range(0..structured_b.len())]]));
        }
        same.sort_by(f32::total_cmp);
        other.sort_by(f32::total_cmp);
        let (same_median, other_median) = (same[same.len() / 2], other[other.len() / 2]);
        assert!(tried > 100);
        // The same place described twice must be far closer than two places chosen at random.
        assert!(
            same_median < 0.35 * other_median,
            "median distance same place {same_median}, elsewhere {other_median}"
        );
        // Points along a straight edge look alike, so a nearest descriptor may lie anywhere
        // on that edge; chance alone would put about 2% within 4.5 mm.
        assert!(found * 100 >= tried * 12, "{found} of {tried} matched within 4.5 mm");
    }
}
