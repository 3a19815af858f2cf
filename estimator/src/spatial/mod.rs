//! The point indexes the stages query, and the cell keys and bucket hash they share.
//!
//! Four structures, because four questions are asked:
//!
//! - [`Neighbours`]: every point within a radius, and the k nearest (normals, descriptors,
//!   the simulator's model builder). A hashed grid keyed by [`pack_cell`] and bucketed by
//!   [`bucket`].
//! - [`VoxelTable`]: which voxel a point falls in, numbered by first appearance, to
//!   accumulate centroids (down-sampling, key points). An open-addressing map over the same
//!   [`pack_cell`] keys and [`bucket`] hash; it answers no distance query.
//! - [`SceneGrid`]: is any scene point within a fixed reach of a model point, and which is
//!   the nearest (RANSAC's scoring, millions of queries a frame). Cells twice the reach, so
//!   a query reads exactly 8 cells and never compares keys. It keeps its own bucket hash:
//!   its nearest query keeps the last of equally distant points in visiting order, and the
//!   hash fixes that order, so another hash could turn a tie and with it a pose.
//! - [`NearestGrid`]: an approximate nearest model point in O(1) (ICP's pairing): a dense
//!   array over a fixed model view with the answer stored per cell, built once per model.
//!   Not a hash at all: the model is small and static, the scene is not.

mod nearest_grid;
mod neighbours;
mod scene_grid;
#[cfg(test)]
mod tests;
mod voxel_table;

pub(crate) use nearest_grid::NearestGrid;
pub use neighbours::Neighbours;
pub(crate) use scene_grid::SceneGrid;
pub(crate) use voxel_table::{check_voxel_size, voxel_key, VoxelTable};

/// `v.floor() as i32`, without the call to libm's `floorf` that the baseline x86-64 target
/// makes (it has no rounding instruction); the queries here take millions a frame. Equal
/// to the cast of the floor for every input: NaN gives 0, and values beyond the range of
/// i32 saturate.
#[inline]
pub(crate) fn floor_i32(v: f32) -> i32 {
    let truncated = v as i32;
    truncated.saturating_sub(i32::from(truncated as f32 > v))
}

/// Cell coordinates fit in [-CELL_LIMIT, CELL_LIMIT) so three pack into one `u64` key.
pub(crate) const CELL_LIMIT: i64 = 1 << 20;

/// The key of cell `c` (each coordinate in [-CELL_LIMIT, CELL_LIMIT)): 21 bits per axis,
/// x lowest.
#[inline]
pub(crate) fn pack_cell(c: [i64; 3]) -> u64 {
    let m = (1u64 << 21) - 1;
    (((c[0] + CELL_LIMIT) as u64) & m)
        | ((((c[1] + CELL_LIMIT) as u64) & m) << 21)
        | ((((c[2] + CELL_LIMIT) as u64) & m) << 42)
}

/// Bucket count for `entries` entries (a power of two, at least twice as many and at least
/// 16) and the shift that makes [`bucket`] land in it.
#[inline]
pub(crate) fn table_size(entries: usize) -> (usize, u32) {
    let len = (2 * entries).next_power_of_two().max(16);
    (len, 64 - len.trailing_zeros())
}

/// Fibonacci hash of a cell key into a table of `2^(64 - shift)` buckets.
#[inline]
pub(crate) fn bucket(key: u64, shift: u32) -> usize {
    (key.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> shift) as usize
}
