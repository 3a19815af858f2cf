//! The closed-form start of A_i·X = Z·B_i (A the robot's poses, B the board's as the rig
//! saw them) and the spread of the rotations that decides how well it is determined. Pairs
//! of poses turn it into A_ij·X = X·B_ij with A_ij = A_j⁻¹·A_i, B_ij = B_j⁻¹·B_i; X's
//! rotation maps every B_ij's rotation axis onto A_ij's (Park and Martin's least squares,
//! solved by SVD), its translation solves (R_Aij − I)·t_X = R_X·t_Bij − t_Aij stacked, and
//! Z is the mean of A_i·X·B_i⁻¹. The refinement on the reprojection error is `refine.rs`'s.

use nalgebra::{DMatrix, DVector, Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};

/// A relative rotation below this angle, degrees, says little about its axis: the robot's
/// own error of a few hundredths of a degree turns a smaller one's axis by a degree.
pub(super) const MIN_RELATIVE_ROTATION_DEG: f64 = 5.0;

/// The nearest rotation to `m` (the polar factor, by SVD).
pub(super) fn nearest_rotation(m: &Matrix3<f64>) -> UnitQuaternion<f64> {
    let svd = m.svd(true, true);
    let (u, v_t) = (svd.u.expect("u requested"), svd.v_t.expect("v_t requested"));
    let d = (u * v_t).determinant().signum();
    let r = u * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * v_t;
    UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r))
}

/// X and Z of A_i·X = Z·B_i from the poses `a` and `b` (same length, at least 3); `None`
/// when the relative rotations do not fix X's rotation (fewer than two axes).
pub(super) fn solve_ax_zb(a: &[Isometry3<f64>], b: &[Isometry3<f64>]) -> Option<(Isometry3<f64>, Isometry3<f64>)> {
    let n = a.len();
    let mut pairs = Vec::new();
    for i in 0..n {
        for j in i + 1..n {
            pairs.push((a[j].inverse() * a[i], b[j].inverse() * b[i]));
        }
    }
    // Rotation: R_X·β = α for every pair's rotation vectors (α of A_ij, β of B_ij).
    let mut h = Matrix3::zeros();
    let mut used = 0;
    for (aij, bij) in &pairs {
        let (alpha, beta) = (aij.rotation.scaled_axis(), bij.rotation.scaled_axis());
        if alpha.norm().to_degrees() < MIN_RELATIVE_ROTATION_DEG {
            continue;
        }
        h += alpha * beta.transpose();
        used += 1;
    }
    if used < 2 {
        return None;
    }
    let r_x = nearest_rotation(&h);
    // Translation: stacked (R_Aij − I)·t_X = R_X·t_Bij − t_Aij.
    let mut lhs = DMatrix::zeros(3 * pairs.len(), 3);
    let mut rhs = DVector::zeros(3 * pairs.len());
    for (k, (aij, bij)) in pairs.iter().enumerate() {
        let m = aij.rotation.to_rotation_matrix().into_inner() - Matrix3::identity();
        let r = r_x * bij.translation.vector - aij.translation.vector;
        lhs.view_mut((3 * k, 0), (3, 3)).copy_from(&m);
        rhs.rows_mut(3 * k, 3).copy_from(&r);
    }
    let t_x = lhs.svd(true, true).solve(&rhs, 1e-12).ok()?;
    let x = Isometry3::from_parts(Translation3::new(t_x[0], t_x[1], t_x[2]), r_x);
    // Z: every pose's A_i·X·B_i⁻¹, rotations averaged as matrices and projected back.
    let zs: Vec<Isometry3<f64>> = a.iter().zip(b).map(|(ai, bi)| ai * x * bi.inverse()).collect();
    let sum = zs.iter().fold(Matrix3::zeros(), |acc, z| acc + z.rotation.to_rotation_matrix().into_inner());
    let t_z = zs.iter().fold(Vector3::zeros(), |acc, z| acc + z.translation.vector) / n as f64;
    let z = Isometry3::from_parts(Translation3::from(t_z), nearest_rotation(&sum));
    x.translation.vector.iter().chain(z.translation.vector.iter()).all(|v| v.is_finite()).then_some((x, z))
}

/// How the robot's rotations spread: what decides whether hand-eye calibration can find
/// the translation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RotationSpread {
    /// The largest angle between the axes of two relative rotations (pairs of poses turned
    /// by at least 5° against each other), degrees in [0, 90]: near 0 all turns were about
    /// one axis, which leaves the translation along it undetermined.
    pub max_axis_angle_deg: f64,
    /// The largest relative rotation between two poses, degrees.
    pub max_rotation_deg: f64,
    /// Pairs of poses turned by at least 5° against each other.
    pub informative_pairs: usize,
}

/// The spread of the robot poses `a` (base ← flange).
pub(super) fn rotation_spread(a: &[Isometry3<f64>]) -> RotationSpread {
    let mut axes = Vec::new();
    let mut max_rotation_deg: f64 = 0.0;
    for i in 0..a.len() {
        for j in i + 1..a.len() {
            let r = (a[j].inverse() * a[i]).rotation;
            let angle = r.angle().to_degrees();
            max_rotation_deg = max_rotation_deg.max(angle);
            if angle >= MIN_RELATIVE_ROTATION_DEG {
                // The axis as A_ij·X = X·B_ij sees it (in flange j's frame): X's rotation maps
                // these vectors, so it is fixed only when two of them are not parallel.
                axes.push(r.axis().expect("a turn of at least 5°").into_inner());
            }
        }
    }
    let mut max_axis_angle_deg: f64 = 0.0;
    for i in 0..axes.len() {
        for j in i + 1..axes.len() {
            let c = axes[i].dot(&axes[j]).abs().min(1.0);
            max_axis_angle_deg = max_axis_angle_deg.max(c.acos().to_degrees());
        }
    }
    RotationSpread { max_axis_angle_deg, max_rotation_deg, informative_pairs: axes.len() }
}
