//! `camplace tolerance` end to end on small cells: every number in tolerance.json is the
//! success of the scenes its placement left in results.jsonl, every point's verdict is the
//! one-sided paired test against the nominal worked out here from those scenes, each edge
//! lies between a point inside and one outside a resolution further (or at the range's
//! end), the corners are the box's, a second run resumes without a scene; and on a cell
//! whose edge lies inside the walked range the walk finds the edge a walk in single
//! resolution steps finds; a study's tolerances are the command's for the placement it
//! recommends.

use std::collections::BTreeMap;
use std::path::Path;

use camplace_config::{PlacementParam, ToleranceReport, WalkEnd};
use camplace_sim::{run_study, tolerance_dir, Method, Preset, Shard, StudyRequest};

use crate::camplace_cmd::{assert_one_line_error, camplace, stderr};

/// Near the small cell's edge of working, so offsets matter.
const PLACEMENT: &str = "r=400,alpha=10,baseline=100,vergence=5";

fn small_cell() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/small_cell.toml").display().to_string()
}

/// Outcomes by scenario per placement, from results.jsonl.
fn outcomes(path: &Path) -> BTreeMap<String, BTreeMap<u64, bool>> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut out: BTreeMap<String, BTreeMap<u64, bool>> = BTreeMap::new();
    for line in text.lines() {
        let v: serde_json::Value = serde_json::from_str(line).unwrap();
        let at = out.entry(v["placement"].as_str().unwrap().to_string()).or_default();
        at.insert(v["scenario"].as_u64().unwrap(), v["success"].as_bool().unwrap());
    }
    out
}

/// The one-sided exact McNemar p-value, the slow obvious way: the chance that a fair coin
/// over `lost + gained` scenes gives at most `gained` to the offset.
fn p_lower(lost: usize, gained: usize) -> f64 {
    let m = lost + gained;
    let choose = |k: usize| (0..k).fold(1.0, |c: f64, i| c * (m - i) as f64 / (i + 1) as f64);
    (0..=gained).map(choose).sum::<f64>() / 2f64.powi(m as i32)
}

/// (lost, gained, p) of `at` against `nominal`, scene by scene.
fn paired(nominal: &BTreeMap<u64, bool>, at: &BTreeMap<u64, bool>) -> (usize, usize, f64) {
    let lost = nominal.iter().filter(|(i, &s)| s && !at[i]).count();
    let gained = nominal.iter().filter(|(i, &s)| !s && at[i]).count();
    (lost, gained, p_lower(lost, gained))
}

/// `placement` with `parameter` moved by `offset` from `nominal_value`, as camplace writes it.
fn moved(placement: &str, parameter: &str, nominal_value: f64, offset: f64) -> String {
    let value = ((nominal_value + offset) * 1e6).round() / 1e6;
    placement.replace(&format!("{parameter}={nominal_value}"), &format!("{parameter}={value}"))
}

