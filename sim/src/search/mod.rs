//! The placement search (docs/design/placement-study.md): a radial-basis-function surrogate optimizer in the
//! spirit of RBFopt (Costa & Nannicini 2018) and Regis & Shoemaker's stochastic RBF method.
//! It minimises over a box through an ask/tell interface; it never calls the objective.
//!
//! The method, on the box scaled to [0,1]^d:
//! - a space-filling start: the box centre plus a maximin Latin hypercube, d + 1 points
//!   in all (at least 6, at most 2(d + 1)) for an exact objective, 2(d + 1) for a noisy
//!   one;
//! - a cubic surrogate with a linear tail (`rbf`), optionally smoothed for noisy values.
//!   Values are log-scaled when a few huge values would otherwise swamp the interesting
//!   low region (as RBFopt does), and optionally clipped at their median;
//! - steps cycling from exploration to exploitation (`SearchStep`). By default two CORS
//!   steps (least surrogate value at least 0.75 then 0.25 of the reachable distance away
//!   from the data), two Regis–Shoemaker steps (w·surrogate + (1 − w)·closeness with
//!   w = 0.8, 0.95) and a trust-region step. Candidates are drawn around the incumbent
//!   (Gaussian, sd = the trust radius, a few coordinates at a time as in DYCORS) and
//!   uniformly over the box. The trust-region step minimises the surrogate within the trust
//!   radius of the incumbent, and is taken again right after every improvement;
//! - the trust radius doubles after a streak of improvements and halves after a streak of
//!   failures, and starts again from its initial size once it falls below its minimum;
//! - after 30 evaluations without a 1 % gain the search restarts with a fresh design and
//!   a surrogate of the new points only (RBFopt's remedy for a local minimum); the best
//!   point and the surrogate winner still range over everything told.
//!
//! For a noisy objective set `noise_smoothing` (0.01 suits success rates at 250 scenarios
//! in [−1, 0]), pick the winner with `best_by_surrogate` and re-evaluate
//! `top_candidates` on fresh scenarios.
//!
//! Everything the next `ask` does is a function of the seed, the told history in order
//! and the points asked but not yet told, so a study that replays its results file through
//! `tell` resumes exactly where it stopped.

pub mod design;
pub mod rbf;
pub mod test_functions;

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::seeds::search_step_seed;

use rbf::{distance, Surrogate};

/// Settings of the surrogate search; `Default` suits a smooth, noise-free objective.
#[derive(Debug, Clone, PartialEq)]
pub struct RbfSettings {
    /// λ added to the kernel diagonal: 0 interpolates; > 0 smooths a noisy objective
    /// (0.01 for success rates at 250 scenarios; the effect does not depend on the scale
    /// of the values, only on the spacing of the points in the unit box).
    pub noise_smoothing: f64,
    /// Size of the space-filling start; 0 picks it from the dimension d.
    ///
    /// For an exact objective: d + 1, the fewest points that fix the linear tail (RBFopt's
    /// size), so the surrogate starts steering sooner and a restart costs less; but at
    /// least 6 (never more than 2(d + 1)), so that in two to four dimensions the first
    /// surrogate has some curvature to go on rather than little more than a plane.
    /// With `noise_smoothing`: 2(d + 1) (Regis–Shoemaker's), as a smoothed fit needs more
    /// points before it can tell the trend from the noise. When the start holds only d + 1
    /// points, the step after it, before a surrogate can be fitted, is the point farthest
    /// from them.
    pub initial_points: usize,
    /// Latin hypercubes tried for the maximin start.
    pub design_tries: usize,
    /// The steps after the start design, repeated in order, exploration first.
    pub cycle: Vec<SearchStep>,
    /// Random candidates scored per step, per dimension.
    pub candidates_per_dim: usize,
    /// Chance that a candidate drawn around the incumbent moves a given coordinate (at
    /// least one always moves): below 1 it probes along few axes at a time (DYCORS).
    pub perturbation_probability: f64,
    /// Clip values above their median to the median before fitting (Regis–Shoemaker).
    pub clip_at_median: bool,
    /// Take a trust-region step right after a point that improved the incumbent.
    pub refine_after_improvement: bool,
    /// Start afresh (a new space-filling design, a surrogate of the new points only) after
    /// this many evaluations without a 1 % gain, as RBFopt does; 0 never restarts.
    /// Stuck in a local minimum, more of the same rarely helps.
    pub restart_after_stall: usize,
    /// Least distance between two asked points in the unit box.
    pub min_distance: f64,
    /// Trust radius at the start, in the unit box.
    pub trust_radius_init: f64,
    /// Below this the trust radius starts again from `trust_radius_init`.
    pub trust_radius_min: f64,
    /// The trust radius never grows beyond this.
    pub trust_radius_max: f64,
    /// Improvements in a row that double the trust radius.
    pub success_streak: usize,
    /// Failures in a row that halve the trust radius; 0 means max(5, d).
    pub failure_streak: usize,
}

