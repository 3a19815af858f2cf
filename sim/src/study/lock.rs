//! A study folder's lock: while a command works in a folder, `study.lock` in it names the
//! process (pid, host, start time), and a second command on the folder is refused naming
//! it, so two runs never compute the same scenes twice nor write the summaries over each
//! other. A lock whose process has died (killed, the machine restarted) is taken over, and
//! the run resumes. Within one process the lock is shared: a study locks its folder and
//! each folder it opens inside.

use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use serde::{Deserialize, Serialize};

use crate::{Error, Result};

/// The lock file's name in a study folder.
pub const LOCK_FILE: &str = "study.lock";

/// The process a lock names.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Holder {
    pid: u32,
    host: String,
    /// When the lock was taken, seconds since 1970 (UTC).
    started_unix_s: u64,
    /// The process's start in clock ticks since boot (`/proc/PID/stat`), so a pid used
    /// again by another process after a restart is not taken for the holder.
    process_start_ticks: Option<u64>,
}

impl Holder {
    fn me() -> Holder {
        let pid = std::process::id();
        Holder {
            pid,
            host: host_name(),
            started_unix_s: std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0, |d| d.as_secs()),
            process_start_ticks: process_start_ticks(pid),
        }
    }

    /// Whether the holder may still run: always on another host (it cannot be told from
    /// here), else when its pid is alive with the start it recorded.
    fn may_be_alive(&self) -> bool {
        if self.host != host_name() {
            return true;
        }
        match (process_start_ticks(self.pid), self.process_start_ticks) {
            (None, _) => !Path::new("/proc/self").exists() && self.pid == std::process::id(),
            (Some(now), Some(then)) => now == then,
            (Some(_), None) => true,
        }
    }

    fn describe(&self) -> String {
        format!("pid {} on host {}, since {}", self.pid, self.host, utc(self.started_unix_s))
    }
}

/// The folders this process holds, with how many holds each.
static HELD: Mutex<BTreeMap<PathBuf, usize>> = Mutex::new(BTreeMap::new());

/// A held study folder; the lock file is removed when the last hold of it ends.
#[derive(Debug)]
#[must_use = "the folder is unlocked when this is dropped"]
pub struct FolderLock {
    dir: PathBuf,
}

/// Locks study folder `dir` (created if missing) for this process: refused naming the
/// holder when another live process holds it, taken over from a dead one.
pub fn lock_folder(dir: &Path) -> Result<FolderLock> {
    std::fs::create_dir_all(dir)
        .map_err(|e| Error::Other(format!("{}: cannot create the folder: {e}", dir.display())))?;
    let key = dir.canonicalize().map_err(|e| Error::Other(format!("{}: cannot resolve: {e}", dir.display())))?;
    let mut held = HELD.lock().unwrap_or_else(|p| p.into_inner());
    if let Some(n) = held.get_mut(&key) {
        *n += 1;
        return Ok(FolderLock { dir: key });
    }
    let path = key.join(LOCK_FILE);
    let me = Holder::me();
    let text = serde_json::to_string(&me).expect("plain data") + "\n";
    let cannot = |e: std::io::Error| Error::Other(format!("{}: cannot write the lock: {e}", path.display()));
    match std::fs::OpenOptions::new().write(true).create_new(true).open(&path) {
        Ok(mut f) => f.write_all(text.as_bytes()).and_then(|()| f.sync_all()).map_err(cannot)?,
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
            match read_holder(&path) {
                Some(h) if h.may_be_alive() => {
                    return Err(Error::Other(format!(
                        "{}: the folder is in use by another camplace run ({}); wait for it to end, or remove the lock if that process is gone",
                        path.display(),
                        h.describe()
                    )))
                }
                Some(_) => {}
                None if recently_written(&path) => {
                    return Err(Error::Other(format!(
                        "{}: another camplace run is taking the folder; try again in a moment",
                        path.display()
                    )))
                }
                None => {}
            }
            // The holder is gone: take the lock over (a whole-file replace), then make
            // sure no other run took it over at the same moment.
            camplace_config::write_atomic(&path, text.as_bytes())?;
            match read_holder(&path) {
                Some(h) if h == me => {}
                Some(h) => {
                    return Err(Error::Other(format!(
                        "{}: the folder is in use by another camplace run ({})",
                        path.display(),
                        h.describe()
                    )))
                }
                None => return Err(Error::Other(format!("{}: cannot take the lock over", path.display()))),
            }
        }
        Err(e) => return Err(cannot(e)),
    }
    held.insert(key.clone(), 1);
    Ok(FolderLock { dir: key })
}

