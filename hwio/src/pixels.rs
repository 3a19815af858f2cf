//! Camera pixel formats to 8-bit grey: YUYV, GREY, RGB24/BGR24, 16-bit pixel-interleaved
//! stereo, side-by-side stereo and (with the `mjpeg` feature) Motion-JPEG. Pure functions
//! into caller-owned images; none allocates when the image size is unchanged.
//!
//! `stride` is the bytes from one row's start to the next (V4L2's `bytesperline`), at
//! least the packed row length; 0 means packed.

use camplace_config::GrayImage;

use crate::{Error, ErrorKind, Result};

/// Which byte of a 16-bit interleaved pixel belongs to the left camera.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum InterleavedOrder {
    /// Byte 0 of each pixel is the left camera, byte 1 the right.
    LeftFirst,
    /// Byte 0 of each pixel is the right camera, byte 1 the left. The Bumblebee2 in its
    /// 16-bit Format7 mode with Point Grey's default little-endian pixels (which the
    /// `dc1394` source sets) sends the right sensor first, so this is the default.
    #[default]
    RightFirst,
}

/// A camera buffer's pixel layout.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PixelFormat {
    /// 8-bit grey (V4L2 `GREY`, `Y8`, IIDC MONO8).
    Gray8,
    /// 4:2:2 YUYV (V4L2 `YUYV`): the Y bytes are the grey image.
    Yuyv,
    /// 4:2:2 UYVY (V4L2 `UYVY`, IIDC YUV422).
    Uyvy,
    /// 8-bit R, G, B.
    Rgb24,
    /// 8-bit B, G, R.
    Bgr24,
    /// Motion-JPEG, one JPEG per buffer.
    Mjpeg,
}

impl PixelFormat {
    /// Bytes per pixel of a packed row (0 for compressed formats).
    pub fn bytes_per_pixel(self) -> usize {
        match self {
            PixelFormat::Gray8 => 1,
            PixelFormat::Yuyv | PixelFormat::Uyvy => 2,
            PixelFormat::Rgb24 | PixelFormat::Bgr24 => 3,
            PixelFormat::Mjpeg => 0,
        }
    }
}

/// Converts one camera buffer of `format` to grey in `out` (resized to `width` x `height`).
/// `scratch` holds a decoded colour image for Motion-JPEG and is unused otherwise.
pub fn to_gray(
    format: PixelFormat,
    src: &[u8],
    width: usize,
    height: usize,
    stride: usize,
    out: &mut GrayImage,
    scratch: &mut Vec<u8>,
) -> Result<()> {
    match format {
        PixelFormat::Gray8 => gray8_to_gray(src, width, height, stride, out),
        PixelFormat::Yuyv => packed_to_gray(src, width, height, stride, 2, 0, out),
        PixelFormat::Uyvy => packed_to_gray(src, width, height, stride, 2, 1, out),
        PixelFormat::Rgb24 => rgb24_to_gray(src, width, height, stride, out),
        PixelFormat::Bgr24 => bgr24_to_gray(src, width, height, stride, out),
        PixelFormat::Mjpeg => mjpeg_to_gray(src, out, scratch),
    }
}

/// 8-bit grey (GREY / Y8) copied, dropping any row padding.
pub fn gray8_to_gray(src: &[u8], width: usize, height: usize, stride: usize, out: &mut GrayImage) -> Result<()> {
    let stride = check(src, width, height, stride, 1)?;
    out.reset(width, height, 0);
    for y in 0..height {
        out.row_mut(y).copy_from_slice(&src[y * stride..y * stride + width]);
    }
    Ok(())
}

/// RGB24 to grey by Rec.601 luma in integers: (77 R + 150 G + 29 B + 128) / 256.
pub fn rgb24_to_gray(src: &[u8], width: usize, height: usize, stride: usize, out: &mut GrayImage) -> Result<()> {
    rgb_to_gray(src, width, height, stride, [0, 1, 2], out)
}

/// BGR24 to grey by Rec.601 luma in integers, as `rgb24_to_gray`.
pub fn bgr24_to_gray(src: &[u8], width: usize, height: usize, stride: usize, out: &mut GrayImage) -> Result<()> {
    rgb_to_gray(src, width, height, stride, [2, 1, 0], out)
}

