//! Comparing two measured success rates the way the report states them: each rate with
//! its Wilson interval, and the difference with an interval at 95 %.
//!
//! Two placements (or methods) judged on the same scenarios are paired samples: scene i is
//! the same scene for both (common random numbers), so most of the luck of the draw is
//! shared. [`Paired`] counts the scenes each side alone succeeded on (the discordant ones)
//! and states the difference with Newcombe's interval for paired proportions (method 10 of
//! Newcombe 1998, Statistics in Medicine 17:2635, Wilson intervals with a correlation
//! correction) and the exact McNemar test on the discordant scenes. The mounting
//! tolerances use the same test one-sided (is this point lower than the nominal?) and its
//! power against a given drop, from which their scene count is chosen.

use camplace_estimator::scoring::wilson_interval;

/// A success count out of a number of scenes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Rate {
    /// Successes.
    pub successes: usize,
    /// Scenes.
    pub scenes: usize,
}

impl Rate {
    /// The rate (0 with no scenes).
    pub fn value(&self) -> f64 {
        if self.scenes == 0 {
            0.0
        } else {
            self.successes as f64 / self.scenes as f64
        }
    }

    /// Its Wilson 95 % interval.
    pub fn interval(&self) -> [f64; 2] {
        wilson_interval(self.successes, self.scenes)
    }

    /// "62.0 % (155 of 250, 95 % interval 55.8–67.8 %)".
    pub fn text(&self) -> String {
        let [lo, hi] = self.interval();
        format!(
            "{:.1} % ({} of {}, 95 % interval {:.1}–{:.1} %)",
            100.0 * self.value(),
            self.successes,
            self.scenes,
            100.0 * lo,
            100.0 * hi
        )
    }
}

/// What a comparison of `a` against `b` shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// The whole interval of a − b is above 0.
    AHigher,
    /// The whole interval of a − b is below 0.
    BHigher,
    /// The interval holds 0: no difference shown.
    NotShown,
}

/// Two sides' outcomes on the same scenes, as the four counts of a paired 2 × 2 table.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Paired {
    /// Scenes both sides succeeded on.
    pub both: usize,
    /// Scenes only side a succeeded on.
    pub only_a: usize,
    /// Scenes only side b succeeded on.
    pub only_b: usize,
    /// Scenes neither succeeded on.
    pub neither: usize,
}

impl Paired {
    /// Pairs the outcomes scene by scene (`None`: the scene is missing or unscored on that
    /// side, and the pair is left out).
    pub fn from_outcomes(a: &[Option<bool>], b: &[Option<bool>]) -> Paired {
        let mut p = Paired::default();
        for (x, y) in a.iter().zip(b) {
            match (x, y) {
                (Some(true), Some(true)) => p.both += 1,
                (Some(true), Some(false)) => p.only_a += 1,
                (Some(false), Some(true)) => p.only_b += 1,
                (Some(false), Some(false)) => p.neither += 1,
                _ => {}
            }
        }
        p
    }

    /// Paired scenes.
    pub fn scenes(&self) -> usize {
        self.both + self.only_a + self.only_b + self.neither
    }

    /// Side a's rate over the paired scenes.
    pub fn a(&self) -> Rate {
        Rate { successes: self.both + self.only_a, scenes: self.scenes() }
    }

    /// Side b's rate over the paired scenes.
    pub fn b(&self) -> Rate {
        Rate { successes: self.both + self.only_b, scenes: self.scenes() }
    }

    /// 95 % interval of rate(a) − rate(b) for paired data (Newcombe 1998, method 10).
    pub fn difference_interval(&self) -> [f64; 2] {
        let n = self.scenes();
        if n == 0 {
            return [-1.0, 1.0];
        }
        let (a, b) = (self.a(), self.b());
        let (p1, p2) = (a.value(), b.value());
        let [l1, u1] = a.interval();
        let [l2, u2] = b.interval();
        // The correlation of the two sides' outcomes (0 when a margin is empty).
        let (e, f, g, h) = (self.both as f64, self.only_a as f64, self.only_b as f64, self.neither as f64);
        let margins = (e + f) * (g + h) * (e + g) * (f + h);
        let phi = if margins > 0.0 { (e * h - f * g) / margins.sqrt() } else { 0.0 };
        let d = p1 - p2;
        let lower = ((p1 - l1).powi(2) - 2.0 * phi * (p1 - l1) * (u2 - p2) + (u2 - p2).powi(2)).max(0.0).sqrt();
        let upper = ((u1 - p1).powi(2) - 2.0 * phi * (u1 - p1) * (p2 - l2) + (p2 - l2).powi(2)).max(0.0).sqrt();
        [(d - lower).max(-1.0), (d + upper).min(1.0)]
    }

