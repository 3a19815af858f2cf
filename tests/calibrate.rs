//! `camplace calibrate` against the truth of `render --board`: boards rendered through lens
//! distortion with the paper's camera noise give back each camera's K and distortion, the
//! baseline and the rig's pose in the world; `placement --rig` then reads the placement the
//! rig was rendered at. Bad input is one line and exit code 2.

use std::path::Path;

use camplace_config::RigFile;
use camplace_estimator::{Camera, Rig};

use crate::camplace_cmd::{assert_one_line_error, camplace, stderr};

/// A cell file with lens distortion (and the default cell's paper noise: amplitude 10, 3x3).
fn distorted_cell(dir: &Path, dist: [f64; 5]) {
    let o = camplace(dir, &["init", "cell.toml"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(dir.join("cell.toml")).unwrap();
    let line = format!("camera_dist = [{}]", dist.map(|d| format!("{d:?}")).join(", "));
    let text = text.replace("camera_k = []\n", &format!("camera_k = []\n{line}\n"));
    std::fs::write(dir.join("cell.toml"), text).unwrap();
}

/// Largest difference, pixels, between two cameras' distortion over the image: each grid
/// pixel's true ray distorted by either set of coefficients, scaled by the true focal length.
fn distortion_difference(truth: &Camera, got: &Camera) -> f64 {
    let mut worst = 0.0f64;
    for y in (0..truth.height).step_by(16) {
        for x in (0..truth.width).step_by(16) {
            let r = truth.ray(x as f64, y as f64);
            let (a, b) = (truth.distort(r.x, r.y), got.distort(r.x, r.y));
            worst = worst.max(((a.0 - b.0) * truth.k[(0, 0)]).hypot((a.1 - b.1) * truth.k[(1, 1)]));
        }
    }
    worst
}

/// The calibration's error against the truth, per camera and for the rig, asserted within
/// the tolerances of a good calibration; returns a line of the figures.
fn check_against_truth(truth: &Rig, got: &Rig, what: &str) -> String {
    let mut line = String::new();
    for (side, t, g) in [("left", &truth.left, &got.left), ("right", &truth.right, &got.right)] {
        let rel = |i: usize| (g.k[(i, i)] / t.k[(i, i)] - 1.0).abs();
        let (dfx, dfy) = (rel(0), rel(1));
        let (dcx, dcy) = ((g.k[(0, 2)] - t.k[(0, 2)]).abs(), (g.k[(1, 2)] - t.k[(1, 2)]).abs());
        let dist = distortion_difference(t, g);
        let position = (g.centre() - t.centre()).norm();
        let angle = (g.t_world_camera.rotation.inverse() * t.t_world_camera.rotation).angle().to_degrees();
        line += &format!(
            "{side}: fx {:.3} % fy {:.3} % cx {dcx:.2} px cy {dcy:.2} px distortion {dist:.3} px position {position:.2} mm rotation {angle:.3} deg; ",
            100.0 * dfx,
            100.0 * dfy
        );
        assert!(dfx < 0.003 && dfy < 0.003, "{what}: {line}");
        assert!(dcx < 1.0 && dcy < 1.0, "{what}: {line}");
        assert!(dist < 0.2, "{what}: {line}");
        assert!(position < 1.0 && angle < 0.1, "{what}: {line}");
    }
    let baseline = (got.baseline() / truth.baseline() - 1.0).abs();
    line += &format!("baseline {:.3} %", 100.0 * baseline);
    assert!(baseline < 0.003, "{what}: {line}");
    line
}

fn rig(path: &Path) -> Rig {
    Rig::from_file(&RigFile::load(path).unwrap())
}

/// The RMS of the "calibrated from" line.
fn rms(stdout: &str) -> f64 {
    let line = stdout.lines().find(|l| l.starts_with("calibrated from")).expect("a summary line");
    let after = line.split_once("reprojection RMS ").unwrap().1;
    after.split_once(" px").unwrap().0.parse().unwrap()
}

#[test]
fn rendered_boards_calibrate_to_the_true_rig() {
    for (case, (placement, dist, board)) in [
        ("r=605,alpha=32,baseline=120,vergence=auto", [-0.1, 0.05, 0.0005, -0.0003, 0.0], "9x6@25"),
        ("r=800,alpha=15,baseline=90,vergence=2,azimuth=40", [0.06, -0.12, -0.0007, 0.0004, 0.03], "11x8@25"),
        // A lens whose k3 matters: the calibration must refine it.
        ("r=700,alpha=25,baseline=100,vergence=auto,azimuth=-30", [-0.25, 0.1, 0.0003, 0.0002, 0.3], "9x6@25"),
    ]
    .into_iter()
    .enumerate()
    {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        distorted_cell(d, dist);
        let o = camplace(
            d,
            &[
                "render",
                "--cell",
                "cell.toml",
                "--placement",
                placement,
                "--board",
                board,
                "--views",
                "15",
                "--seed",
                &format!("{}", 3 + case),
                "--out",
                "boards",
            ],
        );
        assert!(o.status.success(), "{}", stderr(&o));
        let o = camplace(d, &["calibrate", "--images", "boards", "--board", board, "--out", "calibrated.json"]);
        let out = String::from_utf8_lossy(&o.stdout).into_owned();
        assert!(o.status.success(), "{}\n{out}", stderr(&o));
        let r = rms(&out);
        if case == 2 {
            assert!(out.contains("k3: refined"), "{out}");
        }
        assert!(r <= 0.2, "{placement}: reprojection RMS {r} px\n{out}");
        let figures =
            check_against_truth(&rig(&d.join("boards/rig.json")), &rig(&d.join("calibrated.json")), placement);
        println!("{placement}: RMS {r:.3} px; {figures}");
        // The calibrated rig is mounted where it was rendered, within what 1 mm and 0.1 deg
        // of camera pose allow (the azimuth turns by 1 mm over the rig's distance from the
        // table's vertical axis).
        let o = camplace(d, &["placement", "--rig", "calibrated.json", "--placement", placement]);
        assert!(o.status.success(), "{}", stderr(&o));
        let text = String::from_utf8_lossy(&o.stdout).into_owned();
        let rows: Vec<Vec<String>> = text
            .lines()
            .map(|l| l.split_whitespace().map(str::to_string).collect::<Vec<_>>())
            .filter(|r| r.len() >= 7 && ["r", "alpha", "baseline", "vergence", "azimuth"].contains(&r[0].as_str()))
            .collect();
        assert_eq!(rows.len(), 5, "{text}");
        let value =
            |name: &str, col: usize| -> f64 { rows.iter().find(|r| r[0] == name).unwrap()[col].parse().unwrap() };
        let off_axis_mm = value("r", 3) * value("alpha", 3).to_radians().sin();
        for row in &rows {
            let diff: f64 = row[5].parse().unwrap();
            let limit = match row[0].as_str() {
                "r" | "baseline" => 1.0,
                "azimuth" => (1.0 / off_axis_mm).atan().to_degrees().max(0.1),
                _ => 0.1,
            };
            assert!(diff.abs() <= limit, "{placement}: {row:?} beyond {limit}\n{text}");
        }
    }
}

#[test]
fn a_view_whose_corners_disagree_is_dropped_and_named() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    distorted_cell(d, [-0.1, 0.05, 0.0005, -0.0003, 0.0]);
    let o = camplace(d, &["render", "--cell", "cell.toml", "--board", "9x6@25", "--views", "15", "--out", "boards"]);
    assert!(o.status.success(), "{}", stderr(&o));
    // View 4's right image is view 5's: the board is found, but not where view 4 lies.
    std::fs::copy(d.join("boards/frames/0005/right.png"), d.join("boards/frames/0004/right.png")).unwrap();
    // View 7 shows no board at all.
    std::fs::copy(d.join("boards/frames/0007/left.png"), d.join("boards/frames/0007/right.png")).unwrap();
    let blank = vec![128u8; 640 * 480];
    camplace_config::write_gray(&d.join("boards/frames/0007/left.png"), 640, 480, &blank).unwrap();
    let o = camplace(d, &["calibrate", "--images", "boards", "--board", "9x6@25", "--out", "calibrated.json"]);
    let out = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(o.status.success(), "{}\n{out}", stderr(&o));
    let row = out.lines().find(|l| l.starts_with("frames/0004")).unwrap();
    assert!(row.contains("dropped"), "{out}");
    assert_eq!(out.lines().filter(|l| l.contains("dropped")).count(), 1, "{out}");
    assert!(out.contains("not in view: frames/0007/left.png: no chessboard found"), "{out}");
    check_against_truth(&rig(&d.join("boards/rig.json")), &rig(&d.join("calibrated.json")), "one view dropped");
}

#[test]
fn bad_calibration_input_is_a_one_line_error() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let o = camplace(d, &["render", "--board", "9x6@25", "--views", "3", "--out", "boards"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let calibrate = |board: &str| camplace(d, &["calibrate", "--images", "boards", "--board", board]);
    for (board, names) in [
        ("9x6", vec!["--board", "COLSxROWS@SQUARE_MM"]),
        ("9x7@25", vec!["9x7", "half way round"]),
        ("1x6@25", vec!["--board", "2 to 100"]),
        ("9x6@-3", vec!["--board", "square side"]),
    ] {
        let o = calibrate(board);
        assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &names);
    }
    // Too few views once those without a board are skipped.
    let blank = vec![0u8; 640 * 480];
    for view in ["0001", "0002"] {
        camplace_config::write_gray(&d.join(format!("boards/frames/{view}/left.png")), 640, 480, &blank).unwrap();
    }
    let o = calibrate("9x6@25");
    assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["boards", "2 views", "at least 3"]);
    // Images of another size.
    camplace_config::write_gray(&d.join("boards/frames/0001/left.png"), 320, 240, &blank[..320 * 240]).unwrap();
    let o = calibrate("9x6@25");
    assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["frames/0001/left.png", "320x240", "640x480"]);
    // No table view: no world frame.
    std::fs::remove_dir_all(d.join("boards/table")).unwrap();
    let o = calibrate("9x6@25");
    assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["table", "capture --table"]);
    // Nothing there at all.
    let o = camplace(d, &["calibrate", "--images", "nowhere", "--board", "9x6@25"]);
    assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["nowhere"]);
    assert!(!d.join("rig.json").exists(), "no rig.json from bad input");
}