impl Default for RbfSettings {
    fn default() -> Self {
        RbfSettings {
            noise_smoothing: 0.0,
            initial_points: 0,
            design_tries: 20,
            cycle: vec![
                SearchStep::Spaced(0.75),
                SearchStep::Spaced(0.25),
                SearchStep::Weighted(0.8),
                SearchStep::Weighted(0.95),
                SearchStep::TrustRegion,
            ],
            candidates_per_dim: 200,
            perturbation_probability: 0.3,
            clip_at_median: false,
            refine_after_improvement: true,
            restart_after_stall: 30,
            min_distance: 1e-4,
            trust_radius_init: 0.2,
            trust_radius_min: 0.2 * 0.5f64.powi(6),
            trust_radius_max: 0.4,
            success_streak: 3,
            failure_streak: 0,
        }
    }
}

/// One kind of step of the search cycle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SearchStep {
    /// Regis–Shoemaker: the candidate of least w·surrogate + (1 − w)·closeness to
    /// evaluated points (w in [0, 1]; larger exploits more).
    Weighted(f64),
    /// Regis–Shoemaker's CORS: the candidate of least surrogate value among those at least
    /// β·Δ from every evaluated point, Δ being the largest such distance of any candidate
    /// (β in [0, 1]; smaller exploits more). Unlike `Weighted` it does not favour corners.
    Spaced(f64),
    /// The surrogate's minimum within the trust radius of the incumbent.
    TrustRegion,
}

/// The surrogate fitted to the told values, with the value transform it was fitted under.
#[derive(Debug, Clone)]
struct Fit {
    surrogate: Surrogate,
    /// `Some(ymin)` when values were fitted as ln(1 + y − ymin).
    log_from: Option<f64>,
    /// The told indices it was fitted to: `from..told`.
    from: usize,
    told: usize,
}

impl Fit {
    /// A surrogate value back in the objective's units.
    fn to_objective(&self, v: f64) -> f64 {
        match self.log_from {
            Some(ymin) => ymin + v.exp() - 1.0,
            None => v,
        }
    }
}

/// A minimiser over a box by radial-basis-function surrogate, driven by ask and tell.
#[derive(Debug, Clone)]
pub struct RbfOptimizer {
    lower: Vec<f64>,
    width: Vec<f64>,
    settings: RbfSettings,
    seed: u64,
    /// The space-filling start, in the unit box.
    design: Vec<Vec<f64>>,
    /// Told points in the unit box, and as told.
    told_unit: Vec<Vec<f64>>,
    told_raw: Vec<Vec<f64>>,
    told_values: Vec<f64>,
    /// Asked and not yet told, in the unit box.
    pending_unit: Vec<Vec<f64>>,
    trust_radius: f64,
    /// Whether the last told value improved on the best before it.
    last_improved: bool,
    /// Restarts so far; the current restart's first told index, best value and the index
    /// of its last clear gain.
    epoch: u64,
    epoch_start: usize,
    epoch_best: f64,
    last_gain: usize,
    successes: usize,
    failures: usize,
    fit: Option<Fit>,
}

