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

/// The 1-σ errors to expect of X and Z at the solution `refined`, as (X's translation mm,
/// X's rotation deg, Z's translation mm, Z's rotation deg), each the root of its block's
/// trace (the RMS length of the error). The solution weighs corners and the robot's
/// corrections by their stated σ, which need not be the true ones (the detector may be
/// better than 0.1 px, the robot worse than stated); scaling the covariance by one variance
/// per degree of freedom let the many corners' small residuals shrink the robot's share of
/// the error, which dominates it, by two or three times. So each group's true variance
/// factor is estimated from its own residuals, unbiased under the linearised model
/// (E[rᵀ_g r_g] = Σ_k s²_k ‖P_g (I − H) P_k‖², H the hat matrix), and the covariance of the
/// estimate actually made is the sandwich A⁻¹ (Σ_g s²_g J_gᵀJ_g) A⁻¹ with A = JᵀJ. Rotation
/// blocks are taken in the frame the error is measured in (truth⁻¹ · found), not in the
/// rotation-vector parameters. Infinite where A is singular (a direction the poses do not
/// determine).
pub(super) fn expected_errors(problem: &HandEyeProblem<'_>, refined: &Refined) -> [f64; 4] {
    let variance = covariance(problem, refined);
    let Some(variance) = variance else { return [f64::INFINITY; 4] };
    let tangent = |start: usize, pose: &Isometry3<f64>| -> DMatrix<f64> {
        let j = rotation_tangent(pose);
        let block = variance.view((start, start), (3, 3)).into_owned();
        let local = j * block * j.transpose();
        DMatrix::from_fn(3, 3, |r, c| local[(r, c)])
    };
    let trace = |m: &DMatrix<f64>| m.trace().max(0.0).sqrt();
    let translation = |start: usize| (start..start + 3).map(|i| variance[(i, i)]).sum::<f64>().max(0.0).sqrt();
    [
        translation(3),
        trace(&tangent(0, &refined.x)).to_degrees(),
        translation(9),
        trace(&tangent(6, &refined.z)).to_degrees(),
    ]
}

/// d(truth⁻¹ · found)'s rotation vector / d(found's rotation vector) at `pose`: how a step
/// of the parameters turns the pose as seen from the pose itself.
fn rotation_tangent(pose: &Isometry3<f64>) -> nalgebra::Matrix3<f64> {
    let r = pose.rotation.scaled_axis();
    let h = 1e-7;
    let mut j = nalgebra::Matrix3::zeros();
    for k in 0..3 {
        let mut step = nalgebra::Vector3::zeros();
        step[k] = h;
        let plus = nalgebra::UnitQuaternion::from_scaled_axis(r + step);
        let minus = nalgebra::UnitQuaternion::from_scaled_axis(r - step);
        let d = (pose.rotation.inverse() * plus).scaled_axis() - (pose.rotation.inverse() * minus).scaled_axis();
        j.set_column(k, &(d / (2.0 * h)));
    }
    j
}

