//! A frame's result scored against its truth and many summed up: one frame's record as a
//! JSON line ([`FrameRecord`], the paper's metrics in [`score`]), a set of frames' [`Summary`]
//! with Wilson's interval, and the verification's figures over scored frames. Replaying a
//! recording on the cell PC and evaluating a placement in simulation both write and read
//! these, so a rendered dataset replayed gives exactly the numbers its evaluation gave. No
//! file is opened here.

mod intervals;
mod record;
mod summary;
mod verified;

pub use intervals::wilson_interval;
pub use record::{score, FrameRecord, NegativeRecord, Score, SlotRecord, SlotScore, Timings};
pub(crate) use summary::median_or_nan;
pub use summary::{median, median_in_place, pct, percentile, NegativesSummary, SlotSummary, Summary};
pub use verified::{
    choose_threshold, clopper_pearson_upper, gross_error, precision_recall, NearMissExcess, Scored, VerifiedSummary,
    GROSS_FACTOR, REFUSE_ALL,
};