impl RbfOptimizer {
    /// An optimizer over the box `bounds` (lower, upper per parameter), deterministic for
    /// `seed`.
    ///
    /// # Panics
    /// If `bounds` is empty or some lower bound is not finite and below its upper bound:
    /// a fixed parameter belongs outside the search.
    pub fn new(bounds: Vec<(f64, f64)>, settings: RbfSettings, seed: u64) -> RbfOptimizer {
        assert!(!bounds.is_empty(), "the search box needs at least one parameter");
        for &(lo, hi) in &bounds {
            assert!(
                lo.is_finite() && hi.is_finite() && lo < hi,
                "search bounds must be finite with lower < upper, got ({lo}, {hi})"
            );
        }
        let dim = bounds.len();
        let n0 = match settings.initial_points {
            0 if settings.noise_smoothing > 0.0 => 2 * (dim + 1),
            0 => (dim + 1).max(6).min(2 * (dim + 1)),
            n => n,
        };
        let mut rng = ChaCha8Rng::seed_from_u64(search_step_seed(seed, u64::MAX));
        let design = design::latin_hypercube_with_centre(n0, dim, settings.design_tries, &mut rng);
        RbfOptimizer {
            lower: bounds.iter().map(|b| b.0).collect(),
            width: bounds.iter().map(|b| b.1 - b.0).collect(),
            trust_radius: settings.trust_radius_init,
            settings,
            seed,
            design,
            told_unit: Vec::new(),
            told_raw: Vec::new(),
            told_values: Vec::new(),
            pending_unit: Vec::new(),
            last_improved: false,
            epoch: 0,
            epoch_start: 0,
            epoch_best: f64::INFINITY,
            last_gain: 0,
            successes: 0,
            failures: 0,
            fit: None,
        }
    }

    /// The number of parameters.
    pub fn dim(&self) -> usize {
        self.lower.len()
    }

    /// The next point to evaluate; it stays pending until told.
    pub fn ask(&mut self) -> Vec<f64> {
        let u = self.next_unit_point();
        let x = self.to_raw(&u);
        self.pending_unit.push(u);
        x
    }

    /// `n` distinct points to evaluate in parallel; they stay pending until told.
    #[cfg(test)]
    pub fn ask_batch(&mut self, n: usize) -> Vec<Vec<f64>> {
        (0..n).map(|_| self.ask()).collect()
    }

    /// Records the objective `y` at `x` (a point from `ask` or any point of the box).
    /// A value that is not finite counts as the worst value seen.
    ///
    /// # Panics
    /// If `x` has the wrong number of coordinates.
    pub fn tell(&mut self, x: &[f64], y: f64) {
        assert_eq!(x.len(), self.dim(), "told point has the wrong dimension");
        let u = self.to_unit(x);
        if let Some(i) = self.pending_unit.iter().position(|p| p.iter().zip(&u).all(|(a, b)| (a - b).abs() <= 1e-12)) {
            self.pending_unit.remove(i);
        }
        if self.told_values.len() - self.epoch_start >= self.design.len() {
            self.update_trust_region(y);
        }
        self.told_unit.push(u);
        self.told_raw.push(x.to_vec());
        self.told_values.push(y);
        self.watch_for_stall(y);
    }

    /// The best value told so far and where.
    pub fn best_observed(&self) -> Option<(Vec<f64>, f64)> {
        let i = argmin(&self.clean_values())?;
        Some((self.told_raw[i].clone(), self.told_values[i]))
    }

    /// The evaluated point where the (smoothed) surrogate is lowest, with the surrogate's
    /// value there: the winner for a noisy objective. Equal to `best_observed` for an
    /// interpolating surrogate; `best_observed` stands in while no surrogate can be fitted.
    pub fn best_by_surrogate(&self) -> Option<(Vec<f64>, f64)> {
        let fit = match &self.fit {
            Some(f) if f.told == self.told_values.len() && f.from == 0 => f.clone(),
            _ => match self.fit_surrogate(0) {
                Some(f) => f,
                None => return self.best_observed(),
            },
        };
        let order = self.by_surrogate(&fit);
        let &(i, v) = order.first()?;
        Some((self.told_raw[i].clone(), fit.to_objective(v)))
    }

    /// Up to `n` evaluated points, lowest surrogate value first, no two closer than the
    /// minimum distance: the ones worth re-evaluating on fresh scenarios.
    pub fn top_candidates(&self, n: usize) -> Vec<Vec<f64>> {
        let order: Vec<usize> = match self.fit_surrogate(0) {
            Some(fit) => self.by_surrogate(&fit).into_iter().map(|(i, _)| i).collect(),
            None => {
                let y = self.clean_values();
                let mut idx: Vec<usize> = (0..y.len()).collect();
                idx.sort_by(|&a, &b| y[a].total_cmp(&y[b]));
                idx
            }
        };
        let mut picked: Vec<usize> = Vec::new();
        for i in order {
            if picked.len() == n {
                break;
            }
            let u = &self.told_unit[i];
            if picked.iter().all(|&j| distance(u, &self.told_unit[j]) >= self.settings.min_distance) {
                picked.push(i);
            }
        }
        picked.into_iter().map(|i| self.told_raw[i].clone()).collect()
    }