    /// Two-sided p-value of the exact McNemar test: under no difference each discordant
    /// scene is side a's with probability one half.
    pub fn mcnemar_p(&self) -> f64 {
        let m = self.only_a + self.only_b;
        (2.0 * binomial_half_cdf(m, self.only_a.min(self.only_b))).min(1.0)
    }
}

impl Paired {
    /// One-sided p-value of the exact McNemar test that side a succeeds less often than side
    /// b: the chance that a fair coin over the discordant scenes gives side a at most as many
    /// as it got.
    pub fn mcnemar_p_a_lower(&self) -> f64 {
        binomial_half_cdf(self.only_a + self.only_b, self.only_a)
    }
}

/// P(X <= k) for X ~ Binomial(m, 1/2), summed in logs so large m stays finite.
fn binomial_half_cdf(m: usize, k: usize) -> f64 {
    let ln_half_m = m as f64 * 0.5f64.ln();
    let mut ln_choose = 0.0; // ln C(m, 0)
    let mut tail = 0.0;
    for i in 0..=k.min(m) {
        if i > 0 {
            ln_choose += ((m - i + 1) as f64).ln() - (i as f64).ln();
        }
        tail += (ln_choose + ln_half_m).exp();
    }
    tail.min(1.0)
}

/// The fewest scenes side a must lose (gaining none) for the one-sided exact McNemar test
/// to show it lower at `level`: 5 at 5 %.
pub fn losses_to_show_a_drop(level: f64) -> usize {
    (1..64).find(|&l| binomial_half_cdf(l, 0) < level).unwrap_or(64)
}

/// The power of the one-sided exact McNemar test at `level` on `scenes` paired scenes when
/// side a loses each scene side b succeeds on with probability `drop` and gains none: the
/// chance that Binomial(scenes, drop) reaches [`losses_to_show_a_drop`].
pub fn drop_detection_power(scenes: usize, drop: f64, level: f64) -> f64 {
    let need = losses_to_show_a_drop(level);
    if drop.is_nan() || drop <= 0.0 || scenes < need {
        return 0.0;
    }
    if drop >= 1.0 {
        return 1.0;
    }
    // 1 - P(X < need), each term by its logarithm.
    let (n, ln_p, ln_q) = (scenes as f64, drop.ln(), (1.0 - drop).ln());
    let mut ln_choose = 0.0;
    let mut below = 0.0;
    for i in 0..need {
        if i > 0 {
            ln_choose += (n - i as f64 + 1.0).ln() - (i as f64).ln();
        }
        below += (ln_choose + i as f64 * ln_p + (n - i as f64) * ln_q).exp();
    }
    (1.0 - below).clamp(0.0, 1.0)
}

/// The fewest paired scenes on which [`drop_detection_power`] of a `drop` reaches `power`
/// (at most 100 000).
pub fn scenes_for_power(drop: f64, power: f64, level: f64) -> Option<usize> {
    (1..=100_000).find(|&n| drop_detection_power(n, drop, level) >= power)
}

/// `a` against `b` on the same scenes: the verdict (from the paired interval) and a sentence
/// with the figures and the exact McNemar test.
pub fn compare_paired(a_name: &str, b_name: &str, p: Paired) -> (Verdict, String) {
    let [lo, hi] = p.difference_interval();
    let verdict = if lo > 0.0 {
        Verdict::AHigher
    } else if hi < 0.0 {
        Verdict::BHigher
    } else {
        Verdict::NotShown
    };
    let (a, b) = (p.a(), p.b());
    let text = format!(
        "{a_name}: {}; {b_name}: {}; on the same {} scenes, difference {:+.1} points (paired 95 % interval {:+.1} to {:+.1}); \
         {} only the first succeeded on, {} only the second (exact McNemar p {})",
        a.text(),
        b.text(),
        p.scenes(),
        100.0 * (a.value() - b.value()),
        100.0 * lo,
        100.0 * hi,
        count_scenes(p.only_a),
        p.only_b,
        p_value(p.mcnemar_p())
    );
    (verdict, text)
}

