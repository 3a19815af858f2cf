//! The placement study: for each method, a 2-parameter sweep then a 4-parameter search over
//! the trays studied, the best placements checked on fresh scenes, the recommended
//! placement's mounting tolerances, and a self-contained `report.html` that opens with the
//! answer. Two kinds of study:
//! - the cell's own trays (the default): one placement must serve every tray the cell
//!   lists, so a placement's success is its lowest over the trays;
//! - the paper's experiment (`--paper`): both built-in trays, each studied on its own, and
//!   the findings stated against the paper's.
//!
//! Each tray's scenes live in `TRAY/METHOD/` (a search over several trays writes its own
//! outputs to `all-trays/METHOD/`); re-running resumes.

use std::path::{Path, PathBuf};
use std::time::Instant;

use camplace_config::{Cell, Placement, PlacementParam, TrayKind};

use super::optimize::{recheck_seed, SearchOutcome, SearchParameter, SearchPlan};
use super::placement_search::optimize_set;
use super::shard::Shard;
use super::sweep::sweep;
use super::tolerance::{measure_tolerance, ToleranceRequest};
use super::tray_set::{lowest, margin_order, ranked_rate, TraySet};
use crate::render::{Frame, Method, Simulator};
use crate::report::sweep_panels::SweepResult;
use crate::report::table::{write_summary_csv, SummaryRow};
use crate::report::tolerance_plot::write_tolerance_plots;
use crate::scene::scenario::draw_scenario;
use crate::seeds::noise_key;
use crate::{Error, Result};
use camplace_config::ToleranceReport;
use camplace_config::{Axis, Grid};
use camplace_estimator::scoring::pct;
use camplace_estimator::scoring::Summary;

/// The scale of a study.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Preset {
    /// "full" or "quick".
    pub name: &'static str,
    /// The sweep's horizontal axis.
    pub x: Axis,
    /// The sweep's vertical axis.
    pub y: Axis,
    /// Scenes per sweep cell.
    pub sweep_scenarios: u64,
    /// Evaluations the search may spend (0: no search; the grid's best is recommended).
    pub budget: usize,
    /// Scenes per search evaluation.
    pub search_scenarios: u64,
    /// Search candidates re-checked on fresh scenes.
    pub top: usize,
    /// Fresh scenes of a re-check.
    pub recheck_scenarios: u64,
    /// Scenes per placement of the mounting tolerances (0: not measured).
    pub tolerance_scenarios: u64,
    /// The drop of success the tolerances' scene count detects with the stated power.
    pub tolerance_margin: f64,
    /// The share of each found tolerance the corners of the box are placed at.
    pub tolerance_corner_fraction: f64,
    /// The parameters whose tolerances are walked (every one in both presets).
    pub tolerance_parameters: Vec<PlacementParam>,
}

impl Preset {
    /// The default: the paper's 5 × 5 grid and 4-parameter search, scaled to finish on a
    /// 2-core machine in minutes rather than days (the paper used 250 scenes and 100
    /// steps), then the mounting tolerances of the recommended placement.
    pub fn full() -> Preset {
        Preset {
            name: "full",
            x: "r=400:900:5".parse().expect("valid"),
            y: "alpha=0:60:5".parse().expect("valid"),
            sweep_scenarios: 20,
            budget: 30,
            search_scenarios: 25,
            top: 3,
            recheck_scenarios: 100,
            tolerance_scenarios: 44,
            tolerance_margin: 0.15,
            tolerance_corner_fraction: 1.0,
            tolerance_parameters: PlacementParam::ALL.to_vec(),
        }
    }

    /// A coarse preview in about two minutes: a 3 × 3 grid of few scenes, no search, no
    /// tolerances; the grid's best cell checked on fresh scenes.
    pub fn quick() -> Preset {
        Preset {
            name: "quick",
            x: "r=450:850:3".parse().expect("valid"),
            y: "alpha=10:50:3".parse().expect("valid"),
            sweep_scenarios: 4,
            budget: 0,
            search_scenarios: 4,
            top: 1,
            recheck_scenarios: 8,
            tolerance_scenarios: 0,
            tolerance_margin: 0.15,
            tolerance_corner_fraction: 1.0,
            tolerance_parameters: PlacementParam::ALL.to_vec(),
        }
    }

    /// Whether this is a coarse preview.
    pub fn is_preview(&self) -> bool {
        self.name == "quick"
    }
}