    /// Evaluated indices with their surrogate values, lowest first.
    fn by_surrogate(&self, fit: &Fit) -> Vec<(usize, f64)> {
        let mut v: Vec<(usize, f64)> =
            (fit.from..fit.told).map(|i| (i, fit.surrogate.value(&self.told_unit[i]))).collect();
        v.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
        v
    }

    fn to_unit(&self, x: &[f64]) -> Vec<f64> {
        x.iter().zip(&self.lower).zip(&self.width).map(|((v, lo), w)| (v - lo) / w).collect()
    }

    fn to_raw(&self, u: &[f64]) -> Vec<f64> {
        u.iter().zip(&self.lower).zip(&self.width).map(|((v, lo), w)| lo + v * w).collect()
    }

    /// Told values with every non-finite one replaced by the worst finite one.
    fn clean_values(&self) -> Vec<f64> {
        let worst = self.told_values.iter().filter(|v| v.is_finite()).fold(f64::NEG_INFINITY, |a, &b| a.max(b));
        let worst = if worst.is_finite() { worst } else { 0.0 };
        self.told_values.iter().map(|&v| if v.is_finite() { v } else { worst }).collect()
    }

    fn failure_streak(&self) -> usize {
        if self.settings.failure_streak == 0 {
            self.dim().max(5)
        } else {
            self.settings.failure_streak
        }
    }

    /// Counts evaluations since the last 1 % gain of this restart's best, and restarts
    /// when there have been too many.
    fn watch_for_stall(&mut self, y: f64) {
        let n = self.told_values.len();
        if y.is_finite() && y < self.epoch_best - 0.01 * self.epoch_best.abs() {
            self.last_gain = n;
        }
        if y.is_finite() {
            self.epoch_best = self.epoch_best.min(y);
        }
        let limit = self.settings.restart_after_stall;
        if limit == 0 || n - self.epoch_start < self.design.len() + limit || n - self.last_gain < limit {
            return;
        }
        self.epoch += 1;
        self.epoch_start = n;
        self.epoch_best = f64::INFINITY;
        self.last_gain = n;
        self.trust_radius = self.settings.trust_radius_init;
        self.successes = 0;
        self.failures = 0;
        self.last_improved = false;
        self.fit = None;
        let mut rng = ChaCha8Rng::seed_from_u64(search_step_seed(self.seed, u64::MAX - self.epoch));
        self.design =
            design::latin_hypercube_with_centre(self.design.len(), self.dim(), self.settings.design_tries, &mut rng);
        // The box centre comes round again; having been evaluated, `ask` skips it.
    }

    fn update_trust_region(&mut self, y: f64) {
        let best = self.clean_values()[self.epoch_start..].iter().copied().fold(f64::INFINITY, f64::min);
        let improved = y.is_finite() && y < best - 1e-3 * best.abs().max(1e-9);
        self.last_improved = improved;
        if improved {
            self.successes += 1;
            self.failures = 0;
        } else {
            self.failures += 1;
            self.successes = 0;
        }
        let s = &self.settings;
        if self.successes >= s.success_streak.max(1) {
            self.trust_radius = (2.0 * self.trust_radius).min(s.trust_radius_max);
            self.successes = 0;
        }
        if self.failures >= self.failure_streak() {
            self.trust_radius *= 0.5;
            if self.trust_radius < s.trust_radius_min {
                self.trust_radius = s.trust_radius_init;
            }
            self.failures = 0;
        }
    }

    /// Fits the surrogate to the told values, or `None` while too few points fix it.
    fn fit_surrogate(&self, from: usize) -> Option<Fit> {
        let d = self.dim();
        let n = self.told_values.len();
        if n < from + d + 2 {
            return None;
        }
        let mut y = self.clean_values().split_off(from);
        let ymin = y.iter().copied().fold(f64::INFINITY, f64::min);
        let ymax = y.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let mut log_from = None;
        // Log scaling when the spread above the median dwarfs the spread below it: a few
        // huge values (Goldstein–Price's corners) would otherwise bend the whole surface.
        if ymax - ymin > 50.0 * (camplace_estimator::scoring::median(&y).unwrap_or(0.0) - ymin).max(1e-300) {
            for v in &mut y {
                *v = (1.0 + *v - ymin).ln();
            }
            log_from = Some(ymin);
        }
        let med = camplace_estimator::scoring::median(&y).unwrap_or(0.0);
        if self.settings.clip_at_median {
            for v in &mut y {
                *v = v.min(med);
            }
        }
        let pts: Vec<f64> = self.told_unit[from..].iter().flatten().copied().collect();
        let surrogate = Surrogate::fit(&pts, d, &y, self.settings.noise_smoothing).ok()?;
        Some(Fit { surrogate, log_from, from, told: n })
    }

