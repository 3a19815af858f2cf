//! Pose verification, after ICP: evidence beyond RANSAC's consensus that the model at the
//! found pose explains what the sensor measured, summed up as a score in [0, 1] and a
//! verdict (`accepted` or `rejected: <reason>`). It owns the evidence and the decision; the
//! scene index it reads is RANSAC's and the whole-tray lookup is ICP's.
//!
//! The evidence, each a share in [0, 1]:
//! - coverage: of the tray's surface (not the slots' items: which slots hold one is the
//!   scene's) that faces the sensor in the closest view, the share with a measured point
//!   within the inlier distance (the tray is where the model says), leaving out the points
//!   the measured depth shows hidden behind something nearer (a gripper over the tray) or
//!   did not measure;
//! - explained: of the measured points inside the tray's box at the pose, the share the
//!   model explains (nothing stands where the model says there is free space);
//! - turn margin: of the scene points the pose and its closest alternative that the tray's
//!   symmetries do not list (a quarter turn, or a turn that lays the slot grid onto itself
//!   shifted: `Alternatives`) explain differently, how many more only the pose explains (a
//!   near-symmetric tray is told from its turn by a small feature alone, so only the points
//!   where the two differ count);
//! - see-through: of the tray's sensor-facing points at the pose that fall on a measured
//!   pixel of the left camera, the share the sensor saw past (`see_through`), against the
//!   same share of the pose moved by one slot's pitch each way: a tray shifted by a slot's
//!   pitch explains the points it lies on as well as the right pose, but its end wall
//!   floats where the camera saw the table, and the pose a pitch back does not. The share
//!   itself depends on the depth method (one-shot stereo smears thin walls: 3–7 % on right
//!   poses, phase-12 0.2 %), so the pose is judged against its neighbours, not a level;
//! - turn see-through: the same count over the pose's own distinct parts (those its turn
//!   lacks: a tab) against the turn's over its own. Where the tab stands behind the tray's
//!   far wall no scene point lies on it, yet the camera saw the table where the wrong turn
//!   puts it.
//!
//! The score is coverage × explained: both must be high for a pose to be right, and each
//! falls with a different kind of wrong pose (a shifted or half-seen tray loses coverage,
//! another object under the model loses explained share). The threshold is measured in
//! simulation and travels with the model. The turn margin is no part of the score: a
//! turned pose explains as much as the right one, so it is judged apart, as a count.

use std::fmt;

use camplace_config::EstimatorParams;
use nalgebra::{Isometry3, Point3, Translation3, Vector3};
use rayon::prelude::*;

use crate::pose::alternatives::{Alternative, Alternatives, MAX_ALTERNATIVES};
use crate::pose::icp::ExplainedCounts;
use crate::pose::icp::DISTINCT_MARGIN;
use crate::pose::see_through::{
    all_tray_points, see_through, slot_pitches, thin_tray_points, turn_see_through, DepthEvidence, SeeThroughCounts,
    Sight, TurnParts,
};
use crate::pose::self_occlusion::Occluder;
use crate::spatial::SceneGrid;
use crate::{Icp, Model};

