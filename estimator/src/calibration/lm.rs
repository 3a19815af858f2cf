//! A small dense Levenberg–Marquardt for least-squares problems whose parameters are a shared
//! block plus one block per view, a view's residuals depending only on the shared block and
//! its own: the Jacobian is taken by central differences one view at a time, and the normal
//! equations are solved dense by Cholesky. The least-squares crates (levenberg-marquardt,
//! tiny-solver, vision-calibration) all depend on nalgebra 0.34 and would pull a second
//! nalgebra next to the workspace's 0.35.

use nalgebra::{DMatrix, DVector};

use crate::error::{Error, ErrorKind, Result};

/// Iterations (Jacobian evaluations) before the refinement settles for where it is.
const MAX_ITERATIONS: usize = 100;
/// A relative cost decrease below this is convergence.
const MIN_RELATIVE_DECREASE: f64 = 1e-12;
/// A step below this fraction of the parameter vector's norm is convergence.
const MIN_RELATIVE_STEP: f64 = 1e-12;
/// Damping (relative to JᵀJ's diagonal) to start from: close to Gauss–Newton, as a good start
/// allows.
const INITIAL_DAMPING: f64 = 1e-3;
/// Damping beyond this means no step can lower the cost: the refinement is at a minimum.
const MAX_DAMPING: f64 = 1e16;
/// Damping never falls below this, so one bad step after many good ones is not a thousand-fold
/// climb back.
const MIN_DAMPING: f64 = 1e-12;
/// The cube root of machine epsilon: the central-difference step (relative to a parameter's
/// magnitude) that balances truncation against rounding error.
pub(super) const CENTRAL_DIFFERENCE_STEP: f64 = 6e-6;

/// A least-squares problem of shared parameters and per-view parameters.
pub(super) trait ViewProblem {
    /// Parameters every view's residuals depend on (the intrinsics, the stereo pose).
    fn shared_len(&self) -> usize;
    /// Parameters of one view (its board pose).
    fn view_len(&self) -> usize;
    /// Number of views.
    fn view_count(&self) -> usize;
    /// Residuals of one view.
    fn residual_len(&self) -> usize;
    /// View `view`'s residuals from the shared parameters and its own; NaN where a point
    /// falls behind a camera.
    fn residuals(&self, shared: &[f64], own: &[f64], view: usize, out: &mut [f64]);
    /// The magnitude of each parameter of `x` below which its finite-difference step does
    /// not shrink (a parameter near zero still has a scale).
    fn typical_magnitudes(&self, x: &DVector<f64>) -> DVector<f64>;
    /// Brings the parameters back to their canonical range after a step.
    fn canonicalise(&self, _x: &mut DVector<f64>) {}
}

/// Refines `x` in place by Levenberg–Marquardt; `what` names what is refined in messages.
pub(super) fn minimise<P: ViewProblem>(problem: &P, x: &mut DVector<f64>, what: &str) -> Result<()> {
    let n = problem.shared_len() + problem.view_len() * problem.view_count();
    assert_eq!(x.len(), n, "parameter vector length");
    let diverged = || {
        Error::new(
            ErrorKind::Calibration,
            format!(
                "calibration {what}: the refinement reached non-finite values; expected views of the whole board \
                 with their corners in board order"
            ),
        )
    };
    let typical = problem.typical_magnitudes(x);
    let mut residuals = DVector::zeros(problem.residual_len() * problem.view_count());
    let mut trial_residuals = residuals.clone();
    let mut cost = evaluate(problem, x, &mut residuals);
    if !cost.is_finite() {
        return Err(diverged());
    }
    let mut damping = INITIAL_DAMPING;
    for _ in 0..MAX_ITERATIONS {
        let (jtj, jtr) = normal_equations(problem, x, &residuals, &typical);
        if !(jtj.iter().all(|v| v.is_finite()) && jtr.iter().all(|v| v.is_finite())) {
            return Err(diverged());
        }
        // Scaling the columns to a unit diagonal makes the damping Marquardt's λ·diag(JᵀJ)
        // and keeps the Cholesky well conditioned across parameters of different units.
        let max_diagonal = jtj.diagonal().max();
        let scale = jtj.diagonal().map(|d| d.max(max_diagonal * 1e-30).max(f64::MIN_POSITIVE).sqrt());
        let scaled = DMatrix::from_fn(n, n, |i, j| jtj[(i, j)] / (scale[i] * scale[j]));
        let gradient = jtr.component_div(&scale);
        loop {
            let mut lhs = scaled.clone();
            for i in 0..n {
                lhs[(i, i)] += damping;
            }
            let Some(cholesky) = lhs.cholesky() else {
                damping *= 10.0;
                if damping > MAX_DAMPING {
                    return Ok(());
                }
                continue;
            };
            let step = cholesky.solve(&-&gradient).component_div(&scale);
            let step_is_tiny = step.norm() <= MIN_RELATIVE_STEP * (x.norm() + MIN_RELATIVE_STEP);
            let mut trial = &*x + &step;
            problem.canonicalise(&mut trial);
            let trial_cost = evaluate(problem, &trial, &mut trial_residuals);
            if trial_cost.is_finite() && trial_cost < cost {
                let relative_decrease = (cost - trial_cost) / cost;
                *x = trial;
                std::mem::swap(&mut residuals, &mut trial_residuals);
                cost = trial_cost;
                damping = (damping / 10.0).max(MIN_DAMPING);
                if relative_decrease < MIN_RELATIVE_DECREASE || step_is_tiny || cost == 0.0 {
                    return Ok(());
                }
                break;
            }
            damping *= 10.0;
            if step_is_tiny || damping > MAX_DAMPING {
                return Ok(());
            }
        }
    }
    Ok(())
}

