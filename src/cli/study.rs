//! `camplace study`: the paper's experiment on the cell — both built-in trays × both
//! methods, each a 2-parameter sweep then a 4-parameter search — into one folder, ending
//! with a self-contained `report.html` that states what was measured against the paper's
//! findings. The folder is `TRAY/METHOD/` per combination; re-running resumes.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Context;
use camplace_config::{Cell, TrayKind};
use camplace_sim::frame_files::write_preview;
use camplace_sim::placement_rig::rig_for;
use camplace_sim::report::convergence::{Convergence, Curve};
use camplace_sim::report::html::HtmlPage;
use camplace_sim::report::rig_sketch::RigSketch;
use camplace_sim::report::save_plot;
use camplace_sim::report::sweep_panels::SweepResult;
use camplace_sim::study::findings::{compare, Rate, Verdict};
use camplace_sim::study::grid::{Axis, Grid};
use camplace_sim::study::optimize::{recheck_seed, SearchOutcome, SearchParameter, SearchPlan};
use camplace_sim::study::run::{PlacementJob, SceneRunner};
use camplace_sim::study::shard::Shard;
use camplace_sim::study::Summary;
use camplace_sim::tray::TrayModel;
use camplace_sim::{draw_scenario, noise_key, Frame, Method, Simulator};

use super::optimize::optimize;
use super::run_args::open_folder;
use super::sweep::sweep;

/// Flags of `camplace study`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Cell file (TOML); the built-in default cell when not given. Its tray kind is
    /// replaced by each built-in tray in turn.
    #[arg(long, value_name = "FILE")]
    cell: Option<PathBuf>,
    /// Study seed (default: the cell's scenarios.seed).
    #[arg(long)]
    seed: Option<u64>,
    /// A small preset for a first look (3 × 3 grid, few scenes, short search).
    #[arg(long)]
    quick: bool,
    /// Run only part I of N of the sweeps; merge the parts, then run study on the merged folder.
    #[arg(long, value_name = "I/N")]
    shard: Option<String>,
    /// Output folder.
    #[arg(long, default_value = "out/study")]
    out: PathBuf,
}

/// The scale of a study.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
struct Preset {
    name: &'static str,
    x: Axis,
    y: Axis,
    sweep_scenarios: u64,
    budget: usize,
    search_scenarios: u64,
    top: usize,
    recheck_scenarios: u64,
}

impl Preset {
    /// The default: the paper's 5 × 5 grid and 4-parameter search, scaled to finish on a
    /// 2-core machine in hours rather than days (the paper used 250 scenes and 100 steps).
    fn full() -> Preset {
        Preset {
            name: "full",
            x: "r=400:900:5".parse().expect("valid"),
            y: "alpha=0:60:5".parse().expect("valid"),
            sweep_scenarios: 50,
            budget: 30,
            search_scenarios: 50,
            top: 3,
            recheck_scenarios: 100,
        }
    }

    fn quick() -> Preset {
        Preset {
            name: "quick",
            x: "r=450:850:3".parse().expect("valid"),
            y: "alpha=10:50:3".parse().expect("valid"),
            sweep_scenarios: 6,
            budget: 12,
            search_scenarios: 6,
            top: 1,
            recheck_scenarios: 12,
        }
    }
}

/// What one (tray, method) combination measured.
struct Combination {
    tray: &'static str,
    method: Method,
    cell: Cell,
    sweep: SweepResult,
    search: SearchOutcome,
    /// The sweep's best cell on the fresh scenarios the search's candidates were rechecked on.
    sweep_best_recheck: Option<Summary>,
}

