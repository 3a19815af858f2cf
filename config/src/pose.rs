//! The check every pose read from a file passes before anything uses it: a rigid
//! transform, finite, last row `0 0 0 1`, a rotation part that is orthonormal within
//! [`ROTATION_TOLERANCE`] and turns the right way (determinant +1, not a reflection).

/// How far `RᵀR` may stray from the identity, and `det R` from +1, in a pose read from a
/// file. JSON written with full precision is far inside it; a rotation typed by hand with
/// six decimals is inside it too.
pub const ROTATION_TOLERANCE: f64 = 1e-5;

/// Checks a row-major 4x4 transform; the error says what was expected.
pub fn check_rigid(t: &[[f64; 4]; 4]) -> Result<(), String> {
    if t.iter().flatten().any(|v| !v.is_finite()) {
        return Err("expected a 4x4 rigid transform of finite numbers".into());
    }
    if t[3] != [0.0, 0.0, 0.0, 1.0] {
        return Err("expected a 4x4 rigid transform, last row [0, 0, 0, 1]".into());
    }
    for i in 0..3 {
        for j in 0..3 {
            let dot: f64 = (0..3).map(|r| t[r][i] * t[r][j]).sum();
            let want = if i == j { 1.0 } else { 0.0 };
            if (dot - want).abs() > ROTATION_TOLERANCE {
                return Err(format!(
                    "expected an orthonormal rotation part (columns of length 1 at right angles, within {ROTATION_TOLERANCE})"
                ));
            }
        }
    }
    let det = t[0][0] * (t[1][1] * t[2][2] - t[1][2] * t[2][1]) - t[0][1] * (t[1][0] * t[2][2] - t[1][2] * t[2][0])
        + t[0][2] * (t[1][0] * t[2][1] - t[1][1] * t[2][0]);
    if (det - 1.0).abs() > ROTATION_TOLERANCE {
        return Err(format!(
            "expected a rotation with determinant +1, found {det:.6} (a reflection: one axis has the wrong sign)"
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn turn(yaw_deg: f64, t: [f64; 3]) -> [[f64; 4]; 4] {
        let (s, c) = yaw_deg.to_radians().sin_cos();
        [[c, -s, 0.0, t[0]], [s, c, 0.0, t[1]], [0.0, 0.0, 1.0, t[2]], [0.0, 0.0, 0.0, 1.0]]
    }

    #[test]
    fn rotations_pass_and_reflections_do_not() {
        for yaw in [0.0, 17.0, 90.0, 179.0, -33.3] {
            assert!(check_rigid(&turn(yaw, [1.0, -2.0, 600.0])).is_ok(), "{yaw}");
            let mut m = turn(yaw, [0.0; 3]);
            for row in m.iter_mut().take(3) {
                row[2] = -row[2];
            }
            let e = check_rigid(&m).unwrap_err();
            assert!(e.contains("determinant"), "{e}");
        }
    }

    #[test]
    fn scaled_zero_and_non_finite_rotations_are_refused() {
        let mut scaled = turn(10.0, [0.0; 3]);
        for row in scaled.iter_mut().take(3) {
            for v in row.iter_mut().take(3) {
                *v *= 2.0;
            }
        }
        assert!(check_rigid(&scaled).unwrap_err().contains("orthonormal"));
        let mut zero = [[0.0; 4]; 4];
        zero[3][3] = 1.0;
        assert!(check_rigid(&zero).is_err());
        let mut nan = turn(0.0, [0.0; 3]);
        nan[1][3] = f64::NAN;
        assert!(check_rigid(&nan).unwrap_err().contains("finite"));
        let mut row = turn(0.0, [0.0; 3]);
        row[3] = [0.0, 0.0, 1.0, 1.0];
        assert!(check_rigid(&row).unwrap_err().contains("last row"));
    }
}
