//! A recorded dataset folder (docs/architecture.md §3) as a frame source: `rig.json`, an optional
//! `background/`, and `frames/NNNN/` with `left.png` + `right.png` (one shot) or
//! `left_00.png` ... `right_11.png` (N shots), each frame with an optional `truth.json`.
//! Simulated and real recordings take this one path.

use std::path::{Path, PathBuf};
use std::time::UNIX_EPOCH;

use camplace_config::read_gray;
use camplace_config::GrayImage;
use camplace_config::RigFile;

use crate::frames::{FrameInfo, FrameSource, Frames};
use crate::{Error, ErrorKind, Result};

/// Most shots per side a recording may have; phase-12 uses 12.
const MAX_SHOTS: usize = 64;

/// A recorded dataset folder, read frame by frame in folder-name order.
#[derive(Debug, Clone)]
pub struct RecordedSource {
    dir: PathBuf,
    rig: RigFile,
    shots: usize,
    frame_dirs: Vec<PathBuf>,
    next: usize,
}

impl RecordedSource {
    /// Opens `dir`: reads `rig.json`, lists `frames/`, detects the shots from the first
    /// frame and checks its images agree in size with each other and with the rig.
    pub fn open(dir: &Path) -> Result<RecordedSource> {
        if !dir.is_dir() {
            return Err(Error::new(
                ErrorKind::Io,
                format!("{}: expected a recorded dataset folder (rig.json, frames/NNNN/)", dir.display()),
            ));
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
            return Err(Error::format(&frames_dir, "expected at least one frame folder (frames/0000/)"));
        };
        let shots = detect_shots(first)?;
        let source = RecordedSource { dir: dir.to_path_buf(), rig, shots, frame_dirs, next: 0 };
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

    /// The frame folders, in the order `next` reads them.
    pub fn frame_dirs(&self) -> &[PathBuf] {
        &self.frame_dirs
    }

    /// The `truth.json` of frame `i`, when the recording has one.
    pub fn truth_path(&self, i: usize) -> Option<PathBuf> {
        let p = self.frame_dirs.get(i)?.join("truth.json");
        p.is_file().then_some(p)
    }

    /// Starts the stream again from the first frame.
    pub fn rewind(&mut self) {
        self.next = 0;
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
            Error::new(
                ErrorKind::Format,
                format!("{}: no frame {i} (it has {})", self.dir.display(), self.frame_dirs.len()),
            )
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
                return Err(Error::format(&path, format!("missing {side} image (expected {w}x{h} 8-bit PNG)")));
            }
            let img = read_gray(&path)?;
            if (img.width, img.height) != (w, h) {
                return Err(Error::format(
                    &path,
                    format!(
                        "image is {}x{}, expected {w}x{h} as rig.json says for the {side} camera",
                        img.width, img.height
                    ),
                ));
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

impl FrameSource for RecordedSource {
    fn next(&mut self, frames: &mut Frames) -> Result<Option<FrameInfo>> {
        if self.next >= self.frame_dirs.len() {
            return Ok(None);
        }
        let info = self.read_into(self.next, frames)?;
        self.next += 1;
        Ok(Some(info))
    }

    fn shots(&self) -> usize {
        self.shots
    }
}

pub use camplace_config::image_name;

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
                        Error::format(
                            &entry.path(),
                            format!("a frame number past {MAX_FRAME_NUMBER}, the largest a dataset takes; start a new dataset"),
                        )
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
            Error::format(
                path,
                format!("frame {n} is the last a dataset takes ({MAX_FRAME_NUMBER}); start a new dataset"),
            )
        })?,
    };
    check_frame_fits(root, frames, rig, highest.as_ref().map(|(_, p)| p.as_path()))?;
    let dir = all.join(camplace_config::frame_name(next));
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
        return Err(Error::new(ErrorKind::Format, "the source gave a frame without images"));
    };
    let (left_size, right_size) = (size(left), size(right));
    if frames.left.iter().any(|i| size(i) != left_size) || frames.right.iter().any(|i| size(i) != right_size) {
        return Err(Error::new(ErrorKind::Format, "the source gave a frame whose shots differ in size"));
    }
    let dataset_rig = root.join("rig.json");
    let given = rig.map(RigFile::load).transpose()?;
    let own = if dataset_rig.exists() { Some(RigFile::load(&dataset_rig)?) } else { None };
    if let Some((r, path)) = own.as_ref().map(|r| (r, dataset_rig.as_path())).or(given.as_ref().zip(rig)) {
        for (side, cam, got) in [("left", &r.left, left_size), ("right", &r.right, right_size)] {
            let want = (cam.width as usize, cam.height as usize);
            if got != want {
                return Err(Error::format(
                    path,
                    format!(
                        "{side}.width: the frame's {side} images are {}x{}, the rig's {side} camera {}x{}; a dataset holds frames of one rig",
                        got.0, got.1, want.0, want.1
                    ),
                ));
            }
        }
    }
    if let Some(earlier) = earlier {
        let shots = detect_shots(earlier)?;
        if shots != frames.shots() {
            return Err(Error::format(
                earlier,
                format!(
                    "holds {shots} shot(s) per side, the new frame {}; a dataset holds frames of one method",
                    frames.shots()
                ),
            ));
        }
        for (side, got) in [("left", left_size), ("right", right_size)] {
            let path = earlier.join(image_name(side, 0, shots));
            let had = camplace_config::read_image_size(&path)?;
            if had != got {
                return Err(Error::format(
                    &path,
                    format!(
                        "{}x{} pixels, the new frame's {side} images {}x{}; a dataset holds frames of one size",
                        had.0, had.1, got.0, got.1
                    ),
                ));
            }
        }
    }
    if let (Some(given), Some(own), Some(path)) = (&given, &own, rig) {
        // The cameras and projector; `rectified` is what reconstruction added since.
        if (&given.left, &given.right, &given.projector) != (&own.left, &own.right, &own.projector) {
            return Err(Error::format(
                path,
                format!("differs from the dataset's {}; a dataset holds frames of one rig", dataset_rig.display()),
            ));
        }
    }
    Ok(())
}

