//! The trial's report (the paper's Section 7 and Figure 8): per placement the real success
//! (frames judged by truth or by the reviewer) with its Wilson interval beside the simulated
//! one at the same placement, the two success maps side by side, Spearman's ρ over the
//! placements, whether the simulation's best placement is in the real top set, and the
//! paired difference between the simulation's best and the real best on the same tray
//! set-downs; `trial_report.json` and `trial_report.html`.
//!
//! Definitions: the real top set holds every placement whose real 95 % interval reaches the
//! real best's lower end (the placements the trial cannot tell apart from the best). The
//! simulation's best is the plan placement of highest simulated success (first on ties),
//! the study's recommendation when that is one of the plan's.

use std::path::{Path, PathBuf};

use camplace_config::{write_atomic, Cell, Placement};
use serde::Serialize;

use super::judge::JudgedDataset;
use super::layout::check_placement_rig;
use super::rank::{spearman, RankCorrelation};
use crate::report::heatmap::{ColourScale, HeatMap};
use crate::report::html::HtmlPage;
use crate::report::recommended::Recommended;
use crate::report::table::SummaryRow;
use crate::study::findings::{Paired, Rate};
use crate::study::sweep::load_sweep;
use crate::{Error, Result};
use camplace_config::Grid;
use camplace_config::{parse_placement, placement_dir, TrialPlan, PLAN_FILE};
use camplace_plot::save_plot;

/// The report's JSON file.
pub const REPORT_JSON: &str = "trial_report.json";
/// The report's page.
pub const REPORT_HTML: &str = "trial_report.html";

/// A success count with its rate and 95 % Wilson interval.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RateFigures {
    /// Successes.
    pub successes: usize,
    /// Frames (or scenes) counted.
    pub frames: usize,
    /// successes / frames.
    pub success_rate: f64,
    /// Wilson 95 % interval.
    pub success_interval: [f64; 2],
}

impl RateFigures {
    fn of(successes: usize, frames: usize) -> RateFigures {
        let r = Rate { successes, scenes: frames };
        RateFigures { successes, frames, success_rate: r.value(), success_interval: r.interval() }
    }

    fn text(&self) -> String {
        Rate { successes: self.successes, scenes: self.frames }.text()
    }
}

/// One placement's row.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PlacementRow {
    /// Its number in the plan (its folder `NNN/`).
    pub index: usize,
    /// The placement as written.
    pub placement: String,
    /// Frames in its dataset (0: not captured yet).
    pub frames: usize,
    /// Frames judged by their truth, marked correct or wrong, marked unsure, not judged.
    pub judged_by_truth: usize,
    pub marked: usize,
    pub unsure: usize,
    pub not_judged: usize,
    /// Of the frames not judged, those whose marks judged earlier poses (the placement was
    /// estimated again since): their marks stay in labels.jsonl but are not counted.
    pub marked_on_earlier_poses: usize,
    /// Success over the frames judged (truth or a correct / wrong mark).
    pub real: Option<RateFigures>,
    /// The study's success at the same placement.
    pub simulated: Option<RateFigures>,
    /// In the real top set.
    pub in_real_top_set: bool,
}

/// The paired comparison of two placements over the tray set-downs judged at both.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PairedDifference {
    /// Side a: the simulation's best placement.
    pub a: String,
    /// Side b: the real best placement.
    pub b: String,
    /// Set-downs judged at both.
    pub frames: usize,
    /// Real success of a and of b over them.
    pub a_rate: f64,
    pub b_rate: f64,
    /// rate(a) − rate(b) and its 95 % interval (Newcombe's paired method).
    pub difference: f64,
    pub difference_interval: [f64; 2],
    /// Two-sided exact McNemar p.
    pub mcnemar_p: f64,
}

/// The whole report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TrialReport {
    /// The trial folder.
    pub trial: String,
    /// The study folder the simulated side comes from.
    pub study: Option<String>,
    /// The study's method.
    pub method: Option<String>,
    /// One row per plan placement.
    pub placements: Vec<PlacementRow>,
    /// Spearman's ρ between real and simulated success over placements that have both.
    pub rank_correlation: Option<RankCorrelation>,
    /// The real best placement's index (highest real success, first on ties).
    pub real_best: Option<usize>,
    /// The simulation's best placement's index.
    pub simulated_best: Option<usize>,
    /// The study's recommended placement, when the study has one.
    pub recommended: Option<String>,
    /// Whether the simulation's best placement is within the real top set.
    pub simulated_best_in_real_top_set: Option<bool>,
    /// The simulation's best against the real best on the same set-downs.
    pub paired_difference: Option<PairedDifference>,
}