    /// The unit-box point the next `ask` hands out.
    fn next_unit_point(&mut self) -> Vec<f64> {
        for p in &self.design {
            if !self.is_taken(p, 1e-12) {
                return p.clone();
            }
        }
        let k = self.told_values.len() + self.pending_unit.len();
        let mut rng = ChaCha8Rng::seed_from_u64(search_step_seed(self.seed, k as u64));
        if self.fit.as_ref().map(|f| (f.from, f.told)) != Some((self.epoch_start, self.told_values.len())) {
            self.fit = self.fit_surrogate(self.epoch_start);
        }
        let Some(fit) = self.fit.clone() else {
            return self.weighted_step(None, 0.0, &mut rng);
        };
        let cycle = &self.settings.cycle;
        // After an improvement the incumbent's neighbourhood is worth another look at once,
        // which is what makes the local convergence quick.
        let refine = self.settings.refine_after_improvement && self.last_improved && self.pending_unit.is_empty();
        if cycle.is_empty() || refine {
            return self.trust_region_step(&fit, &mut rng);
        }
        match cycle[k.saturating_sub(self.epoch_start + self.design.len()) % cycle.len()] {
            SearchStep::Weighted(w) => self.weighted_step(Some(&fit), w, &mut rng),
            SearchStep::Spaced(beta) => self.spaced_step(&fit, beta, &mut rng),
            SearchStep::TrustRegion => self.trust_region_step(&fit, &mut rng),
        }
    }

    /// Whether a told or pending point lies within `tol` of `u`.
    fn is_taken(&self, u: &[f64], tol: f64) -> bool {
        self.told_unit.iter().chain(&self.pending_unit).any(|p| distance(p, u) <= tol)
    }

    /// The distance from `u` to the nearest told or pending point.
    fn nearest(&self, u: &[f64]) -> f64 {
        self.told_unit.iter().chain(&self.pending_unit).map(|p| distance(p, u)).fold(f64::INFINITY, f64::min)
    }

    /// The point searches centre on: the lowest told value, or for a smoothed surrogate
    /// the evaluated point it rates lowest (a lucky noisy draw should not steer).
    fn incumbent(&self, fit: Option<&Fit>) -> Vec<f64> {
        let i = match fit {
            Some(f) if self.settings.noise_smoothing > 0.0 => self.by_surrogate(f).first().map(|p| p.0),
            _ => argmin(&self.clean_values()[self.epoch_start..]).map(|i| i + self.epoch_start),
        };
        i.map_or_else(|| vec![0.5; self.dim()], |i| self.told_unit[i].clone())
    }

    /// Random candidates: half Gaussian around the incumbent with the trust radius, half
    /// uniform over the box.
    fn candidates(&self, fit: Option<&Fit>, rng: &mut ChaCha8Rng) -> Vec<Vec<f64>> {
        let d = self.dim();
        let centre = self.incumbent(fit);
        let n = (self.settings.candidates_per_dim * d).max(2);
        let sigma = self.trust_radius;
        (0..n)
            .map(|i| {
                if i % 2 == 0 && fit.is_some() {
                    let p = self.settings.perturbation_probability;
                    let mut x = centre.clone();
                    let mut moved = false;
                    for v in x.iter_mut() {
                        if rng.random::<f64>() < p {
                            *v = reflect(*v + sigma * gaussian(rng));
                            moved = true;
                        }
                    }
                    if !moved {
                        let k = rng.random_range(0..d);
                        x[k] = reflect(x[k] + sigma * gaussian(rng));
                    }
                    x
                } else {
                    (0..d).map(|_| rng.random::<f64>()).collect()
                }
            })
            .collect()
    }

