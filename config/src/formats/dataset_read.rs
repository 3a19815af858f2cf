//! Reading a recorded dataset folder (docs/design/interchange-formats.md): `rig.json`, an optional
//! `background/`, and `frames/NNNN/` with `left.png` + `right.png` (one shot) or
//! `left_00.png` ... `right_11.png` (N shots), each frame with an optional `truth.json`.
//! Simulated and real recordings take this one path: hwio streams it as a frame source, the
//! simulator's sensor fit reads it, replay scores it.

use std::path::{Path, PathBuf};
use std::time::UNIX_EPOCH;

use super::dataset::image_name;
use super::frames::{FrameInfo, Frames};
use super::png::read_gray;
use crate::{Error, ErrorKind, GrayImage, RigFile};

type Result<T> = std::result::Result<T, Error>;

/// Most shots per side a recording may have; phase-12 uses 12.
const MAX_SHOTS: usize = 64;

/// A recorded dataset folder, its frames read by number in folder-name order.
#[derive(Debug, Clone)]
pub struct RecordedDataset {
    dir: PathBuf,
    rig: RigFile,
    shots: usize,
    frame_dirs: Vec<PathBuf>,
}

impl RecordedDataset {
    /// Opens `dir`: reads `rig.json`, lists `frames/`, detects the shots from the first
    /// frame and checks its images agree in size with each other and with the rig.
    pub fn open(dir: &Path) -> Result<RecordedDataset> {
        if !dir.is_dir() {
            return Err(Error::new(ErrorKind::Io, "", "expected a recorded dataset folder (rig.json, frames/NNNN/)")
                .in_file(dir));
        }
        let rig = RigFile::load(&dir.join("rig.json"))?;
        let frames_dir = dir.join("frames");
        let entries = std::fs::read_dir(&frames_dir).map_err(|e| Error::io(&frames_dir, &e))?;
        let mut named = Vec::new();
        for entry in entries {
            let entry = entry.map_err(|e| Error::io(&frames_dir, &e))?;
            // A name starting with '.' is a frame still being written (or left by a kill).
            if entry.path().is_dir() && !entry.file_name().to_string_lossy().starts_with('.') {
                named.push((entry.file_name().to_string_lossy().into_owned(), entry.path()));
            }
        }
        // Numeric names sort as numbers, so 10000 comes after 9999 even without padding.
        named.sort_by(|(a, _), (b, _)| (a.parse::<u64>().ok(), a).cmp(&(b.parse::<u64>().ok(), b)));
        let frame_dirs: Vec<PathBuf> = named.into_iter().map(|(_, p)| p).collect();
        let Some(first) = frame_dirs.first() else {
            return Err(Error::format("expected at least one frame folder (frames/0000/)").in_file(&frames_dir));
        };
        let shots = detect_shots(first)?;
        let source = RecordedDataset { dir: dir.to_path_buf(), rig, shots, frame_dirs };
        let mut frames = Frames::new(shots);
        source.read_into(0, &mut frames)?;
        Ok(source)
    }

    /// The dataset folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The calibration in the folder's `rig.json`.
    pub fn rig(&self) -> &RigFile {
        &self.rig
    }

    /// Images per side in every frame (1 for one shot, 12 for phase-12).
    pub fn shots(&self) -> usize {
        self.shots
    }

    /// The frame folders, in number order.
    pub fn frame_dirs(&self) -> &[PathBuf] {
        &self.frame_dirs
    }

    /// The `truth.json` of frame `i`, when the recording has one.
    pub fn truth_path(&self, i: usize) -> Option<PathBuf> {
        let p = self.frame_dirs.get(i)?.join("truth.json");
        p.is_file().then_some(p)
    }

    /// Fills `frames` with the images of `background/`; `Ok(false)` when the recording
    /// has no background.
    pub fn background(&self, frames: &mut Frames) -> Result<bool> {
        let dir = self.dir.join("background");
        if !dir.is_dir() {
            return Ok(false);
        }
        self.read_folder(&dir, frames)?;
        Ok(true)
    }