/// A pose is ambiguous when the scene points on its distinct parts (where the tray and an
/// unlisted quarter turn of it differ, `Icp::explained_near_and_apart`) exceed those on the
/// turn's by fewer than this many standard deviations (counts taken as Poisson, so the
/// difference's deviation is the root of their sum); the pipeline's turn check takes the
/// turn when the turn's exceed the pose's by as many. With no point on either's parts the
/// scene neither confirms nor denies the turn, and the pose stands. Measured with the
/// `verify_features` example (one shot, 200 scenes each): correct poses of tray-8 at
/// r=605, alpha=32 stood at 1.9 and higher (seed 1; 6.4 at the 5th percentile), the one
/// half turn there at −0.16; at r=1000, alpha=60 (150 scenes of seed 5) 117 of 130
/// correct poses and 9 of 20 half turns stood at 1 or higher, 104 and 4 at 2, 96 and 2 at
/// 3: where the camera barely sees the tab the turns cannot be told, and the score's
/// threshold takes the half turns that pass.
pub const AMBIGUOUS_TURN_SIGMAS: f32 = 1.0;
/// Scene points on an alternative's distinct parts exceeding those on the pose's by this
/// many standard deviations make the pose ambiguous against it even where the camera saw
/// past the alternative's parts and not past the pose's: the scene's points and its depth
/// then contradict each other, and the pose is not handed on.
pub const CONFLICTING_TURN_SIGMAS: f32 = 3.0;
/// A pose is seen through when the camera saw past its tray surface on a share larger, by
/// at least this many standard deviations (two proportions), than the pose moved by one
/// slot's pitch, and by at least [`SEE_THROUGH_MIN_EXCESS`]. Measured with `camplace
/// evaluate --scenarios 300` (seed 1): at tray-8's quick-study placement (phase-12, r=450,
/// alpha=10, baseline=120) the 13 poses it rejected, each a pitch off and accepted by the
/// score, stood at 9–16 % against 0.3–3.7 % a pitch back, and none of 260 correct poses
/// fell; at the paper's optimum (one-shot) the correct poses stood at 4–11 % against 11 %
/// and more a pitch away, none rejected.
pub const SEE_THROUGH_SIGMAS: f32 = 4.0;
/// The smallest excess share over the shifted pose that makes a pose seen through.
pub const SEE_THROUGH_MIN_EXCESS: f32 = 0.02;
/// Fewer tested points than this, at the pose or at the shifted pose, are no evidence.
pub const SEE_THROUGH_MIN_TESTED: u32 = 200;
/// A pose is turned the wrong way when the camera saw past its own distinct parts (those
/// an unlisted quarter turn lacks) on a share larger, by at least this many standard
/// deviations and by [`TURN_SEE_THROUGH_MIN_EXCESS`], than it saw past the turn's. Measured
/// with the `verify_features` example (300 scenes, seed 1): at tray-8's quick-study
/// placement (phase-12) the half turns stood at 0.81–1.0 with the right tab untested, the
/// correct poses' own share at most 0.04 above their turn's; at the paper's optimum (one
/// shot, whose captured model smears the walls beside the tab) the right pose's tab parts
/// stood at 0.43–0.47 against 0.59–0.61 at the half turn (`tests/verify.rs`).
pub const TURN_SEE_THROUGH_SIGMAS: f32 = 3.0;
/// The smallest excess share over the turn's that makes a pose turned the wrong way.
pub const TURN_SEE_THROUGH_MIN_EXCESS: f32 = 0.1;
/// Where too few of the turn's parts were tested to weigh, the share of the pose's own
/// parts seen past that alone makes the pose turned the wrong way.
pub const TURN_SEE_THROUGH_ALONE: f32 = 0.5;
/// Fewer tested distinct points than this, at the pose or at its turn, are no evidence.
pub const TURN_SEE_THROUGH_MIN_TESTED: u32 = 30;
/// A tray resting on the table has its bottom within this of the table, mm.
pub const RESTING_HEIGHT_MM: f64 = 6.0;
/// A tray resting on the table has its z axis within this of the world's, deg.
pub const RESTING_TILT_DEG: f64 = 4.0;

/// The largest share of a view's facing points the coverage sets aside as hidden or
/// unmeasured.
pub const MOST_HIDDEN: f32 = 0.6;

/// View points per parallel task of the coverage count.
const COVERAGE_CHUNK: usize = 2048;
/// Facing points the coverage count hands the scene grid at once.
const COVERAGE_BATCH: usize = 64;

/// Why a pose is not handed on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Verdict {
    /// The pose is handed to the robot.
    Accepted,
    /// No pose passed RANSAC's checks: nothing in view looks like the tray.
    #[default]
    NoTray,
    /// The pose does not rest on the table.
    OffTable,
    /// A turn the tray's symmetries do not list explains the data almost as well.
    Ambiguous,
    /// The camera saw past where the model puts the tray's surface.
    SeenThrough,
    /// The score is below the model's threshold.
    PoorFit,
}