    /// A CORS step: the least surrogate value among candidates far enough from the data.
    fn spaced_step(&self, fit: &Fit, beta: f64, rng: &mut ChaCha8Rng) -> Vec<f64> {
        let cands = self.candidates(Some(fit), rng);
        let dist: Vec<f64> = cands.iter().map(|c| self.nearest(c)).collect();
        let reach = dist.iter().copied().fold(0.0, f64::max);
        let least = (beta * reach).max(self.settings.min_distance);
        let mut best = None;
        let mut best_value = f64::INFINITY;
        for (c, &dc) in cands.iter().zip(&dist) {
            if dc >= least {
                let v = fit.surrogate.value(c);
                if v < best_value || best.is_none() {
                    best_value = v;
                    best = Some(c);
                }
            }
        }
        match best {
            Some(c) => c.clone(),
            None => self.pick_by_score(&cands, Some(fit), 0.0),
        }
    }

    /// A Regis–Shoemaker step: score random candidates by w·surrogate + (1 − w)·closeness.
    fn weighted_step(&self, fit: Option<&Fit>, w: f64, rng: &mut ChaCha8Rng) -> Vec<f64> {
        let cands = self.candidates(fit, rng);
        self.pick_by_score(&cands, fit, w)
    }

    /// The candidate of least score among those far enough from every point; the
    /// farthest candidate when none is.
    fn pick_by_score(&self, cands: &[Vec<f64>], fit: Option<&Fit>, w: f64) -> Vec<f64> {
        let dist: Vec<f64> = cands.iter().map(|c| self.nearest(c)).collect();
        let sval: Vec<f64> = match fit {
            Some(f) => cands.iter().map(|c| f.surrogate.value(c)).collect(),
            None => vec![0.0; cands.len()],
        };
        let ok = |i: &usize| dist[*i] >= self.settings.min_distance;
        let idx: Vec<usize> = (0..cands.len()).filter(ok).collect();
        if idx.is_empty() {
            let i = argmax(&dist).unwrap_or(0);
            return cands[i].clone();
        }
        let (smin, smax) = min_max(idx.iter().map(|&i| sval[i]));
        let (dmin, dmax) = min_max(idx.iter().map(|&i| dist[i]));
        let scale = |v: f64, lo: f64, hi: f64| if hi > lo { (v - lo) / (hi - lo) } else { 1.0 };
        let mut best = idx[0];
        let mut best_score = f64::INFINITY;
        for &i in &idx {
            let score = w * scale(sval[i], smin, smax) + (1.0 - w) * (1.0 - scale(dist[i], dmin, dmax));
            if score < best_score {
                best_score = score;
                best = i;
            }
        }
        cands[best].clone()
    }

    /// Minimises the surrogate within the trust radius of the incumbent, from the incumbent
    /// and the best few random starts; falls back to an exploiting candidate step when the
    /// minimiser lands on an evaluated point.
    fn trust_region_step(&self, fit: &Fit, rng: &mut ChaCha8Rng) -> Vec<f64> {
        let d = self.dim();
        let centre = self.incumbent(Some(fit));
        let r = self.trust_radius;
        let lo: Vec<f64> = centre.iter().map(|c| (c - r).max(0.0)).collect();
        let hi: Vec<f64> = centre.iter().map(|c| (c + r).min(1.0)).collect();
        let mut starts: Vec<(f64, Vec<f64>)> = (0..50 * d)
            .map(|_| {
                let x: Vec<f64> = (0..d).map(|k| lo[k] + (hi[k] - lo[k]) * rng.random::<f64>()).collect();
                (fit.surrogate.value(&x), x)
            })
            .collect();
        starts.sort_by(|a, b| a.0.total_cmp(&b.0));
        starts.truncate(4);
        starts.push((fit.surrogate.value(&centre), centre));
        let mut best: Option<(f64, Vec<f64>)> = None;
        for (_, x0) in starts {
            let (x, v) = descend(&fit.surrogate, x0, &lo, &hi, 200);
            if self.nearest(&x) >= self.settings.min_distance && best.as_ref().is_none_or(|b| v < b.0) {
                best = Some((v, x));
            }
        }
        match best {
            Some((_, x)) => x,
            None => self.weighted_step(Some(fit), 0.95, rng),
        }
    }
}