/// Rec.601 luma of one pixel, integer weights summing to 256.
#[inline]
pub fn luma601(r: u8, g: u8, b: u8) -> u8 {
    ((77 * r as u32 + 150 * g as u32 + 29 * b as u32 + 128) >> 8) as u8
}

/// 16-bit pixel-interleaved stereo (Bumblebee2 Format7, some USB stereo cameras): each
/// 16-bit pixel carries one byte per sensor, split into `left` and `right` by `order`.
pub fn deinterleave16(
    src: &[u8],
    width: usize,
    height: usize,
    stride: usize,
    order: InterleavedOrder,
    left: &mut GrayImage,
    right: &mut GrayImage,
) -> Result<()> {
    let stride = check(src, width, height, stride, 2)?;
    let (l, r) = match order {
        InterleavedOrder::LeftFirst => (0, 1),
        InterleavedOrder::RightFirst => (1, 0),
    };
    left.reset(width, height, 0);
    right.reset(width, height, 0);
    for y in 0..height {
        let row = &src[y * stride..y * stride + 2 * width];
        for ((pair, a), b) in row.chunks_exact(2).zip(left.row_mut(y)).zip(right.row_mut(y).iter_mut()) {
            *a = pair[l];
            *b = pair[r];
        }
    }
    Ok(())
}

/// A side-by-side grey frame split into its left and right halves (the left camera on the
/// left). The frame's width must be even.
pub fn split_side_by_side(frame: &GrayImage, left: &mut GrayImage, right: &mut GrayImage) -> Result<()> {
    if !frame.width.is_multiple_of(2) || frame.data.len() != frame.width * frame.height {
        return Err(Error::new(
            ErrorKind::Format,
            format!("side-by-side frame is {}x{}, expected an even width", frame.width, frame.height),
        ));
    }
    let half = frame.width / 2;
    left.reset(half, frame.height, 0);
    right.reset(half, frame.height, 0);
    for y in 0..frame.height {
        let row = frame.row(y);
        left.row_mut(y).copy_from_slice(&row[..half]);
        right.row_mut(y).copy_from_slice(&row[half..]);
    }
    Ok(())
}

/// Motion-JPEG (one JPEG image) to grey; colour JPEGs go through `scratch` as RGB and then
/// Rec.601 luma. The decoder itself allocates its working memory per image.
#[cfg(feature = "mjpeg")]
pub fn mjpeg_to_gray(src: &[u8], out: &mut GrayImage, scratch: &mut Vec<u8>) -> Result<()> {
    use image::ImageDecoder;
    let bad = |e: image::ImageError| Error::new(ErrorKind::Format, format!("MJPEG buffer does not decode: {e}"));
    let decoder = image::codecs::jpeg::JpegDecoder::new(std::io::Cursor::new(src)).map_err(bad)?;
    let (w, h) = decoder.dimensions();
    let (w, h) = (w as usize, h as usize);
    match decoder.color_type() {
        image::ColorType::L8 => {
            out.reset(w, h, 0);
            decoder.read_image(&mut out.data).map_err(bad)?;
        }
        image::ColorType::Rgb8 => {
            scratch.clear();
            scratch.resize(3 * w * h, 0);
            decoder.read_image(scratch).map_err(bad)?;
            rgb24_to_gray(scratch, w, h, 3 * w, out)?;
        }
        other => {
            return Err(Error::new(ErrorKind::Format, format!("MJPEG buffer is {other:?}, expected grey or RGB")));
        }
    }
    Ok(())
}

/// Motion-JPEG needs the `mjpeg` feature; without it every buffer is refused.
#[cfg(not(feature = "mjpeg"))]
pub fn mjpeg_to_gray(_src: &[u8], _out: &mut GrayImage, _scratch: &mut Vec<u8>) -> Result<()> {
    Err(Error::new(
        ErrorKind::NotBuilt,
        "MJPEG camera buffers need camplace-hwio's `mjpeg` feature, which this build lacks",
    ))
}