/// What to study.
pub struct StudyRequest<'a> {
    /// The study folder.
    pub out: &'a Path,
    /// The cell: its trays (or, with `paper`, everything but its trays).
    pub cell: &'a Cell,
    /// Study seed.
    pub seed: u64,
    /// The scale.
    pub preset: &'a Preset,
    /// Both built-in trays, each on its own, with the findings against the paper.
    pub paper: bool,
    /// The methods studied.
    pub methods: Vec<Method>,
    /// The part of the sweeps to run.
    pub shard: Shard,
}

/// A placement checked on fresh scenes.
#[derive(Debug, Clone)]
pub struct Candidate {
    /// The placement.
    pub placement: Placement,
    /// Where it came from: "search" or "grid".
    pub source: &'static str,
    /// Its lowest tray's summary on the fresh scenes.
    pub summary: Summary,
    /// Each tray's summary on the fresh scenes, in the trays' order.
    pub per_tray: Vec<Summary>,
}

/// The placement the study recommends mounting.
#[derive(Debug, Clone)]
pub struct Recommendation {
    /// The method.
    pub method: Method,
    /// The placement.
    pub placement: Placement,
    /// Where it came from: "search" or "grid".
    pub source: &'static str,
    /// Its lowest tray's summary on fresh scenes.
    pub summary: Summary,
    /// The trays it serves, each with its name.
    pub cells: Vec<(String, Cell)>,
    /// Each tray's summary on the fresh scenes, in the order of `cells`.
    pub per_tray: Vec<Summary>,
    /// How many checked candidates (over every method) reached the same success rate.
    pub tied_candidates: usize,
}

impl Recommendation {
    /// The trays' names joined by " + ", as [`Combination::trays_label`].
    pub fn trays_label(&self) -> String {
        trays_label(self.cells.iter().map(|(n, _)| n.as_str()))
    }
}

/// Names joined by " + ".
fn trays_label<'a>(names: impl Iterator<Item = &'a str>) -> String {
    names.collect::<Vec<_>>().join(" + ")
}

/// What one method measured over one group of trays.
pub struct Combination {
    /// The trays' names joined by " + ".
    pub trays_label: String,
    /// The method.
    pub method: Method,
    /// The trays' open study folders (names, cells, folders).
    pub set: TraySet,
    /// Each tray's 2-parameter sweep, in the order of `set`.
    pub sweeps: Vec<SweepResult>,
    /// The sweep judged over the trays: each cell's lowest tray.
    pub sweep: SweepResult,
    /// The 4-parameter search, if the preset runs one.
    pub search: Option<SearchOutcome>,
    /// The folder of the search's outputs.
    pub search_dir: PathBuf,
    /// The search's re-checked candidates and the grid's best, on the same fresh scenes,
    /// best first (by success, then by the secondary measure).
    pub candidates: Vec<Candidate>,
}

impl Combination {
    /// "TRAYS METHOD".
    pub fn name(&self) -> String {
        format!("{} {}", self.trays_label, self.method)
    }
}

/// What a whole study found: each combination's sweeps, search and re-checks, the
/// recommended placement and its mounting tolerances. `write_report` lays it out as
/// `report.html` and `recommended.json`.
pub struct StudyOutcome {
    /// The sweep grid.
    pub grid: Grid,
    /// Each group of trays with each method, in the order they ran.
    pub combinations: Vec<Combination>,
    /// The placement to mount by, when any combination has one.
    pub recommendation: Option<Recommendation>,
    /// The recommendation's mounting tolerances, when the preset measures them.
    pub tolerance: Option<ToleranceReport>,
    /// Scenario 0 rendered at the recommended placement with its method, for a look at
    /// what the rig sees.
    pub preview: Option<Frame>,
}

/// Runs the study: every combination's sweep (only shard `shard`'s part of each when it is
/// not the whole), then its search and re-checks, the recommendation and its tolerances.
/// `say` is handed one line per finished step; returns what the study found, or `None` when
/// only a shard of the sweeps was run.
pub fn run_study(req: &StudyRequest, mut say: impl FnMut(&str)) -> Result<Option<StudyOutcome>> {
    let (out, preset, seed, shard) = (req.out, req.preset, req.seed, req.shard);
    let grid = Grid { x: preset.x.clone(), y: preset.y.clone() };
    // The report is written here later; each tray's folder is cleaned as it is opened.
    camplace_config::remove_stale_temp_files(out)?;
    let groups: Vec<Vec<(String, Cell)>> = if req.paper {
        [("tray-8", TrayKind::Tray8), ("tray-4", TrayKind::Tray4)]
            .into_iter()
            .map(|(name, kind)| {
                let mut cell = req.cell.clone();
                cell.trays.clear();
                cell.tray = Cell::default().tray;
                cell.tray.kind = kind;
                vec![(name.to_string(), cell)]
            })
            .collect()
    } else {
        vec![req.cell.tray_cells()]
    };
    let mut combos = Vec::new();
    for group in &groups {
        for &method in &req.methods {
            let Some(c) = run_combination(out, group, method, seed, preset, &grid, shard, &mut say)? else { continue };
            combos.push(c);
        }
    }
    if !shard.is_whole() {
        return Ok(None);
    }
    let recommendation = recommend(&combos);
    let tolerance = match &recommendation {
        Some(r) if preset.tolerance_scenarios > 0 => {
            let started = Instant::now();
            let t = tolerance(out, r, seed, preset)?;
            say(&format!("tolerances around {} ({}):\n{}", r.placement, took(started), t.table()));
            Some(t)
        }
        _ => None,
    };
    let preview = recommendation.as_ref().map(|r| preview_frame(r, seed)).transpose()?;
    Ok(Some(StudyOutcome { grid, combinations: combos, recommendation, tolerance, preview }))
}