impl Verdict {
    /// Whether the pose may be handed on.
    pub fn accepted(self) -> bool {
        self == Verdict::Accepted
    }

    /// The verdict as written in JSON lines: `accepted` or `rejected: <reason>`.
    pub fn as_str(self) -> &'static str {
        match self {
            Verdict::Accepted => "accepted",
            Verdict::NoTray => "rejected: no tray",
            Verdict::OffTable => "rejected: off the table",
            Verdict::Ambiguous => "rejected: ambiguous",
            Verdict::PoorFit => "rejected: poor fit",
            Verdict::SeenThrough => "rejected: seen through",
        }
    }

    /// The verdict of [`Verdict::as_str`]'s text, if it is one.
    pub fn parse(text: &str) -> Option<Verdict> {
        [
            Verdict::Accepted,
            Verdict::NoTray,
            Verdict::OffTable,
            Verdict::Ambiguous,
            Verdict::PoorFit,
            Verdict::SeenThrough,
        ]
        .into_iter()
        .find(|v| v.as_str() == text)
    }
}

impl fmt::Display for Verdict {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// The verification of one pose.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Verification {
    /// coverage × explained, in [0, 1]; 0 when no pose was found.
    pub score: f32,
    /// The decision at the threshold in force.
    pub verdict: Verdict,
    /// Share of the closest view's sensor-facing tray points (not the slots' items) with a
    /// measured point within reach, of those the measured depth does not hide.
    pub coverage: f32,
    /// Share of the closest view's sensor-facing tray points that the measured depth hides
    /// behind a nearer surface (an occluder), which the coverage sets aside.
    pub hidden: f32,
    /// Share of the same points with nothing measured around their pixel (a surface out of
    /// the matcher's range, a shadow), which the coverage sets aside too.
    pub unmeasured: f32,
    /// Share of the measured points inside the tray's box that the model explains.
    pub explained: f32,
    /// Against the closest unlisted alternative (the fewest deviations ahead, those not
    /// confirmed against first): (scene points on the pose's distinct parts − those on the
    /// alternative's) / both, in [−1, 1]; 1 when every one is listed or
    /// neither's parts have a point.
    pub turn_margin: f32,
    /// Scene points on the parts of the tray at the pose that the turn lacks.
    pub turn_own: u32,
    /// Scene points on the parts of the turned tray that the pose lacks.
    pub turn_other: u32,
    /// Height of the tray's bottom above the table, mm.
    pub height_mm: f32,
    /// Angle between the tray's z axis and the world's, deg.
    pub tilt_deg: f32,
    /// The model's sensor-facing points set against the left camera's measured depth
    /// (none tested when the pose came from a cloud without its depth map).
    pub see_through: SeeThroughCounts,
    /// The same of the pose moved by one slot's pitch (either way, along either of the
    /// tray's two slot directions) that the camera saw past least.
    pub see_through_shifted: SeeThroughCounts,
    /// The pose's own distinct parts (those an unlisted alternative lacks) set
    /// against the measured depth: of the turns, the one whose parts the camera saw past
    /// least against the pose's.
    pub turn_see_through: SeeThroughCounts,
    /// The same turn's distinct parts (those the pose lacks) at the turned pose.
    pub turn_see_through_other: SeeThroughCounts,
    /// That alternative (a quarter turn, or a turn that lays the slot grid onto itself
    /// shifted); `None` when none was weighed.
    pub turn_seen: Option<Alternative>,
    /// The camera saw past the distinct parts of the closest unlisted alternative (the one
    /// the turn margin is of) and not past the pose's, by the measure of
    /// [`Verification::turned_wrong_way`] the other way round, with less than
    /// [`TURN_SEE_THROUGH_ALONE`] of the pose's seen past: the pose stands against that
    /// alternative whatever the few scene points on either's parts say (but not against
    /// [`CONFLICTING_TURN_SIGMAS`] of them).
    pub turn_confirmed: bool,
    /// Neither the pose's distinct parts nor those of the closest unlisted alternative
    /// hold a scene point: nothing tells the two apart but what the camera saw past them
    /// (`turn_confirmed`), and without that the pose is ambiguous.
    pub turn_unseen: bool,
}

