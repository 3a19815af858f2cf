//! `camplace placement`: a rig rendered at a placement gives that placement back, and a
//! rig mounted off the plan is named outside its tolerance (exit 1).

use std::path::Path;

use camplace_config::{AxisTolerance, TolerancePoint, ToleranceReport, WalkEnd};

use crate::camplace_cmd::{assert_one_line_error, camplace, stderr};

/// The numbers of the "as built" line: r, alpha, baseline, vergence, azimuth.
fn as_built(stdout: &str) -> Vec<f64> {
    let line = stdout.lines().find(|l| l.starts_with("as built")).expect("an as-built line");
    let values = line.split_once("): ").unwrap().1;
    values.split(',').map(|kv| kv.split_once('=').unwrap().1.parse().unwrap()).collect()
}

/// A point of a tolerance.json: success 1 on 44 scenes, nothing lost.
fn point(offset: f64) -> TolerancePoint {
    TolerancePoint {
        offset,
        success_rate: 1.0,
        success_interval: [0.92, 1.0],
        scenes: 44,
        lost: 0,
        gained: 0,
        p_lower: 1.0,
    }
}

/// A tolerance.json around `placement` allowing ±`mm` on r and baseline and ±`deg` on the angles.
fn tolerance_json(dir: &Path, placement: &str, mm: f64, deg: f64) {
    let axes = [
        ("r", mm, "mm"),
        ("alpha", deg, "deg"),
        ("baseline", mm, "mm"),
        ("vergence", deg, "deg"),
        ("azimuth", deg, "deg"),
    ]
    .iter()
    .map(|&(name, t, unit)| AxisTolerance {
        parameter: name.to_string(),
        unit: unit.to_string(),
        resolution: 1.0,
        limit: 90.0,
        minus: t,
        minus_end: WalkEnd::Drop,
        minus_inside: point(-t),
        minus_outside: Some(point(-t - 1.0)),
        minus_range: -90.0,
        plus: t,
        plus_end: WalkEnd::Drop,
        plus_inside: point(t),
        plus_outside: Some(point(t + 1.0)),
        plus_range: 90.0,
        points: vec![point(0.0)],
    })
    .collect();
    let report = ToleranceReport {
        placement: placement.to_string(),
        method: "one-shot".into(),
        seed: 1,
        scenarios: 44,
        margin: 0.15,
        level: 0.05,
        power: 0.81,
        nominal: point(0.0),
        axes,
        corner_fraction: 1.0,
        corners: Vec::new(),
        corner_screen: 0,
    };
    std::fs::write(dir.join("tolerance.json"), serde_json::to_string_pretty(&report).unwrap()).unwrap();
}

#[test]
fn a_rendered_rig_gives_back_its_placement() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for (i, p) in
        ["r=605,alpha=32,baseline=81,vergence=3.5,azimuth=20", "r=930.5,alpha=0,baseline=150,vergence=auto,azimuth=-75"]
            .iter()
            .enumerate()
    {
        let out = format!("r{i}");
        let o = camplace(d, &["render", "--placement", p, "--out", &out]);
        assert!(o.status.success(), "{}", stderr(&o));
        let o = camplace(d, &["placement", "--rig", &format!("{out}/rig.json"), "--placement", p]);
        assert!(o.status.success(), "{}", stderr(&o));
        let text = String::from_utf8_lossy(&o.stdout);
        let got = as_built(&text);
        let want: Vec<f64> = match i {
            0 => vec![605.0, 32.0, 81.0, 3.5, 20.0],
            _ => vec![930.5, 0.0, 150.0, (75.0f64 / 930.5).atan().to_degrees(), -75.0],
        };
        for (g, w) in got.iter().zip(&want) {
            assert!((g - w).abs() <= 0.005 + 1e-9, "{p}: {got:?} against {want:?}\n{text}");
        }
        assert!(text.contains("not measured") && text.contains("aim: 0.00 deg"), "{text}");
    }
}

