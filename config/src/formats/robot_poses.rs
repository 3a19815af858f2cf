//! Robot pose files: one flange pose a line as the controller reports it, paired with the
//! calibration images by index (line k ↔ `frames/k`). Blank lines and `#` comments are
//! skipped; a header line `format CONVENTION UNIT` (e.g. `format kuka mm`) may come
//! first, or the caller gives the format. Parsing one line is `robot_pose.rs`'s.

use std::path::Path;

use crate::robot_pose::{parse_pose, LengthUnit, PoseConvention, RobotPoseFormat};
use crate::{Error, ErrorKind};

/// The poses of a file, base ← flange, row-major, mm.
#[derive(Debug, Clone, PartialEq)]
pub struct RobotPoses {
    /// The format the lines were read in.
    pub format: RobotPoseFormat,
    /// One pose per pose line, in order.
    pub poses: Vec<[[f64; 4]; 4]>,
    /// The 1-based line number of each pose, for messages.
    pub lines: Vec<usize>,
    /// Each pose line's text without its comment: what a reading in another format starts
    /// from (a pose read back would lose how the controller wrote its angles).
    pub texts: Vec<String>,
}

/// Parses a `format CONVENTION UNIT` header.
fn parse_header(rest: &str) -> Result<RobotPoseFormat, String> {
    let expected = format!(
        "expected `format CONVENTION UNIT` with CONVENTION one of {} and UNIT mm or m",
        PoseConvention::names()
    );
    let words: Vec<&str> = rest.split_whitespace().collect();
    let [convention, unit] = words[..] else { return Err(expected) };
    match (PoseConvention::from_name(convention), LengthUnit::from_name(unit)) {
        (Some(convention), Some(unit)) => Ok(RobotPoseFormat { convention, unit }),
        _ => Err(format!("{:?}: {expected}", rest.trim())),
    }
}

/// Reads the pose file at `path`. `given` is the format named outside the file (flags):
/// used when the file has no header, and refused when it contradicts the header.
pub fn read_robot_poses(path: &Path, given: Option<RobotPoseFormat>) -> Result<RobotPoses, Error> {
    // A pose file is a person's text file: bounded like every other (a device is refused).
    let text = super::read::read_text(path)?;
    parse_robot_poses(&text, given).map_err(|e| e.in_file(path))
}

/// Parses the text of a pose file (see [`read_robot_poses`]).
pub fn parse_robot_poses(text: &str, given: Option<RobotPoseFormat>) -> Result<RobotPoses, Error> {
    let mut format: Option<RobotPoseFormat> = None;
    let mut poses = Vec::new();
    let mut lines = Vec::new();
    let mut texts = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let number = i + 1;
        let line = raw.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let key = format!("line {number}");
        if let Some(rest) = line.strip_prefix("format").filter(|r| r.starts_with(char::is_whitespace)) {
            if format.is_some() || !poses.is_empty() {
                return Err(Error::new(ErrorKind::Format, key, "a second `format` line; expected it once, first"));
            }
            let header = parse_header(rest).map_err(|m| Error::new(ErrorKind::Format, key.clone(), m))?;
            if let Some(g) = given.filter(|g| *g != header) {
                return Err(Error::new(
                    ErrorKind::Value,
                    key,
                    format!("the file says `format {header}` but the flags say {g}; expected one format"),
                ));
            }
            format = Some(header);
            continue;
        }
        let f = match format.or(given) {
            Some(f) => f,
            None => {
                return Err(Error::new(
                    ErrorKind::Format,
                    key,
                    format!(
                        "a pose before any `format CONVENTION UNIT` line; expected one first (CONVENTION one of {}, \
                         UNIT mm or m) or --pose-format and --pose-unit",
                        PoseConvention::names()
                    ),
                ))
            }
        };
        format = Some(f);
        let pose = parse_pose(line, f).map_err(|m| Error::new(ErrorKind::Value, key, m))?;
        poses.push(pose);
        lines.push(number);
        texts.push(line.to_string());
    }
    let Some(format) = format.or(given) else {
        return Err(Error::new(ErrorKind::Format, "", "no poses; expected one pose a line"));
    };
    if poses.is_empty() {
        return Err(Error::new(ErrorKind::Format, "", "no poses; expected one pose a line"));
    }
    Ok(RobotPoses { format, poses, lines, texts })
}

/// The text of a pose file: a header naming `format`, then one line per pose.
pub fn robot_poses_text(poses: &[[[f64; 4]; 4]], format: RobotPoseFormat, comment: &str) -> String {
    let mut out = String::new();
    for line in comment.lines() {
        out.push_str(&format!("# {line}\n"));
    }
    out.push_str(&format!("format {format}\n"));
    for p in poses {
        out.push_str(&crate::robot_pose::format_pose(p, format));
        out.push('\n');
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    const KUKA_MM: RobotPoseFormat = RobotPoseFormat { convention: PoseConvention::Kuka, unit: LengthUnit::Mm };

    #[test]
    fn a_file_round_trips_with_its_header_and_comments() {
        let poses = vec![
            crate::robot_pose::parse_pose("100 200 300 10 20 30", KUKA_MM).unwrap(),
            crate::robot_pose::parse_pose("-100 50 700 -170 5 -30", KUKA_MM).unwrap(),
        ];
        let text = robot_poses_text(&poses, KUKA_MM, "flange poses\nof a test");
        let back = parse_robot_poses(&text, None).unwrap();
        assert_eq!(back.format, KUKA_MM);
        assert_eq!(back.lines, vec![4, 5]);
        for (a, b) in poses.iter().zip(&back.poses) {
            for (ra, rb) in a.iter().zip(b) {
                for (x, y) in ra.iter().zip(rb) {
                    assert!((x - y).abs() < 1e-6);
                }
            }
        }
        // The flags may repeat the header, not contradict it.
        assert!(parse_robot_poses(&text, Some(KUKA_MM)).is_ok());
        let m = RobotPoseFormat { unit: LengthUnit::M, ..KUKA_MM };
        let e = parse_robot_poses(&text, Some(m)).unwrap_err();
        assert_eq!(e.key(), "line 3");
        assert!(e.to_string().contains("flags say kuka m"), "{e}");
    }

    #[test]
    fn bad_lines_are_named() {
        let e = parse_robot_poses("# poses\n1 2 3 0 0 0\n", None).unwrap_err();
        assert_eq!(e.key(), "line 2");
        assert!(e.message().contains("format CONVENTION UNIT"), "{e}");
        let e = parse_robot_poses("format kuka cm\n", None).unwrap_err();
        assert!(e.message().contains("UNIT mm or m"), "{e}");
        let e = parse_robot_poses("format abb mm\n1 2 3 1 0 0 0\n4 5 6 0.9 0.9 0 0 # a typo\n", None).unwrap_err();
        assert_eq!(e.key(), "line 3");
        assert!(e.message().contains("not a rigid transform"), "{e}");
        let e = parse_robot_poses("format ur m\n", None).unwrap_err();
        assert!(e.message().contains("no poses"), "{e}");
        let ok = parse_robot_poses("1 2 3 0 0 0\n", Some(KUKA_MM)).unwrap();
        assert_eq!(ok.poses.len(), 1);
    }
}
