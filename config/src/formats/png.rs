//! 8-bit grey PNG images (colour input is converted to luma) and RGB previews.

use std::path::Path;

use super::read::{read_bounded, FileKind, MAX_IMAGE_PIXELS};
use crate::{Error, ErrorKind, GrayImage};

/// Reads a PNG as 8-bit grey; other image formats are refused (whatever else the `image`
/// crate might decode, a GIF's canvas, say, can cost seconds of work for a few bytes).
/// The file is read within [`FileKind::Image`]'s budget and its header's size checked against
/// [`MAX_IMAGE_PIXELS`] before a pixel is decoded, so a small file that would decode to a
/// huge image is refused for what it would take.
pub fn read_gray(path: &Path) -> Result<GrayImage, Error> {
    let bytes = read_bounded(path, FileKind::Image)?;
    decode_gray(&bytes).map_err(|e| e.in_file(path))
}

/// The width and height of an image file from its header alone (the file checked as
/// [`read_gray`] checks it, no pixel decoded).
pub fn read_image_size(path: &Path) -> Result<(usize, usize), Error> {
    let (file, _) = super::read::open_checked(path, FileKind::Image)?;
    let reader = image::ImageReader::with_format(std::io::BufReader::new(file), image::ImageFormat::Png);
    let (w, h) = reader
        .into_dimensions()
        .map_err(|e| Error::new(ErrorKind::Format, "", not_a_png(&e)).in_file(path).with_source(e))?;
    Ok((w as usize, h as usize))
}

/// Decodes image bytes as 8-bit grey within the pixel budget (see [`read_gray`]).
pub fn decode_gray(bytes: &[u8]) -> Result<GrayImage, Error> {
    use image::ImageDecoder;
    let unreadable = |e: image::ImageError| Error::new(ErrorKind::Format, "", not_a_png(&e)).with_source(e);
    let mut reader = image::ImageReader::with_format(std::io::Cursor::new(bytes), image::ImageFormat::Png);
    let mut limits = image::Limits::default();
    // A decoded colour image at the pixel budget, 16 bits a channel, and its grey copy.
    limits.max_alloc = Some(MAX_IMAGE_PIXELS * 8 + MAX_IMAGE_PIXELS);
    reader.limits(limits);
    let decoder = reader.into_decoder().map_err(unreadable)?;
    let (w, h) = decoder.dimensions();
    let pixels = u64::from(w) * u64::from(h);
    if pixels > MAX_IMAGE_PIXELS {
        return Err(Error::new(
            ErrorKind::Value,
            "",
            format!(
                "{w} x {h} pixels ({:.0} MB decoded), expected at most {MAX_IMAGE_PIXELS} pixels (8192 x 8192) before it is decoded",
                pixels as f64 * f64::from(decoder.color_type().bytes_per_pixel()) / 1e6
            ),
        ));
    }
    let img = image::DynamicImage::from_decoder(decoder).map_err(unreadable)?;
    let g = img.to_luma8();
    Ok(GrayImage { width: g.width() as usize, height: g.height() as usize, data: g.into_raw() })
}

/// What a file that does not decode as a PNG is told.
fn not_a_png(e: &image::ImageError) -> String {
    format!("not a readable PNG image (expected an 8-bit or 16-bit PNG, grey or colour): {e}")
}

/// Writes an 8-bit grey PNG.
pub fn write_gray(path: &Path, width: usize, height: usize, data: &[u8]) -> Result<(), Error> {
    assert_eq!(data.len(), width * height, "grey image size");
    let mut out = Vec::new();
    image::codecs::png::PngEncoder::new_with_quality(
        &mut out,
        image::codecs::png::CompressionType::Fast,
        image::codecs::png::FilterType::Sub,
    )
    .write_image_checked(data, width as u32, height as u32, image::ExtendedColorType::L8)
    .map_err(|e| Error::new(ErrorKind::Format, "", e.to_string()).in_file(path).with_source(e))?;
    super::write_atomic(path, &out)
}

