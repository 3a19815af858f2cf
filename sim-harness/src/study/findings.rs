//! Comparing two measured success rates the way the report states them: each rate with
//! its Wilson interval, and the difference with Newcombe's hybrid score interval (method
//! 10 of Newcombe 1998), which treats the two as independent samples. Scenes shared by
//! both (common random numbers) make the true interval narrower, so the verdict errs on
//! the side of "not shown".

use super::summary::wilson_interval;

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

/// 95 % interval of `a − b` (Newcombe's hybrid score method).
pub fn difference_interval(a: Rate, b: Rate) -> [f64; 2] {
    let (p1, p2) = (a.value(), b.value());
    let [l1, u1] = a.interval();
    let [l2, u2] = b.interval();
    let d = p1 - p2;
    [d - ((p1 - l1).powi(2) + (u2 - p2).powi(2)).sqrt(), d + ((u1 - p1).powi(2) + (p2 - l2).powi(2)).sqrt()]
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

/// `a` against `b`: the verdict and a sentence with the figures.
pub fn compare(a_name: &str, a: Rate, b_name: &str, b: Rate) -> (Verdict, String) {
    let [lo, hi] = difference_interval(a, b);
    let verdict = if lo > 0.0 {
        Verdict::AHigher
    } else if hi < 0.0 {
        Verdict::BHigher
    } else {
        Verdict::NotShown
    };
    let text = format!(
        "{a_name}: {}; {b_name}: {}; difference {:+.1} points (95 % interval {:+.1} to {:+.1})",
        a.text(),
        b.text(),
        100.0 * (a.value() - b.value()),
        100.0 * lo,
        100.0 * hi
    );
    (verdict, text)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn newcombe_example() {
        // Newcombe (1998), Statistics in Medicine 17, table II example (e): 56/70 vs 48/80,
        // method 10 gives 0.0524 to 0.3339.
        let [lo, hi] = difference_interval(Rate { successes: 56, scenes: 70 }, Rate { successes: 48, scenes: 80 });
        assert!((lo - 0.0524).abs() < 1e-3 && (hi - 0.3339).abs() < 1e-3, "{lo} {hi}");
        let (v, _) = compare("a", Rate { successes: 56, scenes: 70 }, "b", Rate { successes: 48, scenes: 80 });
        assert_eq!(v, Verdict::AHigher);
        let (v, _) = compare("a", Rate { successes: 5, scenes: 10 }, "b", Rate { successes: 6, scenes: 10 });
        assert_eq!(v, Verdict::NotShown);
    }
}
