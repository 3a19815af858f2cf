//! The hand-eye refinement: X and Z of A_i·X = Z·B_i (twelve parameters) by the
//! reprojection error of every corner in both cameras, the board's pose in each view being
//! no longer a free parameter but what the robot's pose and the two unknowns put it at.
//! The robot's reported pose is not exact either: each view has its own correction of it
//! (a turn at the flange, a shift in the base), held to the robot's stated accuracy by a
//! prior, so that a robot error of 0.1 mm is not read as a turn of the rig. Residuals are in
//! units of their σ. Also the covariance of the result, from which the expected error is
//! reported.

use nalgebra::{DMatrix, DVector, Isometry3, Point3};

use super::super::board::BoardView;
use super::super::lm::{self, ViewProblem};
use super::super::refine::{pose_from_params, pose_params, pose_typical, wrap_rotation, POSE_LEN};
use super::board_poses::StereoPair;
use super::HandEyeSetup;
use crate::error::Result;

/// The σ of each kind of residual.
#[derive(Debug, Clone, Copy)]
pub(super) struct Sigmas {
    /// A corner's position, pixels.
    pub corner_px: f64,
    /// The robot's reported translation, per axis, mm.
    pub robot_mm: f64,
    /// The robot's reported rotation, per axis, radians.
    pub robot_rad: f64,
}

/// The refinement of X and Z over the kept poses.
pub(super) struct HandEyeProblem<'a> {
    pub pair: &'a StereoPair<'a>,
    pub object: &'a [Point3<f64>],
    pub setup: HandEyeSetup,
    /// The kept views and their robot poses (base ← flange), side by side.
    pub views: Vec<&'a BoardView>,
    pub a: Vec<Isometry3<f64>>,
    pub sigmas: Sigmas,
}

/// The robot's pose `a` corrected by `delta` (a rotation vector at the flange, radians, and
/// a shift in the base, mm), the way its reported pose errs.
pub(super) fn corrected(a: &Isometry3<f64>, delta: &[f64]) -> Isometry3<f64> {
    let turn = nalgebra::UnitQuaternion::from_scaled_axis(nalgebra::Vector3::new(delta[0], delta[1], delta[2]));
    let shift = nalgebra::Vector3::new(delta[3], delta[4], delta[5]);
    Isometry3::from_parts((a.translation.vector + shift).into(), a.rotation * turn)
}

impl HandEyeProblem<'_> {
    /// The board's pose in the left camera's frame at robot pose `a` under X and Z.
    pub fn t_left_board(
        setup: HandEyeSetup,
        a: &Isometry3<f64>,
        x: &Isometry3<f64>,
        z: &Isometry3<f64>,
    ) -> Isometry3<f64> {
        let m = z.inverse() * a * x;
        match setup {
            // Z = T_base_rig, X = T_flange_board: rig ← base ← flange ← board.
            HandEyeSetup::EyeToHand => m,
            // Z = T_base_board, X = T_flange_rig: board ← base ← flange ← rig, inverted.
            HandEyeSetup::EyeInHand => m.inverse(),
        }
    }
}

impl ViewProblem for HandEyeProblem<'_> {
    fn shared_len(&self) -> usize {
        2 * POSE_LEN
    }
    fn view_len(&self) -> usize {
        POSE_LEN
    }
    fn view_count(&self) -> usize {
        self.views.len()
    }
    fn residual_len(&self) -> usize {
        4 * self.object.len() + POSE_LEN
    }
    fn residuals(&self, shared: &[f64], own: &[f64], view: usize, out: &mut [f64]) {
        let (x, z) = (pose_from_params(&shared[..POSE_LEN]), pose_from_params(&shared[POSE_LEN..]));
        let pose = Self::t_left_board(self.setup, &corrected(&self.a[view], own), &x, &z);
        let (corners, prior) = out.split_at_mut(4 * self.object.len());
        self.pair.residuals(self.object, self.views[view], &pose, corners);
        corners.iter_mut().for_each(|r| *r /= self.sigmas.corner_px);
        for i in 0..3 {
            prior[i] = own[i] / self.sigmas.robot_rad;
            prior[3 + i] = own[3 + i] / self.sigmas.robot_mm;
        }
    }
    fn typical_magnitudes(&self, x: &DVector<f64>) -> DVector<f64> {
        let mut typical = DVector::zeros(x.len());
        let (shared, own) = typical.as_mut_slice().split_at_mut(2 * POSE_LEN);
        for (p, o) in x.as_slice()[..2 * POSE_LEN].chunks_exact(POSE_LEN).zip(shared.chunks_exact_mut(POSE_LEN)) {
            pose_typical(p, o);
        }
        for o in own.chunks_exact_mut(POSE_LEN) {
            o[..3].fill(self.sigmas.robot_rad.max(1e-9));
            o[3..].fill(self.sigmas.robot_mm.max(1e-9));
        }
        typical
    }
    fn canonicalise(&self, x: &mut DVector<f64>) {
        x.as_mut_slice()[..2 * POSE_LEN].chunks_exact_mut(POSE_LEN).for_each(wrap_rotation);
    }
}

/// A refined solution: X, Z, each view's correction of the robot's pose, each view's
/// residuals' RMS in units of their σ, and the whole cost.
pub(super) struct Refined {
    pub x: Isometry3<f64>,
    pub z: Isometry3<f64>,
    pub deltas: Vec<[f64; POSE_LEN]>,
    pub scores: Vec<f64>,
}

