//! Many frames summed up: the success rate with its Wilson 95 % interval, mean and median
//! errors, mean correct matches and the median time of each stage.

use camplace_config::Metrics;
use serde::{Deserialize, Serialize};

use super::intervals::wilson_interval;
use super::record::{FrameRecord, SlotScore, Timings};
use super::verified::{clopper_pearson_upper, Scored, VerifiedSummary, UPPER_CONFIDENCE};

/// The summary of a set of frames (`summary.json`, and the end of `replay`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    /// Frames summed up.
    pub frames: usize,
    /// Frames with a truth to score against.
    pub scored: usize,
    /// Scored frames whose pose was found within the success limits.
    pub successes: usize,
    /// `successes / scored` (0 when nothing is scored).
    pub success_rate: f64,
    /// Wilson score interval of the success rate at 95 %: [low, high].
    pub success_interval: [f64; 2],
    /// Frames where a pose was found.
    pub found: usize,
    /// Mean and median position error over the scored frames where a pose was found, mm.
    pub mean_position_error_mm: Option<f64>,
    pub median_position_error_mm: Option<f64>,
    /// Mean and median rotation error over the scored frames where a pose was found, deg.
    pub mean_rotation_error_deg: Option<f64>,
    pub median_rotation_error_deg: Option<f64>,
    /// Mean correct feature matches per scored frame.
    pub mean_correct_matches: Option<f64>,
    /// Median time of each stage over all frames, ms.
    pub median_timings_ms: Timings,
    /// Median whole-frame time, ms.
    pub median_ms: f64,
    /// The verification's figures at the threshold chosen from these frames (absent when
    /// no frame has a score and a truth, and from summaries written before it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub verification: Option<VerifiedSummary>,
    /// The slots' states of the accepted poses against the truth (absent when no record
    /// carries a slot score).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub slots: Option<SlotSummary>,
    /// The hard negatives of the frames that carry them, against the frames' own correct
    /// poses (absent when no record carries negatives).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub negatives: Option<NegativesSummary>,
}

/// The hard negatives of a set of frames (each a wrong pose made from the truth, refined
/// and verified, [`super::NegativeRecord`]) beside the frames' own correct poses, both by
/// the verdicts the estimator gave them: how well the verification at the model's
/// threshold separates the two.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct NegativesSummary {
    /// Frames that carry negatives.
    pub frames: usize,
    /// Negatives that stayed grossly wrong once refined (off by more than `GROSS_FACTOR`
    /// times a success limit).
    pub negatives: usize,
    /// Of them, rejected by the verification.
    pub rejected: usize,
    /// The one-sided 95 % upper bound of the share of negatives accepted.
    pub accepted_upper: f64,
    /// Negatives whose refinement brought them back within the success limits (no
    /// negative after all; not counted above).
    pub returned: usize,
    /// Negatives refined to a near miss (wrong, within `GROSS_FACTOR` times a success
    /// limit; not counted above), and of them accepted.
    pub near_misses: usize,
    pub near_misses_accepted: usize,
    /// Per kind (`turn`, `grid turn`, `shift`, `tilt`): (negatives, rejected).
    pub by_kind: Vec<(String, usize, usize)>,
    /// The same frames' own poses: correct ones, and of them accepted.
    pub correct: usize,
    pub correct_accepted: usize,
}

