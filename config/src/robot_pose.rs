//! Robot poses as controllers print them: one codec for the conventions of the big vendors
//! (a 4 × 4 matrix, x y z with a quaternion either way round, UR's rotation vector, KUKA's
//! A B C, ABB's quaternion, FANUC's W P R), in mm or m. It parses one line into a rigid
//! transform in mm and formats one transform back; reading whole files is
//! `formats/robot_poses.rs`'s.
//!
//! Definitions (the rotation R of the flange, or tool, in the base frame):
//! - `matrix`: 16 numbers (or the top 12), row-major, translation in the last column.
//! - `quat-wxyz`, `abb`: x y z qw qx qy qz (ABB's `robtarget`: q1 the scalar part).
//! - `quat-xyzw`: x y z qx qy qz qw (ROS's order).
//! - `ur`: x y z rx ry rz, the rotation vector (axis × angle, radians) of UR's `p[...]`.
//! - `kuka`: X Y Z A B C (deg), intrinsic Z-Y'-X'': R = Rz(A)·Ry(B)·Rx(C).
//! - `fanuc`: X Y Z W P R (deg), fixed axes X then Y then Z: R = Rz(R)·Ry(P)·Rx(W).

use std::fmt;

use crate::check_rigid;

/// How far a quaternion's norm may be from 1 before it is not a rotation: controllers print
/// five to nine decimals, far inside it.
pub const QUATERNION_NORM_TOLERANCE: f64 = 1e-3;

/// How a controller writes a pose's rotation, and in which order its numbers come.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PoseConvention {
    /// 16 (or 12) numbers, row-major 4 × 4.
    Matrix,
    /// x y z qw qx qy qz.
    QuatWxyz,
    /// x y z qx qy qz qw.
    QuatXyzw,
    /// Universal Robots: x y z rx ry rz, rotation vector in radians.
    Ur,
    /// KUKA: X Y Z A B C, degrees, R = Rz(A)·Ry(B)·Rx(C).
    Kuka,
    /// ABB: x y z q1 q2 q3 q4, q1 the scalar part.
    Abb,
    /// FANUC: X Y Z W P R, degrees, R = Rz(R)·Ry(P)·Rx(W).
    Fanuc,
}

impl PoseConvention {
    /// Every convention, in the order the docs list them.
    pub const ALL: [PoseConvention; 7] = [
        PoseConvention::Matrix,
        PoseConvention::QuatWxyz,
        PoseConvention::QuatXyzw,
        PoseConvention::Ur,
        PoseConvention::Kuka,
        PoseConvention::Abb,
        PoseConvention::Fanuc,
    ];

    /// The name files and flags use.
    pub fn name(self) -> &'static str {
        match self {
            PoseConvention::Matrix => "matrix",
            PoseConvention::QuatWxyz => "quat-wxyz",
            PoseConvention::QuatXyzw => "quat-xyzw",
            PoseConvention::Ur => "ur",
            PoseConvention::Kuka => "kuka",
            PoseConvention::Abb => "abb",
            PoseConvention::Fanuc => "fanuc",
        }
    }

    /// The convention called `name` (as [`PoseConvention::name`] gives it).
    pub fn from_name(name: &str) -> Option<PoseConvention> {
        PoseConvention::ALL.into_iter().find(|c| c.name().eq_ignore_ascii_case(name.trim()))
    }

    /// The names of all conventions, for messages.
    pub fn names() -> String {
        PoseConvention::ALL.map(|c| c.name()).join(", ")
    }

    /// What one line holds, for messages.
    pub fn fields(self) -> &'static str {
        match self {
            PoseConvention::Matrix => "16 numbers (or 12), a row-major 4x4 rigid transform",
            PoseConvention::QuatWxyz => "7 numbers: x y z qw qx qy qz",
            PoseConvention::QuatXyzw => "7 numbers: x y z qx qy qz qw",
            PoseConvention::Ur => "6 numbers: x y z rx ry rz (rotation vector, rad)",
            PoseConvention::Kuka => "6 numbers: X Y Z A B C (deg)",
            PoseConvention::Abb => "7 numbers: x y z q1 q2 q3 q4 (q1 the scalar)",
            PoseConvention::Fanuc => "6 numbers: X Y Z W P R (deg)",
        }
    }
}

