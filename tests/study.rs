//! The placement study through the CLI: the same seed gives the same summary with 1 or 2
//! threads and as 3 shards merged; a killed evaluate resumes to the uninterrupted result
//! without computing a scene twice; accept passes a good placement and fails a poor one;
//! bad study flags are one-line errors.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Duration;

use camplace_estimator::scoring::SlotSummary;
use serde_json::Value;

use crate::camplace_cmd::{camplace, stderr};
use crate::study_folder::{results_without_timings, summary_without_timings};

const SCENES: &str = "6";

fn cell() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/small_cell.toml").display().to_string()
}

fn evaluate(dir: &Path, out: &str, threads: &str, extra: &[&str]) {
    let cell = cell();
    let mut args = vec!["evaluate", "--cell", &cell, "--seed", "5", "--scenarios", SCENES, "--out", out];
    args.extend_from_slice(extra);
    let o = Command::new(env!("CARGO_BIN_EXE_camplace"))
        .args(&args)
        .current_dir(dir)
        .env("RAYON_NUM_THREADS", threads)
        .output()
        .expect("camplace runs");
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn same_seed_same_summary_with_one_or_two_threads_and_as_three_shards() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    evaluate(d, "one", "1", &[]);
    evaluate(d, "two", "2", &[]);
    for i in 0..3 {
        evaluate(d, &format!("part{i}"), "2", &["--shard", &format!("{i}/3")]);
    }
    let o = camplace(d, &["merge", "part0", "part1", "part2", "--out", "merged"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let one = summary_without_timings(&d.join("one/summary.json"));
    assert_eq!(one[0]["frames"], 6, "{one}");
    assert_eq!(summary_without_timings(&d.join("two/summary.json")), one);
    assert_eq!(summary_without_timings(&d.join("merged/summary.json")), one);
    assert_eq!(
        results_without_timings(&d.join("merged/results.jsonl")),
        results_without_timings(&d.join("one/results.jsonl"))
    );
}

#[test]
fn a_killed_evaluate_resumes_to_the_uninterrupted_result() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    evaluate(d, "whole", "2", &[]);
    let cell = cell();
    let results = d.join("resumed/results.jsonl");
    let mut child = Command::new(env!("CARGO_BIN_EXE_camplace"))
        .args(["evaluate", "--cell", &cell, "--seed", "5", "--scenarios", SCENES, "--out", "resumed"])
        .current_dir(d)
        .env("RAYON_NUM_THREADS", "1")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let lines = |p: &PathBuf| std::fs::read_to_string(p).map_or(0, |t| t.lines().count());
    while lines(&results) < 2 {
        if let Some(status) = child.try_wait().unwrap() {
            panic!("evaluate ended before it could be killed: {status}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let before = lines(&results);
    assert!(before < 6, "the run finished before the kill ({before} lines)");
    evaluate(d, "resumed", "2", &[]);
    let resumed = results_without_timings(&results);
    let scenarios: Vec<u64> = resumed.iter().map(|((_, i), _)| *i).collect();
    assert_eq!(scenarios, (0..6).collect::<Vec<_>>(), "each scenario once");
    assert_eq!(resumed, results_without_timings(&d.join("whole/results.jsonl")));
    assert_eq!(
        summary_without_timings(&d.join("resumed/summary.json")),
        summary_without_timings(&d.join("whole/summary.json"))
    );
}

#[test]
fn accept_fails_a_poor_placement_and_passes_a_good_one() {
    let dir = tempfile::tempdir().unwrap();
    // Measured with the default cell, seed 1, scenarios 0-7: the paper's optimum
    // (r 605, alpha 32, baseline 81, vergence 3.5) 6 of 8 (Wilson low 41 %); a 5 mm
    // baseline at 1500 mm (depth noise of centimetres) 0 of 8 (Wilson high 32 %).
    let good = camplace(
        dir.path(),
        &[
            "accept",
            "--placement",
            "r=605,alpha=32,baseline=81,vergence=3.5",
            "--min-success",
            "0.2",
            "--scenarios",
            "8",
            "--out",
            "acc",
        ],
    );
    assert_eq!(good.status.code(), Some(0), "{}{}", String::from_utf8_lossy(&good.stdout), stderr(&good));
    assert!(String::from_utf8_lossy(&good.stdout).contains("PASS"));
    slot_accuracy_is_judged_on_the_accepted_poses_slots(dir.path());
    let poor = camplace(
        dir.path(),
        &["accept", "--placement", "r=1500,alpha=32,baseline=5", "--min-success", "0.2", "--scenarios", "8"],
    );
    assert_eq!(poor.status.code(), Some(1), "{}{}", String::from_utf8_lossy(&poor.stdout), stderr(&poor));
    assert!(String::from_utf8_lossy(&poor.stdout).contains("FAIL"));
}

/// `accept --min-slot-accuracy` on the folder of the good placement above (its scenes
/// kept, not run again): the wrong calls and slots it names are those of the accepted
/// records, and it passes just below their lower bound and fails just above it.
fn slot_accuracy_is_judged_on_the_accepted_poses_slots(dir: &Path) {
    let mut summary = SlotSummary::default();
    let results = std::fs::read_to_string(dir.join("acc/results.jsonl")).unwrap();
    for record in results.lines().map(|l| serde_json::from_str::<Value>(l).unwrap()) {
        if record["verdict"] != "accepted" {
            continue;
        }
        let score = &record["slot_score"];
        let count = |key: &str| score[key].as_u64().unwrap_or_else(|| panic!("{key} in {score}"));
        summary.frames += 1;
        summary.slots += count("slots");
        summary.wrong += count("filled_called_empty") + count("empty_called_filled");
        summary.unseen += count("unseen");
    }
    assert!(summary.slots >= 8, "the good placement's accepted poses judged slots: {summary:?}");
    let low = summary.accuracy_lower();
    let counts = format!(
        "({} wrong of {} slots in {} accepted poses, {} unseen)",
        summary.wrong, summary.slots, summary.frames, summary.unseen
    );
    let accept = |min: f64| {
        let min = format!("{min:.4}");
        camplace(
            dir,
            &["accept", "--placement", "r=605,alpha=32,baseline=81,vergence=3.5", "--scenarios", "8"]
                .into_iter()
                .chain(["--out", "acc", "--min-slot-accuracy", &min])
                .collect::<Vec<_>>(),
        )
    };
    for (min, code, verdict) in [(low - 0.01, 0, "PASS"), (low + 0.01, 1, "FAIL")] {
        let o = accept(min.clamp(0.0, 1.0));
        let out = String::from_utf8_lossy(&o.stdout);
        assert_eq!(o.status.code(), Some(code), "{out}{}", stderr(&o));
        let line = out.lines().find(|l| l.contains("slots called right")).unwrap_or_else(|| panic!("{out}"));
        assert!(line.starts_with(verdict) && line.ends_with(&counts), "{line} vs {counts}");
        assert!(line.contains(&format!("{:.2} %", 100.0 * low)), "{line}: lower bound {low}");
    }
}

#[test]
fn bad_study_flags_are_one_line_errors() {
    let dir = tempfile::tempdir().unwrap();
    let cases: [&[&str]; 6] = [
        &["sweep", "--x", "foo=1:2:3", "--out", "s"],
        &["evaluate", "--shard", "4/3", "--out", "e"],
        &["optimize", "--params", "r,height", "--out", "o"],
        &["accept", "--min-success", "1.5"],
        &["accept", "--min-slot-accuracy", "1.5"],
        &["optimize", "--test-function", "rosenbrock"],
    ];
    for args in cases {
        let o = camplace(dir.path(), args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: one line: {err}");
    }
    // A different seed in a folder holding another seed's results.
    std::fs::create_dir_all(dir.path().join("f")).unwrap();
    let cell = camplace_config::Cell::default();
    let settings = serde_json::json!({"cell": cell, "method": "one-shot", "seed": 1});
    std::fs::write(dir.path().join("f/settings.json"), settings.to_string()).unwrap();
    let o = camplace(dir.path(), &["evaluate", "--seed", "2", "--scenarios", "1", "--out", "f"]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("settings.json") && err.contains("seed 1"), "{err}");
}

#[test]
fn optimize_on_a_test_function_prints_one_json_line() {
    let dir = tempfile::tempdir().unwrap();
    let o = camplace(dir.path(), &["optimize", "--test-function", "goldstein-price", "--seed", "2", "--budget", "300"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: Value = serde_json::from_str(String::from_utf8_lossy(&o.stdout).trim()).unwrap();
    // The search's own runner gives the same numbers (the same seed, the same function).
    let run = camplace_sim::run_test_function("goldstein_price", 2, 300);
    assert_eq!(v["evaluations_to_within_1pct"].as_u64().map(|n| n as usize), run.evaluations_to_within_1pct);
    assert_eq!(v["best_value"].as_f64().unwrap(), run.best_value);
}

#[test]
fn ablate_switches_each_active_effect_off_on_the_same_scenes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cell = cell();
    let base = ["ablate", "--cell", &cell, "--seed", "5", "--scenarios", "3"];
    let o = camplace(d, &[&base[..], &["--weak", "r=abc", "--out", "bad"]].concat());
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("--weak"), "{}", stderr(&o));
    // The recommended placement from a study folder: its placement and method, not the cell's.
    let planned = "r=650,alpha=25,baseline=120,vergence=auto";
    std::fs::create_dir_all(d.join("st")).unwrap();
    let rec = serde_json::json!({
        "alpha": 25.0, "azimuth": 0.0, "baseline": 120.0, "chosen_from": "grid", "mean_correct_matches": null,
        "method": "one-shot", "placement": planned, "preset": "quick", "r": 650.0, "scenes": 0,
        "secondary_measure": "mean correct feature matches per scene", "seed": 6, "success_interval": [0.0, 1.0],
        "success_rate": 0.0, "successes": 0, "tied_candidates": 1, "trays": [], "verification": null,
        "tilt_deg": { "left_camera": 25.0, "projector": null, "right_camera": 25.0 },
        "vergence_deg": (60.0f64 / 650.0).atan().to_degrees(),
        "world_mm": { "left_camera": [0.0, 0.0, 0.0], "look_at": [0.0, 0.0, 0.0], "projector": null,
                      "right_camera": [0.0, 0.0, 0.0] },
    });
    std::fs::write(d.join("st/recommended.json"), rec.to_string()).unwrap();
    let o = camplace(d, &[&base[..], &["--study", "st", "--placement", planned, "--out", "bad"]].concat());
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let o = camplace(d, &[&base[..], &["--study", "st", "--weak", "r=700,alpha=20", "--out", "abl"]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    let table = std::fs::read_to_string(d.join("abl/ablation.md")).unwrap();
    assert!(table.contains(&format!("recommended ({planned})")), "{table}");
    // The occluder is off by default (probability 0), so it has no row of its own.
    for row in ["| all on |", "| defocus off |", "| specular off |", "| calibration_error off |"] {
        assert!(table.contains(row), "{row} missing from\n{table}");
    }
    assert!(!table.contains("occluder off"), "{table}");
    // The all-on variant is the cell itself: its scenes at the recommended placement are the
    // ones `evaluate` computes there.
    let o = camplace(
        d,
        &["evaluate", "--cell", &cell, "--placement", planned, "--seed", "5", "--scenarios", "3", "--out", "ev"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let evaluated = results_without_timings(&d.join("ev/results.jsonl"));
    let all_on = results_without_timings(&d.join("abl/all-on/results.jsonl"));
    for line in &evaluated {
        assert!(all_on.contains(line), "{line:?} not among the ablation's");
    }
}
