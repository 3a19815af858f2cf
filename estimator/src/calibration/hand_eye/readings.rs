//! When the robot's poses do not fit the images: the other readings of the same numbers
//! (another convention or unit, angles in the other unit, the poses inverted, paired one
//! frame off, the other setup), each solved cheaply by the closed form, the best refined,
//! and the one that fits named in a one-line refusal. Also the typed call that pairs a
//! pose file's lines with the frames' views and calibrates; listing the frames and finding
//! their corners is hwio's.

use std::fmt;

use camplace_config::{parse_pose, LengthUnit, PoseConvention, RobotPoseFormat, RobotPoses};
use nalgebra::Isometry3;

use super::board_poses::StereoPair;
use super::closed_form::solve_ax_zb;
use super::refine::HandEyeProblem;
use super::{
    fit, median, prepare, Failure, HandEyeCalibration, HandEyeInput, HandEyeSetup, Misfit, Prepared, CORNER_SIGMA_PX,
    MIN_HAND_EYE_POSES,
};
use crate::calibration::board::{BoardView, CalibrationBoard};
use crate::camera::{isometry_from_rows, Camera};
use crate::error::Error;

/// A flange farther than this from the robot's base, mm, is not a robot's pose: the largest
/// arms reach about 4 m.
pub const MAX_REACH_MM: f64 = 100_000.0;
/// The readings refined after the closed form ranked them: the best two (the runner-up
/// when the best's refinement still does not fit).
const REFINED_READINGS: usize = 2;

/// A reading of the robot's poses other than the one given.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum PoseReading {
    /// The lines in convention `fits` instead of `read`.
    Convention { read: PoseConvention, fits: PoseConvention },
    /// The translations written in `written`, read as `read`.
    Unit { written: LengthUnit, read: LengthUnit },
    /// The rotation's numbers written in degrees but read as radians (`true`), or the
    /// reverse (`false`).
    AnglesInDegrees(bool),
    /// Each pose inverted: the base in the flange's frame instead of the flange in the
    /// base's.
    Inverted,
    /// Frame k paired with pose k + this (one line too many or too few at the start).
    Shifted(i8),
    /// The other setup than the one given.
    Setup(HandEyeSetup),
}

impl PoseReading {
    /// The reading and what to check, for a refusal: "{reading} they fit (… px): {check}".
    fn phrases(self) -> (String, String) {
        match self {
            PoseReading::Convention { read, fits } => {
                (format!("read as {fits} instead of {read}"), "check the file's format line".into())
            }
            PoseReading::Unit { written, read } => (
                format!("with the translations in {written} instead of {read}"),
                format!("the translations are in {written} but were read as {read}; check the unit the file names"),
            ),
            PoseReading::AnglesInDegrees(true) => (
                "with the rotation's numbers in degrees instead of radians".into(),
                "the controller wrote degrees; convert them to radians".into(),
            ),
            PoseReading::AnglesInDegrees(false) => (
                "with the rotation's numbers in radians instead of degrees".into(),
                "the controller wrote radians; convert them to degrees".into(),
            ),
            // A_i·X = Z·B_i inverted is A_i⁻¹·Z = X·B_i⁻¹: inverted poses and the other
            // setup fit alike, so both are named.
            PoseReading::Inverted => (
                "inverted (the base in the flange's frame), or with the other setup (the two fit alike)".into(),
                "expected each line to be the flange's pose in the base frame, and --eye-in-hand only for a rig on \
                 the flange"
                    .into(),
            ),
            PoseReading::Shifted(s) => (
                format!("paired one frame off (frame k with pose k {} 1)", if s > 0 { "+" } else { "−" }),
                "check that the first pose line belongs to the first frame".into(),
            ),
            PoseReading::Setup(setup) => (
                format!(
                    "as {} instead of {}, or inverted (the two fit alike)",
                    setup.name(),
                    other_setup(setup).name()
                ),
                format!(
                    "the images are {}'s ({} --eye-in-hand), or each line is the base in the flange's frame",
                    setup.name(),
                    if setup == HandEyeSetup::EyeInHand { "give" } else { "leave out" }
                ),
            ),
        }
    }
}

