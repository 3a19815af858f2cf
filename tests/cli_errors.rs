//! Bad input ends with one line naming the file, the key and what was expected, exit 2.

use crate::camplace_cmd::{assert_one_line_error, camplace, stderr};

fn render_with_cell(cell_text: &str, extra: &[(&str, &[u8])]) -> (i32, String) {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("cell.toml"), cell_text).unwrap();
    for (name, bytes) in extra {
        std::fs::write(dir.path().join(name), bytes).unwrap();
    }
    let o = camplace(dir.path(), &["render", "--cell", "cell.toml", "--out", "out"]);
    (o.status.code().unwrap_or(-1), stderr(&o))
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

/// Flags and cell values that once crashed, hung or were silently accepted: each ends at
/// once with one line naming the flag, file or key and what was expected.
#[test]
fn hostile_flags_and_values_are_one_line_errors() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let huge_ply = "ply\nformat binary_little_endian 1.0\nelement vertex 18446744073709551615\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
    std::fs::write(d.join("huge.ply"), huge_ply).unwrap();
    let cells = [
        ("texture.toml", "[stereo]\nmin_texture = 4294967295\n", "stereo.min_texture"),
        ("normals.toml", "[estimator]\nnormal_radius = 1e9\n", "estimator.normal_radius"),
        ("sres.toml", "[estimator]\nsurface_resolution = 1e-9\n", "estimator.surface_resolution"),
        ("ransac.toml", "[estimator]\nransac_iterations = 4000000000\n", "estimator.ransac_iterations"),
        ("mesh.toml", "[tray]\nkind = \"mesh\"\nmesh = \"huge.ply\"\n", "tray.mesh"),
        ("syntax.toml", "[scenarios]\ncount = 3\n\n[stereo]\nmin_texture = = 3\n", "line 5"),
    ];
    for (name, text, key) in cells {
        std::fs::write(d.join(name), text).unwrap();
        let o = camplace(d, &["render", "--cell", name, "--out", "out"]);
        assert_one_line_error(o.status.code().unwrap_or(-1), &stderr(&o), &[name, key]);
    }
    let flags: [(&[&str], &[&str]); 7] = [
        (&["evaluate"], &["--out"]),
        (&["capture", "--source", "dir:x"], &["--out"]),
        (&["replay", "--bogus"], &["--bogus"]),
        (&["evaluate", "--placement", "vergence=auto,r=1e-6", "--out", "o"], &["placement.vergence", "auto"]),
        (&["evaluate", "--scenarios", "1000000000", "--out", "o"], &["--scenarios"]),
        (&["sweep", "--x", "r=400:900:100000000", "--out", "o"], &["--x", "steps"]),
        (&["evaluate", "--placement", "r=1e12", "--out", "o"], &["placement.r"]),
    ];
    for (args, names) in flags {
        let o = camplace(d, args);
        assert_one_line_error(o.status.code().unwrap_or(-1), &stderr(&o), names);
        assert!(!stderr(&o).contains("Usage"), "{}", stderr(&o));
    }
    assert!(!d.join("o").exists(), "a refused run writes no study folder");
}

#[test]
fn a_reflected_camera_pose_is_refused_not_hung() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::create_dir_all(d.join("ds/frames/0000")).unwrap();
    let t = |x: f64| format!("[[{x}, 0, 0, -40], [0, -1, 0, 0], [0, 0, -1, 600], [0, 0, 0, 1]]");
    let cam = |x: f64| {
        format!(
            "{{\"width\": 640, \"height\": 480, \"K\": [[812, 0, 319.5], [0, 812, 239.5], [0, 0, 1]], \"dist\": [0, 0, 0, 0, 0], \"T_world_camera\": {}}}",
            t(x)
        )
    };
    std::fs::write(
        d.join("ds/rig.json"),
        format!("{{\"left\": {}, \"right\": {}, \"projector\": null}}", cam(-1.0), cam(1.0)),
    )
    .unwrap();
    let o = camplace(d, &["reconstruct", "--dataset", "ds"]);
    assert_one_line_error(
        o.status.code().unwrap_or(-1),
        &stderr(&o),
        &["rig.json", "left.T_world_camera", "determinant"],
    );
}

