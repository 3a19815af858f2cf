//! The voxel table of down-sampling and key point selection: packed voxel keys mapped to
//! dense slot numbers in order of first appearance, so centroids can be accumulated per
//! voxel and every output order is a function of the input order alone.

use nalgebra::Point3;

use super::{bucket, pack_cell, table_size, CELL_LIMIT};
use crate::{Error, ErrorKind, Result};

const EMPTY: u64 = u64::MAX;

/// Packed voxel key of `p` for voxels of side `1 / inv_size`, or `None` for a non-finite
/// point or one beyond the packable range (over 2 km out at SRes 2 mm: bad data, dropped).
#[inline]
pub(crate) fn voxel_key(p: &Point3<f32>, inv_size: f32) -> Option<u64> {
    let mut c = [0i64; 3];
    for (axis, v) in [p.x, p.y, p.z].into_iter().enumerate() {
        let f = (v * inv_size).floor();
        if !(f >= -(CELL_LIMIT as f32) && f < CELL_LIMIT as f32) {
            return None;
        }
        c[axis] = f as i64;
    }
    Some(pack_cell(c))
}

/// Open-addressing map from packed voxel key to a dense slot number given out in order of
/// first appearance. Unlike [`super::Neighbours`] it answers no distance query: it only
/// numbers voxels, so the stages can accumulate per voxel in flat arrays.
#[derive(Debug, Clone, Default)]
pub(crate) struct VoxelTable {
    keys: Vec<u64>,
    slots: Vec<u32>,
    occupied: u32,
    shift: u32,
}

impl VoxelTable {
    /// An empty table with room for `points` distinct voxels reserved but not yet touched,
    /// so memory is committed only as far as frames use it.
    pub(crate) fn with_capacity(points: usize) -> Self {
        let (len, _) = table_size(points);
        VoxelTable { keys: Vec::with_capacity(len), slots: Vec::with_capacity(len), ..Self::default() }
    }

    /// Empties the table, sized for up to `points` distinct voxels.
    pub(crate) fn reset(&mut self, points: usize) {
        let (len, shift) = table_size(points);
        self.shift = shift;
        self.keys.clear();
        self.keys.resize(len, EMPTY);
        self.slots.clear();
        self.slots.resize(len, 0);
        self.occupied = 0;
    }

    /// Slot of `key`, and whether it was new.
    #[inline]
    pub(crate) fn slot(&mut self, key: u64) -> (u32, bool) {
        let mask = self.keys.len() - 1;
        let mut at = bucket(key, self.shift);
        loop {
            let k = self.keys[at];
            if k == key {
                return (self.slots[at], false);
            }
            if k == EMPTY {
                // reset() sized the table at twice the point count, so it never fills.
                self.keys[at] = key;
                self.slots[at] = self.occupied;
                self.occupied += 1;
                return (self.slots[at], true);
            }
            at = (at + 1) & mask;
        }
    }
}

/// Checks a voxel size given in mm.
pub(crate) fn check_voxel_size(what: &str, size: f32) -> Result<f32> {
    if size.is_finite() && size > 0.0 {
        Ok(1.0 / size)
    } else {
        Err(Error::new(ErrorKind::Input, format!("{what}: expected a positive voxel size in mm, got {size}")))
    }
}
