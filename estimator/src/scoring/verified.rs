//! What the verification does over many scored frames: the threshold chosen from their scores
//! and truth (the lowest score at which wrong poses are at most the target share of the
//! accepted ones), the figures at it (verified success, wrong poses accepted with their
//! Clopper–Pearson upper bound, correct poses rejected) and the precision–recall curve.
//! It does not verify poses (the estimator does) nor draw the curve (the report does).

use crate::{ModelVerification, Verdict};
use serde::{Deserialize, Serialize};

use super::intervals::wilson_interval;
use super::record::FrameRecord;

/// One-sided confidence of the upper bound on the wrong share.
const UPPER_CONFIDENCE: f64 = 0.95;

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
}

impl Scored {
    /// The record's view, or `None` for a record without truth or written before the
    /// verification.
    pub fn of(record: &FrameRecord) -> Option<Scored> {
        let (score, verdict, truth) = (record.verify_score?, record.verdict.as_deref()?, record.score?);
        let eligible = record.found && [Verdict::Accepted.as_str(), Verdict::PoorFit.as_str()].contains(&verdict);
        Some(Scored { score, eligible, correct: truth.success })
    }
}

/// The verification's figures over a set of frames at one threshold (`verification` in
/// `summary.json`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct VerifiedSummary {
    /// Scores at or above this are accepted: the lowest at which wrong poses are at most
    /// `max_wrong` of the accepted ones on these frames (above every score when none is).
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
}

impl VerifiedSummary {
    /// The threshold chosen for `max_wrong` over `frames`, and the figures at it; `None`
    /// when no frame has a score.
    pub fn choose(frames: &[Scored], max_wrong: f64) -> Option<VerifiedSummary> {
        if frames.is_empty() {
            return None;
        }
        Some(Self::at(frames, choose_threshold(frames, max_wrong), max_wrong))
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
        )
    }
}

/// The lowest threshold at which wrong poses are at most `max_wrong` of the accepted ones:
/// one of the eligible scores, or just above the highest when no score qualifies.
pub fn choose_threshold(frames: &[Scored], max_wrong: f64) -> f32 {
    let mut eligible: Vec<(f32, bool)> = frames.iter().filter(|f| f.eligible).map(|f| (f.score, f.correct)).collect();
    // Highest first; walking down, each distinct score is a candidate threshold.
    eligible.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut best = eligible.first().map_or(0.0, |f| f.0.next_up());
    let (mut accepted, mut wrong) = (0usize, 0usize);
    let mut i = 0;
    while i < eligible.len() {
        let score = eligible[i].0;
        while i < eligible.len() && eligible[i].0 == score {
            accepted += 1;
            wrong += usize::from(!eligible[i].1);
            i += 1;
        }
        if wrong as f64 <= max_wrong * accepted as f64 {
            best = score;
        }
    }
    best
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

    fn frame(score: f32, correct: bool) -> Scored {
        Scored { score, eligible: true, correct }
    }

    #[test]
    fn the_threshold_is_the_lowest_score_within_the_target() {
        // 200 correct poses scored 0.5..0.9, 2 wrong ones at 0.3 and 0.6.
        let mut frames: Vec<Scored> = (0..200).map(|i| frame(0.5 + 0.4 * i as f32 / 200.0, true)).collect();
        frames.push(frame(0.3, false));
        frames.push(frame(0.6, false));
        // Ineligible (off the table) never counts as accepted.
        frames.push(Scored { score: 0.95, eligible: false, correct: false });
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
        let strict = VerifiedSummary::choose(&frames, 0.004).unwrap();
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
}