impl Verification {
    /// Whether the fitted tray rests on the table: its bottom within [`RESTING_HEIGHT_MM`]
    /// of it and its z axis within [`RESTING_TILT_DEG`] of the world's.
    pub fn rests_on_table(&self) -> bool {
        f64::from(self.height_mm).abs() <= RESTING_HEIGHT_MM && f64::from(self.tilt_deg) <= RESTING_TILT_DEG
    }

    /// Whether the camera saw past the tray's surface at the pose more than at the pose
    /// moved by a slot's pitch: by [`SEE_THROUGH_SIGMAS`] and [`SEE_THROUGH_MIN_EXCESS`],
    /// each tested on at least [`SEE_THROUGH_MIN_TESTED`] points.
    pub fn seen_past(&self) -> bool {
        seen_past_more(
            self.see_through,
            self.see_through_shifted,
            SEE_THROUGH_MIN_TESTED,
            SEE_THROUGH_SIGMAS,
            SEE_THROUGH_MIN_EXCESS,
        )
    }

    /// Whether the camera saw past the pose's own distinct parts more than past those of
    /// its turn (`turn_see_through` against `turn_see_through_other`): by
    /// [`TURN_SEE_THROUGH_SIGMAS`] and [`TURN_SEE_THROUGH_MIN_EXCESS`], each tested on at
    /// least [`TURN_SEE_THROUGH_MIN_TESTED`] points. The tray stands the other way round.
    pub fn turned_wrong_way(&self) -> bool {
        turn_favoured(self.turn_see_through, self.turn_see_through_other)
    }

    /// How many standard deviations the points only the pose explains exceed those only
    /// the closest unlisted alternative explains (infinite when every one is listed or
    /// neither explains a point).
    pub fn turn_sigmas(&self) -> f32 {
        if self.turn_own + self.turn_other == 0 {
            return f32::INFINITY;
        }
        lead_sigmas(self.turn_own, self.turn_other)
    }
}

/// How many standard deviations `own` exceeds `other` by, the counts taken as Poisson; 0
/// when both are 0 (no evidence either way). The verification's closest alternative and
/// the turn check's candidates are both weighed by it.
pub(crate) fn lead_sigmas(own: u32, other: u32) -> f32 {
    (own as f32 - other as f32) / ((own + other).max(1) as f32).sqrt()
}

/// Whether the camera saw past `pose`'s parts on a share larger than past `other`'s by
/// `sigmas` standard deviations (two proportions) and by `min_excess`, both tested on at
/// least `min_tested` points.
fn seen_past_more(
    pose: SeeThroughCounts,
    other: SeeThroughCounts,
    min_tested: u32,
    sigmas: f32,
    min_excess: f32,
) -> bool {
    if pose.tested < min_tested || other.tested < min_tested {
        return false;
    }
    let (p, q) = (pose.share(), other.share());
    let deviation = (p * (1.0 - p) / pose.tested as f32 + q * (1.0 - q) / other.tested as f32).sqrt();
    p - q >= min_excess && p - q >= sigmas * deviation
}

/// Whether the see-through evidence stands a pose against a turn of it, the pose's distinct
/// parts `own` and the turn's `other`: the camera saw past the turn's more
/// ([`turn_favoured`] the other way round), and past less than [`TURN_SEE_THROUGH_ALONE`]
/// of the pose's own where they were tested. A pose whose own parts the camera mostly saw
/// past is confirmed against nothing, however much more it saw past the turn's (a turned
/// tray whose both ends it saw past).
pub(crate) fn turn_confirmed(own: SeeThroughCounts, other: SeeThroughCounts) -> bool {
    let own_clear = own.tested < TURN_SEE_THROUGH_MIN_TESTED || own.share() < TURN_SEE_THROUGH_ALONE;
    turn_favoured(other, own) && own_clear
}

