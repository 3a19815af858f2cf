//! Atomic writes (a temporary file beside the target, then a rename) and the clean-up of the
//! temporary files a killed process leaves behind. Temporary names are recognisable, so a
//! folder camplace owns can be cleaned without touching anything else.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime};

use crate::Error;

/// What a temporary file's name carries between the target's name and the writer's process id.
const TEMP_MARK: &str = ".camplace-tmp-";

/// Without /proc a writer cannot be asked whether it still runs: a temporary file older than
/// this is taken to be left over.
const STALE_WITHOUT_PROC: Duration = Duration::from_secs(3600);

/// Writes `bytes` to `path` through a temporary file (`.NAME.camplace-tmp-PID` in the same
/// folder) and a rename, so a reader never sees half a file. A `path` that names anything
/// but a regular file (a device, a FIFO, a socket, a folder) is refused and left as it was:
/// the rename would put a regular file in its place.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), Error> {
    write_atomic_all(&[(path, bytes)])
}

/// Writes several files as one output: every target is checked ([`check_output_file`]) and
/// every temporary file written before any is renamed to its target, so a command whose
/// outputs cannot all be written writes none of them. Only a rename failing part-way (the
/// folder's disk gone between two renames) leaves the first files written.
pub fn write_atomic_all(files: &[(&Path, &[u8])]) -> Result<(), Error> {
    for (path, _) in files {
        check_output_file(path)?;
    }
    let mut temps: Vec<PathBuf> = Vec::with_capacity(files.len());
    let remove_temps = |temps: &[PathBuf]| {
        for tmp in temps {
            let _ = std::fs::remove_file(tmp);
        }
    };
    for (path, bytes) in files {
        let tmp = temp_path_for(path);
        temps.push(tmp.clone());
        let written = (|| {
            let mut f = std::fs::File::create(&tmp)?;
            f.write_all(bytes)?;
            f.sync_all()
        })();
        if let Err(e) = written {
            remove_temps(&temps);
            return Err(Error::io(path, &e));
        }
    }
    for (i, ((path, _), tmp)) in files.iter().zip(&temps).enumerate() {
        if let Err(e) = std::fs::rename(tmp, path) {
            remove_temps(&temps[i..]);
            return Err(Error::io(path, &e));
        }
    }
    Ok(())
}

/// Checks that `path` can take a file output: it is a regular file (symbolic links
/// followed) or does not exist yet, and its folder is there. A device, FIFO, socket or
/// folder is refused, naming the path, what it is and what was expected, so a command can
/// refuse its outputs before it works for them.
pub fn check_output_file(path: &Path) -> Result<(), Error> {
    let refused = |what: &str| {
        Error::format(format!(
            "is {what}; a file output must be a regular file or a path not there yet (left as it was)"
        ))
        .in_file(path)
    };
    match std::fs::metadata(path) {
        Ok(meta) if meta.is_file() => Ok(()),
        Ok(meta) if meta.is_dir() => Err(refused("a folder")),
        Ok(meta) => Err(refused(special_file_kind(&meta.file_type()))),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            let dir = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
            match std::fs::metadata(dir) {
                Ok(meta) if meta.is_dir() => Ok(()),
                Ok(_) => Err(Error::format("is not a folder; the file output's folder must be one").in_file(dir)),
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                    Err(Error::format(format!("no such folder to write {} into; make it first", path.display()))
                        .in_file(dir))
                }
                Err(e) => Err(Error::io(dir, &e)),
            }
        }
        Err(e) => Err(Error::io(path, &e)),
    }
}

/// What a file that is neither a regular file nor a folder is, in words.
fn special_file_kind(file_type: &std::fs::FileType) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if file_type.is_fifo() {
            return "a FIFO (named pipe)";
        }
        if file_type.is_socket() {
            return "a socket";
        }
        if file_type.is_char_device() {
            return "a character device";
        }
        if file_type.is_block_device() {
            return "a block device";
        }
    }
    let _ = file_type;
    "not a regular file"
}

/// Whether `file_name` is an atomic write's temporary file (this version's or an earlier one's).
pub fn is_temp_file_name(file_name: &str) -> bool {
    temp_file_writer(file_name).is_some()
}

/// The process id in a temporary file's name: `.NAME.camplace-tmp-PID`, or `.NAME.tmpPID` as
/// earlier versions named them. `None` for any other name.
pub(crate) fn temp_file_writer(file_name: &str) -> Option<u32> {
    let rest = file_name.strip_prefix('.')?;
    let digits = match rest.rfind(TEMP_MARK) {
        Some(i) => &rest[i + TEMP_MARK.len()..],
        None => &rest[rest.rfind(".tmp")? + ".tmp".len()..],
    };
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    digits.parse().ok()
}

/// The temporary name (in the same folder) a whole folder is written under by this
/// process before it is renamed to `path`: `.NAME.camplace-tmp-PID`, so readers skip it
/// and [`remove_stale_temp_files`] removes it once its writer is gone.
pub fn temp_path_for(path: &Path) -> PathBuf {
    let dir = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    dir.join(format!(".{name}{TEMP_MARK}{}", std::process::id()))
}