/// Writes an 8-bit RGB PNG (`data` is r, g, b per pixel).
pub fn write_rgb(path: &Path, width: usize, height: usize, data: &[u8]) -> Result<(), Error> {
    assert_eq!(data.len(), 3 * width * height, "rgb image size");
    let mut out = Vec::new();
    image::codecs::png::PngEncoder::new(&mut out)
        .write_image_checked(data, width as u32, height as u32, image::ExtendedColorType::Rgb8)
        .map_err(|e| Error::new(ErrorKind::Format, "", e.to_string()).in_file(path).with_source(e))?;
    super::write_atomic(path, &out)
}

trait WriteChecked {
    fn write_image_checked(self, data: &[u8], w: u32, h: u32, c: image::ExtendedColorType) -> image::ImageResult<()>;
}

impl<W: std::io::Write> WriteChecked for image::codecs::png::PngEncoder<W> {
    fn write_image_checked(self, data: &[u8], w: u32, h: u32, c: image::ExtendedColorType) -> image::ImageResult<()> {
        use image::ImageEncoder;
        self.write_image(data, w, h, c)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grey_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.png");
        let data: Vec<u8> = (0..12u8).map(|v| v * 20).collect();
        write_gray(&p, 4, 3, &data).unwrap();
        let g = read_gray(&p).unwrap();
        assert_eq!((g.width, g.height), (4, 3));
        assert_eq!(g.data, data);
    }

    #[test]
    fn not_an_image_names_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("b.png");
        std::fs::write(&p, b"hello").unwrap();
        let e = read_gray(&p).unwrap_err();
        assert!(e.to_string().contains("b.png"), "{e}");
    }

    /// A grey PNG of `w` x `h` black pixels, small on disk however large it decodes.
    fn black_png(w: u32, h: u32) -> Vec<u8> {
        let mut out = Vec::new();
        let mut enc = png::Encoder::new(&mut out, w, h);
        enc.set_color(png::ColorType::Grayscale);
        enc.set_compression(png::Compression::High);
        let mut writer = enc.write_header().unwrap();
        let mut stream = writer.stream_writer().unwrap();
        let row = vec![0u8; w as usize];
        for _ in 0..h {
            std::io::Write::write_all(&mut stream, &row).unwrap();
        }
        stream.finish().unwrap();
        writer.finish().unwrap();
        out
    }

    #[test]
    fn an_image_past_the_pixel_budget_is_refused_from_its_header() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("bomb.png");
        let bytes = black_png(16384, 16384);
        assert!(bytes.len() < 2 << 20, "a bomb is small on disk: {}", bytes.len());
        std::fs::write(&p, &bytes).unwrap();
        let e = read_gray(&p).unwrap_err().to_string();
        assert!(e.contains("bomb.png") && e.contains("16384 x 16384") && e.contains("at most"), "{e}");
        // One within the budget decodes.
        let small = black_png(64, 32);
        assert_eq!(decode_gray(&small).unwrap().data, vec![0u8; 64 * 32]);
    }

    #[test]
    fn other_image_formats_are_refused_as_not_png() {
        // A GIF header with a 3328 x 2629 canvas and no frame data (a GIF decoder fills the
        // whole canvas for it), and the start of a JPEG and of a BMP.
        let mut gif = b"GIF89a".to_vec();
        gif.extend_from_slice(&3328u16.to_le_bytes());
        gif.extend_from_slice(&2629u16.to_le_bytes());
        gif.extend_from_slice(&[0, 0, 0, b';']);
        let jpeg = [0xff, 0xd8, 0xff, 0xe0, 0, 16, b'J', b'F', b'I', b'F', 0];
        let bmp = *b"BM\x3e\0\0\0\0\0\0\0\x3e\0\0\0";
        let dir = tempfile::tempdir().unwrap();
        for (name, bytes) in [("a.gif", &gif[..]), ("b.jpg", &jpeg[..]), ("c.bmp", &bmp[..])] {
            let e = decode_gray(bytes).unwrap_err().to_string();
            assert!(e.contains("not a readable PNG image"), "{name}: {e}");
            let p = dir.path().join(name);
            std::fs::write(&p, bytes).unwrap();
            for e in [read_gray(&p).unwrap_err().to_string(), read_image_size(&p).unwrap_err().to_string()] {
                assert!(e.contains(name) && e.contains("expected an 8-bit or 16-bit PNG"), "{e}");
            }
        }
    }
}