/// The study's side: its method, one row per placement, its recommended placement.
struct Simulated {
    dir: PathBuf,
    method: String,
    rows: Vec<SummaryRow>,
    recommended: Option<String>,
}

/// The sweep folder of `dir` — `dir` itself when it holds a `sweep.json`, else the sweep of
/// a study folder's recommended method and (first) tray, named by its `recommended.json` —
/// and the study's recommended placement.
pub fn sweep_folder(dir: &Path) -> Result<(PathBuf, Option<String>)> {
    if dir.join("sweep.json").is_file() {
        return Ok((dir.to_path_buf(), None));
    }
    let path = dir.join("recommended.json");
    if !path.is_file() {
        return Err(Error::Other(format!(
            "--study {}: expected a study folder (recommended.json) or a sweep folder (sweep.json)",
            dir.display()
        )));
    }
    let rec = Recommended::load(dir)?;
    let tray = rec
        .trays
        .first()
        .ok_or_else(|| Error::Other(format!("{}: trays: expected at least one tray", path.display())))?;
    Ok((dir.join(&tray.name).join(rec.method.to_string()), Some(rec.placement.to_string())))
}

/// The grid, scenes per placement and base placement of the sweep of `dir` (see
/// [`sweep_folder`]).
pub fn study_grid(dir: &Path) -> Result<(Grid, u64, Placement)> {
    let (sweep_dir, _) = sweep_folder(dir)?;
    load_sweep(&sweep_dir)?.ok_or_else(|| {
        Error::Other(format!("{}: missing: expected the study's sweep", sweep_dir.join("sweep.json").display()))
    })
}

/// Reads the simulated side of study (or sweep) folder `dir`.
fn read_study(dir: &Path) -> Result<Simulated> {
    let (sweep_dir, recommended) = sweep_folder(dir)?;
    study_grid(dir)?;
    let path = sweep_dir.join("summary.json");
    let rows: Vec<SummaryRow> = serde_json::from_str(&camplace_config::read_text(&path)?)
        .map_err(|e| Error::Other(format!("{}: expected a sweep's summary rows: {e}", path.display())))?;
    let method = rows.first().map(|r| r.method.clone()).unwrap_or_default();
    Ok(Simulated { dir: dir.to_path_buf(), method, rows, recommended })
}

fn same_placement(a: &Placement, b: &Placement) -> bool {
    let close = |x: f64, y: f64| (x - y).abs() <= 1e-6 * (1.0 + x.abs().max(y.abs()));
    close(a.r, b.r)
        && close(a.alpha, b.alpha)
        && close(a.baseline, b.baseline)
        && close(a.azimuth, b.azimuth)
        && a.vergence.to_string() == b.vergence.to_string()
}

