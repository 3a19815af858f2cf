//! Opening the frame source a [`SourceSpec`] names: a recorded dataset always, cameras
//! when this build has their feature (a clear error naming the feature otherwise).

use crate::frames::FrameSource;
use crate::pixels::InterleavedOrder;
use crate::recorded::RecordedSource;
use crate::spec::SourceSpec;
use crate::{Error, ErrorKind, Result};

/// Opens the source `spec` names; a clear error when this build lacks its feature.
pub fn open_source(spec: &SourceSpec) -> Result<Box<dyn FrameSource + Send>> {
    match spec {
        SourceSpec::Recorded(dir) => Ok(Box::new(RecordedSource::open(dir)?)),
        SourceSpec::V4l2Pair { .. } | SourceSpec::V4l2SideBySide { .. } | SourceSpec::V4l2Interleaved { .. } => {
            open_v4l2(spec)
        }
        SourceSpec::Dc1394 { guid, order } => open_dc1394(*guid, *order),
    }
}

#[cfg(feature = "v4l")]
fn open_v4l2(spec: &SourceSpec) -> Result<Box<dyn FrameSource + Send>> {
    Ok(Box::new(crate::v4l2::V4l2Source::open(spec)?))
}

#[cfg(not(feature = "v4l"))]
fn open_v4l2(_spec: &SourceSpec) -> Result<Box<dyn FrameSource + Send>> {
    Err(not_built("V4L2 cameras", "v4l"))
}

#[cfg(feature = "dc1394")]
fn open_dc1394(guid: Option<u64>, order: InterleavedOrder) -> Result<Box<dyn FrameSource + Send>> {
    Ok(Box::new(crate::dc1394::Dc1394Source::open(guid, order)?))
}

#[cfg(not(feature = "dc1394"))]
fn open_dc1394(_guid: Option<u64>, _order: InterleavedOrder) -> Result<Box<dyn FrameSource + Send>> {
    Err(not_built("FireWire (IIDC) cameras", "dc1394"))
}

#[allow(dead_code)] // unused when every feature is built
fn not_built(what: &str, feature: &str) -> Error {
    Error::new(
        ErrorKind::NotBuilt,
        format!("{what} need camplace-hwio's `{feature}` feature, which this build lacks (rebuild with --features {feature})"),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spec::parse_source;

    #[test]
    fn missing_cameras_are_errors_not_panics() {
        let dev = "/dev/video-camplace-test-missing";
        for spec in [format!("v4l2:{dev},{dev}"), format!("v4l2-sbs:{dev}"), format!("v4l2-16:{dev}")] {
            let e = open_source(&parse_source(&spec).unwrap()).err().expect("no such camera");
            if cfg!(feature = "v4l") {
                assert_eq!(e.kind(), ErrorKind::Device, "{e}");
                assert!(e.to_string().contains(dev), "{e}");
            } else {
                assert_eq!(e.kind(), ErrorKind::NotBuilt, "{e}");
                assert!(e.to_string().contains("`v4l`"), "{e}");
            }
        }
        if !cfg!(feature = "dc1394") {
            let e = open_source(&parse_source("dc1394").unwrap()).err().expect("not built");
            assert_eq!(e.kind(), ErrorKind::NotBuilt, "{e}");
        }
        let e = open_source(&SourceSpec::Recorded("/nonexistent/camplace".into())).err().expect("no folder");
        assert!(e.to_string().contains("/nonexistent/camplace"), "{e}");
    }
}
