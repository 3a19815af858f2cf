//! The placement search run into a study folder: each evaluation's scenes go to the
//! folder's results file (so a re-run resumes), then `optimize.json`, `optimize.csv` and the
//! convergence plot (the paper's Figure 7).

use std::path::Path;

use camplace_config::write_atomic;
use camplace_config::{Cell, Placement};

use super::optimize::{search_placement, SearchOutcome, SearchPlan};
use super::sweep::load_sweep;
use super::tray_set::{lowest, ranked_rate, TraySet};
use crate::render::Method;
use crate::report::convergence::{Convergence, Curve};
use crate::report::table::{write_summary_csv, SummaryRow};
use crate::{Error, Result};
use camplace_plot::save_plot;

/// Runs the search into `dir`: optimize.json, optimize.csv and the convergence plot.
pub fn optimize(
    dir: &Path,
    cell: &Cell,
    base: &Placement,
    method: Method,
    seed: u64,
    plan: &SearchPlan,
    label: &str,
) -> Result<SearchOutcome> {
    let set = TraySet::open(vec![(cell.tray_folder_name(), cell.clone(), dir.to_path_buf())], method, seed)?;
    optimize_set(dir, &set, base, seed, plan, label)
}

/// Runs the search for one placement serving every tray of `set` (each placement's
/// success is its lowest over the trays) and writes its outputs into `dir`.
pub fn optimize_set(
    dir: &Path,
    set: &TraySet,
    base: &Placement,
    seed: u64,
    plan: &SearchPlan,
    label: &str,
) -> Result<SearchOutcome> {
    let method = set.method;
    let mut step = 0;
    let outcome = search_placement(base, plan, seed, |p, s, n| {
        step += 1;
        Ok(lowest(&set.evaluate(p, s, n, &format!("{label} {step}/{}", plan.budget))?))
    })?;
    std::fs::create_dir_all(dir)
        .map_err(|e| Error::Other(format!("{}: cannot create the folder: {e}", dir.display())))?;
    let text = serde_json::to_string_pretty(&(plan, &outcome)).expect("plain data");
    write_atomic(&dir.join("optimize.json"), text.as_bytes())?;
    let rows: Vec<SummaryRow> = outcome
        .history
        .iter()
        .map(|e| SummaryRow {
            placement: e.placement.clone(),
            method: method.to_string(),
            seed,
            summary: e.summary.clone(),
        })
        .collect();
    write_summary_csv(&dir.join("optimize.csv"), &rows)?;
    let curve = Curve {
        label: format!("{method}"),
        rates: outcome.history.iter().map(|e| ranked_rate(&e.summary)).collect(),
        sweep_best: sweep_best(set, seed)?,
    };
    let plot = Convergence { title: format!("search over {} parameters", plan.parameters.len()), curves: vec![curve] };
    save_plot(&plot, dir, "convergence")?;
    Ok(outcome)
}

/// The best success rate, lowest over the trays, of the sweep held in the trays' folders,
/// if every tray has it complete.
pub fn sweep_best(set: &TraySet, seed: u64) -> Result<Option<f64>> {
    let Some(first) = set.trays.first() else { return Ok(None) };
    let Some((grid, n, base)) = load_sweep(&first.dir)? else { return Ok(None) };
    let mut best: Option<f64> = None;
    for p in grid.placements(&base)? {
        let summaries = set.stored(&p, seed, n);
        if summaries.iter().any(|s| s.frames as u64 != n) {
            return Ok(None);
        }
        let rate = ranked_rate(&lowest(&summaries));
        best = Some(best.map_or(rate, |b: f64| b.max(rate)));
    }
    Ok(best)
}
