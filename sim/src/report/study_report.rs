//! The study's `report.html`, the answer first: the recommended placement with its
//! success, interval and where the rig's parts are in the world (also `recommended.json`),
//! its mounting tolerances, then each tray's maps, the placements checked on fresh scenes,
//! the search, the findings against the paper (`--paper`) and the settings.

use std::path::{Path, PathBuf};
use std::time::Instant;

use camplace_config::{studied_names, Cell, Effect, EstimatorPreset, PlacementParam};
use camplace_plot::save_plot;

use super::convergence::{Convergence, Curve};
use super::html::HtmlPage;
use super::recommended::Recommended;
use super::rig_sketch::RigSketch;
use super::view3d::{scene_json, view_html, CheckedPlacement, View3d};
use crate::render::frame_files::write_preview;
use crate::render::{Frame, Method};
use crate::scene::tray::TrayModel;
use crate::study::findings::{compare_paired, Paired, Verdict};
use crate::study::optimize::recheck_seed;
use crate::study::placement_study::{tolerance_dir, Combination, Preset, Recommendation, StudyOutcome, StudyRequest};
use crate::study::tray_set::ranked_rate;
use crate::{Error, Result};
use camplace_config::Axis;
use camplace_config::{end_text, offset_text, WalkEnd};
use camplace_estimator::geometry::rig_for;
use camplace_estimator::geometry::Camera;
use camplace_estimator::scoring::pct;
use camplace_estimator::scoring::Summary;

