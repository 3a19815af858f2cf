//! Reading an input file within a budget: every reader of outside bytes opens its file
//! through here. The file must be a regular file (a device such as `/dev/zero`, a FIFO or
//! a socket is refused before it is opened, so nothing blocks or reads forever) and no
//! larger than what its kind can need, checked from its size before a byte is read (and
//! again while reading, for a file that grows).

use std::io::Read;
use std::path::Path;

use crate::Error;

/// The kinds of input file and the most bytes each can need.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum FileKind {
    /// A text file a person writes or edits: cell file, `rig.json`, `truth.json`,
    /// `tolerance.json`, `recommended.json`, `settings.json`.
    Text,
    /// An image (PNG): its pixels are budgeted again from its header.
    Image,
    /// A depth or disparity map, a cloud or a mesh.
    Data,
    /// A tray model file.
    Model,
}

/// The most bytes a text file is read to.
pub const MAX_TEXT_BYTES: u64 = 16 << 20;

/// The most bytes an image file is read to: an 8-bit grey PNG at the pixel budget
/// ([`MAX_IMAGE_PIXELS`]) stored uncompressed is 64 MiB; a colour one four times that.
pub const MAX_IMAGE_FILE_BYTES: u64 = 256 << 20;

/// The most pixels an input image may have: 8192 x 8192, the largest camera a cell gives.
/// Checked from the image's header before it is decoded.
pub const MAX_IMAGE_PIXELS: u64 = 8192 * 8192;

/// The most bytes a data file (depth map, cloud, mesh) is read to.
pub const MAX_DATA_BYTES: u64 = 4 << 30;

/// The most bytes a model file is read to.
pub const MAX_MODEL_BYTES: u64 = 2 << 30;

impl FileKind {
    /// The most bytes a file of this kind is read to.
    pub fn budget(self) -> u64 {
        match self {
            FileKind::Text => MAX_TEXT_BYTES,
            FileKind::Image => MAX_IMAGE_FILE_BYTES,
            FileKind::Data => MAX_DATA_BYTES,
            FileKind::Model => MAX_MODEL_BYTES,
        }
    }

    fn name(self) -> &'static str {
        match self {
            FileKind::Text => "a text file",
            FileKind::Image => "an image",
            FileKind::Data => "a data file",
            FileKind::Model => "a model file",
        }
    }
}

/// Opens `path` for reading after checking that it is a regular file of at most `most`
/// bytes; returns the file and its length.
pub fn open_checked(path: &Path, kind: FileKind) -> Result<(std::fs::File, u64), Error> {
    let most = kind.budget();
    // Before opening: opening a FIFO for reading blocks until a writer comes.
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, &e))?;
    if !meta.is_file() {
        let what = if meta.is_dir() { "a folder" } else { "a device, FIFO or socket" };
        return Err(Error::format(format!("expected {} (a regular file), found {what}", kind.name())).in_file(path));
    }
    if meta.len() > most {
        return Err(too_long(path, kind, meta.len()));
    }
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, &e))?;
    Ok((file, meta.len()))
}

fn too_long(path: &Path, kind: FileKind, len: u64) -> Error {
    Error::format(format!("{len} bytes, expected {} of at most {} bytes", kind.name(), kind.budget())).in_file(path)
}

/// The bytes of `path`, a file of `kind`: refused when it is not a regular file or is
/// longer than the kind's budget.
pub fn read_bounded(path: &Path, kind: FileKind) -> Result<Vec<u8>, Error> {
    let (file, len) = open_checked(path, kind)?;
    let most = kind.budget();
    let mut bytes = Vec::with_capacity(len as usize);
    file.take(most + 1).read_to_end(&mut bytes).map_err(|e| Error::io(path, &e))?;
    if bytes.len() as u64 > most {
        return Err(too_long(path, kind, bytes.len() as u64));
    }
    Ok(bytes)
}

/// The text of `path`, refused when longer than [`MAX_TEXT_BYTES`] or not UTF-8.
pub fn read_text(path: &Path) -> Result<String, Error> {
    let bytes = read_bounded(path, FileKind::Text)?;
    String::from_utf8(bytes).map_err(|_| Error::format("expected UTF-8 text, found other bytes").in_file(path))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_endless_device_is_refused_before_a_byte_is_read() {
        for kind in [FileKind::Text, FileKind::Image, FileKind::Data, FileKind::Model] {
            let e = read_bounded(Path::new("/dev/zero"), kind).unwrap_err().to_string();
            assert!(e.contains("/dev/zero") && e.contains("regular file"), "{e}");
        }
        let e = read_text(Path::new("/dev/zero")).unwrap_err().to_string();
        assert!(e.contains("regular file"), "{e}");
    }

    #[test]
    fn a_fifo_is_refused_without_blocking() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("pipe");
        let made = std::process::Command::new("mkfifo").arg(&p).status();
        if !made.is_ok_and(|s| s.success()) {
            return; // no mkfifo on this system: the device case above covers the check
        }
        let e = read_text(&p).unwrap_err().to_string();
        assert!(e.contains("FIFO"), "{e}");
    }

    #[test]
    fn a_file_within_the_budget_reads_whole_and_one_past_it_is_refused_from_its_size() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.txt");
        std::fs::write(&p, "[table]\nalbedo = 0.5\n").unwrap();
        assert_eq!(read_text(&p).unwrap(), "[table]\nalbedo = 0.5\n");
        let big = dir.path().join("big.toml");
        std::fs::File::create(&big).unwrap().set_len(MAX_TEXT_BYTES + 1).unwrap();
        let e = read_text(&big).unwrap_err().to_string();
        assert!(e.contains("big.toml") && e.contains(&format!("at most {MAX_TEXT_BYTES} bytes")), "{e}");
        let e = read_text(dir.path()).unwrap_err().to_string();
        assert!(e.contains("a folder"), "{e}");
    }
}
