//! Judging a placement's frames: a frame with a `truth.json` by the success tolerances (its
//! line in `poses.jsonl` carries `success`), any other by the reviewer's mark in
//! `labels.jsonl` — one JSON line per mark, `{"frame":"0003","mark":"correct"}` (or
//! `wrong`, `unsure`), appended as marks are made; a frame's last mark stands. The file is
//! the review's whole state: nothing else is kept between sittings.

use std::io::Write;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::{Error, Result};
use camplace_estimator::FrameRecord;

/// The reviewer's marks beside a dataset's frames.
pub const LABELS_FILE: &str = "labels.jsonl";
/// The estimated poses of a dataset's frames.
pub const POSES_FILE: &str = "poses.jsonl";

/// A reviewer's judgement of one frame's pose.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Mark {
    /// The outline lies on the tray: the pose is correct.
    Correct,
    /// The outline misses the tray (or no pose where a tray is): wrong.
    Wrong,
    /// The reviewer cannot tell; the frame is left out of the count.
    Unsure,
}

impl Mark {
    /// The mark of a review page key: c, w or u.
    pub fn from_key(key: &str) -> Option<Mark> {
        match key {
            "c" | "correct" => Some(Mark::Correct),
            "w" | "wrong" => Some(Mark::Wrong),
            "u" | "unsure" => Some(Mark::Unsure),
            _ => None,
        }
    }
}

/// One line of `labels.jsonl`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Label {
    /// The frame's folder name.
    pub frame: String,
    /// The judgement.
    pub mark: Mark,
}

/// How one frame was judged.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Judgement {
    /// By its `truth.json` and the success tolerances.
    Truth(bool),
    /// By the reviewer's mark.
    Marked(Mark),
    /// Not judged yet.
    Open,
}

impl Judgement {
    /// Success (`Some(true)`), failure, or left out of the count (unsure, not judged).
    pub fn outcome(self) -> Option<bool> {
        match self {
            Judgement::Truth(s) => Some(s),
            Judgement::Marked(Mark::Correct) => Some(true),
            Judgement::Marked(Mark::Wrong) => Some(false),
            Judgement::Marked(Mark::Unsure) | Judgement::Open => None,
        }
    }
}

/// The frames of a dataset folder (`frames/NNNN/`), sorted.
pub fn frame_names(dir: &Path) -> Result<Vec<String>> {
    let frames = dir.join("frames");
    let cannot = |e: std::io::Error| Error::Other(format!("{}: cannot list: {e}", frames.display()));
    let mut names = Vec::new();
    for entry in std::fs::read_dir(&frames).map_err(cannot)? {
        let entry = entry.map_err(cannot)?;
        let name = entry.file_name().to_string_lossy().into_owned();
        if entry.file_type().map_err(cannot)?.is_dir() && !name.is_empty() && name.bytes().all(|b| b.is_ascii_digit()) {
            names.push(name);
        }
    }
    names.sort();
    Ok(names)
}

/// The poses of `dir/poses.jsonl`, one per frame of the dataset, in frame order.
pub fn read_poses(dir: &Path) -> Result<Vec<FrameRecord>> {
    let path = dir.join(POSES_FILE);
    if !path.is_file() {
        return Err(Error::Other(format!(
            "{}: missing: expected the frames' poses (camplace trial estimate or camplace replay writes them)",
            path.display()
        )));
    }
    let text = camplace_config::read_text(&path)?;
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty()) {
        let r: FrameRecord = serde_json::from_str(line).map_err(|e| {
            Error::Other(format!("{}: line {}: expected a pose line as replay writes it: {e}", path.display(), i + 1))
        })?;
        out.push(r);
    }
    Ok(out)
}