/// Runs `camplace study`.
pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let started = Instant::now();
    let base_cell = match &a.cell {
        Some(p) => Cell::load(p)?,
        None => Cell::default(),
    };
    let seed = a.seed.unwrap_or(base_cell.scenarios.seed);
    let shard = match &a.shard {
        Some(t) => t.parse::<Shard>().map_err(|e| anyhow::anyhow!("--shard: {e}"))?,
        None => Shard::WHOLE,
    };
    let preset = if a.quick { Preset::quick() } else { Preset::full() };
    let grid = Grid { x: preset.x.clone(), y: preset.y.clone() };
    let mut combos = Vec::new();
    for (tray, kind) in [("tray-8", TrayKind::Tray8), ("tray-4", TrayKind::Tray4)] {
        for method in [Method::OneShot, Method::Phase12] {
            let mut cell = base_cell.clone();
            cell.tray.kind = kind;
            let dir = a.out.join(tray).join(method.to_string());
            let base = cell.placement;
            let label = format!("{tray} {method} sweep");
            let sweep = sweep(&dir, &cell, &base, method, seed, &grid, preset.sweep_scenarios, shard, &label)?;
            if !shard.is_whole() {
                continue;
            }
            let plan = SearchPlan {
                parameters: ["r", "alpha", "baseline", "vergence"]
                    .iter()
                    .map(|n| SearchParameter::default_for(n).expect("known"))
                    .collect(),
                budget: preset.budget,
                scenarios: preset.search_scenarios,
                optimizer_seed: seed,
                top: preset.top,
                recheck_scenarios: preset.recheck_scenarios,
            };
            let search = optimize(&dir, &cell, &base, method, seed, &plan, &format!("{tray} {method} search"))?;
            let sweep_best_recheck = match sweep.best {
                Some(b) => {
                    Some(recheck(&dir, &cell, method, seed, &sweep.rows[b].placement, preset.recheck_scenarios)?)
                }
                None => None,
            };
            println!(
                "{tray} {method}: sweep best {}; search best {}",
                sweep.best.map_or("n/a".into(), |b| format!(
                    "{} at {}",
                    pct(sweep.rows[b].summary.success_rate),
                    sweep.rows[b].placement
                )),
                format_args!("{} at {}", pct(search.best().summary.success_rate), search.best().placement)
            );
            combos.push(Combination { tray, method, cell, sweep, search, sweep_best_recheck });
        }
    }
    if !shard.is_whole() {
        println!(
            "shard {shard} of the sweeps done into {}; merge the parts, then run camplace study on the merged folder",
            a.out.display()
        );
        return Ok(ExitCode::SUCCESS);
    }
    let report = write_report(&a.out, &preset, seed, &base_cell, &grid, &combos, started)?;
    println!("wrote {} ({:.0} s)", report.display(), started.elapsed().as_secs_f64());
    Ok(ExitCode::SUCCESS)
}

fn pct(r: f64) -> String {
    format!("{:.1} %", 100.0 * r)
}

/// Evaluates `placement` on the fresh scenarios of the search's re-check.
fn recheck(dir: &Path, cell: &Cell, method: Method, seed: u64, placement: &str, n: u64) -> anyhow::Result<Summary> {
    let p = cell.placement.with_overrides(placement)?;
    let store = open_folder(dir, cell, method, seed)?;
    let s = recheck_seed(seed);
    SceneRunner::new(cell, method, &store)
        .run(&[PlacementJob { placement: p, seed: s, scenarios: (0..n).collect() }], "re-check")?;
    Ok(Summary::from_records(&store.records(&p, method, s, n)))
}

fn rate(s: &Summary) -> Rate {
    Rate { successes: s.successes, scenes: s.scored }
}

fn write_report(
    out: &Path,
    preset: &Preset,
    seed: u64,
    base_cell: &Cell,
    grid: &Grid,
    combos: &[Combination],
    started: Instant,
) -> anyhow::Result<PathBuf> {
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
    let median_ms = camplace_sim::study::median(&all.iter().map(|s| s.median_ms).collect::<Vec<_>>()).unwrap_or(0.0);
    page.list(&[
        format!("preset {}: grid {} × {}, {} scenes per cell; search over r, alpha, baseline, vergence with {} evaluations of {} scenes; top {} re-checked on {} fresh scenes", preset.name, describe(&grid.x), describe(&grid.y), preset.sweep_scenarios, preset.budget, preset.search_scenarios, preset.top, preset.recheck_scenarios),
        format!("study seed {seed}; re-checks on seed {}", recheck_seed(seed)),
        format!("median estimator time per scene over the sweeps: {median_ms:.0} ms; this run of camplace study: {:.0} s with {} threads (finished scenes from an earlier run are reused)", started.elapsed().as_secs_f64(), rayon::current_num_threads()),
        format!("success: position error below {} mm and rotation error below {} deg", base_cell.metrics.success_position, base_cell.metrics.success_rotation),
    ]);
    page.pre(&base_cell.to_toml_string());
    let path = out.join("report.html");
    page.write(&path).with_context(|| path.display().to_string())?;
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
