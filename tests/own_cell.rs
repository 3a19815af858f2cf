//! A study of the user's own cell: two mesh trays with their own items, one placement for
//! both. The study reports each tray, judges every placement by its lower tray, and its
//! report opens in a real browser with every image loaded and the headline numbers of
//! `recommended.json`, which agree with the scenes in the trays' results files.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use serde_json::Value;

use crate::camplace_cmd::{assert_one_line_error, camplace, stderr};
use crate::meshes::{boxes_stl, tray_stl};

const TWO_TRAYS: &str = r#"
[sensor]
camera_resolution = [320, 240]

[estimator]
ransac_iterations = 2000

[[trays]]
name = "six-slot"
kind = "mesh"
mesh = "six.stl"
slots = [[-70.0, -35.0, 6.0, 0.0], [0.0, -35.0, 6.0, 0.0], [70.0, -35.0, 6.0, 0.0],
         [-70.0, 35.0, 6.0, 0.0], [0.0, 35.0, 6.0, 0.0], [70.0, 35.0, 6.0, 0.0]]
[trays.items]
kind = "mesh"
mesh = "item.stl"

[[trays]]
name = "four-slot"
kind = "mesh"
mesh = "four.stl"
slots = [[-40.0, -30.0, 6.0, 0.0], [40.0, -30.0, 6.0, 0.0], [-40.0, 30.0, 6.0, 0.0], [40.0, 30.0, 6.0, 0.0]]
[trays.items]
size = [40.0, 40.0, 20.0]
"#;

/// Writes the two-tray cell and its meshes into `d`.
fn write_cell(d: &Path) {
    std::fs::write(d.join("six.stl"), tray_stl(240.0, 150.0, 6.0, 8.0, 30.0)).unwrap();
    std::fs::write(d.join("four.stl"), tray_stl(180.0, 130.0, 6.0, 8.0, 25.0)).unwrap();
    std::fs::write(d.join("item.stl"), boxes_stl(&[([-17.0, -17.0, 0.0], [17.0, 17.0, 30.0])])).unwrap();
    std::fs::write(d.join("cell.toml"), TWO_TRAYS).unwrap();
}

/// A quick one-shot study of the two-tray cell, run once for the tests here.
pub(crate) fn study() -> &'static Path {
    static FOLDER: OnceLock<(tempfile::TempDir, PathBuf)> = OnceLock::new();
    &FOLDER
        .get_or_init(|| {
            let dir = tempfile::tempdir().unwrap();
            write_cell(dir.path());
            let o = camplace(
                dir.path(),
                &["study", "--quick", "--method", "one-shot", "--cell", "cell.toml", "--out", "study"],
            );
            assert!(o.status.success(), "{}", stderr(&o));
            let out = dir.path().join("study");
            (dir, out)
        })
        .1
}

/// `summary.csv` as placement → (successes, scenes).
fn sweep_rates(path: &Path) -> HashMap<String, (u64, u64)> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (scenes, successes) = (col("scenes"), col("successes"));
    lines
        .map(|l| {
            // The placement is quoted and holds commas; the numbers follow it.
            let (placement, rest) = l.strip_prefix('"').unwrap().split_once("\",").unwrap();
            let f: Vec<&str> = rest.split(',').collect();
            let at = |i: usize| f[i - 1].parse::<u64>().unwrap();
            (placement.to_string(), (at(successes), at(scenes)))
        })
        .collect()
}

fn json(path: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))).unwrap()
}

