//! The placement study: the paper's experiment on the cell — both built-in trays × both
//! methods, each a 2-parameter sweep then a 4-parameter search — into one folder, ending
//! with a self-contained `report.html` that states what was measured against the paper's
//! findings. The folder is `TRAY/METHOD/` per combination; re-running resumes.

use std::path::{Path, PathBuf};
use std::time::Instant;

use camplace_config::{Cell, TrayKind};

use super::folder::open_folder;
use super::grid::{Axis, Grid};
use super::jobs::{JobEvaluator, PlacementJob};
use super::optimize::{recheck_seed, SearchOutcome, SearchParameter, SearchPlan};
use super::placement_search::optimize;
use super::shard::Shard;
use super::summary::Summary;
use super::sweep::sweep;
use crate::render::Method;
use crate::report::study_report::{pct, write_report};
use crate::report::sweep_panels::SweepResult;
use crate::Result;

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
    /// Evaluations the search may spend.
    pub budget: usize,
    /// Scenes per search evaluation.
    pub search_scenarios: u64,
    /// Search candidates re-checked on fresh scenes.
    pub top: usize,
    /// Fresh scenes of a re-check.
    pub recheck_scenarios: u64,
}

impl Preset {
    /// The default: the paper's 5 × 5 grid and 4-parameter search, scaled to finish on a
    /// 2-core machine in hours rather than days (the paper used 250 scenes and 100 steps).
    pub fn full() -> Preset {
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

    /// A small preset for a first look (3 × 3 grid, few scenes, short search).
    pub fn quick() -> Preset {
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
pub struct Combination {
    /// The tray's name.
    pub tray: &'static str,
    /// The method.
    pub method: Method,
    /// The cell with this tray.
    pub cell: Cell,
    /// The 2-parameter sweep.
    pub sweep: SweepResult,
    /// The 4-parameter search.
    pub search: SearchOutcome,
    /// The sweep's best cell on the fresh scenarios the search's candidates were rechecked on.
    pub sweep_best_recheck: Option<Summary>,
}

/// Runs the study into `out`: every (tray, method) combination's sweep (only shard
/// `shard`'s part of each when it is not the whole), then its search and re-checks, and
/// `report.html`. `say` is handed one line per finished combination; returns the report's
/// path, or `None` when only a shard of the sweeps was run.
pub fn run_study(
    out: &Path,
    base_cell: &Cell,
    seed: u64,
    preset: &Preset,
    shard: Shard,
    started: Instant,
    mut say: impl FnMut(&str),
) -> Result<Option<PathBuf>> {
    let grid = Grid { x: preset.x.clone(), y: preset.y.clone() };
    // report.html is written here; each combination's folder is cleaned as it is opened.
    camplace_config::remove_stale_temp_files(out)?;
    let mut combos = Vec::new();
    for (tray, kind) in [("tray-8", TrayKind::Tray8), ("tray-4", TrayKind::Tray4)] {
        for method in [Method::OneShot, Method::Phase12] {
            let mut cell = base_cell.clone();
            cell.tray.kind = kind;
            let dir = out.join(tray).join(method.to_string());
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
            say(&format!(
                "{tray} {method}: sweep best {}; search best {}",
                sweep.best.map_or("n/a".into(), |b| format!(
                    "{} at {}",
                    pct(sweep.rows[b].summary.success_rate),
                    sweep.rows[b].placement
                )),
                format_args!("{} at {}", pct(search.best().summary.success_rate), search.best().placement)
            ));
            combos.push(Combination { tray, method, cell, sweep, search, sweep_best_recheck });
        }
    }
    if !shard.is_whole() {
        return Ok(None);
    }
    let report = write_report(out, preset, seed, base_cell, &grid, &combos, started)?;
    Ok(Some(report))
}

/// Evaluates `placement` on the fresh scenarios of the search's re-check.
fn recheck(dir: &Path, cell: &Cell, method: Method, seed: u64, placement: &str, n: u64) -> Result<Summary> {
    let p = cell.placement.with_overrides(placement)?;
    let store = open_folder(dir, cell, method, seed)?;
    let s = recheck_seed(seed);
    JobEvaluator::new(cell, method, &store)
        .evaluate(&[PlacementJob { placement: p, seed: s, scenarios: (0..n).collect() }], "re-check")?;
    Ok(Summary::from_records(&store.records(&p, method, s, n)))
}
