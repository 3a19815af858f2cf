//! What the verification does over many scored frames: the threshold chosen from their scores
//! and truth (the lowest score at which gross wrong poses are at most the target share of the
//! accepted ones, raised as far as every wrong pose's share needs only where the score tells
//! the near misses from the correct poses), the figures at it (verified success, wrong poses
//! accepted with their Clopper–Pearson upper bound, correct poses rejected) and the
//! precision–recall curve. It does not verify poses (the estimator does) nor draw the curve
//! (the report does).

use crate::{ModelVerification, Verdict};
use camplace_config::Metrics;
use serde::{Deserialize, Serialize};

use super::intervals::wilson_interval;
use super::record::{FrameRecord, NegativeRecord};

/// One-sided confidence of the upper bound on the wrong share.
pub(super) const UPPER_CONFIDENCE: f64 = 0.95;

/// A wrong pose off by more than this many times a success limit is gross (a turn, a slot
/// away): what the score is there to reject. A wrong pose within it is a near miss.
pub const GROSS_FACTOR: f64 = 2.0;

/// The largest share of the hard negatives the score is for (wrong poses made from each
/// scene's truth and refined: a turn laying the slot grid onto itself, a slot's pitch away,
/// a tilt; not a turn about the centre, [`TURN_NEGATIVE`]) that the chosen threshold may let
/// through. RANSAC's own wrong poses are a handful in hundreds of scenes,
/// too few to set a threshold on; the negatives are tens a scene.
pub const MAX_NEGATIVES_ACCEPTED: f64 = 0.005;

/// Near misses raise the threshold only when the poses the raise would reject are wrong more
/// often than those it keeps at this one-sided significance (Fisher's exact test).
const SEPARATION_ALPHA: f64 = 0.05;

/// Near misses the score cannot tell from correct poses refuse every pose when, at the
/// threshold the gross wrong poses allow, they are more than the target share of the
/// accepted ones beyond chance at this one-sided significance (the binomial test).
const EXCESS_ALPHA: f64 = 0.05;

/// The threshold of a verification that refuses every pose: above any score (scores lie
/// in [0, 1]).
pub const REFUSE_ALL: f32 = 1.0 + f32::EPSILON;

/// A frame as the threshold choice sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scored {
    /// The verification's score.
    pub score: f32,
    /// A pose was found that passed the checks a threshold does not move (on the table,
    /// not ambiguous): the threshold alone decides it.
    pub eligible: bool,
    /// The pose is within the success limits.
    pub correct: bool,
    /// The pose is wrong by more than `GROSS_FACTOR` times a success limit.
    pub gross: bool,
}

impl Scored {
    /// The record's view under the success limits `metrics`, or `None` for a record without
    /// truth or written before the verification.
    pub fn of(record: &FrameRecord, metrics: &Metrics) -> Option<Scored> {
        let (score, verdict, truth) = (record.verify_score?, record.verdict.as_deref()?, record.score?);
        let eligible = record.found && threshold_decides(verdict);
        let gross =
            record.found && !truth.success && gross_error(truth.position_error_mm, truth.rotation_error_deg, metrics);
        Some(Scored { score, eligible, correct: truth.success, gross })
    }
}

/// The kind of hard negative the threshold leaves to the turn check: a turn about the
/// tray's centre explains the scene as well as the right pose wherever the telling feature
/// is out of sight, so its score is the right pose's, and the turn margin and the
/// see-through evidence of the distinct parts judge it, not the score.
pub const TURN_NEGATIVE: &str = "turn";

impl Scored {
    /// A hard negative as the threshold choice sees it: `None` unless it stayed grossly
    /// wrong once refined (one refined back to the truth is no negative, a near miss is
    /// the rig's calibration error's scale), and for a turn about the centre
    /// ([`TURN_NEGATIVE`]).
    pub fn of_negative(negative: &NegativeRecord) -> Option<Scored> {
        (!negative.correct && negative.gross && negative.kind != TURN_NEGATIVE).then(|| Scored {
            score: negative.score,
            eligible: threshold_decides(&negative.verdict),
            correct: false,
            gross: true,
        })
    }
}

/// Whether the threshold alone decides a pose of `verdict`: accepted, or refused for its
/// score (the checks a threshold does not move passed).
fn threshold_decides(verdict: &str) -> bool {
    [Verdict::Accepted.as_str(), Verdict::PoorFit.as_str()].contains(&verdict)
}

/// Whether a pose off by `position_mm` and `rotation_deg` is grossly wrong under `metrics`:
/// off by more than [`GROSS_FACTOR`] times a success limit.
pub fn gross_error(position_mm: f64, rotation_deg: f64, metrics: &Metrics) -> bool {
    position_mm > GROSS_FACTOR * metrics.success_position || rotation_deg > GROSS_FACTOR * metrics.success_rotation
}