/// Whether the see-through evidence of a pose's distinct parts (`own`) against its turn's
/// (`other`) says the tray stands turned: [`Verification::turned_wrong_way`]. The turn's
/// parts count as not seen past when too few of them were tested: a telling part the
/// camera cannot see at the right pose (behind the tray's own far wall, under an
/// occluder) gives no evidence there, while the camera saw past it where the wrong pose
/// puts it.
pub(crate) fn turn_favoured(own: SeeThroughCounts, other: SeeThroughCounts) -> bool {
    if other.tested < TURN_SEE_THROUGH_MIN_TESTED {
        own.tested >= TURN_SEE_THROUGH_MIN_TESTED && own.share() >= TURN_SEE_THROUGH_ALONE
    } else {
        seen_past_more(own, other, TURN_SEE_THROUGH_MIN_TESTED, TURN_SEE_THROUGH_SIGMAS, TURN_SEE_THROUGH_MIN_EXCESS)
    }
}

/// The verification stage's settings: whether it may reject, and the threshold.
#[derive(Debug, Clone, PartialEq)]
pub struct Verifier {
    /// When false every found pose is accepted (the score is still computed).
    pub enabled: bool,
    /// Scores below this are rejected as a poor fit.
    pub threshold: f32,
    /// RANSAC's inlier distance: the reach of coverage and explained, mm.
    pub reach: f32,
    /// The model's two shortest slot-to-slot offsets, tray frame (see-through's shifts).
    pub pitches: [Option<Vector3<f64>>; 2],
    /// Per model view, its points that are the tray's and not an item's (see-through's).
    pub tray_points: Vec<Vec<u32>>,
    /// Per model view, one bit a point (point i at bit i % 64 of word i / 64): set where the
    /// point is the tray's and not an item's (the coverage's points).
    pub tray_mask: Vec<Vec<u64>>,
    /// The tray's parts that each alternative to it lacks (the turn's see-through evidence).
    pub turn_parts: TurnParts,
}

impl Verifier {
    /// The settings for `model` under the cell's `params`: the threshold the model carries,
    /// or the cell's `verify_threshold` for a model that carries none. `alternatives` are
    /// the model's ([`crate::pose::Alternatives::of`] it, as ICP holds them).
    pub fn for_model(params: &EstimatorParams, model: &Model, alternatives: &Alternatives, sight: f32) -> Verifier {
        Verifier::with_occluder(params, model, alternatives, &Occluder::of(model, sight))
    }

    /// [`Verifier::for_model`] with the model's occluder already built (the pipeline builds
    /// it once for ICP and the verifier).
    pub(crate) fn with_occluder(
        params: &EstimatorParams,
        model: &Model,
        alternatives: &Alternatives,
        occluder: &Occluder,
    ) -> Verifier {
        let all_tray = all_tray_points(model);
        let margin = DISTINCT_MARGIN * params.inlier_distance as f32;
        Verifier {
            enabled: params.verify,
            threshold: model.verification.map_or(params.verify_threshold as f32, |v| v.threshold),
            reach: params.inlier_distance as f32,
            pitches: slot_pitches(model),
            tray_points: thin_tray_points(&all_tray),
            tray_mask: model
                .views
                .iter()
                .zip(&all_tray)
                .map(|(view, tray)| bit_mask(view.points.len(), tray))
                .collect(),
            turn_parts: TurnParts::of_tray_points(model, alternatives, margin, occluder, &all_tray),
        }
    }

    /// The score at or above which a pose that rests on the table and is not ambiguous is
    /// accepted: the threshold, or 0 when the verification may not reject.
    pub fn threshold_in_force(&self) -> f32 {
        if self.enabled {
            self.threshold
        } else {
            0.0
        }
    }