    /// Reads frame `i` into `frames`.
    pub fn read_into(&self, i: usize, frames: &mut Frames) -> Result<FrameInfo> {
        let dir = self.frame_dirs.get(i).ok_or_else(|| {
            Error::format(format!("no frame {i} (it has {})", self.frame_dirs.len())).in_file(&self.dir)
        })?;
        let timestamp_us = self.read_folder(dir, frames)?;
        let name = dir.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        Ok(FrameInfo { index: i as u64, name, timestamp_us })
    }

    /// Reads the shots of one folder into `frames` and checks every size; returns the
    /// left image's modification time in microseconds (0 when the file system has none).
    fn read_folder(&self, dir: &Path, frames: &mut Frames) -> Result<u64> {
        read_shots(dir, &self.rig, self.shots, frames)
    }
}

/// The images of a folder named as a frame's (`shots` per side, e.g. the empty cell's
/// background), each checked to be the size `rig` says.
pub fn read_background(dir: &Path, rig: &RigFile, shots: usize) -> Result<Frames> {
    let mut frames = Frames::new(shots);
    read_shots(dir, rig, shots, &mut frames)?;
    Ok(frames)
}

/// Reads `shots` images per side from `dir` into `frames`, checking each is the size `rig`
/// says; returns the left image's modification time in microseconds (0 when the file system
/// has none).
fn read_shots(dir: &Path, rig: &RigFile, shots: usize, frames: &mut Frames) -> Result<u64> {
    frames.set_shots(shots);
    let want = [
        ("left", (rig.left.width as usize, rig.left.height as usize)),
        ("right", (rig.right.width as usize, rig.right.height as usize)),
    ];
    let mut timestamp_us = 0;
    for shot in 0..shots {
        for (side, (w, h)) in want {
            let path = dir.join(image_name(side, shot, shots));
            if !path.is_file() {
                return Err(Error::format(format!("missing {side} image (expected {w}x{h} 8-bit PNG)")).in_file(&path));
            }
            let img = read_gray(&path)?;
            if (img.width, img.height) != (w, h) {
                return Err(Error::format(format!(
                    "image is {}x{}, expected {w}x{h} as rig.json says for the {side} camera",
                    img.width, img.height
                ))
                .in_file(&path));
            }
            let out = if side == "left" { &mut frames.left[shot] } else { &mut frames.right[shot] };
            copy_into(&img.data, w, h, out);
            if shot == 0 && side == "left" {
                timestamp_us = modified_us(&path);
            }
        }
    }
    Ok(timestamp_us)
}

/// One shot when `left.png` is there, else as many as consecutive `left_NN.png` from 00.
pub(crate) fn detect_shots(dir: &Path) -> Result<usize> {
    if dir.join("left.png").is_file() {
        return Ok(1);
    }
    let shots = (0..MAX_SHOTS).take_while(|&i| dir.join(image_name("left", i, 2)).is_file()).count();
    if shots == 0 {
        return Err(Error::format("expected left.png + right.png or left_00.png ... right_11.png").in_file(dir));
    }
    Ok(shots)
}

fn copy_into(data: &[u8], width: usize, height: usize, out: &mut GrayImage) {
    out.width = width;
    out.height = height;
    out.data.clear();
    out.data.extend_from_slice(data);
}

fn modified_us(path: &Path) -> u64 {
    std::fs::metadata(path)
        .and_then(|m| m.modified())
        .ok()
        .and_then(|t| t.duration_since(UNIX_EPOCH).ok())
        .map_or(0, |d| d.as_micros() as u64)
}

/// The `truth.json` of the frame called `name` in dataset `dir`, when it has one.
pub fn truth_path(dir: &Path, name: &str) -> Option<PathBuf> {
    let p = dir.join("frames").join(name).join("truth.json");
    p.is_file().then_some(p)
}
