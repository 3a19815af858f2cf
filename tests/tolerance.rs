//! `camplace tolerance` end to end on a small cell: every number in tolerance.json is the
//! success rate of the scenes its placement left in results.jsonl, each walk ends where its
//! definition says, the corners are the box's, and a second run resumes without a scene.

use std::collections::BTreeMap;
use std::path::Path;

use camplace_sim::{ToleranceReport, WalkEnd};

use crate::camplace_cmd::{assert_one_line_error, camplace, stderr};

/// Near the small cell's edge of working (3 of 4 scenes succeed here), so offsets matter.
const PLACEMENT: &str = "r=400,alpha=10,baseline=100,vergence=5";

fn small_cell() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/small_cell.toml").display().to_string()
}

/// (successes, scenes) per placement, counted from results.jsonl.
fn counted(path: &Path) -> BTreeMap<String, (usize, usize)> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut out: BTreeMap<String, (usize, usize)> = BTreeMap::new();
    for line in text.lines() {
        let v: serde_json::Value = serde_json::from_str(line).unwrap();
        let entry = out.entry(v["placement"].as_str().unwrap().to_string()).or_default();
        entry.0 += usize::from(v["success"].as_bool().unwrap());
        entry.1 += 1;
    }
    out
}

#[test]
fn tolerances_are_the_results_walked_out_and_resume_without_a_scene() {
    let dir = tempfile::tempdir().unwrap();
    let cell = small_cell();
    let args = [
        "tolerance",
        "--cell",
        &cell,
        "--placement",
        PLACEMENT,
        "--parameters",
        "alpha,r",
        "--steps",
        "2",
        "--scenarios",
        "3",
        "--margin",
        "0.3",
        "--out",
        "tol",
    ];
    let o = camplace(dir.path(), &args);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout).into_owned();
    let json = std::fs::read_to_string(dir.path().join("tol/tolerance.json")).unwrap();
    let report: ToleranceReport = serde_json::from_str(&json).unwrap();
    let counts = counted(&dir.path().join("tol/results.jsonl"));
    let rate_at = |placement: &str| {
        let (k, n) = counts.get(placement).unwrap_or_else(|| panic!("no results at {placement}"));
        assert_eq!(*n, 3, "{placement}");
        *k as f64 / *n as f64
    };

    assert_eq!(report.placement, PLACEMENT);
    let nominal = rate_at(PLACEMENT);
    assert_eq!(report.nominal.success_rate, nominal);
    assert_eq!(report.axes.iter().map(|a| a.parameter.as_str()).collect::<Vec<_>>(), ["r", "alpha"]);
    for axis in &report.axes {
        let nominal_value = if axis.parameter == "r" { 400.0 } else { 10.0 };
        let at = |offset: f64| {
            let from = format!("{}={nominal_value}", axis.parameter);
            PLACEMENT.replace(&from, &format!("{}={}", axis.parameter, nominal_value + offset))
        };
        for p in &axis.points {
            assert_eq!(p.success_rate, rate_at(&at(p.offset)), "{} {}", axis.parameter, p.offset);
        }
        // Each side by the definition: the furthest step with it and every step before it
        // within the margin.
        for (sign, tolerance, end) in [(-1.0, axis.minus, axis.minus_end), (1.0, axis.plus, axis.plus_end)] {
            let mut expected = 0.0;
            let mut expected_end = WalkEnd::LastStep;
            for k in 1..=2 {
                let offset = sign * axis.step * f64::from(k);
                if rate_at(&at(offset)) < nominal - 0.3 - 1e-12 {
                    expected_end = WalkEnd::Drop;
                    break;
                }
                expected = offset.abs();
            }
            assert_eq!((tolerance, end), (expected, expected_end), "{} side {sign}", axis.parameter);
        }
    }
    // The box's corners: every combination of each side's tolerance, each counted.
    let (r, alpha) = (&report.axes[0], &report.axes[1]);
    let mut expected: Vec<[f64; 5]> = Vec::new();
    for ar in [-alpha.minus, alpha.plus] {
        for rr in [-r.minus, r.plus] {
            let offsets = [rr, ar, 0.0, 0.0, 0.0];
            if !expected.contains(&offsets) {
                expected.push(offsets);
            }
        }
    }
    let mut got: Vec<[f64; 5]> = report.corners.iter().map(|c| c.offsets).collect();
    let key = |o: &[f64; 5]| format!("{o:?}");
    got.sort_by_key(key);
    expected.sort_by_key(key);
    assert_eq!(got, expected);
    for c in &report.corners {
        assert_eq!(c.success_rate, rate_at(&c.placement), "{}", c.placement);
    }
    assert!(out.contains(&format!("tolerance of {PLACEMENT}")), "{out}");
    for name in ["r", "alpha"] {
        assert!(dir.path().join(format!("tol/tolerance_{name}.svg")).is_file() || stderr(&o).contains("plots skipped"));
    }

    // Resumed: no scene is run again and the report is the same.
    let lines = std::fs::read_to_string(dir.path().join("tol/results.jsonl")).unwrap().lines().count();
    let o = camplace(dir.path(), &args);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(std::fs::read_to_string(dir.path().join("tol/results.jsonl")).unwrap().lines().count(), lines);
    assert_eq!(std::fs::read_to_string(dir.path().join("tol/tolerance.json")).unwrap(), json);
}

#[test]
fn bad_tolerance_flags_are_one_line_errors() {
    let dir = tempfile::tempdir().unwrap();
    for (flag, value, must) in [
        ("--margin", "0", "between 0 and 1"),
        ("--margin", "1.5", "between 0 and 1"),
        ("--steps", "0", "1 to 100"),
        ("--parameters", "r,height", "unknown parameter \"height\""),
        ("--parameters", ",", "at least one"),
    ] {
        let o = camplace(dir.path(), &["tolerance", flag, value, "--out", "t"]);
        assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &[flag, must]);
    }
}
