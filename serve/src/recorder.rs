//! The flight recorder: the frames of every trigger that ended `NO_POSE` or `REJECTED`, kept
//! as a recorded dataset (`rig.json`, the background reference, `frames/NNNN/`) that
//! `camplace replay` runs unchanged, under a disk quota: when its frames grow past it, the
//! oldest go first. Only the frames it wrote, named in its folder's `flight-recorder.json`,
//! are counted and deleted; a folder holding frames it did not write is refused.

use std::path::{Path, PathBuf};

use camplace_config::frame_name;
use camplace_hwio::{append_frame, write_background, Frames};
use serde::{Deserialize, Serialize};

use crate::{Error, ErrorKind, Result};

/// The file in the recorder's folder naming the frames it wrote, oldest first: the only
/// frames it counts against its quota and the only ones it ever deletes.
pub const RECORDED_FRAMES_FILE: &str = "flight-recorder.json";

/// The flight recorder's folder and quota.
#[derive(Debug, Clone, PartialEq)]
pub struct RecorderSettings {
    /// The dataset folder frames are added to (made when missing).
    pub dir: PathBuf,
    /// Most bytes the recorder's own files (its frames, `rig.json`, the background and
    /// its list of frames) may take.
    pub quota_bytes: u64,
}

/// [`RECORDED_FRAMES_FILE`]'s contents.
#[derive(Debug, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct RecordedFrames {
    /// Folder names under `frames/`, oldest first.
    frames: Vec<String>,
}

pub(crate) struct FlightRecorder {
    settings: RecorderSettings,
    rig: PathBuf,
    background: Option<Frames>,
    /// The frames this recorder (this run or an earlier one) wrote, oldest first.
    own: Vec<String>,
}

