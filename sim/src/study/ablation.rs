//! What each effect of the simulation costs: the success rate at a few placements with every
//! effect on, and with each active effect switched off in turn, on the same scenarios (so
//! each comparison is paired scene by scene). Each variant's scenes go to a study folder of
//! their own (the variant is another cell, with another hash), resumable like any other.

use std::path::Path;

use camplace_config::{Cell, Effect, Placement};

use super::findings::{compare_paired, Paired, Rate};
use super::one_placement::evaluate_placement;
use super::shard::Shard;
use crate::render::Method;
use crate::Result;
use camplace_estimator::scoring::Summary;

/// One variant at one placement.
#[derive(Debug, Clone)]
pub struct AblationRow {
    /// The placement's label ("recommended", "weak") and the placement.
    pub label: String,
    pub placement: Placement,
    /// The effect switched off, `None` for every effect on.
    pub off: Option<Effect>,
    pub summary: Summary,
    /// Against every effect on at this placement: the paired comparison's text (none for
    /// the all-on row).
    pub against_all_on: Option<String>,
}

/// Runs the ablation at each labelled placement into `dir`: `all-on/` and `no-<effect>/`
/// folders, `scenarios` scenes each.
pub fn ablate(
    dir: &Path,
    cell: &Cell,
    placements: &[(String, Placement)],
    method: Method,
    seed: u64,
    scenarios: u64,
) -> Result<Vec<AblationRow>> {
    let mut variants: Vec<Option<Effect>> = vec![None];
    variants.extend(Effect::ALL.into_iter().filter(|&e| cell.effect_active(e)).map(Some));
    let mut rows = Vec::new();
    for (label, placement) in placements {
        let mut all_on: Option<Vec<Option<bool>>> = None;
        for &off in &variants {
            let mut variant = cell.clone();
            if let Some(e) = off {
                variant.effects.set(e, false);
            }
            let folder = dir.join(off.map_or("all-on".to_string(), |e| format!("no-{}", e.key())));
            evaluate_placement(&folder, &variant, placement, method, seed, scenarios, Shard::WHOLE)?;
            let store = super::folder::open_folder(&folder, &variant, method, seed)?;
            let records = store.records(placement, method, seed, scenarios);
            let outcomes: Vec<Option<bool>> = records.iter().map(|r| r.score.as_ref().map(|s| s.success)).collect();
            let summary = Summary::from_records(&records);
            let against_all_on = match (&all_on, off) {
                (Some(base), Some(e)) => {
                    let pair = Paired::from_outcomes(&outcomes, base);
                    Some(compare_paired(&format!("{} off", e.key()), "every effect on", pair).1)
                }
                _ => None,
            };
            if off.is_none() {
                all_on = Some(outcomes);
            }
            rows.push(AblationRow { label: label.clone(), placement: *placement, off, summary, against_all_on });
        }
    }
    Ok(rows)
}

/// The ablation as a Markdown table (one row per variant, one column per placement) and the
/// paired comparisons under it.
pub fn ablation_markdown(rows: &[AblationRow]) -> String {
    let mut labels: Vec<(&str, Placement)> = Vec::new();
    for r in rows {
        if !labels.iter().any(|(l, _)| *l == r.label) {
            labels.push((&r.label, r.placement));
        }
    }
    let mut variants: Vec<Option<Effect>> = Vec::new();
    for r in rows {
        if !variants.contains(&r.off) {
            variants.push(r.off);
        }
    }
    let mut out = String::from("| effects |");
    for (l, p) in &labels {
        out += &format!(" {l} ({p}) |");
    }
    out += "\n|---|";
    out += &"---|".repeat(labels.len());
    out += "\n";
    for v in &variants {
        out += &format!("| {} |", v.map_or("all on".to_string(), |e| format!("{} off", e.key())));
        for (l, _) in &labels {
            let cell = rows.iter().find(|r| r.label == *l && r.off == *v).map_or(String::from("—"), |r| {
                Rate { successes: r.summary.successes, scenes: r.summary.scored }.text()
            });
            out += &format!(" {cell} |");
        }
        out += "\n";
    }
    out += "\nPaired against every effect on, at the same placement and on the same scenes:\n\n";
    for r in rows {
        if let Some(text) = &r.against_all_on {
            out += &format!("- {}: {text}\n", r.label);
        }
    }
    out
}