    /// Verifies `pose` against the scene cloud indexed in `grid` (the same cloud as
    /// `scene_points`, world frame) seen from `sensor` (world frame). `weighed` is what the
    /// turn check already weighed of this pose (its passes are then not made again). `depth`
    /// is the frame's measured depth, when the pose came from a stereo frame.
    /// Allocates nothing.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn verify(
        &self,
        model: &Model,
        icp: &Icp,
        grid: &SceneGrid,
        scene_points: &[Point3<f32>],
        sensor: &Point3<f32>,
        pose: &Isometry3<f64>,
        weighed: Option<&Weighed>,
        depth: Option<&DepthEvidence>,
    ) -> Verification {
        let z_axis = pose.rotation * Vector3::z();
        let mut v = Verification {
            height_mm: pose.translation.vector.z as f32,
            tilt_deg: z_axis.z.clamp(-1.0, 1.0).acos().to_degrees() as f32,
            turn_margin: 1.0,
            ..Verification::default()
        };
        (v.coverage, v.hidden, v.unmeasured) = coverage(model, &self.tray_mask, grid, sensor, pose, self.reach, depth);
        // The alternatives the symmetries do not list, weighed by what the camera saw past:
        // each turn's counts taken once (by the turn check, when it weighed this pose), for
        // the turn they favour most and for the closest.
        let mut evidence = weighed.and_then(|w| w.evidence);
        if let Some(depth) = depth {
            v.see_through = see_through(model, &self.tray_points, depth, sensor, pose);
            // The shifted pose the camera saw past least (by share), of those tested enough;
            // not looked for where the pose's own share is too small to exceed any by
            // SEE_THROUGH_MIN_EXCESS (most right poses of a phase-12 frame).
            let suspect = v.see_through.share() >= SEE_THROUGH_MIN_EXCESS;
            let [a, b] = self.pitches.map(|d| d.filter(|_| suspect));
            let shifts = [a, a.map(|d| -d), b, b.map(|d| -d)];
            // The shifts' passes and the turns' are independent: taken side by side on the
            // pool, each a whole count, so the verdict is the same whatever the threads.
            let mut shifted = [None; 4];
            let (_, fresh) = rayon::join(
                || {
                    shifted.par_iter_mut().zip(&shifts).for_each(|(out, d)| {
                        *out = d.map(|d| {
                            see_through(model, &self.tray_points, depth, sensor, &(pose * Translation3::from(d)))
                        })
                    })
                },
                || weighed.is_none().then(|| self.turn_evidences(model, depth, sensor, pose)),
            );
            v.see_through_shifted = shifted
                .into_iter()
                .flatten()
                .filter(|c| c.tested >= SEE_THROUGH_MIN_TESTED)
                .min_by(|a, b| a.share().total_cmp(&b.share()))
                .unwrap_or_default();
            evidence = evidence.or(fresh);
        }
        let alternatives = self.turn_parts.alternatives.list();
        if let Some(e) = &evidence {
            let seen;
            (seen, v.turn_see_through, v.turn_see_through_other) = most_favoured_turn(e);
            v.turn_seen = seen.and_then(|k| alternatives.get(k).copied());
        }
        // The alternatives weighed against the pose in the same pass over the scene as the
        // explained share.
        let counts = match weighed {
            Some(w) => w.counts,
            None => icp.explained_near_and_apart(scene_points, pose, icp.alternatives().every(), self.reach, sensor),
        };
        v.explained = if counts.inside == 0 { 0.0 } else { counts.explained as f32 / counts.inside as f32 };
        v.score = (v.coverage * v.explained).clamp(0.0, 1.0);
        // The alternative the tray's symmetries do not list that comes closest: the points
        // on the pose's distinct parts against those on the alternative's, in deviations
        // (a tab's few points and a whole end's many weigh by their counts). An alternative
        // the camera saw past where it did not past the pose (confirmed against) stands
        // aside for one it did not, unless the scene's points speak for it so strongly
        // (CONFLICTING_TURN_SIGMAS) that the two kinds of evidence contradict each other.
        let mut closest: Option<(usize, f32, bool)> = None;
        for (k, &(own, other)) in counts.apart.iter().enumerate().take(alternatives.len()) {
            if alternatives[k].listed(model) {
                continue;
            }
            // No point on either's parts is no evidence either way (0): the closest of all.
            let sigmas = lead_sigmas(own, other);
            let confirmed = evidence.and_then(|e| e[k]).is_some_and(|(own, other)| turn_confirmed(own, other))
                && sigmas >= -CONFLICTING_TURN_SIGMAS;
            let closer = match closest {
                None => true,
                Some((_, best, best_confirmed)) => {
                    (best_confirmed && !confirmed) || (best_confirmed == confirmed && sigmas < best)
                }
            };
            if closer {
                closest = Some((k, sigmas, confirmed));
            }
        }
        if let Some((k, _, confirmed)) = closest {
            let (own, other) = counts.apart[k];
            v.turn_margin = if own + other == 0 { 1.0 } else { (own as f32 - other as f32) / (own + other) as f32 };
            (v.turn_own, v.turn_other, v.turn_confirmed) = (own, other, confirmed);
            v.turn_unseen = own + other == 0;
        }
        v.verdict = if !self.enabled {
            Verdict::Accepted
        } else if !v.rests_on_table() {
            Verdict::OffTable
        } else if v.score < self.threshold {
            Verdict::PoorFit
        } else if v.seen_past() || v.turned_wrong_way() {
            Verdict::SeenThrough
        } else if (v.turn_unseen || v.turn_sigmas() < AMBIGUOUS_TURN_SIGMAS) && !v.turn_confirmed {
            Verdict::Ambiguous
        } else {
            Verdict::Accepted
        };
        v
    }
}