/// "= 0.037", or "< 0.001" for smaller.
fn p_value(p: f64) -> String {
    if p < 0.001 {
        "< 0.001".to_string()
    } else {
        format!("= {p:.3}")
    }
}

/// "1 scene", "3 scenes".
fn count_scenes(n: usize) -> String {
    if n == 1 {
        "1 scene".to_string()
    } else {
        format!("{n} scenes")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The interval for independent samples (Newcombe's hybrid score method): what the
    /// paired one reduces to when the two sides are uncorrelated.
    fn difference_interval(a: Rate, b: Rate) -> [f64; 2] {
        let (p1, p2) = (a.value(), b.value());
        let [l1, u1] = a.interval();
        let [l2, u2] = b.interval();
        let d = p1 - p2;
        [d - ((p1 - l1).powi(2) + (u2 - p2).powi(2)).sqrt(), d + ((u1 - p1).powi(2) + (p2 - l2).powi(2)).sqrt()]
    }

    /// ln(n!) by summing logs: the slow obvious version.
    fn ln_factorial(n: usize) -> f64 {
        (1..=n).map(|i| (i as f64).ln()).sum()
    }

    #[test]
    fn mcnemar_equals_the_binomial_tail_summed_from_factorials() {
        for m in 0..60usize {
            for k in 0..=m {
                let p = Paired { both: 3, only_a: k, only_b: m - k, neither: 4 };
                let probability =
                    |i: usize| (ln_factorial(m) - ln_factorial(i) - ln_factorial(m - i) - m as f64 * 2f64.ln()).exp();
                // Two-sided: every outcome at most as likely as the one seen (the law is symmetric).
                let seen = probability(k);
                let slow: f64 = (0..=m).map(probability).filter(|&q| q <= seen * (1.0 + 1e-9)).sum();
                assert!((p.mcnemar_p() - slow.min(1.0)).abs() < 1e-9, "m {m} k {k}: {} vs {slow}", p.mcnemar_p());
            }
        }
        // 0 of 10 discordant scenes against: p = 2 / 1024.
        assert!((Paired { only_a: 10, ..Paired::default() }.mcnemar_p() - 2.0 / 1024.0).abs() < 1e-12);
        // Large counts stay finite.
        let big = Paired { only_a: 4000, only_b: 3800, ..Paired::default() }.mcnemar_p();
        assert!(big.is_finite() && big > 0.0 && big < 0.05, "{big}");
    }

    #[test]
    fn the_paired_interval_covers_the_true_difference_as_often_as_it_says() {
        // Exact coverage by enumerating every table of n paired scenes under a true law
        // (p_both, p_a, p_b, p_neither): the mean over many laws is near 95 % (Newcombe
        // reports 0.95 for method 10) and no law falls far below.
        let n = 30usize;
        let ln_multinomial = |c: [usize; 4], p: [f64; 4]| -> f64 {
            let mut v = ln_factorial(n);
            for (k, q) in c.iter().zip(p) {
                v -= ln_factorial(*k);
                if *k > 0 {
                    v += *k as f64 * q.ln();
                }
            }
            v
        };
        let mut coverages = Vec::new();
        for pa in [0.5f64, 0.7, 0.85, 0.95] {
            for pb in [0.5, 0.7, 0.85, 0.95] {
                for rho_share in [0.0, 0.5, 0.9] {
                    // P(both) from independence towards the largest overlap.
                    let indep = pa * pb;
                    let both: f64 = indep + rho_share * (pa.min(pb) - indep);
                    let law = [both, pa - both, pb - both, 1.0 - pa - pb + both];
                    if law.iter().any(|&q| q <= 0.0) {
                        continue;
                    }
                    let truth = pa - pb;
                    let mut covered = 0.0;
                    for e in 0..=n {
                        for f in 0..=n - e {
                            for g in 0..=n - e - f {
                                let h = n - e - f - g;
                                let t = Paired { both: e, only_a: f, only_b: g, neither: h };
                                let [lo, hi] = t.difference_interval();
                                if lo <= truth + 1e-12 && truth <= hi + 1e-12 {
                                    covered += ln_multinomial([e, f, g, h], law).exp();
                                }
                            }
                        }
                    }
                    coverages.push(covered);
                }
            }
        }
        let mean = coverages.iter().sum::<f64>() / coverages.len() as f64;
        let min = coverages.iter().cloned().fold(1.0, f64::min);
        assert!((0.935..=0.975).contains(&mean), "mean coverage {mean}");
        assert!(min > 0.85, "worst coverage {min}");
    }

    #[test]
    fn paired_outcomes_count_each_scene_once_and_drop_missing_ones() {
        let a = [Some(true), Some(true), Some(false), Some(false), None, Some(true)];
        let b = [Some(true), Some(false), Some(true), Some(false), Some(true), None];
        let p = Paired::from_outcomes(&a, &b);
        assert_eq!(p, Paired { both: 1, only_a: 1, only_b: 1, neither: 1 });
        // With no correlation the paired interval is the unpaired one.
        let t = Paired { both: 25, only_a: 25, only_b: 25, neither: 25 };
        let unpaired = difference_interval(t.a(), t.b());
        let paired = t.difference_interval();
        assert!((unpaired[0] - paired[0]).abs() < 1e-12 && (unpaired[1] - paired[1]).abs() < 1e-12);
        // Shared luck narrows it: 7 more successes of 100 on the same scenes, no scene lost.
        let shared = Paired { both: 85, only_a: 7, only_b: 0, neither: 8 };
        let [lo, _] = shared.difference_interval();
        let [ulo, _] = difference_interval(shared.a(), shared.b());
        assert!(lo > 0.0 && ulo < 0.0, "paired {lo}, unpaired {ulo}");
        assert_eq!(compare_paired("a", "b", shared).0, Verdict::AHigher);
    }

    #[test]
    fn the_one_sided_test_and_its_power_agree_with_sums_of_factorials() {
        let choose = |n: usize, k: usize| (ln_factorial(n) - ln_factorial(k) - ln_factorial(n - k)).exp();
        for m in 0..40usize {
            for k in 0..=m {
                let p = Paired { both: 2, only_a: k, only_b: m - k, neither: 1 };
                let slow: f64 = (0..=k).map(|i| choose(m, i)).sum::<f64>() / 2f64.powi(m as i32);
                assert!((p.mcnemar_p_a_lower() - slow).abs() < 1e-9, "m {m} k {k}");
            }
        }
        // 5 scenes lost and none gained: p = 1/32 < 5 %; 4: 1/16 is not.
        assert_eq!(losses_to_show_a_drop(0.05), 5);
        assert!(Paired { only_b: 5, ..Paired::default() }.mcnemar_p_a_lower() < 0.05);
        assert!(Paired { only_b: 4, ..Paired::default() }.mcnemar_p_a_lower() >= 0.05);
        for n in [5usize, 20, 44, 66, 120] {
            for drop in [0.02f64, 0.1, 0.15, 0.5] {
                let slow: f64 =
                    (5..=n).map(|i| choose(n, i) * drop.powi(i as i32) * (1.0 - drop).powi((n - i) as i32)).sum();
                let fast = drop_detection_power(n, drop, 0.05);
                assert!((fast - slow).abs() < 1e-9, "n {n} drop {drop}: {fast} vs {slow}");
            }
        }
        assert_eq!(scenes_for_power(0.10, 0.8, 0.05), Some(66));
        assert_eq!(scenes_for_power(0.15, 0.8, 0.05), Some(44));
    }

    #[test]
    fn newcombe_example() {
        // Newcombe (1998), Statistics in Medicine 17, table II example (e): 56/70 vs 48/80,
        // method 10 gives 0.0524 to 0.3339.
        let [lo, hi] = difference_interval(Rate { successes: 56, scenes: 70 }, Rate { successes: 48, scenes: 80 });
        assert!((lo - 0.0524).abs() < 1e-3 && (hi - 0.3339).abs() < 1e-3, "{lo} {hi}");
        let (v, _) = compare_paired("a", "b", Paired { both: 5, only_a: 0, only_b: 1, neither: 4 });
        assert_eq!(v, Verdict::NotShown);
    }
}