#[test]
fn tolerances_are_paired_tests_walked_out_and_resume_without_a_scene() {
    let dir = tempfile::tempdir().unwrap();
    let cell = small_cell();
    let args = [
        "tolerance",
        "--cell",
        &cell,
        "--placement",
        PLACEMENT,
        "--parameters",
        "alpha,vergence",
        "--scenarios",
        "6",
        "--out",
        "tol",
    ];
    let o = camplace(dir.path(), &args);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout).into_owned();
    let json = std::fs::read_to_string(dir.path().join("tol/tolerance.json")).unwrap();
    let report: ToleranceReport = serde_json::from_str(&json).unwrap();
    let scenes = outcomes(&dir.path().join("tol/results.jsonl"));
    let at = |placement: &str| {
        let s = scenes.get(placement).unwrap_or_else(|| panic!("no results at {placement}"));
        assert_eq!(s.len(), 6, "{placement}");
        s
    };
    let rate = |s: &BTreeMap<u64, bool>| s.values().filter(|&&v| v).count() as f64 / s.len() as f64;

    assert_eq!(report.placement, PLACEMENT);
    let nominal = at(PLACEMENT);
    assert_eq!(report.nominal.success_rate, rate(nominal));
    assert_eq!((report.scenarios, report.level), (6, 0.05));
    assert_eq!(report.axes.iter().map(|a| a.parameter.as_str()).collect::<Vec<_>>(), ["alpha", "vergence"]);
    for axis in &report.axes {
        // The walk's limits: ±30° alpha, ±6° vergence.
        let (nominal_value, resolution, limit) =
            if axis.parameter == "alpha" { (10.0, 1.0, 30.0) } else { (5.0, 0.25, 6.0) };
        assert_eq!((axis.resolution, axis.limit), (resolution, limit));
        let placement_at = |offset: f64| moved(PLACEMENT, &axis.parameter, nominal_value, offset);
        // Every point: its rate and its paired test against the nominal, from the scenes.
        for p in axis.points.iter().filter(|p| p.offset != 0.0) {
            let s = at(&placement_at(p.offset));
            let (lost, gained, p_value) = paired(nominal, s);
            assert_eq!(p.success_rate, rate(s), "{} {}", axis.parameter, p.offset);
            assert_eq!((p.lost, p.gained), (lost, gained), "{} {}", axis.parameter, p.offset);
            assert!((p.p_lower - p_value).abs() < 1e-12, "{} {}: {} vs {p_value}", axis.parameter, p.offset, p.p_lower);
            // Offsets are whole resolutions.
            assert!((p.offset / resolution - (p.offset / resolution).round()).abs() < 1e-9);
        }
        for side in axis.sides() {
            let inside = side.inside;
            assert_eq!(inside.offset, side.sign * side.tolerance);
            assert!(inside.p_lower >= 0.05, "{}: the point inside is not shown lower", axis.parameter);
            match (side.end, side.outside) {
                (WalkEnd::Drop, Some(out)) => {
                    assert!(out.p_lower < 0.05, "{}: the point outside is shown lower", axis.parameter);
                    assert!((out.offset - inside.offset - side.sign * resolution).abs() < 1e-9, "one resolution apart");
                }
                (WalkEnd::RangeEnd, None) => {
                    assert_eq!(inside.offset, side.range, "{}: the range ended the walk", axis.parameter);
                    if side.at_walk_limit() {
                        assert_eq!(side.range.abs(), limit, "{}: the walk's limit", axis.parameter);
                    } else {
                        assert!(side.range.abs() < limit, "{}: the placement's range ends first", axis.parameter);
                        let past =
                            moved(PLACEMENT, &axis.parameter, nominal_value, side.range + side.sign * resolution);
                        let o =
                            camplace(dir.path(), &["evaluate", "--cell", &cell, "--placement", &past, "--out", "x"]);
                        assert_eq!(o.status.code(), Some(2), "{past} is no placement: {}", stderr(&o));
                    }
                }
                other => panic!("{}: {other:?}", axis.parameter),
            }
        }
    }
    // The box's corners: every combination of each side's tolerance, each counted.
    let (alpha, vergence) = (&report.axes[0], &report.axes[1]);
    let mut expected: Vec<[f64; 5]> = Vec::new();
    for v in [-vergence.minus, vergence.plus] {
        for a in [-alpha.minus, alpha.plus] {
            let offsets = [0.0, a, 0.0, v, 0.0];
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
        let s = at(&c.placement);
        assert_eq!(c.point.success_rate, rate(s), "{}", c.placement);
        assert_eq!((c.point.lost, c.point.gained), (paired(nominal, s).0, paired(nominal, s).1), "{}", c.placement);
    }
    assert!(out.contains(&format!("tolerance of {PLACEMENT}")), "{out}");
    assert!(out.contains("one-sided exact McNemar"), "{out}");
    // With a font (CI installs one) the plots are drawn; without, the run says it skipped them.
    let font = camplace_plot::ensure_plot_font().is_ok();
    for name in ["alpha", "vergence"] {
        let drawn = dir.path().join(format!("tol/tolerance_{name}.svg")).is_file();
        assert_eq!(drawn, font, "tolerance_{name}.svg: {}", stderr(&o));
        assert_eq!(stderr(&o).contains("plots skipped"), !font, "{}", stderr(&o));
    }

    // Resumed: no scene is run again and the report is the same.
    let lines = std::fs::read_to_string(dir.path().join("tol/results.jsonl")).unwrap().lines().count();
    let o = camplace(dir.path(), &args);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(std::fs::read_to_string(dir.path().join("tol/results.jsonl")).unwrap().lines().count(), lines);
    assert_eq!(std::fs::read_to_string(dir.path().join("tol/tolerance.json")).unwrap(), json);
}