impl fmt::Display for PoseConvention {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The unit of a pose's translation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LengthUnit {
    /// Millimetres (KUKA, ABB, FANUC).
    Mm,
    /// Metres (UR, ROS).
    M,
}

impl LengthUnit {
    /// Millimetres in one unit.
    pub fn mm(self) -> f64 {
        match self {
            LengthUnit::Mm => 1.0,
            LengthUnit::M => 1000.0,
        }
    }

    /// The name files and flags use (`mm` or `m`).
    pub fn name(self) -> &'static str {
        match self {
            LengthUnit::Mm => "mm",
            LengthUnit::M => "m",
        }
    }

    /// The unit called `name`.
    pub fn from_name(name: &str) -> Option<LengthUnit> {
        match name.trim().to_ascii_lowercase().as_str() {
            "mm" => Some(LengthUnit::Mm),
            "m" => Some(LengthUnit::M),
            _ => None,
        }
    }
}

impl fmt::Display for LengthUnit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A convention and a unit: all it takes to read or write a pose line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RobotPoseFormat {
    /// The rotation's convention and the order of the numbers.
    pub convention: PoseConvention,
    /// The translation's unit.
    pub unit: LengthUnit,
}

impl RobotPoseFormat {
    /// The format written `"CONVENTION UNIT"` (`"ur m"`, `"kuka mm"`), as it displays;
    /// the error says what was expected.
    pub fn from_text(text: &str) -> Result<RobotPoseFormat, String> {
        let words: Vec<&str> = text.split_whitespace().collect();
        let expected = || {
            format!(
                "expected \"CONVENTION UNIT\" with a convention of {} and a unit of mm, m; got {text:?}",
                PoseConvention::names()
            )
        };
        match words[..] {
            [c, u] => match (PoseConvention::from_name(c), LengthUnit::from_name(u)) {
                (Some(convention), Some(unit)) => Ok(RobotPoseFormat { convention, unit }),
                _ => Err(expected()),
            },
            _ => Err(expected()),
        }
    }
}

impl fmt::Display for RobotPoseFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} {}", self.convention, self.unit)
    }
}

type Rotation = [[f64; 3]; 3];

/// Parses one pose line into a rigid transform (base ← flange, row-major, mm). Numbers are
/// separated by spaces, commas or semicolons; brackets and UR's leading `p` are ignored, so
/// `p[0.1, 0.2, 0.3, 0, 0, 0]` and `[[1,2,3],[1,0,0,0]]` read as they print. The error says
/// what was expected.
pub fn parse_pose(line: &str, format: RobotPoseFormat) -> Result<[[f64; 4]; 4], String> {
    let trimmed = line.trim();
    let body = trimmed.strip_prefix('p').filter(|r| r.trim_start().starts_with('[')).unwrap_or(trimmed);
    let mut numbers = Vec::with_capacity(16);
    for token in body.split(|c: char| c.is_whitespace() || ",;[]()".contains(c)).filter(|t| !t.is_empty()) {
        match token.parse::<f64>() {
            Ok(v) if v.is_finite() => numbers.push(v),
            _ => {
                return Err(format!(
                    "{token:?} is not a finite number; expected {} ({})",
                    format.convention.fields(),
                    format
                ))
            }
        }
    }
    let c = format.convention;
    let count_ok = match c {
        PoseConvention::Matrix => numbers.len() == 16 || numbers.len() == 12,
        PoseConvention::QuatWxyz | PoseConvention::QuatXyzw | PoseConvention::Abb => numbers.len() == 7,
        PoseConvention::Ur | PoseConvention::Kuka | PoseConvention::Fanuc => numbers.len() == 6,
    };
    if !count_ok {
        return Err(format!("{} numbers, expected {} ({format})", numbers.len(), c.fields()));
    }
    let scale = format.unit.mm();
    let (rotation, t) = match c {
        PoseConvention::Matrix => {
            let mut m = [[0.0; 4]; 4];
            for (i, v) in numbers.iter().enumerate() {
                m[i / 4][i % 4] = *v;
            }
            if numbers.len() == 12 {
                m[3] = [0.0, 0.0, 0.0, 1.0];
            }
            check_rigid(&m).map_err(|e| format!("not a rigid transform: {e}"))?;
            let r = [[m[0][0], m[0][1], m[0][2]], [m[1][0], m[1][1], m[1][2]], [m[2][0], m[2][1], m[2][2]]];
            (r, [m[0][3], m[1][3], m[2][3]])
        }
        PoseConvention::QuatWxyz | PoseConvention::Abb => {
            (quaternion_rotation([numbers[3], numbers[4], numbers[5], numbers[6]])?, xyz(&numbers))
        }
        PoseConvention::QuatXyzw => {
            (quaternion_rotation([numbers[6], numbers[3], numbers[4], numbers[5]])?, xyz(&numbers))
        }
        PoseConvention::Ur => (rotation_vector_rotation([numbers[3], numbers[4], numbers[5]])?, xyz(&numbers)),
        PoseConvention::Kuka => (zyx_rotation(numbers[3], numbers[4], numbers[5]), xyz(&numbers)),
        PoseConvention::Fanuc => (zyx_rotation(numbers[5], numbers[4], numbers[3]), xyz(&numbers)),
    };
    let mut out = [[0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]];
    for i in 0..3 {
        out[i][..3].copy_from_slice(&rotation[i]);
        out[i][3] = t[i] * scale;
    }
    // Finite numbers can still make an infinite translation once scaled to mm.
    check_rigid(&out).map_err(|e| format!("not a rigid transform: {e} ({format})"))?;
    Ok(out)
}