/// The covariance of every parameter (X, Z, the corrections) of the solution `refined`,
/// with each residual group's variance factor (corners, robot corrections) estimated from
/// its residuals; `None` where JᵀJ is singular.
pub(super) fn covariance(problem: &HandEyeProblem<'_>, refined: &Refined) -> Option<DMatrix<f64>> {
    let mut params = Vec::with_capacity(2 * POSE_LEN + POSE_LEN * refined.deltas.len());
    params.extend(pose_params(&refined.x));
    params.extend(pose_params(&refined.z));
    refined.deltas.iter().for_each(|d| params.extend(d));
    let params = DVector::from_vec(params);
    let n = params.len();
    let m = problem.residual_len();
    let corner_rows = 4 * problem.object.len();
    let mut residuals = DVector::zeros(m * problem.view_count());
    lm::evaluate(problem, &params, &mut residuals);
    let typical = problem.typical_magnitudes(&params);
    // Each group's JᵀJ over all parameters, its squared residuals and its rows.
    let (mut c_corner, mut c_robot) = (DMatrix::zeros(n, n), DMatrix::zeros(n, n));
    let (mut r_corner, mut r_robot) = (0.0, 0.0);
    let (mut n_corner, mut n_robot) = (0usize, 0usize);
    let shared = 2 * POSE_LEN;
    let mut jacobian = DMatrix::zeros(m, shared + POSE_LEN);
    let mut columns = vec![0; shared + POSE_LEN];
    for view in 0..problem.view_count() {
        lm::view_jacobian(problem, &params, &typical, view, lm::CENTRAL_DIFFERENCE_STEP, &mut jacobian);
        for (c, column) in columns.iter_mut().enumerate() {
            *column = if c < shared { c } else { shared + view * POSE_LEN + (c - shared) };
        }
        let v = problem.views[view];
        n_corner += 2 * problem.object.len() * (v.left.is_some() as usize + v.right.is_some() as usize);
        n_robot += POSE_LEN;
        let r = residuals.rows(view * m, m);
        r_corner += r.rows(0, corner_rows).norm_squared();
        r_robot += r.rows(corner_rows, POSE_LEN).norm_squared();
        let corners = jacobian.rows(0, corner_rows);
        let robot = jacobian.rows(corner_rows, POSE_LEN);
        let (bc, br) = (corners.tr_mul(&corners), robot.tr_mul(&robot));
        for (a, &i) in columns.iter().enumerate() {
            for (b, &j) in columns.iter().enumerate() {
                c_corner[(i, j)] += bc[(a, b)];
                c_robot[(i, j)] += br[(a, b)];
            }
        }
    }
    let a: DMatrix<f64> = &c_corner + &c_robot;
    // Inverted scaled to a unit diagonal so it is judged by its condition, not its units.
    let scale = a.diagonal().map(|d: f64| d.max(f64::MIN_POSITIVE).sqrt());
    let scaled = DMatrix::from_fn(n, n, |i, j| a[(i, j)] / (scale[i] * scale[j]));
    let svd = scaled.clone().svd(false, false);
    let (largest, smallest) = (svd.singular_values.max(), svd.singular_values.min());
    if smallest.is_nan() || smallest <= largest * 1e-12 {
        return None;
    }
    let inverse = scaled.try_inverse()?;
    let q = DMatrix::from_fn(n, n, |i, j| inverse[(i, j)] / (scale[i] * scale[j]));
    // T_gg = n_g − 2 tr(Q C_g) + tr(Q C_g Q C_g), T_gk = tr(Q C_g) − tr(Q C_g Q C_g).
    let terms = |c: &DMatrix<f64>, rows: usize| {
        let qc = &q * c;
        let t = qc.trace();
        let f = (&qc * &qc).trace();
        (rows as f64 - 2.0 * t + f, t - f)
    };
    let (t_cc, t_cr) = terms(&c_corner, n_corner);
    let (t_rr, t_rc) = terms(&c_robot, n_robot);
    let det = t_cc * t_rr - t_cr * t_rc;
    let (mut s_corner, mut s_robot) = if det.abs() > 1e-12 {
        ((r_corner * t_rr - t_cr * r_robot) / det, (t_cc * r_robot - t_rc * r_corner) / det)
    } else {
        let s = (r_corner + r_robot) / (t_cc + t_cr + t_rr + t_rc).max(1.0);
        (s, s)
    };
    // A group whose estimate is not positive (its residuals explained by the other's) is
    // given its share alone, the other group taking the rest.
    if s_robot <= 0.0 {
        s_robot = 0.0;
        s_corner = r_corner / t_cc.max(1.0);
    }
    if s_corner <= 0.0 {
        s_corner = 0.0;
        s_robot = r_robot / t_rr.max(1.0);
    }
    let middle = c_corner * s_corner + c_robot * s_robot;
    Some(&q * middle * &q)
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
