//! PFM float images (Middlebury style: one channel, little-endian, rows stored bottom to
//! top; invalid = +inf).

use std::path::Path;

use crate::{Error, ErrorKind, FloatImage};

/// Encodes a one-channel PFM (little-endian).
pub fn encode_pfm(width: usize, height: usize, data: &[f32]) -> Vec<u8> {
    assert_eq!(data.len(), width * height, "pfm size");
    let mut out = format!("Pf\n{width} {height}\n-1\n").into_bytes();
    out.reserve(data.len() * 4);
    for row in (0..height).rev() {
        for v in &data[row * width..(row + 1) * width] {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    out
}

/// Writes a one-channel PFM.
pub fn write_pfm(path: &Path, width: usize, height: usize, data: &[f32]) -> Result<(), Error> {
    super::write_atomic(path, &encode_pfm(width, height, data))
}

/// Reads a PFM; a three-channel file is reduced to its first channel.
pub fn read_pfm(path: &Path) -> Result<FloatImage, Error> {
    let bytes = super::read::read_bounded(path, super::read::FileKind::Data)?;
    decode_pfm(&bytes).map_err(|e| e.in_file(path))
}

/// Decodes PFM bytes.
pub fn decode_pfm(bytes: &[u8]) -> Result<FloatImage, Error> {
    let bad = |field: &str, m: &str| Error::new(ErrorKind::Format, field, m.to_string());
    let mut pos = 0;
    let token = |pos: &mut usize| -> Option<String> {
        while *pos < bytes.len() && bytes[*pos].is_ascii_whitespace() {
            *pos += 1;
        }
        let start = *pos;
        while *pos < bytes.len() && !bytes[*pos].is_ascii_whitespace() {
            *pos += 1;
        }
        (start < *pos).then(|| String::from_utf8_lossy(&bytes[start..*pos]).into_owned())
    };
    let channels = match token(&mut pos).as_deref() {
        Some("Pf") => 1,
        Some("PF") => 3,
        _ => return Err(bad("header", "not a PFM file: expected \"Pf\" or \"PF\"")),
    };
    let width: usize =
        token(&mut pos).and_then(|t| t.parse().ok()).ok_or_else(|| bad("width", "expected a whole number"))?;
    let height: usize =
        token(&mut pos).and_then(|t| t.parse().ok()).ok_or_else(|| bad("height", "expected a whole number"))?;
    let scale: f32 = token(&mut pos).and_then(|t| t.parse().ok()).ok_or_else(|| bad("scale", "expected a number"))?;
    if !(scale.is_finite() && scale != 0.0) {
        return Err(bad("scale", "expected a non-zero number (negative: little-endian)"));
    }
    if width == 0 || height == 0 {
        return Err(bad("width", &format!("expected a positive image size, got {width} x {height}")));
    }
    pos += 1; // the single whitespace byte after the scale
    let body = bytes.get(pos..).unwrap_or(&[]);
    // Sizes come from the file: compare them with what the file holds before allocating,
    // in arithmetic that cannot wrap.
    let need = (width as u128) * (height as u128) * (channels as u128) * 4;
    if (body.len() as u128) < need {
        return Err(bad(
            "data",
            &format!("expected {need} bytes of floats for {width} x {height}, found {}", body.len()),
        ));
    }
    let little = scale < 0.0;
    let mut data = vec![0f32; width * height];
    for row in 0..height {
        let src_row = height - 1 - row;
        for x in 0..width {
            let o = ((src_row * width + x) * channels) * 4;
            let b = [body[o], body[o + 1], body[o + 2], body[o + 3]];
            data[row * width + x] = if little { f32::from_le_bytes(b) } else { f32::from_be_bytes(b) };
        }
    }
    Ok(FloatImage { width, height, data })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_keeps_inf_and_row_order() {
        let data = vec![1.0, 2.0, f32::INFINITY, 4.5, -1.0, 0.25];
        let img = decode_pfm(&encode_pfm(3, 2, &data)).unwrap();
        assert_eq!((img.width, img.height), (3, 2));
        assert_eq!(img.data, data);
    }

    #[test]
    fn short_file_is_an_error() {
        let mut b = encode_pfm(3, 2, &[0.0; 6]);
        b.truncate(b.len() - 3);
        assert_eq!(decode_pfm(&b).unwrap_err().key(), "data");
        assert_eq!(decode_pfm(b"P6\n1 1\n").unwrap_err().key(), "header");
    }
}