/// Scenario 0 of `seed` at the recommended placement, rendered with its method through the
/// first tray's cell.
fn preview_frame(r: &Recommendation, seed: u64) -> Result<Frame> {
    let cell = &r.cells[0].1;
    let mut sim = Simulator::new(cell, &r.placement, seed)?;
    let mut frame = Frame::default();
    let scenario = draw_scenario(cell, seed, 0);
    sim.render(&scenario.scene(), r.method, noise_key(seed, 0, false), &mut frame);
    Ok(frame)
}

/// Where a study's tolerances of a placement measured with `method` are.
pub fn tolerance_dir(out: &Path, method: Method) -> PathBuf {
    out.join("tolerance").join(method.to_string())
}

/// One method over one group of trays: sweeps, search, fresh-scene checks.
#[allow(clippy::too_many_arguments)]
fn run_combination(
    out: &Path,
    group: &[(String, Cell)],
    method: Method,
    seed: u64,
    preset: &Preset,
    grid: &Grid,
    shard: Shard,
    say: &mut impl FnMut(&str),
) -> Result<Option<Combination>> {
    let trays_label = trays_label(group.iter().map(|(n, _)| n.as_str()));
    let base = group[0].1.placement;
    let mut folders = Vec::new();
    let mut sweeps = Vec::new();
    let started = Instant::now();
    for (name, cell) in group {
        let dir = out.join(name).join(method.to_string());
        let label = format!("{name} {method} sweep");
        sweeps.push(sweep(&dir, cell, &base, method, seed, grid, preset.sweep_scenarios, shard, &label)?);
        folders.push((name.clone(), cell.clone(), dir));
    }
    if !shard.is_whole() {
        return Ok(None);
    }
    // Opened after the sweeps, which keep their own handle on the same files.
    let set = TraySet::open(folders, method, seed)?;
    let sweep = joint_sweep(&sweeps);
    let search_dir =
        if sweeps.len() == 1 { set.trays[0].dir.clone() } else { out.join("all-trays").join(method.to_string()) };
    if sweeps.len() > 1 {
        std::fs::create_dir_all(&search_dir)
            .map_err(|e| Error::Other(format!("{}: cannot create the folder: {e}", search_dir.display())))?;
        write_summary_csv(&search_dir.join("summary.csv"), &sweep.rows)?;
    }
    let swept = took(started);
    let started = Instant::now();
    let search = if preset.budget > 0 {
        let plan = SearchPlan {
            parameters: PlacementParam::STUDIED.into_iter().filter_map(SearchParameter::default_for).collect(),
            budget: preset.budget,
            scenarios: preset.search_scenarios,
            optimizer_seed: seed,
            top: preset.top,
            recheck_scenarios: preset.recheck_scenarios,
        };
        Some(optimize_set(&search_dir, &set, &base, seed, &plan, &format!("{trays_label} {method} search"))?)
    } else {
        None
    };
    let searched = took(started);
    let started = Instant::now();
    let fresh = recheck_seed(seed);
    let mut candidates = Vec::new();
    let mut check = |p: Placement, source: &'static str| -> Result<()> {
        let per_tray =
            set.evaluate(&p, fresh, preset.recheck_scenarios, &format!("{trays_label} {method} re-check"))?;
        candidates.push(Candidate { placement: p, source, summary: lowest(&per_tray), per_tray });
        Ok(())
    };
    if let Some(s) = &search {
        for e in &s.rechecks {
            check(base.with_overrides(&e.placement)?, "search")?;
        }
    }
    if let Some(b) = sweep.best {
        check(base.with_overrides(&sweep.rows[b].placement)?, "grid")?;
    }
    // Stable: of two equal candidates the search's (checked first) stays first.
    candidates.sort_by(|a, b| margin_order(&b.summary, &a.summary));
    let checked = took(started);
    say(&format!(
        "{trays_label} {method}: sweep best {}; {} (sweep {swept}, search {searched}, re-check {checked})",
        sweep.best.map_or("n/a".into(), |b| format!(
            "{} verified ({} success) at {}",
            pct(ranked_rate(&sweep.rows[b].summary)),
            pct(sweep.rows[b].summary.success_rate),
            sweep.rows[b].placement
        )),
        candidates.first().map_or("no placement checked".into(), |c| format!(
            "best on fresh scenes {} verified ({} success) at {}",
            pct(ranked_rate(&c.summary)),
            pct(c.summary.success_rate),
            c.placement
        ))
    ));
    Ok(Some(Combination { trays_label, method, set, sweeps, sweep, search, search_dir, candidates }))
}

