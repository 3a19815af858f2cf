//! The interchange formats of docs/architecture.md §3: PNG (8-bit grey), PFM (float32),
//! PLY (point clouds, meshes), STL and OBJ (meshes). Readers check what they read and say
//! which file and which field is wrong; writers write atomically where results could be
//! lost.

#[cfg(test)]
mod corruption_tests;
pub(crate) mod dataset;
pub(crate) mod json;
pub(crate) mod mesh;
pub(crate) mod pfm;
pub(crate) mod ply;
pub(crate) mod png;

use std::io::Write;
use std::path::Path;

use crate::Error;

/// Writes `bytes` to `path` through a temporary file and a rename, so a reader never sees
/// half a file.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), Error> {
    let dir = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let tmp = dir.join(format!(".{name}.tmp{}", std::process::id()));
    let result = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    result.map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        Error::io(path, &e)
    })
}
