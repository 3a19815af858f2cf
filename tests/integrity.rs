//! Study folders, model caches and datasets refuse what does not belong to them: a tray mesh
//! edited in place, results without settings, a cached model of another cell, a dataset
//! folder holding an earlier dataset or other files, merges of folders that are not studies
//! or have other seeds; and a damaged results line or a killed run's temporary files do not
//! stop a resume, whose results stay those of an uninterrupted run.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use camplace_config::Cell;
use camplace_sim::{open_folder, Method};

use crate::camplace_cmd::{assert_one_line_error, camplace, stderr};
use crate::meshes::box_stl;
use crate::study_folder::results_without_timings;

fn small_cell() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/small_cell.toml").display().to_string()
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        if e.path().is_dir() {
            copy_dir(&e.path(), &to.join(e.file_name()));
        } else {
            std::fs::copy(e.path(), to.join(e.file_name())).unwrap();
        }
    }
}

/// A small study folder of 2 scenes (with its cached model), evaluated once for the tests
/// here; each test works on its own copy.
fn evaluated_folder() -> &'static Path {
    static FOLDER: OnceLock<(tempfile::TempDir, PathBuf)> = OnceLock::new();
    &FOLDER
        .get_or_init(|| {
            let dir = tempfile::tempdir().unwrap();
            let cell = small_cell();
            let o = camplace(
                dir.path(),
                &["evaluate", "--cell", &cell, "--seed", "5", "--scenarios", "2", "--out", "base"],
            );
            assert!(o.status.success(), "{}", stderr(&o));
            let base = dir.path().join("base");
            (dir, base)
        })
        .1
}

#[test]
fn a_tray_mesh_edited_in_place_is_refused_by_its_study_folder() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("tray.stl"), box_stl([200.0, 150.0, 20.0])).unwrap();
    std::fs::write(d.join("cell.toml"), "[tray]\nkind = \"mesh\"\nmesh = \"tray.stl\"\n").unwrap();
    let cell = Cell::load(&d.join("cell.toml")).unwrap();
    drop(open_folder(&d.join("study"), &cell, Method::OneShot, 5).unwrap());
    // The same cell opens the folder again; the mesh edited in place does not.
    drop(open_folder(&d.join("study"), &cell, Method::OneShot, 5).unwrap());
    std::fs::write(d.join("tray.stl"), box_stl([200.0, 150.0, 25.0])).unwrap();
    let o = camplace(d, &["evaluate", "--cell", "cell.toml", "--seed", "5", "--scenarios", "1", "--out", "study"]);
    let err = stderr(&o);
    assert_one_line_error(
        o.status.code().unwrap_or(-1),
        &err,
        &["study/settings.json: built for a cell with hash", "(tray mesh tray.stl changed?)", "use a new folder"],
    );
}

#[test]
fn results_without_settings_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    drop(open_folder(&d.join("study"), &Cell::default(), Method::OneShot, 5).unwrap());
    std::fs::write(d.join("study/results.jsonl"), "{\"a result line\": 1}\n").unwrap();
    std::fs::remove_file(d.join("study/settings.json")).unwrap();
    std::fs::write(d.join("tray4.toml"), "[tray]\nkind = \"tray-4\"\n").unwrap();
    let o = camplace(d, &["evaluate", "--cell", "tray4.toml", "--seed", "5", "--scenarios", "1", "--out", "study"]);
    let err = stderr(&o);
    assert_one_line_error(o.status.code().unwrap_or(-1), &err, &["study/settings.json: missing", "results.jsonl"]);
    assert!(!d.join("study/settings.json").exists());
}

#[test]
fn a_cached_model_of_another_cell_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    copy_dir(evaluated_folder(), &d.join("f"));
    let models: Vec<PathBuf> = std::fs::read_dir(d.join("f/models")).unwrap().map(|e| e.unwrap().path()).collect();
    assert_eq!(models.len(), 1, "{models:?}");
    let mut model = camplace_estimator::Model::from_bytes(&std::fs::read(&models[0]).unwrap()).unwrap();
    let origin = model.origin.as_mut().expect("a study's model records its origin");
    assert_eq!(origin.cell_hash, Cell::load(Path::new(&small_cell())).unwrap().hashes().unwrap().cell);
    origin.cell_hash = Cell::default().hashes().unwrap().cell;
    std::fs::write(&models[0], model.to_bytes()).unwrap();
    let cell = small_cell();
    let o = camplace(d, &["evaluate", "--cell", &cell, "--seed", "5", "--scenarios", "3", "--out", "f"]);
    let err = stderr(&o);
    let name = models[0].file_name().unwrap().to_string_lossy().into_owned();
    assert_one_line_error(
        o.status.code().unwrap_or(-1),
        &err,
        &[&name, "built for a cell with hash", "use a new folder"],
    );
}