/// The marks of `dir/labels.jsonl` (none when the file does not exist), each checked to name
/// a frame of the dataset.
pub fn read_labels(dir: &Path, frames: &[String]) -> Result<Vec<Label>> {
    let path = dir.join(LABELS_FILE);
    if !path.exists() {
        return Ok(Vec::new());
    }
    let text = camplace_config::read_text(&path)?;
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty()) {
        let at = |key: &str, what: String| Error::Other(format!("{}: line {}: {key}: {what}", path.display(), i + 1));
        let label: Label = serde_json::from_str(line).map_err(|e| {
            at("mark", format!("expected {{\"frame\":\"NNNN\",\"mark\":\"correct|wrong|unsure\"}}: {e}"))
        })?;
        if frames.binary_search(&label.frame).is_err() {
            return Err(at(
                "frame",
                format!("expected a frame of the dataset ({}), found \"{}\"", span(frames), label.frame),
            ));
        }
        out.push(label);
    }
    Ok(out)
}

/// "0000 … 0019" (or "none").
fn span(frames: &[String]) -> String {
    match (frames.first(), frames.last()) {
        (Some(a), Some(b)) if a != b => format!("{a} … {b}"),
        (Some(a), _) => a.clone(),
        _ => "it has none".into(),
    }
}

/// Appends one mark to `dir/labels.jsonl` in a single write, after checking that the frame
/// exists; returns the file's path.
pub fn append_label(dir: &Path, frames: &[String], label: &Label) -> Result<PathBuf> {
    let path = dir.join(LABELS_FILE);
    if frames.binary_search(&label.frame).is_err() {
        return Err(Error::Other(format!(
            "{}: frame: expected a frame of the dataset ({}), found \"{}\"",
            path.display(),
            span(frames),
            label.frame
        )));
    }
    let line = format!("{}\n", serde_json::to_string(label).expect("a label is plain data"));
    let mut f = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(&path)
        .map_err(|e| Error::Other(format!("{}: cannot open for appending: {e}", path.display())))?;
    f.write_all(line.as_bytes())
        .and_then(|()| f.sync_data())
        .map_err(|e| Error::Other(format!("{}: cannot append: {e}", path.display())))?;
    Ok(path)
}

/// Every frame of a placement's dataset with its pose and judgement.
#[derive(Debug, Clone)]
pub struct JudgedDataset {
    /// The frames in order: name, pose line, judgement.
    pub frames: Vec<(String, FrameRecord, Judgement)>,
}

impl JudgedDataset {
    /// Reads `dir`'s poses and labels: every frame of `frames/` must have a pose line.
    pub fn read(dir: &Path) -> Result<JudgedDataset> {
        let names = frame_names(dir)?;
        let poses = read_poses(dir)?;
        let labels = read_labels(dir, &names)?;
        let mut frames = Vec::with_capacity(names.len());
        for name in names {
            let Some(pose) = poses.iter().find(|p| p.frame == name) else {
                return Err(Error::Other(format!(
                    "{}: frame: expected a pose line for frame {name}; estimate the placement again",
                    dir.join(POSES_FILE).display()
                )));
            };
            let judgement = match (&pose.score, labels.iter().rev().find(|l| l.frame == name)) {
                (Some(s), _) => Judgement::Truth(s.success),
                (None, Some(l)) => Judgement::Marked(l.mark),
                (None, None) => Judgement::Open,
            };
            frames.push((name, pose.clone(), judgement));
        }
        Ok(JudgedDataset { frames })
    }

    /// Each frame's outcome in frame order (see [`Judgement::outcome`]).
    pub fn outcomes(&self) -> Vec<Option<bool>> {
        self.frames.iter().map(|(_, _, j)| j.outcome()).collect()
    }

    /// Frames of each kind: (judged by truth, marked correct or wrong, unsure, not judged).
    pub fn counts(&self) -> [usize; 4] {
        let mut c = [0; 4];
        for (_, _, j) in &self.frames {
            let k = match j {
                Judgement::Truth(_) => 0,
                Judgement::Marked(Mark::Unsure) => 2,
                Judgement::Marked(_) => 1,
                Judgement::Open => 3,
            };
            c[k] += 1;
        }
        c
    }
}
