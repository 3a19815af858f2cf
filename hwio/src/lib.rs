//! camplace's hardware side: frame sources (recorded dataset folders always; V4L2 and
//! FireWire IIDC cameras behind the `v4l` and `dc1394` features), camera pixel formats,
//! device listing, capture into a recorded dataset, the projector window (behind
//! `display`), the deployed loop that
//! estimates a tray pose per captured frame, and recorded datasets replayed through the
//! estimator (poses scored against their truth) or reconstructed to depth and clouds.

mod board_pairs;
mod capture;
mod cpu_time;
mod dataset_capture;
#[cfg(feature = "dc1394")]
mod dc1394;
mod deploy;
mod device_list;
mod devices;
#[cfg(feature = "display")]
mod display;
mod error;
mod frames;
mod in_step;
mod latency_plot;
mod open;
mod paced;
mod pixels;
mod reconstruct;
mod recorded;
mod replay;
mod resident;
mod spec;
#[cfg(feature = "v4l")]
mod v4l2;

pub use board_pairs::{board_view_folders, find_board_pairs, find_board_views, BoardPairs, MAX_CALIBRATION_VIEWS};
pub use camplace_config::{append_frame, read_background, write_background, write_table_view};
pub use capture::{Capture, Captured, WhenBehind};
pub use dataset_capture::{
    capture_dataset, capture_rig, CaptureKind, CaptureOutcome, CapturePlan, CapturedFrame, MAX_CAPTURE_COUNT,
    MAX_CAPTURE_EVERY_S,
};
pub use deploy::{DeploySource, DeployStats, Deployment, Estimated, FrameTiming};
pub use devices::{list_devices, DeviceList, FirewireDevice, UsbDevice, V4l2Device};
#[cfg(feature = "display")]
pub use display::{Projector, ProjectorThread};
pub use error::{Error, ErrorKind, Result};
pub use frames::{FrameInfo, FrameSource, Frames};
pub use in_step::{capture_in_step, InStepSource, PatternScreen};
pub use latency_plot::{frame_budget_ms, latency_plot_target, write_latency_plot};
pub use open::open_source;
pub use paced::Paced;
pub use pixels::{deinterleave16, luma601, split_side_by_side, to_gray, InterleavedOrder, PixelFormat};
pub use reconstruct::{
    match_rectified, reconstruct_dataset, reconstruct_pair, DatasetDepth, PairDepth, RectifiedDepth, RectifiedPair,
};
pub use recorded::RecordedSource;
pub use replay::{estimate_dataset, estimator_for, record as frame_record, DatasetEstimate};
pub use resident::keep_large_buffers_unbacked;
pub use spec::{parse_source, SourceSpec, SOURCE_FORMS};
