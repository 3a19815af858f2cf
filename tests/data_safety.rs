//! Datasets and study folders that cannot be damaged: frames written whole and numbered
//! on without wrapping, a frame unlike the dataset refused, merge never writing into its
//! inputs or over results of unknown settings, and a study folder locked by the run working
//! in it (a dead run's lock taken over). Every refusal leaves the earlier files as they were.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Duration;

use crate::camplace_cmd::{assert_one_line_error, camplace, stderr};

/// Every file under `root` with its bytes.
fn snapshot(root: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut out = BTreeMap::new();
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
fn capture_never_wraps_overwrites_or_mixes_a_dataset() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let o = camplace(d, &["render", "--dataset", "--count", "1", "--out", "src"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = camplace(d, &["capture", "--source", "dir:src", "--out", "cap"]);
    assert!(o.status.success(), "{}", stderr(&o));
    // The last number a dataset takes, and one past what u64 holds.
    for (name, expected) in [("99999999", "the last a dataset takes"), ("18446744073709551615", "past")] {
        let held = d.join("cap/frames").join(name);
        std::fs::create_dir_all(&held).unwrap();
        std::fs::copy(d.join("cap/frames/0000/left.png"), held.join("left.png")).unwrap();
        std::fs::copy(d.join("cap/frames/0000/right.png"), held.join("right.png")).unwrap();
        let before = snapshot(&d.join("cap"));
        let o = camplace(d, &["capture", "--source", "dir:src", "--out", "cap"]);
        assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &[name, expected]);
        assert_eq!(snapshot(&d.join("cap")), before, "{name}: nothing written");
        std::fs::remove_dir_all(&held).unwrap();
    }
    // A frame of another method (12 shots) or another image size is refused.
    let o = camplace(d, &["render", "--dataset", "--count", "1", "--method", "phase-12", "--out", "twelve"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let before = snapshot(&d.join("cap"));
    let o = camplace(d, &["capture", "--source", "dir:twelve", "--out", "cap"]);
    assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["cap/frames/0000", "shot"]);
    std::fs::write(d.join("small.toml"), "[sensor]\ncamera_resolution = [320, 240]\n").unwrap();
    let o = camplace(d, &["render", "--cell", "small.toml", "--dataset", "--count", "1", "--out", "small"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = camplace(d, &["capture", "--source", "dir:small", "--out", "cap"]);
    assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["cap/rig.json", "320x240"]);
    assert_eq!(snapshot(&d.join("cap")), before, "refusals write nothing");
    // A frame half written by a killed capture is skipped by readers and cleared by the next capture.
    let half = d.join("cap/frames/.0001.camplace-tmp-999999999");
    std::fs::create_dir_all(&half).unwrap();
    std::fs::write(half.join("left.png"), b"torn").unwrap();
    let o = camplace(d, &["reconstruct", "--dataset", "cap"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = camplace(d, &["capture", "--source", "dir:src", "--out", "cap"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!half.exists() && d.join("cap/frames/0001/left.png").is_file());
}

fn small_cell() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/small_cell.toml").display().to_string()
}

#[test]
fn merge_never_writes_into_its_inputs_nor_over_results_of_unknown_settings() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cell = small_cell();
    let o = camplace(d, &["evaluate", "--cell", &cell, "--scenarios", "1", "--out", "a"]);
    assert!(o.status.success(), "{}", stderr(&o));
    // Results without settings.
    std::fs::create_dir_all(d.join("lost")).unwrap();
    std::fs::write(d.join("lost/results.jsonl"), "{\"earlier\": 1}\n".repeat(44)).unwrap();
    // A study tree.
    std::fs::create_dir_all(d.join("tree/tray-8")).unwrap();
    for e in ["settings.json", "results.jsonl"] {
        std::fs::copy(d.join("a").join(e), d.join("tree/tray-8").join(e)).unwrap();
    }
    for (out, expected) in [
        ("lost", "without the settings"),
        ("a", "never writes into its inputs"),
        ("a/inner", "never writes into its inputs"),
        ("tree", "study folder"),
    ] {
        let before = snapshot(d);
        let o = camplace(d, &["merge", "a", "--out", out]);
        assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["--out", out, expected]);
        assert_eq!(snapshot(d), before, "--out {out}: nothing written");
    }
}

#[test]
fn a_study_folder_is_held_by_its_run_and_a_dead_runs_hold_is_taken_over() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cell = small_cell();
    let args = ["evaluate", "--cell", &cell, "--seed", "5", "--scenarios", "6", "--out", "held"];
    let mut first = Command::new(env!("CARGO_BIN_EXE_camplace"))
        .args(args)
        .current_dir(d)
        .env("RAYON_NUM_THREADS", "1")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let results = d.join("held/results.jsonl");
    let lines = |p: &Path| std::fs::read_to_string(p).map_or(0, |t| t.lines().count());
    while lines(&results) < 1 {
        if let Some(status) = first.try_wait().unwrap() {
            panic!("evaluate ended before the second run: {status}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let o = camplace(d, &args);
    let pid = format!("pid {}", first.id());
    assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["held/study.lock", &pid, "in use"]);
    first.kill().unwrap(); // SIGKILL: the lock stays behind, naming a dead process
    first.wait().unwrap();
    assert!(d.join("held/study.lock").exists());
    let before = lines(&results);
    assert!(before < 6, "the run finished before the kill ({before} lines)");
    let o = camplace(d, &args);
    assert!(o.status.success(), "the dead run's lock is taken over: {}", stderr(&o));
    let scenarios: Vec<u64> = std::fs::read_to_string(&results)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap()["scenario"].as_u64().unwrap())
        .collect();
    let mut sorted = scenarios.clone();
    sorted.sort_unstable();
    assert_eq!(sorted, (0..6).collect::<Vec<_>>(), "resumed, each scenario once: {scenarios:?}");
    assert!(!d.join("held/study.lock").exists(), "released at the end");
}

/// Makes a FIFO at `path` (never at one of the machine's own device nodes).
#[cfg(unix)]
fn mkfifo(path: &Path) {
    let made = Command::new("mkfifo").arg(path).status().expect("mkfifo runs");
    assert!(made.success(), "mkfifo {}", path.display());
}

/// What `path` itself is (a symbolic link not followed).
#[cfg(unix)]
fn file_kind(path: &Path) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    let t = std::fs::symlink_metadata(path).expect("still there").file_type();
    match () {
        _ if t.is_fifo() => "fifo",
        _ if t.is_socket() => "socket",
        _ if t.is_symlink() => "symlink",
        _ if t.is_dir() => "dir",
        _ if t.is_file() => "file",
        _ => "other",
    }
}

#[test]
#[cfg(unix)]
fn a_file_output_naming_a_fifo_a_socket_or_a_folder_is_refused_and_left_as_it_was() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cell = small_cell();
    mkfifo(&d.join("pipe"));
    std::os::unix::fs::symlink("pipe", d.join("link")).unwrap();
    let _socket = std::os::unix::net::UnixListener::bind(d.join("sock")).unwrap();
    std::fs::create_dir(d.join("folder")).unwrap();
    std::fs::write(d.join("folder/kept"), b"the user's").unwrap();
    let cases = [
        ("pipe", "FIFO", "fifo"),
        ("link", "FIFO", "symlink"),
        ("sock", "socket", "socket"),
        ("folder", "a folder", "dir"),
    ];
    for (out, what, kind) in cases {
        let model = camplace(d, &["model", "--cell", &cell, "--verify-scenes", "0", "--out", out]);
        assert_one_line_error(model.status.code().unwrap(), &stderr(&model), &[out, what, "regular file"]);
        let init = camplace(d, &["init", out, "--force"]);
        assert_one_line_error(init.status.code().unwrap(), &stderr(&init), &[out, what, "regular file"]);
        assert_eq!(file_kind(&d.join(out)), kind, "{out} left as it was");
    }
    assert_eq!(file_kind(&d.join("pipe")), "fifo");
    assert_eq!(snapshot(&d.join("folder")), BTreeMap::from([(PathBuf::from("kept"), b"the user's".to_vec())]));
    // A folder output naming a FIFO is refused too, the FIFO kept.
    let render = camplace(d, &["render", "--cell", &cell, "--out", "pipe"]);
    assert_eq!(render.status.code(), Some(2), "{}", stderr(&render));
    assert!(stderr(&render).contains("pipe"), "{}", stderr(&render));
    assert_eq!(file_kind(&d.join("pipe")), "fifo");
    let names: Vec<String> =
        std::fs::read_dir(d).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    assert!(names.iter().all(|n| !n.contains("camplace-tmp")), "no temporary file left: {names:?}");
}

#[test]
fn model_writes_neither_file_when_one_of_its_outputs_cannot_be_written() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cell = small_cell();
    let args = ["model", "--cell", &cell, "--verify-scenes", "0", "--ply", "no/such/dir/x.ply", "--out", "m.model"];
    let o = camplace(d, &args);
    assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["no/such/dir"]);
    assert!(!d.join("m.model").exists(), "no model written when its cloud cannot be");
    std::fs::write(d.join("m.model"), b"an earlier model").unwrap();
    let before = snapshot(d);
    let o = camplace(d, &args);
    assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["no/such/dir"]);
    assert_eq!(snapshot(d), before, "the earlier model left byte for byte");
    // Both outputs written when both can be.
    let o = camplace(d, &["model", "--cell", &cell, "--verify-scenes", "0", "--ply", "x.ply", "--out", "m.model"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_ne!(std::fs::read(d.join("m.model")).unwrap(), b"an earlier model");
    assert!(d.join("x.ply").is_file());
}
