//! Hand-eye calibration: where the rig sits in the robot's frame, from views of a board and
//! the robot's pose at each. Eye-to-hand (the rig fixed, the board on the flange) solves
//! T_base_rig and T_flange_board; eye-in-hand (the rig on the flange, the board fixed)
//! T_flange_rig and T_base_board. Both are A_i·X = Z·B_i with A_i the robot's pose
//! (base ← flange) and B_i the board's pose as the calibrated rig saw it. A closed form
//! starts it (`closed_form.rs`), one Levenberg–Marquardt refines X and Z on the
//! reprojection error of every corner in both cameras, with a correction of each reported
//! robot pose held to the robot's accuracy (`refine.rs`), and a pose whose error stands out
//! is dropped and the rest solved again. The cameras are given, not refined.

mod board_poses;
mod closed_form;
mod readings;
mod refine;
#[cfg(test)]
mod tests;

use nalgebra::{Isometry3, Point3};

use super::board::{BoardView, CalibrationBoard};
use crate::camera::Camera;
use crate::error::{Error, ErrorKind, Result};
use crate::scoring::median_or_nan as median;
use board_poses::{board_pose_in_view, StereoPair};
pub use closed_form::RotationSpread;
use closed_form::{rotation_spread, solve_ax_zb};
pub use readings::{calibrate_hand_eye_paired, HandEyeError, PairedHandEye, PoseReading};
use refine::{corrected, expected_errors, refine, HandEyeProblem, Refined, Sigmas};

/// Fewest robot poses a hand-eye calibration takes: three fix X and Z, and two more let a
/// mis-paired pose stand out against the rest instead of deciding the result.
pub const MIN_HAND_EYE_POSES: usize = 5;
/// A pose stands out when its RMS reprojection error exceeds the median pose's by this many
/// robust standard deviations (1.4826 × the median absolute deviation) ...
pub const OUTLIER_MAD_FACTOR: f64 = 5.0;
/// ... and this multiple of the median: with a tight spread of errors the MAD alone would
/// drop poses that are only a little noisier than the rest.
pub const OUTLIER_MEDIAN_FACTOR: f64 = 3.0;
/// A pose stands out only above this score as well (its residuals' RMS in units of their
/// σ): a pose that fits scores about 1.
pub const OUTLIER_MIN_SCORE: f64 = 3.0;
/// The σ of a detected corner's position the refinement weighs pixels by, pixels (the
/// detector's error on the paper's noise is 0.04 px; real images are worse).
pub const CORNER_SIGMA_PX: f64 = 0.1;
/// The closed form leaves a pose out of its start only above this disagreement, mm.
const START_OUTLIER_MIN_MM: f64 = 1.0;
/// A pose agrees with a closed form from three poses below this disagreement, mm: far above
/// what the robot's and the cameras' errors make, far below what a mis-paired pose does.
const START_AGREEMENT_MM: f64 = 10.0;
/// A turn counts as the distance it moves a point this far from the rotation's centre, mm
/// (about a board's size).
const START_REACH_MM: f64 = 100.0;
/// The most triples of poses the start tries (evenly spread over all of them).
const MAX_START_TRIPLES: usize = 500;
/// Below this largest angle between the axes of the relative rotations, degrees, the poses
/// turned about one axis only, and X's rotation is not determined: an error.
pub const MIN_AXIS_SPREAD_DEG: f64 = 3.0;
/// Below this largest angle between axes, degrees, the translation along the common axis is
/// poorly determined: a warning.
pub const WARN_AXIS_SPREAD_DEG: f64 = 30.0;
/// An expected (1 σ) error of the rig's mounting above this translation, mm, or ...
pub const WARN_TRANSLATION_MM: f64 = 0.5;
/// ... this rotation, degrees, is warned of.
pub const WARN_ROTATION_DEG: f64 = 0.05;
/// A median pose score above this (the RMS of its residuals in units of their stated σ) is
/// not noise: the poses do not fit the images, and other readings of them are tried. Correct
/// poses score 0.4 to 1 (the detector's 0.04 px against the 0.1 px weighed; a robot five
/// times worse than stated about 1); poses read in the wrong convention, inverted, paired
/// one off or of the other setup score 50 and more.
pub const FIT_SCORE_LIMIT: f64 = 5.0;
/// The worst poses a refusal names.
const WORST_NAMED: usize = 3;