impl Drop for FolderLock {
    fn drop(&mut self) {
        let mut held = HELD.lock().unwrap_or_else(|p| p.into_inner());
        let Some(n) = held.get_mut(&self.dir) else { return };
        *n -= 1;
        if *n > 0 {
            return;
        }
        held.remove(&self.dir);
        let path = self.dir.join(LOCK_FILE);
        // Only our own lock: one taken over from us is the new holder's.
        if read_holder(&path).is_some_and(|h| h.pid == std::process::id() && h.host == host_name()) {
            let _ = std::fs::remove_file(&path);
        }
    }
}

fn read_holder(path: &Path) -> Option<Holder> {
    let text = camplace_config::read_text(path).ok()?;
    serde_json::from_str(&text).ok()
}

/// A lock file that cannot be read yet may be half written by a run that just took it.
fn recently_written(path: &Path) -> bool {
    std::fs::metadata(path)
        .and_then(|m| m.modified())
        .ok()
        .and_then(|t| t.elapsed().ok())
        .is_some_and(|age| age.as_secs() < 5)
}

fn host_name() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .ok()
        .or_else(|| std::env::var("HOSTNAME").ok())
        .map(|s| s.trim().to_string())
        .filter(|s| !s.is_empty())
        .unwrap_or_else(|| "unknown".to_string())
}

/// Field 22 of `/proc/PID/stat`, the process's start in clock ticks since boot, if the
/// process still runs: a zombie (killed, not yet reaped by its parent) or a dead one has
/// none, so a `kill -9`ed run's lock is taken over at once.
fn process_start_ticks(pid: u32) -> Option<u64> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // The command name (field 2) may hold spaces and parentheses: count from its end.
    let mut fields = stat[stat.rfind(')')? + 1..].split_whitespace();
    if matches!(fields.next()?, "Z" | "X" | "x") {
        return None;
    }
    fields.nth(18)?.parse().ok()
}

/// Seconds since 1970 as `YYYY-MM-DD HH:MM:SS UTC`.
fn utc(secs: u64) -> String {
    let (days, rest) = ((secs / 86_400) as i64, secs % 86_400);
    // Days to a civil date (Howard Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!("{year:04}-{month:02}-{day:02} {:02}:{:02}:{:02} UTC", rest / 3600, rest % 3600 / 60, rest % 60)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dates_are_civil() {
        assert_eq!(utc(0), "1970-01-01 00:00:00 UTC");
        assert_eq!(utc(951_782_400), "2000-02-29 00:00:00 UTC");
        assert_eq!(utc(1_796_425_853), "2026-12-04 23:10:53 UTC");
    }

    #[test]
    fn held_twice_in_one_process_and_released_with_the_last_hold() {
        let dir = tempfile::tempdir().unwrap();
        let a = lock_folder(dir.path()).unwrap();
        let b = lock_folder(dir.path()).unwrap();
        assert!(dir.path().join(LOCK_FILE).exists());
        drop(a);
        assert!(dir.path().join(LOCK_FILE).exists());
        drop(b);
        assert!(!dir.path().join(LOCK_FILE).exists());
    }

    #[test]
    fn a_live_holder_is_named_and_a_dead_one_taken_over() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(LOCK_FILE);
        // A live process of this host: pid 1, as recorded now.
        let live = Holder { pid: 1, host: host_name(), started_unix_s: 0, process_start_ticks: process_start_ticks(1) };
        std::fs::write(&path, serde_json::to_string(&live).unwrap()).unwrap();
        if live.process_start_ticks.is_some() {
            let e = lock_folder(dir.path()).unwrap_err().to_string();
            assert!(e.contains("pid 1 on host") && e.contains("study.lock"), "{e}");
        }
        // The same pid with another start: a process long gone whose pid was used again.
        let dead = Holder { process_start_ticks: Some(u64::MAX), ..live };
        std::fs::write(&path, serde_json::to_string(&dead).unwrap()).unwrap();
        let lock = lock_folder(dir.path()).unwrap();
        assert_eq!(read_holder(&path).unwrap().pid, std::process::id());
        drop(lock);
        assert!(!path.exists());
    }

    #[test]
    fn a_killed_holder_not_yet_reaped_is_dead() {
        let Ok(mut child) = std::process::Command::new("sleep").arg("30").spawn() else { return };
        let pid = child.id();
        assert!(process_start_ticks(pid).is_some(), "a running process has its start");
        child.kill().unwrap();
        // Killed but not waited for: a zombie once the kernel has ended it.
        let state = || std::fs::read_to_string(format!("/proc/{pid}/stat")).unwrap_or_default();
        for _ in 0..500 {
            if state().rsplit(')').next().is_some_and(|rest| rest.trim_start().starts_with('Z')) {
                break;
            }
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
        assert!(state().contains(") Z"), "the child became a zombie: {}", state());
        assert_eq!(process_start_ticks(pid), None, "a zombie holds no lock");
        child.wait().unwrap();
    }
}