/// A rate as a percentage with one decimal.
/// Writes `report.html` (and its plots, and `recommended.json`) into the study folder.
pub fn write_report(req: &StudyRequest, outcome: &StudyOutcome, started: Instant) -> Result<PathBuf> {
    let (out, preset, seed, base_cell) = (req.out, req.preset, req.seed, req.cell);
    let (grid, combos) = (&outcome.grid, &outcome.combinations[..]);
    let (recommendation, tolerance) = (outcome.recommendation.as_ref(), outcome.tolerance.as_ref());
    let title =
        if preset.is_preview() { "camplace placement study (quick preview)" } else { "camplace placement study" };
    let mut page = HtmlPage::new(title);
    if preset.is_preview() {
        page.paragraph(&format!(
            "A coarse preview: {} scenes per grid cell of a {} × {} grid, no 4-parameter search and no mounting \
             tolerances, so the intervals are wide. Run camplace study without --quick for a placement to mount by.",
            preset.sweep_scenarios, grid.x.steps, grid.y.steps
        ));
    }

    // The answer first: where to mount, how good that is, and how precisely.
    page.heading(2, "Recommended placement");
    match recommendation {
        Some(r) => {
            // Each method's own best, for a cell whose sensor is already chosen.
            let label = r.trays_label();
            let others: Vec<String> = combos
                .iter()
                .filter(|c| c.trays_label == label && c.method != r.method)
                .filter_map(|c| {
                    let k = c.candidates.first()?;
                    let [lo, hi] = k.summary.success_interval;
                    Some(format!(
                        "Best with {}: {} at {} (95 % interval {}–{}).",
                        c.method,
                        pct(k.summary.success_rate),
                        k.placement,
                        pct(lo),
                        pct(hi)
                    ))
                })
                .collect();
            answer(&mut page, out, r, outcome.preview.as_ref(), seed, preset, &others)?;
            view3d_section(&mut page, r, tolerance, combos, seed)?;
            super::verification::verification_section(&mut page, out, combos, seed)?;
        }
        None => page.paragraph("No placement was checked on fresh scenes, so there is nothing to recommend."),
    }
    if let (Some(t), Some(method)) = (tolerance, recommendation.map(|r| r.method)) {
        page.heading(2, "Mounting tolerances");
        page.paragraph(&format!(
            "How far each parameter may be off, alone, before success is shown to drop from {} at the recommended \
             placement (seed {}): each side judged first where its range ends, and when that is outside \
             walked out in growing steps and bisected to the parameter's resolution; {}. Each side is walked at \
             most {}: a rig mounted further off is plainly wrong, not within a tolerance. \"At least\" only where \
             that limit, or the placement's own range, ended the side with its furthest point inside (success \
             is taken to fall off away from the nominal, so the points between are not judged).",
            pct(t.nominal.success_rate),
            t.seed,
            t.test_text(),
            t.limits_text().unwrap_or_else(|| "to the placement's range".to_string())
        ));
        let rows: Vec<Vec<String>> = t
            .axes
            .iter()
            .flat_map(|a| {
                a.sides().map(|side| {
                    let rate = |p: &camplace_config::TolerancePoint| {
                        format!(
                            "{} ({}–{}) at {}",
                            pct(p.success_rate),
                            pct(p.success_interval[0]),
                            pct(p.success_interval[1]),
                            offset_text(p.offset)
                        )
                    };
                    let sign = if side.sign < 0.0 { "−" } else { "+" };
                    let edge = match side.end {
                        WalkEnd::Drop => format!("{sign}{} {}", side.tolerance, a.unit),
                        WalkEnd::RangeEnd => format!("at least {sign}{} {}", side.tolerance, a.unit),
                    };
                    let outside = match (side.end, side.outside) {
                        (WalkEnd::Drop, Some(o)) => format!(
                            "{}; {} scenes lost, {} gained (one-sided p {:.3})",
                            rate(o),
                            o.lost,
                            o.gained,
                            o.p_lower
                        ),
                        _ => format!("none: {}", side.range_text(&a.parameter, &a.unit)),
                    };
                    vec![
                        a.parameter.clone(),
                        edge,
                        format!(
                            "{} (resolution {} {})",
                            if side.end == WalkEnd::RangeEnd && side.at_walk_limit() {
                                "walk limit"
                            } else {
                                end_text(side.end)
                            },
                            a.resolution,
                            a.unit
                        ),
                        rate(side.inside),
                        outside,
                    ]
                })
            })
            .collect();
        page.table(&["parameter", "may be off by", "found by", "just inside", "just outside"], &rows);
        if let Some(w) = t.worst_corner() {
            page.paragraph(&format!(
                "Worst of the {} corners of this box ({}{}): {} (95 % interval {}–{}; {} scenes lost and {} gained \
                 against the nominal) at {}.",
                t.corners.len(),
                t.corner_text(),
                t.screen_text(),
                pct(w.point.success_rate),
                pct(w.point.success_interval[0]),
                pct(w.point.success_interval[1]),
                w.point.lost,
                w.point.gained,
                w.placement
            ));
        }
        for axis in &t.axes {
            let svg = tolerance_dir(out, method).join(format!("tolerance_{}.svg", axis.parameter));
            if svg.exists() {
                page.svg(&svg)?;
            }
        }
    } else if let Some(r) = recommendation {
        page.paragraph(&format!(
            "Mounting tolerances were not measured in this preview: camplace tolerance --placement {} --method {} \
             measures them.",
            r.placement, r.method
        ));
    }

    // The maps and the search.
    for c in combos {
        for (t, sweep) in c.set.trays.iter().zip(&c.sweeps) {
            page.heading(
                2,
                &format!("{} {}: success over r and alpha (the paper's Figures 5 and 6)", t.name, c.method),
            );
            for panel in ["success_rate", "correct_matches", "position_error", "rotation_error"] {
                let svg = t.dir.join(format!("{panel}.svg"));
                if svg.exists() {
                    page.svg(&svg)?;
                }
            }
            if c.sweeps.len() == 1 {
                let rows: Vec<Vec<String>> =
                    sweep.rows.iter().map(|r| summary_cells(&r.placement, &r.summary)).collect();
                page.table(&SUMMARY_HEADER, &rows);
            }
        }
        if c.sweeps.len() > 1 {
            page.heading(3, &format!("{}: each grid cell's lowest tray (the placement's objective)", c.name()));
            let rows: Vec<Vec<String>> = c.sweep.rows.iter().map(|r| summary_cells(&r.placement, &r.summary)).collect();
            page.table(&SUMMARY_HEADER, &rows);
        }
        page.heading(3, &format!("{}: placements checked on fresh scenes", c.name()));
        let mut header = vec!["from"];
        header.extend(SUMMARY_HEADER);
        let rows: Vec<Vec<String>> = c
            .candidates
            .iter()
            .map(|k| {
                let mut r = summary_cells(&k.placement.to_string(), &k.summary);
                r.insert(0, k.source.to_string());
                r
            })
            .collect();
        page.table(&header, &rows);
        let Some(search) = &c.search else { continue };
        page.heading(3, &format!("{}: 4-parameter search", c.name()));
        let conv = c.search_dir.join("convergence.svg");
        if conv.exists() {
            page.svg(&conv)?;
        }
        page.paragraph(&format!(
            "The surrogate's winner was {} (smoothed rate {}). Each step's rate is the lowest over the trays.",
            search.surrogate_winner,
            pct(search.surrogate_success_rate)
        ));
        let rows: Vec<Vec<String>> = search
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
    if req.paper {
        findings(&mut page, out, combos, preset, seed)?;
    }

    page.heading(2, "Settings");
    let all: Vec<&Summary> =
        combos.iter().flat_map(|c| c.sweeps.iter().flat_map(|s| s.rows.iter().map(|r| &r.summary))).collect();
    let median_ms =
        camplace_estimator::scoring::median(&all.iter().map(|s| s.median_ms).collect::<Vec<_>>()).unwrap_or(0.0);
    let search =
        if preset.budget > 0 {
            format!(
            "search over {} with {} evaluations of {} scenes; top {} and the grid's best checked on {} fresh scenes",
            studied_names(),
            preset.budget, preset.search_scenarios, preset.top, preset.recheck_scenarios
        )
        } else {
            format!("no search; the grid's best checked on {} fresh scenes", preset.recheck_scenarios)
        };
    let trays = match req.paper {
        true => "the paper's experiment: built-in trays tray-8 and tray-4, each on its own".to_string(),
        false => format!(
            "the cell's trays: {} (a placement's success is its lowest over them)",
            base_cell.tray_cells().iter().map(|(n, _)| n.as_str()).collect::<Vec<_>>().join(", ")
        ),
    };
    page.list(&[
        format!("preset {}: grid {} × {}, {} scenes per cell; {search}", preset.name, describe(&grid.x), describe(&grid.y), preset.sweep_scenarios),
        trays,
        format!("methods: {}", req.methods.iter().map(|m| m.to_string()).collect::<Vec<_>>().join(", ")),
        estimator_line(base_cell),
        effects_line(base_cell),
        format!("study seed {seed}; fresh scenes on seed {}", recheck_seed(seed)),
        format!("median estimator time per scene over the sweeps: {median_ms:.0} ms; this run of camplace study: {:.0} s with {} threads (finished scenes from an earlier run are reused)", started.elapsed().as_secs_f64(), rayon::current_num_threads()),
        format!("success: position error below {} mm and rotation error below {} deg", base_cell.metrics.success_position, base_cell.metrics.success_rotation),
    ]);
    page.pre(&base_cell.to_toml_string());
    let path = out.join("report.html");
    page.write(&path).map_err(|e| Error::Other(format!("{}: {e}", path.display())))?;
    Ok(path)
}

/// Which estimator the study ran: ours or the paper's preset, with the keys that differ.
fn estimator_line(cell: &Cell) -> String {
    let e = &cell.estimator;
    let which = match e.preset {
        EstimatorPreset::Paper => "the paper's (preset = \"paper\")",
        EstimatorPreset::Ours => "ours (preset = \"ours\")",
    };
    format!(
        "estimator: {which}: {}-match RANSAC samples, features of radius {} mm, turn check {}",
        e.ransac_sample,
        e.feature_radius,
        if e.turn_check { "on" } else { "off" }
    )
}

/// Which simulated effects changed the scenes (an effect switched on with nothing to do,
/// such as an occluder of probability 0, is listed as inactive).
fn effects_line(cell: &Cell) -> String {
    let (on, off): (Vec<Effect>, Vec<Effect>) = Effect::ALL.iter().partition(|&&e| cell.effect_active(e));
    let keys = |v: &[Effect]| {
        if v.is_empty() {
            "none".to_string()
        } else {
            v.iter().map(|e| e.key()).collect::<Vec<_>>().join(", ")
        }
    };
    format!("simulated effects active: {}; inactive: {}", keys(&on), keys(&off))
}

/// The recommended placement: its values, its success with the interval, each tray's,
/// where the rig's parts are in the world, the other methods' best (`other_methods`), a
/// sketch and a rendered scene; and `recommended.json` with the same numbers.
fn answer(
    page: &mut HtmlPage,
    out: &Path,
    r: &Recommendation,
    preview: Option<&Frame>,
    seed: u64,
    preset: &Preset,
    other_methods: &[String],
) -> Result<()> {
    let p = r.placement;
    let cell = &r.cells[0].1;
    let s = &r.summary;
    let rec = Recommended::new(r, preset, seed);
    let rig = rig_for(&p, &cell.sensor);
    let axis = |c: &Camera| c.t_world_camera.rotation * nalgebra::Vector3::z();
    let heading = |c: &Camera| {
        let a = axis(c);
        a.y.atan2(a.x).to_degrees()
    };
    // Rounded first, so that a coordinate a hair below zero does not print as "-0.0".
    let tenth = |x: f64| {
        let r = (x * 10.0).round() / 10.0;
        if r == 0.0 {
            0.0
        } else {
            r
        }
    };
    let xyz = |v: [f64; 3]| format!("({:.1}, {:.1}, {:.1})", tenth(v[0]), tenth(v[1]), tenth(v[2]));
    let interval = format!("{:.1}–{:.1} %", 100.0 * s.success_interval[0], 100.0 * s.success_interval[1]);
    let mut rows: Vec<(String, String, String)> =
        vec![("trays".into(), "for".into(), r.trays_label()), ("method".into(), "method".into(), r.method.to_string())];
    // Each parameter's name, unit and value from PlacementParam; what it means and the
    // decimals a drawing wants are the report's.
    for (param, meaning, digits) in [
        (PlacementParam::R, Some("distance of the rig from the table centre"), 1),
        (PlacementParam::Alpha, Some("polar angle from vertical"), 2),
        (PlacementParam::Baseline, None, 1),
        (PlacementParam::Vergence, Some("toe-in of each camera"), 2),
        (PlacementParam::Azimuth, Some("about the table's z axis"), 1),
    ] {
        let name = param.name();
        let label = meaning.map_or_else(|| name.to_string(), |m| format!("{name} ({m})"));
        rows.push((name.into(), label, format!("{:.digits$} {}", param.get(&p), param.unit())));
    }
    rows.push((
        "success_rate".into(),
        format!("success on {} fresh scenes", s.scored),
        format!("{} ({} of {})", pct(s.success_rate), s.successes, s.scored),
    ));
    rows.push(("success_interval".into(), "95 % interval (Wilson)".into(), interval));
    if let Some(v) = &s.verification {
        rows.push((
            "verified_success_rate".into(),
            format!("correct and accepted (threshold {:.3}, set on these scenes)", v.threshold),
            format!(
                "{} ({} of {}; 95 % interval {}–{})",
                pct(v.verified_success_rate),
                v.verified_successes,
                v.scored,
                pct(v.verified_success_interval[0]),
                pct(v.verified_success_interval[1])
            ),
        ));
    }
    rows.push(("ranked_by".into(), "placements ranked by".into(), rec.ranked_by.clone()));
    if r.per_tray.len() > 1 {
        for ((name, _), t) in r.cells.iter().zip(&r.per_tray) {
            rows.push((
                format!("tray:{name}"),
                format!("success with {name}"),
                format!("{} ({} of {})", pct(t.success_rate), t.successes, t.scored),
            ));
        }
    }
    let mut world: Vec<(String, String, String)> = vec![
        ("left_camera".into(), "left camera centre".into(), xyz(rec.world_mm.left_camera)),
        ("right_camera".into(), "right camera centre".into(), xyz(rec.world_mm.right_camera)),
    ];
    if let Some(pr) = rec.world_mm.projector {
        world.push(("projector".into(), "projector centre".into(), xyz(pr)));
    }
    world.push(("look_at".into(), "point the rig looks at".into(), "(0.0, 0.0, 0.0)".into()));
    world.push((
        "left_tilt".into(),
        "left camera tilt from vertical, towards heading".into(),
        format!("{:.2} deg towards {:.1} deg", rec.tilt_deg.left_camera, heading(&rig.left)),
    ));
    world.push((
        "right_tilt".into(),
        "right camera tilt from vertical, towards heading".into(),
        format!("{:.2} deg towards {:.1} deg", rec.tilt_deg.right_camera, heading(&rig.right)),
    ));
    if let (Some(pr), Some(pr_tilt)) = (&rig.projector, rec.tilt_deg.projector) {
        world.push((
            "projector_tilt".into(),
            "projector tilt from vertical, towards heading".into(),
            format!("{:.2} deg towards {:.1} deg", pr_tilt, heading(pr)),
        ));
    }
    if s.success_rate < 0.8 {
        page.paragraph(&format!(
            "Caution: even the best placement found succeeds on only {} of fresh scenes. Check that the trays and \
             items are described as they are (mesh units mm, origin at the bottom face's centre, the slots), that \
             the work volume holds the tray, and whether another method or a wider search range serves better.",
            pct(s.success_rate)
        ));
    }
    page.raw("<div class=\"answer\"><div>\n");
    page.keyed_table("placement", &rows);
    page.raw("</div><div>\n");
    page.keyed_table("world", &world);
    page.raw("</div></div>\n");
    let tie = if r.tied_candidates > 1 {
        format!(
            " {} checked placements reached {}; among them the one with the most correct feature matches per scene \
             (mean {:.1} on its lowest tray) is recommended, as more correct matches leave RANSAC more margin.",
            r.tied_candidates,
            pct(s.success_rate),
            s.mean_correct_matches.unwrap_or(0.0)
        )
    } else {
        String::new()
    };
    page.paragraph(&format!(
        "World frame: origin at the table's centre on its surface, z up, mm; headings are measured from the world x \
         axis towards y. Chosen from the {} on {} fresh scenes (seed {}) that no placement was picked on{}.{tie}",
        if preset.budget > 0 { "search's best candidates and the grid's best cell" } else { "grid's best cell" },
        s.scored,
        recheck_seed(seed),
        if r.per_tray.len() > 1 { "; the rate is the lowest over the cell's trays" } else { "" }
    ));
    if !other_methods.is_empty() {
        page.paragraph(&other_methods.join(" "));
    }
    let (lo, hi) = TrayModel::from_cell(cell)?.solid.bounds();
    let sketch = RigSketch {
        title: format!("rig at {p}"),
        placement: p,
        rig: rig.clone(),
        table: cell.table.size,
        tray: [hi.x - lo.x, hi.y - lo.y],
    };
    if let Some(saved) = save_plot(&sketch, out, "best_rig")? {
        page.svg(&saved.svg)?;
    }
    if let Some(frame) = preview {
        let file = out.join("best_preview.png");
        write_preview(&file, &frame.shots.left[0], &frame.depth_left)?;
        page.png(&file, "scenario 0 at the recommended placement: left camera image and its true depth")?;
    }

    rec.write(out)?;
    Ok(())
}

/// The cell in 3D at the recommended placement, with the method's other checked placements
/// (grid cells and re-checked candidates) as markers.
fn view3d_section(
    page: &mut HtmlPage,
    r: &Recommendation,
    tolerance: Option<&camplace_config::ToleranceReport>,
    combos: &[Combination],
    seed: u64,
) -> Result<()> {
    let cell = &r.cells[0].1;
    let rig = rig_for(&r.placement, &cell.sensor);
    let scenario = crate::scene::scenario::draw_scenario(cell, seed, 0);
    let mut checked = Vec::new();
    for c in combos.iter().filter(|c| c.method == r.method && c.trays_label == r.trays_label()) {
        for row in &c.sweep.rows {
            if let Ok(p) = cell.placement.with_overrides(&row.placement) {
                checked.push(CheckedPlacement { placement: p, from: "grid".into(), success: row.summary.success_rate });
            }
        }
        for k in &c.candidates {
            checked.push(CheckedPlacement {
                placement: k.placement,
                from: format!("{} (fresh scenes)", k.source),
                success: k.summary.success_rate,
            });
        }
    }
    checked.retain(|c| c.placement != r.placement);
    let view = View3d { cell, placement: r.placement, rig: &rig, scenario: &scenario, tolerance, checked };
    let scene = scene_json(&view)?;
    page.heading(3, "The cell in 3D");
    page.paragraph(&format!(
        "The rig at the recommended placement over scenario 0 of seed {seed}: each camera's and the projector's view \
         down to the table, the part of the table all three cover ({:.0} cm²){}, and the rig of every other \
         placement checked with {} as a dot coloured by its success on the maps' scale. camplace export writes the \
         same cell as a glTF file for 3D tools.",
        scene["covered_area_mm2"].as_f64().unwrap_or(0.0) / 100.0,
        if tolerance.is_some() { ", the box the rig may hang in within its mounting tolerances" } else { "" },
        r.method
    ));
    page.raw(&view_html(&scene));
    Ok(())
}

/// The findings against the paper's three claims (`--paper`), each comparison paired by
/// scene: both sides ran the same scenarios.
fn findings(page: &mut HtmlPage, out: &Path, combos: &[Combination], preset: &Preset, seed: u64) -> Result<()> {
    page.heading(2, "Findings against the paper");
    page.paragraph(
        "Each rate is shown with its Wilson 95 % interval. Both sides of every comparison ran the same scenarios \
         (common random numbers), so the comparisons are paired by scene: a difference is called shown only when \
         its paired 95 % interval (Newcombe 1998, method 10) excludes zero, and the exact McNemar test on the scenes \
         only one side succeeded on is given beside it.",
    );
    // Each combination's first tray's results (the paper's experiment has one tray each).
    let outcomes = |i: usize, placement: &str, s: u64, n: u64| -> Result<Vec<Option<bool>>> {
        let set = &combos[i].set;
        Ok(set.outcomes(0, &set.trays[0].cell.placement.with_overrides(placement)?, s, n))
    };
    let mut dependence = Vec::new();
    for (i, c) in combos.iter().enumerate() {
        let scored: Vec<(usize, &Summary)> =
            c.sweep.rows.iter().map(|r| &r.summary).enumerate().filter(|(_, s)| s.scored > 0).collect();
        let best = scored.iter().max_by(|a, b| a.1.success_rate.total_cmp(&b.1.success_rate).then(b.0.cmp(&a.0)));
        let worst = scored.iter().min_by(|a, b| a.1.success_rate.total_cmp(&b.1.success_rate).then(a.0.cmp(&b.0)));
        if let (Some(b), Some(w)) = (best, worst) {
            let (pb, pw) = (&c.sweep.rows[b.0].placement, &c.sweep.rows[w.0].placement);
            let n = preset.sweep_scenarios;
            let pair = Paired::from_outcomes(&outcomes(i, pb, seed, n)?, &outcomes(i, pw, seed, n)?);
            let (v, text) = compare_paired(&format!("best cell {pb}"), &format!("worst cell {pw}"), pair);
            let verdict = if v == Verdict::AHigher { "placement matters (shown)" } else { "not shown at this scale" };
            dependence.push(format!("{}: {verdict}. {text}", c.name()));
        }
    }
    page.heading(3, "1. Success depends strongly on placement (paper: yes)");
    page.paragraph("The best and the worst cell of each 2-parameter sweep (the best is picked from the same scenes, so it is optimistic).");
    page.list(&dependence);

    let fresh = recheck_seed(seed);
    let mut search_vs_grid = Vec::new();
    for (i, c) in combos.iter().enumerate() {
        let (Some(search), Some(grid)) = (&c.search, c.candidates.iter().find(|k| k.source == "grid")) else {
            continue;
        };
        let n = preset.recheck_scenarios;
        let pair = Paired::from_outcomes(
            &outcomes(i, &search.best().placement, fresh, n)?,
            &outcomes(i, &grid.placement.to_string(), fresh, n)?,
        );
        let (v, text) = compare_paired("4-parameter search best", "2-parameter grid best", pair);
        let verdict = match v {
            Verdict::AHigher => "the search beats the grid (shown)",
            Verdict::BHigher => "the grid beats the search (shown)",
            Verdict::NotShown => "no difference shown",
        };
        search_vs_grid.push(format!("{}: {verdict}. {text}", c.name()));
    }
    page.heading(3, "2. Optimizing 4 parameters beats the 2-parameter grid (paper: 96 % against 88 %)");
    page.paragraph(&format!(
        "Both winners evaluated again on the same {} fresh scenarios (seed {}), which neither was chosen on.",
        preset.recheck_scenarios, fresh
    ));
    if search_vs_grid.is_empty() {
        search_vs_grid.push("Not measured: this preset runs no 4-parameter search.".to_string());
    }
    page.list(&search_vs_grid);

    let mut methods = Vec::new();
    let labels: Vec<&str> = combos.iter().map(|c| c.trays_label.as_str()).collect();
    for (i, tray) in labels.iter().enumerate() {
        if labels[..i].contains(tray) {
            continue;
        }
        let pick = |m: Method| combos.iter().position(|c| c.trays_label == *tray && c.method == m);
        let (Some(one), Some(twelve)) = (pick(Method::OneShot), pick(Method::Phase12)) else { continue };
        // Every grid cell's scenes, cell by cell: the same (placement, scenario) on both sides.
        let (mut a, mut b) = (Vec::new(), Vec::new());
        for row in &combos[one].sweep.rows {
            a.extend(outcomes(one, &row.placement, seed, preset.sweep_scenarios)?);
            b.extend(outcomes(twelve, &row.placement, seed, preset.sweep_scenarios)?);
        }
        let (v, text) = compare_paired(
            "one shot over the whole grid",
            "12 shot over the whole grid",
            Paired::from_outcomes(&a, &b),
        );
        let verdict = match v {
            Verdict::AHigher => "one shot is more robust (shown)",
            Verdict::BHigher => "12 shot is more robust (shown)",
            Verdict::NotShown => "no difference shown",
        };
        methods.push(format!("{tray}: {verdict}. {text}"));
        if let (Some(x), Some(y)) = (combos[one].candidates.first(), combos[twelve].candidates.first()) {
            let n = preset.recheck_scenarios;
            let pair = Paired::from_outcomes(
                &outcomes(one, &x.placement.to_string(), fresh, n)?,
                &outcomes(twelve, &y.placement.to_string(), fresh, n)?,
            );
            let (_, text) = compare_paired("one shot, best", "12 shot, best", pair);
            methods.push(format!("{tray}, best placements on fresh scenes: {text}"));
        }
    }
    page.heading(3, "3. Which method is more robust (paper: one shot)");
    page.paragraph(
        "Robustness as the success rate pooled over every placement of the grid, and at each method's best placement.",
    );
    page.list(&methods);

    // Figure 7 analogue: all searches in one plot.
    let curves: Vec<Curve> = combos
        .iter()
        .filter_map(|c| {
            let s = c.search.as_ref()?;
            Some(Curve {
                label: c.name(),
                rates: s.history.iter().map(|e| ranked_rate(&e.summary)).collect(),
                sweep_best: c.sweep.best.map(|b| ranked_rate(&c.sweep.rows[b].summary)),
            })
        })
        .collect();
    if !curves.is_empty() {
        page.heading(3, "Search convergence (the paper's Figure 7)");
        let conv = Convergence { title: "best verified success rate so far (dashed: the grid's best)".into(), curves };
        if let Some(saved) = save_plot(&conv, out, "convergence")? {
            page.svg(&saved.svg)?;
        }
    }
    Ok(())
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

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    #[test]
    fn the_settings_name_the_estimator_and_the_effects_that_changed_the_scenes() {
        let ours = Cell::default();
        assert_eq!(
            estimator_line(&ours),
            "estimator: ours (preset = \"ours\"): 2-match RANSAC samples, features of radius 30 mm, turn check on"
        );
        assert_eq!(
            effects_line(&ours),
            "simulated effects active: defocus, specular, calibration_error; inactive: occluder"
        );
        let text = "[estimator]\npreset = \"paper\"\n[effects]\ndefocus = false\n[occluder]\nprobability = 0.5\n";
        let paper = Cell::from_toml_str(text, Path::new(".")).unwrap();
        assert_eq!(
            estimator_line(&paper),
            "estimator: the paper's (preset = \"paper\"): 3-match RANSAC samples, features of radius 20 mm, turn check off"
        );
        assert_eq!(
            effects_line(&paper),
            "simulated effects active: specular, calibration_error, occluder; inactive: defocus"
        );
    }
}