impl NegativesSummary {
    /// Sums up the negatives of `records`; `None` when none carries them.
    pub fn of(records: &[FrameRecord]) -> Option<NegativesSummary> {
        let carrying: Vec<&FrameRecord> = records.iter().filter(|r| r.negatives.is_some()).collect();
        if carrying.is_empty() {
            return None;
        }
        let mut out = NegativesSummary { frames: carrying.len(), ..NegativesSummary::default() };
        for r in &carrying {
            if r.score.is_some_and(|s| s.success) {
                out.correct += 1;
                out.correct_accepted += usize::from(r.accepted());
            }
            for n in r.negatives.iter().flatten() {
                if n.correct {
                    out.returned += 1;
                    continue;
                }
                if !n.gross {
                    out.near_misses += 1;
                    out.near_misses_accepted += usize::from(n.accepted());
                    continue;
                }
                let rejected = !n.accepted();
                out.negatives += 1;
                out.rejected += usize::from(rejected);
                match out.by_kind.iter_mut().find(|(kind, _, _)| *kind == n.kind) {
                    Some(k) => (k.1, k.2) = (k.1 + 1, k.2 + usize::from(rejected)),
                    None => out.by_kind.push((n.kind.clone(), 1, usize::from(rejected))),
                }
            }
        }
        out.by_kind.sort();
        out.accepted_upper = clopper_pearson_upper(out.negatives - out.rejected, out.negatives, UPPER_CONFIDENCE);
        Some(out)
    }

    /// One line for a terminal and the report.
    pub fn line(&self) -> String {
        let share = |k: usize, n: usize| if n == 0 { 0.0 } else { 100.0 * k as f64 / n as f64 };
        let kinds: Vec<String> = self.by_kind.iter().map(|(kind, n, r)| format!("{kind} {r}/{n}")).collect();
        format!(
            "hard negatives of {} scenes: {} of {} rejected ({:.2} %; accepted at most {:.2} % at 95 %) [{}], {} back at the truth and {} near misses ({} accepted) once refined; correct poses accepted {} of {} ({:.1} %)",
            self.frames,
            self.rejected,
            self.negatives,
            share(self.rejected, self.negatives),
            100.0 * self.accepted_upper,
            kinds.join(", "),
            self.returned,
            self.near_misses,
            self.near_misses_accepted,
            self.correct_accepted,
            self.correct,
            share(self.correct_accepted, self.correct)
        )
    }
}

/// The slot states of a set of frames, among the accepted poses.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct SlotSummary {
    /// Accepted frames with a slot score.
    pub frames: usize,
    /// Slots judged in them.
    pub slots: u64,
    /// Of them, filled slots called empty and empty slots called filled.
    pub wrong: u64,
    /// Of them, slots judged unseen.
    pub unseen: u64,
    /// `1 - wrong / slots` (1 when no slot was judged).
    pub accuracy: f64,
    /// `unseen / slots`.
    pub unseen_share: f64,
    /// Median over accepted, correct poses of each frame's largest grasp-frame error, mm
    /// and deg.
    pub median_grasp_error_mm: Option<f64>,
    pub median_grasp_error_deg: Option<f64>,
    /// Median over every truly filled slot of the accepted, correct poses of its grasp
    /// frame's error, mm and deg.
    #[serde(default)]
    pub median_slot_grasp_error_mm: Option<f64>,
    #[serde(default)]
    pub median_slot_grasp_error_deg: Option<f64>,
}

impl SlotSummary {
    /// Sums up the slot scores of `records`' accepted poses; `None` when none has one.
    pub fn of(records: &[FrameRecord]) -> Option<SlotSummary> {
        let scored: Vec<(&FrameRecord, &SlotScore)> =
            records.iter().filter(|r| r.accepted()).filter_map(|r| r.slot_score.as_ref().map(|s| (r, s))).collect();
        if scored.is_empty() {
            return None;
        }
        let slots: u64 = scored.iter().map(|(_, s)| u64::from(s.slots)).sum();
        let wrong: u64 = scored.iter().map(|(_, s)| u64::from(s.wrong())).sum();
        let unseen: u64 = scored.iter().map(|(_, s)| u64::from(s.unseen)).sum();
        let correct = || scored.iter().filter(|(r, _)| r.score.is_some_and(|s| s.success));
        let mm: Vec<f64> = correct().map(|(_, s)| s.grasp_error_mm).collect();
        let deg: Vec<f64> = correct().map(|(_, s)| s.grasp_error_deg).collect();
        let each = || correct().flat_map(|(_, s)| s.grasp_errors.iter());
        let slot_mm: Vec<f64> = each().map(|e| e[0]).collect();
        let slot_deg: Vec<f64> = each().map(|e| e[1]).collect();
        let share = |n: u64| if slots == 0 { 0.0 } else { n as f64 / slots as f64 };
        Some(SlotSummary {
            frames: scored.len(),
            slots,
            wrong,
            unseen,
            accuracy: 1.0 - share(wrong),
            unseen_share: share(unseen),
            median_grasp_error_mm: median(&mm),
            median_grasp_error_deg: median(&deg),
            median_slot_grasp_error_mm: median(&slot_mm),
            median_slot_grasp_error_deg: median(&slot_deg),
        })
    }

