//! Source specifications as the user types them (`dir:PATH`, `v4l2:A,B`, `v4l2-sbs:N`,
//! `v4l2-16:N`, `dc1394[:GUID]`), parsed; `open.rs` opens the source one names.

use std::path::PathBuf;

use crate::pixels::InterleavedOrder;
use crate::{Error, ErrorKind, Result};

/// The forms `parse_source` accepts, for error messages and `--help`.
pub const SOURCE_FORMS: &str = "dir:PATH, v4l2:LEFT,RIGHT[,WxH], v4l2-sbs:DEV[,WxH], \
     v4l2-16:DEV[,WxH][,left-first|right-first] or dc1394[:GUID][,left-first|right-first] \
     (DEV is /dev/videoN or N)";

/// Where frames come from.
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub enum SourceSpec {
    /// A recorded dataset folder.
    Recorded(PathBuf),
    /// Two V4L2 nodes, one per camera, paired by timestamp.
    V4l2Pair {
        /// The left camera's node.
        left: PathBuf,
        /// The right camera's node.
        right: PathBuf,
        /// Frame size to ask both for; their current one when `None`.
        size: Option<(u32, u32)>,
    },
    /// One V4L2 node whose frames hold the left image beside the right one.
    V4l2SideBySide {
        /// The node.
        device: PathBuf,
        /// Whole frame size (both halves) to ask for; the current one when `None`.
        size: Option<(u32, u32)>,
    },
    /// One V4L2 node of 16-bit pixels, one byte per camera.
    V4l2Interleaved {
        /// The node.
        device: PathBuf,
        /// Frame size to ask for; the current one when `None`.
        size: Option<(u32, u32)>,
        /// Which byte is the left camera.
        order: InterleavedOrder,
    },
    /// A FireWire IIDC stereo camera (Bumblebee2); the first one found when `guid` is None.
    Dc1394 {
        /// The camera's 64-bit GUID.
        guid: Option<u64>,
        /// Which byte is the left camera.
        order: InterleavedOrder,
    },
}

/// Parses a source specification; the error lists the accepted forms.
pub fn parse_source(spec: &str) -> Result<SourceSpec> {
    let bad = |why: &str| Error::new(ErrorKind::Spec, format!("source `{spec}`: {why}; expected {SOURCE_FORMS}"));
    let (scheme, rest) = match spec.split_once(':') {
        Some((s, r)) => (s, Some(r)),
        None => (spec, None),
    };
    match (scheme, rest) {
        ("dir", Some(path)) if !path.is_empty() => Ok(SourceSpec::Recorded(PathBuf::from(path))),
        ("v4l2", Some(rest)) => {
            let mut parts = rest.split(',');
            let (Some(left), Some(right)) = (parts.next(), parts.next()) else {
                return Err(bad("expected two devices"));
            };
            let opts = options(parts, false).map_err(|w| bad(&w))?;
            Ok(SourceSpec::V4l2Pair {
                left: device(left).map_err(|w| bad(&w))?,
                right: device(right).map_err(|w| bad(&w))?,
                size: opts.0,
            })
        }
        ("v4l2-sbs", Some(rest)) => {
            let mut parts = rest.split(',');
            let dev = device(parts.next().unwrap_or("")).map_err(|w| bad(&w))?;
            let opts = options(parts, false).map_err(|w| bad(&w))?;
            Ok(SourceSpec::V4l2SideBySide { device: dev, size: opts.0 })
        }
        ("v4l2-16", Some(rest)) => {
            let mut parts = rest.split(',');
            let dev = device(parts.next().unwrap_or("")).map_err(|w| bad(&w))?;
            let (size, order) = options(parts, true).map_err(|w| bad(&w))?;
            Ok(SourceSpec::V4l2Interleaved { device: dev, size, order: order.unwrap_or_default() })
        }
        ("dc1394", rest) => {
            let mut parts = rest.unwrap_or("").split(',');
            let guid = match parts.next().unwrap_or("") {
                "" => None,
                g => {
                    let hex = g.strip_prefix("0x").or_else(|| g.strip_prefix("0X")).unwrap_or(g);
                    Some(
                        u64::from_str_radix(hex, 16)
                            .map_err(|_| bad(&format!("GUID `{g}` is not a hexadecimal number")))?,
                    )
                }
            };
            let (size, order) = options(parts, true).map_err(|w| bad(&w))?;
            if size.is_some() {
                return Err(bad("the FireWire camera's size comes from its Format7 mode, not the spec"));
            }
            Ok(SourceSpec::Dc1394 { guid, order: order.unwrap_or_default() })
        }
        _ => Err(bad("unknown form")),
    }
}

