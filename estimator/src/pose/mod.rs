//! From feature matches to the tray's pose: the tray model, prerejective RANSAC for the
//! coarse pose, point-to-plane ICP to refine it, the rigid fit both use, and the quality
//! metrics of an estimate against the truth, and the verification of the pose found, and the states of the
//! tray's slots under it.

mod alternatives;
mod icp;
mod kabsch;
mod metrics;
mod model;
mod model_file;
mod model_load;
mod ransac;
mod see_through;
mod self_occlusion;
mod slots;
mod verify;

pub use alternatives::{Alternative, Alternatives, MAX_ALTERNATIVES};
pub(crate) use icp::on_table;
pub use icp::{Icp, IcpResult};
pub use metrics::{correct_matches, pose_errors, PoseErrors};
pub use model::{Model, ModelOrigin, ModelVerification, ModelView};
pub use model_file::MODEL_FORMAT_VERSION;
pub use ransac::{Ransac, RansacCheck, RansacResult};
pub(crate) use see_through::turn_see_through;
pub use see_through::{
    see_through, slot_pitches, tray_points, DepthEvidence, SeeThroughCounts, OCCLUDED_MARGIN_MM, SEE_THROUGH_MARGIN_MM,
};
pub(crate) use self_occlusion::Occluder;
pub use slots::{
    slot_letters, SlotJudge, SlotLayout, SlotReading, SlotState, EDGE_CELL, FLOOR_TOLERANCE_MM, MAX_FOOTPRINT_CELLS,
    MAX_MISMATCH_SHARE, MIN_SEEN_SHARE,
};
pub(crate) use verify::{lead_sigmas, most_favoured_turn, turn_favoured, Weighed};
pub use verify::{
    Verdict, Verification, Verifier, AMBIGUOUS_TURN_SIGMAS, CONFLICTING_TURN_SIGMAS, RESTING_HEIGHT_MM,
    RESTING_TILT_DEG, SEE_THROUGH_MIN_EXCESS, SEE_THROUGH_MIN_TESTED, SEE_THROUGH_SIGMAS,
};