    /// The one-sided 95 % lower bound of [`SlotSummary::accuracy`]: one minus the
    /// Clopper–Pearson upper bound of the wrong calls' share (0 when no slot was judged).
    /// Slots of one frame are counted as independent calls.
    pub fn accuracy_lower(&self) -> f64 {
        1.0 - clopper_pearson_upper(self.wrong as usize, self.slots as usize, UPPER_CONFIDENCE)
    }

    /// One line for a terminal and the report.
    pub fn line(&self) -> String {
        let opt = |v: Option<f64>, unit: &str| v.map_or("n/a".to_string(), |v| format!("{v:.2} {unit}"));
        format!(
            "slots of {} accepted poses: {} wrong filled/empty of {} ({:.2} %), {} unseen ({:.1} %), median grasp error {} / {} (a frame's worst slot), {} / {} (each filled slot)",
            self.frames,
            self.wrong,
            self.slots,
            100.0 * (1.0 - self.accuracy),
            self.unseen,
            100.0 * self.unseen_share,
            opt(self.median_grasp_error_mm, "mm"),
            opt(self.median_grasp_error_deg, "deg"),
            opt(self.median_slot_grasp_error_mm, "mm"),
            opt(self.median_slot_grasp_error_deg, "deg"),
        )
    }
}

impl Summary {
    /// Sums up `records` (their order does not matter).
    pub fn from_records(records: &[FrameRecord]) -> Summary {
        let scored: Vec<_> = records.iter().filter_map(|r| r.score.map(|s| (r.found, s))).collect();
        let successes = scored.iter().filter(|(_, s)| s.success).count();
        let found_errors: Vec<_> = scored.iter().filter(|(found, _)| *found).map(|(_, s)| *s).collect();
        let positions: Vec<f64> = found_errors.iter().map(|s| s.position_error_mm).collect();
        let rotations: Vec<f64> = found_errors.iter().map(|s| s.rotation_error_deg).collect();
        let correct: Vec<f64> = scored.iter().map(|(_, s)| s.correct_matches as f64).collect();
        let stage =
            |pick: fn(&Timings) -> f64| median(&records.iter().map(|r| pick(&r.timings_ms)).collect::<Vec<_>>());
        let median_timings_ms = Timings {
            rectify: stage(|t| t.rectify).unwrap_or(0.0),
            disparity: stage(|t| t.disparity).unwrap_or(0.0),
            cloud: stage(|t| t.cloud).unwrap_or(0.0),
            downsample: stage(|t| t.downsample).unwrap_or(0.0),
            normals: stage(|t| t.normals).unwrap_or(0.0),
            features: stage(|t| t.features).unwrap_or(0.0),
            matching: stage(|t| t.matching).unwrap_or(0.0),
            ransac: stage(|t| t.ransac).unwrap_or(0.0),
            icp: stage(|t| t.icp).unwrap_or(0.0),
            verify: stage(|t| t.verify).unwrap_or(0.0),
        };
        Summary {
            frames: records.len(),
            scored: scored.len(),
            successes,
            success_rate: if scored.is_empty() { 0.0 } else { successes as f64 / scored.len() as f64 },
            success_interval: wilson_interval(successes, scored.len()),
            found: records.iter().filter(|r| r.found).count(),
            mean_position_error_mm: mean(&positions),
            median_position_error_mm: median(&positions),
            mean_rotation_error_deg: mean(&rotations),
            median_rotation_error_deg: median(&rotations),
            mean_correct_matches: mean(&correct),
            median_timings_ms,
            median_ms: median(&records.iter().map(|r| r.ms).collect::<Vec<_>>()).unwrap_or(0.0),
            verification: None,
            slots: SlotSummary::of(records),
            negatives: NegativesSummary::of(records),
        }
    }

