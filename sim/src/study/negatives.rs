//! A scene's hard negatives: wrong poses made from the truth that a verification must
//! reject, beside the one wrong pose (if any) RANSAC happens to produce. Each turn the
//! tray's listed symmetries do not make the same tray (about its centre, or laying its slot
//! grid onto itself), the truth moved by a slot's pitch either way along both slot
//! directions, and the truth tilted off the table; each refined against the frame by ICP
//! as the pipeline refines a RANSAC pose, then verified. A negative refined back within
//! the success limits is recorded as such and is no negative; one refined to a near miss
//! (within `GROSS_FACTOR` times a limit) is recorded as one, apart from the gross.

use camplace_config::Metrics;
use camplace_estimator::pose::pose_errors;
use camplace_estimator::scoring::{gross_error, NegativeRecord};
use camplace_estimator::Estimator;
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

use crate::Result;

/// The tilt of the `tilt` negative about the tray's x axis, deg: past the verification's
/// resting limit (4°), a tray propped on its items or the gripper.
pub const TILT_DEG: f64 = 10.0;

/// The negatives of a tray at `truth` (world frame), each with its kind.
pub fn hard_negatives(estimator: &Estimator, truth: &Isometry3<f64>) -> Vec<(&'static str, Isometry3<f64>)> {
    let model = estimator.model();
    let mut out = Vec::new();
    for a in estimator.verifier().turn_parts.alternatives.list().iter().filter(|a| !a.listed(model)) {
        out.push((if a.about_centre() { "turn" } else { "grid turn" }, truth * a.transform()));
    }
    for d in estimator.verifier().pitches.into_iter().flatten() {
        for d in [d, -d] {
            out.push(("shift", truth * Translation3::from(d)));
        }
    }
    let tilt = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), TILT_DEG.to_radians());
    out.push(("tilt", truth * tilt));
    out
}

/// The hard negatives of the frame `estimator` processed last, whose tray stood at
/// `truth`: each refined, verified and scored against the truth under the model's
/// symmetries and `metrics`.
pub fn weigh_negatives(
    estimator: &mut Estimator,
    truth: &Isometry3<f64>,
    metrics: &Metrics,
) -> Result<Vec<NegativeRecord>> {
    let mut out = Vec::new();
    for (kind, start) in hard_negatives(estimator, truth) {
        let refined = estimator.refine(&start)?;
        let v = estimator.verify(&refined);
        let errors = pose_errors(&refined, truth, &estimator.model().symmetries_deg, metrics);
        out.push(NegativeRecord {
            kind: kind.to_string(),
            verdict: v.verdict.as_str().to_string(),
            score: v.score,
            position_error_mm: errors.position_mm,
            rotation_error_deg: errors.rotation_deg,
            correct: errors.success,
            gross: gross_error(errors.position_mm, errors.rotation_deg, metrics),
        });
    }
    Ok(out)
}
