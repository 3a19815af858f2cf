//! Capture into a recorded dataset (`camplace capture`): the schedule — how many frames,
//! how far apart, how many thrown away before each — and where each goes: the next
//! `frames/NNNN/`, or the one frame of `background/` or `table/`. The frames come from any
//! [`FrameSource`]; the dataset is written through config's writer. What is said about each
//! frame is the caller's, through a callback.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use camplace_config::{append_frame, write_background, write_table_view, DatasetLayout, RigFile};

use crate::frames::{FrameInfo, FrameSource, Frames};
use crate::spec::SourceSpec;
use crate::{Error, Result};

/// The most frames one capture may take.
pub const MAX_CAPTURE_COUNT: u64 = 1_000_000;
/// The longest wait between frames, s.
pub const MAX_CAPTURE_EVERY_S: f64 = 86_400.0;

/// What the captured frames are.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CaptureKind {
    /// Frames of the dataset, each appended as the next `frames/NNNN/`.
    Frames,
    /// The empty cell, the dataset's `background/` (one frame).
    Background,
    /// The calibration board lying flat on the table, the dataset's `table/` (one frame).
    TableView,
}

/// How to capture: checked by [`CapturePlan::new`].
#[derive(Debug, Clone, PartialEq)]
pub struct CapturePlan {
    count: u64,
    every_s: f64,
    skip: u64,
    kind: CaptureKind,
}

impl CapturePlan {
    /// `count` frames (1 to [`MAX_CAPTURE_COUNT`]; one for a background or table view),
    /// each `every_s` seconds after the one before counted from the first (0: as the source
    /// gives them), `skip` source frames thrown away before each (frames a driver queued
    /// earlier). The error names the flag (`--count`, `--every`, `--background`, `--table`).
    pub fn new(count: u64, every_s: f64, skip: u64, kind: CaptureKind) -> Result<CapturePlan> {
        if !(1..=MAX_CAPTURE_COUNT).contains(&count) {
            return Err(Error::input(format!("--count: expected 1 to {MAX_CAPTURE_COUNT} frames, got {count}")));
        }
        if !(every_s.is_finite() && (0.0..=MAX_CAPTURE_EVERY_S).contains(&every_s)) {
            return Err(Error::input(format!("--every: expected 0 to {MAX_CAPTURE_EVERY_S} seconds, got {every_s}")));
        }
        let one = match kind {
            CaptureKind::Frames => None,
            CaptureKind::Background => Some(("--background", "the background")),
            CaptureKind::TableView => Some(("--table", "the table view")),
        };
        if let Some((flag, what)) = one.filter(|_| count != 1) {
            return Err(Error::input(format!("{flag}: {what} is one frame; leave out --count {count}")));
        }
        Ok(CapturePlan { count, every_s, skip, kind })
    }

    /// Frames to capture.
    pub fn count(&self) -> u64 {
        self.count
    }
}

/// One frame written, as the callback is told of it.
#[derive(Debug, Clone, PartialEq)]
pub struct CapturedFrame {
    /// What the source said about it (its own index and name).
    pub source: FrameInfo,
    /// Images per side.
    pub shots: usize,
    /// The folder it was written to.
    pub dir: PathBuf,
    /// Seconds from the start of the capture to its writing.
    pub elapsed_s: f64,
}

/// What a capture did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CaptureOutcome {
    /// Frames written.
    pub captured: u64,
    /// Frames the plan asked for (more than captured when the source ended first).
    pub requested: u64,
    /// Whether the dataset has a `rig.json` now.
    pub has_rig: bool,
}

/// The calibration a capture copies to the dataset when it has none: `given`, else a `dir:`
/// source's own `rig.json` when there is one; read and checked here, so a bad file is
/// refused before any frame is taken.
pub fn capture_rig(given: Option<&Path>, spec: &SourceSpec) -> Result<Option<PathBuf>> {
    let rig = match (given, spec) {
        (Some(r), _) => Some(r.to_path_buf()),
        (None, SourceSpec::Recorded(dir)) => Some(DatasetLayout::new(dir).rig()).filter(|p| p.is_file()),
        (None, _) => None,
    };
    if let Some(r) = &rig {
        RigFile::load(r)?;
    }
    Ok(rig)
}

