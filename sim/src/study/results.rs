//! The study's results file `results.jsonl`: one line per finished (placement, scenario),
//! appended the moment the scene is done, so a killed run loses only the scenes in flight.
//! It owns the line format ([`ResultLine`]), reading a file back (a torn last line from a
//! kill is cut off; a damaged complete line is moved aside to `results.rejected.jsonl` and
//! its scene computed again), and the in-memory index a re-run uses to skip finished scenes.

use std::collections::HashMap;
use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use camplace_config::Placement;
use serde::{Deserialize, Serialize};

use crate::render::Method;
use crate::{Error, Result};
use camplace_estimator::scoring::FrameRecord;

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
    /// The hold on the file's folder while the store is open.
    _lock: Option<super::lock::FolderLock>,
}

impl ResultsStore {
    /// Results kept in memory only (an acceptance test without an output folder).
    pub fn in_memory() -> ResultsStore {
        ResultsStore { file: None, lines: Mutex::new(HashMap::new()), _lock: None }
    }

    /// Opens (or creates) `path`, reading the lines already there. A last line without
    /// its newline is what a kill mid-write leaves: it is cut off and its scene redone. A
    /// complete line that is not a result line (a damaged disk block, a hand edit) is moved
    /// to [`REJECTED_FILE`] beside it, said in one line on stderr, and its scene redone.
    /// A scene found twice keeps its first line. The folder is locked while the store is
    /// open: another process's run on it is refused (see [`super::lock`]).
    pub fn open(path: &Path) -> Result<ResultsStore> {
        let folder = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
        let lock = super::lock::lock_folder(folder)?;
        let mut lines = HashMap::new();
        if path.exists() {
            let read = read_results(path)?;
            if !read.rejected.is_empty() {
                set_rejected_aside(path, &read)?;
            }
            for line in read.lines {
                lines.entry(line.key()).or_insert(line);
            }
        }
        let file = OpenOptions::new()
            .create(true)
            .append(true)
            .open(path)
            .map_err(|e| Error::Other(format!("{}: cannot open for appending: {e}", path.display())))?;
        Ok(ResultsStore {
            file: Some((path.to_path_buf(), Mutex::new(file))),
            lines: Mutex::new(lines),
            _lock: Some(lock),
        })
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
    /// Whether scenario 0..count succeeded, by scenario index (`None` where the scene is
    /// not in the folder or has no truth to score against): for comparisons paired by scene.
    pub fn outcomes(&self, placement: &Placement, method: Method, seed: u64, count: u64) -> Vec<Option<bool>> {
        let lines = self.lines.lock().expect("results lock");
        (0..count)
            .map(|i| {
                lines.get(&SceneKey::new(placement, method, seed, i)).and_then(|l| l.record.score.map(|s| s.success))
            })
            .collect()
    }

    pub fn records(&self, placement: &Placement, method: Method, seed: u64, count: u64) -> Vec<FrameRecord> {
        let lines = self.lines.lock().expect("results lock");
        (0..count)
            .filter_map(|i| lines.get(&SceneKey::new(placement, method, seed, i)).map(|l| l.record.clone()))
            .collect()
    }
}

/// The file beside `results.jsonl` that keeps its damaged lines, appended to, never read back.
pub const REJECTED_FILE: &str = "results.rejected.jsonl";

/// A results file read back.
#[derive(Debug, Clone, Default)]
pub struct ReadResults {
    /// The result lines, in file order.
    pub lines: Vec<ResultLine>,
    /// The complete lines that are not result lines: (1-based line number, the line's bytes;
    /// of a line longer than [`MAX_RESULT_LINE_BYTES`], its first that many).
    pub rejected: Vec<(usize, Vec<u8>)>,
}

/// The longest line a results file holds, bytes: a scene's record is about a kilobyte, so
/// a longer line is damage, set aside without being held whole.
pub const MAX_RESULT_LINE_BYTES: usize = 1 << 20;

/// Reads `path` line by line, each complete line (without its newline, cut at
/// [`MAX_RESULT_LINE_BYTES`]) handed to `each` with its 1-based number; returns the bytes
/// of complete lines (a torn last line, with no newline, is not handed on).
fn each_line(path: &Path, mut each: impl FnMut(usize, &[u8])) -> Result<u64> {
    use std::io::{BufRead, Read};
    let (file, _) = camplace_config::open_checked(path, camplace_config::FileKind::Data)?;
    let cannot = |e: std::io::Error| Error::Other(format!("{}: cannot read: {e}", path.display()));
    let mut reader = std::io::BufReader::new(file);
    let (mut line, mut complete, mut number) = (Vec::new(), 0u64, 0usize);
    loop {
        line.clear();
        let n = (&mut reader).take(MAX_RESULT_LINE_BYTES as u64 + 1).read_until(b'\n', &mut line).map_err(cannot)?;
        if n == 0 {
            return Ok(complete);
        }
        let mut length = n as u64;
        let mut ended = line.last() == Some(&b'\n');
        if !ended && n > MAX_RESULT_LINE_BYTES {
            // Too long to be a record: skip to its end without holding it.
            line.truncate(MAX_RESULT_LINE_BYTES);
            let mut rest = Vec::new();
            loop {
                rest.clear();
                let m = (&mut reader).take(1 << 16).read_until(b'\n', &mut rest).map_err(cannot)?;
                length += m as u64;
                if m == 0 || rest.last() == Some(&b'\n') {
                    ended = m != 0;
                    break;
                }
            }
        }
        if !ended {
            return Ok(complete);
        }
        if line.last() == Some(&b'\n') {
            line.pop();
        }
        number += 1;
        complete += length;
        each(number, &line);
    }
}

impl ReadResults {
    /// One line saying which lines were rejected from `path` and what became of them.
    pub fn rejected_note(&self, path: &Path, what_became: &str) -> String {
        let numbers: Vec<String> = self.rejected.iter().take(10).map(|(n, _)| n.to_string()).collect();
        let more = if self.rejected.len() > 10 { ", ..." } else { "" };
        let (count, s) = (self.rejected.len(), if self.rejected.len() == 1 { "" } else { "s" });
        format!(
            "note: {}: {count} damaged line{s} (line{s} {}{more}) {what_became}",
            path.display(),
            numbers.join(", ")
        )
    }
}

/// One line of a results file (without its newline) as a result line; `Err` says why not.
pub fn parse_line(bytes: &[u8]) -> std::result::Result<ResultLine, String> {
    let text = std::str::from_utf8(bytes).map_err(|e| format!("not UTF-8 text: {e}"))?;
    serde_json::from_str(text).map_err(|e| format!("expected a study result line: {e}"))
}

/// Reads a results file: every complete line, the good ones parsed and the damaged ones set
/// apart; a torn last line (no newline: a kill mid-write) is cut off the file.
pub fn read_results(path: &Path) -> Result<ReadResults> {
    read_results_with(path, true)
}

/// Reads a results file as [`read_results`] does but leaves it as it is: a torn last line
/// is only left out (`merge` reads its inputs so and never writes into them).
pub fn read_results_unchanged(path: &Path) -> Result<ReadResults> {
    read_results_with(path, false)
}

fn read_results_with(path: &Path, repair: bool) -> Result<ReadResults> {
    let mut out = ReadResults::default();
    let complete = each_line(path, |n, line| {
        if line.iter().all(u8::is_ascii_whitespace) {
            return;
        }
        match parse_line(line) {
            Ok(parsed) => out.lines.push(parsed),
            Err(_) => out.rejected.push((n, line.to_vec())),
        }
    })?;
    let length =
        std::fs::metadata(path).map_err(|e| Error::Other(format!("{}: cannot read: {e}", path.display())))?.len();
    if repair && complete < length {
        let f = OpenOptions::new()
            .write(true)
            .open(path)
            .map_err(|e| Error::Other(format!("{}: cannot repair a torn last line: {e}", path.display())))?;
        f.set_len(complete)
            .map_err(|e| Error::Other(format!("{}: cannot repair a torn last line: {e}", path.display())))?;
    }
    Ok(out)
}

/// Appends `read`'s rejected lines to `to`, each on its own line.
pub fn append_rejected(to: &Path, read: &ReadResults) -> Result<()> {
    let mut text = Vec::new();
    for (_, line) in &read.rejected {
        text.extend_from_slice(line);
        text.push(b'\n');
    }
    let mut f = OpenOptions::new()
        .create(true)
        .append(true)
        .open(to)
        .map_err(|e| Error::Other(format!("{}: cannot open for appending: {e}", to.display())))?;
    f.write_all(&text)
        .and_then(|_| f.sync_all())
        .map_err(|e| Error::Other(format!("{}: cannot append: {e}", to.display())))
}

/// Moves `read`'s rejected lines out of `path` into [`REJECTED_FILE`] beside it: appended
/// there first, then `path` rewritten atomically with the good lines as they were, so a kill
/// in between loses no line (at worst one is kept twice in the rejected file).
fn set_rejected_aside(path: &Path, read: &ReadResults) -> Result<()> {
    let to = path.with_file_name(REJECTED_FILE);
    append_rejected(&to, read)?;
    // The good lines as they were, read again (only a damaged file pays for this).
    let rejected: std::collections::HashSet<usize> = read.rejected.iter().map(|(n, _)| *n).collect();
    let mut kept = Vec::new();
    each_line(path, |n, line| {
        if !rejected.contains(&n) && !line.iter().all(u8::is_ascii_whitespace) {
            kept.extend_from_slice(line);
            kept.push(b'\n');
        }
    })?;
    camplace_config::write_atomic(path, &kept)?;
    let became = format!("moved to {}; their scenes will be computed again", to.display());
    eprintln!("{}", read.rejected_note(path, &became));
    Ok(())
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
        assert_eq!(read_results(&path).unwrap().lines, vec![line(0), line(1), line(2)]);
    }