/// Where the rig is mounted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HandEyeSetup {
    /// The rig fixed above the cell, the board on the robot's flange.
    EyeToHand,
    /// The rig on the robot's flange, the board fixed in the cell.
    EyeInHand,
}

impl HandEyeSetup {
    /// `eye-to-hand` or `eye-in-hand`.
    pub fn name(self) -> &'static str {
        match self {
            HandEyeSetup::EyeToHand => "eye-to-hand",
            HandEyeSetup::EyeInHand => "eye-in-hand",
        }
    }
}

/// What a hand-eye calibration takes.
#[derive(Debug, Clone, Copy)]
pub struct HandEyeInput<'a> {
    /// Eye-to-hand or eye-in-hand.
    pub setup: HandEyeSetup,
    /// The board.
    pub board: &'a CalibrationBoard,
    /// The calibrated left camera; its frame is the rig's.
    pub left: &'a Camera,
    /// The calibrated right camera (its `t_world_camera` in the same frame as the left's).
    pub right: &'a Camera,
    /// The board's corners at each robot pose.
    pub views: &'a [BoardView],
    /// The robot's flange pose at each view, base ← flange, mm.
    pub t_base_flange: &'a [Isometry3<f64>],
    /// The robot's accuracy, 1 σ per axis of its reported translation, mm ...
    pub robot_sigma_mm: f64,
    /// ... and rotation, degrees.
    pub robot_sigma_deg: f64,
}

/// One robot pose's fit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseResidual {
    /// The pose's index in the input.
    pub index: usize,
    /// RMS reprojection distance over its corners in both cameras, pixels.
    pub rms_px: f64,
    /// The RMS of its residuals (corners and the correction of the robot's pose) in units
    /// of their σ: about 1 for a pose that fits.
    pub score: f64,
    /// The correction of the robot's reported pose the fit took: translation, mm ...
    pub translation_mm: f64,
    /// ... and rotation, degrees.
    pub rotation_deg: f64,
    /// Whether its error stood out and it was left out; its errors are then those under
    /// the final solution.
    pub dropped: bool,
}

/// The 1-σ errors to expect of the result, from the residuals and the poses' geometry.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExpectedError {
    /// Of the rig's mounting (T_base_rig or T_flange_rig): translation, mm.
    pub rig_translation_mm: f64,
    /// Of the rig's mounting: rotation, degrees.
    pub rig_rotation_deg: f64,
    /// Of the board's mounting (T_flange_board or T_base_board): translation, mm.
    pub board_translation_mm: f64,
    /// Of the board's mounting: rotation, degrees.
    pub board_rotation_deg: f64,
}

/// A hand-eye calibration's result.
#[derive(Debug, Clone, PartialEq)]
pub struct HandEyeCalibration {
    /// Eye-to-hand or eye-in-hand.
    pub setup: HandEyeSetup,
    /// The rig (left camera frame) in what holds it: T_base_rig eye-to-hand, T_flange_rig
    /// eye-in-hand.
    pub t_mount_rig: Isometry3<f64>,
    /// The board in what holds it: T_flange_board eye-to-hand, T_base_board eye-in-hand.
    pub t_mount_board: Isometry3<f64>,
    /// Every input pose's fit, in input order.
    pub poses: Vec<PoseResidual>,
    /// RMS reprojection distance over the kept poses' corners, pixels.
    pub rms_px: f64,
    /// How the robot's rotations spread.
    pub spread: RotationSpread,
    /// The errors to expect.
    pub expected: ExpectedError,
    /// What the user should know: a poorly determined translation, too little spread.
    pub warnings: Vec<String>,
}

/// Calibrates the hand-eye transform of `input`. Poses that do not fit the images (the
/// median pose's score above `FIT_SCORE_LIMIT`) are refused, with the reading of them
/// that fits when one does (another unit, inverted, paired one off, the other setup).
pub fn calibrate_hand_eye(input: &HandEyeInput<'_>) -> Result<HandEyeCalibration> {
    let prepared = prepare(input)?;
    match fit(input, &prepared) {
        Ok(cal) => Ok(cal),
        Err(Failure::Error(e)) => Err(e),
        Err(Failure::Misfit(misfit)) => {
            let frames: Vec<usize> = (0..input.views.len()).collect();
            let candidates = readings::pose_readings(input, &frames, input.t_base_flange, None);
            let fits = readings::diagnose(input, &prepared, &candidates);
            let worst = misfit.worst.iter().map(|i| format!("pose {i}")).collect();
            Err(Error::new(ErrorKind::Input, HandEyeError::misfit(&misfit, fits, worst).to_string()))
        }
    }
}

