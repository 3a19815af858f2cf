//! The real-world trial end to end on a mock trial: plan, mock (truth hidden), estimate,
//! scripted marks, report; the review page driven in headless Chromium; bad trial folders.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::OnceLock;

use serde_json::Value;

use crate::camplace_cmd::{assert_one_line_error, camplace, stderr};

/// The small cell: 320 × 240 cameras, few RANSAC iterations.
fn small_cell() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/small_cell.toml")
}

fn run_ok(dir: &Path, args: &[&str]) -> String {
    let o = camplace(dir, args);
    assert!(o.status.success(), "{args:?}: {}", stderr(&o));
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// A 2 × 2 sweep (5 scenes each), a mock trial of its 4 placements × 6 frames rendered
/// with another seed, noise and blur, its truth hidden, the tray model, every placement
/// estimated. Returns the folder holding `sweep/`, `trial/`, `hidden/`, `tray.model`.
fn fixture() -> &'static Path {
    static FOLDER: OnceLock<tempfile::TempDir> = OnceLock::new();
    FOLDER
        .get_or_init(|| {
            let dir = tempfile::tempdir().unwrap();
            let d = dir.path();
            let cell = small_cell();
            let cell = cell.to_str().unwrap();
            run_ok(
                d,
                &[
                    "sweep",
                    "--cell",
                    cell,
                    "--x",
                    "r=500:800:2",
                    "--y",
                    "alpha=10:50:2",
                    "--scenarios",
                    "5",
                    "--out",
                    "sweep",
                ],
            );
            run_ok(d, &["trial", "plan", "--cell", cell, "--study", "sweep", "--out", "plan.json"]);
            run_ok(
                d,
                &[
                    "trial",
                    "mock",
                    "--plan",
                    "plan.json",
                    "--cell",
                    cell,
                    "--noise-amplitude",
                    "5",
                    "--blur",
                    "3",
                    "--seed",
                    "4242",
                    "--frames",
                    "6",
                    "--hidden",
                    "hidden",
                    "--out",
                    "trial",
                ],
            );
            run_ok(d, &["model", "--cell", cell, "--verify-scenes", "5", "--out", "tray.model"]);
            run_ok(d, &["trial", "estimate", "--trial", "trial", "--model", "tray.model", "--cell", cell]);
            dir
        })
        .path()
}

fn json(path: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// Copies a folder tree.
fn copy_tree(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        let target = to.join(e.file_name());
        if e.file_type().unwrap().is_dir() {
            copy_tree(&e.path(), &target);
        } else {
            std::fs::copy(e.path(), target).unwrap();
        }
    }
}

/// Successes at placement `i` by the hidden truth, counted another way than the trial's:
/// the placement's frames copied with their truth.json put back and replayed.
fn hidden_successes(d: &Path, i: usize) -> u64 {
    let copy = tempfile::tempdir().unwrap();
    let ds = copy.path().join("ds");
    copy_tree(&d.join(format!("trial/{i:03}")), &ds);
    for f in ["poses.jsonl", "labels.jsonl"] {
        let _ = std::fs::remove_file(ds.join(f));
    }
    for e in std::fs::read_dir(d.join(format!("hidden/{i:03}"))).unwrap() {
        let p = e.unwrap().path();
        let name = p.file_stem().unwrap().to_str().unwrap().to_string();
        std::fs::copy(&p, ds.join("frames").join(name).join("truth.json")).unwrap();
    }
    let cell = small_cell();
    run_ok(d, &["replay", ds.to_str().unwrap(), "--model", "tray.model", "--cell", cell.to_str().unwrap()]);
    json(&ds.join("summary.json"))["successes"].as_u64().unwrap()
}