/// Writes `frames` into a temporary folder beside `dir` and renames it to `dir` whole;
/// a `dir` already there is never replaced.
fn write_whole(dir: &Path, frames: &Frames) -> Result<()> {
    if dir.exists() {
        return Err(Error::format(dir, "already there; a frame is never written over"));
    }
    let parent = dir.parent().unwrap_or(Path::new("."));
    std::fs::create_dir_all(parent).map_err(|e| Error::io(parent, &e))?;
    camplace_config::remove_stale_temp_files(parent)?;
    let tmp = camplace_config::temp_path_for(dir);
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
        return Err(Error::format(&dir, format!("already holds {what}; remove the folder first to capture a new one")));
    }
    check_frame_fits(root, frames, rig, None)?;
    write_whole(&dir, frames)?;
    copy_rig(root, rig)?;
    Ok(dir)
}

/// `left.png` + `right.png` (or `left_NN.png` ... for several shots) into `dir`.
fn write_shots(dir: &Path, frames: &Frames) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, &e))?;
    for (side, images) in [("left", &frames.left), ("right", &frames.right)] {
        for (i, img) in images.iter().enumerate() {
            camplace_config::write_gray(
                &dir.join(image_name(side, i, images.len())),
                img.width,
                img.height,
                &img.data,
            )?;
        }
    }
    Ok(())
}

fn copy_rig(root: &Path, rig: Option<&Path>) -> Result<()> {
    if let Some(rig) = rig {
        let to = root.join("rig.json");
        if !to.exists() {
            camplace_config::write_atomic(&to, camplace_config::read_text(rig)?.as_bytes())?;
        }
    }
    Ok(())
}