impl Verifier {
    /// Per alternative `k` that the model's symmetries do not list (at `k`), the
    /// see-through counts of the pose's distinct parts and of the alternative's
    /// ([`turn_see_through`]); `None` for a listed turn and past the alternatives. The
    /// alternatives' passes are taken side by side on the pool, each a whole count.
    pub(crate) fn turn_evidences(
        &self,
        model: &Model,
        depth: &DepthEvidence,
        sensor: &Point3<f32>,
        pose: &Isometry3<f64>,
    ) -> TurnEvidence {
        let mut out = [None; MAX_ALTERNATIVES];
        let alternatives = self.turn_parts.alternatives.list();
        out.par_iter_mut().zip(alternatives.par_iter()).enumerate().for_each(|(k, (slot, a))| {
            *slot = (!a.listed(model)).then(|| turn_see_through(model, &self.turn_parts, depth, sensor, pose, k));
        });
        out
    }
}

/// Per alternative (the index into the model's [`crate::pose::Alternatives`]), the
/// see-through counts of the pose's distinct parts and of the alternative's; `None` for a
/// turn the symmetries list and past the alternatives.
pub(crate) type TurnEvidence = [Option<(SeeThroughCounts, SeeThroughCounts)>; MAX_ALTERNATIVES];

/// What the turn check weighed of a pose, which the verification reuses while the pose
/// stands: [`Icp::explained_near_and_apart`] of it against every alternative and, from
/// a stereo frame, each turn's see-through evidence ([`Verifier::turn_evidences`]).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Weighed {
    pub(crate) counts: ExplainedCounts,
    pub(crate) evidence: Option<TurnEvidence>,
}

/// Of the alternatives weighed in `evidence`, the one whose distinct parts the camera saw
/// past least against the pose's own (the largest excess of the pose's share over the
/// alternative's; the last of equals), with both counts; `(None, none, none)` when none
/// was weighed.
pub(crate) fn most_favoured_turn(evidence: &TurnEvidence) -> (Option<usize>, SeeThroughCounts, SeeThroughCounts) {
    let excess = |(_, own, other): &(usize, SeeThroughCounts, SeeThroughCounts)| own.share() - other.share();
    evidence
        .iter()
        .enumerate()
        .filter_map(|(k, e)| e.map(|(own, other)| (k, own, other)))
        .max_by(|a, b| excess(a).total_cmp(&excess(b)))
        .map_or((None, SeeThroughCounts::default(), SeeThroughCounts::default()), |(k, own, other)| {
            (Some(k), own, other)
        })
}

