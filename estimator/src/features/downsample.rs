//! Voxel-grid down-sampling to the surface resolution SRes: one point per occupied voxel,
//! the centroid of the points in it. The voxel table it fills (which key point selection
//! uses too) lives in `spatial`; neither allocates once it has seen a cloud as large as the
//! current one.

use nalgebra::{Point3, Vector3};

use crate::spatial::{check_voxel_size, voxel_key, VoxelTable};
use crate::Result;

/// Down-samples clouds to voxel centroids, reusing its buffers from frame to frame.
#[derive(Debug, Clone, Default)]
pub struct Downsampler {
    table: VoxelTable,
    /// Per voxel: sum of offsets from the voxel's first point, and the count.
    sums: Vec<(Vector3<f32>, u32)>,
}

impl Downsampler {
    /// A down-sampler whose buffers grow on first use.
    pub fn new() -> Self {
        Downsampler::default()
    }

    /// A down-sampler with room for clouds of up to `points` points.
    pub fn with_capacity(points: usize) -> Self {
        Downsampler { table: VoxelTable::with_capacity(points), sums: Vec::with_capacity(points) }
    }

    /// Replaces `out` with one point per occupied voxel of side `voxel_size` (mm): the
    /// centroid of its points, in order of each voxel's first point in `cloud`.
    /// Non-finite points are skipped.
    pub fn downsample(&mut self, cloud: &[Point3<f32>], voxel_size: f32, out: &mut Vec<Point3<f32>>) -> Result<()> {
        let inv = check_voxel_size("down-sampling", voxel_size)?;
        self.table.reset(cloud.len());
        self.sums.clear();
        out.clear();
        for p in cloud {
            let Some(key) = voxel_key(p, inv) else { continue };
            let (slot, new) = self.table.slot(key);
            if new {
                // Summing offsets from the first point keeps f32 sums exact to ~1e-6 mm.
                out.push(*p);
                self.sums.push((Vector3::zeros(), 1));
            } else {
                let s = &mut self.sums[slot as usize];
                s.0 += p - out[slot as usize];
                s.1 += 1;
            }
        }
        for (p, &(sum, count)) in out.iter_mut().zip(&self.sums) {
            *p += sum / count as f32;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use std::collections::HashMap;

    #[test]
    fn centroids_match_a_map_of_voxels() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let mut down = Downsampler::new();
        let mut out = Vec::new();
        for &(n, size) in &[(5000usize, 2.0f32), (20000, 1.5), (300, 7.0)] {
            let mut cloud: Vec<Point3<f32>> = (0..n)
                .map(|_| {
                    Point3::new(
                        rng.random_range(-50.0..50.0),
                        rng.random_range(-30.0..30.0),
                        rng.random_range(0.0..4.0),
                    )
                })
                .collect();
            cloud.push(Point3::new(f32::NAN, 1.0, 1.0));
            down.downsample(&cloud, size, &mut out).unwrap();
            // The slow version: group by voxel with a map, remember first appearance.
            let mut groups: HashMap<[i64; 3], (usize, Vec<Point3<f64>>)> = HashMap::new();
            for (i, p) in cloud.iter().enumerate().filter(|(_, p)| p.x.is_finite()) {
                // Voxel membership is defined by the f32 product, as in the fast version.
                let v = [p.x, p.y, p.z].map(|c| (c * (1.0 / size)).floor() as i64);
                groups.entry(v).or_insert((i, Vec::new())).1.push(p.cast::<f64>());
            }
            let mut want: Vec<(usize, Point3<f64>)> = groups
                .into_values()
                .map(|(first, pts)| {
                    let c = pts.iter().fold(Vector3::zeros(), |a, p| a + p.coords) / pts.len() as f64;
                    (first, Point3::from(c))
                })
                .collect();
            want.sort_by_key(|w| w.0);
            assert_eq!(out.len(), want.len());
            for (got, (_, w)) in out.iter().zip(&want) {
                assert!((got.cast::<f64>() - w).norm() < 1e-4, "{got} vs {w}");
            }
        }
    }

    #[test]
    fn bad_sizes_are_errors() {
        let mut down = Downsampler::new();
        let mut out = Vec::new();
        for size in [0.0, -1.0, f32::NAN, f32::INFINITY] {
            assert!(down.downsample(&[Point3::origin()], size, &mut out).is_err());
        }
    }
}