/// Why a hand-eye calibration of paired views and poses was refused.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub enum HandEyeError {
    /// Inputs that cannot be calibrated whatever the poses mean: counts, too few poses,
    /// turns about one axis, a view without corners.
    Input(Error),
    /// A pose line absurd on its own (a typo, a stray exponent).
    AbsurdPose {
        /// Where it is: `line N`.
        line: String,
        /// The flange's distance from the base as read, mm.
        distance_mm: f64,
    },
    /// The poses do not fit the images.
    Misfit {
        /// The median pose's RMS reprojection error as read, pixels.
        rms_px: f64,
        /// What a fit leaves, pixels (the corners' σ weighed).
        expected_px: f64,
        /// The reading that fits, with its RMS reprojection error, pixels.
        fits: Option<(PoseReading, f64)>,
        /// The worst poses (`line N` or `pose N`), worst first.
        worst: Vec<String>,
    },
}

impl HandEyeError {
    pub(super) fn misfit(misfit: &Misfit, fits: Option<(PoseReading, f64)>, worst: Vec<String>) -> HandEyeError {
        HandEyeError::Misfit { rms_px: misfit.rms_px, expected_px: CORNER_SIGMA_PX, fits, worst }
    }
}

impl fmt::Display for HandEyeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            HandEyeError::Input(e) => write!(f, "{e}"),
            HandEyeError::AbsurdPose { line, distance_mm } => write!(
                f,
                "{line}: the flange {distance_mm:.3e} mm from the robot's base; expected a robot's reach (under \
                 {MAX_REACH_MM:.0} mm): a mistyped number?"
            ),
            HandEyeError::Misfit { rms_px, expected_px, fits, worst } => {
                let rms = if rms_px.is_finite() { format!("RMS {rms_px:.1} px") } else { "no finite RMS".into() };
                write!(f, "hand-eye: the poses do not fit the images ({rms}, expected about {expected_px} px); ")?;
                match fits {
                    Some((reading, px)) => {
                        let (how, check) = reading.phrases();
                        write!(f, "{how} they fit ({px:.2} px): {check}")
                    }
                    None => {
                        write!(
                            f,
                            "no other reading fits either (conventions, units, angles in degrees or radians, \
                             inverted, paired one frame off, the other setup)"
                        )?;
                        if !worst.is_empty() {
                            write!(f, "; the worst: {}", worst.join(", "))?;
                        }
                        write!(f, "; expected each pose line to be the flange's pose when its frame was taken")
                    }
                }
            }
        }
    }
}

impl std::error::Error for HandEyeError {}

/// A reading to try: the views it pairs (indices of the input's) with its poses, and the
/// setup it solves.
pub(super) struct Candidate {
    reading: PoseReading,
    setup: HandEyeSetup,
    views: Vec<usize>,
    a: Vec<Isometry3<f64>>,
}

fn other_setup(setup: HandEyeSetup) -> HandEyeSetup {
    match setup {
        HandEyeSetup::EyeToHand => HandEyeSetup::EyeInHand,
        HandEyeSetup::EyeInHand => HandEyeSetup::EyeToHand,
    }
}

