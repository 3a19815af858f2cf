//! The placement study's common ground: what one frame's result is ([`FrameRecord`]), how it
//! is scored against the truth ([`score`]), how results of many scenes are summed up
//! ([`Summary`], with a Wilson interval), and how one placement's scenes are run
//! ([`Evaluator`]). `estimate`, `replay`, `run` and `evaluate` all write and read these, so a
//! rendered dataset replayed gives exactly the numbers its evaluation gave. On top: the
//! results file, the job evaluator, shards, the sweep's grid, the search and the comparisons
//! the report states.

pub mod ablation;
mod evaluate;
pub mod findings;
pub mod folder;
pub mod grid;
mod intervals;
pub mod jobs;
pub mod lock;
pub mod merge;
pub mod one_placement;
pub mod optimize;
pub mod placement_search;
pub mod placement_study;
mod record;
pub mod recording;
pub mod results;
pub mod settings;
pub mod shard;
mod summary;
pub mod sweep;
pub mod tolerance;
pub mod tolerance_report;
pub mod tolerance_walk;
pub mod tray_set;
pub mod verified;

pub use evaluate::Evaluator;
pub use record::{score, FrameRecord, Score};
pub use summary::{median, pct, Summary};
