//! Reading a whole input file with a ceiling: a path that names a device such as
//! `/dev/zero`, or a file far larger than its kind ever is, ends in an error instead of
//! filling the memory or reading forever.

use std::io::Read;
use std::path::Path;

use crate::Error;

/// The most bytes a text file (cell file, `rig.json`, `truth.json`) is read to.
pub const MAX_TEXT_BYTES: u64 = 16 << 20;

/// The most bytes a data file (image, depth map, cloud, mesh) is read to.
pub const MAX_DATA_BYTES: u64 = 4 << 30;

/// The bytes of `path`, refused when there are more than `most`.
pub fn read_bounded(path: &Path, most: u64) -> Result<Vec<u8>, Error> {
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, &e))?;
    let mut bytes = Vec::new();
    file.take(most + 1).read_to_end(&mut bytes).map_err(|e| Error::io(path, &e))?;
    if bytes.len() as u64 > most {
        return Err(Error::format(format!("expected a file of at most {most} bytes, it is longer")).in_file(path));
    }
    Ok(bytes)
}

/// The text of `path`, refused when longer than [`MAX_TEXT_BYTES`] or not UTF-8.
pub fn read_text(path: &Path) -> Result<String, Error> {
    let bytes = read_bounded(path, MAX_TEXT_BYTES)?;
    String::from_utf8(bytes).map_err(|_| Error::format("expected UTF-8 text, found other bytes").in_file(path))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_endless_device_is_refused_not_read_forever() {
        let e = read_bounded(Path::new("/dev/zero"), 1 << 20).unwrap_err();
        assert!(e.to_string().contains("/dev/zero") && e.to_string().contains("at most"), "{e}");
        let e = read_text(Path::new("/dev/zero")).unwrap_err();
        assert!(e.to_string().contains("at most"), "{e}");
    }

    #[test]
    fn a_file_within_the_ceiling_reads_whole() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.txt");
        std::fs::write(&p, "[table]\nalbedo = 0.5\n").unwrap();
        assert_eq!(read_text(&p).unwrap(), "[table]\nalbedo = 0.5\n");
        assert!(read_bounded(&p, 3).is_err());
    }
}
