//! Writing a recorded dataset (docs/design/interchange-formats.md): a frame appended whole as the next
//! `frames/NNNN/`, the empty cell's `background/`, the calibration's `table/` view, each
//! checked against the dataset's rig and earlier frames first, and the camera images of one
//! folder. `capture`, `serve`'s flight recorder, `project` and the simulator's
//! `render --dataset` all write through here.

use std::path::{Path, PathBuf};

use super::dataset::{frame_name, image_name};
use super::dataset_read::detect_shots;
use super::frames::Frames;
use crate::{Error, GrayImage, RigFile};

type Result<T> = std::result::Result<T, Error>;

/// The largest frame number a dataset takes: frames are numbered on, never wrapped round.
pub const MAX_FRAME_NUMBER: u64 = 99_999_999;

/// Writes `frames` as the next frame of the dataset `root` (`frames/NNNN/`, one past the
/// highest number there) and returns its folder; with `rig`, copies that calibration to the
/// dataset's `rig.json` when it has none yet. The frame is written into a temporary folder
/// and renamed whole, so a kill leaves no half frame; a frame that does not match the
/// dataset (its rig, its frames' shot count and image size) and a number past
/// [`MAX_FRAME_NUMBER`] are refused before anything is written.
pub fn append_frame(root: &Path, frames: &Frames, rig: Option<&Path>) -> Result<PathBuf> {
    let all = root.join("frames");
    let mut highest: Option<(u64, PathBuf)> = None;
    match std::fs::read_dir(&all) {
        Ok(entries) => {
            for entry in entries {
                let entry = entry.map_err(|e| Error::io(&all, &e))?;
                let name = entry.file_name().to_string_lossy().into_owned();
                if name.starts_with('.') || !entry.path().is_dir() {
                    continue;
                }
                if !name.is_empty() && name.bytes().all(|b| b.is_ascii_digit()) {
                    let n = name.parse::<u64>().ok().filter(|&n| n <= MAX_FRAME_NUMBER).ok_or_else(|| {
                        Error::format(format!(
                            "a frame number past {MAX_FRAME_NUMBER}, the largest a dataset takes; start a new dataset"
                        ))
                        .in_file(&entry.path())
                    })?;
                    if highest.as_ref().is_none_or(|(h, _)| n > *h) {
                        highest = Some((n, entry.path()));
                    }
                }
            }
        }
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
        Err(e) => return Err(Error::io(&all, &e)),
    }
    let next = match &highest {
        None => 0,
        Some((n, path)) => n.checked_add(1).filter(|&n| n <= MAX_FRAME_NUMBER).ok_or_else(|| {
            Error::format(format!("frame {n} is the last a dataset takes ({MAX_FRAME_NUMBER}); start a new dataset"))
                .in_file(path)
        })?,
    };
    check_frame_fits(root, frames, rig, highest.as_ref().map(|(_, p)| p.as_path()))?;
    let dir = all.join(frame_name(next));
    write_whole(&dir, frames)?;
    copy_rig(root, rig)?;
    Ok(dir)
}

/// Refuses a frame that does not match the dataset `root`: its images' sizes against the
/// dataset's `rig.json` (or `rig` when the dataset has none yet), `rig` against the
/// dataset's own, and its shot count and sizes against the frame in `earlier`.
fn check_frame_fits(root: &Path, frames: &Frames, rig: Option<&Path>, earlier: Option<&Path>) -> Result<()> {
    let size = |img: &GrayImage| (img.width, img.height);
    let (Some(left), Some(right)) = (frames.left.first(), frames.right.first()) else {
        return Err(Error::format("the source gave a frame without images"));
    };
    let (left_size, right_size) = (size(left), size(right));
    if frames.left.iter().any(|i| size(i) != left_size) || frames.right.iter().any(|i| size(i) != right_size) {
        return Err(Error::format("the source gave a frame whose shots differ in size"));
    }
    let dataset_rig = root.join("rig.json");
    let given = rig.map(RigFile::load).transpose()?;
    let own = if dataset_rig.exists() { Some(RigFile::load(&dataset_rig)?) } else { None };
    if let Some((r, path)) = own.as_ref().map(|r| (r, dataset_rig.as_path())).or(given.as_ref().zip(rig)) {
        for (side, cam, got) in [("left", &r.left, left_size), ("right", &r.right, right_size)] {
            let want = (cam.width as usize, cam.height as usize);
            if got != want {
                return Err(Error::format(format!(
                        "{side}.width: the frame's {side} images are {}x{}, the rig's {side} camera {}x{}; a dataset holds frames of one rig",
                        got.0, got.1, want.0, want.1
                    )).in_file(path));
            }
        }
    }
    if let Some(earlier) = earlier {
        let shots = detect_shots(earlier)?;
        if shots != frames.shots() {
            return Err(Error::format(format!(
                "holds {shots} shot(s) per side, the new frame {}; a dataset holds frames of one method",
                frames.shots()
            ))
            .in_file(earlier));
        }
        for (side, got) in [("left", left_size), ("right", right_size)] {
            let path = earlier.join(image_name(side, 0, shots));
            let had = crate::read_image_size(&path)?;
            if had != got {
                return Err(Error::format(format!(
                    "{}x{} pixels, the new frame's {side} images {}x{}; a dataset holds frames of one size",
                    had.0, had.1, got.0, got.1
                ))
                .in_file(&path));
            }
        }
    }
    if let (Some(given), Some(own), Some(path)) = (&given, &own, rig) {
        // The cameras and projector; `rectified` is what reconstruction added since.
        if (&given.left, &given.right, &given.projector) != (&own.left, &own.right, &own.projector) {
            return Err(Error::format(format!(
                "differs from the dataset's {}; a dataset holds frames of one rig",
                dataset_rig.display()
            ))
            .in_file(path));
        }
    }
    Ok(())
}