    #[test]
    fn a_damaged_line_is_moved_aside_and_its_scene_left_to_do() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("results.jsonl");
        let rejected = dir.path().join(REJECTED_FILE);
        let text = |l: &ResultLine| serde_json::to_string(l).unwrap();
        let damaged = format!("X{}", &text(&line(1))[1..]);
        std::fs::write(&path, format!("{}\n{damaged}\n{}\n", text(&line(0)), text(&line(2)))).unwrap();
        let store = ResultsStore::open(&path).unwrap();
        assert_eq!(store.all(), vec![line(0), line(2)]);
        assert_eq!(std::fs::read_to_string(&rejected).unwrap(), format!("{damaged}\n"));
        assert_eq!(std::fs::read_to_string(&path).unwrap(), format!("{}\n{}\n", text(&line(0)), text(&line(2))));
        drop(store);
        // Opened again: nothing more to move; a line damaged later is appended to the rest.
        let store = ResultsStore::open(&path).unwrap();
        assert_eq!(store.all(), vec![line(0), line(2)]);
        assert_eq!(std::fs::read_to_string(&rejected).unwrap(), format!("{damaged}\n"));
        store.add(line(1)).unwrap();
        drop(store);
        let mut bytes = std::fs::read(&path).unwrap();
        bytes[0] = 0xff;
        std::fs::write(&path, &bytes).unwrap();
        let store = ResultsStore::open(&path).unwrap();
        assert_eq!(store.all(), vec![line(1), line(2)]);
        assert_eq!(std::fs::read(&rejected).unwrap().split(|&b| b == b'\n').filter(|l| !l.is_empty()).count(), 2);
    }

    /// Every cut of a result line and seeded random byte changes: the parser returns, never
    /// panics, and a cut line is never taken for a result; a damaged file opens, keeps what
    /// reads, and reads back the same when opened again.
    #[test]
    fn result_lines_survive_truncation_and_flips() {
        use rand::{RngExt, SeedableRng};
        let mut good = line(4);
        good.record.score = Some(camplace_estimator::scoring::Score {
            position_error_mm: 1.25,
            rotation_error_deg: 0.5,
            correct_matches: 17,
            success: true,
        });
        let text = serde_json::to_string(&good).unwrap();
        assert_eq!(parse_line(text.as_bytes()).unwrap(), good);
        for n in 0..text.len() {
            assert!(parse_line(&text.as_bytes()[..n]).is_err(), "cut at {n}");
        }
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(21);
        for _ in 0..3000 {
            let mut b = text.as_bytes().to_vec();
            for _ in 0..rng.random_range(1..4) {
                let i = rng.random_range(0..b.len());
                b[i] = rng.random();
            }
            let _ = parse_line(&b);
        }
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("results.jsonl");
        let whole: String = (0..6).map(|i| serde_json::to_string(&line(i)).unwrap() + "\n").collect();
        for _ in 0..200 {
            let mut b = whole.as_bytes().to_vec();
            for _ in 0..rng.random_range(1..6) {
                let i = rng.random_range(0..b.len());
                b[i] = rng.random();
            }
            std::fs::write(&path, &b).unwrap();
            let first = ResultsStore::open(&path).unwrap().all();
            let rejected = std::fs::metadata(dir.path().join(REJECTED_FILE)).map_or(0, |m| m.len());
            assert_eq!(ResultsStore::open(&path).unwrap().all(), first);
            assert_eq!(std::fs::metadata(dir.path().join(REJECTED_FILE)).map_or(0, |m| m.len()), rejected);
            assert!(read_results(&path).unwrap().rejected.is_empty());
        }
    }
}
