//! The placement search run into a study folder: each evaluation's scenes go to the
//! folder's results file (so a re-run resumes), then `optimize.json`, `optimize.csv` and the
//! convergence plot (the paper's Figure 7).

use std::path::Path;

use camplace_config::write_atomic;
use camplace_config::{Cell, Placement};

use super::folder::open_folder;
use super::jobs::{JobEvaluator, PlacementJob};
use super::optimize::{search_placement, SearchOutcome, SearchPlan};
use super::results::ResultsStore;
use super::summary::Summary;
use super::sweep::load_sweep;
use crate::render::Method;
use crate::report::convergence::{Convergence, Curve};
use crate::report::save_plot;
use crate::report::table::{write_summary_csv, SummaryRow};
use crate::Result;

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
    let store = open_folder(dir, cell, method, seed)?;
    let runner = JobEvaluator::new(cell, method, &store);
    let mut step = 0;
    let outcome = search_placement(base, plan, seed, |p, s, n| {
        step += 1;
        let job = PlacementJob { placement: *p, seed: s, scenarios: (0..n).collect() };
        runner.evaluate(&[job], &format!("{label} {step}/{}", plan.budget))?;
        Ok(Summary::from_records(&store.records(p, method, s, n)))
    })?;
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
        rates: outcome.history.iter().map(|e| e.summary.success_rate).collect(),
        sweep_best: sweep_best(dir, &store, method, seed)?,
    };
    let plot = Convergence { title: format!("search over {} parameters", plan.parameters.len()), curves: vec![curve] };
    save_plot(&plot, dir, "convergence")?;
    Ok(outcome)
}

/// The best success rate of the sweep held in `dir`, if one is there and complete.
pub fn sweep_best(dir: &Path, store: &ResultsStore, method: Method, seed: u64) -> Result<Option<f64>> {
    let Some((grid, n, base)) = load_sweep(dir)? else { return Ok(None) };
    let mut best: Option<f64> = None;
    for p in grid.placements(&base)? {
        let records = store.records(&p, method, seed, n);
        if records.len() as u64 != n {
            return Ok(None);
        }
        let rate = Summary::from_records(&records).success_rate;
        best = Some(best.map_or(rate, |b: f64| b.max(rate)));
    }
    Ok(best)
}
