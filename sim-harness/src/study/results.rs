//! The study's results file `results.jsonl`: one line per finished (placement, scenario),
//! appended the moment the scene is done, so a killed run loses only the scenes in flight.
//! It owns the line format ([`ResultLine`]), reading a file back (a torn last line from a
//! kill is cut off), and the in-memory index a re-run uses to skip finished scenes.

use std::collections::HashMap;
use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use camplace_config::Placement;
use serde::{Deserialize, Serialize};

use super::record::FrameRecord;
use crate::render::Method;
use crate::{Error, Result};

/// One line of `results.jsonl`: which scene it was, then the frame's record.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ResultLine {
    /// The placement, as `r=..,alpha=..,baseline=..,vergence=..`.
    pub placement: String,
    /// `one-shot` or `phase-12`.
    pub method: String,
    /// The study seed the scenario was drawn with.
    pub seed: u64,
    /// The scenario index within the seed.
    pub scenario: u64,
    /// The frame's result.
    #[serde(flatten)]
    pub record: FrameRecord,
}

impl ResultLine {
    /// The key that identifies the scene.
    pub fn key(&self) -> SceneKey {
        SceneKey {
            placement: self.placement.clone(),
            method: self.method.clone(),
            seed: self.seed,
            scenario: self.scenario,
        }
    }
}

/// What makes two result lines the same scene.
#[derive(Debug, Clone, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct SceneKey {
    /// The placement text.
    pub placement: String,
    /// The method's name.
    pub method: String,
    /// The study seed.
    pub seed: u64,
    /// The scenario index.
    pub scenario: u64,
}

impl SceneKey {
    /// The key of scenario `scenario` of `seed` at `placement` with `method`.
    pub fn new(placement: &Placement, method: Method, seed: u64, scenario: u64) -> SceneKey {
        SceneKey { placement: placement.to_string(), method: method.to_string(), seed, scenario }
    }
}

/// The results of a study folder (or of memory only): every line read at open, and those
/// added since; `add` appends to the file at once.
#[derive(Debug)]
pub struct ResultsStore {
    file: Option<(PathBuf, Mutex<File>)>,
    lines: Mutex<HashMap<SceneKey, ResultLine>>,
}

impl ResultsStore {
    /// Results kept in memory only (an acceptance test without an output folder).
    pub fn in_memory() -> ResultsStore {
        ResultsStore { file: None, lines: Mutex::new(HashMap::new()) }
    }

    /// Opens (or creates) `path`, reading the lines already there. A last line without
    /// its newline is what a kill mid-write leaves: it is cut off and its scene redone.
    /// A scene found twice keeps its first line.
    pub fn open(path: &Path) -> Result<ResultsStore> {
        let mut lines = HashMap::new();
        if path.exists() {
            for line in read_lines(path)? {
                lines.entry(line.key()).or_insert(line);
            }
        }
        let file = OpenOptions::new()
            .create(true)
            .append(true)
            .open(path)
            .map_err(|e| Error::Other(format!("{}: cannot open for appending: {e}", path.display())))?;
        Ok(ResultsStore { file: Some((path.to_path_buf(), Mutex::new(file))), lines: Mutex::new(lines) })
    }

    /// Whether the scene is done.
    pub fn contains(&self, key: &SceneKey) -> bool {
        self.lines.lock().expect("results lock").contains_key(key)
    }

    /// Records a finished scene: appended to the file (one write of one whole line) and
    /// kept in memory.
    pub fn add(&self, line: ResultLine) -> Result<()> {
        if let Some((path, file)) = &self.file {
            let mut text = serde_json::to_string(&line).expect("a result line is plain data");
            text.push('\n');
            let mut f = file.lock().expect("results file lock");
            f.write_all(text.as_bytes())
                .map_err(|e| Error::Other(format!("{}: cannot append: {e}", path.display())))?;
        }
        self.lines.lock().expect("results lock").insert(line.key(), line);
        Ok(())
    }

    /// Every line, sorted by key.
    #[cfg(test)]
    pub fn all(&self) -> Vec<ResultLine> {
        let mut v: Vec<ResultLine> = self.lines.lock().expect("results lock").values().cloned().collect();
        v.sort_by_key(ResultLine::key);
        v
    }

    /// The records of scenarios `0..count` of `seed` at `placement` with `method` that are done.
    pub fn records(&self, placement: &Placement, method: Method, seed: u64, count: u64) -> Vec<FrameRecord> {
        let lines = self.lines.lock().expect("results lock");
        (0..count)
            .filter_map(|i| lines.get(&SceneKey::new(placement, method, seed, i)).map(|l| l.record.clone()))
            .collect()
    }
}

/// Reads every complete line of a results file; a torn last line is cut off the file.
pub fn read_lines(path: &Path) -> Result<Vec<ResultLine>> {
    let text =
        std::fs::read_to_string(path).map_err(|e| Error::Other(format!("{}: cannot read: {e}", path.display())))?;
    let complete = match text.rfind('\n') {
        Some(i) => i + 1,
        None => 0,
    };
    if complete < text.len() {
        let f = OpenOptions::new()
            .write(true)
            .open(path)
            .map_err(|e| Error::Other(format!("{}: cannot repair a torn last line: {e}", path.display())))?;
        f.set_len(complete as u64)
            .map_err(|e| Error::Other(format!("{}: cannot repair a torn last line: {e}", path.display())))?;
    }
    let mut out = Vec::new();
    for (n, line) in text[..complete].lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let parsed: ResultLine = serde_json::from_str(line).map_err(|e| {
            Error::Other(format!("{}: line {}: expected a study result line: {e}", path.display(), n + 1))
        })?;
        out.push(parsed);
    }
    Ok(out)
}

/// Writes `lines` as a whole results file, atomically.
pub fn write_lines(path: &Path, lines: &[ResultLine]) -> Result<()> {
    let mut text = String::new();
    for l in lines {
        text.push_str(&serde_json::to_string(l).expect("a result line is plain data"));
        text.push('\n');
    }
    Ok(camplace_config::write_atomic(path, text.as_bytes())?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use camplace_estimator::PoseEstimate;

    fn line(scenario: u64) -> ResultLine {
        let placement = camplace_config::Cell::default().placement;
        ResultLine {
            placement: placement.to_string(),
            method: Method::OneShot.to_string(),
            seed: 3,
            scenario,
            record: FrameRecord::new(format!("{scenario:04}"), &PoseEstimate::default()),
        }
    }

    #[test]
    fn a_torn_last_line_is_cut_and_the_rest_kept() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("results.jsonl");
        {
            let store = ResultsStore::open(&path).unwrap();
            store.add(line(0)).unwrap();
            store.add(line(1)).unwrap();
        }
        let whole = std::fs::read_to_string(&path).unwrap();
        let torn = serde_json::to_string(&line(2)).unwrap();
        std::fs::write(&path, format!("{whole}{}", &torn[..torn.len() / 2])).unwrap();
        let store = ResultsStore::open(&path).unwrap();
        assert_eq!(store.all(), vec![line(0), line(1)]);
        store.add(line(2)).unwrap();
        assert_eq!(read_lines(&path).unwrap(), vec![line(0), line(1), line(2)]);
    }
}