/// The other readings of `input`'s poses. `frames[v]` is view v's frame and `all` every
/// frame's pose (seen or not), so a pairing one frame off can be tried; `file` the pose
/// file's lines when the numbers are at hand (conventions and angle units need them).
pub(super) fn pose_readings(
    input: &HandEyeInput<'_>,
    frames: &[usize],
    all: &[Isometry3<f64>],
    file: Option<&RobotPoses>,
) -> Vec<Candidate> {
    let views: Vec<usize> = (0..input.views.len()).collect();
    let mut out = Vec::new();
    let mut push = |reading: PoseReading, setup: HandEyeSetup, views: Vec<usize>, a: Vec<Isometry3<f64>>| {
        out.push(Candidate { reading, setup, views, a });
    };
    // Another reading of each line's numbers: every convention that parses them, the other
    // unit, the angles in the other unit.
    // Poses without their texts (made by hand) are read again from their numbers only.
    let mut formats: Vec<(PoseReading, RobotPoseFormat, Option<f64>)> = Vec::new();
    match file.filter(|f| !f.texts.is_empty()) {
        Some(file) => {
            let f = file.format;
            for c in PoseConvention::ALL.into_iter().filter(|&c| c != f.convention) {
                formats.push((
                    PoseReading::Convention { read: f.convention, fits: c },
                    RobotPoseFormat { convention: c, unit: f.unit },
                    None,
                ));
            }
            let other = if f.unit == LengthUnit::Mm { LengthUnit::M } else { LengthUnit::Mm };
            formats.push((
                PoseReading::Unit { written: other, read: f.unit },
                RobotPoseFormat { unit: other, ..f },
                None,
            ));
            if matches!(f.convention, PoseConvention::Ur | PoseConvention::Kuka | PoseConvention::Fanuc) {
                let radians_per_degree = 1f64.to_radians();
                // A UR file in degrees was read as radians: its numbers times π/180 are what
                // the controller meant; a KUKA or FANUC file in radians was read as degrees.
                let written_deg = f.convention == PoseConvention::Ur;
                let (first, second) = if written_deg {
                    (radians_per_degree, 1.0 / radians_per_degree)
                } else {
                    (1.0 / radians_per_degree, radians_per_degree)
                };
                formats.push((PoseReading::AnglesInDegrees(written_deg), f, Some(first)));
                formats.push((PoseReading::AnglesInDegrees(!written_deg), f, Some(second)));
            }
            let mut seen: Vec<Vec<Isometry3<f64>>> = vec![all.to_vec()];
            for (reading, format, angle_scale) in formats {
                let parsed: Option<Vec<Isometry3<f64>>> = file
                    .texts
                    .iter()
                    .map(|t| {
                        let text = match angle_scale {
                            Some(k) => scaled_angles(t, k)?,
                            None => t.clone(),
                        };
                        parse_pose(&text, format).ok().map(|rows| isometry_from_rows(&rows))
                    })
                    .collect();
                let Some(parsed) = parsed else { continue };
                // quat-wxyz and abb read the same numbers alike: one is enough.
                if seen.iter().any(|s| same_poses(s, &parsed)) {
                    continue;
                }
                seen.push(parsed.clone());
                push(reading, input.setup, views.clone(), frames.iter().map(|&k| parsed[k]).collect());
            }
        }
        None => {
            for (factor, written, read) in
                [(1000.0, LengthUnit::M, LengthUnit::Mm), (0.001, LengthUnit::Mm, LengthUnit::M)]
            {
                let a = input
                    .t_base_flange
                    .iter()
                    .map(|t| Isometry3::from_parts((t.translation.vector * factor).into(), t.rotation))
                    .collect();
                push(PoseReading::Unit { written, read }, input.setup, views.clone(), a);
            }
        }
    }
    push(PoseReading::Inverted, input.setup, views.clone(), input.t_base_flange.iter().map(|t| t.inverse()).collect());
    for shift in [1i8, -1] {
        let (mut v, mut a) = (Vec::new(), Vec::new());
        for (view, &frame) in frames.iter().enumerate() {
            let pose = frame as i64 + shift as i64;
            if (0..all.len() as i64).contains(&pose) {
                v.push(view);
                a.push(all[pose as usize]);
            }
        }
        push(PoseReading::Shifted(shift), input.setup, v, a);
    }
    let other = other_setup(input.setup);
    push(PoseReading::Setup(other), other, views, input.t_base_flange.to_vec());
    out
}

/// Whether two lists of poses are the same to far below any robot's accuracy.
fn same_poses(a: &[Isometry3<f64>], b: &[Isometry3<f64>]) -> bool {
    a.len() == b.len()
        && a.iter().zip(b).all(|(p, q)| {
            let d = p.inverse() * q;
            d.translation.vector.norm() < 1e-6 && d.rotation.angle() < 1e-9
        })
}

