//! 8-bit grey PNG images (colour input is converted to luma) and RGB previews.

use std::path::Path;

use crate::{Error, ErrorKind};

/// A grey image read from a file: width, height and row-major pixels.
#[derive(Debug, Clone, PartialEq)]
pub struct Gray {
    pub width: usize,
    pub height: usize,
    pub data: Vec<u8>,
}

/// Reads a PNG (or any image the `image` crate decodes) as 8-bit grey.
pub fn read_gray(path: &Path) -> Result<Gray, Error> {
    let bytes = super::read::read_bounded(path, super::read::MAX_DATA_BYTES)?;
    let img = image::load_from_memory(&bytes).map_err(|e| {
        Error::new(ErrorKind::Format, "", format!("not a readable image: {e}")).in_file(path).with_source(e)
    })?;
    let g = img.to_luma8();
    Ok(Gray { width: g.width() as usize, height: g.height() as usize, data: g.into_raw() })
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
}