/// Formats a rigid transform (row-major, mm) as one line of `format`, numbers separated by
/// single spaces, with the digits a controller's pose needs to round-trip far below 1 µm and
/// 1e-6°.
pub fn format_pose(t: &[[f64; 4]; 4], format: RobotPoseFormat) -> String {
    let length_digits = match format.unit {
        LengthUnit::Mm => 5,
        LengthUnit::M => 8,
    };
    format_pose_with(t, format, |v, kind| match kind {
        Number::Length => format!("{v:.length_digits$}"),
        Number::Unitless => format!("{v:.10}"),
        Number::Degrees => format!("{v:.8}"),
    })
}

/// Formats like [`format_pose`], every number in the fewest digits that read back as the
/// same `f64`: a pose handed on and parsed back is the transform it came from to rounding
/// (1e-12 and below), not to a controller's display digits.
pub fn format_pose_exact(t: &[[f64; 4]; 4], format: RobotPoseFormat) -> String {
    format_pose_with(t, format, |v, _| format!("{v}"))
}

/// What a number of a pose line stands for, so a formatter can choose its digits.
#[derive(Clone, Copy)]
enum Number {
    Length,
    Unitless,
    Degrees,
}

fn format_pose_with(t: &[[f64; 4]; 4], format: RobotPoseFormat, number: impl Fn(f64, Number) -> String) -> String {
    let scale = format.unit.mm();
    let len = |v: f64| number(v / scale, Number::Length);
    let one = |v: f64| number(v, Number::Unitless);
    let deg = |v: f64| number(v, Number::Degrees);
    let xyz = format!("{} {} {}", len(t[0][3]), len(t[1][3]), len(t[2][3]));
    let r = [[t[0][0], t[0][1], t[0][2]], [t[1][0], t[1][1], t[1][2]], [t[2][0], t[2][1], t[2][2]]];
    match format.convention {
        PoseConvention::Matrix => {
            let mut parts = Vec::with_capacity(16);
            for (i, row) in t.iter().enumerate() {
                for (j, v) in row.iter().enumerate() {
                    parts.push(if j == 3 && i < 3 { len(*v) } else { one(*v) });
                }
            }
            parts.join(" ")
        }
        PoseConvention::QuatWxyz | PoseConvention::Abb => {
            let [w, qx, qy, qz] = rotation_quaternion(&r);
            format!("{xyz} {} {} {} {}", one(w), one(qx), one(qy), one(qz))
        }
        PoseConvention::QuatXyzw => {
            let [w, qx, qy, qz] = rotation_quaternion(&r);
            format!("{xyz} {} {} {} {}", one(qx), one(qy), one(qz), one(w))
        }
        PoseConvention::Ur => {
            let [rx, ry, rz] = rotation_vector(&r);
            format!("{xyz} {} {} {}", one(rx), one(ry), one(rz))
        }
        PoseConvention::Kuka => {
            let (a, b, c) = zyx_angles(&r);
            format!("{xyz} {} {} {}", deg(a), deg(b), deg(c))
        }
        PoseConvention::Fanuc => {
            let (rz, p, w) = zyx_angles(&r);
            format!("{xyz} {} {} {}", deg(w), deg(p), deg(rz))
        }
    }
}