/// `/dev/videoN` from `N`, or the path as given.
fn device(s: &str) -> std::result::Result<PathBuf, String> {
    if s.is_empty() {
        return Err("expected a device".into());
    }
    if s.bytes().all(|b| b.is_ascii_digit()) {
        return Ok(PathBuf::from(format!("/dev/video{s}")));
    }
    Ok(PathBuf::from(s))
}

type Options = (Option<(u32, u32)>, Option<InterleavedOrder>);

/// The optional `WxH` and byte-order words after the devices.
fn options<'a>(parts: impl Iterator<Item = &'a str>, order_allowed: bool) -> std::result::Result<Options, String> {
    let (mut size, mut order) = (None, None);
    for p in parts {
        match p {
            "left-first" if order_allowed => order = Some(InterleavedOrder::LeftFirst),
            "right-first" if order_allowed => order = Some(InterleavedOrder::RightFirst),
            _ => {
                let parsed =
                    p.split_once('x').and_then(|(w, h)| Some((w.parse::<u32>().ok()?, h.parse::<u32>().ok()?)));
                match parsed {
                    Some((w, h)) if w > 0 && h > 0 => size = Some((w, h)),
                    _ => return Err(format!("`{p}` is neither a size WxH nor a known option")),
                }
            }
        }
    }
    Ok((size, order))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_form_parses() {
        assert_eq!(parse_source("dir:data/run 1").unwrap(), SourceSpec::Recorded("data/run 1".into()));
        assert_eq!(
            parse_source("v4l2:/dev/video2,3").unwrap(),
            SourceSpec::V4l2Pair { left: "/dev/video2".into(), right: "/dev/video3".into(), size: None }
        );
        assert_eq!(
            parse_source("v4l2:0,1,1280x720").unwrap(),
            SourceSpec::V4l2Pair { left: "/dev/video0".into(), right: "/dev/video1".into(), size: Some((1280, 720)) }
        );
        assert_eq!(
            parse_source("v4l2-sbs:4").unwrap(),
            SourceSpec::V4l2SideBySide { device: "/dev/video4".into(), size: None }
        );
        assert_eq!(
            parse_source("v4l2-16:/dev/v4l/by-id/cam,left-first,640x480").unwrap(),
            SourceSpec::V4l2Interleaved {
                device: "/dev/v4l/by-id/cam".into(),
                size: Some((640, 480)),
                order: InterleavedOrder::LeftFirst
            }
        );
        assert_eq!(
            parse_source("dc1394").unwrap(),
            SourceSpec::Dc1394 { guid: None, order: InterleavedOrder::RightFirst }
        );
        assert_eq!(
            parse_source("dc1394:0x00b09d01006fb38f").unwrap(),
            SourceSpec::Dc1394 { guid: Some(0x00b0_9d01_006f_b38f), order: InterleavedOrder::RightFirst }
        );
        assert_eq!(
            parse_source("dc1394:,left-first").unwrap(),
            SourceSpec::Dc1394 { guid: None, order: InterleavedOrder::LeftFirst }
        );
    }

    #[test]
    fn bad_specs_say_what_is_accepted() {
        for bad in [
            "",
            "dir:",
            "v4l2:/dev/video0",
            "v4l2-sbs:",
            "v4l2:0,1,left-first",
            "v4l2-16:0,12x",
            "dc1394:xyz",
            "usb:1",
            "video0",
        ] {
            let e = parse_source(bad).unwrap_err();
            assert_eq!(e.kind(), ErrorKind::Spec, "{bad}");
            assert!(e.to_string().contains("v4l2-sbs:DEV"), "{bad}: {e}");
            assert!(e.to_string().contains(&format!("`{bad}`")), "{bad}: {e}");
        }
    }
}