/// Why a fit failed: an error of the input, or poses that do not fit the images.
pub(super) enum Failure {
    Error(Error),
    Misfit(Misfit),
}

impl From<Error> for Failure {
    fn from(e: Error) -> Self {
        Failure::Error(e)
    }
}

/// How badly the poses as read fit the images.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Misfit {
    /// The median pose's RMS reprojection error, pixels.
    pub rms_px: f64,
    /// The worst poses (input indices), worst first.
    pub worst: Vec<usize>,
}

/// What every solve of one set of views shares: the board's pose in each view, once.
pub(super) struct Prepared {
    pub t_right_left: Isometry3<f64>,
    pub object: Vec<Point3<f64>>,
    /// The board in the left camera's frame, per view.
    pub t_left_board: Vec<Isometry3<f64>>,
}

impl Prepared {
    /// The B_i of `setup`: the board's pose as the rig saw it, or the rig's in the board's
    /// frame.
    pub fn b(&self, setup: HandEyeSetup) -> Vec<Isometry3<f64>> {
        match setup {
            HandEyeSetup::EyeToHand => self.t_left_board.clone(),
            HandEyeSetup::EyeInHand => self.t_left_board.iter().map(|t| t.inverse()).collect(),
        }
    }

    /// The views `kept` alone.
    pub fn subset(&self, kept: &[usize]) -> Prepared {
        Prepared {
            t_right_left: self.t_right_left,
            object: self.object.clone(),
            t_left_board: kept.iter().map(|&i| self.t_left_board[i]).collect(),
        }
    }
}

/// The checks that do not depend on the poses' reading, and the board's pose in each view.
fn prepare(input: &HandEyeInput<'_>) -> Result<Prepared> {
    let n = input.views.len();
    if input.t_base_flange.len() != n {
        return Err(Error::new(
            ErrorKind::Input,
            format!(
                "hand-eye: {n} board views but {} robot poses; expected one pose per view",
                input.t_base_flange.len()
            ),
        ));
    }
    if !(input.robot_sigma_mm > 0.0 && input.robot_sigma_deg > 0.0) {
        return Err(Error::new(
            ErrorKind::Input,
            format!(
                "hand-eye: robot accuracy {} mm, {}°; expected positive values",
                input.robot_sigma_mm, input.robot_sigma_deg
            ),
        ));
    }
    if n < MIN_HAND_EYE_POSES {
        return Err(Error::new(
            ErrorKind::Input,
            format!("hand-eye: {n} poses with the board seen, expected at least {MIN_HAND_EYE_POSES}"),
        ));
    }
    let t_right_left = input.right.t_world_camera.inverse() * input.left.t_world_camera;
    let pair = StereoPair { left: input.left, right: input.right, t_right_left };
    let object = input.board.object_points();
    let t_left_board: Vec<Isometry3<f64>> =
        input.views.iter().enumerate().map(|(i, v)| board_pose_in_view(&pair, &object, v, i)).collect::<Result<_>>()?;
    Ok(Prepared { t_right_left, object, t_left_board })
}