impl FlightRecorder {
    /// A recorder writing frames of the rig in `rig` (copied as the dataset's `rig.json`)
    /// with `background` as its reference; checks the folder can be made and holds no
    /// frames but the ones an earlier recorder in it wrote.
    pub(crate) fn new(settings: RecorderSettings, rig: &Path, background: Option<Frames>) -> Result<FlightRecorder> {
        let dir = settings.dir.clone();
        let refused = |what: String| Error::new(ErrorKind::Recorder, format!("--record {}: {what}", dir.display()));
        std::fs::create_dir_all(&dir).map_err(|e| refused(format!("cannot make the folder: {e}")))?;
        let list = dir.join(RECORDED_FRAMES_FILE);
        let mut own = match std::fs::read_to_string(&list) {
            Ok(text) => {
                let recorded: RecordedFrames = serde_json::from_str(&text).map_err(|e| {
                    refused(format!(
                        "{RECORDED_FRAMES_FILE}: frames: expected the list of frames this recorder wrote: {e}"
                    ))
                })?;
                recorded.frames
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Vec::new(),
            Err(e) => return Err(refused(format!("{RECORDED_FRAMES_FILE}: cannot read: {e}"))),
        };
        let present = numbered_frames(&dir).map_err(|e| refused(format!("frames: cannot list: {e}")))?;
        let foreign: Vec<&String> = present.iter().filter(|name| !own.contains(name)).collect();
        if let (Some(first), Some(last)) = (foreign.first(), foreign.last()) {
            let span = if first == last { format!("frames/{first}") } else { format!("frames/{first} … {last}") };
            return Err(refused(format!(
                "holds frames the flight recorder did not write ({span}, {} in all; it counts and deletes only the ones \
                 {RECORDED_FRAMES_FILE} names): expected a folder of its own, new or recorded into before",
                foreign.len()
            )));
        }
        // A name whose folder is gone: deleted by the quota, or listed just before a kill
        // stopped its frame being written.
        let listed = own.len();
        own.retain(|name| present.contains(name));
        let recorder = FlightRecorder { settings, rig: rig.to_path_buf(), background, own };
        if recorder.own.len() != listed {
            recorder.save_list().map_err(|e| refused(e.to_string()))?;
        }
        Ok(recorder)
    }

    /// Keeps `frames` as the dataset's next frame, then drops its oldest frames until its
    /// own files fit the quota; returns the new frame's folder, or `None` when the quota
    /// cannot hold even it.
    pub(crate) fn keep(&mut self, frames: &Frames) -> Result<Option<PathBuf>> {
        let dir = self.settings.dir.clone();
        let failed = |e: &dyn std::fmt::Display| {
            Error::new(ErrorKind::Recorder, format!("--record {}: cannot keep the frame: {e}", dir.display()))
        };
        if let Some(bg) = &self.background {
            if !dir.join("background").exists() {
                write_background(&dir, bg, Some(&self.rig)).map_err(|e| failed(&e))?;
            }
        }
        // Listed before it is written, so a kill in between never leaves a frame of its own
        // it does not know (a listed name without its folder is dropped at the next start).
        let next = self.own.iter().filter_map(|n| n.parse::<u64>().ok()).max().map_or(0, |n| n + 1);
        self.own.push(frame_name(next));
        self.save_list().map_err(|e| failed(&e))?;
        let written = match append_frame(&dir, frames, Some(&self.rig)) {
            Ok(written) => written,
            Err(e) => {
                // Not written (a full disk, most likely): the name is no frame of its own, and
                // the next frame takes it. A list that cannot be saved now lists a name whose
                // folder is missing, which the quota and the next start pass over.
                self.own.pop();
                let _ = self.save_list();
                return Err(failed(&e));
            }
        };
        let written_name = written.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        if self.own.last() != Some(&written_name) {
            self.own.pop();
            self.own.retain(|n| n != &written_name);
            self.own.push(written_name);
            self.save_list().map_err(|e| failed(&e))?;
        }
        self.enforce_quota().map_err(|e| failed(&e))?;
        Ok(written.exists().then_some(written))
    }

    /// Removes the recorder's oldest frames while its own files take more than the quota.
    fn enforce_quota(&mut self) -> std::io::Result<()> {
        let dir = self.settings.dir.clone();
        let frames = dir.join("frames");
        let mut sizes = Vec::with_capacity(self.own.len());
        // A folder already gone (removed by hand while serving) weighs nothing and is dropped.
        let gone_is_nothing = |r: std::io::Result<u64>| match r {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(0),
            other => other,
        };
        for name in &self.own {
            sizes.push(gone_is_nothing(size_of(&frames.join(name)))?);
        }
        let mut total: u64 = sizes.iter().sum();
        for kept in ["rig.json", "background", RECORDED_FRAMES_FILE] {
            total += gone_is_nothing(size_of(&dir.join(kept)))?;
        }
        let mut removed = 0;
        while total > self.settings.quota_bytes && removed < self.own.len() {
            match std::fs::remove_dir_all(frames.join(&self.own[removed])) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => return Err(e),
                _ => {}
            }
            total = total.saturating_sub(sizes[removed]);
            removed += 1;
        }
        if removed > 0 {
            self.own.drain(..removed);
            self.save_list().map_err(|e| std::io::Error::other(e.to_string()))?;
        }
        Ok(())
    }

    /// Writes the list of the recorder's frames (whole, through a temporary file).
    fn save_list(&self) -> std::result::Result<(), camplace_config::Error> {
        let text = serde_json::to_string_pretty(&RecordedFrames { frames: self.own.clone() })
            .expect("a list of names is plain data");
        camplace_config::write_atomic(&self.settings.dir.join(RECORDED_FRAMES_FILE), format!("{text}\n").as_bytes())
    }
}