/// Captures `plan` from `source` into the dataset `dataset_dir` (created when missing),
/// with `rig` copied to its `rig.json` when it has none, telling `on_frame` of each frame
/// once it is written. Stops early, without an error, when the source ends; an error of
/// the source or of a write (a frame of another size, shot count or rig than the
/// dataset's) ends it.
pub fn capture_dataset(
    source: &mut dyn FrameSource,
    plan: &CapturePlan,
    dataset_dir: &Path,
    rig: Option<&Path>,
    mut on_frame: impl FnMut(&CapturedFrame),
) -> Result<CaptureOutcome> {
    let mut frames = Frames::new(source.shots());
    let started = Instant::now();
    let mut captured = 0;
    while captured < plan.count {
        if captured > 0 && plan.every_s > 0.0 {
            // Kept to the schedule from the start, so slow writes do not add up.
            let due = started + Duration::from_secs_f64(plan.every_s * captured as f64);
            std::thread::sleep(due.saturating_duration_since(Instant::now()));
        }
        let mut info = None;
        for _ in 0..=plan.skip {
            info = source.next(&mut frames)?;
            if info.is_none() {
                break;
            }
        }
        let Some(info) = info else { break };
        let dir = match plan.kind {
            CaptureKind::Frames => append_frame(dataset_dir, &frames, rig)?,
            CaptureKind::Background => write_background(dataset_dir, &frames, rig)?,
            CaptureKind::TableView => write_table_view(dataset_dir, &frames, rig)?,
        };
        captured += 1;
        on_frame(&CapturedFrame {
            source: info,
            shots: frames.left.len(),
            dir,
            elapsed_s: started.elapsed().as_secs_f64(),
        });
    }
    Ok(CaptureOutcome { captured, requested: plan.count, has_rig: DatasetLayout::new(dataset_dir).rig().exists() })
}

#[cfg(test)]
mod tests {
    use super::*;
    use camplace_config::{frame_name, read_gray, GrayImage};

    /// A stand-in camera: frame k's left image is all k, its right all k + 100; it ends
    /// after `limit` frames.
    struct Counting {
        next: u64,
        limit: u64,
    }

    impl FrameSource for Counting {
        fn next(&mut self, frames: &mut Frames) -> Result<Option<FrameInfo>> {
            if self.next == self.limit {
                return Ok(None);
            }
            let k = self.next;
            frames.left[0] = GrayImage::new(8, 6, k as u8);
            frames.right[0] = GrayImage::new(8, 6, k as u8 + 100);
            self.next += 1;
            Ok(Some(FrameInfo { index: k, name: format!("cam{k}"), timestamp_us: k }))
        }
        fn shots(&self) -> usize {
            1
        }
    }

    /// The value of every pixel of `path` (all equal in these tests).
    fn value(path: &Path) -> u8 {
        let image = read_gray(path).unwrap();
        assert!(image.data.iter().all(|&v| v == image.data[0]), "{}", path.display());
        image.data[0]
    }

