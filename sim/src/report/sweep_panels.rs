//! A sweep's outputs from its results: `summary.csv` and `summary.json` (one row per grid
//! placement) and, once every cell is complete, the four panels of the paper's Figure 5
//! (success rate, correct matches, position error, rotation error) with the best cell
//! ringed: success on a fixed 0–100 % scale, the others over their own range.

use std::path::Path;

use camplace_config::{Cell, Placement};

use super::heatmap::{ColourScale, HeatMap};
use super::table::{write_summary_csv, write_summary_json, SummaryRow};
use crate::render::Method;
use crate::study::results::ResultsStore;
use crate::study::tray_set::ranked_rate;
use crate::Result;
use camplace_config::Grid;
use camplace_estimator::scoring::Summary;
use camplace_plot::save_plot;

/// What a sweep measured.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepResult {
    /// One row per grid placement, x fastest.
    pub rows: Vec<SummaryRow>,
    /// Whether every cell has all its scenes.
    pub complete: bool,
    /// The cell of the highest ranked rate (verified success; first on ties), among cells
    /// with scenes.
    pub best: Option<usize>,
}

/// Sums up the grid's cells from `store` and writes the summaries and (when complete) the
/// panels into `dir`.
#[allow(clippy::too_many_arguments)]
pub fn write_sweep_outputs(
    dir: &Path,
    cell: &Cell,
    grid: &Grid,
    placements: &[Placement],
    store: &ResultsStore,
    method: Method,
    seed: u64,
    scenarios: u64,
) -> Result<SweepResult> {
    let rows: Vec<SummaryRow> = placements
        .iter()
        .map(|p| SummaryRow {
            placement: p.to_string(),
            method: method.to_string(),
            seed,
            summary: {
                let records = store.records(p, method, seed, scenarios);
                Summary::from_records(&records).verified(&records, cell.estimator.verify_max_wrong, &cell.metrics)
            },
        })
        .collect();
    let complete = rows.iter().all(|r| r.summary.frames as u64 == scenarios);
    let mut best: Option<usize> = None;
    for (i, r) in rows.iter().enumerate() {
        if r.summary.scored > 0 && best.is_none_or(|b| ranked_rate(&r.summary) > ranked_rate(&rows[b].summary)) {
            best = Some(i);
        }
    }
    write_summary_csv(&dir.join("summary.csv"), &rows)?;
    write_summary_json(&dir.join("summary.json"), &rows)?;
    if complete {
        // Success on one fixed scale on every map, so a colour reads as the same rate.
        let success = ColourScale::Fixed { lo: 0.0, hi: 100.0 };
        let panel =
            |title: &str, decimals: usize, scale: ColourScale, pick: &dyn Fn(&Summary) -> Option<f64>| HeatMap {
                title: format!("{title} ({method})"),
                x_label: grid.x.name.label(),
                y_label: grid.y.name.label(),
                xs: grid.x.values(),
                ys: grid.y.values(),
                values: rows.iter().map(|r| pick(&r.summary)).collect(),
                best,
                decimals,
                scale,
            };
        let panels = [
            ("success_rate", panel("success rate, %", 0, success, &|s| Some(100.0 * s.success_rate))),
            ("correct_matches", panel("mean correct matches", 0, ColourScale::Range, &|s| s.mean_correct_matches)),
            ("position_error", panel("mean position error, mm", 1, ColourScale::Range, &|s| s.mean_position_error_mm)),
            (
                "rotation_error",
                panel("mean rotation error, deg", 1, ColourScale::Range, &|s| s.mean_rotation_error_deg),
            ),
        ];
        for (name, p) in &panels {
            save_plot(p, dir, name)?;
        }
    }
    Ok(SweepResult { rows, complete, best })
}