/// Grey from a packed format whose luma is every `step`-th byte from `offset`.
fn packed_to_gray(
    src: &[u8],
    width: usize,
    height: usize,
    stride: usize,
    step: usize,
    offset: usize,
    out: &mut GrayImage,
) -> Result<()> {
    let stride = check(src, width, height, stride, step)?;
    out.reset(width, height, 0);
    for y in 0..height {
        let row = &src[y * stride..y * stride + step * width];
        for (o, px) in out.row_mut(y).iter_mut().zip(row.chunks_exact(step)) {
            *o = px[offset];
        }
    }
    Ok(())
}

fn rgb_to_gray(
    src: &[u8],
    width: usize,
    height: usize,
    stride: usize,
    rgb: [usize; 3],
    out: &mut GrayImage,
) -> Result<()> {
    let stride = check(src, width, height, stride, 3)?;
    out.reset(width, height, 0);
    for y in 0..height {
        let row = &src[y * stride..y * stride + 3 * width];
        for (o, px) in out.row_mut(y).iter_mut().zip(row.chunks_exact(3)) {
            *o = luma601(px[rgb[0]], px[rgb[1]], px[rgb[2]]);
        }
    }
    Ok(())
}

/// The effective stride, or an error when `src` is too short for the image it should hold.
/// Counted in u128 (saturating), so sizes a device reports too large for any buffer are
/// errors too rather than an overflow.
fn check(src: &[u8], width: usize, height: usize, stride: usize, bytes_per_pixel: usize) -> Result<usize> {
    let packed = width as u128 * bytes_per_pixel as u128;
    let stride = if stride == 0 { packed } else { stride as u128 };
    if stride < packed {
        return Err(Error::new(
            ErrorKind::Format,
            format!("camera row stride {stride} bytes is shorter than {width} pixels of {bytes_per_pixel} bytes"),
        ));
    }
    let need = if height == 0 { 0 } else { (height as u128 - 1).saturating_mul(stride).saturating_add(packed) };
    if (src.len() as u128) < need {
        return Err(Error::new(
            ErrorKind::Format,
            format!("camera buffer holds {} bytes, expected at least {need} for {width}x{height}", src.len()),
        ));
    }
    // Without rows nothing is read, whatever the stride; with them it fits in `src`.
    Ok(usize::try_from(stride).unwrap_or(usize::MAX))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn noise(seed: u64, n: usize) -> Vec<u8> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..n).map(|_| rng.random::<u8>()).collect()
    }

    /// Sizes and strides to try: packed, padded, odd widths.
    const SHAPES: [(usize, usize, usize); 4] = [(8, 5, 0), (7, 3, 5), (64, 48, 0), (33, 17, 11)];

    #[test]
    fn yuyv_and_uyvy_keep_the_luma_bytes() {
        for (i, &(w, h, pad)) in SHAPES.iter().enumerate() {
            let stride = 2 * w + pad;
            let src = noise(i as u64, stride * h);
            let mut out = GrayImage::default();
            to_gray(PixelFormat::Yuyv, &src, w, h, stride, &mut out, &mut Vec::new()).unwrap();
            let mut out2 = GrayImage::default();
            to_gray(PixelFormat::Uyvy, &src, w, h, stride, &mut out2, &mut Vec::new()).unwrap();
            for y in 0..h {
                for x in 0..w {
                    assert_eq!(out.get(x, y), src[y * stride + 2 * x]);
                    assert_eq!(out2.get(x, y), src[y * stride + 2 * x + 1]);
                }
            }
        }
    }

    #[test]
    fn gray8_drops_row_padding() {
        for (i, &(w, h, pad)) in SHAPES.iter().enumerate() {
            let stride = w + pad;
            let src = noise(10 + i as u64, stride * h);
            let mut out = GrayImage::default();
            gray8_to_gray(&src, w, h, if pad == 0 { 0 } else { stride }, &mut out).unwrap();
            assert_eq!((out.width, out.height), (w, h));
            for y in 0..h {
                assert_eq!(out.row(y), &src[y * stride..y * stride + w]);
            }
        }
    }

    #[test]
    fn rgb_and_bgr_luma_match_rec601_within_rounding() {
        for (i, &(w, h, pad)) in SHAPES.iter().enumerate() {
            let stride = 3 * w + pad;
            let src = noise(20 + i as u64, stride * h);
            let mut rgb = GrayImage::default();
            rgb24_to_gray(&src, w, h, stride, &mut rgb).unwrap();
            // The same bytes read as BGR are the RGB image with R and B swapped.
            let mut swapped = src.clone();
            for y in 0..h {
                for px in swapped[y * stride..y * stride + 3 * w].chunks_exact_mut(3) {
                    px.swap(0, 2);
                }
            }
            let mut bgr = GrayImage::default();
            bgr24_to_gray(&swapped, w, h, stride, &mut bgr).unwrap();
            assert_eq!(rgb, bgr);
            for y in 0..h {
                for x in 0..w {
                    let p = &src[y * stride + 3 * x..];
                    let exact = 0.299 * p[0] as f64 + 0.587 * p[1] as f64 + 0.114 * p[2] as f64;
                    let got = rgb.get(x, y) as f64;
                    assert!((got - exact).abs() <= 1.0, "({x},{y}) {p:?}: {got} vs {exact}");
                }
            }
        }
    }

    #[test]
    fn deinterleave_recovers_both_cameras_in_either_order() {
        for (i, &(w, h, pad)) in SHAPES.iter().enumerate() {
            let left = noise(30 + i as u64, w * h);
            let right = noise(40 + i as u64, w * h);
            for order in [InterleavedOrder::LeftFirst, InterleavedOrder::RightFirst] {
                let stride = 2 * w + pad;
                let mut src = vec![0u8; stride * h];
                for y in 0..h {
                    for x in 0..w {
                        let (a, b) = match order {
                            InterleavedOrder::LeftFirst => (left[y * w + x], right[y * w + x]),
                            InterleavedOrder::RightFirst => (right[y * w + x], left[y * w + x]),
                        };
                        src[y * stride + 2 * x] = a;
                        src[y * stride + 2 * x + 1] = b;
                    }
                }
                let (mut l, mut r) = (GrayImage::default(), GrayImage::default());
                deinterleave16(&src, w, h, stride, order, &mut l, &mut r).unwrap();
                assert_eq!(l.data, left);
                assert_eq!(r.data, right);
            }
        }
    }

    #[test]
    fn side_by_side_splits_into_halves() {
        let (w, h) = (40, 9);
        let full = GrayImage::from_vec(w, h, noise(50, w * h)).unwrap();
        let (mut l, mut r) = (GrayImage::default(), GrayImage::default());
        split_side_by_side(&full, &mut l, &mut r).unwrap();
        for y in 0..h {
            for x in 0..w / 2 {
                assert_eq!(l.get(x, y), full.get(x, y));
                assert_eq!(r.get(x, y), full.get(x + w / 2, y));
            }
        }
        let odd = GrayImage::new(5, 2, 0);
        assert_eq!(split_side_by_side(&odd, &mut l, &mut r).unwrap_err().kind(), ErrorKind::Format);
    }

    #[test]
    fn short_buffers_and_strides_are_errors() {
        let mut out = GrayImage::default();
        let e = to_gray(PixelFormat::Yuyv, &[0; 10], 4, 2, 0, &mut out, &mut Vec::new()).unwrap_err();
        assert!(e.to_string().contains("expected at least 16"), "{e}");
        let e = rgb24_to_gray(&[0; 100], 4, 2, 11, &mut out).unwrap_err();
        assert!(e.to_string().contains("stride"), "{e}");
        let (mut l, mut r) = (GrayImage::default(), GrayImage::default());
        assert!(deinterleave16(&[0; 15], 4, 2, 0, InterleavedOrder::LeftFirst, &mut l, &mut r).is_err());
    }

    #[test]
    fn sizes_whose_byte_count_overflows_are_errors() {
        // Sizes a device could report: the bytes they need do not fit a usize, so no buffer
        // is long enough, and the answer is an error rather than an overflow.
        let big = usize::MAX / 2;
        let (mut l, mut r) = (GrayImage::default(), GrayImage::default());
        let e = deinterleave16(&[0; 64], 4, big, big, InterleavedOrder::LeftFirst, &mut l, &mut r).unwrap_err();
        assert_eq!(e.kind(), ErrorKind::Format);
        assert!(e.to_string().contains("camera buffer holds 64 bytes"), "{e}");
        let mut out = GrayImage::default();
        let e = rgb24_to_gray(&[0; 64], big, 1, 0, &mut out).unwrap_err();
        assert!(e.to_string().contains("camera buffer holds 64 bytes"), "{e}");
        let e = rgb24_to_gray(&[0; 64], usize::MAX, usize::MAX, 0, &mut out).unwrap_err();
        assert!(e.to_string().contains("camera buffer holds 64 bytes"), "{e}");
    }

    #[test]
    fn no_allocation_when_the_size_is_unchanged() {
        let (w, h) = (32, 24);
        let src = noise(60, 2 * w * h);
        let (mut l, mut r) = (GrayImage::default(), GrayImage::default());
        deinterleave16(&src, w, h, 0, InterleavedOrder::RightFirst, &mut l, &mut r).unwrap();
        let before = (l.data.as_ptr(), l.data.capacity(), r.data.as_ptr(), r.data.capacity());
        let src2 = noise(61, 2 * w * h);
        deinterleave16(&src2, w, h, 0, InterleavedOrder::RightFirst, &mut l, &mut r).unwrap();
        assert_eq!(before, (l.data.as_ptr(), l.data.capacity(), r.data.as_ptr(), r.data.capacity()));
        let mut scratch = Vec::new();
        let mut out = GrayImage::default();
        to_gray(PixelFormat::Yuyv, &src, w, h, 0, &mut out, &mut scratch).unwrap();
        let before = (out.data.as_ptr(), out.data.capacity());
        to_gray(PixelFormat::Yuyv, &src2, w, h, 0, &mut out, &mut scratch).unwrap();
        assert_eq!(before, (out.data.as_ptr(), out.data.capacity()));
    }

    /// A smooth seeded image (JPEG is lossy on noise).
    #[cfg(feature = "mjpeg")]
    fn smooth(seed: u64, w: usize, h: usize) -> Vec<u8> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let (a, b): (f64, f64) = (rng.random_range(0.05..0.2), rng.random_range(0.05..0.2));
        (0..w * h).map(|i| (128.0 + 100.0 * ((i % w) as f64 * a).sin() * ((i / w) as f64 * b).cos()) as u8).collect()
    }

    #[cfg(feature = "mjpeg")]
    #[test]
    fn mjpeg_grey_and_colour_decode_to_their_luma() {
        use image::ImageEncoder;
        let (w, h) = (64, 48);
        let grey = smooth(70, w, h);
        let mut jpeg = Vec::new();
        image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, 100)
            .write_image(&grey, w as u32, h as u32, image::ExtendedColorType::L8)
            .unwrap();
        let (mut out, mut scratch) = (GrayImage::default(), Vec::new());
        mjpeg_to_gray(&jpeg, &mut out, &mut scratch).unwrap();
        assert_eq!((out.width, out.height), (w, h));
        let err: f64 =
            out.data.iter().zip(&grey).map(|(&a, &b)| (a as f64 - b as f64).abs()).sum::<f64>() / (w * h) as f64;
        assert!(err < 2.0, "mean error {err}");

        let (r, g, b) = (smooth(71, w, h), smooth(72, w, h), smooth(73, w, h));
        let rgb: Vec<u8> = (0..w * h).flat_map(|i| [r[i], g[i], b[i]]).collect();
        let mut jpeg = Vec::new();
        image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, 100)
            .write_image(&rgb, w as u32, h as u32, image::ExtendedColorType::Rgb8)
            .unwrap();
        mjpeg_to_gray(&jpeg, &mut out, &mut scratch).unwrap();
        let err: f64 = (0..w * h).map(|i| (out.data[i] as f64 - luma601(r[i], g[i], b[i]) as f64).abs()).sum::<f64>()
            / (w * h) as f64;
        assert!(err < 3.0, "mean error {err}");
        assert_eq!(mjpeg_to_gray(b"not a jpeg", &mut out, &mut scratch).unwrap_err().kind(), ErrorKind::Format);
    }
}
