//! FireWire IIDC stereo cameras (the Bumblebee2) through libdc1394 (feature `dc1394`): a
//! small hand-written FFI covering what capture needs. The camera is put in Format7 mode 3
//! with 16-bit pixels, whose two bytes are the two sensors, in Point Grey's little-endian
//! order (right sensor first); `pixels::deinterleave16` splits them. Colour models send Bayer mosaics: their raw values are taken as grey.

use std::ffi::{c_char, c_int, c_void, CStr};
use std::ptr;

use camplace_config::GrayImage;

use crate::device_list::FirewireDevice;
use crate::frames::{frame_name, FrameInfo, FrameSource, Frames};
use crate::pixels::{self, InterleavedOrder};
use crate::{Error, Result};

/// Mirrors of the libdc1394-2 declarations used here (dc1394/*.h); only the leading fields
/// of the structs are read, so only those need to match.
mod ffi {
    use std::ffi::{c_char, c_int, c_void};

    pub const SUCCESS: c_int = 0;
    pub const VIDEO_MODE_FORMAT7_3: c_int = 91;
    pub const COLOR_CODING_MONO16: c_int = 357;
    pub const COLOR_CODING_RAW16: c_int = 362;
    pub const ISO_SPEED_400: c_int = 2;
    pub const CAPTURE_FLAGS_DEFAULT: u32 = 0x4;
    pub const CAPTURE_POLICY_WAIT: c_int = 672;
    pub const USE_MAX_AVAIL: i32 = -2;
    pub const ON: c_int = 1;
    /// Point Grey's image data format register and its value for little-endian 16-bit
    /// pixels, in which the right sensor's byte comes first.
    pub const PGR_IMAGE_DATA_FORMAT: u64 = 0x1048;
    pub const PGR_LITTLE_ENDIAN: u32 = 0x8000_0000;
    pub const OFF: c_int = 0;

    #[repr(C)]
    pub struct CameraId {
        pub unit: u16,
        pub guid: u64,
    }

    #[repr(C)]
    pub struct CameraList {
        pub num: u32,
        pub ids: *mut CameraId,
    }

    /// `dc1394camera_t` up to `model`.
    #[repr(C)]
    pub struct Camera {
        pub guid: u64,
        pub unit: c_int,
        pub unit_spec_id: u32,
        pub unit_sw_version: u32,
        pub unit_sub_sw_version: u32,
        pub command_registers_base: u32,
        pub unit_directory: u32,
        pub unit_dependent_directory: u32,
        pub advanced_features_csr: u64,
        pub pio_control_csr: u64,
        pub sio_control_csr: u64,
        pub strobe_control_csr: u64,
        pub format7_csr: [u64; 8],
        pub iidc_version: c_int,
        pub vendor: *const c_char,
        pub model: *const c_char,
    }

    /// `dc1394video_frame_t` up to `timestamp`.
    #[repr(C)]
    pub struct VideoFrame {
        pub image: *mut u8,
        pub size: [u32; 2],
        pub position: [u32; 2],
        pub color_coding: c_int,
        pub color_filter: c_int,
        pub yuv_byte_order: u32,
        pub data_depth: u32,
        pub stride: u32,
        pub video_mode: c_int,
        pub total_bytes: u64,
        pub image_bytes: u32,
        pub padding_bytes: u32,
        pub packet_size: u32,
        pub packets_per_frame: u32,
        pub timestamp: u64,
    }

    #[link(name = "dc1394")]
    unsafe extern "C" {
        pub fn dc1394_new() -> *mut c_void;
        pub fn dc1394_free(d: *mut c_void);
        pub fn dc1394_camera_enumerate(d: *mut c_void, list: *mut *mut CameraList) -> c_int;
        pub fn dc1394_camera_free_list(list: *mut CameraList);
        pub fn dc1394_camera_new(d: *mut c_void, guid: u64) -> *mut Camera;
        pub fn dc1394_camera_free(camera: *mut Camera);
        pub fn dc1394_set_control_registers(camera: *mut Camera, offset: u64, value: *const u32, n: u32) -> c_int;
        pub fn dc1394_video_set_iso_speed(camera: *mut Camera, speed: c_int) -> c_int;
        pub fn dc1394_video_set_mode(camera: *mut Camera, mode: c_int) -> c_int;
        pub fn dc1394_format7_get_max_image_size(camera: *mut Camera, mode: c_int, w: *mut u32, h: *mut u32) -> c_int;
        pub fn dc1394_format7_set_roi(
            camera: *mut Camera,
            mode: c_int,
            coding: c_int,
            packet_size: i32,
            left: i32,
            top: i32,
            width: i32,
            height: i32,
        ) -> c_int;
        pub fn dc1394_capture_setup(camera: *mut Camera, buffers: u32, flags: u32) -> c_int;
        pub fn dc1394_capture_stop(camera: *mut Camera) -> c_int;
        pub fn dc1394_video_set_transmission(camera: *mut Camera, on: c_int) -> c_int;
        pub fn dc1394_capture_dequeue(camera: *mut Camera, policy: c_int, frame: *mut *mut VideoFrame) -> c_int;
        pub fn dc1394_capture_enqueue(camera: *mut Camera, frame: *mut VideoFrame) -> c_int;
        pub fn dc1394_error_get_string(err: c_int) -> *const c_char;
    }
}