#[test]
fn a_mock_trial_reports_every_placements_real_success_as_the_hidden_truth_counts_it() {
    let d = fixture();
    let trial = tempfile::tempdir().unwrap();
    let t = trial.path().join("trial");
    copy_tree(&d.join("trial"), &t);
    // The trial folder holds no truth: the mock moved it aside.
    for i in 0..4 {
        let frame = t.join(format!("{i:03}/frames/0000"));
        assert!(
            frame.join("left.png").is_file()
                && !frame.join("truth.json").exists()
                && !frame.join("depth_left.pfm").exists()
        );
    }
    let cell = small_cell();
    let cell = cell.to_str().unwrap();
    let t_arg = t.to_str().unwrap();
    let hidden = d.join("hidden");
    run_ok(d, &["trial", "mark", "--trial", t_arg, "--hidden", hidden.to_str().unwrap(), "--cell", cell]);
    let out = run_ok(d, &["trial", "report", "--trial", t_arg, "--study", "sweep", "--cell", cell]);
    let r = json(&t.join("trial_report.json"));
    let rows = r["placements"].as_array().unwrap();
    assert_eq!(rows.len(), 4);
    let sweep = json(&d.join("sweep/summary.json"));
    for (i, row) in rows.iter().enumerate() {
        assert_eq!(row["real"]["frames"], 6, "{row}");
        assert_eq!(row["real"]["successes"].as_u64().unwrap(), hidden_successes(d, i), "placement {i}: {row}");
        // The simulated side is the sweep's own count at the same placement.
        let s = &sweep[i];
        assert_eq!(row["placement"], s["placement"]);
        assert_eq!(row["simulated"]["successes"], s["successes"], "{row}");
        assert_eq!(row["simulated"]["frames"], s["scored"], "{row}");
    }
    // Both maps, the correlation as the rows give it, the verdict and the paired difference.
    for m in ["trial_map_real.svg", "trial_map_simulated.svg"] {
        assert!(t.join(m).is_file(), "{m}");
    }
    let real: Vec<f64> = rows.iter().map(|x| x["real"]["success_rate"].as_f64().unwrap()).collect();
    let sim: Vec<f64> = rows.iter().map(|x| x["simulated"]["success_rate"].as_f64().unwrap()).collect();
    let constant = |v: &[f64]| v.iter().all(|x| *x == v[0]);
    if constant(&real) || constant(&sim) {
        assert!(r["rank_correlation"].is_null(), "{r}");
    } else {
        let rho = r["rank_correlation"]["rho"].as_f64().unwrap();
        assert!((-1.0..=1.0).contains(&rho));
        assert!(r["rank_correlation"]["interval"].is_array());
    }
    assert!(out.contains("ρ"), "{out}");
    let best = r["simulated_best"].as_u64().unwrap() as usize;
    let best_sim = sim.iter().cloned().fold(f64::MIN, f64::max);
    assert_eq!(sim[best], best_sim, "the simulation's best is its highest");
    assert_eq!(r["simulated_best_in_real_top_set"], rows[best]["in_real_top_set"]);
    assert_eq!(r["paired_difference"]["frames"], 6);
    let html = std::fs::read_to_string(t.join("trial_report.html")).unwrap();
    assert!(html.matches("<svg").count() >= 2 && html.contains("data-key=\"rank_correlation\""));
}

/// The first stdout line of `camplace review --listen` names the address.
fn serve(d: &Path, dataset: &Path) -> (std::process::Child, String) {
    let cell = small_cell();
    let mut child = Command::new(env!("CARGO_BIN_EXE_camplace"))
        .args([
            "review",
            dataset.to_str().unwrap(),
            "--cell",
            cell.to_str().unwrap(),
            "--listen",
            "127.0.0.1:0",
            "--idle-exit",
            "60",
        ])
        .current_dir(d)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.as_mut().unwrap()).read_line(&mut line).unwrap();
    let url =
        line.split_whitespace().find(|w| w.starts_with("http://")).unwrap_or_else(|| panic!("{line}")).to_string();
    (child, url)
}

/// The `<body ...>` attributes of the page after the script ran.
fn drive(browser: &str, url: &str) -> String {
    let o = Command::new(browser)
        .args(["--headless", "--no-sandbox", "--disable-gpu", "--virtual-time-budget=20000", "--dump-dom", url])
        .output()
        .expect("chromium runs");
    let dom = String::from_utf8_lossy(&o.stdout).into_owned();
    let at = dom.find("<body").unwrap_or_else(|| panic!("no page: {}", stderr(&o)));
    dom[at..at + dom[at..].find('>').unwrap()].to_string()
}

fn attr(body: &str, name: &str) -> String {
    let at = body.find(&format!("{name}=\"")).unwrap_or_else(|| panic!("no {name} in {body}"));
    let v = &body[at + name.len() + 2..];
    v[..v.find('"').unwrap()].to_string()
}

