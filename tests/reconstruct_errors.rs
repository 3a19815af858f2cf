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
    assert_one_line_error(code, &err, &["junk.png", "not a readable PNG image"]);
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

/// A rectified pair that sees a fronto-parallel plane: random dots, the right image the left
/// shifted by `shift` pixels.
fn shifted_pair(dir: &Path, shift: usize) {
    let (w, h) = (160, 96);
    let mut state = 0x9e37_79b9_7f4a_7c15_u64;
    let left: Vec<u8> = (0..w * h)
        .map(|_| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 56) as u8
        })
        .collect();
    let right: Vec<u8> =
        (0..h).flat_map(|y| (0..w).map(move |x| (y, x))).map(|(y, x)| left[y * w + (x + shift).min(w - 1)]).collect();
    camplace_config::write_gray(&dir.join("left.png"), w, h, &left).unwrap();
    camplace_config::write_gray(&dir.join("right.png"), w, h, &right).unwrap();
}

#[test]
fn a_rectified_pair_gives_the_depth_of_its_plane() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    shifted_pair(d, 12);
    let o = camplace(
        d,
        &[
            "reconstruct",
            "--left",
            "left.png",
            "--right",
            "right.png",
            "--rectified",
            "--focal-px",
            "800",
            "--baseline-mm",
            "80",
            "--disparity-range",
            "0:40",
            "--out",
            "out",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let depth = camplace_config::read_pfm(&d.join("out/depth.pfm")).unwrap().data;
    let mut seen: Vec<f32> = depth.iter().copied().filter(|z| z.is_finite()).collect();
    assert!(seen.len() > depth.len() / 2, "{} of {} pixels have a depth", seen.len(), depth.len());
    seen.sort_by(f32::total_cmp);
    let median = seen[seen.len() / 2];
    // z = f b / d = 800 * 80 / 12.
    assert!((median - 800.0 * 80.0 / 12.0).abs() < 0.01 * 800.0 * 80.0 / 12.0, "median depth {median}");
}

#[test]
fn rectified_numbers_that_mean_nothing_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    shifted_pair(d, 12);
    let cases: [(&[&str], &str); 7] = [
        (&["--focal-px", "0", "--baseline-mm", "80"], "--focal-px"),
        (&["--focal-px", "-800", "--baseline-mm", "80"], "--focal-px"),
        (&["--focal-px", "NaN", "--baseline-mm", "80"], "--focal-px"),
        (&["--focal-px", "800", "--baseline-mm", "inf"], "--baseline-mm"),
        (&["--focal-px", "800", "--baseline-mm", "0"], "--baseline-mm"),
        (&["--focal-px", "800", "--baseline-mm", "80", "--disparity-range", "0:3e9"], "--disparity-range"),
        (&["--focal-px", "800", "--baseline-mm", "80", "--disparity-range", "40:10"], "--disparity-range"),
    ];
    for (extra, flag) in cases {
        let mut args = vec!["reconstruct", "--left", "left.png", "--right", "right.png", "--rectified", "--out", "out"];
        args.extend_from_slice(extra);
        let o = camplace(d, &args);
        assert_one_line_error(o.status.code().unwrap_or(-1), &stderr(&o), &[flag]);
        assert!(!d.join("out/depth.pfm").exists(), "{extra:?} wrote a depth map");
    }
}