/// The time since `started`, for a line: "212 s" (a resumed stage counts only what it ran).
fn took(started: Instant) -> String {
    format!("{:.0} s", started.elapsed().as_secs_f64())
}

/// The sweep over several trays: each cell's lowest tray (one tray's sweep as it is).
fn joint_sweep(sweeps: &[SweepResult]) -> SweepResult {
    if sweeps.len() == 1 {
        return sweeps[0].clone();
    }
    let first = &sweeps[0];
    let rows: Vec<SummaryRow> = (0..first.rows.len())
        .map(|i| {
            let summaries: Vec<Summary> = sweeps.iter().map(|s| s.rows[i].summary.clone()).collect();
            SummaryRow { summary: lowest(&summaries), ..first.rows[i].clone() }
        })
        .collect();
    let best = rows
        .iter()
        .enumerate()
        .filter(|(_, r)| r.summary.scored > 0)
        .max_by(|a, b| ranked_rate(&a.1.summary).total_cmp(&ranked_rate(&b.1.summary)).then(b.0.cmp(&a.0)))
        .map(|(i, _)| i);
    SweepResult { rows, complete: sweeps.iter().all(|s| s.complete), best }
}

/// The placement to mount: the best candidate on fresh scenes over every method, by the
/// ranked rate (verified success), then success, then the secondary measure; the first
/// method studied wins a full tie.
/// Only the first group of trays counts (the paper's experiment studies two trays each on
/// its own, and a placement found for one says nothing of the other).
fn recommend(combos: &[Combination]) -> Option<Recommendation> {
    let group = &combos.first()?.trays_label;
    let combos: Vec<&Combination> = combos.iter().filter(|c| &c.trays_label == group).collect();
    let mut best: Option<(&Combination, &Candidate)> = None;
    for &c in &combos {
        let Some(top) = c.candidates.first() else { continue };
        if best.is_none_or(|(_, b)| margin_order(&top.summary, &b.summary).is_gt()) {
            best = Some((c, top));
        }
    }
    let (combo, top) = best?;
    // Distinct (method, placement) pairs: the grid's best may also be a search candidate.
    let mut tied: Vec<(Method, Placement)> = Vec::new();
    for c in &combos {
        for k in c.candidates.iter().filter(|k| ranked_rate(&k.summary) == ranked_rate(&top.summary)) {
            if !tied.contains(&(c.method, k.placement)) {
                tied.push((c.method, k.placement));
            }
        }
    }
    let tied = tied.len();
    Some(Recommendation {
        method: combo.method,
        placement: top.placement,
        source: top.source,
        summary: top.summary.clone(),
        cells: combo.set.trays.iter().map(|t| (t.name.clone(), t.cell.clone())).collect(),
        per_tray: top.per_tray.clone(),
        tied_candidates: tied,
    })
}

/// The recommended placement's mounting tolerances, into `out/tolerance/METHOD/` (a study
/// folder per method, so a later study that recommends the other method does not find a
/// folder of the first).
fn tolerance(out: &Path, r: &Recommendation, seed: u64, preset: &Preset) -> Result<ToleranceReport> {
    let dir = tolerance_dir(out, r.method);
    let request = ToleranceRequest {
        placement: r.placement,
        method: r.method,
        seed,
        scenarios: preset.tolerance_scenarios,
        margin: preset.tolerance_margin,
        corner_fraction: preset.tolerance_corner_fraction,
        parameters: preset.tolerance_parameters.clone(),
    };
    let report = measure_tolerance(&dir, r.cells.clone(), &request)?;
    write_tolerance_plots(&dir, &report)?;
    Ok(report)
}