    /// The summary with the verification's figures of `records` judged by the success
    /// limits `metrics`: the threshold [`choose_threshold`](super::choose_threshold) picks
    /// for `max_wrong`, and the figures at it.
    pub fn verified(mut self, records: &[FrameRecord], max_wrong: f64, metrics: &Metrics) -> Summary {
        self.verification = VerifiedSummary::of_records(records, max_wrong, metrics);
        self
    }

    /// The summary with the verification's figures of `records` at `threshold` (the one an
    /// estimator applied), where [`Summary::verified`] chooses it.
    pub fn verified_at(
        mut self,
        records: &[FrameRecord],
        threshold: f32,
        max_wrong: f64,
        metrics: &Metrics,
    ) -> Summary {
        let frames: Vec<Scored> = records.iter().filter_map(|r| Scored::of(r, metrics)).collect();
        self.verification = (!frames.is_empty()).then(|| VerifiedSummary::at(&frames, threshold, max_wrong));
        self
    }

    /// One line for a terminal: rate, interval, errors and time.
    pub fn line(&self) -> String {
        let opt = |v: Option<f64>, unit: &str| v.map_or("n/a".to_string(), |v| format!("{v:.2} {unit}"));
        if self.scored == 0 {
            return format!(
                "{} frames, {} with a pose, none with a truth; median {:.1} ms per frame",
                self.frames, self.found, self.median_ms
            );
        }
        format!(
            "success {:.1} % ({} of {}, 95 % interval {:.1}–{:.1} %), median errors {} / {}, \
             mean correct matches {:.1}, median {:.1} ms per frame",
            100.0 * self.success_rate,
            self.successes,
            self.scored,
            100.0 * self.success_interval[0],
            100.0 * self.success_interval[1],
            opt(self.median_position_error_mm, "mm"),
            opt(self.median_rotation_error_deg, "deg"),
            self.mean_correct_matches.unwrap_or(0.0),
            self.median_ms
        ) + &self.verification.map_or(String::new(), |v| format!("; {}", v.line()))
            + &self.slots.map_or(String::new(), |s| format!("; {}", s.line()))
            + &self.negatives.as_ref().map_or(String::new(), |n| format!("; {}", n.line()))
    }
}

/// A rate as a percentage with one decimal (config's, so files and summaries agree).
pub use camplace_config::pct;

/// Median of `values` (mean of the middle two for an even count); `None` when empty.
pub fn median(values: &[f64]) -> Option<f64> {
    median_in_place(&mut values.to_vec())
}

/// [`median`] of values the caller owns, sorted in place: no copy.
pub fn median_in_place(values: &mut [f64]) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    values.sort_by(f64::total_cmp);
    let m = values.len() / 2;
    Some(if values.len() % 2 == 1 { values[m] } else { 0.5 * (values[m - 1] + values[m]) })
}

/// [`median`], NaN when empty: for the calibrations' outlier rules, where an empty list
/// has been refused before.
pub(crate) fn median_or_nan(values: &[f64]) -> f64 {
    median(values).unwrap_or(f64::NAN)
}

/// The nearest-rank `q`-th percentile (0 < q ≤ 100) of ascending `sorted` values: the
/// smallest value with at least q % of all at or below it; `None` when empty.
pub fn percentile(sorted: &[f64], q: f64) -> Option<f64> {
    if sorted.is_empty() {
        return None;
    }
    let rank = ((q / 100.0) * sorted.len() as f64).ceil() as usize;
    Some(sorted[rank.clamp(1, sorted.len()) - 1])
}