/// X and Z refined from `start`, every view's correction from zero.
pub(super) fn refine(problem: &HandEyeProblem<'_>, start: (Isometry3<f64>, Isometry3<f64>)) -> Result<Refined> {
    let n = 2 * POSE_LEN + POSE_LEN * problem.views.len();
    let mut x = DVector::zeros(n);
    x.as_mut_slice()[..POSE_LEN].copy_from_slice(&pose_params(&start.0));
    x.as_mut_slice()[POSE_LEN..2 * POSE_LEN].copy_from_slice(&pose_params(&start.1));
    lm::minimise(problem, &mut x, "hand-eye")?;
    let mut residuals = DVector::zeros(problem.residual_len() * problem.view_count());
    lm::evaluate(problem, &x, &mut residuals);
    let m = problem.residual_len();
    let scores = residuals
        .as_slice()
        .chunks_exact(m)
        .zip(&problem.views)
        .map(|(r, v)| {
            let seen = v.left.is_some() as usize + v.right.is_some() as usize;
            (r.iter().map(|e| e * e).sum::<f64>() / (2 * seen * problem.object.len() + POSE_LEN) as f64).sqrt()
        })
        .collect();
    let x = x.as_slice();
    Ok(Refined {
        x: pose_from_params(&x[..POSE_LEN]),
        z: pose_from_params(&x[POSE_LEN..2 * POSE_LEN]),
        deltas: x[2 * POSE_LEN..].chunks_exact(POSE_LEN).map(|d| std::array::from_fn(|i| d[i])).collect(),
        scores,
    })
}

/// The 1-σ errors to expect of X and Z at the solution `x_z`: the parameters' covariance
/// σ²·(JᵀJ)⁻¹ with σ² the residuals' variance, as (X's translation mm, X's rotation deg,
/// Z's translation mm, Z's rotation deg), each the root of its block's trace. Infinite where
/// JᵀJ is singular (a direction the poses do not determine).
pub(super) fn expected_errors(problem: &HandEyeProblem<'_>, refined: &Refined) -> [f64; 4] {
    let mut params = Vec::with_capacity(2 * POSE_LEN + POSE_LEN * refined.deltas.len());
    params.extend(pose_params(&refined.x));
    params.extend(pose_params(&refined.z));
    refined.deltas.iter().for_each(|d| params.extend(d));
    let params = DVector::from_vec(params);
    let mut residuals = DVector::zeros(problem.residual_len() * problem.view_count());
    let cost = lm::evaluate(problem, &params, &mut residuals);
    let typical = problem.typical_magnitudes(&params);
    let (jtj, _) = lm::normal_equations(problem, &params, &residuals, &typical);
    let observed = residuals.iter().filter(|r| **r != 0.0).count();
    let sigma2 = cost / observed.saturating_sub(params.len()).max(1) as f64;
    // Scaled to a unit diagonal so the inverse is judged by its condition, not its units.
    let scale = jtj.diagonal().map(|d| d.max(f64::MIN_POSITIVE).sqrt());
    let scaled = DMatrix::from_fn(jtj.nrows(), jtj.ncols(), |i, j| jtj[(i, j)] / (scale[i] * scale[j]));
    let svd = scaled.clone().svd(false, false);
    let (largest, smallest) = (svd.singular_values.max(), svd.singular_values.min());
    if smallest.is_nan() || smallest <= largest * 1e-12 {
        return [f64::INFINITY; 4];
    }
    let Some(inverse) = scaled.try_inverse() else { return [f64::INFINITY; 4] };
    let block = |start: usize| -> f64 {
        (start..start + 3).map(|i| sigma2 * inverse[(i, i)] / (scale[i] * scale[i])).sum::<f64>().sqrt()
    };
    [block(3), block(0).to_degrees(), block(9), block(6).to_degrees()]
}

/// One view's correction of the robot's pose alone, X and Z held: how far a dropped pose's
/// robot pose would have to be off to fit.
pub(super) struct HeldMounting<'a> {
    pub problem: &'a HandEyeProblem<'a>,
    pub x: Isometry3<f64>,
    pub z: Isometry3<f64>,
}

impl ViewProblem for HeldMounting<'_> {
    fn shared_len(&self) -> usize {
        POSE_LEN
    }
    fn view_len(&self) -> usize {
        0
    }
    fn view_count(&self) -> usize {
        1
    }
    fn residual_len(&self) -> usize {
        self.problem.residual_len()
    }
    fn residuals(&self, shared: &[f64], _own: &[f64], _view: usize, out: &mut [f64]) {
        let mut mounting = [0.0; 2 * POSE_LEN];
        mounting[..POSE_LEN].copy_from_slice(&pose_params(&self.x));
        mounting[POSE_LEN..].copy_from_slice(&pose_params(&self.z));
        self.problem.residuals(&mounting, shared, 0, out);
    }
    fn typical_magnitudes(&self, _x: &DVector<f64>) -> DVector<f64> {
        let s = &self.problem.sigmas;
        DVector::from_fn(POSE_LEN, |i, _| if i < 3 { s.robot_rad } else { s.robot_mm })
    }
}