/// One bit per index below `len`, set at `indices`.
fn bit_mask(len: usize, indices: &[u32]) -> Vec<u64> {
    let mut mask = vec![0u64; len.div_ceil(64)];
    for &i in indices {
        mask[i as usize / 64] |= 1 << (i % 64);
    }
    mask
}

/// Share of the closest view's tray points (those `tray_mask` sets: not a slot's item, since
/// which slots hold one is the scene's, not the tray's) facing the sensor, at `pose`, with a
/// scene point within `reach`; with the frame's `depth`, of those the sensor could see: a
/// point with no scene point near that the measured depth puts behind a nearer surface, or
/// where it measured nothing ([`Sight`]: a gripper over the tray, an arm), counts neither
/// way. At most [`MOST_HIDDEN`] of the facing points are set aside, so a pose the sensor
/// barely saw cannot score as if it saw it whole. Returns the coverage and the hidden and
/// unmeasured shares of the facing points.
fn coverage(
    model: &Model,
    tray_mask: &[Vec<u64>],
    grid: &SceneGrid,
    sensor: &Point3<f32>,
    pose: &Isometry3<f64>,
    reach: f32,
    depth: Option<&DepthEvidence>,
) -> (f32, f32, f32) {
    let k = model.closest_view(pose, sensor);
    let (view, mask) = (&model.views[k], tray_mask.get(k).map_or(&[][..], Vec::as_slice));
    let to_world = pose.cast::<f32>();
    let eye = pose.inverse().cast::<f32>() * sensor;
    let r2 = reach * reach;
    let occlusion = depth.map(DepthEvidence::occlusion);
    // Fixed chunks, integer counts: the same share whatever the number of threads.
    let (facing, seen, hidden, unmeasured) = view
        .points
        .par_chunks(COVERAGE_CHUNK)
        .zip(view.normals.par_chunks(COVERAGE_CHUNK))
        .enumerate()
        .map(|(chunk, (points, normals))| {
            // The facing points moved to the world in small batches, each looked up in the
            // grid at once so that their cache misses overlap.
            let (mut facing, mut seen, mut hidden, mut unmeasured) = (0u32, 0u32, 0u32, 0u32);
            let mut batch = [Point3::origin(); COVERAGE_BATCH];
            let mut filled = 0;
            let mut count = |batch: &[Point3<f32>]| {
                grid.each_within(batch, r2, |q, within| {
                    if within {
                        seen += 1;
                    } else {
                        match occlusion.as_ref().map_or(Sight::Open, |o| o.sight(q)) {
                            Sight::Open => {}
                            Sight::Hidden => hidden += 1,
                            Sight::Unmeasured => unmeasured += 1,
                        }
                    }
                })
            };
            for (j, (m, n)) in points.iter().zip(normals).enumerate() {
                let i = chunk * COVERAGE_CHUNK + j;
                let tray = mask.get(i / 64).is_some_and(|w| w & (1 << (i % 64)) != 0);
                if !tray || n.dot(&(eye - m)) <= 0.0 {
                    continue;
                }
                facing += 1;
                batch[filled] = to_world * m;
                filled += 1;
                if filled == COVERAGE_BATCH {
                    count(&batch);
                    filled = 0;
                }
            }
            count(&batch[..filled]);
            (facing, seen, hidden, unmeasured)
        })
        .reduce(|| (0, 0, 0, 0), |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2, a.3 + b.3));
    let visible = facing - (hidden + unmeasured).min((MOST_HIDDEN * facing as f32) as u32);
    if visible == 0 {
        (0.0, 0.0, 0.0)
    } else {
        let share = |n: u32| n as f32 / facing as f32;
        (seen as f32 / visible as f32, share(hidden), share(unmeasured))
    }
}