fn mean(values: &[f64]) -> Option<f64> {
    (!values.is_empty()).then(|| values.iter().sum::<f64>() / values.len() as f64)
}

#[cfg(test)]
mod tests {
    use super::super::record::Score;
    use super::*;

    #[test]
    fn nearest_rank_percentiles_match_counting() {
        let values: Vec<f64> = (1..=200).rev().map(f64::from).collect();
        let mut sorted = values.clone();
        sorted.sort_by(f64::total_cmp);
        for q in [1.0, 50.0, 90.0, 99.0, 100.0] {
            let got = percentile(&sorted, q).unwrap();
            // The smallest value with at least q % of all values at or below it.
            let slow = values
                .iter()
                .copied()
                .filter(|&v| values.iter().filter(|&&w| w <= v).count() as f64 >= q / 100.0 * values.len() as f64)
                .fold(f64::INFINITY, f64::min);
            assert_eq!(got, slow, "q {q}");
        }
        assert_eq!(percentile(&[7.0], 99.0), Some(7.0));
        assert_eq!(percentile(&[], 50.0), None);
    }

    #[test]
    fn slot_accuracy_lower_bound_is_where_so_few_wrong_calls_become_unlikely() {
        // The slowest way: the smallest accuracy a (on a 1e-5 grid) at which seeing `wrong`
        // or fewer wrong calls in `slots` still has probability 5 % or more, from the
        // binomial tail summed term by term.
        let slow = |wrong: u64, slots: u64| {
            let tail = |p: f64| {
                (0..=wrong)
                    .map(|k| {
                        let ln_choose: f64 = (0..k).map(|i| ((slots - i) as f64 / (i + 1) as f64).ln()).sum();
                        (ln_choose + k as f64 * p.ln() + (slots - k) as f64 * (1.0 - p).ln()).exp()
                    })
                    .sum::<f64>()
            };
            (0..100_000).map(|i| i as f64 * 1e-5).filter(|&a| tail(1.0 - a) >= 0.05).fold(1.0, f64::min)
        };
        for (wrong, slots) in [(0, 40), (1, 300), (3, 2400), (10, 500)] {
            let s = SlotSummary { slots, wrong, ..SlotSummary::default() };
            let got = s.accuracy_lower();
            assert!((got - slow(wrong, slots)).abs() < 2e-5, "{wrong} of {slots}: {got} vs {}", slow(wrong, slots));
            assert!(got < 1.0 - wrong as f64 / slots as f64, "{wrong} of {slots}: below the point estimate");
        }
        assert_eq!(SlotSummary::default().accuracy_lower(), 0.0, "no slot judged is no evidence");
    }

    #[test]
    fn the_median_is_the_middle_value_or_the_mean_of_the_middle_two() {
        assert_eq!(median(&[3.0, 1.0, 2.0]), Some(2.0));
        assert_eq!(median(&[4.0, 1.0, 3.0, 2.0]), Some(2.5));
        assert_eq!(median(&[]), None);
    }
    use crate::PoseEstimate;

    #[test]
    fn summary_counts_errors_of_found_poses_only() {
        let record = |found: bool, pos: f64, success: bool, ms: f64| {
            let pose = PoseEstimate { found, ..Default::default() };
            let mut r = FrameRecord::new("x", &pose);
            r.ms = ms;
            r.score =
                Some(Score { position_error_mm: pos, rotation_error_deg: pos / 10.0, correct_matches: 4, success });
            r
        };
        let records = [record(true, 1.0, true, 10.0), record(true, 5.0, false, 30.0), record(false, 99.0, false, 20.0)];
        let s = Summary::from_records(&records);
        assert_eq!((s.frames, s.scored, s.successes, s.found), (3, 3, 1, 2));
        assert!((s.success_rate - 1.0 / 3.0).abs() < 1e-12);
        assert_eq!(s.mean_position_error_mm, Some(3.0));
        assert_eq!(s.median_position_error_mm, Some(3.0));
        assert_eq!(s.mean_correct_matches, Some(4.0));
        assert_eq!(s.median_ms, 20.0);
        let reversed: Vec<_> = records.iter().rev().cloned().collect();
        assert_eq!(Summary::from_records(&reversed), s);
    }