/// DMA buffers libdc1394 cycles through.
const BUFFERS: u32 = 4;

/// The library handle; freed on drop.
struct Library(*mut c_void);

impl Library {
    fn new() -> Result<Library> {
        // SAFETY: dc1394_new takes no arguments and returns null on failure.
        let d = unsafe { ffi::dc1394_new() };
        if d.is_null() {
            return Err(Error::device(
                "libdc1394",
                "could not start (is the FireWire stack loaded and /dev/fw* readable?)",
            ));
        }
        Ok(Library(d))
    }
}

impl Drop for Library {
    fn drop(&mut self) {
        // SAFETY: self.0 came from dc1394_new and is freed once.
        unsafe { ffi::dc1394_free(self.0) }
    }
}

fn check(code: c_int, what: &str) -> Result<()> {
    if code == ffi::SUCCESS {
        return Ok(());
    }
    // SAFETY: dc1394_error_get_string returns a static string for every code.
    let text = unsafe {
        let s = ffi::dc1394_error_get_string(code);
        if s.is_null() {
            String::from("unknown error")
        } else {
            CStr::from_ptr(s).to_string_lossy().into_owned()
        }
    };
    Err(Error::device("FireWire camera", format!("{what} failed: {text}")))
}

fn guids(lib: &Library) -> Result<Vec<u64>> {
    let mut list: *mut ffi::CameraList = ptr::null_mut();
    // SAFETY: the library handle is live; the list is freed below.
    check(unsafe { ffi::dc1394_camera_enumerate(lib.0, &mut list) }, "listing cameras")?;
    if list.is_null() {
        return Ok(Vec::new());
    }
    // SAFETY: a successful enumerate gives `num` ids.
    let ids = unsafe {
        let l = &*list;
        let ids =
            if l.ids.is_null() { Vec::new() } else { (0..l.num as usize).map(|i| (*l.ids.add(i)).guid).collect() };
        ffi::dc1394_camera_free_list(list);
        ids
    };
    Ok(ids)
}

fn c_string(p: *const c_char) -> String {
    if p.is_null() {
        return String::new();
    }
    // SAFETY: libdc1394 keeps vendor and model as NUL-terminated strings of the camera.
    unsafe { CStr::from_ptr(p).to_string_lossy().into_owned() }
}

/// The FireWire cameras on the bus.
pub fn enumerate() -> Result<Vec<FirewireDevice>> {
    let lib = Library::new()?;
    let mut out = Vec::new();
    for guid in guids(&lib)? {
        // SAFETY: the library handle is live; the camera is freed right after reading.
        unsafe {
            let cam = ffi::dc1394_camera_new(lib.0, guid);
            if cam.is_null() {
                continue;
            }
            out.push(FirewireDevice { guid, vendor: c_string((*cam).vendor), model: c_string((*cam).model) });
            ffi::dc1394_camera_free(cam);
        }
    }
    Ok(out)
}

/// A Bumblebee2-style FireWire stereo camera as a `FrameSource` of one shot per frame.
pub struct Dc1394Source {
    // Field order matters: the camera must be freed before the library.
    camera: *mut ffi::Camera,
    _lib: Library,
    guid: u64,
    order: InterleavedOrder,
    index: u64,
}

// SAFETY: the camera handle is owned by this value alone and used from one thread at a time.
unsafe impl Send for Dc1394Source {}

impl Dc1394Source {
    /// Opens the camera `guid` (or the first one found), sets Format7 mode 3 with 16-bit
    /// pixels at its largest size and starts transmission.
    pub fn open(guid: Option<u64>, order: InterleavedOrder) -> Result<Dc1394Source> {
        let lib = Library::new()?;
        let found = guids(&lib)?;
        let guid = match guid {
            Some(g) if found.contains(&g) => g,
            Some(g) => {
                return Err(Error::device(
                    format!("dc1394:{g:016x}"),
                    format!("no such camera on the bus (found {})", list_guids(&found)),
                ))
            }
            None => *found.first().ok_or_else(|| {
                Error::device("dc1394", "no FireWire camera found; expected a Bumblebee2 (see `camplace devices`)")
            })?,
        };
        // SAFETY: the library handle is live.
        let camera = unsafe { ffi::dc1394_camera_new(lib.0, guid) };
        if camera.is_null() {
            return Err(Error::device(format!("dc1394:{guid:016x}"), "could not be opened"));
        }
        let source = Dc1394Source { camera, _lib: lib, guid, order, index: 0 };
        source.start().map_err(|e| Error::device(format!("dc1394:{guid:016x}"), e.message()))?;
        Ok(source)
    }

