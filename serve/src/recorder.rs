//! The flight recorder: the frames of every trigger that ended `NO_POSE` or `REJECTED`, kept
//! as a recorded dataset (`rig.json`, the background reference, `frames/NNNN/`) that
//! `camplace replay` runs unchanged, under a disk quota: when the folder grows past it, the
//! oldest frames go first.

use std::path::{Path, PathBuf};

use camplace_hwio::{append_frame, write_background, Frames};

use crate::{Error, ErrorKind, Result};

/// The flight recorder's folder and quota.
#[derive(Debug, Clone, PartialEq)]
pub struct RecorderSettings {
    /// The dataset folder frames are added to (made when missing).
    pub dir: PathBuf,
    /// Most bytes the folder may hold.
    pub quota_bytes: u64,
}

pub(crate) struct FlightRecorder {
    settings: RecorderSettings,
    rig: PathBuf,
    background: Option<Frames>,
}

impl FlightRecorder {
    /// A recorder writing frames of the rig in `rig` (copied as the dataset's `rig.json`)
    /// with `background` as its reference; checks the folder can be made.
    pub(crate) fn new(settings: RecorderSettings, rig: &Path, background: Option<Frames>) -> Result<FlightRecorder> {
        std::fs::create_dir_all(&settings.dir).map_err(|e| {
            Error::new(ErrorKind::Recorder, format!("--record {}: cannot make the folder: {e}", settings.dir.display()))
        })?;
        Ok(FlightRecorder { settings, rig: rig.to_path_buf(), background })
    }

    /// Keeps `frames` as the dataset's next frame, then drops the oldest frames until the
    /// folder fits its quota; returns the new frame's folder, or `None` when the quota
    /// cannot hold even it.
    pub(crate) fn keep(&mut self, frames: &Frames) -> Result<Option<PathBuf>> {
        let dir = &self.settings.dir;
        let failed = |e: &dyn std::fmt::Display| {
            Error::new(ErrorKind::Recorder, format!("--record {}: cannot keep the frame: {e}", dir.display()))
        };
        if let Some(bg) = &self.background {
            if !dir.join("background").exists() {
                write_background(dir, bg, Some(&self.rig)).map_err(|e| failed(&e))?;
            }
        }
        let written = append_frame(dir, frames, Some(&self.rig)).map_err(|e| failed(&e))?;
        self.enforce_quota().map_err(|e| failed(&e))?;
        Ok(written.exists().then_some(written))
    }

    /// Removes the oldest frames while the folder is larger than the quota.
    fn enforce_quota(&self) -> std::io::Result<()> {
        let dir = &self.settings.dir;
        let mut frames: Vec<(u64, PathBuf, u64)> = Vec::new();
        for entry in std::fs::read_dir(dir.join("frames"))? {
            let entry = entry?;
            let name = entry.file_name().to_string_lossy().into_owned();
            if let Ok(n) = name.parse::<u64>() {
                frames.push((n, entry.path(), size_of(&entry.path())?));
            }
        }
        frames.sort();
        let mut total: u64 = size_of(dir)?;
        for (_, path, size) in &frames {
            if total <= self.settings.quota_bytes {
                break;
            }
            std::fs::remove_dir_all(path)?;
            total = total.saturating_sub(*size);
        }
        Ok(())
    }
}

/// Bytes of the files under `path` (a file's own size for a file).
pub(crate) fn size_of(path: &Path) -> std::io::Result<u64> {
    let meta = std::fs::symlink_metadata(path)?;
    if !meta.is_dir() {
        return Ok(meta.len());
    }
    let mut total = 0;
    for entry in std::fs::read_dir(path)? {
        total += size_of(&entry?.path())?;
    }
    Ok(total)
}
