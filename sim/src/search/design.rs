//! The space-filling start of the search: the centre of the unit box plus a Latin
//! hypercube chosen by maximin distance over a few random tries.

use rand::{Rng, RngExt};

use super::rbf::distance;

/// `n` points in [0,1]^`dim` (the first is the centre), `dim` numbers per point.
///
/// The rest form a Latin hypercube: each axis cut into n − 1 equal strata, one point per
/// stratum, placed at random within it. Of `tries` hypercubes the one whose closest pair
/// (the centre included) lies farthest apart wins, so no two start points crowd together.
pub fn latin_hypercube_with_centre<R: Rng>(n: usize, dim: usize, tries: usize, rng: &mut R) -> Vec<Vec<f64>> {
    let centre = vec![0.5; dim];
    if n == 0 {
        return Vec::new();
    }
    let m = n - 1;
    let mut best: Vec<Vec<f64>> = Vec::new();
    let mut best_gap = f64::NEG_INFINITY;
    let mut perm: Vec<usize> = (0..m).collect();
    for _ in 0..tries.max(1) {
        let mut pts = vec![vec![0.0; dim]; m];
        for k in 0..dim {
            for i in (1..m).rev() {
                let j = rng.random_range(0..=i);
                perm.swap(i, j);
            }
            for (p, &stratum) in pts.iter_mut().zip(&perm) {
                p[k] = (stratum as f64 + rng.random::<f64>()) / m as f64;
            }
        }
        pts.push(centre.clone());
        let gap = min_pairwise_distance(&pts);
        if gap > best_gap {
            best_gap = gap;
            best = pts;
        }
    }
    best.pop();
    best.insert(0, centre);
    best
}

/// The smallest distance between any two of `pts` (infinite for fewer than two).
fn min_pairwise_distance(pts: &[Vec<f64>]) -> f64 {
    let mut gap = f64::INFINITY;
    for (i, a) in pts.iter().enumerate() {
        for b in &pts[..i] {
            gap = gap.min(distance(a, b));
        }
    }
    gap
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn one_point_per_stratum_on_every_axis() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        for (n, d) in [(6, 2), (8, 3), (14, 6), (2, 1)] {
            let pts = latin_hypercube_with_centre(n, d, 10, &mut rng);
            assert_eq!(pts.len(), n);
            assert!(pts[0].iter().all(|&v| v == 0.5));
            for k in 0..d {
                let mut seen = vec![false; n - 1];
                for p in &pts[1..] {
                    assert!((0.0..=1.0).contains(&p[k]));
                    let s = ((p[k] * (n - 1) as f64) as usize).min(n - 2);
                    assert!(!seen[s], "two points in stratum {s} of axis {k}");
                    seen[s] = true;
                }
            }
        }
    }

    #[test]
    fn more_tries_never_give_a_smaller_gap() {
        // The winner of many tries beats the average single try on the maximin criterion.
        let mut single = 0.0;
        for seed in 0..20 {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            single += min_pairwise_distance(&latin_hypercube_with_centre(8, 3, 1, &mut rng));
        }
        let mut many = 0.0;
        for seed in 0..20 {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            many += min_pairwise_distance(&latin_hypercube_with_centre(8, 3, 30, &mut rng));
        }
        assert!(many > single, "{many} vs {single}");
    }
}