    /// The negatives' summary against a count over every negative: only the grossly wrong
    /// count as negatives, those back at the truth and the near misses apart; the frames'
    /// own correct poses and their acceptance beside them; records without negatives left
    /// out; the order of the records irrelevant.
    #[test]
    fn negatives_are_counted_by_kind_apart_from_near_misses_and_returns() {
        use super::super::record::NegativeRecord;
        use crate::Verdict;
        let kinds = ["turn", "grid turn", "shift", "tilt"];
        let verdicts = [Verdict::Accepted, Verdict::PoorFit, Verdict::SeenThrough, Verdict::Ambiguous];
        let mut records = Vec::new();
        for f in 0..40u32 {
            let pose = PoseEstimate { found: true, ..Default::default() };
            let mut r = FrameRecord::new(format!("{f}"), &pose);
            r.verdict = Some(verdicts[(f % 3) as usize].as_str().to_string());
            r.score = Some(Score {
                position_error_mm: 1.0,
                rotation_error_deg: 0.1,
                correct_matches: 4,
                success: f % 5 != 0,
            });
            if f % 7 != 3 {
                r.negatives = Some(
                    (0..(f % 6))
                        .map(|k| NegativeRecord {
                            kind: kinds[((f + k) % 4) as usize].to_string(),
                            verdict: verdicts[((f * 3 + k) % 4) as usize].as_str().to_string(),
                            score: 0.5,
                            position_error_mm: 50.0,
                            rotation_error_deg: 90.0,
                            correct: (f + k) % 9 == 0,
                            gross: (f + k) % 4 != 1,
                        })
                        .collect(),
                );
            }
            records.push(r);
        }
        let s = NegativesSummary::of(&records).unwrap();
        let carrying: Vec<&FrameRecord> = records.iter().filter(|r| r.negatives.is_some()).collect();
        let all: Vec<&NegativeRecord> = carrying.iter().flat_map(|r| r.negatives.iter().flatten()).collect();
        let counted = |n: &&&NegativeRecord| !n.correct && n.gross;
        assert_eq!(s.frames, carrying.len());
        assert_eq!(s.negatives, all.iter().filter(counted).count());
        assert_eq!(s.rejected, all.iter().filter(counted).filter(|n| n.verdict != "accepted").count());
        assert_eq!(s.returned, all.iter().filter(|n| n.correct).count());
        assert_eq!(s.near_misses, all.iter().filter(|n| !n.correct && !n.gross).count());
        assert_eq!(
            s.near_misses_accepted,
            all.iter().filter(|n| !n.correct && !n.gross && n.verdict == "accepted").count()
        );
        for (kind, n, rejected) in &s.by_kind {
            let of_kind = || all.iter().filter(counted).filter(|x| x.kind == *kind);
            assert_eq!((*n, *rejected), (of_kind().count(), of_kind().filter(|x| x.verdict != "accepted").count()));
        }
        assert_eq!(s.by_kind.iter().map(|k| k.1).sum::<usize>(), s.negatives);
        let correct = || carrying.iter().filter(|r| r.score.is_some_and(|x| x.success));
        assert_eq!((s.correct, s.correct_accepted), (correct().count(), correct().filter(|r| r.accepted()).count()));
        assert!(s.rejected < s.negatives && s.near_misses > 0 && s.returned > 0, "{s:?}");
        let reversed: Vec<_> = records.iter().rev().cloned().collect();
        assert_eq!(NegativesSummary::of(&reversed), Some(s));
        assert_eq!(NegativesSummary::of(&records[3..4]), None);
    }
}
