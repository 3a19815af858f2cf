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

#[cfg(test)]
mod tests {
    use super::*;
    use camplace_config::{CameraFile, GrayImage, RigFile};

    /// A rig.json of two 64 × 48 cameras.
    fn rig(dir: &Path) -> PathBuf {
        let camera = |x: f64| CameraFile {
            width: 64,
            height: 48,
            k: [[60.0, 0.0, 31.5], [0.0, 60.0, 23.5], [0.0, 0.0, 1.0]],
            dist: [0.0; 5],
            t_world_camera: [[1.0, 0.0, 0.0, x], [0.0, -1.0, 0.0, 0.0], [0.0, 0.0, -1.0, 600.0], [0.0, 0.0, 0.0, 1.0]],
        };
        let file = RigFile { left: camera(0.0), right: camera(80.0), projector: None, rectified: None };
        let path = dir.join("rig.json");
        std::fs::write(&path, serde_json::to_string(&file).unwrap()).unwrap();
        path
    }

    /// Frames whose pixels vary (so the PNGs do not compress to nothing), seeded by `k`.
    fn frames(k: u8) -> Frames {
        let image = |side: u8| {
            let data =
                (0..64 * 48).map(|i: usize| (i as u8).wrapping_mul(31).wrapping_add(k).wrapping_add(side)).collect();
            GrayImage { width: 64, height: 48, data }
        };
        Frames { left: vec![image(0)], right: vec![image(1)] }
    }

    #[test]
    fn the_oldest_frames_go_when_the_quota_is_reached() {
        let dir = tempfile::tempdir().unwrap();
        let rig = rig(dir.path());
        let kept = dir.path().join("kept");
        let mut big =
            FlightRecorder::new(RecorderSettings { dir: kept.clone(), quota_bytes: u64::MAX }, &rig, Some(frames(200)))
                .unwrap();
        big.keep(&frames(0)).unwrap().unwrap();
        let one_frame = size_of(&kept.join("frames/0000")).unwrap();
        let base = size_of(&kept).unwrap() - one_frame;
        // Room for the rig, the background and three frames (and a little less than four).
        let quota = base + 3 * one_frame + one_frame / 2;
        let mut recorder =
            FlightRecorder::new(RecorderSettings { dir: kept.clone(), quota_bytes: quota }, &rig, Some(frames(200)))
                .unwrap();
        for k in 1..8 {
            recorder.keep(&frames(k)).unwrap();
            assert!(size_of(&kept).unwrap() <= quota, "frame {k}: {} > {quota}", size_of(&kept).unwrap());
        }
        let mut left: Vec<String> = std::fs::read_dir(kept.join("frames"))
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        left.sort();
        assert_eq!(left, ["0005", "0006", "0007"], "the newest three stay");
        assert!(kept.join("background").is_dir() && kept.join("rig.json").is_file());
    }
}
