//! Video4Linux2 cameras as a frame source (feature `v4l`): two nodes paired by timestamp,
//! one side-by-side node, or one node of 16-bit pixels carrying a byte per camera. Each
//! buffer is converted to grey straight into the caller's frame (see `pixels`).
//!
//! The v4l crate's memory-mapped stream panics when the driver refuses to stop streaming
//! on drop (for any reason but an unplugged device); nothing here can catch that.

use std::path::{Path, PathBuf};
use std::time::Duration;

use camplace_config::GrayImage;
use v4l::buffer::Type;
use v4l::io::mmap::Stream;
use v4l::io::traits::CaptureStream;
use v4l::video::Capture;
use v4l::{Device, Format, FourCC};

use crate::frames::{frame_name, FrameInfo, FrameSource, Frames};
use crate::pixels::{self, InterleavedOrder, PixelFormat};
use crate::spec::SourceSpec;
use crate::{Error, ErrorKind, Result};

/// Buffers the driver cycles through per node.
const BUFFERS: u32 = 4;
/// How long to wait for a frame before calling the camera dead.
const FRAME_TIMEOUT: Duration = Duration::from_secs(2);
/// Most frames dropped while looking for a left/right pair with close timestamps.
const MAX_PAIRING_DROPS: usize = 8;
/// Two frames of a pair are taken as simultaneous within this many microseconds (a bit
/// under half a 30 Hz frame period), so a pair never spans two exposures.
pub const PAIR_TOLERANCE_US: u64 = 15_000;

/// How the two cameras' images reach us.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Layout {
    Pair,
    SideBySide,
    Interleaved(InterleavedOrder),
}

/// What one node delivers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Carrier {
    Pixels(PixelFormat),
    /// Two bytes per pixel, one per camera (V4L2 `Y16 `, or YUYV abused by stereo cameras).
    Interleaved16,
}

struct Node {
    path: PathBuf,
    stream: Stream<'static>,
    carrier: Carrier,
    width: usize,
    height: usize,
    stride: usize,
}

/// V4L2 cameras as a `FrameSource` of one shot per frame.
pub struct V4l2Source {
    layout: Layout,
    nodes: Vec<Node>,
    /// The whole side-by-side frame before it is split.
    full: GrayImage,
    jpeg_scratch: Vec<u8>,
    index: u64,
}

impl V4l2Source {
    /// Opens the V4L2 source of `spec` (a `V4l2*` variant); errors name the device and
    /// what was expected of it.
    pub fn open(spec: &SourceSpec) -> Result<V4l2Source> {
        let (layout, nodes) = match spec {
            SourceSpec::V4l2Pair { left, right, size } => {
                (Layout::Pair, vec![open_node(left, *size, false)?, open_node(right, *size, false)?])
            }
            SourceSpec::V4l2SideBySide { device, size } => (Layout::SideBySide, vec![open_node(device, *size, false)?]),
            SourceSpec::V4l2Interleaved { device, size, order } => {
                (Layout::Interleaved(*order), vec![open_node(device, *size, true)?])
            }
            other => return Err(Error::new(ErrorKind::Spec, format!("{other:?} is not a V4L2 source"))),
        };
        if layout == Layout::Pair && (nodes[0].width, nodes[0].height) != (nodes[1].width, nodes[1].height) {
            return Err(Error::device(
                nodes[1].path.display(),
                format!(
                    "delivers {}x{} but {} delivers {}x{}; expected both cameras at one size",
                    nodes[1].width,
                    nodes[1].height,
                    nodes[0].path.display(),
                    nodes[0].width,
                    nodes[0].height
                ),
            ));
        }
        Ok(V4l2Source { layout, nodes, full: GrayImage::default(), jpeg_scratch: Vec::new(), index: 0 })
    }
}