    #[test]
    fn frames_are_numbered_on_from_the_dataset_with_skipped_frames_thrown_away() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("set");
        let mut source = Counting { next: 0, limit: 100 };
        let plan = CapturePlan::new(3, 0.0, 2, CaptureKind::Frames).unwrap();
        let mut told = Vec::new();
        let outcome = capture_dataset(&mut source, &plan, &out, None, |f| told.push(f.clone())).unwrap();
        assert_eq!(outcome, CaptureOutcome { captured: 3, requested: 3, has_rig: false });
        // Two thrown away before each kept frame: source frames 2, 5 and 8.
        let kept: Vec<u64> = told.iter().map(|f| f.source.index).collect();
        assert_eq!(kept, [2, 5, 8]);
        for (k, f) in told.iter().enumerate() {
            assert_eq!(f.dir, out.join("frames").join(frame_name(k as u64)));
            assert_eq!(f.shots, 1);
            assert_eq!(value(&f.dir.join("left.png")), kept[k] as u8);
            assert_eq!(value(&f.dir.join("right.png")), kept[k] as u8 + 100);
        }
        // A second run appends after the frames already there.
        let plan = CapturePlan::new(2, 0.0, 0, CaptureKind::Frames).unwrap();
        let mut dirs = Vec::new();
        capture_dataset(&mut source, &plan, &out, None, |f| dirs.push(f.dir.clone())).unwrap();
        assert_eq!(dirs, [out.join("frames").join(frame_name(3)), out.join("frames").join(frame_name(4))]);
        assert_eq!(value(&dirs[1].join("left.png")), 10);
    }

    #[test]
    fn a_source_that_ends_stops_the_capture_early() {
        let dir = tempfile::tempdir().unwrap();
        // Frames 0 … 3: with one thrown away before each, 1 and 3 are kept, then it ends.
        let mut source = Counting { next: 0, limit: 4 };
        let plan = CapturePlan::new(5, 0.0, 1, CaptureKind::Frames).unwrap();
        let mut kept = Vec::new();
        let outcome = capture_dataset(&mut source, &plan, dir.path(), None, |f| kept.push(f.source.index)).unwrap();
        assert_eq!((outcome.captured, outcome.requested), (2, 5));
        assert_eq!(kept, [1, 3]);
        // An ended source gives nothing.
        let outcome = capture_dataset(&mut source, &plan, dir.path(), None, |_| panic!("no frame")).unwrap();
        assert_eq!(outcome.captured, 0);
    }

    #[test]
    fn a_background_and_a_table_view_are_one_frame_each_in_their_folders() {
        let dir = tempfile::tempdir().unwrap();
        let mut source = Counting { next: 0, limit: 100 };
        for (kind, folder, value_left) in
            [(CaptureKind::Background, "background", 0), (CaptureKind::TableView, "table", 1)]
        {
            let plan = CapturePlan::new(1, 0.0, 0, kind).unwrap();
            let mut dirs = Vec::new();
            capture_dataset(&mut source, &plan, dir.path(), None, |f| dirs.push(f.dir.clone())).unwrap();
            assert_eq!(dirs, [dir.path().join(folder)]);
            assert_eq!(value(&dirs[0].join("left.png")), value_left);
            let e = CapturePlan::new(2, 0.0, 0, kind).unwrap_err();
            assert!(e.to_string().contains("is one frame; leave out --count 2"), "{e}");
        }
        assert!(!dir.path().join("frames").exists());
    }

    #[test]
    fn frames_keep_to_the_schedule_from_the_start() {
        let dir = tempfile::tempdir().unwrap();
        let mut source = Counting { next: 0, limit: 100 };
        let plan = CapturePlan::new(3, 0.02, 0, CaptureKind::Frames).unwrap();
        let mut at = Vec::new();
        capture_dataset(&mut source, &plan, dir.path(), None, |f| at.push(f.elapsed_s)).unwrap();
        // Frame k is taken no earlier than k × every after the start.
        for (k, t) in at.iter().enumerate() {
            assert!(*t >= 0.02 * k as f64, "frame {k} at {t} s");
        }
    }

    #[test]
    fn a_bad_plan_names_its_flag() {
        for (count, every, flag) in [(0, 0.0, "--count"), (2_000_000, 0.0, "--count"), (1, -1.0, "--every")] {
            let e = CapturePlan::new(count, every, 0, CaptureKind::Frames).unwrap_err();
            assert!(e.to_string().starts_with(flag), "{e}");
        }
        assert!(CapturePlan::new(1, f64::NAN, 0, CaptureKind::Frames).is_err());
    }

    #[test]
    fn the_rig_copied_is_the_given_one_else_a_recorded_sources_own() {
        let dir = tempfile::tempdir().unwrap();
        let recorded = SourceSpec::Recorded(dir.path().to_path_buf());
        assert_eq!(capture_rig(None, &recorded).unwrap(), None);
        let bad = dir.path().join("rig.json");
        std::fs::write(&bad, "{}").unwrap();
        assert!(capture_rig(None, &recorded).unwrap_err().to_string().contains("rig.json"));
    }
}
