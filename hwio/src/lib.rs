//! camplace's hardware side: frame sources (recorded dataset folders always; V4L2 and
//! FireWire IIDC cameras behind the `v4l` and `dc1394` features), camera pixel formats,
//! device listing, the projector window (behind `display`), and the deployed loop that
//! estimates a tray pose per captured frame.

pub mod capture;
#[cfg(feature = "dc1394")]
pub mod dc1394;
pub mod deploy;
pub mod devices;
#[cfg(feature = "display")]
pub mod display;
mod error;
pub mod frames;
pub mod paced;
pub mod pixels;
pub mod recorded;
pub mod spec;
#[cfg(feature = "v4l")]
pub mod v4l2;

pub use capture::{Capture, Captured, WhenBehind};
pub use deploy::{DeploySource, DeployStats, Deployment, Estimated};
pub use devices::{list_devices, DeviceList};
#[cfg(feature = "display")]
pub use display::show_patterns;
pub use error::{Error, ErrorKind, Result};
pub use frames::{FrameInfo, FrameSource, Frames};
pub use paced::Paced;
pub use pixels::{InterleavedOrder, PixelFormat};
pub use recorded::{read_background, RecordedSource};
pub use spec::{open_source, parse_source, SourceSpec};
