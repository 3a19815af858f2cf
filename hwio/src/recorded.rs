//! A recorded dataset folder (docs/design/interchange-formats.md) as a frame source: config's
//! [`RecordedDataset`] reader streamed frame by frame. Simulated and real recordings take this
//! one path.

use std::path::{Path, PathBuf};

use camplace_config::{RecordedDataset, RigFile};

use crate::frames::{FrameInfo, FrameSource, Frames};
use crate::Result;

/// A recorded dataset folder, read frame by frame in folder-name order.
#[derive(Debug, Clone)]
pub struct RecordedSource {
    dataset: RecordedDataset,
    next: usize,
}

impl RecordedSource {
    /// Opens `dir`: reads `rig.json`, lists `frames/`, detects the shots from the first
    /// frame and checks its images agree in size with each other and with the rig.
    pub fn open(dir: &Path) -> Result<RecordedSource> {
        Ok(RecordedSource { dataset: RecordedDataset::open(dir)?, next: 0 })
    }

    /// The dataset folder.
    pub fn dir(&self) -> &Path {
        self.dataset.dir()
    }

    /// The calibration in the folder's `rig.json`.
    pub fn rig(&self) -> &RigFile {
        self.dataset.rig()
    }

    /// The frame folders, in the order `next` reads them.
    pub fn frame_dirs(&self) -> &[PathBuf] {
        self.dataset.frame_dirs()
    }

    /// The `truth.json` of frame `i`, when the recording has one.
    pub fn truth_path(&self, i: usize) -> Option<PathBuf> {
        self.dataset.truth_path(i)
    }

    /// Starts the stream again from the first frame.
    pub fn rewind(&mut self) {
        self.next = 0;
    }

    /// Fills `frames` with the images of `background/`; `Ok(false)` when the recording
    /// has no background.
    pub fn background(&self, frames: &mut Frames) -> Result<bool> {
        Ok(self.dataset.background(frames)?)
    }

    /// Reads frame `i` into `frames`.
    pub fn read_into(&self, i: usize, frames: &mut Frames) -> Result<FrameInfo> {
        Ok(self.dataset.read_into(i, frames)?)
    }
}

impl FrameSource for RecordedSource {
    fn next(&mut self, frames: &mut Frames) -> Result<Option<FrameInfo>> {
        if self.next >= self.dataset.frame_dirs().len() {
            return Ok(None);
        }
        let info = self.read_into(self.next, frames)?;
        self.next += 1;
        Ok(Some(info))
    }

    fn shots(&self) -> usize {
        self.dataset.shots()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use camplace_config::CameraFile;
    use camplace_config::{append_frame, image_name, write_gray, GrayImage};
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