    fn start(&self) -> Result<()> {
        let mode = ffi::VIDEO_MODE_FORMAT7_3;
        let (mut w, mut h) = (0u32, 0u32);
        // SAFETY: the camera handle is live; the out-pointers are local.
        unsafe {
            // Fix the byte order of the 16-bit pixels so `order` means the same on every
            // camera, whatever its memory channel says. Not a Point Grey camera: keep its own.
            let value = ffi::PGR_LITTLE_ENDIAN;
            let _ = ffi::dc1394_set_control_registers(self.camera, ffi::PGR_IMAGE_DATA_FORMAT, &value, 1);
            check(ffi::dc1394_video_set_iso_speed(self.camera, ffi::ISO_SPEED_400), "setting 400 Mb/s")?;
            check(ffi::dc1394_video_set_mode(self.camera, mode), "setting Format7 mode 3")?;
            check(ffi::dc1394_format7_get_max_image_size(self.camera, mode, &mut w, &mut h), "reading the image size")?;
            // Grey models take MONO16, colour models RAW16; try both.
            let roi = |coding| {
                ffi::dc1394_format7_set_roi(self.camera, mode, coding, ffi::USE_MAX_AVAIL, 0, 0, w as i32, h as i32)
            };
            if roi(ffi::COLOR_CODING_MONO16) != ffi::SUCCESS {
                check(roi(ffi::COLOR_CODING_RAW16), "setting 16-bit stereo pixels")?;
            }
            check(ffi::dc1394_capture_setup(self.camera, BUFFERS, ffi::CAPTURE_FLAGS_DEFAULT), "capture setup")?;
            check(ffi::dc1394_video_set_transmission(self.camera, ffi::ON), "starting transmission")?;
        }
        Ok(())
    }
}

impl FrameSource for Dc1394Source {
    fn next(&mut self, frames: &mut Frames) -> Result<Option<FrameInfo>> {
        frames.set_shots(1);
        let mut frame: *mut ffi::VideoFrame = ptr::null_mut();
        let device = || format!("dc1394:{:016x}", self.guid);
        // SAFETY: the camera is capturing; the frame is handed back with enqueue below.
        check(unsafe { ffi::dc1394_capture_dequeue(self.camera, ffi::CAPTURE_POLICY_WAIT, &mut frame) }, "capture")
            .map_err(|e| Error::device(device(), e.message()))?;
        if frame.is_null() {
            return Err(Error::device(device(), "capture gave no frame"));
        }
        // SAFETY: a successful dequeue gives a frame that libdc1394 neither frees nor
        // writes until it is enqueued again below, with `image` null or pointing to the
        // `image_bytes` bytes the driver filled, as `split_frame` needs.
        let result = unsafe {
            let f = &*frame;
            (split_frame(f, self.order, &mut frames.left[0], &mut frames.right[0]), f.timestamp)
        };
        // SAFETY: the frame came from dequeue on this camera.
        let enqueued = unsafe { ffi::dc1394_capture_enqueue(self.camera, frame) };
        let (converted, timestamp_us) = result;
        converted.map_err(|e| Error::device(device(), e))?;
        check(enqueued, "returning the frame buffer").map_err(|e| Error::device(device(), e.message()))?;
        let index = self.index;
        self.index += 1;
        Ok(Some(FrameInfo { index, name: frame_name(index), timestamp_us }))
    }

    fn shots(&self) -> usize {
        1
    }
}

impl Drop for Dc1394Source {
    fn drop(&mut self) {
        // SAFETY: the camera handle is live and freed once, before the library.
        unsafe {
            ffi::dc1394_video_set_transmission(self.camera, ffi::OFF);
            ffi::dc1394_capture_stop(self.camera);
            ffi::dc1394_camera_free(self.camera);
        }
    }
}