/// A pose line of six numbers with its last three (the rotation's) times `k`; `None` when
/// the line is not six numbers.
fn scaled_angles(text: &str, k: f64) -> Option<String> {
    let trimmed = text.trim();
    let body = trimmed.strip_prefix('p').filter(|r| r.trim_start().starts_with('[')).unwrap_or(trimmed);
    let mut numbers: Vec<f64> = body
        .split(|c: char| c.is_whitespace() || ",;[]()".contains(c))
        .filter(|t| !t.is_empty())
        .map(|t| t.parse::<f64>().ok())
        .collect::<Option<_>>()?;
    if numbers.len() != 6 {
        return None;
    }
    numbers[3..].iter_mut().for_each(|v| *v *= k);
    Some(numbers.iter().map(|v| format!("{v:?}")).collect::<Vec<_>>().join(" "))
}

/// The median pose's RMS reprojection error, pixels, of the closed form of `setup` from the
/// views `views` (of `input`) paired with `a`, the robot's poses taken as given; infinite
/// where the closed form has no solution.
pub(super) fn closed_form_px(
    input: &HandEyeInput<'_>,
    prepared: &Prepared,
    setup: HandEyeSetup,
    views: &[usize],
    a: &[Isometry3<f64>],
) -> f64 {
    let b_all = prepared.b(setup);
    let b: Vec<Isometry3<f64>> = views.iter().map(|&v| b_all[v]).collect();
    if views.len() < 3 {
        return f64::INFINITY;
    }
    let Some((x, z)) = solve_ax_zb(a, &b) else { return f64::INFINITY };
    let pair = StereoPair { left: input.left, right: input.right, t_right_left: prepared.t_right_left };
    let mut out = vec![0.0; 4 * prepared.object.len()];
    let px: Vec<f64> = views
        .iter()
        .zip(a)
        .map(|(&v, a)| {
            let view = &input.views[v];
            let pose = HandEyeProblem::t_left_board(setup, a, &x, &z);
            pair.residuals(&prepared.object, view, &pose, &mut out);
            let seen = prepared.object.len() * (view.left.is_some() as usize + view.right.is_some() as usize);
            (out.iter().map(|e| e * e).sum::<f64>() / seen.max(1) as f64).sqrt()
        })
        .collect();
    let m = median(&px);
    if m.is_finite() {
        m
    } else {
        f64::INFINITY
    }
}

/// The reading among `candidates` that fits, with its RMS reprojection error, pixels: the
/// closed form ranks them, and the best are refined and held to the same limit as the poses
/// as given.
pub(super) fn diagnose(
    input: &HandEyeInput<'_>,
    prepared: &Prepared,
    candidates: &[Candidate],
) -> Option<(PoseReading, f64)> {
    let mut ranked: Vec<(f64, &Candidate)> = candidates
        .iter()
        .filter(|c| c.views.len() >= MIN_HAND_EYE_POSES)
        .map(|c| (closed_form_px(input, prepared, c.setup, &c.views, &c.a), c))
        .filter(|(px, _)| px.is_finite())
        .collect();
    ranked.sort_by(|p, q| p.0.total_cmp(&q.0));
    for (_, c) in ranked.into_iter().take(REFINED_READINGS) {
        let views: Vec<BoardView> = c.views.iter().map(|&v| input.views[v].clone()).collect();
        let other = HandEyeInput { setup: c.setup, views: &views, t_base_flange: &c.a, ..*input };
        if let Ok(cal) = fit(&other, &prepared.subset(&c.views)) {
            return Some((c.reading, cal.rms_px));
        }
    }
    None
}

/// Views of a calibration's frames paired with a pose file's lines, one line a frame in the
/// frames' order.
#[derive(Debug, Clone, Copy)]
pub struct PairedHandEye<'a> {
    /// Eye-to-hand or eye-in-hand.
    pub setup: HandEyeSetup,
    /// The board.
    pub board: &'a CalibrationBoard,
    /// The calibrated left camera; its frame is the rig's.
    pub left: &'a Camera,
    /// The calibrated right camera.
    pub right: &'a Camera,
    /// Each frame's board corners; `None` where neither camera saw the whole board.
    pub frames: &'a [Option<BoardView>],
    /// The pose file, one pose a frame.
    pub poses: &'a RobotPoses,
    /// The robot's accuracy, 1 σ per axis of its reported translation, mm ...
    pub robot_sigma_mm: f64,
    /// ... and rotation, degrees.
    pub robot_sigma_deg: f64,
}

