//! The placement study: how one placement's scenes are run ([`Evaluator`], each frame scored
//! into the estimator's `FrameRecord` and summed up in its `Summary`, as a replayed recording
//! is), the results file, the job evaluator, shards, the sweep's grid, the search and the
//! comparisons the report states.

pub mod ablation;
mod evaluate;
pub mod findings;
pub mod folder;
pub mod jobs;
pub mod lock;
pub mod merge;
pub(crate) mod negatives;
pub mod one_placement;
pub mod optimize;
pub mod placement_search;
pub mod placement_study;
pub mod results;
pub mod settings;
pub mod shard;
pub mod sweep;
pub mod tolerance;
pub mod tolerance_walk;
pub mod tray_set;

pub use evaluate::Evaluator;