/// Writes `frames` into a temporary folder beside `dir` and renames it to `dir` whole;
/// a `dir` already there is never replaced.
fn write_whole(dir: &Path, frames: &Frames) -> Result<()> {
    if dir.exists() {
        return Err(Error::format("already there; a frame is never written over").in_file(dir));
    }
    let parent = dir.parent().unwrap_or(Path::new("."));
    std::fs::create_dir_all(parent).map_err(|e| Error::io(parent, &e))?;
    crate::remove_stale_temp_files(parent)?;
    let tmp = crate::temp_path_for(dir);
    if tmp.exists() {
        std::fs::remove_dir_all(&tmp).map_err(|e| Error::io(&tmp, &e))?;
    }
    let written = write_shots(&tmp, frames).and_then(|()| {
        // The folder's entries made durable before it takes its name.
        if let Ok(f) = std::fs::File::open(&tmp) {
            let _ = f.sync_all();
        }
        std::fs::rename(&tmp, dir).map_err(|e| Error::io(dir, &e))
    });
    if written.is_err() {
        let _ = std::fs::remove_dir_all(&tmp);
    }
    written
}

/// Writes `frames` as the dataset `root`'s `background/` (the empty cell, which `run` and
/// `replay` remove from every frame) and returns its folder; refuses to replace one that is
/// there. With `rig`, copies that calibration to the dataset's `rig.json` when it has none.
pub fn write_background(root: &Path, frames: &Frames, rig: Option<&Path>) -> Result<PathBuf> {
    write_once(root, "background", "a background", frames, rig)
}

/// Writes `frames` as the calibration images' `table/` (the board lying flat on the table,
/// which ties the calibration to the world frame) and returns its folder; refuses to replace
/// one that is there.
pub fn write_table_view(root: &Path, frames: &Frames, rig: Option<&Path>) -> Result<PathBuf> {
    write_once(root, "table", "a table view", frames, rig)
}

/// Writes `frames` into `root/name/` (whole, as [`append_frame`] does) unless that folder exists.
fn write_once(root: &Path, name: &str, what: &str, frames: &Frames, rig: Option<&Path>) -> Result<PathBuf> {
    let dir = root.join(name);
    if dir.exists() {
        return Err(
            Error::format(format!("already holds {what}; remove the folder first to capture a new one")).in_file(&dir)
        );
    }
    check_frame_fits(root, frames, rig, None)?;
    write_whole(&dir, frames)?;
    copy_rig(root, rig)?;
    Ok(dir)
}

/// The shots of `frames` as `left.png` + `right.png` (or `left_NN.png` ... for several
/// shots) into `dir`, which is made when missing.
pub fn write_shots(dir: &Path, frames: &Frames) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, &e))?;
    for (side, images) in [("left", &frames.left), ("right", &frames.right)] {
        for (i, img) in images.iter().enumerate() {
            crate::write_gray(&dir.join(image_name(side, i, images.len())), img.width, img.height, &img.data)?;
        }
    }
    Ok(())
}

fn copy_rig(root: &Path, rig: Option<&Path>) -> Result<()> {
    if let Some(rig) = rig {
        let to = root.join("rig.json");
        if !to.exists() {
            crate::write_atomic(&to, crate::read_text(rig)?.as_bytes())?;
        }
    }
    Ok(())
}

/// Paths of a dataset folder.
pub struct DatasetLayout {
    pub root: PathBuf,
}

impl DatasetLayout {
    /// The layout under `root`.
    pub fn new(root: &Path) -> Self {
        DatasetLayout { root: root.to_path_buf() }
    }
    /// `rig.json`.
    pub fn rig(&self) -> PathBuf {
        self.root.join("rig.json")
    }
    /// `background/`.
    pub fn background(&self) -> PathBuf {
        self.root.join("background")
    }
    /// `frames/NNNN/`.
    pub fn frame(&self, index: u64) -> PathBuf {
        self.root.join("frames").join(frame_name(index))
    }
}