/// Writes every view's residuals into `out` and returns their sum of squares.
pub(super) fn evaluate<P: ViewProblem>(problem: &P, x: &DVector<f64>, out: &mut DVector<f64>) -> f64 {
    let (shared_len, view_len, m) = (problem.shared_len(), problem.view_len(), problem.residual_len());
    let (shared, views) = x.as_slice().split_at(shared_len);
    // A problem without per-view parameters (`view_len` 0) still has its views.
    for view in 0..problem.view_count() {
        let own = &views[view * view_len..(view + 1) * view_len];
        problem.residuals(shared, own, view, &mut out.as_mut_slice()[view * m..(view + 1) * m]);
    }
    out.norm_squared()
}

/// JᵀJ and Jᵀr, assembled view by view: a view's Jacobian has the shared columns and its own.
pub(super) fn normal_equations<P: ViewProblem>(
    problem: &P,
    x: &DVector<f64>,
    residuals: &DVector<f64>,
    typical: &DVector<f64>,
) -> (DMatrix<f64>, DVector<f64>) {
    let (shared_len, view_len, m) = (problem.shared_len(), problem.view_len(), problem.residual_len());
    let n = x.len();
    let mut jtj = DMatrix::zeros(n, n);
    let mut jtr = DVector::zeros(n);
    let mut jacobian = DMatrix::zeros(m, shared_len + view_len);
    // Where each column of a view's Jacobian sits in the full parameter vector.
    let mut columns = vec![0; shared_len + view_len];
    for view in 0..problem.view_count() {
        view_jacobian(problem, x, typical, view, CENTRAL_DIFFERENCE_STEP, &mut jacobian);
        for (c, column) in columns.iter_mut().enumerate() {
            *column = if c < shared_len { c } else { shared_len + view * view_len + (c - shared_len) };
        }
        let block = jacobian.tr_mul(&jacobian);
        let gradient = jacobian.tr_mul(&residuals.rows(view * m, m));
        for (a, &i) in columns.iter().enumerate() {
            jtr[i] += gradient[a];
            for (b, &j) in columns.iter().enumerate() {
                jtj[(i, j)] += block[(a, b)];
            }
        }
    }
    (jtj, jtr)
}

/// View `view`'s Jacobian (its residuals against the shared parameters, then its own) by
/// central differences with steps of `relative_step` times each parameter's magnitude.
pub(super) fn view_jacobian<P: ViewProblem>(
    problem: &P,
    x: &DVector<f64>,
    typical: &DVector<f64>,
    view: usize,
    relative_step: f64,
    out: &mut DMatrix<f64>,
) {
    let (shared_len, view_len, m) = (problem.shared_len(), problem.view_len(), problem.residual_len());
    let own_start = shared_len + view * view_len;
    let mut shared = x.as_slice()[..shared_len].to_vec();
    let mut own = x.as_slice()[own_start..own_start + view_len].to_vec();
    let (mut plus, mut minus) = (vec![0.0; m], vec![0.0; m]);
    for c in 0..shared_len + view_len {
        let (index, value) =
            if c < shared_len { (c, shared[c]) } else { (own_start + c - shared_len, own[c - shared_len]) };
        let step = relative_step * value.abs().max(typical[index]);
        let set = |shared: &mut [f64], own: &mut [f64], v: f64| {
            if c < shared_len {
                shared[c] = v;
            } else {
                own[c - shared_len] = v;
            }
        };
        // The steps actually taken, which rounding makes differ from `step`.
        let (up, down) = (value + step, value - step);
        set(&mut shared, &mut own, up);
        problem.residuals(&shared, &own, view, &mut plus);
        set(&mut shared, &mut own, down);
        problem.residuals(&shared, &own, view, &mut minus);
        set(&mut shared, &mut own, value);
        let width = up - down;
        for r in 0..m {
            out[(r, c)] = (plus[r] - minus[r]) / width;
        }
    }
}