/// Builds the report of trial `dir` (its rigs checked against `cell`), with the simulated
/// side from `study` when given, and writes it into `out`.
pub fn trial_report(dir: &Path, cell: &Cell, study: Option<&Path>, out: &Path) -> Result<TrialReport> {
    let plan = TrialPlan::load(&dir.join(PLAN_FILE))?;
    let sim = study.map(read_study).transpose()?;
    let mut rows = Vec::with_capacity(plan.placements.len());
    let mut outcomes = Vec::with_capacity(plan.placements.len());
    for (i, entry) in plan.placements.iter().enumerate() {
        let p = plan.placement(i);
        let folder = placement_dir(dir, i);
        let simulated = sim.as_ref().and_then(|s| {
            s.rows
                .iter()
                .find(|r| parse_placement(&r.placement).is_ok_and(|q| same_placement(&p, &q)))
                .map(|r| RateFigures::of(r.summary.successes, r.summary.scored))
        });
        let mut row = PlacementRow {
            index: i,
            placement: entry.placement.clone(),
            frames: 0,
            judged_by_truth: 0,
            marked: 0,
            unsure: 0,
            not_judged: 0,
            marked_on_earlier_poses: 0,
            real: None,
            simulated,
            in_real_top_set: false,
        };
        if !folder.exists() {
            rows.push(row);
            outcomes.push(Vec::new());
            continue;
        }
        check_placement_rig(&folder, cell, &p)?;
        let judged = JudgedDataset::read(&folder)?;
        let o = judged.outcomes();
        let [truth, marked, unsure, open] = judged.counts();
        let successes = o.iter().filter(|x| **x == Some(true)).count();
        let counted = o.iter().filter(|x| x.is_some()).count();
        row.frames = o.len();
        row.judged_by_truth = truth;
        row.marked = marked;
        row.unsure = unsure;
        row.not_judged = open;
        row.marked_on_earlier_poses = judged.marked_on_earlier_poses.len();
        row.real = (counted > 0).then(|| RateFigures::of(successes, counted));
        rows.push(row);
        outcomes.push(judged.frames.iter().map(|(n, _, j)| (n.clone(), j.outcome())).collect::<Vec<_>>());
    }
    let best_of = |pick: &dyn Fn(&PlacementRow) -> Option<f64>| {
        let mut best: Option<usize> = None;
        for (i, r) in rows.iter().enumerate() {
            if let Some(v) = pick(r) {
                if best.is_none_or(|b| v > pick(&rows[b]).unwrap_or(f64::NEG_INFINITY)) {
                    best = Some(i);
                }
            }
        }
        best
    };
    let real_best = best_of(&|r| r.real.map(|x| x.success_rate));
    let recommended_index = sim.as_ref().and_then(|s| s.recommended.as_deref()).and_then(|text| {
        let q = parse_placement(text).ok()?;
        (0..rows.len()).find(|&i| same_placement(&plan.placement(i), &q))
    });
    let simulated_best = recommended_index.or_else(|| best_of(&|r| r.simulated.map(|x| x.success_rate)));
    if let Some(b) = real_best {
        let floor = rows[b].real.expect("the best has a rate").success_interval[0];
        for r in &mut rows {
            r.in_real_top_set = r.real.is_some_and(|x| x.success_interval[1] >= floor);
        }
    }
    let both: Vec<(f64, f64)> =
        rows.iter().filter_map(|r| Some((r.real?.success_rate, r.simulated?.success_rate))).collect();
    let rank_correlation =
        spearman(&both.iter().map(|x| x.0).collect::<Vec<_>>(), &both.iter().map(|x| x.1).collect::<Vec<_>>());
    let simulated_best_in_real_top_set = simulated_best.and_then(|s| real_best.map(|_| rows[s].in_real_top_set));
    let paired_difference = match (simulated_best, real_best) {
        (Some(a), Some(b)) => {
            // Frame k is the same set-down at every placement: pair by frame name.
            let (mut xa, mut xb) = (Vec::new(), Vec::new());
            for (name, o) in &outcomes[a] {
                if let Some((_, ob)) = outcomes[b].iter().find(|(n, _)| n == name) {
                    xa.push(*o);
                    xb.push(*ob);
                }
            }
            let p = Paired::from_outcomes(&xa, &xb);
            Some(PairedDifference {
                a: rows[a].placement.clone(),
                b: rows[b].placement.clone(),
                frames: p.scenes(),
                a_rate: p.a().value(),
                b_rate: p.b().value(),
                difference: p.a().value() - p.b().value(),
                difference_interval: p.difference_interval(),
                mcnemar_p: p.mcnemar_p(),
            })
        }
        _ => None,
    };
    let report = TrialReport {
        trial: dir.display().to_string(),
        study: sim.as_ref().map(|s| s.dir.display().to_string()),
        method: sim.as_ref().map(|s| s.method.clone()),
        placements: rows,
        rank_correlation,
        real_best,
        simulated_best,
        recommended: sim.as_ref().and_then(|s| s.recommended.clone()),
        simulated_best_in_real_top_set,
        paired_difference,
    };
    std::fs::create_dir_all(out).map_err(|e| camplace_config::Error::io(out, &e))?;
    let json = serde_json::to_string_pretty(&report).expect("a report is plain data");
    write_atomic(&out.join(REPORT_JSON), format!("{json}\n").as_bytes())?;
    write_html(&report, &plan, out)?;
    Ok(report)
}