/// The verification's figures over a set of frames at one threshold (`verification` in
/// `summary.json`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct VerifiedSummary {
    /// Scores at or above this are accepted: chosen by [`choose_threshold`] (above every
    /// score when no score keeps the gross wrong poses within `max_wrong`).
    pub threshold: f32,
    /// The target share of wrong poses among the accepted ones.
    pub max_wrong: f64,
    /// Frames with a score and a truth.
    pub scored: usize,
    /// Frames whose pose is correct (within the success limits).
    pub correct: usize,
    /// Poses accepted at the threshold.
    pub accepted: usize,
    /// Correct and accepted.
    pub verified_successes: usize,
    /// `verified_successes / scored`.
    pub verified_success_rate: f64,
    /// Wilson 95 % interval of the verified success rate.
    pub verified_success_interval: [f64; 2],
    /// Accepted but wrong.
    pub wrong_accepted: usize,
    /// `wrong_accepted / accepted` (0 when nothing is accepted).
    pub wrong_accepted_share: f64,
    /// One-sided 95 % upper bound (Clopper–Pearson) of the wrong share among accepted poses.
    pub wrong_accepted_upper: f64,
    /// Correct poses the verification rejected.
    pub correct_rejected: usize,
    /// `correct_rejected / correct` (0 when no pose is correct).
    pub correct_rejected_share: f64,
    /// Hard negatives weighed beside the frames (gross ones, not turns about the centre:
    /// [`Scored::of_negative`]; 0 when none was weighed).
    #[serde(default)]
    pub negatives: usize,
    /// Of them, accepted at the threshold.
    #[serde(default)]
    pub negatives_accepted: usize,
    /// Where every pose is refused because the score cannot tell the near misses from the
    /// correct poses and they are too many (the placement cannot keep the target): what
    /// the threshold the gross wrong poses allow would have accepted.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub near_misses_untold: Option<NearMissExcess>,
}

/// Near misses the score cannot tell apart, at the threshold the gross wrong poses allow.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct NearMissExcess {
    /// That threshold.
    pub threshold: f32,
    /// Poses it accepts.
    pub accepted: usize,
    /// Of them, wrong.
    pub wrong: usize,
    /// Of those, near misses (the gross ones being within the target).
    #[serde(default)]
    pub near_misses: usize,
}

impl std::fmt::Display for NearMissExcess {
    /// The refusal in words, as the terminal line and the study report give it.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "every pose refused: at {:.3} {} of the {} accepted ({:.1} %) were wrong, {} of them near misses the \
             score cannot tell from correct poses",
            self.threshold,
            self.wrong,
            self.accepted,
            100.0 * self.wrong as f64 / self.accepted.max(1) as f64,
            self.near_misses
        )
    }
}

impl VerifiedSummary {
    /// The threshold chosen for `max_wrong` over `frames` and, where the frames' hard
    /// `negatives` were weighed, raised as far as [`negatives_threshold`] needs; the figures
    /// at it. `None` when no frame has a score.
    pub fn choose(frames: &[Scored], negatives: &[Scored], max_wrong: f64) -> Option<VerifiedSummary> {
        if frames.is_empty() {
            return None;
        }
        let (chosen, untold) = threshold_choice(frames, max_wrong);
        let threshold = chosen.max(negatives_threshold(negatives));
        let mut summary = Self::at(frames, threshold, max_wrong).with_negatives(negatives);
        summary.near_misses_untold = untold;
        Some(summary)
    }

    /// [`VerifiedSummary::choose`] over `records` judged by the success limits `metrics`:
    /// each record's own pose ([`Scored::of`]) and its hard negatives, where it carries them
    /// ([`Scored::of_negative`]).
    pub fn of_records(records: &[FrameRecord], max_wrong: f64, metrics: &Metrics) -> Option<VerifiedSummary> {
        let frames: Vec<Scored> = records.iter().filter_map(|r| Scored::of(r, metrics)).collect();
        let negatives: Vec<Scored> =
            records.iter().flat_map(|r| r.negatives.iter().flatten()).filter_map(Scored::of_negative).collect();
        Self::choose(&frames, &negatives, max_wrong)
    }

    /// The summary with the hard `negatives` counted at its threshold.
    fn with_negatives(mut self, negatives: &[Scored]) -> VerifiedSummary {
        self.negatives = negatives.len();
        self.negatives_accepted = negatives.iter().filter(|n| n.eligible && n.score >= self.threshold).count();
        self
    }

