//! Deployment end to end: a dataset written by `render --dataset` replayed equals the
//! evaluation of the same scenarios, `run` on it equals `replay`, a slow estimator behind a
//! paced source drops frames and says how many, the deployed loop driven in process gives
//! the evaluation's poses, and missing hardware is a clear error.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use camplace_config::Cell;
use camplace_estimator::{depth::Method, scoring::FrameRecord, scoring::Summary};
use camplace_hwio::{parse_source, DeploySource, Deployment, WhenBehind};
use camplace_sim::Evaluator;

use crate::camplace_cmd::{camplace, stderr};

pub(crate) const OPTIMUM: &str = "r=605,alpha=32,baseline=81,vergence=3.5";
const SEED: u64 = 1;
const SCENES: u64 = 4;

/// A rendered dataset of `SCENES` scenarios at the optimum and the model of that placement,
/// made once for every test here. Its verification threshold is measured on 40 scenes (the
/// command's default is 200): the tests compare what replay, run and serve do with it, not its value.
pub(crate) struct Fixture {
    _dir: tempfile::TempDir,
    pub(crate) root: PathBuf,
}

pub(crate) fn fixture() -> &'static Fixture {
    static FIXTURE: OnceLock<Fixture> = OnceLock::new();
    FIXTURE.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path().to_path_buf();
        let (count, seed) = (SCENES.to_string(), SEED.to_string());
        let o = camplace(
            &root,
            &["render", "--dataset", "--count", &count, "--placement", OPTIMUM, "--seed", &seed, "--out", "data"],
        );
        assert!(o.status.success(), "{}", stderr(&o));
        let o = camplace(
            &root,
            &["model", "--placement", OPTIMUM, "--seed", &seed, "--verify-scenes", "40", "--out", "tray.model"],
        );
        assert!(o.status.success(), "{}", stderr(&o));
        Fixture { _dir: dir, root }
    })
}

/// The JSON lines of `text` as frame records (extra keys such as `sequence` ignored).
fn records(text: &str) -> Vec<FrameRecord> {
    text.lines().map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{e}: {l}"))).collect()
}

/// Everything of a record but its timings, which differ from run to run.
fn untimed(r: &FrameRecord) -> FrameRecord {
    FrameRecord { timings_ms: Default::default(), ms: 0.0, ..r.clone() }
}

fn untimed_summary(s: &Summary) -> Summary {
    Summary { median_timings_ms: Default::default(), median_ms: 0.0, ..s.clone() }
}