/// Splits the 16-bit stereo pixels of frame `f` into `left` and `right`, reading exactly
/// the `image_bytes` the driver says it filled: a frame whose rows do not fit in them is
/// refused with an error by `pixels::deinterleave16`'s size check, never read past its end.
/// A null image reads as no bytes.
///
/// # Safety
///
/// `f.image` is null or points to `f.image_bytes` bytes that stay readable and unchanged
/// during the call, as a dequeued frame's do until it is enqueued again.
unsafe fn split_frame(
    f: &ffi::VideoFrame,
    order: InterleavedOrder,
    left: &mut GrayImage,
    right: &mut GrayImage,
) -> Result<()> {
    let (w, h) = (f.size[0] as usize, f.size[1] as usize);
    let stride = if f.stride == 0 { 2 * w } else { f.stride as usize };
    let bytes: &[u8] = if f.image.is_null() {
        &[]
    } else {
        // SAFETY: the caller vouches for `image_bytes` readable, unchanging bytes at `image`,
        // which as one buffer hold at most isize::MAX bytes.
        unsafe { std::slice::from_raw_parts(f.image, f.image_bytes as usize) }
    };
    pixels::deinterleave16(bytes, w, h, stride, order, left, right)
}

fn list_guids(found: &[u64]) -> String {
    if found.is_empty() {
        return "none".into();
    }
    found.iter().map(|g| format!("{g:016x}")).collect::<Vec<_>>().join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A frame as libdc1394 hands it over: `width` x `height` pixels `stride` bytes apart
    /// (0: packed), of which the driver says it filled `image_bytes` of `buffer`.
    fn frame(buffer: &mut [u8], width: u32, height: u32, stride: u32, image_bytes: u32) -> ffi::VideoFrame {
        assert!(image_bytes as usize <= buffer.len(), "the test's buffer holds what the driver filled");
        ffi::VideoFrame {
            image: buffer.as_mut_ptr(),
            size: [width, height],
            position: [0, 0],
            color_coding: ffi::COLOR_CODING_MONO16,
            color_filter: 0,
            yuv_byte_order: 0,
            data_depth: 16,
            stride,
            video_mode: ffi::VIDEO_MODE_FORMAT7_3,
            total_bytes: buffer.len() as u64,
            image_bytes,
            padding_bytes: 0,
            packet_size: 0,
            packets_per_frame: 0,
            timestamp: 0,
        }
    }

    /// `split_frame` of a frame, on fresh images.
    fn split(f: &ffi::VideoFrame) -> Result<(GrayImage, GrayImage)> {
        let (mut left, mut right) = (GrayImage::default(), GrayImage::default());
        // SAFETY: every frame here points into a live buffer of at least `image_bytes`.
        unsafe { split_frame(f, InterleavedOrder::RightFirst, &mut left, &mut right) }?;
        Ok((left, right))
    }

    #[test]
    fn frames_are_read_within_the_bytes_the_driver_filled() {
        // 4 x 3 pixels of 2 bytes at a stride of 10: the last row ends at 2 x 10 + 8 = 28.
        let mut buffer: Vec<u8> = (0..40).collect();
        let (left, right) = split(&frame(&mut buffer, 4, 3, 10, 28)).unwrap();
        // Right sensor first: byte 0 of each pixel is the right camera's.
        assert_eq!(left.data, [1, 3, 5, 7, 11, 13, 15, 17, 21, 23, 25, 27]);
        assert_eq!(right.data, [0, 2, 4, 6, 10, 12, 14, 16, 20, 22, 24, 26]);
        for short in [27, 20, 1, 0] {
            let e = split(&frame(&mut buffer, 4, 3, 10, short)).unwrap_err();
            assert!(e.to_string().contains(&format!("camera buffer holds {short} bytes, expected at least 28")), "{e}");
        }
    }

    #[test]
    fn packed_null_and_oversized_frames() {
        let mut buffer: Vec<u8> = (0..24).collect();
        // Stride 0 is packed rows.
        let (left, _) = split(&frame(&mut buffer, 4, 3, 0, 24)).unwrap();
        assert_eq!(left.data, [1, 3, 5, 7, 9, 11, 13, 15, 17, 19, 21, 23]);
        assert!(split(&frame(&mut buffer, 4, 3, 0, 23)).is_err());
        // No image is no bytes: only an empty frame fits.
        let mut f = frame(&mut buffer, 4, 3, 0, 24);
        f.image = ptr::null_mut();
        assert!(split(&f).is_err());
        f.size = [0, 0];
        assert!(split(&f).is_ok());
        // Sizes far beyond the bytes the driver filled are refused, not overflowed.
        for (w, h, stride) in [(u32::MAX, u32::MAX, 0), (4, u32::MAX, u32::MAX), (u32::MAX, 1, 0)] {
            assert!(split(&frame(&mut buffer, w, h, stride, 24)).is_err(), "{w}x{h} at {stride}");
        }
    }
}