#[test]
fn a_damaged_results_line_is_set_aside_and_its_scene_computed_again() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let f = d.join("f");
    copy_dir(evaluated_folder(), &f);
    let whole = results_without_timings(&f.join("results.jsonl"));
    let text = std::fs::read_to_string(f.join("results.jsonl")).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    let damaged = format!("#{}", &lines[0][1..]);
    std::fs::write(f.join("results.jsonl"), format!("{damaged}\n{}\n", lines[1])).unwrap();
    // What a run killed while writing the model and a summary leaves.
    let stale = [f.join(format!("models/.x.model.camplace-tmp-{}", u32::MAX)), f.join(".summary.json.tmp4294967295")];
    for p in &stale {
        std::fs::write(p, b"half a file").unwrap();
    }
    let cell = small_cell();
    let o = camplace(d, &["evaluate", "--cell", &cell, "--seed", "5", "--scenarios", "2", "--out", "f"]);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    let notes: Vec<&str> = err.lines().filter(|l| l.contains("results.rejected.jsonl")).collect();
    assert_eq!(notes.len(), 1, "{err}");
    assert!(notes[0].contains("1 damaged line (line 1)") && notes[0].contains("computed again"), "{err}");
    assert_eq!(std::fs::read_to_string(f.join("results.rejected.jsonl")).unwrap(), format!("{damaged}\n"));
    assert_eq!(results_without_timings(&f.join("results.jsonl")), whole, "the scene computed again is the same");
    for p in &stale {
        assert!(!p.exists(), "{} left", p.display());
    }
}

#[test]
fn merge_refuses_a_folder_that_is_not_a_study_and_names_seeds_in_order() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cell = Cell::default();
    drop(open_folder(&d.join("a"), &cell, Method::OneShot, 1).unwrap());
    drop(open_folder(&d.join("b"), &cell, Method::OneShot, 2).unwrap());
    std::fs::create_dir_all(d.join("plain/sub")).unwrap();
    std::fs::write(d.join("plain/notes.txt"), "not a study").unwrap();
    let o = camplace(d, &["merge", "a", "plain", "--out", "m"]);
    assert_one_line_error(o.status.code().unwrap_or(-1), &stderr(&o), &["plain: not a study folder"]);
    let o = camplace(d, &["merge", "a", "b", "--out", "m"]);
    let err = stderr(&o);
    assert_one_line_error(
        o.status.code().unwrap_or(-1),
        &err,
        &["a/settings.json has seed 1, b/settings.json has seed 2"],
    );
    let o = camplace(d, &["merge", "b", "a", "--out", "m"]);
    let err = stderr(&o);
    assert_one_line_error(
        o.status.code().unwrap_or(-1),
        &err,
        &["b/settings.json has seed 2, a/settings.json has seed 1"],
    );
    assert!(!d.join("m").exists());
}

#[test]
fn render_into_a_dataset_folder_refuses_unless_forced_and_force_removes_only_its_files() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cell = small_cell();
    let render = |count: &str, force: bool| {
        let mut args = vec!["render", "--cell", &cell, "--dataset", "--count", count, "--seed", "1", "--out", "data"];
        if force {
            args.push("--force");
        }
        camplace(d, &args)
    };
    let o = render("2", false);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = camplace(d, &["reconstruct", "--dataset", "data"]);
    assert!(o.status.success(), "{}", stderr(&o));
    std::fs::write(d.join("data/poses.jsonl"), "").unwrap();
    std::fs::write(d.join(format!("data/frames/0001/.left.png.camplace-tmp-{}", u32::MAX)), "").unwrap();

    let o = render("1", false);
    assert_one_line_error(o.status.code().unwrap_or(-1), &stderr(&o), &["data", "not empty", "--force"]);
    std::fs::write(d.join("data/frames/0001/notes.txt"), "mine").unwrap();
    let o = render("1", true);
    assert_one_line_error(o.status.code().unwrap_or(-1), &stderr(&o), &["notes.txt", "nothing was removed"]);
    assert!(d.join("data/frames/0001/left.png").exists() && d.join("data/poses.jsonl").exists());

    std::fs::remove_file(d.join("data/frames/0001/notes.txt")).unwrap();
    let o = render("1", true);
    assert!(o.status.success(), "{}", stderr(&o));
    let frames: Vec<String> = std::fs::read_dir(d.join("data/frames"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(frames, ["0000"]);
    assert!(!d.join("data/poses.jsonl").exists());
    assert!(!d.join("data/frames/0000/cloud.ply").exists(), "the earlier reconstruction is gone");
}
