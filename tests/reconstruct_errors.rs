//! `camplace reconstruct` on inputs that are not a stereo pair: one stderr line naming the
//! offending file, exit 2.

use std::path::Path;

use crate::camplace_cmd::{assert_one_line_error, camplace, stderr};

/// A rendered pair with its `rig.json` in `dir` (left.png, right.png, rig.json).
fn rendered_pair(dir: &Path) {
    let o = camplace(dir, &["render", "--out", "."]);
    assert!(o.status.success(), "render failed: {}", stderr(&o));
}

fn reconstruct(dir: &Path, left: &str, right: &str, rig: &str) -> (i32, String) {
    let o = camplace(dir, &["reconstruct", "--left", left, "--right", right, "--rig", rig, "--out", "out"]);
    (o.status.code().unwrap_or(-1), stderr(&o))
}

#[test]
fn images_of_different_sizes() {
    let dir = tempfile::tempdir().unwrap();
    rendered_pair(dir.path());
    let right = camplace_config::read_gray(&dir.path().join("right.png")).unwrap();
    // The right image cropped by one column.
    let (w, h) = (right.width - 1, right.height);
    let cropped: Vec<u8> = (0..h).flat_map(|y| right.data[y * right.width..y * right.width + w].to_vec()).collect();
    camplace_config::write_gray(&dir.path().join("small.png"), w, h, &cropped).unwrap();
    let (code, err) = reconstruct(dir.path(), "left.png", "small.png", "rig.json");
    assert_one_line_error(code, &err, &["small.png", &format!("{} x {h}", right.width), &format!("{w} x {h}")]);
}

#[test]
fn a_file_that_is_not_a_png() {
    let dir = tempfile::tempdir().unwrap();
    rendered_pair(dir.path());
    std::fs::write(dir.path().join("junk.png"), b"\x00\x01 not an image \xff").unwrap();
    let (code, err) = reconstruct(dir.path(), "junk.png", "right.png", "rig.json");
    assert_one_line_error(code, &err, &["junk.png", "not a readable image"]);
    let (code, err) = reconstruct(dir.path(), "left.png", "missing.png", "rig.json");
    assert_one_line_error(code, &err, &["missing.png"]);
}

#[test]
fn a_rig_without_a_right_camera() {
    let dir = tempfile::tempdir().unwrap();
    rendered_pair(dir.path());
    let text = std::fs::read_to_string(dir.path().join("rig.json")).unwrap();
    let mut rig: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert!(rig.as_object_mut().unwrap().remove("right").is_some(), "rig.json has a right camera");
    std::fs::write(dir.path().join("left-only.json"), serde_json::to_string_pretty(&rig).unwrap()).unwrap();
    let (code, err) = reconstruct(dir.path(), "left.png", "right.png", "left-only.json");
    assert_one_line_error(code, &err, &["left-only.json", "right"]);
}