/// The calibration of `input` whose board poses are `prepared`'s; a misfit when the poses
/// as given do not fit the images.
pub(super) fn fit(input: &HandEyeInput<'_>, prepared: &Prepared) -> std::result::Result<HandEyeCalibration, Failure> {
    let n = input.views.len();
    let pair = StereoPair { left: input.left, right: input.right, t_right_left: prepared.t_right_left };
    let object = &prepared.object[..];
    let b = prepared.b(input.setup);
    let spread = rotation_spread(input.t_base_flange);
    if spread.informative_pairs == 0 {
        return Err(Error::new(
            ErrorKind::Input,
            format!(
                "hand-eye: the robot's {n} poses turn by at most {:.2}° against each other; expected turns of 10° or \
                 more about at least two axes",
                spread.max_rotation_deg
            ),
        )
        .into());
    }
    if spread.max_axis_angle_deg < MIN_AXIS_SPREAD_DEG {
        return Err(Error::new(
            ErrorKind::Input,
            format!(
                "hand-eye: the robot's {n} poses all turn about one axis (its turns' axes within {:.2}° of each \
                 other), which leaves the mounting undetermined; expected turns about at least two axes at 30° or more \
                 to each other",
                spread.max_axis_angle_deg
            ),
        )
        .into());
    }

    let all: Vec<usize> = (0..n).collect();
    // Poses that do not belong to the images can send the refinement anywhere, even to
    // values that are not finite: that is a misfit too, measured on the closed form.
    let first = match solve(input, &pair, object, &b, input.t_base_flange, &all) {
        Ok(first) => first,
        Err(_) => {
            let rms_px = readings::closed_form_px(input, prepared, input.setup, &all, input.t_base_flange);
            return Err(Failure::Misfit(Misfit { rms_px, worst: Vec::new() }));
        }
    };
    let median_score = median(&first.scores);
    if median_score.is_nan() || median_score > FIT_SCORE_LIMIT {
        let px: Vec<f64> = all
            .iter()
            .map(|&i| {
                pose_fit(&problem_of(input, &pair, object, input.t_base_flange, &[i]), &first, &first.deltas[i]).0
            })
            .collect();
        let mut worst: Vec<usize> = all.clone();
        worst.sort_by(|&p, &q| first.scores[q].total_cmp(&first.scores[p]));
        worst.truncate(WORST_NAMED);
        return Err(Failure::Misfit(Misfit { rms_px: median(&px), worst }));
    }

    // Drop the worst pose while it stands out, and solve again without it.
    let mut kept = all;
    let mut dropped = Vec::new();
    let mut current = first;
    loop {
        let threshold = outlier_threshold(&current.scores, OUTLIER_MIN_SCORE);
        let (worst, &worst_score) =
            current.scores.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1)).expect("at least the minimum poses");
        if worst_score <= threshold || kept.len() <= MIN_HAND_EYE_POSES {
            break;
        }
        dropped.push(kept.remove(worst));
        current = solve(input, &pair, object, &b, input.t_base_flange, &kept)?;
    }

    let problem = problem_of(input, &pair, object, input.t_base_flange, &kept);
    let [x_t, x_r, z_t, z_r] = expected_errors(&problem, &current);
    let expected = match input.setup {
        HandEyeSetup::EyeToHand => ExpectedError {
            rig_translation_mm: z_t,
            rig_rotation_deg: z_r,
            board_translation_mm: x_t,
            board_rotation_deg: x_r,
        },
        HandEyeSetup::EyeInHand => ExpectedError {
            rig_translation_mm: x_t,
            rig_rotation_deg: x_r,
            board_translation_mm: z_t,
            board_rotation_deg: z_r,
        },
    };
    let mut warnings = Vec::new();
    let kept_spread = rotation_spread(&kept.iter().map(|&i| input.t_base_flange[i]).collect::<Vec<_>>());
    if kept_spread.max_axis_angle_deg < WARN_AXIS_SPREAD_DEG {
        warnings.push(format!(
            "the robot's turns have axes within {:.1}° of each other; turn it about axes at least \
             {WARN_AXIS_SPREAD_DEG}° apart (tilt the flange both ways as well as turning it) to fix the translation",
            kept_spread.max_axis_angle_deg
        ));
    }
    if !(expected.rig_translation_mm <= WARN_TRANSLATION_MM && expected.rig_rotation_deg <= WARN_ROTATION_DEG) {
        warnings.push(format!(
            "the rig's mounting is poorly determined: expected error ±{:.2} mm, ±{:.3}° (1 σ) from {} poses; add \
             poses turned about other axes, spread over the view",
            expected.rig_translation_mm,
            expected.rig_rotation_deg,
            kept.len()
        ));
    }

    // Every pose's errors under the final solution; a dropped pose's with the correction
    // that best fits it alone.
    let poses = (0..n)
        .map(|i| {
            let delta = match kept.iter().position(|&k| k == i) {
                Some(p) => current.deltas[p],
                None => {
                    let one = problem_of(input, &pair, object, input.t_base_flange, &[i]);
                    refine_delta(&one, &current).unwrap_or([0.0; 6])
                }
            };
            let one = problem_of(input, &pair, object, input.t_base_flange, &[i]);
            let (rms_px, score) = pose_fit(&one, &current, &delta);
            PoseResidual {
                index: i,
                rms_px,
                score,
                translation_mm: (delta[3] * delta[3] + delta[4] * delta[4] + delta[5] * delta[5]).sqrt(),
                rotation_deg: (delta[0] * delta[0] + delta[1] * delta[1] + delta[2] * delta[2]).sqrt().to_degrees(),
                dropped: dropped.contains(&i),
            }
        })
        .collect::<Vec<_>>();
    let kept_px: Vec<f64> = poses.iter().filter(|p| !p.dropped).map(|p| p.rms_px).collect();
    let rms_px = (kept_px.iter().map(|r| r * r).sum::<f64>() / kept_px.len() as f64).sqrt();
    Ok(HandEyeCalibration {
        setup: input.setup,
        t_mount_rig: match input.setup {
            HandEyeSetup::EyeToHand => current.z,
            HandEyeSetup::EyeInHand => current.x,
        },
        t_mount_board: match input.setup {
            HandEyeSetup::EyeToHand => current.x,
            HandEyeSetup::EyeInHand => current.z,
        },
        poses,
        rms_px,
        spread: kept_spread,
        expected,
        warnings,
    })
}

