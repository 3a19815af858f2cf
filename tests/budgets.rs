//! Memory budgets: an endless device, a FIFO, an image that decodes huge, cameras whose
//! buffers would pass the budget and too many calibration views are refused before they
//! are read or allocated, each with one line naming the file (or flag) and key.

use std::path::Path;

use crate::camplace_cmd::{assert_one_line_error, camplace, stderr};

/// A grey PNG of `w` x `h` black pixels: small on disk however large it decodes.
pub fn black_png(path: &Path, w: u32, h: u32) {
    let file = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let mut enc = png::Encoder::new(file, w, h);
    enc.set_color(png::ColorType::Grayscale);
    enc.set_compression(png::Compression::High);
    let mut writer = enc.write_header().unwrap();
    let mut stream = writer.stream_writer().unwrap();
    let row = vec![0u8; w as usize];
    for _ in 0..h {
        std::io::Write::write_all(&mut stream, &row).unwrap();
    }
    stream.finish().unwrap();
}

/// A board-image folder (`frames/0000/`, `table/`) whose `frames/0000/left.png` is made by
/// `left`, the other images small black ones.
fn board_folder(root: &Path, left: impl FnOnce(&Path)) {
    for sub in ["frames/0000", "table"] {
        std::fs::create_dir_all(root.join(sub)).unwrap();
    }
    left(&root.join("frames/0000/left.png"));
    black_png(&root.join("frames/0000/right.png"), 64, 48);
    black_png(&root.join("table/left.png"), 64, 48);
    black_png(&root.join("table/right.png"), 64, 48);
}

#[test]
fn an_endless_device_or_a_fifo_as_an_image_is_refused_unread() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    board_folder(&d.join("zero"), |p| std::os::unix::fs::symlink("/dev/zero", p).unwrap());
    let o = camplace(d, &["calibrate", "--images", "zero", "--board", "9x6@25", "--out", "rig.json"]);
    assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["zero/frames/0000/left.png", "regular file"]);
    if std::process::Command::new("mkfifo").arg(d.join("fifo.toml")).status().is_ok_and(|s| s.success()) {
        let o = camplace(d, &["render", "--cell", "fifo.toml", "--out", "r"]);
        assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["fifo.toml", "FIFO"]);
    }
    let o = camplace(d, &["placement", "--rig", "/dev/zero"]);
    assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["/dev/zero", "regular file"]);
    assert!(!d.join("rig.json").exists() && !d.join("r").exists());
}

#[test]
fn an_image_that_decodes_past_the_pixel_budget_is_refused_from_its_header() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    board_folder(&d.join("bomb"), |p| black_png(p, 16384, 16384));
    assert!(std::fs::metadata(d.join("bomb/frames/0000/left.png")).unwrap().len() < 2 << 20);
    let o = camplace(d, &["calibrate", "--images", "bomb", "--board", "9x6@25"]);
    assert_one_line_error(
        o.status.code().unwrap(),
        &stderr(&o),
        &["bomb/frames/0000/left.png", "16384 x 16384", "at most"],
    );
}

#[test]
fn calibration_views_past_the_cap_are_refused_before_any_is_read() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    board_folder(&d.join("many"), |p| black_png(p, 64, 48));
    for i in 1..=100 {
        std::fs::create_dir_all(d.join(format!("many/frames/{i:04}"))).unwrap();
    }
    let o = camplace(d, &["calibrate", "--images", "many", "--board", "9x6@25"]);
    assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["many/frames", "101 board views", "at most 100"]);
}

#[test]
fn cameras_whose_buffers_pass_the_budget_are_refused_with_the_estimate_and_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let o = camplace(d, &["render", "--out", "r"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let mut rig: serde_json::Value = serde_json::from_slice(&std::fs::read(d.join("r/rig.json")).unwrap()).unwrap();
    for side in ["left", "right"] {
        rig[side]["width"] = 8192.into();
        rig[side]["height"] = 8192.into();
    }
    std::fs::write(d.join("big.json"), rig.to_string()).unwrap();
    for cmd in ["evaluate", "model", "accept"] {
        let mut args = vec![cmd, "--rig", "big.json"];
        match cmd {
            "evaluate" => args.extend(["--scenarios", "1", "--out", "e"]),
            "model" => args.extend(["--out", "m.model"]),
            _ => args.extend(["--min-success", "0.5", "--scenarios", "1"]),
        }
        let o = camplace(d, &args);
        assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["big.json", "left.width", "GB", "budget"]);
    }
    std::fs::write(d.join("big.toml"), "[sensor]\ncamera_resolution = [8192, 8192]\n").unwrap();
    let o = camplace(d, &["render", "--cell", "big.toml", "--out", "r2"]);
    assert_one_line_error(
        o.status.code().unwrap(),
        &stderr(&o),
        &["big.toml", "sensor.camera_resolution", "GB", "budget"],
    );
}