#[test]
fn a_study_of_two_mesh_trays_reports_both_and_judges_each_placement_by_the_lower() {
    let out = study();
    let six = sweep_rates(&out.join("six-slot/one-shot/summary.csv"));
    let four = sweep_rates(&out.join("four-slot/one-shot/summary.csv"));
    let joint = sweep_rates(&out.join("all-trays/one-shot/summary.csv"));
    assert_eq!(joint.len(), 9, "a 3 × 3 grid");
    for (placement, &(k, n)) in &joint {
        let (a, b) = (six[placement], four[placement]);
        assert_eq!(n, 4);
        // The lower rate of the two (both trays ran the same number of scenes).
        assert_eq!(k, a.0.min(b.0), "{placement}: six-slot {a:?}, four-slot {b:?}, joint {k}");
    }
    let rec = json(&out.join("recommended.json"));
    let trays = rec["trays"].as_array().unwrap();
    let names: Vec<&str> = trays.iter().map(|t| t["name"].as_str().unwrap()).collect();
    assert_eq!(names, ["six-slot", "four-slot"]);
    let lowest = trays.iter().map(|t| t["success_rate"].as_f64().unwrap()).fold(f64::INFINITY, f64::min);
    assert_eq!(rec["success_rate"].as_f64().unwrap(), lowest);
    // Each tray's rate is what its results file holds for the placement on the fresh seed.
    let placement = rec["placement"].as_str().unwrap();
    let seed = rec["seed"].as_u64().unwrap();
    for t in trays {
        let results = out.join(t["name"].as_str().unwrap()).join("one-shot/results.jsonl");
        let lines: Vec<Value> = std::fs::read_to_string(&results)
            .unwrap()
            .lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .filter(|v: &Value| v["placement"] == placement && v["seed"] == seed)
            .collect();
        assert_eq!(lines.len() as u64, t["scenes"].as_u64().unwrap(), "{}", results.display());
        let ok = lines.iter().filter(|v| v["success"] == true).count() as u64;
        assert_eq!(ok, t["successes"].as_u64().unwrap(), "{}", results.display());
    }
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    for heading in ["six-slot one-shot", "four-slot one-shot", "Recommended placement", "quick preview"] {
        assert!(html.contains(heading), "{heading} missing from the report");
    }
    assert!(!html.contains("Findings against the paper"), "the paper's findings come with --paper only");
    // A rig mounted exactly at the recommendation reads back as it, against the study's plan.
    let dir = tempfile::tempdir().unwrap();
    write_cell(dir.path());
    let o = camplace(
        dir.path(),
        &["render", "--cell", "cell.toml", "--tray", "six-slot", "--placement", placement, "--out", "r"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let study_dir = out.display().to_string();
    let o = camplace(dir.path(), &["placement", "--rig", "r/rig.json", "--study", &study_dir]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout);
    let line =
        |start: &str| text.lines().find(|l| l.starts_with(start)).unwrap().split_once(": ").unwrap().1.to_string();
    assert_eq!(line("as built"), line("planned"), "{text}");
    assert!(stderr(&o).contains("no tolerances"), "a quick study measures none: {}", stderr(&o));
}

#[test]
fn a_command_of_one_tray_asks_which_of_a_listed_cell() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_cell(d);
    let o = camplace(d, &["render", "--cell", "cell.toml", "--out", "r"]);
    assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["cell.toml", "trays", "--tray", "six-slot"]);
    let o = camplace(d, &["render", "--cell", "cell.toml", "--tray", "hex", "--out", "r"]);
    assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &["--tray hex", "four-slot"]);
    for tray in ["four-slot", "six-slot"] {
        let o = camplace(d, &["render", "--cell", "cell.toml", "--tray", tray, "--scenario", "3", "--out", tray]);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let filled = |tray: &str| -> Vec<u64> {
        json(&d.join(tray).join("truth.json"))["filled"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_u64().unwrap())
            .collect()
    };
    assert!(filled("four-slot").iter().all(|&i| i < 4), "{:?}", filled("four-slot"));
    let image = |tray: &str| std::fs::read(d.join(tray).join("left.png")).unwrap();
    assert_ne!(image("four-slot"), image("six-slot"), "each tray is its own scene");
}