/// One shot when `left.png` is there, else as many as consecutive `left_NN.png` from 00.
fn detect_shots(dir: &Path) -> Result<usize> {
    if dir.join("left.png").is_file() {
        return Ok(1);
    }
    let shots = (0..MAX_SHOTS).take_while(|&i| dir.join(image_name("left", i, 2)).is_file()).count();
    if shots == 0 {
        return Err(Error::format(dir, "expected left.png + right.png or left_00.png ... right_11.png"));
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

#[cfg(test)]
mod tests {
    use super::*;
    use camplace_config::write_gray;
    use camplace_config::CameraFile;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    const W: usize = 24;
    const H: usize = 16;

    fn rig() -> RigFile {
        let cam = CameraFile {
            width: W as u32,
            height: H as u32,
            k: [[30.0, 0.0, 11.5], [0.0, 30.0, 7.5], [0.0, 0.0, 1.0]],
            dist: [0.0; 5],
            // 600 mm above the table, looking straight down.
            t_world_camera: [
                [1.0, 0.0, 0.0, 0.0],
                [0.0, -1.0, 0.0, 0.0],
                [0.0, 0.0, -1.0, 600.0],
                [0.0, 0.0, 0.0, 1.0],
            ],
        };
        let mut right = cam.clone();
        right.t_world_camera[0][3] = 80.0;
        RigFile { left: cam, right, projector: None, rectified: None }
    }

    /// Writes a dataset of `names` frames with `shots` seeded random images per side and
    /// returns the images as written: [frame][side][shot].
    fn dataset(dir: &Path, names: &[&str], shots: usize, seed: u64) -> Vec<[Vec<Vec<u8>>; 2]> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rig().save(&dir.join("rig.json")).unwrap();
        let mut written = Vec::new();
        for name in names {
            let fdir = dir.join("frames").join(name);
            std::fs::create_dir_all(&fdir).unwrap();
            let mut sides = [Vec::new(), Vec::new()];
            for (s, side) in ["left", "right"].iter().enumerate() {
                for shot in 0..shots {
                    let img: Vec<u8> = (0..W * H).map(|_| rng.random::<u8>()).collect();
                    write_gray(&fdir.join(image_name(side, shot, shots)), W, H, &img).unwrap();
                    sides[s].push(img);
                }
            }
            written.push(sides);
        }
        written
    }

    #[test]
    fn one_shot_frames_come_back_in_numeric_order() {
        let t = tempfile::tempdir().unwrap();
        // Written out of order and not all padded: 9 must come before 10.
        let names = ["10", "0002", "9"];
        let written = dataset(t.path(), &names, 1, 1);
        let mut src = RecordedSource::open(t.path()).unwrap();
        assert_eq!(src.shots(), 1);
        let mut frames = Frames::default();
        for (i, want) in [1usize, 2, 0].into_iter().enumerate() {
            let info = src.next(&mut frames).unwrap().expect("a frame");
            assert_eq!((info.index, info.name.as_str()), (i as u64, names[want]));
            assert!(info.timestamp_us > 0);
            assert_eq!((frames.left[0].width, frames.left[0].height), (W, H));
            assert_eq!(frames.left[0].data, written[want][0][0]);
            assert_eq!(frames.right[0].data, written[want][1][0]);
        }
        assert!(src.next(&mut frames).unwrap().is_none());
        src.rewind();
        assert_eq!(src.next(&mut frames).unwrap().unwrap().name, "0002");
    }

    #[test]
    fn twelve_shot_frames_background_and_truth() {
        let t = tempfile::tempdir().unwrap();
        let written = dataset(t.path(), &["0000", "0001"], 12, 2);
        // The background holds the same image names as a frame.
        let bg = tempfile::tempdir().unwrap();
        let bg_written = dataset(bg.path(), &["b"], 12, 3);
        std::fs::rename(bg.path().join("frames").join("b"), t.path().join("background")).unwrap();
        std::fs::write(t.path().join("frames/0001/truth.json"), "{}").unwrap();

        let mut src = RecordedSource::open(t.path()).unwrap();
        assert_eq!(src.shots(), 12);
        assert_eq!(src.frame_dirs().len(), 2);
        assert!(src.truth_path(0).is_none() && src.truth_path(1).is_some());
        let mut frames = Frames::new(12);
        assert!(src.background(&mut frames).unwrap());
        let data = |imgs: &[GrayImage]| imgs.iter().map(|i| i.data.clone()).collect::<Vec<_>>();
        assert_eq!(data(&frames.left), bg_written[0][0]);
        assert_eq!(data(&frames.right), bg_written[0][1]);
        let ptrs: Vec<_> = frames.left.iter().map(|i| i.data.as_ptr()).collect();
        for want in &written {
            src.next(&mut frames).unwrap().unwrap();
            assert_eq!(data(&frames.left), want[0]);
            assert_eq!(data(&frames.right), want[1]);
        }
        // The caller's buffers were reused, not replaced.
        assert_eq!(ptrs, frames.left.iter().map(|i| i.data.as_ptr()).collect::<Vec<_>>());
    }

    #[test]
    fn no_background_is_false() {
        let t = tempfile::tempdir().unwrap();
        dataset(t.path(), &["0000"], 1, 4);
        let src = RecordedSource::open(t.path()).unwrap();
        assert!(!src.background(&mut Frames::new(1)).unwrap());
    }

    #[test]
    fn a_missing_right_image_is_named() {
        let t = tempfile::tempdir().unwrap();
        dataset(t.path(), &["0000"], 12, 5);
        std::fs::remove_file(t.path().join("frames/0000/right_03.png")).unwrap();
        let e = RecordedSource::open(t.path()).unwrap_err();
        assert!(e.to_string().contains("right_03.png") && e.to_string().contains("missing right image"), "{e}");
    }

    #[test]
    fn a_size_that_disagrees_with_the_rig_is_named() {
        let t = tempfile::tempdir().unwrap();
        dataset(t.path(), &["0000", "0001"], 1, 6);
        write_gray(&t.path().join("frames/0001/left.png"), W + 2, H, &vec![0; (W + 2) * H]).unwrap();
        // The first frame is fine, so opening works; the bad frame fails when read.
        let mut src = RecordedSource::open(t.path()).unwrap();
        let mut frames = Frames::default();
        src.next(&mut frames).unwrap().unwrap();
        let e = src.next(&mut frames).unwrap_err();
        let msg = e.to_string();
        assert!(
            msg.contains("0001/left.png")
                && msg.contains(&format!("{}x{H}", W + 2))
                && msg.contains(&format!("expected {W}x{H}")),
            "{msg}"
        );

        write_gray(&t.path().join("frames/0000/right.png"), W, H + 1, &vec![0; W * (H + 1)]).unwrap();
        let e = RecordedSource::open(t.path()).unwrap_err();
        assert!(e.to_string().contains("0000/right.png"), "{e}");
    }

    #[test]
    fn unreadable_png_and_missing_parts_are_named() {
        let t = tempfile::tempdir().unwrap();
        dataset(t.path(), &["0000"], 1, 7);
        std::fs::write(t.path().join("frames/0000/left.png"), b"not a png").unwrap();
        let e = RecordedSource::open(t.path()).unwrap_err();
        assert!(e.to_string().contains("0000/left.png"), "{e}");

        std::fs::remove_file(t.path().join("frames/0000/left.png")).unwrap();
        let e = RecordedSource::open(t.path()).unwrap_err();
        assert!(e.to_string().contains("left_00.png"), "{e}");

        std::fs::remove_dir_all(t.path().join("frames/0000")).unwrap();
        let e = RecordedSource::open(t.path()).unwrap_err();
        assert!(e.to_string().contains("frames") && e.to_string().contains("at least one frame"), "{e}");

        std::fs::remove_file(t.path().join("rig.json")).unwrap();
        let e = RecordedSource::open(t.path()).unwrap_err();
        assert!(e.to_string().contains("rig.json"), "{e}");
    }

    #[test]
    fn appended_frames_read_back_as_written_after_the_last_number() {
        let t = tempfile::tempdir().unwrap();
        let written = dataset(t.path(), &["0007"], 12, 3);
        let rig_copy = t.path().join("other-rig.json");
        rig().save(&rig_copy).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let mut frames = Frames::new(12);
        for img in frames.left.iter_mut().chain(frames.right.iter_mut()) {
            *img = GrayImage::from_vec(W, H, (0..W * H).map(|_| rng.random::<u8>()).collect()).unwrap();
        }
        let dir = append_frame(t.path(), &frames, Some(&rig_copy)).unwrap();
        assert_eq!(dir, t.path().join("frames").join("0008"));
        let mut src = RecordedSource::open(t.path()).unwrap();
        let mut back = Frames::default();
        assert_eq!(src.next(&mut back).unwrap().unwrap().name, "0007");
        assert_eq!(back.left[11].data, written[0][0][11]);
        assert_eq!(src.next(&mut back).unwrap().unwrap().name, "0008");
        for i in 0..12 {
            assert_eq!(back.left[i].data, frames.left[i].data);
            assert_eq!(back.right[i].data, frames.right[i].data);
        }
        // A fresh dataset starts at 0000 and takes the given rig.
        let fresh = t.path().join("fresh");
        assert_eq!(append_frame(&fresh, &frames, Some(&rig_copy)).unwrap(), fresh.join("frames").join("0000"));
        assert_eq!(RigFile::load(&fresh.join("rig.json")).unwrap(), rig());
    }
}