/// Projected gradient descent with a backtracking step on the box [lo, hi].
fn descend(s: &Surrogate, mut x: Vec<f64>, lo: &[f64], hi: &[f64], iters: usize) -> (Vec<f64>, f64) {
    let d = x.len();
    let mut g = vec![0.0; d];
    let mut gt = vec![0.0; d];
    let mut f = s.value_and_gradient(&x, &mut g);
    let span = lo.iter().zip(hi).map(|(a, b)| b - a).fold(0.0, f64::max);
    let mut step = 0.1 * span;
    let mut trial = vec![0.0; d];
    for _ in 0..iters {
        let gn = g.iter().map(|v| v * v).sum::<f64>().sqrt();
        if gn == 0.0 || step < 1e-10 * span.max(1e-12) {
            break;
        }
        for k in 0..d {
            trial[k] = (x[k] - step * g[k] / gn).clamp(lo[k], hi[k]);
        }
        let ft = s.value_and_gradient(&trial, &mut gt);
        let decrease: f64 = (0..d).map(|k| g[k] * (x[k] - trial[k])).sum();
        if ft <= f - 1e-4 * decrease && ft < f {
            x.copy_from_slice(&trial);
            g.copy_from_slice(&gt);
            f = ft;
            step *= 2.0;
        } else {
            step *= 0.5;
        }
    }
    (x, f)
}

/// A standard normal draw (Box–Muller).
fn gaussian(rng: &mut ChaCha8Rng) -> f64 {
    let u1: f64 = 1.0 - rng.random::<f64>();
    let u2: f64 = rng.random();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// Folds a coordinate back into [0, 1] by reflection at the faces.
fn reflect(v: f64) -> f64 {
    let m = v.rem_euclid(2.0);
    if m > 1.0 {
        2.0 - m
    } else {
        m
    }
}

fn min_max(it: impl Iterator<Item = f64>) -> (f64, f64) {
    it.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)))
}

fn argmin(v: &[f64]) -> Option<usize> {
    (0..v.len()).min_by(|&a, &b| v[a].total_cmp(&v[b]))
}