#[test]
fn tolerances_of_a_listed_cell_judge_each_offset_by_the_lower_tray() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_cell(d);
    let o = camplace(
        d,
        &[
            "tolerance",
            "--cell",
            "cell.toml",
            "--placement",
            "r=450,alpha=50",
            "--scenarios",
            "3",
            "--parameters",
            "r",
            "--out",
            "t",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let report = json(&d.join("t/tolerance.json"));
    // Each tray's outcomes: placement -> scenario -> success.
    let results = |tray: &str| -> HashMap<String, HashMap<u64, bool>> {
        let mut ok: HashMap<String, HashMap<u64, bool>> = HashMap::new();
        for line in std::fs::read_to_string(d.join("t").join(tray).join("results.jsonl")).unwrap().lines() {
            let v: Value = serde_json::from_str(line).unwrap();
            ok.entry(v["placement"].as_str().unwrap().to_string())
                .or_default()
                .insert(v["scenario"].as_u64().unwrap(), v["success"] == true);
        }
        ok
    };
    let (six, four) = (results("six-slot"), results("four-slot"));
    // A point's rate is its lower tray's over the scenes that settled it (the first
    // `scenes` scenarios): the lower of the trays run there (a tray that shows a drop ends
    // the point before the next is run), or 0 where the estimator could not run at all.
    let check = |p: &str, point: &Value| {
        let scenes = point["scenes"].as_u64().unwrap();
        let rate = point["success_rate"].as_f64().unwrap();
        let rates: Vec<f64> = [&six, &four]
            .iter()
            .filter_map(|t| t.get(p))
            .filter(|o| (0..scenes).all(|i| o.contains_key(&i)))
            .map(|o| (0..scenes).filter(|i| o[i]).count() as f64 / scenes as f64)
            .collect();
        let lower = rates.iter().copied().fold(f64::INFINITY, f64::min);
        let want = if rates.is_empty() { 0.0 } else { lower };
        assert!(scenes > 0 && (rate - want).abs() < 1e-12, "{p}: {point} against the trays' {rates:?}");
    };
    for corner in report["corners"].as_array().unwrap() {
        check(corner["placement"].as_str().unwrap(), &corner["point"]);
    }
    check(report["placement"].as_str().unwrap(), &report["nominal"]);
}

/// The page's value in the keyed row `key`.
fn keyed(dom: &str, key: &str) -> String {
    let at = dom.find(&format!("data-key=\"{key}\"")).unwrap_or_else(|| panic!("no row {key}"));
    let row = &dom[at..];
    let td = row.find("<td>").unwrap() + 4;
    row[td..td + row[td..].find("</td>").unwrap()].to_string()
}

#[test]
fn the_report_opens_in_a_browser_with_every_image_and_the_summary_numbers() {
    let Some(browser) = crate::browser::chromium("the report's browser test") else {
        return;
    };
    let out = study();
    let dir = tempfile::tempdir().unwrap();
    // The report with a script that marks, once loaded, how many images failed to load.
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    let probe = "<script>window.addEventListener('load',()=>{const im=[...document.images];\
        const svg=[...document.querySelectorAll('svg')];\
        document.body.dataset.images=im.length;\
        document.body.dataset.broken=im.filter(i=>!(i.complete&&i.naturalWidth>0)).length;\
        document.body.dataset.svgs=svg.length;\
        document.body.dataset.emptySvgs=svg.filter(s=>!(s.getBBox().width>0&&s.getBBox().height>0)).length;});</script>";
    let page = dir.path().join("report.html");
    std::fs::write(&page, html.replace("</body>", &format!("{probe}</body>"))).unwrap();
    let url = format!("file://{}", page.display());
    let run = |extra: &[&str]| {
        let mut args =
            vec!["--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars", "--window-size=1280,800"];
        args.extend(extra);
        args.push(&url);
        Command::new(browser).args(&args).current_dir(dir.path()).output().expect("chromium runs")
    };
    let o = run(&["--virtual-time-budget=10000", "--dump-dom"]);
    let dom = String::from_utf8_lossy(&o.stdout).into_owned();
    let attr = |name: &str| -> u64 {
        let at = dom.find(&format!("{name}=\"")).unwrap_or_else(|| panic!("no {name} on the page: {}", stderr(&o)));
        let v = &dom[at + name.len() + 2..];
        v[..v.find('"').unwrap()].parse().unwrap()
    };
    assert!(attr("data-images") >= 1, "the rendered scene is an image");
    assert_eq!(attr("data-broken"), 0, "every image loads");
    assert!(attr("data-svgs") >= 5, "the sketch and the maps are drawn");
    assert_eq!(attr("data-empty-svgs"), 0, "every figure has a size");
    let rec = json(&out.join("recommended.json"));
    let pct = |v: &Value| format!("{:.1}", 100.0 * v.as_f64().unwrap());
    let success = keyed(&dom, "success_rate");
    assert!(
        success.starts_with(&format!("{} %", pct(&rec["success_rate"])))
            && success.contains(&format!("({} of {})", rec["successes"], rec["scenes"])),
        "{success} against {rec}"
    );
    let i = &rec["success_interval"];
    assert_eq!(keyed(&dom, "success_interval"), format!("{}–{} %", pct(&i[0]), pct(&i[1])));
    assert_eq!(keyed(&dom, "r"), format!("{:.1} mm", rec["r"].as_f64().unwrap()));
    assert_eq!(keyed(&dom, "method"), rec["method"].as_str().unwrap());
    let left = &rec["world_mm"]["left_camera"];
    // To a tenth of a mm, a zero without its sign, as the page writes it.
    let tenth = |x: f64| {
        let r = (x * 10.0).round() / 10.0;
        if r == 0.0 {
            0.0
        } else {
            r
        }
    };
    let xyz = |v: &Value| {
        let c = |i: usize| tenth(v[i].as_f64().unwrap());
        format!("({:.1}, {:.1}, {:.1})", c(0), c(1), c(2))
    };
    assert_eq!(keyed(&dom, "left_camera"), xyz(left));
    for t in rec["trays"].as_array().unwrap() {
        let row = keyed(&dom, &format!("tray:{}", t["name"].as_str().unwrap()));
        assert!(row.starts_with(&format!("{} %", pct(&t["success_rate"]))), "{row} against {t}");
    }
    // The verified figures of the recommended method, as recommended.json carries them, and
    // each method's precision-recall curve.
    let v = &rec["verification"];
    let m = rec["method"].as_str().unwrap();
    let row = keyed(&dom, &format!("{m}:verified_success_rate"));
    assert!(
        row.starts_with(&format!("{} %", pct(&v["verified_success_rate"])))
            && row.contains(&format!("({} of {})", v["verified_successes"], v["scored"])),
        "{row} against {v}"
    );
    let row = keyed(&dom, &format!("{m}:wrong_accepted_share"));
    assert!(
        row.starts_with(&format!("{} %", pct(&v["wrong_accepted_share"])))
            && row.contains(&format!("({} of {})", v["wrong_accepted"], v["accepted"])),
        "{row} against {v}"
    );
    assert_eq!(keyed(&dom, &format!("{m}:wrong_accepted_upper")), format!("{} %", pct(&v["wrong_accepted_upper"])));
    let row = keyed(&dom, &format!("{m}:threshold"));
    match v.get("near_misses_untold") {
        Some(e) => {
            let refused = format!(
                "every pose refused: at {:.3} {} of the {}",
                e["threshold"].as_f64().unwrap(),
                e["wrong"],
                e["accepted"]
            );
            assert!(row.starts_with(&refused), "{row} against {v}");
        }
        None => assert_eq!(row, format!("{:.3}", v["threshold"].as_f64().unwrap())),
    }
    assert!(dom.contains("precision against recall"), "no precision-recall curve on the page");
    // Every map's legend states its scale: success on the fixed 0–100 % scale on every map,
    // the correct matches over their own range, which is the tray's summary.csv's.
    let svgs: Vec<&str> = dom.split("<svg").skip(1).map(|s| &s[..s.find("</svg>").unwrap_or(s.len())]).collect();
    let success_maps: Vec<&&str> = svgs.iter().filter(|s| s.contains("success rate, %")).collect();
    assert_eq!(success_maps.len(), 2, "one success map per tray");
    for m in &success_maps {
        assert!(m.contains("fixed 0–100"), "a success map's legend: fixed 0–100");
    }
    let mut legends: Vec<String> = svgs
        .iter()
        .filter(|s| s.contains("mean correct matches"))
        .map(|s| {
            let at = s.find("range ").or_else(|| s.find("uniform: ")).expect("the legend states the range");
            s[at..at + s[at..].find('<').unwrap()].trim().to_string()
        })
        .collect();
    let mut expected: Vec<String> = ["six-slot", "four-slot"]
        .iter()
        .map(|tray| {
            let csv = std::fs::read_to_string(out.join(tray).join("one-shot/summary.csv")).unwrap();
            let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
            let column = header.iter().position(|h| *h == "mean_correct_matches").unwrap();
            // The placement is quoted and holds commas: count columns from the end.
            let values: Vec<f64> = csv
                .lines()
                .skip(1)
                .filter_map(|l| l.rsplit(',').nth(header.len() - 1 - column).and_then(|v| v.parse().ok()))
                .collect();
            let lo = values.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            if lo == hi {
                format!("uniform: {lo:.0}")
            } else {
                format!("range {lo:.0}–{hi:.0}")
            }
        })
        .collect();
    legends.sort();
    expected.sort();
    assert_eq!(legends, expected, "the correct matches' legends state each tray's range");
    // And the first screen as a person sees it.
    let shot = dir.path().join("first_screen.png");
    let o = run(&[&format!("--screenshot={}", shot.display())]);
    let size = std::fs::metadata(&shot).map(|m| m.len()).unwrap_or(0);
    assert!(size > 10_000, "a screenshot of the first screen: {} bytes, {}", size, stderr(&o));
}

/// scripts/example_tray.py writes a tray of one's own that camplace takes as it is: rendered,
/// the tray and every filled slot's item are in the left image where the truth says.
#[test]
fn the_example_tray_script_writes_a_cell_camplace_renders() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let o = Command::new("python3")
        .arg(concat!(env!("CARGO_MANIFEST_DIR"), "/scripts/example_tray.py"))
        .arg(d.join("own"))
        .output()
        .expect("python3 runs");
    assert!(o.status.success(), "{}", stderr(&o));
    let o = camplace(d, &["render", "--dataset", "--count", "2", "--cell", "own/cell.toml", "--out", "data"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let mut items_seen = 0;
    for frame in ["0000", "0001"] {
        let f = d.join("data/frames").join(frame);
        let truth: Value = serde_json::from_slice(&std::fs::read(f.join("truth.json")).unwrap()).unwrap();
        let ids = camplace_config::read_gray(&f.join("ids_left.png")).unwrap();
        let count = |id: u8| ids.data.iter().filter(|&&v| v == id).count();
        assert!(count(1) > 1000, "frame {frame}: the tray covers {} pixels", count(1));
        for n in truth["filled"].as_array().unwrap() {
            let n = n.as_u64().unwrap();
            assert!(n < 6, "frame {frame}: slot {n} of a six-slot tray");
            items_seen += usize::from(count(2 + n as u8) > 50);
        }
    }
    assert!(items_seen > 0, "no item of the script's tray was seen");
}
