//! `--rig`: `evaluate` and `accept` simulate the rig as installed. A rig.json rendered at a
//! placement gives that placement's results scene by scene; a rig mounted 5 degrees off in
//! alpha gives the results of where it really is; commands that vary the placement refuse
//! a cell whose cameras are fixed.

use std::collections::BTreeMap;
use std::path::Path;

use crate::camplace_cmd::{assert_one_line_error, camplace, stderr};

/// Per scenario: whether the pose was found and the pose's translation, from results.jsonl.
fn outcomes(folder: &Path) -> BTreeMap<u64, (bool, [f64; 3])> {
    let text = std::fs::read_to_string(folder.join("results.jsonl")).unwrap();
    text.lines()
        .map(|l| {
            let v: serde_json::Value = serde_json::from_str(l).unwrap();
            let t = &v["T_world_tray"];
            let at = |r: usize| t[r][3].as_f64().unwrap_or(f64::NAN);
            (v["scenario"].as_u64().unwrap(), (v["success"].as_bool().unwrap(), [at(0), at(1), at(2)]))
        })
        .collect()
}

fn evaluate(dir: &Path, how: &[&str], out: &str) -> String {
    let mut args = vec!["evaluate", "--scenarios", "6", "--out", out];
    args.extend_from_slice(how);
    let o = camplace(dir, &args);
    assert!(o.status.success(), "{}", stderr(&o));
    String::from_utf8_lossy(&o.stdout).into_owned()
}

#[test]
fn an_installed_rig_is_simulated_where_it_is_mounted() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let planned = "r=605,alpha=32,baseline=120,vergence=4";
    let off = "r=605,alpha=37,baseline=120,vergence=4";
    for (name, p) in [("planned", planned), ("off", off)] {
        let o = camplace(d, &["render", "--placement", p, "--out", name]);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let by_placement = evaluate(d, &["--placement", planned], "e-placement");
    let by_rig = evaluate(d, &["--rig", "planned/rig.json"], "e-rig");
    assert!(by_rig.starts_with("r=605,alpha=32,baseline=120,vergence=4 "), "{by_rig}");
    let (a, b) = (outcomes(&d.join("e-placement")), outcomes(&d.join("e-rig")));
    assert_eq!(a.len(), 6);
    for (s, (found, t)) in &a {
        let (found_rig, t_rig) = b[s];
        assert_eq!(*found, found_rig, "scenario {s}");
        let moved = (0..3).map(|i| (t[i] - t_rig[i]).powi(2)).sum::<f64>().sqrt();
        // A scene where no pose was found has none to compare.
        assert!(moved <= 0.01 || moved.is_nan() && !found, "scenario {s}: poses {moved} mm apart");
    }
    let rate = |line: &str| line.split_once("success ").unwrap().1.split_once(" %").unwrap().0.to_string();
    assert_eq!(rate(&by_rig), rate(&by_placement), "{by_rig}\n{by_placement}");
    // Mounted 5 degrees off in alpha: the results of alpha 37, not of the plan.
    let off_rig = evaluate(d, &["--rig", "off/rig.json"], "e-off-rig");
    let off_placement = evaluate(d, &["--placement", off], "e-off-placement");
    assert!(off_rig.starts_with("r=605,alpha=37,"), "{off_rig}");
    assert_eq!(rate(&off_rig), rate(&off_placement), "{off_rig}\n{off_placement}");
    assert_eq!(
        outcomes(&d.join("e-off-rig")).values().map(|o| o.0).collect::<Vec<_>>(),
        outcomes(&d.join("e-off-placement")).values().map(|o| o.0).collect::<Vec<_>>()
    );
    // The installed rig is part of the cell: its results never join the plan's folder.
    let o = camplace(d, &["evaluate", "--scenarios", "6", "--rig", "off/rig.json", "--out", "e-placement"]);
    assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["e-placement"]);
    // --rig and --placement name the sensor twice.
    let o = camplace(d, &["accept", "--min-success", "0.5", "--rig", "off/rig.json", "--placement", planned]);
    assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["--rig", "--placement"]);
}

#[test]
fn commands_that_vary_the_placement_refuse_an_installed_rig() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let o = camplace(d, &["render", "--out", "r"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = camplace(d, &["init", "cell.toml"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let rig: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(d.join("r/rig.json")).unwrap()).unwrap();
    let mut cell: toml::Table = std::fs::read_to_string(d.join("cell.toml")).unwrap().parse().unwrap();
    cell.insert("rig".into(), toml::Value::try_from(rig).unwrap());
    std::fs::write(d.join("cell.toml"), toml::to_string(&cell).unwrap()).unwrap();
    for args in [
        vec!["sweep", "--cell", "cell.toml", "--out", "s"],
        vec!["study", "--cell", "cell.toml", "--out", "s"],
        vec!["tolerance", "--cell", "cell.toml", "--out", "s"],
    ] {
        let o = camplace(d, &args);
        assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["[rig]", args[0]]);
    }
    // A bad [rig] names its key.
    let text = std::fs::read_to_string(d.join("cell.toml")).unwrap();
    let bad = text.replacen("width = 640\n\n[rig.projector]", "width = 0\n\n[rig.projector]", 1);
    assert_ne!(bad, text);
    std::fs::write(d.join("bad.toml"), bad).unwrap();
    let o = camplace(d, &["evaluate", "--cell", "bad.toml", "--scenarios", "1", "--out", "b"]);
    assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["bad.toml", "rig.left.width"]);
}
