//! The real-world trial (the paper's Section 7): the plan of placements to carry the real
//! rig to, the trial folder with one recorded dataset per placement, judging real poses
//! (by truth, or by a reviewer's marks made on the review page), a mock trial rendered by a
//! cell the study does not know, and the report that sets the real success map beside the
//! simulated one.

pub mod judge;
pub mod layout;
pub mod mock;
pub mod plan;
pub mod rank;
pub mod report;
pub mod review_page;
pub mod review_server;