fn xyz(numbers: &[f64]) -> [f64; 3] {
    [numbers[0], numbers[1], numbers[2]]
}

/// The rotation of quaternion (w, x, y, z), which must have unit norm.
fn quaternion_rotation(q: [f64; 4]) -> Result<Rotation, String> {
    let norm = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    // The numbers are finite, so a norm that overflowed is infinite and refused here.
    if (norm - 1.0).abs() > QUATERNION_NORM_TOLERANCE {
        return Err(format!(
            "not a rigid transform: the quaternion's norm is {norm:.6}, expected 1 (within {QUATERNION_NORM_TOLERANCE})"
        ));
    }
    let [w, x, y, z] = q.map(|v| v / norm);
    Ok([
        [1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - w * z), 2.0 * (x * z + w * y)],
        [2.0 * (x * y + w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - w * x)],
        [2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y)],
    ])
}

/// The unit quaternion (w, x, y, z) of a rotation, w ≥ 0 (Shepperd's method: the largest
/// of the four squares decides, so no division is by a small number).
fn rotation_quaternion(r: &Rotation) -> [f64; 4] {
    let trace = r[0][0] + r[1][1] + r[2][2];
    let q = if trace > r[0][0].max(r[1][1]).max(r[2][2]) {
        let s = 2.0 * (1.0 + trace).sqrt();
        [s / 4.0, (r[2][1] - r[1][2]) / s, (r[0][2] - r[2][0]) / s, (r[1][0] - r[0][1]) / s]
    } else if r[0][0] >= r[1][1] && r[0][0] >= r[2][2] {
        let s = 2.0 * (1.0 + r[0][0] - r[1][1] - r[2][2]).sqrt();
        [(r[2][1] - r[1][2]) / s, s / 4.0, (r[0][1] + r[1][0]) / s, (r[0][2] + r[2][0]) / s]
    } else if r[1][1] >= r[2][2] {
        let s = 2.0 * (1.0 + r[1][1] - r[0][0] - r[2][2]).sqrt();
        [(r[0][2] - r[2][0]) / s, (r[0][1] + r[1][0]) / s, s / 4.0, (r[1][2] + r[2][1]) / s]
    } else {
        let s = 2.0 * (1.0 + r[2][2] - r[0][0] - r[1][1]).sqrt();
        [(r[1][0] - r[0][1]) / s, (r[0][2] + r[2][0]) / s, (r[1][2] + r[2][1]) / s, s / 4.0]
    };
    let norm = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    let sign = if q[0] < 0.0 { -1.0 } else { 1.0 };
    q.map(|v| sign * v / norm)
}

/// The rotation of rotation vector `v` (axis × angle, radians), by Rodrigues' formula. The
/// angle is the vector's length, taken scaled so that large finite components do not
/// overflow; a length past what a float holds is refused.
fn rotation_vector_rotation(v: [f64; 3]) -> Result<Rotation, String> {
    let largest = v.iter().fold(0.0f64, |m, c| m.max(c.abs()));
    if largest < 1e-300 {
        return Ok([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]);
    }
    let angle = largest * v.iter().map(|c| (c / largest) * (c / largest)).sum::<f64>().sqrt();
    if !angle.is_finite() {
        return Err(format!(
            "not a rigid transform: the rotation vector [{}, {}, {}] is longer than a number holds",
            v[0], v[1], v[2]
        ));
    }
    let half = angle / 2.0;
    let s = half.sin() / angle;
    quaternion_rotation([half.cos(), v[0] * s, v[1] * s, v[2] * s])
}