    /// The figures over `frames` at `threshold`.
    pub fn at(frames: &[Scored], threshold: f32, max_wrong: f64) -> VerifiedSummary {
        let accepted = |f: &&Scored| f.eligible && f.score >= threshold;
        let n_accepted = frames.iter().filter(accepted).count();
        let verified = frames.iter().filter(accepted).filter(|f| f.correct).count();
        let wrong = n_accepted - verified;
        let correct = frames.iter().filter(|f| f.correct).count();
        let ratio = |a: usize, b: usize| if b == 0 { 0.0 } else { a as f64 / b as f64 };
        VerifiedSummary {
            threshold,
            max_wrong,
            scored: frames.len(),
            correct,
            accepted: n_accepted,
            verified_successes: verified,
            verified_success_rate: ratio(verified, frames.len()),
            verified_success_interval: wilson_interval(verified, frames.len()),
            wrong_accepted: wrong,
            wrong_accepted_share: ratio(wrong, n_accepted),
            wrong_accepted_upper: clopper_pearson_upper(wrong, n_accepted, UPPER_CONFIDENCE),
            correct_rejected: correct - verified,
            correct_rejected_share: ratio(correct - verified, correct),
            negatives: 0,
            negatives_accepted: 0,
            near_misses_untold: None,
        }
    }

    /// The figures a model carries.
    pub fn to_model(&self) -> ModelVerification {
        ModelVerification {
            threshold: self.threshold,
            max_wrong: self.max_wrong as f32,
            scenes: self.scored as u32,
            accepted: self.accepted as u32,
            wrong_accepted: self.wrong_accepted as u32,
            wrong_upper: self.wrong_accepted_upper as f32,
        }
    }

    /// One line for a terminal.
    pub fn line(&self) -> String {
        let negatives = if self.negatives == 0 {
            String::new()
        } else {
            format!(
                ", hard negatives accepted {} of {} ({:.2} %)",
                self.negatives_accepted,
                self.negatives,
                100.0 * self.negatives_accepted as f64 / self.negatives as f64
            )
        };
        let untold = self.near_misses_untold.map_or(String::new(), |e| {
            format!(
                "; {e} (at the gross wrong poses' limit), beyond the {:.1} % target (the cell's \
                 estimator.verify_max_wrong)",
                100.0 * self.max_wrong
            )
        });
        format!(
            "verified success {:.1} % ({} of {}), wrong accepted {} of {} ({:.2} %, 95 % upper bound {:.2} %), \
             correct rejected {} of {} ({:.1} %) at threshold {:.3}",
            100.0 * self.verified_success_rate,
            self.verified_successes,
            self.scored,
            self.wrong_accepted,
            self.accepted,
            100.0 * self.wrong_accepted_share,
            100.0 * self.wrong_accepted_upper,
            self.correct_rejected,
            self.correct,
            100.0 * self.correct_rejected_share,
            self.threshold
        ) + &negatives
            + &untold
    }
}

/// The threshold for `max_wrong` over `frames`. First the lowest score at which gross wrong
/// poses (turns, a slot away: what the score is for) are at most `max_wrong` of the accepted
/// ones. Then, when every wrong pose's share needs a higher one, that higher one only if the
/// poses it would reject in addition are wrong more often than those it keeps, beyond chance
/// (one-sided Fisher exact test at `SEPARATION_ALPHA`). A near miss the score cannot tell
/// from a correct pose (the rig's calibration error moving the whole cloud, which no frame
/// shows) would otherwise lift the threshold to just above its own score and reject every
/// correct pose below it by the luck of where it fell; it stays accepted and counted in the
/// wrong share and its bound. But where such near misses are more than `max_wrong` of the
/// accepted poses beyond chance (one-sided binomial test at `EXCESS_ALPHA`), no threshold
/// keeps the target and every pose is refused ([`REFUSE_ALL`]): a placement whose poses are
/// off by more than the success limits in a share the score cannot see hands the robot
/// nothing rather than those.
pub fn choose_threshold(frames: &[Scored], max_wrong: f64) -> f32 {
    threshold_choice(frames, max_wrong).0
}

/// [`choose_threshold`] and, where it refuses every pose for the near misses, what the
/// gross wrong poses' threshold would have accepted.
fn threshold_choice(frames: &[Scored], max_wrong: f64) -> (f32, Option<NearMissExcess>) {
    let gross = lowest_within(frames, max_wrong, |f| f.gross);
    let every = lowest_within(frames, max_wrong, |f| !f.correct);
    if every > gross && wrong_more_often_below(frames, gross, every) {
        return (every, None);
    }
    let accepted = frames.iter().filter(|f| f.eligible && f.score >= gross);
    let (n, wrong, near) = accepted
        .fold((0, 0, 0), |(n, w, m), f| (n + 1, w + usize::from(!f.correct), m + usize::from(!f.correct && !f.gross)));
    if wrong > 0 && 1.0 - binomial_cdf(wrong - 1, n, max_wrong) < EXCESS_ALPHA {
        (REFUSE_ALL, Some(NearMissExcess { threshold: gross, accepted: n, wrong, near_misses: near }))
    } else {
        (gross, None)
    }
}