/// The refinement problem over the poses `kept`.
fn problem_of<'a>(
    input: &'a HandEyeInput<'a>,
    pair: &'a StereoPair<'a>,
    object: &'a [Point3<f64>],
    a: &[Isometry3<f64>],
    kept: &[usize],
) -> HandEyeProblem<'a> {
    HandEyeProblem {
        pair,
        object,
        setup: input.setup,
        views: kept.iter().map(|&i| &input.views[i]).collect(),
        a: kept.iter().map(|&i| a[i]).collect(),
        sigmas: Sigmas {
            corner_px: CORNER_SIGMA_PX,
            robot_mm: input.robot_sigma_mm,
            robot_rad: input.robot_sigma_deg.to_radians(),
        },
    }
}

/// The one view of `problem`'s RMS reprojection error (pixels) and score under X and Z of
/// `solution` with the robot's pose corrected by `delta`.
fn pose_fit(problem: &HandEyeProblem<'_>, solution: &Refined, delta: &[f64; 6]) -> (f64, f64) {
    let corners = problem.object.len();
    let mut out = vec![0.0; 4 * corners];
    let view = problem.views[0];
    let pose = HandEyeProblem::t_left_board(problem.setup, &corrected(&problem.a[0], delta), &solution.x, &solution.z);
    problem.pair.residuals(problem.object, view, &pose, &mut out);
    let seen = 2 * corners * (view.left.is_some() as usize + view.right.is_some() as usize);
    let squares = out.iter().map(|e| e * e).sum::<f64>();
    let s = &problem.sigmas;
    let prior = (0..3).map(|i| (delta[i] / s.robot_rad).powi(2) + (delta[3 + i] / s.robot_mm).powi(2)).sum::<f64>();
    ((squares / (seen / 2) as f64).sqrt(), ((squares / (s.corner_px * s.corner_px) + prior) / (seen + 6) as f64).sqrt())
}

/// The correction of the one view of `problem` that best fits it under X and Z held at
/// `solution`'s.
fn refine_delta(problem: &HandEyeProblem<'_>, solution: &Refined) -> Result<[f64; 6]> {
    let held = refine::HeldMounting { problem, x: solution.x, z: solution.z };
    let mut x = nalgebra::DVector::zeros(6);
    super::lm::minimise(&held, &mut x, "hand-eye pose")?;
    Ok(std::array::from_fn(|i| x[i]))
}

