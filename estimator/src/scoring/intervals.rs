//! Confidence intervals of a success rate: Wilson's score interval, the one every success
//! figure of a study carries.

/// z of a two-sided 95 % normal interval.
const Z95: f64 = 1.959_963_984_540_054;

/// Wilson score interval at 95 % of `successes` out of `n` trials ([0, 1] when `n` is 0).
pub fn wilson_interval(successes: usize, n: usize) -> [f64; 2] {
    if n == 0 {
        return [0.0, 1.0];
    }
    let (k, n) = (successes as f64, n as f64);
    let p = k / n;
    let z2 = Z95 * Z95;
    let centre = (p + z2 / (2.0 * n)) / (1.0 + z2 / n);
    let half = Z95 / (1.0 + z2 / n) * (p * (1.0 - p) / n + z2 / (4.0 * n * n)).sqrt();
    [(centre - half).max(0.0), (centre + half).min(1.0)]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wilson_matches_published_values() {
        // Newcombe (1998), Statistics in Medicine 17, table I: 81/263 -> 0.2553-0.3662,
        // 15/148 -> 0.0624-0.1605, 0/20 -> 0-0.1611.
        let close = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).abs() < 1e-4 && (a[1] - b[1]).abs() < 1e-4;
        assert!(close(wilson_interval(81, 263), [0.2553, 0.3662]), "{:?}", wilson_interval(81, 263));
        assert!(close(wilson_interval(15, 148), [0.0624, 0.1605]), "{:?}", wilson_interval(15, 148));
        assert!(close(wilson_interval(0, 20), [0.0, 0.1611]), "{:?}", wilson_interval(0, 20));
        assert_eq!(wilson_interval(0, 0), [0.0, 1.0]);
    }
}