/// The numbered frame folders under `dir/frames/` (none when it has no `frames/`), sorted.
fn numbered_frames(dir: &Path) -> std::io::Result<Vec<String>> {
    let mut names = Vec::new();
    let entries = match std::fs::read_dir(dir.join("frames")) {
        Ok(entries) => entries,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(names),
        Err(e) => return Err(e),
    };
    for entry in entries {
        let entry = entry?;
        let name = entry.file_name().to_string_lossy().into_owned();
        if !name.is_empty() && name.bytes().all(|b| b.is_ascii_digit()) && entry.file_type()?.is_dir() {
            names.push(name);
        }
    }
    names.sort();
    Ok(names)
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
    fn a_frame_removed_by_hand_while_recording_leaves_the_quota_kept() {
        let dir = tempfile::tempdir().unwrap();
        let rig = rig(dir.path());
        let kept = dir.path().join("kept");
        let mut probe =
            FlightRecorder::new(RecorderSettings { dir: kept.clone(), quota_bytes: u64::MAX }, &rig, Some(frames(200)))
                .unwrap();
        probe.keep(&frames(0)).unwrap().unwrap();
        let one_frame = size_of(&kept.join("frames/0000")).unwrap();
        let quota = size_of(&kept).unwrap() + one_frame + one_frame / 2;
        let mut recorder =
            FlightRecorder::new(RecorderSettings { dir: kept.clone(), quota_bytes: quota }, &rig, Some(frames(200)))
                .unwrap();
        recorder.keep(&frames(1)).unwrap().unwrap();
        std::fs::remove_dir_all(kept.join("frames/0000")).unwrap();
        for k in 2..6 {
            recorder.keep(&frames(k)).unwrap_or_else(|e| panic!("frame {k}: {e}")).unwrap();
        }
        let mut left: Vec<String> = numbered_frames(&kept).unwrap();
        left.sort();
        assert_eq!(left, ["0004", "0005"], "the newest two fit the quota");
        assert_eq!(recorder.own, left, "the list names the frames on disk");
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

    /// Every file under `root` with its bytes.
    fn snapshot(root: &Path) -> std::collections::BTreeMap<PathBuf, Vec<u8>> {
        let mut out = std::collections::BTreeMap::new();
        let mut stack = vec![root.to_path_buf()];
        while let Some(dir) = stack.pop() {
            for e in std::fs::read_dir(&dir).unwrap().flatten() {
                let p = e.path();
                if p.is_dir() {
                    stack.push(p);
                } else {
                    out.insert(p.strip_prefix(root).unwrap().to_path_buf(), std::fs::read(&p).unwrap());
                }
            }
        }
        out
    }

    #[test]
    fn frames_the_recorder_did_not_write_are_never_deleted_nor_counted() {
        let dir = tempfile::tempdir().unwrap();
        let rig = rig(dir.path());
        // A recorded dataset of five frames, as capture writes one.
        let dataset = dir.path().join("dataset");
        write_background(&dataset, &frames(200), Some(&rig)).unwrap();
        for k in 0..5 {
            append_frame(&dataset, &frames(k), Some(&rig)).unwrap();
        }
        let before = snapshot(&dataset);
        let one_frame = size_of(&dataset.join("frames/0000")).unwrap();
        let settings = RecorderSettings { dir: dataset.clone(), quota_bytes: 2 * one_frame };
        match FlightRecorder::new(settings, &rig, Some(frames(200))) {
            Err(e) => {
                let said = e.to_string();
                assert!(said.contains("dataset") && said.contains("0000") && said.contains("did not write"), "{said}");
            }
            Ok(mut recorder) => {
                for k in 10..14 {
                    let _ = recorder.keep(&frames(k));
                }
            }
        }
        let after = snapshot(&dataset);
        let lost: Vec<_> = before.keys().filter(|k| after.get(*k) != before.get(*k)).collect();
        assert!(lost.is_empty(), "the dataset's own files changed or went: {lost:?}");
        assert_eq!(after.len(), before.len(), "nothing added to a dataset the recorder did not make");
    }

    #[test]
    fn a_restarted_recorder_counts_its_earlier_frames_and_only_those() {
        let dir = tempfile::tempdir().unwrap();
        let rig = rig(dir.path());
        let kept = dir.path().join("kept");
        let mut first =
            FlightRecorder::new(RecorderSettings { dir: kept.clone(), quota_bytes: u64::MAX }, &rig, Some(frames(200)))
                .unwrap();
        for k in 0..3 {
            first.keep(&frames(k)).unwrap().unwrap();
        }
        drop(first);
        // A file of the user's in the folder is neither counted against the quota nor removed.
        let notes = vec![7u8; 1 << 20];
        std::fs::write(kept.join("notes.bin"), &notes).unwrap();
        let one_frame = size_of(&kept.join("frames/0000")).unwrap();
        let base = size_of(&kept).unwrap() - notes.len() as u64 - 3 * one_frame;
        let quota = base + 2 * one_frame + one_frame / 2;
        let mut second =
            FlightRecorder::new(RecorderSettings { dir: kept.clone(), quota_bytes: quota }, &rig, Some(frames(200)))
                .unwrap();
        second.keep(&frames(3)).unwrap().unwrap();
        let mut left: Vec<String> = std::fs::read_dir(kept.join("frames"))
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        left.sort();
        assert_eq!(left, ["0002", "0003"], "the earlier run's oldest frames went first, two fit");
        assert_eq!(std::fs::read(kept.join("notes.bin")).unwrap(), notes);
    }
}