/// The closed form over `kept` (poses whose A·X and Z·B disagree far more than the rest's
/// left out of it, so a mis-paired pose does not spoil the start), then the refinement over
/// all of `kept`.
fn solve(
    input: &HandEyeInput<'_>,
    pair: &StereoPair<'_>,
    object: &[Point3<f64>],
    b: &[Isometry3<f64>],
    a: &[Isometry3<f64>],
    kept: &[usize],
) -> Result<Refined> {
    let not_fixed = || {
        Error::new(
            ErrorKind::Input,
            "hand-eye: the robot's turns do not fix the mounting's rotation; expected turns about at least two axes",
        )
    };
    // A pose's disagreement under (X, Z): how far A·X and Z·B put a point a board's size
    // from the origin apart, mm.
    let disagreement = |i: usize, x: &Isometry3<f64>, z: &Isometry3<f64>| {
        let d = (z * b[i]).inverse() * (a[i] * x);
        d.translation.vector.norm() + START_REACH_MM * d.rotation.angle()
    };
    // The closed form from triples of poses, the one that agrees with the most poses
    // kept (a mis-paired pose agrees with none), then from all that agree with it.
    let n = kept.len();
    let total = n * (n - 1) * (n - 2) / 6;
    let stride = total.div_ceil(MAX_START_TRIPLES).max(1);
    let mut best: Option<(usize, f64, Vec<usize>)> = None;
    let mut index = 0;
    for i in 0..n {
        for j in i + 1..n {
            for k in j + 1..n {
                index += 1;
                if (index - 1) % stride != 0 {
                    continue;
                }
                let three = [kept[i], kept[j], kept[k]];
                let Some((x, z)) = solve_ax_zb(&three.map(|p| a[p]), &three.map(|p| b[p])) else { continue };
                let d: Vec<f64> = kept.iter().map(|&p| disagreement(p, &x, &z)).collect();
                let agreeing: Vec<usize> =
                    kept.iter().zip(&d).filter(|(_, &v)| v < START_AGREEMENT_MM).map(|(&p, _)| p).collect();
                let spread: f64 = d.iter().map(|v| v.min(START_AGREEMENT_MM)).sum();
                if best
                    .as_ref()
                    .is_none_or(|(count, s, _)| agreeing.len() > *count || (agreeing.len() == *count && spread < *s))
                {
                    best = Some((agreeing.len(), spread, agreeing));
                }
            }
        }
    }
    let mut inliers = match best {
        Some((count, _, agreeing)) if count >= 3 => agreeing,
        _ => kept.to_vec(),
    };
    let mut start = None;
    // At most a third of the poses are left out of the start.
    for _ in 0..=kept.len() / 3 {
        let a_in: Vec<Isometry3<f64>> = inliers.iter().map(|&i| a[i]).collect();
        let b_in: Vec<Isometry3<f64>> = inliers.iter().map(|&i| b[i]).collect();
        let (x, z) = solve_ax_zb(&a_in, &b_in).ok_or_else(not_fixed)?;
        start = Some((x, z));
        let disagreements: Vec<f64> = inliers.iter().map(|&i| disagreement(i, &x, &z)).collect();
        let threshold = outlier_threshold(&disagreements, START_OUTLIER_MIN_MM);
        let (worst, &worst_value) =
            disagreements.iter().enumerate().max_by(|p, q| p.1.total_cmp(q.1)).expect("poses to solve from");
        if worst_value <= threshold || inliers.len() < MIN_HAND_EYE_POSES {
            break;
        }
        inliers.remove(worst);
    }
    let start = start.ok_or_else(not_fixed)?;
    let refined = refine(&problem_of(input, pair, object, a, &inliers), start)?;
    if inliers.len() == kept.len() {
        return Ok(refined);
    }
    // The poses left out of the start, judged under the others' solution: all of them are
    // taken back when none stands out; else each keeps its own fit, for the caller to drop
    // the worst.
    let threshold = outlier_threshold(&refined.scores, OUTLIER_MIN_SCORE);
    let mut deltas = Vec::with_capacity(kept.len());
    let mut scores = Vec::with_capacity(kept.len());
    for &i in kept {
        match inliers.iter().position(|&k| k == i) {
            Some(p) => {
                deltas.push(refined.deltas[p]);
                scores.push(refined.scores[p]);
            }
            None => {
                let one = problem_of(input, pair, object, a, &[i]);
                let delta = refine_delta(&one, &refined)?;
                deltas.push(delta);
                scores.push(pose_fit(&one, &refined, &delta).1);
            }
        }
    }
    if scores.iter().all(|&s| s <= threshold) {
        return refine(&problem_of(input, pair, object, a, kept), (refined.x, refined.z));
    }
    Ok(Refined { x: refined.x, z: refined.z, deltas, scores })
}

/// Above this a value stands out among `values`: median + k·σ_MAD, k'·median and `floor`.
fn outlier_threshold(values: &[f64], floor: f64) -> f64 {
    let m = median(values);
    let deviations: Vec<f64> = values.iter().map(|v| (v - m).abs()).collect();
    let sigma = 1.4826 * median(&deviations);
    (m + OUTLIER_MAD_FACTOR * sigma).max(OUTLIER_MEDIAN_FACTOR * m).max(floor)
}