#[test]
fn rig_geometry_errors_name_the_file_and_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let o = camplace(d, &["render", "--dataset", "--count", "1", "--out", "ds"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let rig: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("ds/rig.json")).unwrap()).unwrap();
    // Both cameras at one centre; then both looking straight up, away from the table.
    let mut same = rig.clone();
    same["right"]["T_world_camera"] = rig["left"]["T_world_camera"].clone();
    let mut up = rig.clone();
    for side in ["left", "right"] {
        for r in 0..3 {
            for c in 0..3 {
                up[side]["T_world_camera"][r][c] = serde_json::json!(if r == c { 1.0 } else { 0.0 });
            }
        }
    }
    for (rig, key) in [(same, "right.T_world_camera"), (up, "left.T_world_camera")] {
        std::fs::write(d.join("ds/rig.json"), rig.to_string()).unwrap();
        let o = camplace(d, &["reconstruct", "--dataset", "ds"]);
        assert_one_line_error(o.status.code().unwrap_or(-1), &stderr(&o), &["rig.json", key]);
    }
}

/// Every command that reads a recorded dataset checks its poses: a reflected camera in
/// `rig.json` and a rotation that is not one in `truth.json` end in one line naming the file
/// and the key, never a hang or a score.
#[test]
fn every_dataset_command_checks_the_poses_it_reads() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A coarse cell builds its model in moments.
    std::fs::write(
        d.join("coarse.toml"),
        "[estimator]\nsurface_resolution = 12.0\nnormal_radius = 40\nfeature_radius = 60\nkeypoint_spacing = 30\n",
    )
    .unwrap();
    for args in [
        &["render", "--cell", "coarse.toml", "--dataset", "--count", "2", "--out", "ds"][..],
        &["model", "--cell", "coarse.toml", "--verify-scenes", "0", "--out", "tray.model"],
    ] {
        let o = camplace(d, args);
        assert!(o.status.success(), "{args:?}: {}", stderr(&o));
    }
    let commands: [&[&str]; 3] = [
        &["estimate", "--cell", "coarse.toml", "--dataset", "ds", "--model", "tray.model"],
        &["replay", "ds", "--cell", "coarse.toml", "--model", "tray.model"],
        &["run", "--cell", "coarse.toml", "--source", "dir:ds", "--model", "tray.model"],
    ];
    let good_rig = std::fs::read_to_string(d.join("ds/rig.json")).unwrap();
    let mut rig: serde_json::Value = serde_json::from_str(&good_rig).unwrap();
    for r in 0..3 {
        let v = rig["left"]["T_world_camera"][r][0].as_f64().unwrap();
        rig["left"]["T_world_camera"][r][0] = serde_json::json!(-v);
    }
    std::fs::write(d.join("ds/rig.json"), rig.to_string()).unwrap();
    for args in commands {
        let o = camplace(d, args);
        assert_one_line_error(o.status.code().unwrap_or(-1), &stderr(&o), &["rig.json", "left.T_world_camera"]);
    }
    std::fs::write(d.join("ds/rig.json"), good_rig).unwrap();
    let truth_path = d.join("ds/frames/0001/truth.json");
    let mut truth: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&truth_path).unwrap()).unwrap();
    for (rows, name) in [
        (serde_json::json!([[0, 0, 0, 0], [0, 0, 0, 0], [0, 0, 0, 0], [0, 0, 0, 1]]), "all zero"),
        (serde_json::json!([[2, 0, 0, 0], [0, 2, 0, 0], [0, 0, 2, 0], [0, 0, 0, 1]]), "scaled"),
        (serde_json::json!([[-1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]), "reflected"),
    ] {
        truth["T_world_tray"] = rows;
        std::fs::write(&truth_path, truth.to_string()).unwrap();
        for args in commands {
            let o = camplace(d, args);
            let err = stderr(&o);
            assert!(!err.is_empty(), "{name} truth accepted by {args:?}");
            assert_one_line_error(o.status.code().unwrap_or(-1), &err, &["0001/truth.json", "T_world_tray"]);
        }
    }
}

#[test]
fn endless_files_and_empty_budgets_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cases: [(&[&str], &[&str]); 4] = [
        (&["render", "--cell", "/dev/zero", "--out", "o"], &["/dev/zero", "regular file"]),
        (&["optimize", "--budget", "0", "--out", "o"], &["--budget"]),
        (&["optimize", "--test-function", "branin", "--budget", "100000000"], &["--budget"]),
        (&["optimize", "--top", "0", "--out", "o"], &["--top"]),
    ];
    for (args, names) in cases {
        let o = camplace(d, args);
        assert_one_line_error(o.status.code().unwrap_or(-1), &stderr(&o), names);
    }
}