/// Cores this process may run on.
fn cores() -> f64 {
    std::thread::available_parallelism().map_or(1.0, |n| n.get() as f64)
}

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn replay_equals_the_evaluation_and_run_equals_replay() {
    let f = fixture();
    let o = camplace(&f.root, &["replay", "data", "--model", "tray.model"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let replayed = records(&read(&f.root.join("data/poses.jsonl")));
    let summary: Summary = serde_json::from_str(&read(&f.root.join("data/summary.json"))).unwrap();
    assert!(String::from_utf8_lossy(&o.stdout).contains(&summary.line()[..20]));

    // The evaluator of the same placement, seed and model, scene by scene.
    let evaluated = evaluated(f);

    assert_eq!(replayed.len(), SCENES as usize);
    for (r, e) in replayed.iter().zip(&evaluated) {
        assert!(r.score.is_some(), "frame {} not scored", r.frame);
        assert_eq!(untimed(r), untimed(e), "frame {}", r.frame);
    }
    // The verified figures at the threshold the model carries, as replay applied it.
    let threshold = summary.verification.expect("replay reports the verification").threshold;
    let expected =
        Summary::from_records(&evaluated).verified_at(&evaluated, threshold, 0.005, &Cell::default().metrics);
    assert_eq!(untimed_summary(&summary), untimed_summary(&expected));
    // Not a vacuous comparison: the estimator found trays here.
    assert!(summary.found > 0, "{summary:?}");

    let o = camplace(
        &f.root,
        &["run", "--source", "dir:data", "--model", "tray.model", "--out", "run.jsonl", "--latency-plot", "latency"],
    );
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    let text = read(&f.root.join("run.jsonl"));
    let run = records(&text);
    assert_eq!(run.len(), replayed.len(), "one pose per frame");
    for (r, p) in run.iter().zip(&replayed) {
        assert_eq!(untimed(r), untimed(p), "frame {}", r.frame);
    }
    for (i, line) in text.lines().enumerate() {
        let v: serde_json::Value = serde_json::from_str(line).unwrap();
        assert_eq!(v["sequence"], i as u64, "{line}");
        let (latency, cpu) = (v["latency_ms"].as_f64().unwrap(), v["cpu_ms"].as_f64().unwrap());
        assert!(latency > 0.0, "{line}");
        // The process cannot use more CPU than its cores over the wall time (1 ms for clock steps).
        assert!(cpu > 0.0 && cpu <= latency * cores() + 1.0, "{line}");
    }
    assert!(err.contains(&format!("{SCENES} frames estimated, 0 dropped")), "{err}");
    assert!(err.contains("p50") && err.contains("p90") && err.contains("p99"), "{err}");
    // Each one-shot stage's percentiles, and the CPU time per frame.
    for stage in camplace_estimator::StageTimings::STAGES {
        assert!(err.lines().any(|l| l.split_whitespace().next() == Some(stage)), "no {stage} row: {err}");
    }
    assert!(err.contains("CPU time per frame: while estimating p50"), "{err}");
    // With a font (CI installs one) the plot is drawn; without, the run says it skipped it.
    let font = camplace_plot::ensure_plot_font().is_ok();
    assert_eq!(err.contains("latency plot:"), font, "{err}");
    assert_eq!(err.contains("plots skipped"), !font, "{err}");
    for ext in ["svg", "png"] {
        assert_eq!(f.root.join(format!("latency.{ext}")).is_file(), font, "latency.{ext}: {err}");
    }
}

#[test]
fn run_gives_each_pose_in_the_robots_frame_when_the_cell_has_one() {
    let f = fixture();
    let t_robot_world = [[0.0, -1.0, 0.0, 450.0], [1.0, 0.0, 0.0, -120.0], [0.0, 0.0, 1.0, 35.0], [0.0, 0.0, 0.0, 1.0]];
    let rows: Vec<String> = t_robot_world.iter().map(|r| format!("{r:?}")).collect();
    std::fs::write(f.root.join("robot.toml"), format!("[robot]\nT_robot_world = [{}]\n", rows.join(", "))).unwrap();
    let o = camplace(
        &f.root,
        &["run", "--source", "dir:data", "--model", "tray.model", "--cell", "robot.toml", "--out", "robot.jsonl"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let text = read(&f.root.join("robot.jsonl"));
    let mut found = 0;
    for line in text.lines() {
        let v: serde_json::Value = serde_json::from_str(line).unwrap();
        if v["found"] != true || v["verdict"] != "accepted" {
            assert!(v.get("T_robot_tray").is_none(), "no robot pose without an accepted pose: {line}");
            continue;
        }
        found += 1;
        let m = |key: &str| -> nalgebra::Matrix4<f64> {
            nalgebra::Matrix4::from_fn(|i, j| v[key][i][j].as_f64().unwrap_or_else(|| panic!("{key}: {line}")))
        };
        let want = nalgebra::Matrix4::from_fn(|i, j| t_robot_world[i][j]) * m("T_world_tray");
        assert!((m("T_robot_tray") - want).abs().max() < 1e-9, "{line}");
    }
    assert!(found > 0, "the estimator found and accepted trays here");
}

/// The evaluator's records of the fixture's scenes. A dataset's `rig.json` is the rig that
/// took it, so replay and run use the true rig; the evaluation does too when its
/// per-scenario calibration error is off (which changes neither the images nor the model).
fn evaluated(f: &Fixture) -> Vec<FrameRecord> {
    let mut cell = Cell::default();
    cell.effects.calibration_error = false;
    let placement = cell.placement.with_overrides(OPTIMUM).unwrap();
    let bytes = std::fs::read(f.root.join("tray.model")).unwrap();
    let model = camplace_estimator::Model::from_bytes(&bytes).unwrap();
    let evaluator = Evaluator::with_model(&cell, &placement, Method::OneShot, SEED, model).unwrap();
    let mut worker = evaluator.worker().unwrap();
    (0..SCENES).map(|i| worker.scene(i).unwrap()).collect()
}

#[test]
fn the_deployed_loop_in_process_gives_the_evaluations_poses() {
    let f = fixture();
    let spec = parse_source(&format!("dir:{}", f.root.join("data").display())).unwrap();
    let opened = DeploySource::open(&spec, None, None, None).unwrap();
    assert_eq!(opened.when_behind, WhenBehind::Wait, "an unpaced recording drops nothing");
    let cell = Cell::default();
    let rig = camplace_estimator::Rig::from_file(&opened.rig);
    let bytes = std::fs::read(f.root.join("tray.model")).unwrap();
    let model = camplace_estimator::Model::from_bytes(&bytes).unwrap();
    let mut estimator = camplace_estimator::Estimator::new(
        &camplace_estimator::EstimatorConfig::from(&cell),
        &rig,
        model,
        Method::OneShot,
    )
    .unwrap();
    let background = opened.background.as_ref().expect("render --dataset writes the background");
    estimator.set_background(&background.left, &background.right).unwrap();

    let mut got = Vec::new();
    let stats = Deployment::new(opened.source, opened.when_behind, estimator)
        .run(
            |estimator, pose, info| {
                Ok::<_, camplace_hwio::Error>(FrameRecord::new(info.name.as_str(), pose).with_slots(estimator.slots()))
            },
            |e| {
                got.push(e);
                Ok(())
            },
        )
        .unwrap();

    assert_eq!(stats.dropped, 0);
    assert_eq!(stats.frames.len(), SCENES as usize);
    assert!(stats.line().starts_with(&format!("{SCENES} frames estimated, 0 dropped")), "{}", stats.line());
    let evaluated = evaluated(f);
    assert_eq!(got.len(), evaluated.len(), "one pose per frame");
    for (i, (g, e)) in got.iter().zip(&evaluated).enumerate() {
        let t = &g.timing;
        assert_eq!(t.sequence, i as u64);
        assert_eq!(stats.frames[i], *t, "the stats keep what was handed over");
        // The estimator's time is part of the capture-to-pose latency, and the process cannot
        // use more CPU than its cores over that time (1 ms for clock steps).
        assert!(t.stages.total_ms > 0.0 && t.stages.total_ms <= t.latency_ms, "{t:?}");
        assert!(t.cpu_ms > 0.0 && t.cpu_ms <= t.latency_ms * cores() + 1.0, "{t:?}");
        assert!(t.stages.by_stage().iter().sum::<f64>() <= t.stages.total_ms, "{t:?}");
        assert_eq!(
            untimed(&g.record),
            FrameRecord { score: None, slot_score: None, ..untimed(e) },
            "frame {}",
            e.frame
        );
    }
}

#[test]
fn a_slow_estimator_behind_a_paced_source_drops_frames_and_counts_them() {
    let f = fixture();
    let o = camplace(
        &f.root,
        &["run", "--source", "dir:data", "--model", "tray.model", "--fps", "20", "--debug-delay-ms", "500"],
    );
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    let sequences: Vec<u64> = text
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap()["sequence"].as_u64().unwrap())
        .collect();
    let dropped: u64 = err
        .split(" dropped")
        .next()
        .and_then(|s| s.rsplit(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no drop count in: {err}"));
    assert!(dropped > 0, "{err}");
    assert_eq!(sequences.len() as u64 + dropped, SCENES, "{sequences:?} + {dropped}");
    // The newest frames win: what is emitted is in order and ends with the last frame.
    assert!(sequences.windows(2).all(|w| w[0] < w[1]), "{sequences:?}");
    assert_eq!(sequences.last(), Some(&(SCENES - 1)));
}

fn assert_one_line_error(o: &std::process::Output, must_name: &[&str]) {
    let err = stderr(o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "one line: {err}");
    assert!(!err.contains("panicked"), "{err}");
    for s in must_name {
        assert!(err.contains(s), "{s:?} missing from: {err}");
    }
}

#[test]
fn bad_run_flags_are_one_line_errors() {
    let f = fixture();
    let o = camplace(&f.root, &["run", "--source", "dir:data", "--model", "tray.model", "--fps", "0"]);
    assert_one_line_error(&o, &["--fps", "positive"]);
    let o = camplace(&f.root, &["run", "--source", "dir:nowhere", "--model", "tray.model"]);
    assert_one_line_error(&o, &["nowhere"]);
    let o = camplace(
        &f.root,
        &["run", "--source", "dir:data", "--model", "tray.model", "--latency-plot", "no/such/folder/latency"],
    );
    assert_one_line_error(&o, &["--latency-plot", "no/such/folder/latency", "existing folder"]);
}

#[test]
fn a_model_of_another_tray_is_refused_when_a_cell_is_given() {
    let f = fixture();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("tray4.toml"), "[tray]\nkind = \"tray-4\"\n").unwrap();
    std::fs::write(d.join("old.model"), camplace_testing::tray(false, 1).to_bytes()).unwrap();
    let data = f.root.join("data").display().to_string();
    let model = f.root.join("tray.model").display().to_string();
    let source = format!("dir:{data}");
    let runs: [&[&str]; 3] = [
        &["estimate", "--dataset", &data, "--model", &model, "--cell", "tray4.toml"],
        &["replay", &data, "--model", &model, "--cell", "tray4.toml"],
        &["run", "--source", &source, "--model", &model, "--cell", "tray4.toml"],
    ];
    for args in runs {
        let o = camplace(d, args);
        assert_one_line_error(
            &o,
            &["tray.model", "built for tray tray-8", "tray4.toml has tray tray-4", "camplace model"],
        );
    }
    std::fs::write(d.join("default.toml"), "").unwrap();
    let o = camplace(d, &["estimate", "--dataset", &data, "--model", "old.model", "--cell", "default.toml"]);
    assert_one_line_error(&o, &["old.model", "records no tray", "rebuild it with camplace model"]);
}

#[test]
fn replay_without_truth_leaves_no_earlier_summary() {
    let f = fixture();
    let dir = tempfile::tempdir().unwrap();
    let bare = dir.path().join("bare");
    // The fixture's dataset without its truth: rig, background and the camera images.
    std::fs::create_dir_all(bare.join("background")).unwrap();
    std::fs::copy(f.root.join("data/rig.json"), bare.join("rig.json")).unwrap();
    for side in ["left.png", "right.png"] {
        std::fs::copy(f.root.join("data/background").join(side), bare.join("background").join(side)).unwrap();
        for i in 0..SCENES {
            let frame = format!("frames/{i:04}");
            std::fs::create_dir_all(bare.join(&frame)).unwrap();
            std::fs::copy(f.root.join("data").join(&frame).join(side), bare.join(&frame).join(side)).unwrap();
        }
    }
    std::fs::write(bare.join("summary.json"), "{\"frames\": 99}").unwrap();
    // A cell file of the model's own tray passes the tray check.
    std::fs::write(dir.path().join("default.toml"), "").unwrap();
    let model = f.root.join("tray.model").display().to_string();
    let o = camplace(dir.path(), &["replay", "bare", "--model", &model, "--cell", "default.toml"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!bare.join("summary.json").exists(), "the earlier summary is gone");
    let replayed = records(&read(&bare.join("poses.jsonl")));
    let evaluated = evaluated(f);
    assert_eq!(replayed.len(), evaluated.len());
    for (r, e) in replayed.iter().zip(&evaluated) {
        assert_eq!(untimed(r), FrameRecord { score: None, slot_score: None, ..untimed(e) }, "frame {}", r.frame);
    }
}