impl FrameSource for V4l2Source {
    fn next(&mut self, frames: &mut Frames) -> Result<Option<FrameInfo>> {
        frames.set_shots(1);
        let timestamp_us = match self.layout {
            Layout::Pair => {
                let (left, right) = (&mut frames.left[0], &mut frames.right[0]);
                let [a, b] = &mut self.nodes[..] else { unreachable!("a pair has two nodes") };
                let mut ta = read_gray(a, left, &mut self.jpeg_scratch)?;
                let mut tb = read_gray(b, right, &mut self.jpeg_scratch)?;
                let mut drops = 0;
                // The cameras run free: drop the older frame until both come from one moment.
                while ta.abs_diff(tb) > PAIR_TOLERANCE_US {
                    drops += 1;
                    if drops > MAX_PAIRING_DROPS {
                        return Err(Error::device(
                            b.path.display(),
                            format!(
                                "no frame within {} ms of {} after {MAX_PAIRING_DROPS} tries; expected two cameras at one frame rate",
                                PAIR_TOLERANCE_US / 1000,
                                a.path.display()
                            ),
                        ));
                    }
                    if ta < tb {
                        ta = read_gray(a, left, &mut self.jpeg_scratch)?;
                    } else {
                        tb = read_gray(b, right, &mut self.jpeg_scratch)?;
                    }
                }
                ta.min(tb)
            }
            Layout::SideBySide => {
                let t = read_gray(&mut self.nodes[0], &mut self.full, &mut self.jpeg_scratch)?;
                pixels::split_side_by_side(&self.full, &mut frames.left[0], &mut frames.right[0])
                    .map_err(|e| Error::device(self.nodes[0].path.display(), e))?;
                t
            }
            Layout::Interleaved(order) => {
                let n = &mut self.nodes[0];
                let (bytes, meta) = dequeue(&mut n.stream, &n.path)?;
                pixels::deinterleave16(
                    bytes,
                    n.width,
                    n.height,
                    n.stride,
                    order,
                    &mut frames.left[0],
                    &mut frames.right[0],
                )
                .map_err(|e| Error::device(n.path.display(), e))?;
                micros(meta)
            }
        };
        let index = self.index;
        self.index += 1;
        Ok(Some(FrameInfo { index, name: frame_name(index), timestamp_us }))
    }

    fn shots(&self) -> usize {
        1
    }
}

/// The capture formats of the node at `path`, as `FOURCC WxH` (or a size range).
pub fn describe_formats(path: &Path) -> Result<Vec<String>> {
    let dev = Device::with_path(path).map_err(|e| open_error(path, &e))?;
    let formats = dev.enum_formats().map_err(|e| Error::device(path.display(), format!("cannot list formats: {e}")))?;
    let mut out = Vec::new();
    for f in formats {
        let sizes = dev.enum_framesizes(f.fourcc).unwrap_or_default();
        if sizes.is_empty() {
            out.push(f.fourcc.to_string());
        }
        for s in sizes {
            match s.size {
                v4l::framesize::FrameSizeEnum::Discrete(d) => {
                    out.push(format!("{} {}x{}", f.fourcc, d.width, d.height))
                }
                v4l::framesize::FrameSizeEnum::Stepwise(s) => {
                    out.push(format!("{} {}x{}..{}x{}", f.fourcc, s.min_width, s.min_height, s.max_width, s.max_height))
                }
            }
        }
    }
    Ok(out)
}