/// The rank correlation as one line.
pub fn rho_text(r: &Option<RankCorrelation>) -> String {
    match r {
        Some(RankCorrelation { rho, interval: Some([lo, hi]), n }) => {
            format!("ρ = {rho:.2} (95 % interval {lo:.2} to {hi:.2}, {n} placements)")
        }
        Some(RankCorrelation { rho, interval: None, n }) => {
            format!("ρ = {rho:.2} ({n} placements, too few for an interval)")
        }
        None => "ρ undefined (fewer than two placements with both rates, or one side constant)".into(),
    }
}

impl TrialReport {
    /// The verdict on the simulation's best placement, one line.
    pub fn verdict_text(&self) -> String {
        match (self.simulated_best, self.real_best, self.simulated_best_in_real_top_set) {
            (Some(s), Some(b), Some(inside)) => format!(
                "the simulation's best {} is {} the real top set (real best {}: {})",
                self.placements[s].placement,
                if inside { "within" } else { "outside" },
                self.placements[b].placement,
                self.placements[b].real.map_or("-".into(), |r| r.text())
            ),
            _ => "no verdict: needs a study and judged frames".into(),
        }
    }

    /// The paired difference, one line.
    pub fn paired_text(&self) -> String {
        match &self.paired_difference {
            Some(p) => format!(
                "simulation's best minus real best on the same {} set-downs: {:+.1} points (95 % interval {:+.1} to \
                 {:+.1}, McNemar p = {:.3})",
                p.frames,
                100.0 * p.difference,
                100.0 * p.difference_interval[0],
                100.0 * p.difference_interval[1],
                p.mcnemar_p
            ),
            None => "no paired difference: needs a study and judged frames".into(),
        }
    }
}

fn write_html(r: &TrialReport, plan: &TrialPlan, out: &Path) -> Result<()> {
    let mut page = HtmlPage::new("Real-world trial against the simulation");
    let pct = |f: &Option<RateFigures>| f.map_or("-".to_string(), |x| x.text());
    page.keyed_table(
        "answer",
        &[
            ("rank_correlation".into(), "rank correlation (Spearman)".into(), rho_text(&r.rank_correlation)),
            ("verdict".into(), "simulation's best".into(), r.verdict_text()),
            ("paired_difference".into(), "paired difference".into(), r.paired_text()),
        ],
    );
    if let Some(g) = &plan.grid {
        page.heading(2, "Success maps: simulated and real");
        let map = |title: &str, pick: &dyn Fn(&PlacementRow) -> Option<f64>, best: Option<usize>| HeatMap {
            title: title.to_string(),
            x_label: g.x.name.label(),
            y_label: g.y.name.label(),
            xs: g.x.values(),
            ys: g.y.values(),
            values: r.placements.iter().map(|row| pick(row).map(|v| 100.0 * v)).collect(),
            best,
            decimals: 0,
            scale: ColourScale::Fixed { lo: 0.0, hi: 100.0 },
        };
        let sim = map("simulated success, %", &|row| row.simulated.map(|x| x.success_rate), r.simulated_best);
        let real = map("real success, %", &|row| row.real.map(|x| x.success_rate), r.real_best);
        page.raw("<div class=\"answer\">\n");
        for (name, m) in [("trial_map_simulated", &sim), ("trial_map_real", &real)] {
            if let Some(saved) = save_plot(m, out, name)? {
                page.svg(&saved.svg)?;
            }
        }
        page.raw("</div>\n");
    }
    page.heading(2, "Per placement");
    let rows: Vec<Vec<String>> = r
        .placements
        .iter()
        .map(|p| {
            vec![
                format!("{:03}", p.index),
                p.placement.clone(),
                pct(&p.real),
                pct(&p.simulated),
                format!("{} / {} / {} / {}", p.judged_by_truth, p.marked, p.unsure, p.not_judged),
                if p.in_real_top_set { "yes".into() } else { String::new() },
            ]
        })
        .collect();
    page.table(
        &["folder", "placement", "real success", "simulated success", "truth / marked / unsure / open", "real top set"],
        &rows,
    );
    page.paragraph(
        "Real success counts the frames judged by their truth.json or marked correct or wrong; unsure and unjudged \
         frames are left out. The real top set holds every placement whose 95 % interval reaches the real best's \
         lower end. Frame k is the same tray set-down at every placement, so the simulation's best and the real \
         best are compared pair by pair.",
    );
    page.write(&out.join(REPORT_HTML))
}
