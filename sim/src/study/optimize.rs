//! The placement search (docs/design/placement-study.md) over the study's parameters: the RBF surrogate
//! optimizer asks for placements, each is evaluated on the same scenarios (its success rate
//! negated is the objective), the winner is chosen by the smoothed surrogate, and the top
//! candidates are evaluated again on fresh scenarios (the next seed) to pick the placement
//! reported. Evaluating is the caller's closure, so a resumed search reads finished scenes
//! from the results file and the optimizer, being deterministic in its told history, asks
//! the same placements again.

use std::str::FromStr;

use camplace_config::{Placement, PlacementParam};
use serde::{Deserialize, Serialize};

use super::tray_set::ranked_rate;
use crate::search::{RbfOptimizer, RbfSettings};
use crate::Result;
use camplace_estimator::scoring::Summary;

/// One parameter searched, with its box.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SearchParameter {
    /// One of r, alpha, baseline, vergence.
    pub name: PlacementParam,
    /// Lower bound.
    pub lo: f64,
    /// Upper bound.
    pub hi: f64,
}

impl SearchParameter {
    /// The default box of a parameter ([`PlacementParam::bounds`]); none for the azimuth.
    pub fn default_for(name: PlacementParam) -> Option<SearchParameter> {
        let (lo, hi) = name.bounds()?;
        Some(SearchParameter { name, lo, hi })
    }

    /// The value rounded to what a placement is written with: 0.1 mm or 0.01°.
    fn round(&self, v: f64) -> f64 {
        let step = self.name.step();
        ((v / step).round() * step * 1e6).round() / 1e6
    }
}

impl FromStr for SearchParameter {
    type Err = String;

    /// `name` (its default box) or `name=lo:hi`.
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        let bad = || {
            format!(
                "expected one of {} optionally with =lo:hi (e.g. baseline=40:200), got \"{s}\"",
                camplace_config::studied_names()
            )
        };
        let (name, range) = match s.split_once('=') {
            Some((n, r)) => (n.trim(), Some(r)),
            None => (s.trim(), None),
        };
        let mut p = PlacementParam::from_name(name).and_then(SearchParameter::default_for).ok_or_else(bad)?;
        if let Some(range) = range {
            let (lo, hi) = range.split_once(':').ok_or_else(bad)?;
            p.lo = lo.trim().parse().map_err(|_| bad())?;
            p.hi = hi.trim().parse().map_err(|_| bad())?;
            if !(p.lo.is_finite() && p.hi.is_finite() && p.lo < p.hi) {
                return Err(bad());
            }
        }
        Ok(p)
    }
}

/// How the search runs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SearchPlan {
    /// The parameters searched; the others keep the base placement's values.
    pub parameters: Vec<SearchParameter>,
    /// Evaluations (placements) the search may spend.
    pub budget: usize,
    /// Scenarios per evaluation.
    pub scenarios: u64,
    /// Seed of the optimizer's own random choices.
    pub optimizer_seed: u64,
    /// Candidates evaluated again on fresh scenarios.
    pub top: usize,
    /// Scenarios of each re-evaluation (drawn with the study seed + 1).
    pub recheck_scenarios: u64,
}

/// One evaluated placement.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Evaluation {
    /// The placement evaluated.
    pub placement: String,
    /// Its summary over the scenarios.
    pub summary: Summary,
}

/// What a search found.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SearchOutcome {
    /// Every evaluation, in order.
    pub history: Vec<Evaluation>,
    /// The evaluated placement the smoothed surrogate rates best, and its smoothed rate.
    pub surrogate_winner: String,
    pub surrogate_success_rate: f64,
    /// The top candidates evaluated on fresh scenarios, best first.
    pub rechecks: Vec<Evaluation>,
}

impl SearchOutcome {
    /// The placement reported: the best re-evaluated one.
    pub fn best(&self) -> &Evaluation {
        &self.rechecks[0]
    }
}

/// The seed fresh scenarios are drawn with for re-evaluation.
pub fn recheck_seed(study_seed: u64) -> u64 {
    study_seed.wrapping_add(1)
}

/// Runs the search from `base`; `evaluate(placement, seed, scenarios)` gives a placement's
/// summary.
pub fn search_placement(
    base: &Placement,
    plan: &SearchPlan,
    study_seed: u64,
    mut evaluate: impl FnMut(&Placement, u64, u64) -> Result<Summary>,
) -> Result<SearchOutcome> {
    let bounds: Vec<(f64, f64)> = plan.parameters.iter().map(|p| (p.lo, p.hi)).collect();
    // Binomial noise shrinks with the scenario count; 0.01 suits 250 scenarios.
    let smoothing = (0.01 * 250.0 / plan.scenarios.max(1) as f64).clamp(0.01, 0.1);
    let settings = RbfSettings { noise_smoothing: smoothing, ..RbfSettings::default() };
    let mut opt = RbfOptimizer::new(bounds, settings, plan.optimizer_seed);
    let placement_of = |x: &[f64]| -> Result<Placement> {
        let mut p = *base;
        for (param, &v) in plan.parameters.iter().zip(x) {
            p = param.name.set(&p, param.round(v));
        }
        p.validate("placement")?;
        Ok(p)
    };
    let mut history = Vec::with_capacity(plan.budget);
    for _ in 0..plan.budget {
        let x = opt.ask();
        let p = placement_of(&x)?;
        let summary = evaluate(&p, study_seed, plan.scenarios)?;
        opt.tell(&x, -ranked_rate(&summary));
        history.push(Evaluation { placement: p.to_string(), summary });
    }
    let (wx, wv) = opt.best_by_surrogate().expect("the budget is at least one evaluation");
    let surrogate_winner = placement_of(&wx)?;
    let mut rechecks = Vec::new();
    for x in opt.top_candidates(plan.top.max(1)) {
        let p = placement_of(&x)?;
        if rechecks.iter().any(|e: &Evaluation| e.placement == p.to_string()) {
            continue;
        }
        let summary = evaluate(&p, recheck_seed(study_seed), plan.recheck_scenarios)?;
        rechecks.push(Evaluation { placement: p.to_string(), summary });
    }
    // Best ranked rate first; the surrogate's order (the order evaluated) breaks ties.
    rechecks.sort_by(|a, b| ranked_rate(&b.summary).total_cmp(&ranked_rate(&a.summary)));
    Ok(SearchOutcome { history, surrogate_winner: surrogate_winner.to_string(), surrogate_success_rate: -wv, rechecks })
}