/// The lowest threshold at which at most [`MAX_NEGATIVES_ACCEPTED`] of the hard `negatives`
/// (all of them, whatever rejected them) are accepted: just above the score of the first
/// eligible one beyond that count, highest first; 0 when the other checks already reject
/// enough of them, or none was weighed.
pub fn negatives_threshold(negatives: &[Scored]) -> f32 {
    let allowed = (MAX_NEGATIVES_ACCEPTED * negatives.len() as f64).floor() as usize;
    let mut eligible: Vec<f32> = negatives.iter().filter(|n| n.eligible).map(|n| n.score).collect();
    if eligible.len() <= allowed {
        return 0.0;
    }
    eligible.sort_by(|a, b| b.total_cmp(a));
    eligible[allowed].next_up()
}

/// The lowest threshold at which the frames `wrong` picks are at most `max_wrong` of the
/// accepted ones: one of the eligible scores, or just above the highest when none qualifies.
fn lowest_within(frames: &[Scored], max_wrong: f64, wrong: impl Fn(&Scored) -> bool) -> f32 {
    let mut eligible: Vec<(f32, bool)> = frames.iter().filter(|f| f.eligible).map(|f| (f.score, wrong(f))).collect();
    // Highest first; walking down, each distinct score is a candidate threshold.
    eligible.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut best = eligible.first().map_or(0.0, |f| f.0.next_up());
    let (mut accepted, mut wrong) = (0usize, 0usize);
    let mut i = 0;
    while i < eligible.len() {
        let score = eligible[i].0;
        while i < eligible.len() && eligible[i].0 == score {
            accepted += 1;
            wrong += usize::from(eligible[i].1);
            i += 1;
        }
        if wrong as f64 <= max_wrong * accepted as f64 {
            best = score;
        }
    }
    best
}

/// Whether, among the eligible frames scored at or above `low`, those below `high` are wrong
/// more often than those at or above it, beyond chance: the one-sided Fisher exact test's
/// p below `SEPARATION_ALPHA`.
fn wrong_more_often_below(frames: &[Scored], low: f32, high: f32) -> bool {
    let (mut below, mut wrong_below, mut kept, mut wrong_kept) = (0usize, 0usize, 0usize, 0usize);
    for f in frames.iter().filter(|f| f.eligible && f.score >= low) {
        if f.score < high {
            below += 1;
            wrong_below += usize::from(!f.correct);
        } else {
            kept += 1;
            wrong_kept += usize::from(!f.correct);
        }
    }
    hypergeometric_upper_tail(wrong_below, below + kept, wrong_below + wrong_kept, below) < SEPARATION_ALPHA
}

/// P(X >= k) for X ~ Hypergeometric(`total` items, `marked` of them marked, `drawn` drawn):
/// the chance that `drawn` items taken at random hold `k` or more of the marked ones.
fn hypergeometric_upper_tail(k: usize, total: usize, marked: usize, drawn: usize) -> f64 {
    let top = marked.min(drawn);
    // The fewest marked items a draw can hold.
    let least = (marked + drawn).saturating_sub(total);
    if k <= least {
        return 1.0;
    }
    if k > top {
        return 0.0;
    }
    let ln_choose = |n: usize, r: usize| -> f64 { (1..=r).map(|i| ((n - r + i) as f64 / i as f64).ln()).sum() };
    // P(X = k), then each next term by the ratio of consecutive terms.
    let mut term = (ln_choose(marked, k) + ln_choose(total - marked, drawn - k) - ln_choose(total, drawn)).exp();
    let mut sum = 0.0f64;
    for x in k..=top {
        sum += term;
        if x < top {
            term *= ((marked - x) * (drawn - x)) as f64 / ((x + 1) * (total + x + 1 - marked - drawn)) as f64;
        }
    }
    sum.min(1.0)
}

/// The precision–recall curve over `frames`: for each distinct eligible score as threshold
/// (highest first), (recall: correct poses accepted / correct poses, precision: correct
/// among accepted, threshold).
pub fn precision_recall(frames: &[Scored]) -> Vec<(f64, f64, f32)> {
    let correct = frames.iter().filter(|f| f.correct).count();
    let mut eligible: Vec<(f32, bool)> = frames.iter().filter(|f| f.eligible).map(|f| (f.score, f.correct)).collect();
    eligible.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut out = Vec::new();
    let (mut accepted, mut right) = (0usize, 0usize);
    let mut i = 0;
    while i < eligible.len() {
        let score = eligible[i].0;
        while i < eligible.len() && eligible[i].0 == score {
            accepted += 1;
            right += usize::from(eligible[i].1);
            i += 1;
        }
        let recall = if correct == 0 { 0.0 } else { right as f64 / correct as f64 };
        out.push((recall, right as f64 / accepted as f64, score));
    }
    out
}

