//! What the robot pose targets share: a format picked by one byte, and the checks of a
//! decoded pose.

use camplace_config::{check_rigid, LengthUnit, PoseConvention, RobotPoseFormat};

const CONVENTIONS: [PoseConvention; 7] = [
    PoseConvention::Matrix,
    PoseConvention::QuatWxyz,
    PoseConvention::QuatXyzw,
    PoseConvention::Ur,
    PoseConvention::Kuka,
    PoseConvention::Abb,
    PoseConvention::Fanuc,
];

/// The format byte `pick` names: each convention in mm and in m, or none (the file's header
/// must say it).
pub fn format(pick: u8) -> Option<RobotPoseFormat> {
    let k = pick as usize % (2 * CONVENTIONS.len() + 1);
    (k < 2 * CONVENTIONS.len()).then(|| RobotPoseFormat {
        convention: CONVENTIONS[k / 2],
        unit: if k % 2 == 0 { LengthUnit::Mm } else { LengthUnit::M },
    })
}

/// A decoded pose is finite and rigid.
pub fn assert_rigid(p: &[[f64; 4]; 4]) {
    assert!(p.iter().flatten().all(|v| v.is_finite()), "{p:?}");
    assert!(check_rigid(p).is_ok(), "{p:?}");
}

/// Two decodings of one pose agree to the written digits: rotations to 1e-6, translations
/// to 1e-4 mm relative to their size.
pub fn assert_close(a: &[[f64; 4]; 4], b: &[[f64; 4]; 4]) {
    for i in 0..3 {
        for j in 0..3 {
            assert!((a[i][j] - b[i][j]).abs() <= 1e-6, "{a:?}\n{b:?}");
        }
        let size = a[i][3].abs().max(1.0);
        assert!((a[i][3] - b[i][3]).abs() <= 1e-4 * size, "{a:?}\n{b:?}");
    }
}
