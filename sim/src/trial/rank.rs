//! Spearman's rank correlation between two placements' success rates with its 95 %
//! interval by Fisher's z with the Fieller–Hartley–Pearson standard error 1.03 / √(n − 3)
//! (Fieller et al. 1957): ties share the mean of their ranks.

/// ρ with its 95 % interval.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct RankCorrelation {
    /// Spearman's ρ.
    pub rho: f64,
    /// Its 95 % interval (Fisher z); `None` with fewer than 4 placements.
    pub interval: Option<[f64; 2]>,
    /// Placements ranked.
    pub n: usize,
}

/// Ranks 1 … n, ties given the mean of the ranks they span.
pub fn ranks(values: &[f64]) -> Vec<f64> {
    let mut order: Vec<usize> = (0..values.len()).collect();
    order.sort_by(|&a, &b| values[a].total_cmp(&values[b]));
    let mut out = vec![0.0; values.len()];
    let mut i = 0;
    while i < order.len() {
        let mut j = i;
        while j + 1 < order.len() && values[order[j + 1]] == values[order[i]] {
            j += 1;
        }
        let mean = (i + j) as f64 / 2.0 + 1.0;
        for &k in &order[i..=j] {
            out[k] = mean;
        }
        i = j + 1;
    }
    out
}

/// Spearman's ρ of paired values (Pearson's r of their ranks); `None` with fewer than two
/// pairs or when either side has one value only (ρ is then undefined).
pub fn spearman(a: &[f64], b: &[f64]) -> Option<RankCorrelation> {
    assert_eq!(a.len(), b.len(), "paired values");
    let n = a.len();
    if n < 2 {
        return None;
    }
    let (ra, rb) = (ranks(a), ranks(b));
    let mean = (n as f64 + 1.0) / 2.0;
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in ra.iter().zip(&rb) {
        sab += (x - mean) * (y - mean);
        saa += (x - mean).powi(2);
        sbb += (y - mean).powi(2);
    }
    if saa == 0.0 || sbb == 0.0 {
        return None;
    }
    let rho = (sab / (saa * sbb).sqrt()).clamp(-1.0, 1.0);
    let interval = (n >= 4).then(|| {
        let z = rho.clamp(-0.999_999, 0.999_999).atanh();
        let half = 1.959_964 * 1.03 / ((n - 3) as f64).sqrt();
        [(z - half).tanh(), (z + half).tanh()]
    });
    Some(RankCorrelation { rho, interval, n })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The textbook formula 1 − 6 Σd² / (n (n² − 1)), valid without ties.
    fn spearman_slow(a: &[f64], b: &[f64]) -> f64 {
        let rank = |v: &[f64], i: usize| 1.0 + v.iter().filter(|&&x| x < v[i]).count() as f64;
        let n = a.len() as f64;
        let d2: f64 = (0..a.len()).map(|i| (rank(a, i) - rank(b, i)).powi(2)).sum();
        1.0 - 6.0 * d2 / (n * (n * n - 1.0))
    }

    #[test]
    fn spearman_matches_the_textbook_formula_without_ties_and_shares_ranks_on_ties() {
        let mut state = 12345u64;
        let mut next = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        for n in [4usize, 9, 25] {
            let a: Vec<f64> = (0..n).map(|_| next()).collect();
            let b: Vec<f64> = (0..n).map(|_| next()).collect();
            let r = spearman(&a, &b).unwrap();
            assert!((r.rho - spearman_slow(&a, &b)).abs() < 1e-12, "{n}: {r:?}");
            let [lo, hi] = r.interval.unwrap();
            assert!(lo <= r.rho && r.rho <= hi && lo >= -1.0 && hi <= 1.0);
        }
        assert_eq!(ranks(&[0.5, 0.9, 0.5, 0.1]), vec![2.5, 4.0, 2.5, 1.0]);
        let same = spearman(&[0.1, 0.2, 0.3, 0.4, 0.5], &[1.0, 2.0, 3.0, 4.0, 5.0]).unwrap();
        assert_eq!(same.rho, 1.0);
        let reversed = spearman(&[0.1, 0.2, 0.3, 0.4, 0.5], &[5.0, 4.0, 3.0, 2.0, 1.0]).unwrap();
        assert_eq!(reversed.rho, -1.0);
        assert!(spearman(&[0.5, 0.5, 0.5], &[1.0, 2.0, 3.0]).is_none(), "one value: undefined");
    }
}
