//! The commissioning path of docs/commissioning.md on simulated data, step by step with the
//! commands it names: boards rendered through the installed rig's lenses -> calibrate ->
//! placement -> accept --rig -> background and frames -> model --rig -> run --source dir:,
//! and every pose `run` writes meets the success rule against the render's truth.

use camplace_config::{Cell, TruthFile};
use camplace_estimator::{geometry::isometry_from_rows, pose::pose_errors};

use crate::camplace_cmd::{camplace, stderr};

#[test]
fn the_commissioning_path_gives_good_poses_from_a_calibrated_rig() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let ok = |args: &[&str]| -> String {
        let o = camplace(d, args);
        assert!(o.status.success(), "{args:?}: {}\n{}", stderr(&o), String::from_utf8_lossy(&o.stdout));
        String::from_utf8_lossy(&o.stdout).into_owned()
    };
    // The cell, its lenses distorting, and the plan the rig is mounted at.
    ok(&["init", "cell.toml"]);
    let text = std::fs::read_to_string(d.join("cell.toml")).unwrap();
    let text = text.replace("camera_k = []\n", "camera_k = []\ncamera_dist = [-0.1, 0.05, 0.0005, -0.0003, 0.0]\n");
    std::fs::write(d.join("cell.toml"), text).unwrap();
    let plan = "r=605,alpha=32,baseline=81,vergence=3.5";
    // Capture + calibrate: the installed rig sees the board (rendered, with its truth).
    ok(&["render", "--cell", "cell.toml", "--placement", plan, "--board", "9x6@25", "--views", "15", "--out", "calib"]);
    let out = ok(&["calibrate", "--images", "calib", "--board", "9x6@25", "--out", "rig.json"]);
    assert!(out.contains("wrote rig.json"), "{out}");
    // The placement check: mounted as planned, within the calibration's accuracy.
    let out = ok(&["placement", "--rig", "rig.json", "--cell", "cell.toml", "--placement", plan]);
    assert!(out.contains("as built (rig.json): r=605."), "{out}");
    // Accept the rig as installed.
    let out = ok(&["accept", "--cell", "cell.toml", "--rig", "rig.json", "--min-success", "0.4", "--scenarios", "6"]);
    assert!(out.contains("PASS"), "{out}");
    // Background and frames from the real rig (rendered by the true rig; the estimator
    // knows only the calibration).
    ok(&[
        "render",
        "--cell",
        "cell.toml",
        "--placement",
        plan,
        "--dataset",
        "--count",
        "4",
        "--seed",
        "7",
        "--out",
        "cell-data",
    ]);
    std::fs::copy(d.join("rig.json"), d.join("cell-data/rig.json")).unwrap();
    // The model of the installed rig, then the deployed loop.
    // The verification threshold measured on 20 scenes: enough for the path, a tenth of the
    // default's time.
    ok(&["model", "--cell", "cell.toml", "--rig", "rig.json", "--verify-scenes", "20", "--out", "tray.model"]);
    ok(&["run", "--source", "dir:cell-data", "--model", "tray.model", "--cell", "cell.toml", "--out", "poses.jsonl"]);
    let poses = std::fs::read_to_string(d.join("poses.jsonl")).unwrap();
    let cell = Cell::load(&d.join("cell.toml")).unwrap();
    let mut checked = 0;
    for line in poses.lines() {
        let v: serde_json::Value = serde_json::from_str(line).unwrap();
        let frame = v["frame"].as_str().unwrap();
        let truth = TruthFile::load(&d.join("cell-data/frames").join(frame).join("truth.json")).unwrap();
        let t: [[f64; 4]; 4] = serde_json::from_value(v["T_world_tray"].clone()).unwrap();
        let symmetries: Vec<f32> = truth.symmetries.iter().map(|&s| s as f32).collect();
        let e =
            pose_errors(&isometry_from_rows(&t), &isometry_from_rows(&truth.t_world_tray), &symmetries, &cell.metrics);
        assert!(e.success, "{frame}: {:.2} mm, {:.2} deg off", e.position_mm, e.rotation_deg);
        checked += 1;
    }
    assert_eq!(checked, 4, "{poses}");
}