#[test]
fn the_review_page_driven_by_key_presses_in_chromium_saves_the_scripted_marks_and_resumes() {
    let Some(browser) = crate::browser::chromium("the review page's browser test") else {
        return;
    };
    let d = fixture();
    let work = tempfile::tempdir().unwrap();
    // The scripted reviewer's marks, from the hidden truth, on a copy of the trial.
    let scripted = work.path().join("scripted");
    copy_tree(&d.join("trial"), &scripted);
    let cell = small_cell();
    run_ok(
        d,
        &[
            "trial",
            "mark",
            "--trial",
            scripted.to_str().unwrap(),
            "--hidden",
            "hidden",
            "--cell",
            cell.to_str().unwrap(),
        ],
    );
    let expected = std::fs::read_to_string(scripted.join("002/labels.jsonl")).unwrap();
    let keys: String = expected.lines().map(|l| if l.contains("\"correct\"") { 'c' } else { 'w' }).collect();
    assert_eq!(keys.len(), 6);
    // The dataset under review: placement 002 without marks.
    let ds = work.path().join("ds");
    copy_tree(&d.join("trial/002"), &ds);
    // First sitting: three frames, then the page is closed.
    let (mut server, url) = serve(d, &ds);
    let body = drive(browser, &format!("{url}#script={}&quit", &keys[..3]));
    assert!(server.wait().unwrap().success());
    assert_eq!(attr(&body, "data-start"), "0000");
    assert_eq!(attr(&body, "data-script-done"), "1");
    let saved = std::fs::read_to_string(ds.join("labels.jsonl")).unwrap();
    let first: Vec<&str> = expected.lines().take(3).collect();
    assert_eq!(saved.lines().collect::<Vec<_>>(), first, "the first sitting's marks");
    // Reopened: the page starts at the first open frame and the rest are marked.
    let (mut server, url) = serve(d, &ds);
    let body = drive(browser, &format!("{url}#script={}&quit", &keys[3..]));
    assert!(server.wait().unwrap().success());
    assert_eq!(attr(&body, "data-start"), "0003", "resumes at the first frame without a mark");
    assert_eq!(attr(&body, "data-judged"), "6");
    assert_eq!(std::fs::read_to_string(ds.join("labels.jsonl")).unwrap(), expected, "every mark as scripted");
    assert_eq!(attr(&body, "data-marks"), keys);

    // The 3D view, on the page written to a file: each frame's scene cloud (its scene.ply,
    // which `trial estimate` wrote) and the tray's surface at the frame's pose.
    run_ok(d, &["review", ds.to_str().unwrap(), "--cell", small_cell().to_str().unwrap()]);
    let html = std::fs::read_to_string(ds.join("review.html")).unwrap();
    let at = html.find("const data = ").unwrap() + "const data = ".len();
    let data: Value = serde_json::from_str(&html[at..at + html[at..].find(";\n").unwrap()]).unwrap();
    let tray = &data["tray_points"][0];
    let poses: Vec<Value> = std::fs::read_to_string(ds.join("poses.jsonl"))
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let mut checked = 0;
    for (frame, pose) in data["frames"].as_array().unwrap().iter().zip(&poses) {
        let name = frame["name"].as_str().unwrap();
        let scene = camplace_config::read_cloud(&ds.join("frames").join(name).join("scene.ply")).unwrap().points;
        let drawn = frame["cloud"].as_array().unwrap();
        assert!(!drawn.is_empty() && drawn.len() <= 1500 && drawn.len() >= scene.len().min(1500) / 2, "{name}");
        // Every drawn point is one of scene.ply's, written to 0.1 mm (brute force).
        let drawn: Vec<[f64; 3]> = drawn.iter().map(|p| [0, 1, 2].map(|i| p[i].as_f64().unwrap())).collect();
        let written: Vec<[f64; 3]> = scene.iter().map(|p| p.map(f64::from)).collect();
        let off = crate::browser::farthest_from(&drawn, &written);
        assert!(off < 0.09, "frame {name}: a drawn point is {off} mm from its scene.ply");
        assert_eq!(frame["pose"].is_null(), !pose["found"].as_bool().unwrap(), "{name}");
        checked += 1;
    }
    assert_eq!(checked, 6);
    // In Chromium: the first frame's view, its points and the tray placed by its pose.
    let o = Command::new(browser)
        .args(["--headless", "--no-sandbox", "--disable-gpu", "--virtual-time-budget=5000", "--dump-dom"])
        .arg(format!("file://{}", ds.join("review.html").display()))
        .output()
        .expect("chromium runs");
    let dom = String::from_utf8_lossy(&o.stdout).into_owned();
    let shown = crate::browser::dom_attr(&dom, "data-frame").expect("the frame shown");
    let k = data["frames"].as_array().unwrap().iter().position(|f| f["name"] == shown.as_str()).unwrap();
    let counts: Value = serde_json::from_str(&crate::browser::dom_attr(&dom, "data-clouds").unwrap()).unwrap();
    assert_eq!(counts["scene"], data["frames"][k]["cloud"].as_array().unwrap().len(), "{counts}");
    let posed: Value = serde_json::from_str(&crate::browser::dom_attr(&dom, "data-posed").unwrap()).unwrap();
    if poses[k]["found"].as_bool().unwrap() {
        assert_eq!(counts["model"], data["tray_points"].as_array().unwrap().len(), "{counts}");
        let t = &poses[k]["T_world_tray"];
        for r in 0..3 {
            let want: f64 = (0..3).map(|c| t[r][c].as_f64().unwrap() * tray[c].as_f64().unwrap()).sum::<f64>()
                + t[r][3].as_f64().unwrap();
            let got = posed["model"][r].as_f64().unwrap();
            assert!((got - want).abs() < 1e-6, "the tray's first point drawn at {posed} against {want} (row {r})");
        }
    } else {
        assert!(counts["model"].is_null() && posed["model"].is_null(), "no pose, no tray: {counts} {posed}");
    }
    // As a screenshot, the view alone at the top: the scene cloud's grey is drawn.
    let top = ds.join("top.html");
    let style = "<style>#view3d{position:fixed;top:0;left:0;z-index:9;background:#fff}</style>";
    std::fs::write(&top, html.replace("</body>", &format!("{style}</body>"))).unwrap();
    let shot = work.path().join("review.png");
    Command::new(browser)
        .args(["--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars", "--window-size=1280,800"])
        .args(["--virtual-time-budget=5000".to_string(), format!("--screenshot={}", shot.display())])
        .arg(format!("file://{}", top.display()))
        .output()
        .expect("chromium runs");
    let canvas = crate::browser::region(&shot, 2..718, 2..478);
    let drawn = canvas.iter().filter(|p| **p != [0xf4, 0xf6, 0xf8]).count();
    assert!(drawn > 500, "{drawn} pixels of the 3D view drawn");
    assert!(crate::browser::shows_colour(&canvas, "#6b6f76"), "the scene cloud is drawn");
}