/// One-sided upper confidence bound (Clopper–Pearson) of a binomial share from `k` events in
/// `n` trials: the p at which seeing k or fewer has probability 1 − `confidence`. 1 when
/// `n` is 0.
pub fn clopper_pearson_upper(k: usize, n: usize, confidence: f64) -> f64 {
    if n == 0 || k >= n {
        return 1.0;
    }
    let alpha = 1.0 - confidence;
    // P(X <= k) falls as p grows: bisect for where it crosses alpha.
    let (mut lo, mut hi) = (k as f64 / n as f64, 1.0f64);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if binomial_cdf(k, n, mid) > alpha {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    hi
}

/// P(X <= k) for X ~ Binomial(n, p), summed in log space.
fn binomial_cdf(k: usize, n: usize, p: f64) -> f64 {
    if p <= 0.0 {
        return 1.0;
    }
    if p >= 1.0 {
        return if k >= n { 1.0 } else { 0.0 };
    }
    let (lp, lq) = (p.ln(), (1.0 - p).ln());
    // log C(n, i) built up term by term.
    let mut log_choose = 0.0f64;
    let mut sum = 0.0f64;
    for i in 0..=k {
        if i > 0 {
            log_choose += ((n - i + 1) as f64).ln() - (i as f64).ln();
        }
        sum += (log_choose + i as f64 * lp + (n - i) as f64 * lq).exp();
    }
    sum.min(1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clopper_pearson_matches_closed_forms_and_tables() {
        // k = 0: 1 - alpha^(1/n) exactly (the "rule of three" is its approximation).
        for n in [1usize, 10, 300, 1000] {
            let want = 1.0 - 0.05f64.powf(1.0 / n as f64);
            assert!((clopper_pearson_upper(0, n, 0.95) - want).abs() < 1e-9, "n {n}");
        }
        // k = n - 1: P(X <= n - 1) = 1 - p^n, so the bound solves 1 - p^n = alpha.
        let want = 0.95f64.powf(1.0 / 10.0);
        assert!((clopper_pearson_upper(9, 10, 0.95) - want).abs() < 1e-9);
        // A slow obvious version: the smallest p on a fine grid with P(X <= k) <= alpha.
        for (k, n) in [(1usize, 20usize), (3, 100), (7, 300)] {
            let slow = (0..=200_000)
                .map(|i| f64::from(i) / 200_000.0)
                .find(|&p| {
                    let cdf: f64 = (0..=k)
                        .map(|i| {
                            let choose: f64 = (0..i).map(|j| (n - j) as f64 / (j + 1) as f64).product();
                            choose * p.powi(i as i32) * (1.0 - p).powi((n - i) as i32)
                        })
                        .sum();
                    cdf <= 0.05
                })
                .unwrap();
            let fast = clopper_pearson_upper(k, n, 0.95);
            assert!((fast - slow).abs() <= 1e-5, "{k}/{n}: {fast} against {slow}");
        }
        assert_eq!(clopper_pearson_upper(0, 0, 0.95), 1.0);
    }

    /// A correct pose, or a gross wrong one.
    fn frame(score: f32, correct: bool) -> Scored {
        Scored { score, eligible: true, correct, gross: !correct }
    }

    /// A wrong pose within twice the limits.
    fn near_miss(score: f32) -> Scored {
        Scored { score, eligible: true, correct: false, gross: false }
    }

    #[test]
    fn the_threshold_is_the_lowest_score_within_the_target() {
        // 200 correct poses scored 0.5..0.9, 2 wrong ones at 0.3 and 0.6.
        let mut frames: Vec<Scored> = (0..200).map(|i| frame(0.5 + 0.4 * i as f32 / 200.0, true)).collect();
        frames.push(frame(0.3, false));
        frames.push(frame(0.6, false));
        // Ineligible (off the table) never counts as accepted.
        frames.push(Scored { score: 0.95, eligible: false, correct: false, gross: true });
        // Every threshold by brute force: the lowest whose share is within 0.8 % (2 wrong of
        // 202 is 0.99 %, 1 of 201 is 0.50 %).
        let share = |t: f32| {
            let acc: Vec<_> = frames.iter().filter(|f| f.eligible && f.score >= t).collect();
            acc.iter().filter(|f| !f.correct).count() as f64 / acc.len().max(1) as f64
        };
        let brute = frames
            .iter()
            .filter(|f| f.eligible)
            .map(|f| f.score)
            .filter(|&t| share(t) <= 0.008)
            .fold(f32::INFINITY, f32::min);
        let t = choose_threshold(&frames, 0.008);
        assert_eq!(t, brute);
        assert!(t > 0.3 && t <= 0.5, "{t}");
        let s = VerifiedSummary::at(&frames, t, 0.008);
        assert_eq!((s.accepted, s.wrong_accepted, s.correct_rejected), (201, 1, 0));
        // At 0.4 % even one wrong in 201 is too many: the threshold rises above 0.6.
        let strict = VerifiedSummary::choose(&frames, &[], 0.004).unwrap();
        assert!(strict.threshold > 0.6 && strict.wrong_accepted == 0, "{strict:?}");
        assert!(strict.correct_rejected > 0 && strict.wrong_accepted_upper > 0.0);
        // The curve's last point accepts every eligible frame.
        let curve = precision_recall(&frames);
        let last = curve.last().unwrap();
        assert_eq!((last.0, last.2), (1.0, 0.3));
        assert!((last.1 - 200.0 / 202.0).abs() < 1e-12);
    }

    #[test]
    fn a_wrong_pose_scored_highest_accepts_nothing() {
        let frames = [frame(0.9, false), frame(0.5, true)];
        let t = choose_threshold(&frames, 0.005);
        assert!(t > 0.9);
        assert_eq!(VerifiedSummary::at(&frames, t, 0.005).accepted, 0);
    }

    #[test]
    fn hypergeometric_tail_matches_closed_forms_and_counting() {
        // 5 marked of 20, 10 drawn: all 5 drawn in C(15, 5) of C(20, 10) draws.
        let want = 3003.0 / 184_756.0;
        assert!((hypergeometric_upper_tail(5, 20, 5, 10) - want).abs() < 1e-12);
        assert_eq!(hypergeometric_upper_tail(0, 20, 5, 10), 1.0);
        assert_eq!(hypergeometric_upper_tail(6, 20, 5, 10), 0.0);
        // 15 marked of 20, 10 drawn: at least 5 are marked in every draw.
        assert_eq!(hypergeometric_upper_tail(5, 20, 15, 10), 1.0);
        // A slow obvious version: every term's binomial coefficients as products.
        let choose = |n: usize, r: usize| -> f64 { (0..r).map(|j| (n - j) as f64 / (j + 1) as f64).product() };
        for (total, marked, drawn) in [(30usize, 7usize, 12usize), (60, 2, 45), (40, 25, 30), (12, 12, 5)] {
            for k in 0..=drawn.min(marked) {
                let slow: f64 = (k..=drawn.min(marked))
                    .filter(|&x| drawn - x <= total - marked)
                    .map(|x| choose(marked, x) * choose(total - marked, drawn - x) / choose(total, drawn))
                    .sum();
                let fast = hypergeometric_upper_tail(k, total, marked, drawn);
                assert!(
                    (fast - slow.min(1.0)).abs() < 1e-9,
                    "{k} of {total}, {marked}, {drawn}: {fast} against {slow}"
                );
            }
        }
    }

    #[test]
    fn near_misses_among_the_correct_poses_do_not_lift_the_threshold() {
        // 200 correct poses scored 0.5..0.9 and 2 near misses among them: 0.99 % wrong when
        // everything is accepted, above a 0.5 % target, but the poses below the highest near
        // miss are wrong no more often than chance makes them.
        let mut frames: Vec<Scored> = (0..200).map(|i| frame(0.5 + 0.4 * i as f32 / 200.0, true)).collect();
        frames.push(near_miss(0.62));
        frames.push(near_miss(0.81));
        let s = VerifiedSummary::choose(&frames, &[], 0.005).unwrap();
        assert_eq!(s.threshold, 0.5);
        assert_eq!((s.accepted, s.wrong_accepted, s.correct_rejected), (202, 2, 0));
        // Gross wrong poses in the same places are rejected, whatever it costs.
        frames[200] = frame(0.62, false);
        frames[201] = frame(0.81, false);
        let s = VerifiedSummary::choose(&frames, &[], 0.005).unwrap();
        assert!(s.threshold > 0.81, "{s:?}");
        assert_eq!(s.wrong_accepted, 0);
    }

    #[test]
    fn near_misses_the_score_tells_apart_lift_the_threshold() {
        // 200 correct poses scored 0.5..0.9 and 10 near misses all below them.
        let mut frames: Vec<Scored> = (0..200).map(|i| frame(0.5 + 0.4 * i as f32 / 200.0, true)).collect();
        frames.extend((0..10).map(|i| near_miss(0.40 + 0.005 * i as f32)));
        // Every wrong pose's share is within 0.5 % from the highest near miss up (1 of 201).
        let s = VerifiedSummary::choose(&frames, &[], 0.005).unwrap();
        assert_eq!(s.threshold, frames[209].score);
        assert_eq!((s.accepted, s.wrong_accepted, s.correct_rejected), (201, 1, 0));
    }

    #[test]
    fn near_misses_the_score_cannot_tell_apart_refuse_every_pose_when_too_many() {
        // 200 correct poses scored 0.5..0.9 with 40 near misses spread among them (every
        // sixth from the top): 16.7 % wrong at any threshold, far beyond 0.5 %.
        let mut frames: Vec<Scored> = (0..200).map(|i| frame(0.5 + 0.4 * i as f32 / 200.0, true)).collect();
        frames.extend((0..40).map(|i| near_miss(0.9 - 0.01 * i as f32 - 0.0025)));
        let s = VerifiedSummary::choose(&frames, &[], 0.005).unwrap();
        assert_eq!(s.threshold, REFUSE_ALL);
        assert_eq!((s.accepted, s.correct_rejected), (0, 200));
        let untold = s.near_misses_untold.unwrap();
        assert_eq!((untold.threshold, untold.accepted, untold.wrong, untold.near_misses), (0.5, 240, 40, 40));
        assert!(s.line().contains("every pose refused"), "{}", s.line());
        // Gross wrong poses in their places lift the threshold above the highest of them,
        // as ever: no refusal of the whole placement.
        for f in &mut frames[200..] {
            f.gross = true;
        }
        let s = VerifiedSummary::choose(&frames, &[], 0.005).unwrap();
        assert!(s.near_misses_untold.is_none() && s.threshold > 0.8975 && s.threshold < 1.0, "{s:?}");
        assert_eq!((s.accepted, s.wrong_accepted), (1, 0));
    }

    /// The rule as stated, slowly: each threshold's share by a pass over every frame, and
    /// Fisher's test by counting draws. Returns the threshold and, when it hinged on the
    /// test, the test's p and the threshold the other outcome gives.
    fn slow_threshold(frames: &[Scored], max_wrong: f64) -> (f32, Option<(f64, f32)>) {
        let eligible: Vec<&Scored> = frames.iter().filter(|f| f.eligible).collect();
        let lowest = |wrong: &dyn Fn(&Scored) -> bool| {
            let top = eligible.iter().map(|f| f.score).fold(f32::NEG_INFINITY, f32::max);
            eligible
                .iter()
                .map(|f| f.score)
                .filter(|&t| {
                    let acc: Vec<_> = eligible.iter().filter(|f| f.score >= t).collect();
                    acc.iter().filter(|f| wrong(f)).count() as f64 <= max_wrong * acc.len() as f64
                })
                .fold(top.next_up(), f32::min)
        };
        let gross = lowest(&|f| f.gross);
        let every = lowest(&|f| !f.correct);
        // Near misses beyond the target at the gross threshold, beyond chance: every
        // pose refused (the binomial tail as a sum of products).
        let at_gross = || {
            let acc: Vec<_> = eligible.iter().filter(|f| f.score >= gross).collect();
            let (n, k) = (acc.len(), acc.iter().filter(|f| !f.correct).count());
            let tail: f64 = (k..=n)
                .map(|i| {
                    let choose: f64 = (0..i).map(|j| (n - j) as f64 / (j + 1) as f64).product();
                    choose * max_wrong.powi(i as i32) * (1.0 - max_wrong).powi((n - i) as i32)
                })
                .sum();
            if k > 0 && tail < EXCESS_ALPHA {
                REFUSE_ALL
            } else {
                gross
            }
        };
        if every <= gross {
            return (at_gross(), None);
        }
        let pool: Vec<&&Scored> = eligible.iter().filter(|f| f.score >= gross).collect();
        let below: Vec<bool> = pool.iter().map(|f| f.score < every).collect();
        let wrong: Vec<bool> = pool.iter().map(|f| !f.correct).collect();
        let seen = below.iter().zip(&wrong).filter(|(b, w)| **b && **w).count();
        // Every way to place the wrong poses among the pool: the share with as many below.
        let n = pool.len();
        let marked = wrong.iter().filter(|w| **w).count();
        let (mut hits, mut all) = (0u64, 0u64);
        for mask in 0u32..(1 << n) {
            if mask.count_ones() as usize != marked {
                continue;
            }
            all += 1;
            let k = (0..n).filter(|&i| mask & (1 << i) != 0 && below[i]).count();
            hits += u64::from(k >= seen);
        }
        let p = hits as f64 / all as f64;
        if p < SEPARATION_ALPHA {
            (every, Some((p, at_gross())))
        } else {
            (at_gross(), Some((p, every)))
        }
    }

    /// A xorshift generator from `state` (not 0): the random sets of the slow-rule tests.
    fn xorshift(mut state: u64) -> impl FnMut() -> u64 {
        move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        }
    }

    #[test]
    fn the_threshold_is_the_slow_rules() {
        // Small random sets (up to 16 eligible frames, so every placement of the wrong
        // poses can be counted), scores on a coarse grid so that ties occur.
        let mut next = xorshift(0x2545_f491_4f6c_dd1d);
        let (mut raised, mut refused) = (0, 0);
        for _ in 0..3000 {
            let n = 4 + (next() % 13) as usize;
            let frames: Vec<Scored> = (0..n)
                .map(|_| {
                    let r = next();
                    let correct = r % 10 < 6;
                    let gross = !correct && r % 10 == 9;
                    let score = (((r >> 8) % 20) as f32) / 20.0;
                    // Wrong poses lean low, so the test sometimes lets near misses lift it.
                    let score = if correct { score } else { score * 0.6 };
                    Scored { score, eligible: !(r >> 16).is_multiple_of(8), correct, gross }
                })
                .collect();
            let max_wrong = [0.005, 0.1, 0.25][(next() % 3) as usize];
            let fast = choose_threshold(&frames, max_wrong);
            let (slow, test) = slow_threshold(&frames, max_wrong);
            // A p that lands on the significance level itself (1 in 20 draws) may round
            // either way; either outcome's threshold is then the rule's.
            let on_the_level = test.is_some_and(|(p, other)| (p - SEPARATION_ALPHA).abs() < 1e-9 && fast == other);
            assert!(fast == slow || on_the_level, "{frames:?} at {max_wrong}: {fast} against {slow}");
            raised += usize::from(fast > lowest_within(&frames, max_wrong, |f| f.gross));
            refused += usize::from(fast == REFUSE_ALL);
        }
        // Every branch taken.
        assert!(raised > 100 && raised < 2900, "{raised}");
        assert!(refused > 30 && refused < raised, "{refused} of {raised}");
    }

    /// The negatives' threshold against the slow rule: of every candidate (0 and just above
    /// each score), the lowest at which at most the allowed share of all the negatives is
    /// eligible and scored at or above it.
    #[test]
    fn the_negatives_threshold_is_the_lowest_within_the_share() {
        let mut next = xorshift(0x9e37_79b9_7f4a_7c15);
        let mut raised = 0;
        for _ in 0..2000 {
            let n = (next() % 1200) as usize;
            // One in 4, 128 or 1024 passes the other checks: often more than the share.
            let rare = [4, 128, 1024][(next() % 3) as usize];
            let negatives: Vec<Scored> = (0..n)
                .map(|_| {
                    let r = next();
                    let score = ((r >> 16) % 50) as f32 / 50.0;
                    Scored { score, eligible: r.is_multiple_of(rare), correct: false, gross: true }
                })
                .collect();
            let fast = negatives_threshold(&negatives);
            let allowed = MAX_NEGATIVES_ACCEPTED * n as f64;
            let accepted = |t: f32| negatives.iter().filter(|f| f.eligible && f.score >= t).count() as f64;
            let slow = std::iter::once(0.0)
                .chain(negatives.iter().map(|f| f.score.next_up()))
                .filter(|&t| accepted(t) <= allowed)
                .fold(f32::INFINITY, f32::min);
            assert_eq!(fast, slow, "{n} negatives");
            raised += usize::from(fast > 0.0);
        }
        assert!(raised > 100 && raised < 1900, "{raised}");
    }

    /// A summary chosen with negatives holds the threshold the negatives need when it is
    /// above the frames' own, and counts them at it.
    #[test]
    fn negatives_raise_the_threshold_and_are_counted_at_it() {
        let frames: Vec<Scored> = (0..100)
            .map(|i| Scored { score: 0.5 + i as f32 / 250.0, eligible: true, correct: true, gross: false })
            .collect();
        let negatives: Vec<Scored> =
            (0..400).map(|i| Scored { score: i as f32 / 500.0, eligible: true, correct: false, gross: true }).collect();
        let s = VerifiedSummary::choose(&frames, &negatives, 0.005).unwrap();
        // Two of 400 may pass: the two highest, 0.796 and 0.798.
        assert_eq!(s.threshold, (0.794f32).next_up());
        assert_eq!((s.negatives, s.negatives_accepted), (400, 2));
        assert_eq!(s.correct_rejected, frames.iter().filter(|f| f.score < s.threshold).count());
        let alone = VerifiedSummary::choose(&frames, &[], 0.005).unwrap();
        assert_eq!((alone.threshold, alone.negatives), (0.5, 0));
    }
}