/// Opens one node, picks the best format it offers and starts nothing yet.
fn open_node(path: &Path, size: Option<(u32, u32)>, interleaved: bool) -> Result<Node> {
    let dev = Device::with_path(path).map_err(|e| open_error(path, &e))?;
    let offered: Vec<FourCC> = dev
        .enum_formats()
        .map_err(|e| {
            Error::device(path.display(), format!("cannot list formats ({e}); expected a V4L2 capture device"))
        })?
        .into_iter()
        .map(|d| d.fourcc)
        .collect();
    // Grey first (no conversion), compressed last (costly and lossy).
    let preferred: &[(&[u8; 4], Carrier)] = if interleaved {
        &[(b"Y16 ", Carrier::Interleaved16), (b"YUYV", Carrier::Interleaved16), (b"UYVY", Carrier::Interleaved16)]
    } else {
        &[
            (b"GREY", Carrier::Pixels(PixelFormat::Gray8)),
            (b"Y800", Carrier::Pixels(PixelFormat::Gray8)),
            (b"YUYV", Carrier::Pixels(PixelFormat::Yuyv)),
            (b"UYVY", Carrier::Pixels(PixelFormat::Uyvy)),
            (b"RGB3", Carrier::Pixels(PixelFormat::Rgb24)),
            (b"BGR3", Carrier::Pixels(PixelFormat::Bgr24)),
            (b"MJPG", Carrier::Pixels(PixelFormat::Mjpeg)),
        ]
    };
    let Some(&(code, carrier)) = preferred.iter().find(|(c, _)| offered.contains(&FourCC::new(c))) else {
        let names: Vec<String> = offered.iter().map(|f| f.to_string()).collect();
        let wanted: Vec<&str> = preferred.iter().map(|(c, _)| std::str::from_utf8(&c[..]).unwrap_or("?")).collect();
        return Err(Error::device(
            path.display(),
            format!("offers formats [{}], expected one of [{}]", names.join(", "), wanted.join(", ")),
        ));
    };
    let current = dev.format().map_err(|e| Error::device(path.display(), format!("cannot read its format: {e}")))?;
    let (w, h) = size.unwrap_or((current.width, current.height));
    let want = Format::new(w, h, FourCC::new(code));
    let got =
        dev.set_format(&want).map_err(|e| Error::device(path.display(), format!("refused format {want}: {e}")))?;
    if (got.width, got.height) != (w, h) || got.fourcc != want.fourcc {
        return Err(Error::device(
            path.display(),
            format!("set to {} {}x{}, expected {} {w}x{h}", got.fourcc, got.width, got.height, want.fourcc),
        ));
    }
    let mut stream = Stream::with_buffers(&dev, Type::VideoCapture, BUFFERS)
        .map_err(|e| Error::device(path.display(), format!("cannot map capture buffers: {e}")))?;
    stream.set_timeout(FRAME_TIMEOUT);
    Ok(Node {
        path: path.to_path_buf(),
        stream,
        carrier,
        width: got.width as usize,
        height: got.height as usize,
        stride: got.stride as usize,
    })
}

fn open_error(path: &Path, e: &std::io::Error) -> Error {
    let why = match e.kind() {
        std::io::ErrorKind::NotFound => "no such device".to_string(),
        std::io::ErrorKind::PermissionDenied => "permission denied (is the user in the `video` group?)".to_string(),
        _ => e.to_string(),
    };
    Error::device(path.display(), format!("{why}; expected a V4L2 capture device (list them with `camplace devices`)"))
}

/// The next buffer of the stream of node `path`, and its metadata.
fn dequeue<'a>(stream: &'a mut Stream<'static>, path: &Path) -> Result<(&'a [u8], &'a v4l::buffer::Metadata)> {
    let (bytes, meta) = CaptureStream::next(stream).map_err(|e| {
        let why = if e.kind() == std::io::ErrorKind::TimedOut {
            format!("no frame within {} s", FRAME_TIMEOUT.as_secs())
        } else {
            format!("capture failed: {e}")
        };
        Error::device(path.display(), why)
    })?;
    // Compressed buffers are only `bytesused` long; the rest is stale.
    let used = (meta.bytesused as usize).min(bytes.len());
    let used = if used == 0 { bytes.len() } else { used };
    Ok((&bytes[..used], meta))
}

/// The next frame of `node` as grey in `out`; returns its timestamp in microseconds.
fn read_gray(node: &mut Node, out: &mut GrayImage, jpeg_scratch: &mut Vec<u8>) -> Result<u64> {
    let (width, height, stride, carrier) = (node.width, node.height, node.stride, node.carrier);
    let Carrier::Pixels(format) = carrier else {
        return Err(Error::device(node.path.display(), "16-bit interleaved pixels are not one camera's image"));
    };
    let (bytes, meta) = dequeue(&mut node.stream, &node.path)?;
    let t = micros(meta);
    pixels::to_gray(format, bytes, width, height, stride, out, jpeg_scratch)
        .map_err(|e| Error::device(node.path.display(), e))?;
    Ok(t)
}

fn micros(meta: &v4l::buffer::Metadata) -> u64 {
    (meta.timestamp.sec as u64).saturating_mul(1_000_000).saturating_add(meta.timestamp.usec as u64)
}