#[test]
fn bad_trial_folders_end_with_one_line_naming_the_file_and_key() {
    let d = fixture();
    let cell = small_cell();
    let cell = cell.to_str().unwrap();
    // A placement folder with another cell's rig: the default cell's 640 × 480 cameras.
    let w = tempfile::tempdir().unwrap();
    let t = w.path().join("trial");
    copy_tree(&d.join("trial"), &t);
    run_ok(w.path(), &["render", "--out", "other"]);
    std::fs::copy(w.path().join("other/rig.json"), t.join("001/rig.json")).unwrap();
    let o = camplace(w.path(), &["trial", "report", "--trial", "trial", "--cell", cell]);
    assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["001/rig.json", "left.width", "camera_resolution"]);
    // Labels for a frame that does not exist.
    let t = w.path().join("trial2");
    copy_tree(&d.join("trial"), &t);
    std::fs::write(
        t.join("000/labels.jsonl"),
        "{\"frame\":\"0000\",\"mark\":\"correct\"}\n{\"frame\":\"0042\",\"mark\":\"wrong\"}\n",
    )
    .unwrap();
    let o = camplace(w.path(), &["trial", "report", "--trial", "trial2", "--cell", cell]);
    assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["000/labels.jsonl", "line 2", "frame", "0042"]);
    let o = camplace(w.path(), &["review", "trial2/000", "--cell", cell]);
    assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["000/labels.jsonl", "frame", "0042"]);
    // A plan with no placements.
    let t = w.path().join("trial3");
    copy_tree(&d.join("trial"), &t);
    std::fs::write(t.join("plan.json"), "{\"placements\": []}\n").unwrap();
    for args in [
        &["trial", "report", "--trial", "trial3", "--cell", cell][..],
        &["trial", "estimate", "--trial", "trial3", "--model", "x.model"][..],
        &["capture", "--source", "dir:x", "--trial", "trial3", "--placement", "0"][..],
    ] {
        let o = camplace(w.path(), args);
        assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["trial3/plan.json", "placements"]);
    }
    let o = camplace(w.path(), &["trial", "plan", "--placements", " ; ", "--out", "p.json"]);
    assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["--placements", "at least one"]);
}

