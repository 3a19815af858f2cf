//! The study's `report.html`: the findings against the paper first, then the search's
//! convergence, the best placement (a rendered scene and a sketch of the rig), each
//! combination's sweep and search, and the settings.

use std::path::{Path, PathBuf};
use std::time::Instant;

use camplace_config::Cell;

use super::convergence::{Convergence, Curve};
use super::html::HtmlPage;
use super::rig_sketch::RigSketch;
use super::save_plot;
use crate::render::frame_files::write_preview;
use crate::render::{Frame, Method, Simulator};
use crate::scene::placement_rig::rig_for;
use crate::scene::scenario::draw_scenario;
use crate::scene::tray::TrayModel;
use crate::seeds::noise_key;
use crate::study::findings::{compare, Rate, Verdict};
use crate::study::grid::{Axis, Grid};
use crate::study::optimize::recheck_seed;
use crate::study::placement_study::{Combination, Preset};
use crate::study::Summary;
use crate::{Error, Result};

/// A rate as a percentage with one decimal.
pub fn pct(r: f64) -> String {
    format!("{:.1} %", 100.0 * r)
}

fn rate(s: &Summary) -> Rate {
    Rate { successes: s.successes, scenes: s.scored }
}

/// Writes `report.html` (and its plots) into `out` from the combinations measured.
pub fn write_report(
    out: &Path,
    preset: &Preset,
    seed: u64,
    base_cell: &Cell,
    grid: &Grid,
    combos: &[Combination],
    started: Instant,
) -> Result<PathBuf> {
    let mut page = HtmlPage::new("camplace placement study");
    let name = |c: &Combination| format!("{} {}", c.tray, c.method);

    // Findings first: what the measurements say about the paper's three claims.
    page.heading(2, "Findings against the paper");
    page.paragraph(
        "Each rate is shown with its Wilson 95 % interval; a difference is called shown only when its 95 % interval \
         (Newcombe's hybrid score method, conservative here because both sides share scenes) excludes zero.",
    );
    let mut dependence = Vec::new();
    for c in combos {
        let scored: Vec<(usize, &Summary)> =
            c.sweep.rows.iter().map(|r| &r.summary).enumerate().filter(|(_, s)| s.scored > 0).collect();
        let best = scored.iter().max_by(|a, b| a.1.success_rate.total_cmp(&b.1.success_rate).then(b.0.cmp(&a.0)));
        let worst = scored.iter().min_by(|a, b| a.1.success_rate.total_cmp(&b.1.success_rate).then(a.0.cmp(&b.0)));
        if let (Some(b), Some(w)) = (best, worst) {
            let (v, text) = compare(
                &format!("best cell {}", c.sweep.rows[b.0].placement),
                rate(b.1),
                &format!("worst cell {}", c.sweep.rows[w.0].placement),
                rate(w.1),
            );
            let verdict = if v == Verdict::AHigher { "placement matters (shown)" } else { "not shown at this scale" };
            dependence.push(format!("{}: {verdict}. {text}", name(c)));
        }
    }
    page.heading(3, "1. Success depends strongly on placement (paper: yes)");
    page.paragraph("The best and the worst cell of each 2-parameter sweep (the best is picked from the same scenes, so it is optimistic).");
    page.list(&dependence);

    let mut search_vs_grid = Vec::new();
    for c in combos {
        let Some(g) = &c.sweep_best_recheck else { continue };
        let o = &c.search.best().summary;
        let (v, text) = compare("4-parameter search best", rate(o), "2-parameter grid best", rate(g));
        let verdict = match v {
            Verdict::AHigher => "the search beats the grid (shown)",
            Verdict::BHigher => "the grid beats the search (shown)",
            Verdict::NotShown => "no difference shown",
        };
        search_vs_grid.push(format!("{}: {verdict}. {text}", name(c)));
    }
    page.heading(3, "2. Optimizing 4 parameters beats the 2-parameter grid (paper: 96 % against 88 %)");
    page.paragraph(&format!(
        "Both winners evaluated again on {} fresh scenarios (seed {}), which neither was chosen on.",
        preset.recheck_scenarios,
        recheck_seed(seed)
    ));
    page.list(&search_vs_grid);

    let mut methods = Vec::new();
    for tray in ["tray-8", "tray-4"] {
        let pick = |m: Method| combos.iter().find(|c| c.tray == tray && c.method == m);
        let (Some(one), Some(twelve)) = (pick(Method::OneShot), pick(Method::Phase12)) else { continue };
        let pooled = |c: &Combination| {
            let (k, n) = c.sweep.rows.iter().fold((0, 0), |(k, n), r| (k + r.summary.successes, n + r.summary.scored));
            Rate { successes: k, scenes: n }
        };
        let (v, text) =
            compare("one shot over the whole grid", pooled(one), "12 shot over the whole grid", pooled(twelve));
        let verdict = match v {
            Verdict::AHigher => "one shot is more robust (shown)",
            Verdict::BHigher => "12 shot is more robust (shown)",
            Verdict::NotShown => "no difference shown",
        };
        methods.push(format!("{tray}: {verdict}. {text}"));
        let (_, text) = compare(
            "one shot, search best",
            rate(&one.search.best().summary),
            "12 shot, search best",
            rate(&twelve.search.best().summary),
        );
        methods.push(format!("{tray}, best placements on fresh scenes: {text}"));
    }
    page.heading(3, "3. Which method is more robust (paper: one shot)");
    page.paragraph(
        "Robustness as the success rate pooled over every placement of the grid, and at each method's best placement.",
    );
    page.list(&methods);

    // Figure 7 analogue: all searches in one plot.
    page.heading(2, "Search convergence (the paper's Figure 7)");
    let curves: Vec<Curve> = combos
        .iter()
        .map(|c| Curve {
            label: name(c),
            rates: c.search.history.iter().map(|e| e.summary.success_rate).collect(),
            sweep_best: c.sweep.best.map(|b| c.sweep.rows[b].summary.success_rate),
        })
        .collect();
    let conv = Convergence { title: "best success rate so far (dashed: the grid's best)".into(), curves };
    if let Some(saved) = save_plot(&conv, out, "convergence")? {
        page.svg(&saved.svg)?;
    }

    // The best placement overall, with a rendered scene and a sketch of the rig.
    if let Some(best) = combos
        .iter()
        .max_by(|a, b| a.search.best().summary.success_rate.total_cmp(&b.search.best().summary.success_rate))
    {
        let p = best.cell.placement.with_overrides(&best.search.best().placement)?;
        page.heading(2, "Best placement");
        page.paragraph(&format!(
            "{} with {} ({}): {} on fresh scenes.",
            p,
            best.tray,
            best.method,
            best.search.best().summary.line()
        ));
        let preview = out.join("best_preview.png");
        let mut sim = Simulator::new(&best.cell, &p, seed)?;
        let mut frame = Frame::default();
        let scenario = draw_scenario(&best.cell, seed, 0);
        sim.render(&scenario.scene(), best.method, noise_key(seed, 0, false), &mut frame);
        write_preview(&preview, &frame.left[0], &frame.depth_left)?;
        page.png(&preview, "scenario 0 at the best placement: left camera image and its true depth")?;
        let (lo, hi) = TrayModel::from_cell(&best.cell)?.solid.bounds();
        let sketch = RigSketch {
            title: format!("rig at {p}"),
            placement: p,
            rig: rig_for(&p, &best.cell.sensor),
            table: best.cell.table.size,
            tray: [hi.x - lo.x, hi.y - lo.y],
        };
        if let Some(saved) = save_plot(&sketch, out, "best_rig")? {
            page.svg(&saved.svg)?;
        }
    }

    for c in combos {
        let dir = out.join(c.tray).join(c.method.to_string());
        page.heading(2, &format!("{}: 2-parameter sweep (the paper's Figures 5 and 6)", name(c)));
        for panel in ["success_rate", "correct_matches", "position_error", "rotation_error"] {
            let svg = dir.join(format!("{panel}.svg"));
            if svg.exists() {
                page.svg(&svg)?;
            }
        }
        let rows: Vec<Vec<String>> = c.sweep.rows.iter().map(|r| summary_cells(&r.placement, &r.summary)).collect();
        page.table(&SUMMARY_HEADER, &rows);
        page.heading(3, &format!("{}: 4-parameter search", name(c)));
        let conv = dir.join("convergence.svg");
        if conv.exists() {
            page.svg(&conv)?;
        }
        let mut rows: Vec<Vec<String>> =
            c.search.rechecks.iter().map(|e| summary_cells(&e.placement, &e.summary)).collect();
        if let (Some(b), Some(g)) = (c.sweep.best, &c.sweep_best_recheck) {
            rows.push(summary_cells(&format!("{} (grid best)", c.sweep.rows[b].placement), g));
        }
        page.paragraph(&format!(
            "Candidates on {} fresh scenarios (seed {}); the surrogate's winner was {} (smoothed rate {}).",
            c.search.rechecks.first().map_or(0, |e| e.summary.scored),
            recheck_seed(seed),
            c.search.surrogate_winner,
            pct(c.search.surrogate_success_rate)
        ));
        page.table(&SUMMARY_HEADER, &rows);
        let rows: Vec<Vec<String>> = c
            .search
            .history
            .iter()
            .enumerate()
            .map(|(i, e)| {
                let mut r = summary_cells(&e.placement, &e.summary);
                r.insert(0, (i + 1).to_string());
                r
            })
            .collect();
        let mut header = vec!["step"];
        header.extend(SUMMARY_HEADER);
        page.table(&header, &rows);
    }

    page.heading(2, "Settings");
    let all: Vec<&Summary> = combos.iter().flat_map(|c| c.sweep.rows.iter().map(|r| &r.summary)).collect();
    let median_ms = crate::study::median(&all.iter().map(|s| s.median_ms).collect::<Vec<_>>()).unwrap_or(0.0);
    page.list(&[
        format!("preset {}: grid {} × {}, {} scenes per cell; search over r, alpha, baseline, vergence with {} evaluations of {} scenes; top {} re-checked on {} fresh scenes", preset.name, describe(&grid.x), describe(&grid.y), preset.sweep_scenarios, preset.budget, preset.search_scenarios, preset.top, preset.recheck_scenarios),
        format!("study seed {seed}; re-checks on seed {}", recheck_seed(seed)),
        format!("median estimator time per scene over the sweeps: {median_ms:.0} ms; this run of camplace study: {:.0} s with {} threads (finished scenes from an earlier run are reused)", started.elapsed().as_secs_f64(), rayon::current_num_threads()),
        format!("success: position error below {} mm and rotation error below {} deg", base_cell.metrics.success_position, base_cell.metrics.success_rotation),
    ]);
    page.pre(&base_cell.to_toml_string());
    let path = out.join("report.html");
    page.write(&path).map_err(|e| Error::Other(format!("{}: {e}", path.display())))?;
    Ok(path)
}

fn describe(a: &Axis) -> String {
    format!("{} {}–{} in {} steps", a.name, a.lo, a.hi, a.steps)
}

const SUMMARY_HEADER: [&str; 7] = [
    "placement",
    "success",
    "95 % interval",
    "mean position error, mm",
    "mean rotation error, deg",
    "mean correct matches",
    "scenes",
];

fn summary_cells(placement: &str, s: &Summary) -> Vec<String> {
    let opt = |v: Option<f64>| v.map_or("–".to_string(), |v| format!("{v:.2}"));
    vec![
        placement.to_string(),
        pct(s.success_rate),
        format!("{:.1}–{:.1} %", 100.0 * s.success_interval[0], 100.0 * s.success_interval[1]),
        opt(s.mean_position_error_mm),
        opt(s.mean_rotation_error_deg),
        opt(s.mean_correct_matches),
        s.scored.to_string(),
    ]
}