/// Calibrates the hand-eye transform from the frames and the pose lines of `job`: a line
/// absurd on its own is named before any solve, and poses that do not fit the images are
/// refused with the reading of them that does (another convention, unit or angle unit,
/// inverted, paired one frame off, the other setup), or the worst lines when none does.
/// Each [`PoseResidual`](super::PoseResidual)'s index is its frame's (and pose line's).
pub fn calibrate_hand_eye_paired(job: &PairedHandEye<'_>) -> Result<HandEyeCalibration, HandEyeError> {
    let n = job.frames.len();
    let poses = job.poses;
    if poses.poses.len() != n {
        return Err(HandEyeError::Input(Error::new(
            crate::error::ErrorKind::Input,
            format!("{} poses, but {n} frames; expected one pose a frame, in the frames' order", poses.poses.len()),
        )));
    }
    // A `RobotPoses` made by hand rather than parsed: each pose needs its line number, and
    // its text where the other readings are tried.
    if poses.lines.len() != n || !(poses.texts.is_empty() || poses.texts.len() == n) {
        return Err(HandEyeError::Input(Error::new(
            crate::error::ErrorKind::Input,
            format!(
                "{n} poses with {} line numbers and {} texts; expected a line number for each pose and a text for \
                 each or none",
                poses.lines.len(),
                poses.texts.len()
            ),
        )));
    }
    let all: Vec<Isometry3<f64>> = poses.poses.iter().map(isometry_from_rows).collect();
    let far: Vec<usize> = (0..n).filter(|&i| all[i].translation.vector.norm() > MAX_REACH_MM).collect();
    // Most lines beyond any reach is a unit read wrong, which the readings below name; a few
    // are typos.
    if let Some(&first) = far.first().filter(|_| 2 * far.len() < n) {
        return Err(HandEyeError::AbsurdPose {
            line: format!("line {}", poses.lines[first]),
            distance_mm: all[first].translation.vector.norm(),
        });
    }
    let seen: Vec<usize> = (0..n).filter(|&k| job.frames[k].is_some()).collect();
    let views: Vec<BoardView> = seen.iter().filter_map(|&k| job.frames[k].clone()).collect();
    let a: Vec<Isometry3<f64>> = seen.iter().map(|&k| all[k]).collect();
    let input = HandEyeInput {
        setup: job.setup,
        board: job.board,
        left: job.left,
        right: job.right,
        views: &views,
        t_base_flange: &a,
        robot_sigma_mm: job.robot_sigma_mm,
        robot_sigma_deg: job.robot_sigma_deg,
    };
    let prepared = prepare(&input).map_err(HandEyeError::Input)?;
    let result = if far.is_empty() {
        fit(&input, &prepared)
    } else {
        // Translations beyond any reach make the refinement's steps meaningless: the
        // readings decide without it.
        let all_views: Vec<usize> = (0..views.len()).collect();
        let rms_px = closed_form_px(&input, &prepared, input.setup, &all_views, &a);
        let worst = (0..seen.len()).filter(|&v| far.contains(&seen[v])).collect();
        Err(Failure::Misfit(Misfit { rms_px, worst }))
    };
    match result {
        Ok(mut cal) => {
            cal.poses.iter_mut().for_each(|p| p.index = seen[p.index]);
            Ok(cal)
        }
        Err(Failure::Error(e)) => Err(HandEyeError::Input(e)),
        Err(Failure::Misfit(misfit)) => {
            let candidates = pose_readings(&input, &seen, &all, Some(poses));
            let fits = diagnose(&input, &prepared, &candidates);
            let worst = misfit.worst.iter().map(|&i| format!("line {}", poses.lines[seen[i]])).collect();
            Err(HandEyeError::misfit(&misfit, fits, worst))
        }
    }
}