/// Removes, from `dir` itself (not its sub-folders), the temporary files (and folders) of atomic writes
/// whose writer is gone: a process that no longer runs, or one with this process's id (this
/// process has no write in flight when it opens a folder, so such a file is an earlier
/// process's whose id came round again). Call it before writing into the folder. Returns
/// what was removed; a missing folder has nothing to remove.
pub fn remove_stale_temp_files(dir: &Path) -> Result<Vec<PathBuf>, Error> {
    let entries = match std::fs::read_dir(dir) {
        Ok(entries) => entries,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(e) => return Err(Error::io(dir, &e)),
    };
    let proc_fs = Path::new("/proc/self").exists();
    let mut removed = Vec::new();
    for entry in entries {
        let entry = entry.map_err(|e| Error::io(dir, &e))?;
        let Some(pid) = temp_file_writer(&entry.file_name().to_string_lossy()) else { continue };
        let path = entry.path();
        // A folder so named is a whole-folder write's (a captured frame) in the making.
        let is_dir = entry.file_type().is_ok_and(|t| t.is_dir());
        let stale = if proc_fs {
            pid == std::process::id() || !Path::new("/proc").join(pid.to_string()).exists()
        } else {
            let modified = entry.metadata().and_then(|m| m.modified()).unwrap_or(SystemTime::now());
            modified.elapsed().unwrap_or_default() > STALE_WITHOUT_PROC
        };
        if stale {
            let removed_now = if is_dir { std::fs::remove_dir_all(&path) } else { std::fs::remove_file(&path) };
            match removed_now {
                Ok(()) => removed.push(path),
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
                Err(e) => return Err(Error::io(&path, &e)),
            }
        }
    }
    removed.sort();
    Ok(removed)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn temporary_names_are_recognised_and_nothing_else() {
        assert_eq!(temp_file_writer(".a.model.camplace-tmp-1234"), Some(1234));
        assert_eq!(temp_file_writer(".summary.json.tmp77"), Some(77));
        for other in ["a.model", ".a.model", ".a.tmp", ".a.tmpx1", "a.model.camplace-tmp-12", ".x.camplace-tmp-"] {
            assert_eq!(temp_file_writer(other), None, "{other}");
        }
    }

    #[test]
    #[cfg(target_os = "linux")]
    fn stale_temporary_files_go_and_live_ones_and_others_stay() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        write_atomic(&d.join("kept.json"), b"{}").unwrap();
        // No process has the largest id; process 1 always runs.
        let dead = d.join(format!(".big.model{TEMP_MARK}{}", u32::MAX));
        let legacy = d.join(format!(".old.model.tmp{}", u32::MAX));
        let mine = d.join(format!(".mine.model{TEMP_MARK}{}", std::process::id()));
        let live = d.join(format!(".live.model{TEMP_MARK}1"));
        for p in [&dead, &legacy, &mine, &live] {
            std::fs::write(p, b"partial").unwrap();
        }
        std::fs::write(d.join("notes.tmp1"), b"user's").unwrap();
        let removed = remove_stale_temp_files(d).unwrap();
        let mut want = vec![dead, legacy, mine];
        want.sort();
        assert_eq!(removed, want);
        let mut left: Vec<String> =
            std::fs::read_dir(d).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
        left.sort();
        assert_eq!(left, [format!(".live.model{TEMP_MARK}1"), "kept.json".into(), "notes.tmp1".into()]);
        assert!(remove_stale_temp_files(&d.join("missing")).unwrap().is_empty());
    }

    #[test]
    #[cfg(unix)]
    fn a_fifo_socket_or_folder_is_refused_and_left_as_it_was() {
        use std::os::unix::fs::FileTypeExt;
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let fifo = d.join("pipe");
        assert!(std::process::Command::new("mkfifo").arg(&fifo).status().unwrap().success());
        std::os::unix::fs::symlink(&fifo, d.join("link")).unwrap();
        let _socket = std::os::unix::net::UnixListener::bind(d.join("sock")).unwrap();
        std::fs::create_dir(d.join("folder")).unwrap();
        for (name, what) in [("pipe", "FIFO"), ("link", "FIFO"), ("sock", "socket"), ("folder", "a folder")] {
            let e = write_atomic(&d.join(name), b"x").unwrap_err().to_string();
            assert!(e.contains(name) && e.contains(what) && e.contains("regular file"), "{e}");
        }
        let kind = |n: &str| std::fs::symlink_metadata(d.join(n)).unwrap().file_type();
        assert!(
            kind("pipe").is_fifo() && kind("link").is_symlink() && kind("sock").is_socket() && kind("folder").is_dir()
        );
        let mut left: Vec<String> =
            std::fs::read_dir(d).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
        left.sort();
        assert_eq!(left, ["folder", "link", "pipe", "sock"], "no temporary file left");
    }

    #[test]
    fn several_files_are_written_all_or_none() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::write(d.join("a.model"), b"earlier").unwrap();
        let missing = d.join("no/such/dir/x.ply");
        let e = write_atomic_all(&[(&d.join("a.model"), b"new"), (&missing, b"cloud")]).unwrap_err().to_string();
        assert!(e.contains("no/such/dir") && e.contains("no such folder"), "{e}");
        assert_eq!(std::fs::read(d.join("a.model")).unwrap(), b"earlier");
        assert_eq!(std::fs::read_dir(d).unwrap().count(), 1, "nothing else written");
        write_atomic_all(&[(&d.join("a.model"), b"new"), (&d.join("x.ply"), b"cloud")]).unwrap();
        assert_eq!(std::fs::read(d.join("a.model")).unwrap(), b"new");
        assert_eq!(std::fs::read(d.join("x.ply")).unwrap(), b"cloud");
    }
}
