//! Judging a placement's frames: a frame with a `truth.json` by the success tolerances (its
//! line in `poses.jsonl` carries `success`), any other by the reviewer's mark in
//! `labels.jsonl` — one JSON line per mark, `{"frame":"0003","mark":"correct","pose":"…"}`
//! (or `wrong`, `unsure`), appended as marks are made; a frame's last mark on its present
//! pose stands. `pose` is the fingerprint of the pose the mark judged, so a mark made before
//! the frame was estimated again (another model, another cell) judges nothing now: it is
//! kept in the file but not counted, and the frame is open until marked again. The file is
//! the review's whole state: nothing else is kept between sittings.

use std::io::Write;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::{Error, Result};
use camplace_config::ContentHash;
use camplace_estimator::scoring::FrameRecord;

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
    /// The [`pose_fingerprint`] of the pose judged; [`append_label`] fills it in. Marks
    /// written before marks carried one have none (see [`tie_marks_to_poses`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pose: Option<String>,
}

/// What a reviewer sees of a frame's pose, as 12 hex digits: whether one was found, where
/// (`T_world_tray`) and the verification's verdict. Timings and counts do not change it, so
/// estimating again to the same poses keeps the marks.
pub fn pose_fingerprint(r: &FrameRecord) -> String {
    let seen = serde_json::json!([r.found, r.found.then_some(r.t_world_tray), r.verdict]);
    ContentHash::of(seen.to_string().as_bytes()).short()
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
    parse_labels(&text, frames, &path)
}

/// The marks of a `labels.jsonl`'s text, each checked to name one of `frames` (sorted);
/// errors name `path` and the line.
pub fn parse_labels(text: &str, frames: &[String], path: &Path) -> Result<Vec<Label>> {
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
/// exists, with the fingerprint of the frame's present pose (`dir/poses.jsonl`); returns
/// the file's path.
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
    let poses = read_poses(dir)?;
    let Some(pose) = poses.iter().find(|p| p.frame == label.frame) else {
        return Err(Error::Other(format!(
            "{}: frame: expected a pose line for frame {}; estimate the dataset again",
            dir.join(POSES_FILE).display(),
            label.frame
        )));
    };
    let label = Label { pose: Some(pose_fingerprint(pose)), ..label.clone() };
    let line = format!("{}\n", serde_json::to_string(&label).expect("a label is plain data"));
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

/// Each frame's last mark made on its present pose in `poses`, and the frames marked only on
/// earlier poses (their marks judge nothing now). A mark without a fingerprint, written
/// before marks carried one, is taken to judge the present pose.
pub fn present_marks(labels: &[Label], poses: &[FrameRecord]) -> (Vec<(String, Mark)>, Vec<String>) {
    let mut marks: Vec<(String, Mark)> = Vec::new();
    let mut earlier: Vec<String> = Vec::new();
    for pose in poses {
        let fingerprint = pose_fingerprint(pose);
        let of_frame: Vec<&Label> = labels.iter().filter(|l| l.frame == pose.frame).collect();
        if of_frame.is_empty() {
            continue;
        }
        match of_frame.iter().rev().find(|l| l.pose.as_ref().is_none_or(|p| *p == fingerprint)) {
            Some(l) => marks.push((l.frame.clone(), l.mark)),
            None => earlier.push(pose.frame.clone()),
        }
    }
    (marks, earlier)
}

/// Ties the marks of `dir/labels.jsonl` that carry no fingerprint (written before marks
/// carried one) to the poses of `dir/poses.jsonl` they were made on, so that estimating the
/// frames again cannot hand them new poses to judge. Call it before `poses.jsonl` is
/// written again; returns how many marks it tied (the file is rewritten whole only then).
pub fn tie_marks_to_poses(dir: &Path) -> Result<usize> {
    let path = dir.join(LABELS_FILE);
    if !path.exists() || !dir.join(POSES_FILE).is_file() {
        return Ok(0);
    }
    let names = frame_names(dir)?;
    let mut labels = read_labels(dir, &names)?;
    if labels.iter().all(|l| l.pose.is_some()) {
        return Ok(0);
    }
    let poses = read_poses(dir)?;
    let mut tied = 0;
    for label in labels.iter_mut().filter(|l| l.pose.is_none()) {
        if let Some(pose) = poses.iter().find(|p| p.frame == label.frame) {
            label.pose = Some(pose_fingerprint(pose));
            tied += 1;
        }
    }
    let text: String =
        labels.iter().map(|l| format!("{}\n", serde_json::to_string(l).expect("a label is plain data"))).collect();
    camplace_config::write_atomic(&path, text.as_bytes())?;
    Ok(tied)
}

/// Every frame of a placement's dataset with its pose and judgement.
#[derive(Debug, Clone)]
pub struct JudgedDataset {
    /// The frames in order: name, pose line, judgement.
    pub frames: Vec<(String, FrameRecord, Judgement)>,
    /// Frames whose marks all judged earlier poses (not counted; open until marked again).
    pub marked_on_earlier_poses: Vec<String>,
}

impl JudgedDataset {
    /// Reads `dir`'s poses and labels: every frame of `frames/` must have a pose line.
    pub fn read(dir: &Path) -> Result<JudgedDataset> {
        let names = frame_names(dir)?;
        let poses = read_poses(dir)?;
        let labels = read_labels(dir, &names)?;
        let (marks, marked_on_earlier_poses) = present_marks(&labels, &poses);
        let mut frames = Vec::with_capacity(names.len());
        for name in names {
            let Some(pose) = poses.iter().find(|p| p.frame == name) else {
                return Err(Error::Other(format!(
                    "{}: frame: expected a pose line for frame {name}; estimate the placement again",
                    dir.join(POSES_FILE).display()
                )));
            };
            let judgement = match (&pose.score, marks.iter().find(|(frame, _)| *frame == name)) {
                (Some(s), _) => Judgement::Truth(s.success),
                (None, Some((_, mark))) => Judgement::Marked(*mark),
                (None, None) => Judgement::Open,
            };
            frames.push((name, pose.clone(), judgement));
        }
        Ok(JudgedDataset { frames, marked_on_earlier_poses })
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