/// The small cell with a narrow camera: moving the rig closer soon loses the tray from view.
/// Its poses are handed on as fitted: laid on the table, the poses of the rigs just past the
/// edge come out right more often, and on 6 scenes success there rises and falls again
/// (33 % at −355 mm, 17 % at −360, the single steps' drop at −310), so the edge is no
/// longer one place that both walks must find. The same held of 6 scenes once the turn
/// check weighed the half turn moved a slot's pitch (a pose it now corrects at −320 mm
/// left 4 of 6 lost there, 5 at −325 and 2 at −360); on 8 scenes both walks find −305 mm.
/// It keeps the model of 6 viewpoints and the untrimmed ICP: with the default 12 and a
/// trimmed ICP fewer of the 8 scenes are lost past the edge (4 at −400 mm, p = 0.06), so
/// the walk finds no drop inside its ±400 mm to compare. Since the turn check counts only
/// the parts in sight at each pose, the 8 scenes' success dips at −265 mm and recovers
/// until −300 mm, where the walk finds its edge, having stepped over the dip: the test
/// holds the two walks to the same edge only on a profile that falls off monotonically.
const NARROW_CELL: &str = "[sensor]\ncamera_resolution = [320, 240]\ncamera_hfov = 24.0\n\n\
                           [estimator]\nransac_iterations = 2000\npose_on_table = false\n\
                           model_viewpoints = 6\nicp_trim = 0.0\n";