/// The rotation vector of a rotation, its angle in [0, π].
fn rotation_vector(r: &Rotation) -> [f64; 3] {
    let [w, x, y, z] = rotation_quaternion(r);
    let sin_half = (x * x + y * y + z * z).sqrt();
    if sin_half < 1e-300 {
        return [0.0; 3];
    }
    let angle = 2.0 * sin_half.atan2(w);
    [x, y, z].map(|v| v / sin_half * angle)
}

/// Rz(a)·Ry(b)·Rx(c), angles in degrees.
fn zyx_rotation(a_deg: f64, b_deg: f64, c_deg: f64) -> Rotation {
    let (sa, ca) = a_deg.to_radians().sin_cos();
    let (sb, cb) = b_deg.to_radians().sin_cos();
    let (sc, cc) = c_deg.to_radians().sin_cos();
    [
        [ca * cb, ca * sb * sc - sa * cc, ca * sb * cc + sa * sc],
        [sa * cb, sa * sb * sc + ca * cc, sa * sb * cc - ca * sc],
        [-sb, cb * sc, cb * cc],
    ]
}

/// (a, b, c) in degrees with R = Rz(a)·Ry(b)·Rx(c), b in [-90, 90]. At b = ±90° only a ∓ c
/// is defined: c is then 0, as the controllers report it.
fn zyx_angles(r: &Rotation) -> (f64, f64, f64) {
    let cb = (r[0][0] * r[0][0] + r[1][0] * r[1][0]).sqrt();
    let b = (-r[2][0]).atan2(cb);
    if cb < 1e-12 {
        let a = (-r[0][1]).atan2(r[1][1]);
        return (a.to_degrees(), b.to_degrees(), 0.0);
    }
    let a = r[1][0].atan2(r[0][0]);
    let c = r[2][1].atan2(r[2][2]);
    (a.to_degrees(), b.to_degrees(), c.to_degrees())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mul(a: &Rotation, b: &Rotation) -> Rotation {
        let mut out = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                out[i][j] = (0..3).map(|k| a[i][k] * b[k][j]).sum();
            }
        }
        out
    }

    /// An elementary rotation about axis `axis` (0 x, 1 y, 2 z) by `deg`, written out.
    fn elementary(axis: usize, deg: f64) -> Rotation {
        let (s, c) = deg.to_radians().sin_cos();
        match axis {
            0 => [[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]],
            1 => [[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]],
            _ => [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]],
        }
    }

    /// The rotation about unit axis `n` by `angle` radians as the sum I + sinθ K + (1-cosθ) K².
    fn axis_angle(n: [f64; 3], angle: f64) -> Rotation {
        let k = [[0.0, -n[2], n[1]], [n[2], 0.0, -n[0]], [-n[1], n[0], 0.0]];
        let k2 = mul(&k, &k);
        let mut r = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                r[i][j] = if i == j { 1.0 } else { 0.0 } + angle.sin() * k[i][j] + (1.0 - angle.cos()) * k2[i][j];
            }
        }
        r
    }

    fn pose(r: &Rotation, t: [f64; 3]) -> [[f64; 4]; 4] {
        let mut m = [[0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]];
        for i in 0..3 {
            m[i][..3].copy_from_slice(&r[i]);
            m[i][3] = t[i];
        }
        m
    }

    fn max_difference(a: &[[f64; 4]; 4], b: &[[f64; 4]; 4]) -> (f64, f64) {
        let mut rot: f64 = 0.0;
        let mut tr: f64 = 0.0;
        for i in 0..3 {
            for j in 0..3 {
                rot = rot.max((a[i][j] - b[i][j]).abs());
            }
            tr = tr.max((a[i][3] - b[i][3]).abs());
        }
        (rot, tr)
    }

    /// A fixed spread of test rotations: random-looking angle triples, the three gimbal
    /// locks of the Euler conventions and their neighbourhood, half turns.
    fn angle_triples() -> Vec<[f64; 3]> {
        let mut out = vec![
            [0.0, 0.0, 0.0],
            [180.0, 0.0, 0.0],
            [0.0, 0.0, 180.0],
            [37.0, 90.0, 0.0],
            [37.0, -90.0, 12.0],
            [-120.0, 89.9999, 45.0],
            [10.0, -89.99999, -170.0],
            [179.9, 0.1, -179.9],
        ];
        let mut s: u64 = 0x9E37_79B9_7F4A_7C15;
        for _ in 0..200 {
            let mut next = || {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                (s >> 11) as f64 / (1u64 << 53) as f64
            };
            out.push([next() * 360.0 - 180.0, next() * 180.0 - 90.0, next() * 360.0 - 180.0]);
        }
        out
    }

    #[test]
    fn every_convention_round_trips_against_elementary_rotations() {
        for (k, [a, b, c]) in angle_triples().into_iter().enumerate() {
            // The brute-force rotation: three elementary rotations multiplied out.
            let r = mul(&mul(&elementary(2, a), &elementary(1, b)), &elementary(0, c));
            let truth = pose(&r, [412.5 - k as f64, -97.25, 803.0 + 0.001 * k as f64]);
            for convention in PoseConvention::ALL {
                for unit in [LengthUnit::Mm, LengthUnit::M] {
                    let format = RobotPoseFormat { convention, unit };
                    let line = format_pose(&truth, format);
                    let back = parse_pose(&line, format).unwrap_or_else(|e| panic!("{format}: {line}: {e}"));
                    let (rot, tr) = max_difference(&truth, &back);
                    assert!(rot < 1e-8 && tr < 1e-4, "{format} {a} {b} {c}: {line}: {rot} {tr}");
                    let exact = format_pose_exact(&truth, format);
                    let back = parse_pose(&exact, format).unwrap_or_else(|e| panic!("{format}: {exact}: {e}"));
                    let (rot, tr) = max_difference(&truth, &back);
                    assert!(rot < 1e-9 && tr < 1e-9, "exact {format} {a} {b} {c}: {exact}: {rot} {tr}");
                }
            }
        }
    }

    #[test]
    fn a_reply_format_reads_as_it_displays_and_names_what_it_expects() {
        for convention in PoseConvention::ALL {
            for unit in [LengthUnit::Mm, LengthUnit::M] {
                let format = RobotPoseFormat { convention, unit };
                assert_eq!(RobotPoseFormat::from_text(&format.to_string()), Ok(format));
            }
        }
        for bad in ["ur", "ur cm", "euler mm", "ur m extra", ""] {
            let e = RobotPoseFormat::from_text(bad).unwrap_err();
            assert!(e.contains("CONVENTION UNIT") && e.contains("fanuc"), "{bad}: {e}");
        }
    }

    #[test]
    fn euler_conventions_mean_what_the_manuals_say() {
        for [a, b, c] in angle_triples() {
            let r = mul(&mul(&elementary(2, a), &elementary(1, b)), &elementary(0, c));
            let truth = pose(&r, [1.0, 2.0, 3.0]);
            let mm = |convention| RobotPoseFormat { convention, unit: LengthUnit::Mm };
            let kuka = parse_pose(&format!("1 2 3 {a} {b} {c}"), mm(PoseConvention::Kuka)).unwrap();
            assert!(max_difference(&truth, &kuka).0 < 1e-12, "kuka {a} {b} {c}");
            // FANUC W P R about fixed X, Y, Z: W = c about x first, then P = b, then R = a.
            let fanuc = parse_pose(&format!("1 2 3 {c} {b} {a}"), mm(PoseConvention::Fanuc)).unwrap();
            assert!(max_difference(&truth, &fanuc).0 < 1e-12, "fanuc {a} {b} {c}");
        }
    }

    #[test]
    fn quaternions_and_rotation_vectors_mean_what_the_manuals_say() {
        let n = {
            let v = [0.3, -0.5, 0.8f64];
            let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            v.map(|x| x / l)
        };
        for angle_deg in [0.0, 1e-7, 30.0, 90.0, 179.0, 180.0] {
            let angle = f64::to_radians(angle_deg);
            let truth = pose(&axis_angle(n, angle), [0.0; 3]);
            let (s, w) = ((angle / 2.0).sin(), (angle / 2.0).cos());
            let [x, y, z] = n.map(|v| v * s);
            let m = LengthUnit::M;
            let check = |line: String, convention| {
                let back = parse_pose(&line, RobotPoseFormat { convention, unit: m }).unwrap();
                assert!(max_difference(&truth, &back).0 < 1e-12, "{convention} {line}");
            };
            check(format!("0 0 0 {w} {x} {y} {z}"), PoseConvention::QuatWxyz);
            check(format!("0 0 0 {w} {x} {y} {z}"), PoseConvention::Abb);
            check(format!("0 0 0 {x} {y} {z} {w}"), PoseConvention::QuatXyzw);
            let [rx, ry, rz] = n.map(|v| v * angle);
            check(format!("p[0, 0, 0, {rx}, {ry}, {rz}]"), PoseConvention::Ur);
        }
    }

    #[test]
    fn units_scale_the_translation_only() {
        let ur = |unit| RobotPoseFormat { convention: PoseConvention::Ur, unit };
        let m = parse_pose("0.45 -0.12 0.3 0 0 0", ur(LengthUnit::M)).unwrap();
        let mm = parse_pose("450 -120 300 0 0 0", ur(LengthUnit::Mm)).unwrap();
        assert!(max_difference(&m, &mm).1 < 1e-9);
        assert_eq!(m[0][0], 1.0);
    }

    #[test]
    fn bad_lines_say_what_was_expected() {
        let f = |convention| RobotPoseFormat { convention, unit: LengthUnit::Mm };
        let e = parse_pose("1 2 3 4 5", f(PoseConvention::Kuka)).unwrap_err();
        assert!(e.contains("5 numbers") && e.contains("A B C"), "{e}");
        let e = parse_pose("1 2 3 0.5 0.5 0.5 0.9", f(PoseConvention::Abb)).unwrap_err();
        assert!(e.contains("not a rigid transform") && e.contains("norm"), "{e}");
        let e = parse_pose("1 2 3 x 0 0", f(PoseConvention::Fanuc)).unwrap_err();
        assert!(e.contains("\"x\""), "{e}");
        let e = parse_pose("2 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1", f(PoseConvention::Matrix)).unwrap_err();
        assert!(e.contains("not a rigid transform"), "{e}");
        let e = parse_pose("1 2 3 0 0 nan", f(PoseConvention::Ur)).unwrap_err();
        assert!(e.contains("finite"), "{e}");
        // Finite numbers whose squares or mm overflow: refused, never an infinite or NaN pose.
        assert!(
            parse_pose("1 2 3 0 0 1e308", f(PoseConvention::Ur)).is_ok(),
            "a long finite rotation vector is a rotation"
        );
        let e = parse_pose("1 2 3 1.5e308 1.5e308 0", f(PoseConvention::Ur)).unwrap_err();
        assert!(e.contains("rotation vector"), "{e}");
        let e = parse_pose("1 2 3 1e200 0 0 0", f(PoseConvention::QuatWxyz)).unwrap_err();
        assert!(e.contains("norm"), "{e}");
        let m = RobotPoseFormat { convention: PoseConvention::Kuka, unit: LengthUnit::M };
        let e = parse_pose("1e306 0 0 0 0 0", m).unwrap_err();
        assert!(e.contains("finite numbers"), "{e}");
    }

    /// Long rotation vectors read as the rotation of their angle modulo a turn, as the
    /// formula says, and what is read is always a finite rigid transform.
    #[test]
    fn any_finite_rotation_vector_reads_as_a_rigid_transform() {
        let f = RobotPoseFormat { convention: PoseConvention::Ur, unit: LengthUnit::Mm };
        for exponent in [-300, -20, 0, 3, 50, 150, 154, 155, 200, 300, 307] {
            for v in [[1.0, 0.0, 0.0], [0.6, -0.8, 0.0], [1.0, 1.0, 1.0]] {
                let scale = 10f64.powi(exponent);
                let line = format!("0 0 0 {} {} {}", v[0] * scale, v[1] * scale, v[2] * scale);
                let t = parse_pose(&line, f).unwrap();
                assert!(check_rigid(&t).is_ok(), "{line}: {t:?}");
            }
        }
        let quarter = parse_pose(&format!("0 0 0 0 0 {}", std::f64::consts::FRAC_PI_2 + 8.0 * std::f64::consts::PI), f);
        let [[a, b, _, _], ..] = quarter.unwrap();
        assert!(a.abs() < 1e-9 && (b + 1.0).abs() < 1e-9, "a quarter turn about z, four turns later");
    }
}
