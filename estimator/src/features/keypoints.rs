//! Feature key points: a sparser subset of the SRes cloud (one per coarse voxel of side
//! `keypoint_spacing`, the cloud point nearest the centroid of that voxel's points), and,
//! once described, only those whose descriptor shows relief (see [`keep_distinctive`]). Key
//! points are indices into the cloud, which stays the feature support.

use nalgebra::{Point3, Vector3};

use super::ecsad::{relief_deg, Descriptor};
use super::normals::is_valid_normal;
use crate::spatial::{check_voxel_size, voxel_key, VoxelTable};
use crate::{Error, ErrorKind, Result};

/// Picks key points, reusing its buffers from frame to frame.
#[derive(Debug, Clone, Default)]
pub struct KeypointSelector {
    table: VoxelTable,
    /// Per coarse voxel: sum of offsets from its first point, and the count.
    sums: Vec<(Vector3<f32>, u32)>,
    /// Per coarse voxel: its first point (the offsets' origin), then its centroid.
    centres: Vec<Point3<f32>>,
    /// Per cloud point: its voxel slot, or `u32::MAX` when it cannot be a key point.
    slots: Vec<u32>,
    /// Per coarse voxel: distance2 to the centroid of the best point so far.
    best: Vec<f32>,
}

impl KeypointSelector {
    /// A selector whose buffers grow on first use.
    pub fn new() -> Self {
        KeypointSelector::default()
    }

    /// Replaces `out` with the indices of the key points of `cloud`: for each voxel of side
    /// `spacing` (mm) holding points with a valid normal, the one nearest to their centroid
    /// (the lower index on a tie), in order of each voxel's first such point.
    pub fn select(
        &mut self,
        cloud: &[Point3<f32>],
        normals: &[Vector3<f32>],
        spacing: f32,
        out: &mut Vec<u32>,
    ) -> Result<()> {
        let inv = check_voxel_size("key points", spacing)?;
        if cloud.len() != normals.len() {
            return Err(Error::new(
                ErrorKind::Input,
                format!("key points: {} points but {} normals", cloud.len(), normals.len()),
            ));
        }
        self.table.reset(cloud.len());
        self.sums.clear();
        self.centres.clear();
        self.slots.clear();
        out.clear();
        for (p, n) in cloud.iter().zip(normals) {
            let key = if is_valid_normal(n) { voxel_key(p, inv) } else { None };
            let Some(key) = key else {
                self.slots.push(u32::MAX);
                continue;
            };
            let (slot, new) = self.table.slot(key);
            self.slots.push(slot);
            if new {
                self.centres.push(*p);
                self.sums.push((Vector3::zeros(), 1));
                out.push(u32::MAX);
            } else {
                let s = &mut self.sums[slot as usize];
                s.0 += p - self.centres[slot as usize];
                s.1 += 1;
            }
        }
        for (c, &(sum, count)) in self.centres.iter_mut().zip(&self.sums) {
            *c += sum / count as f32;
        }
        self.best.clear();
        self.best.resize(out.len(), f32::INFINITY);
        for (i, (p, &slot)) in cloud.iter().zip(&self.slots).enumerate() {
            if slot == u32::MAX {
                continue;
            }
            let d2 = (p - self.centres[slot as usize]).norm_squared();
            // Strictly closer only: the first (lowest) index wins a tie.
            if d2 < self.best[slot as usize] || out[slot as usize] == u32::MAX {
                self.best[slot as usize] = d2;
                out[slot as usize] = i as u32;
            }
        }
        Ok(())
    }
}

/// Keeps, in order and in place, the key points whose descriptor's relief reaches
/// `min_relief_deg` ([`relief_deg`]), with their descriptors. Flat surface (the tray's floor,
/// an item's top) gives near-identical descriptors everywhere, so its matches are right by
/// chance only and crowd out the few that fix the pose.
pub fn keep_distinctive(keypoints: &mut Vec<u32>, descriptors: &mut Vec<Descriptor>, min_relief_deg: f32) {
    debug_assert_eq!(keypoints.len(), descriptors.len());
    let mut kept = 0;
    for i in 0..keypoints.len().min(descriptors.len()) {
        if relief_deg(&descriptors[i]) >= min_relief_deg {
            keypoints[kept] = keypoints[i];
            descriptors[kept] = descriptors[i];
            kept += 1;
        }
    }
    keypoints.truncate(kept);
    descriptors.truncate(kept);
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use std::collections::BTreeMap;

    #[test]
    fn one_key_point_per_voxel_nearest_its_centroid() {
        let mut rng = ChaCha8Rng::seed_from_u64(8);
        let n = 6000;
        let cloud: Vec<Point3<f32>> = (0..n)
            .map(|_| {
                Point3::new(rng.random_range(-40.0..40.0), rng.random_range(-40.0..40.0), rng.random_range(0.0..2.0))
            })
            .collect();
        let normals: Vec<Vector3<f32>> =
            (0..n).map(|i| if i % 7 == 3 { Vector3::zeros() } else { Vector3::z() }).collect();
        let spacing = 4.0f32;
        let mut sel = KeypointSelector::new();
        let mut got = Vec::new();
        sel.select(&cloud, &normals, spacing, &mut got).unwrap();
        // The slow version: group valid points by voxel, then scan each group.
        let mut groups: BTreeMap<[i64; 3], Vec<usize>> = BTreeMap::new();
        for i in (0..n).filter(|i| i % 7 != 3) {
            let p = cloud[i];
            groups.entry([p.x, p.y, p.z].map(|c| (c * (1.0 / spacing)).floor() as i64)).or_default().push(i);
        }
        let mut want: Vec<u32> = groups
            .values()
            .map(|members| {
                let c = members.iter().fold(Vector3::<f64>::zeros(), |a, &i| a + cloud[i].coords.cast::<f64>())
                    / members.len() as f64;
                let d = |i: usize| (cloud[i].coords.cast::<f64>() - c).norm();
                let best = members.iter().copied().min_by(|&a, &b| d(a).total_cmp(&d(b))).unwrap();
                // Accept a near tie decided the other way by f32 rounding.
                let pick = got.iter().copied().find(|&g| members.contains(&(g as usize)));
                match pick {
                    Some(g) if (d(g as usize) - d(best)).abs() < 1e-4 => g,
                    _ => best as u32,
                }
            })
            .collect();
        assert_eq!(got.len(), want.len());
        let mut sorted = got.clone();
        sorted.sort_unstable();
        want.sort_unstable();
        assert_eq!(sorted, want);
        assert!(got.iter().all(|&i| i % 7 != 3));
        assert!(sel.select(&cloud, &normals[1..], spacing, &mut got).is_err());
    }
}