#[test]
fn a_rig_mounted_off_its_tolerance_is_named_and_fails() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let plan = "r=605,alpha=32,baseline=81,vergence=3.5";
    tolerance_json(d, plan, 20.0, 4.0);
    for (i, (placement, outside)) in [
        ("r=615,alpha=34,baseline=81,vergence=3.5,azimuth=3", None),
        ("r=605,alpha=37,baseline=81,vergence=3.5", Some("alpha")),
        ("r=570,alpha=32,baseline=81,vergence=3.5,azimuth=-5", Some("r, azimuth")),
    ]
    .into_iter()
    .enumerate()
    {
        let rig = format!("rig{i}");
        let o = camplace(d, &["render", "--placement", placement, "--out", &rig]);
        assert!(o.status.success(), "{}", stderr(&o));
        let o = camplace(d, &["placement", "--rig", &format!("{rig}/rig.json"), "--tolerance", "tolerance.json"]);
        let text = String::from_utf8_lossy(&o.stdout);
        match outside {
            None => assert_eq!(o.status.code(), Some(0), "{placement}: {text}"),
            Some(names) => {
                assert_eq!(o.status.code(), Some(1), "{placement}: {text}");
                assert!(text.contains(&format!("outside its tolerance: {names}")), "{placement}: {text}");
            }
        }
        assert!(text.contains("planned: r=605.0,alpha=32.00"), "the plan is the tolerance's placement: {text}");
    }
}

#[test]
fn a_bad_rig_or_tolerance_file_is_a_one_line_error() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("bad.json"), "{\"left\": 3}").unwrap();
    let o = camplace(d, &["placement", "--rig", "bad.json"]);
    assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["bad.json"]);
    let o = camplace(d, &["render", "--out", "r"]);
    assert!(o.status.success(), "{}", stderr(&o));
    std::fs::write(d.join("tolerance.json"), "[1, 2]").unwrap();
    let o = camplace(d, &["placement", "--rig", "r/rig.json", "--tolerance", "tolerance.json"]);
    assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["tolerance.json", "expected"]);
    // A tolerance.json is checked before a rig is judged by it.
    tolerance_json(d, "r=605,alpha=32,baseline=81,vergence=3.5", 20.0, 4.0);
    let good = std::fs::read_to_string(d.join("tolerance.json")).unwrap();
    let placement = |file: &str| camplace(d, &["placement", "--rig", "r/rig.json", "--tolerance", file]);
    for (name, text, must) in [
        ("trailing.json", format!("{good}\n{{}}"), "trailing characters"),
        ("negative.json", good.replacen("\"minus\": 20.0", "\"minus\": -20.0", 1), "axes[0].minus"),
        ("huge_angle.json", good.replacen("\"plus\": 4.0", "\"plus\": 400.0", 1), "axes[1].plus"),
        ("unit.json", good.replacen("\"unit\": \"deg\"", "\"unit\": \"mm\"", 1), "axes[1].parameter"),
        ("infinite.json", good.replacen("\"minus\": 20.0", "\"minus\": 1e999", 1), "tolerance.json camplace"),
        ("unknown.json", good.replacen("\"seed\": 1", "\"seed\": 1, \"extra\": 2", 1), "unknown field"),
    ] {
        assert_ne!(text, good, "{name} differs from the good file");
        std::fs::write(d.join(name), text).unwrap();
        let o = placement(name);
        assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &[name, must]);
    }
    let o = placement("/dev/zero");
    assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["/dev/zero", "regular file"]);
    let huge = std::fs::File::create(d.join("huge.json")).unwrap();
    huge.set_len(64 << 20).unwrap();
    let o = placement("huge.json");
    assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["huge.json", "at most 16777216 bytes"]);
    let o = placement("tolerance.json");
    assert!(matches!(o.status.code(), Some(0 | 1)), "the checked file is read: {}", stderr(&o));
    let o = camplace(d, &["placement", "--rig", "r/rig.json", "--study", "nowhere"]);
    assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["nowhere", "recommended.json"]);
}
