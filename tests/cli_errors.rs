//! Bad input ends with one line naming the file, the key and what was expected, exit 2.

use crate::camplace_cmd::{camplace, stderr};

fn render_with_cell(cell_text: &str, extra: &[(&str, &[u8])]) -> (i32, String) {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("cell.toml"), cell_text).unwrap();
    for (name, bytes) in extra {
        std::fs::write(dir.path().join(name), bytes).unwrap();
    }
    let o = camplace(dir.path(), &["render", "--cell", "cell.toml", "--out", "out"]);
    (o.status.code().unwrap_or(-1), stderr(&o))
}

fn assert_one_line_error(code: i32, err: &str, must_name: &[&str]) {
    assert_eq!(code, 2, "exit code, stderr: {err}");
    assert_eq!(err.trim_end().lines().count(), 1, "one line: {err}");
    for s in must_name {
        assert!(err.contains(s), "{s:?} missing from: {err}");
    }
}

#[test]
fn unknown_key() {
    let (code, err) = render_with_cell("[placement]\nradius = 600\n", &[]);
    assert_one_line_error(code, &err, &["cell.toml", "placement.radius", "unknown key"]);
}

#[test]
fn negative_radius() {
    let (code, err) = render_with_cell("[placement]\nr = -600\n", &[]);
    assert_one_line_error(code, &err, &["cell.toml", "placement.r", "expected a positive"]);
}

#[test]
fn alpha_of_90_degrees_or_more() {
    let (code, err) = render_with_cell("[placement]\nalpha = 90\n", &[]);
    assert_one_line_error(code, &err, &["cell.toml", "placement.alpha", "[0, 90)"]);
}

#[test]
fn missing_mesh() {
    let (code, err) = render_with_cell("[tray]\nkind = \"mesh\"\nmesh = \"nowhere.stl\"\n", &[]);
    assert_one_line_error(code, &err, &["cell.toml", "tray.mesh", "nowhere.stl", "no such file"]);
}

#[test]
fn file_that_is_not_a_mesh() {
    let (code, err) =
        render_with_cell("[tray]\nkind = \"mesh\"\nmesh = \"tray.obj\"\n", &[("tray.obj", b"\x00\x01binary junk\xff")]);
    assert_one_line_error(code, &err, &["cell.toml", "tray.mesh", "tray.obj", "not"]);
}

#[test]
fn bad_placement_flag() {
    let dir = tempfile::tempdir().unwrap();
    let o = camplace(dir.path(), &["render", "--placement", "r=600,alpha=95", "--out", "out"]);
    let err = stderr(&o);
    assert_one_line_error(o.status.code().unwrap_or(-1), &err, &["placement.alpha"]);
}

#[test]
fn cell_file_that_does_not_exist() {
    let dir = tempfile::tempdir().unwrap();
    let o = camplace(dir.path(), &["render", "--cell", "missing.toml", "--out", "out"]);
    let err = stderr(&o);
    assert_one_line_error(o.status.code().unwrap_or(-1), &err, &["missing.toml", "no such file"]);
}

#[test]
fn init_writes_a_file_that_reads_back_as_the_default() {
    let dir = tempfile::tempdir().unwrap();
    let o = camplace(dir.path(), &["init", "my.toml"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let cell = camplace_config::Cell::load(&dir.path().join("my.toml")).unwrap();
    assert_eq!(cell, camplace_config::Cell::default());
    let again = camplace(dir.path(), &["init", "my.toml"]);
    assert_eq!(again.status.code(), Some(2), "refuses to overwrite");
}