/// Each frame's pose as the review page draws it: found, T_world_tray and verdict.
fn drawn_poses(path: &Path) -> Vec<(String, String)> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .map(|l| {
            let v: Value = serde_json::from_str(l).unwrap();
            (v["frame"].as_str().unwrap().to_string(), format!("{} {} {}", v["found"], v["T_world_tray"], v["verdict"]))
        })
        .collect()
}

#[test]
fn marks_count_only_for_the_poses_they_judged_after_the_trial_is_estimated_again() {
    let d = fixture();
    let trial = tempfile::tempdir().unwrap();
    let t = trial.path().join("trial");
    copy_tree(&d.join("trial"), &t);
    let cell = small_cell();
    let cell = cell.to_str().unwrap();
    let t_arg = t.to_str().unwrap();
    let hidden = d.join("hidden");
    run_ok(d, &["trial", "mark", "--trial", t_arg, "--hidden", hidden.to_str().unwrap(), "--cell", cell]);
    let report = || {
        run_ok(d, &["trial", "report", "--trial", t_arg, "--study", "sweep", "--cell", cell]);
        json(&t.join("trial_report.json"))["placements"].as_array().unwrap().clone()
    };
    let rows = report();
    assert!(rows.iter().all(|r| r["marked"].as_u64().unwrap() + r["unsure"].as_u64().unwrap() == 6), "{rows:?}");
    let labels: Vec<Vec<u8>> = (0..4).map(|i| std::fs::read(t.join(format!("{i:03}/labels.jsonl"))).unwrap()).collect();
    let before: Vec<_> = (0..4).map(|i| drawn_poses(&t.join(format!("{i:03}/poses.jsonl")))).collect();
    // Another model draws other poses: a mark stands only where its frame's pose did not change.
    run_ok(d, &["model", "--cell", cell, "--verify-scenes", "0", "--seed", "77", "--out", "other.model"]);
    run_ok(d, &["trial", "estimate", "--trial", t_arg, "--model", "other.model", "--cell", cell]);
    let after_rows = report();
    let mut changed_total = 0;
    for i in 0..4 {
        let after = drawn_poses(&t.join(format!("{i:03}/poses.jsonl")));
        let changed = before[i].iter().zip(&after).filter(|(a, b)| a != b).count() as u64;
        changed_total += changed;
        let (row, earlier) = (&after_rows[i], &rows[i]);
        let judged = |r: &Value| r["marked"].as_u64().unwrap() + r["unsure"].as_u64().unwrap();
        assert_eq!(judged(row), 6 - changed, "placement {i}: {changed} poses changed: {row}");
        assert_eq!(row["not_judged"].as_u64().unwrap(), earlier["not_judged"].as_u64().unwrap() + changed, "{row}");
        // The marks themselves are the reviewer's: kept byte for byte.
        assert_eq!(std::fs::read(t.join(format!("{i:03}/labels.jsonl"))).unwrap(), labels[i], "placement {i}");
    }
    assert!(changed_total > 0, "the other model changed no pose; the test shows nothing");
}

#[test]
#[cfg(unix)]
fn a_plan_whose_table_cannot_be_written_writes_neither_file() {
    let d = fixture();
    let out = tempfile::tempdir().unwrap();
    let o = out.path();
    let made = Command::new("mkfifo").arg(o.join("plan.csv")).status().unwrap();
    assert!(made.success());
    let cell = small_cell();
    let plan = o.join("plan.json");
    let args = ["trial", "plan", "--cell", cell.to_str().unwrap(), "--study", "sweep", "--out", plan.to_str().unwrap()];
    let refused = camplace(d, &args);
    assert_one_line_error(refused.status.code().unwrap(), &stderr(&refused), &["plan.csv", "FIFO"]);
    assert!(!plan.exists(), "no plan.json without its plan.csv");
    use std::os::unix::fs::FileTypeExt;
    assert!(std::fs::symlink_metadata(o.join("plan.csv")).unwrap().file_type().is_fifo(), "the FIFO left as it was");
}