fn argmax(v: &[f64]) -> Option<usize> {
    (0..v.len()).max_by(|&a, &b| v[a].total_cmp(&v[b]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use test_functions::branin;

    fn branin_optimizer(seed: u64) -> RbfOptimizer {
        RbfOptimizer::new(vec![(-5.0, 10.0), (0.0, 15.0)], RbfSettings::default(), seed)
    }

    #[test]
    fn same_seed_same_sequence_other_seed_other_sequence() {
        let run = |seed: u64| {
            let mut opt = branin_optimizer(seed);
            (0..30)
                .map(|_| {
                    let x = opt.ask();
                    opt.tell(&x, branin(&x));
                    x
                })
                .collect::<Vec<_>>()
        };
        assert_eq!(run(4), run(4));
        assert_ne!(run(4), run(5));
    }

    #[test]
    fn replaying_the_history_resumes_with_the_same_next_point() {
        let mut rng = ChaCha8Rng::seed_from_u64(99);
        let bounds = vec![(0.0, 1.0), (-2.0, 2.0), (10.0, 20.0)];
        let f = |x: &[f64]| (x[0] - 0.3).powi(2) + (x[1] * x[1] - 1.0).powi(2) + 0.01 * x[2];
        // A short stall limit makes the replay cross restarts too.
        let settings = RbfSettings { restart_after_stall: 6, ..RbfSettings::default() };
        let mut opt = RbfOptimizer::new(bounds.clone(), settings.clone(), 17);
        let mut history: Vec<(Vec<f64>, f64)> = Vec::new();
        // Batches of three told in a shuffled order, as parallel workers finish.
        for round in 0..12 {
            let mut batch = opt.ask_batch(3);
            for i in (1..batch.len()).rev() {
                batch.swap(i, rng.random_range(0..=i));
            }
            for x in batch {
                let y = f(&x);
                opt.tell(&x, y);
                history.push((x, y));
            }
            let mut resumed = RbfOptimizer::new(bounds.clone(), settings.clone(), 17);
            for (x, y) in &history {
                resumed.tell(x, *y);
            }
            assert_eq!(resumed.ask_batch(3), opt.clone().ask_batch(3), "round {round}");
            assert_eq!(resumed.best_by_surrogate(), opt.best_by_surrogate());
        }
        assert!(opt.epoch > 0, "the history never restarted");
    }

    #[test]
    fn a_batch_holds_distinct_points_inside_the_box() {
        let mut opt = branin_optimizer(8);
        for _ in 0..5 {
            let batch = opt.ask_batch(4);
            for (i, a) in batch.iter().enumerate() {
                assert!((-5.0..=10.0).contains(&a[0]) && (0.0..=15.0).contains(&a[1]));
                for b in &batch[..i] {
                    assert!(distance(&opt.to_unit(a), &opt.to_unit(b)) >= 1e-4);
                }
            }
            for x in batch {
                opt.tell(&x, branin(&x));
            }
        }
    }

    #[test]
    fn failed_evaluations_do_not_break_the_search() {
        let mut opt = branin_optimizer(2);
        for i in 0..30 {
            let x = opt.ask();
            let y = if i % 4 == 3 { f64::NAN } else { branin(&x) };
            opt.tell(&x, y);
        }
        let (_, best) = opt.best_observed().unwrap();
        assert!(best.is_finite() && best < 5.0, "{best}");
        assert!(opt.best_by_surrogate().unwrap().1.is_finite());
    }

    #[test]
    fn top_candidates_are_evaluated_distinct_and_led_by_the_winner() {
        let mut opt = branin_optimizer(6);
        let mut seen = Vec::new();
        for _ in 0..25 {
            let x = opt.ask();
            opt.tell(&x, branin(&x));
            seen.push(x);
        }
        let top = opt.top_candidates(5);
        assert_eq!(top.len(), 5);
        assert_eq!(top[0], opt.best_by_surrogate().unwrap().0);
        for (i, t) in top.iter().enumerate() {
            assert!(seen.contains(t));
            assert!(!top[..i].contains(t));
        }
        // Interpolating: the surrogate's winner is the best observation.
        let (xs, vs) = opt.best_by_surrogate().unwrap();
        let (xo, vo) = opt.best_observed().unwrap();
        assert_eq!(xs, xo);
        assert!((vs - vo).abs() < 1e-6 * (1.0 + vo.abs()), "{vs} vs {vo}");
    }

    #[test]
    fn every_kind_of_step_makes_progress_on_branin() {
        let steps = [SearchStep::Weighted(0.5), SearchStep::Spaced(0.5), SearchStep::TrustRegion];
        for step in steps {
            // The step alone, apart from the refinement after an improvement, measured from
            // the end of a six-point start design.
            let settings = RbfSettings { cycle: vec![step], initial_points: 6, ..RbfSettings::default() };
            let mut opt = RbfOptimizer::new(vec![(-5.0, 10.0), (0.0, 15.0)], settings, 3);
            for _ in 0..6 {
                let x = opt.ask();
                opt.tell(&x, branin(&x));
            }
            let start = opt.best_observed().unwrap().1;
            for _ in 0..60 {
                let x = opt.ask();
                opt.tell(&x, branin(&x));
            }
            let end = opt.best_observed().unwrap().1;
            assert!(end < start && end < 0.897887, "{step:?}: {start} -> {end}");
        }
    }

    /// A smooth success-rate-like surface with Gaussian noise (sd 0.02): the smoothed
    /// surrogate's winner lands nearer the true optimum than the best raw observation.
    #[test]
    fn surrogate_winner_beats_the_luckiest_draw_on_a_noisy_objective() {
        let optimum = [0.35, 0.6];
        let truth = |x: &[f64]| -0.9 + 1.5 * ((x[0] - optimum[0]).powi(2) + (x[1] - optimum[1]).powi(2));
        let settings = RbfSettings { noise_smoothing: 0.01, ..RbfSettings::default() };
        let (mut by_surrogate, mut by_observation) = (0.0, 0.0);
        for seed in 1..=10 {
            let mut noise = ChaCha8Rng::seed_from_u64(1000 + seed);
            let mut opt = RbfOptimizer::new(vec![(0.0, 1.0), (0.0, 1.0)], settings.clone(), seed);
            for _ in 0..50 {
                let x = opt.ask();
                let y = truth(&x) + 0.02 * gaussian(&mut noise);
                opt.tell(&x, y);
            }
            by_surrogate += distance(&opt.best_by_surrogate().unwrap().0, &optimum);
            by_observation += distance(&opt.best_observed().unwrap().0, &optimum);
        }
        println!(
            "mean distance to the optimum: surrogate {:.4}, raw {:.4}",
            by_surrogate / 10.0,
            by_observation / 10.0
        );
        assert!(by_surrogate < by_observation, "{by_surrogate} vs {by_observation}");
    }
}