#[test]
fn an_edge_inside_the_range_is_found_as_a_walk_in_single_steps_finds_it() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("narrow.toml"), NARROW_CELL).unwrap();
    let placement = "r=800,alpha=20,baseline=120,vergence=4.3";
    let o = camplace(
        d,
        &[
            "tolerance",
            "--cell",
            "narrow.toml",
            "--placement",
            placement,
            "--parameters",
            "r",
            "--scenarios",
            "8",
            "--out",
            "tol",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let report: ToleranceReport =
        serde_json::from_str(&std::fs::read_to_string(d.join("tol/tolerance.json")).unwrap()).unwrap();
    let r = &report.axes[0];
    assert_eq!(r.minus_end, WalkEnd::Drop, "the edge lies inside the range: {}", report.table());
    // The oracle: every 5 mm from the nominal inwards, each evaluated on the same scenes
    // (into the same folder: scenes already there are not run again), out to one step past
    // the walk's edge; a step is inside while the paired test shows no drop.
    let nominal = outcomes(&d.join("tol/results.jsonl"))[placement].clone();
    let steps = (r.minus / 5.0).round() as u64 + 1;
    let mut profile = Vec::new();
    for k in 1..=steps.min(r.minus_range.abs() as u64 / 5) {
        let p = moved(placement, "r", 800.0, -5.0 * k as f64);
        let o = camplace(
            d,
            &[
                "evaluate",
                "--cell",
                "narrow.toml",
                "--placement",
                &p,
                "--scenarios",
                "8",
                "--seed",
                "1",
                "--out",
                "tol",
            ],
        );
        assert!(o.status.success(), "{}", stderr(&o));
        let (_, _, p_value) = paired(&nominal, &outcomes(&d.join("tol/results.jsonl"))[&p]);
        profile.push(p_value >= 0.05);
    }
    let first_drop = profile.iter().position(|inside| !inside).expect("the single-step walk finds a drop");
    let fine_edge = 5.0 * first_drop as f64;
    let shown = |profile: &[bool]| profile.iter().map(|&i| if i { 'i' } else { 'o' }).collect::<String>();
    // A walk in growing steps never stops before the first drop a walk in single steps meets.
    assert!(
        fine_edge <= r.minus + r.resolution,
        "walk {} mm, single steps {fine_edge} mm: {}",
        r.minus,
        report.table()
    );
    // Where success falls off monotonically (no step inside past the first drop, up to the
    // walk's edge) both find the same edge; where it dips and recovers, the walk may step
    // over the dip, and then the edge it reports is still an edge of the profile.
    if profile[first_drop..].iter().all(|inside| !inside) {
        assert!(
            (r.minus - fine_edge).abs() <= r.resolution,
            "walk {} mm, single steps {fine_edge} mm: {}",
            r.minus,
            report.table()
        );
    } else {
        let at = |mm: f64| profile[(mm / 5.0).round() as usize - 1];
        assert!(at(r.minus) && !at(r.minus + 5.0), "walk {} mm, profile {}", r.minus, shown(&profile));
        eprintln!("the profile dips and recovers: {} (i inside, o outside, 5 mm a step)", shown(&profile));
    }
    assert!(fine_edge > 0.0 && fine_edge < 795.0, "an edge inside the range: {fine_edge}");
}

#[test]
fn bad_tolerance_flags_are_one_line_errors() {
    let dir = tempfile::tempdir().unwrap();
    for (flag, value, must) in [
        ("--margin", "0", "between 0 and 1"),
        ("--margin", "1.5", "between 0 and 1"),
        ("--corner-fraction", "0", "above 0 and at most 1"),
        ("--corner-fraction", "1.5", "above 0 and at most 1"),
        ("--scenarios", "0", "1 to"),
        ("--parameters", "r,height", "unknown parameter \"height\""),
        ("--parameters", ",", "at least one"),
    ] {
        let o = camplace(dir.path(), &["tolerance", flag, value, "--out", "t"]);
        assert_one_line_error(o.status.code().unwrap(), &stderr(&o), &[flag, must]);
    }
}

#[test]
fn a_studys_tolerances_are_the_tolerance_command_s_for_its_placement() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cell = camplace_config::Cell::load(Path::new(&small_cell())).unwrap();
    // The study at its smallest: one grid cell, no search, alpha's tolerance on 4 scenes.
    let preset = Preset {
        name: "full",
        x: "r=500:500:1".parse().unwrap(),
        y: "alpha=20:20:1".parse().unwrap(),
        sweep_scenarios: 2,
        budget: 0,
        search_scenarios: 2,
        top: 1,
        recheck_scenarios: 2,
        tolerance_scenarios: 4,
        tolerance_margin: 0.15,
        tolerance_corner_fraction: 1.0,
        tolerance_parameters: vec![PlacementParam::Alpha],
    };
    let study = d.join("study");
    let request = StudyRequest {
        out: &study,
        cell: &cell,
        seed: 3,
        preset: &preset,
        paper: false,
        methods: vec![Method::OneShot],
        shard: Shard::WHOLE,
    };
    let outcome = run_study(&request, |_| {}).unwrap().expect("the whole study ran");
    let placement = outcome.recommendation.as_ref().expect("a recommendation").placement.to_string();
    let placement = placement.as_str();
    let o = camplace(
        d,
        &[
            "tolerance",
            "--cell",
            &small_cell(),
            "--placement",
            placement,
            "--method",
            "one-shot",
            "--seed",
            "3",
            "--scenarios",
            "4",
            "--parameters",
            "alpha",
            "--out",
            "alone",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let from_study = std::fs::read_to_string(tolerance_dir(&study, Method::OneShot).join("tolerance.json")).unwrap();
    let alone = std::fs::read_to_string(d.join("alone/tolerance.json")).unwrap();
    let report: ToleranceReport = serde_json::from_str(&alone).unwrap();
    assert_eq!(report.axes.len(), 1);
    assert!(report.axes[0].points.len() >= 3, "alpha walked: {}", report.table());
    assert_eq!(from_study, alone, "the same placement, seed and scenes give the same tolerance.json");
}
