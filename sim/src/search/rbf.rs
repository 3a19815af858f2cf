//! The cubic radial-basis-function surrogate with a linear polynomial tail: fitting it to
//! scattered values (interpolating or smoothed) and evaluating it and its gradient.
//! It knows nothing of boxes, scaling or where to sample next.

use nalgebra::{DMatrix, DVector};

use crate::{Error, Result};

/// A fitted surrogate s(x) = Σ w_i ‖x − c_i‖³ + a₀ + aᵀx over centres c_i.
#[derive(Debug, Clone)]
pub struct Surrogate {
    dim: usize,
    /// Centres, `dim` numbers each, one after the other.
    centres: Vec<f64>,
    weights: Vec<f64>,
    /// a₀ then a (the linear tail).
    tail: Vec<f64>,
}

impl Surrogate {
    /// Fits the surrogate to `values` at `points` (`dim` numbers per point).
    ///
    /// `smoothing` (λ ≥ 0) is added to the diagonal of the kernel block: 0 interpolates,
    /// larger values trade fidelity at the data for a smoother surface, which is what a
    /// noisy objective wants. A nearly singular system (points almost on top of each
    /// other) is retried with a growing λ before giving up.
    pub fn fit(points: &[f64], dim: usize, values: &[f64], smoothing: f64) -> Result<Surrogate> {
        let n = values.len();
        if dim == 0 || points.len() != n * dim {
            return Err(Error::Other(format!(
                "surrogate: {} coordinates for {n} points in {dim} dimensions",
                points.len()
            )));
        }
        if n < dim + 1 {
            return Err(Error::Other(format!("surrogate: {n} points cannot fix a linear tail in {dim} dimensions")));
        }
        if values.iter().any(|v| !v.is_finite()) || !smoothing.is_finite() || smoothing < 0.0 {
            return Err(Error::Other("surrogate: values and smoothing must be finite".into()));
        }
        let m = n + dim + 1;
        let mut base = DMatrix::<f64>::zeros(m, m);
        for i in 0..n {
            let ci = &points[i * dim..(i + 1) * dim];
            for j in 0..i {
                let r = distance(ci, &points[j * dim..(j + 1) * dim]);
                let phi = r * r * r;
                base[(i, j)] = phi;
                base[(j, i)] = phi;
            }
            base[(i, n)] = 1.0;
            base[(n, i)] = 1.0;
            for k in 0..dim {
                base[(i, n + 1 + k)] = ci[k];
                base[(n + 1 + k, i)] = ci[k];
            }
        }
        let mut rhs = DVector::<f64>::zeros(m);
        rhs.rows_mut(0, n).copy_from_slice(values);
        let value_scale = values.iter().fold(0.0f64, |a, v| a.max(v.abs())).max(1e-300);

        // The guard: each retry adds a ridge ten times larger, starting far below anything
        // that would visibly smooth an interpolant.
        let mut lambda = smoothing;
        for attempt in 0..8 {
            let mut a = base.clone();
            for i in 0..n {
                a[(i, i)] += lambda;
            }
            if let Some(inverse) = a.clone().lu().try_inverse() {
                let sol = &inverse * &rhs;
                let residual = (&a * &sol - &rhs).amax();
                if sol.iter().all(|v| v.is_finite()) && residual <= 1e-6 * value_scale {
                    return Ok(Surrogate {
                        dim,
                        centres: points.to_vec(),
                        weights: sol.rows(0, n).iter().copied().collect(),
                        tail: sol.rows(n, dim + 1).iter().copied().collect(),
                    });
                }
            }
            lambda = if attempt == 0 { smoothing.max(1e-12) * 10.0 } else { lambda * 10.0 };
        }
        Err(Error::Other(
            "surrogate: the interpolation system is singular (points coincide or lie on a \
             hyperplane)"
                .into(),
        ))
    }

    /// s(x).
    pub fn value(&self, x: &[f64]) -> f64 {
        let d = self.dim;
        let mut s = self.tail[0] + self.tail[1..].iter().zip(x).map(|(a, v)| a * v).sum::<f64>();
        for (c, w) in self.centres.chunks_exact(d).zip(&self.weights) {
            let r = distance(x, c);
            s += w * r * r * r;
        }
        s
    }

    /// s(x), with ∇s(x) written into `grad`.
    pub fn value_and_gradient(&self, x: &[f64], grad: &mut [f64]) -> f64 {
        let d = self.dim;
        let mut s = self.tail[0];
        for k in 0..d {
            s += self.tail[1 + k] * x[k];
            grad[k] = self.tail[1 + k];
        }
        for (c, w) in self.centres.chunks_exact(d).zip(&self.weights) {
            let r = distance(x, c);
            s += w * r * r * r;
            // d(r³)/dx = 3 r (x − c), smooth even at r = 0.
            let f = 3.0 * w * r;
            for k in 0..d {
                grad[k] += f * (x[k] - c[k]);
            }
        }
        s
    }
}

/// Euclidean distance.
pub(crate) fn distance(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum::<f64>().sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn random_points(rng: &mut ChaCha8Rng, n: usize, d: usize) -> Vec<f64> {
        (0..n * d).map(|_| rng.random::<f64>()).collect()
    }

    #[test]
    fn interpolates_data_and_reproduces_linear_functions() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for d in 1..=5 {
            let n = 3 * (d + 1);
            let pts = random_points(&mut rng, n, d);
            let f = |x: &[f64]| x.iter().enumerate().map(|(k, v)| (k as f64 + 1.0) * v).sum::<f64>() - 0.5;
            let vals: Vec<f64> = pts.chunks(d).map(f).collect();
            let s = Surrogate::fit(&pts, d, &vals, 0.0).unwrap();
            for (p, v) in pts.chunks(d).zip(&vals) {
                assert!((s.value(p) - v).abs() < 1e-8);
            }
            // A linear function lies in the tail's span, so the kernel part must vanish
            // and the surrogate be exact everywhere.
            let q = random_points(&mut rng, d, 1);
            assert!((s.value(&q) - f(&q)).abs() < 1e-8, "d = {d}");
        }
    }

    #[test]
    fn gradient_matches_finite_differences() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let d = 3;
        let pts = random_points(&mut rng, 12, d);
        let vals: Vec<f64> = (0..12).map(|_| rng.random::<f64>()).collect();
        let s = Surrogate::fit(&pts, d, &vals, 0.0).unwrap();
        let mut g = vec![0.0; d];
        for _ in 0..20 {
            let x = random_points(&mut rng, 1, d);
            let v = s.value_and_gradient(&x, &mut g);
            assert!((v - s.value(&x)).abs() < 1e-12);
            for k in 0..d {
                let h = 1e-6;
                let (mut xp, mut xm) = (x.clone(), x.clone());
                xp[k] += h;
                xm[k] -= h;
                let fd = (s.value(&xp) - s.value(&xm)) / (2.0 * h);
                assert!((fd - g[k]).abs() < 1e-5 * (1.0 + g[k].abs()), "{fd} vs {}", g[k]);
            }
        }
    }

    #[test]
    fn smoothing_pulls_noisy_data_towards_the_trend() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let d = 2;
        let n = 60;
        let pts = random_points(&mut rng, n, d);
        let truth = |x: &[f64]| (x[0] - 0.3).powi(2) + (x[1] - 0.6).powi(2);
        let vals: Vec<f64> = pts.chunks(d).map(|x| truth(x) + 0.05 * (rng.random::<f64>() - 0.5)).collect();
        let rough = Surrogate::fit(&pts, d, &vals, 0.0).unwrap();
        let smooth = Surrogate::fit(&pts, d, &vals, 0.05).unwrap();
        let err = |s: &Surrogate| {
            let mut e = 0.0;
            for i in 0..=20 {
                for j in 0..=20 {
                    let x = [i as f64 / 20.0, j as f64 / 20.0];
                    e += (s.value(&x) - truth(&x)).powi(2);
                }
            }
            e
        };
        assert!(err(&smooth) < err(&rough), "{} vs {}", err(&smooth), err(&rough));
    }

    #[test]
    fn coincident_points_are_refused_or_survived_without_panic() {
        let pts = [0.1, 0.2, 0.1, 0.2, 0.5, 0.9, 0.8, 0.1, 0.4, 0.4];
        let vals = [1.0, 2.0, 0.5, 0.3, 0.7];
        // Two equal centres with different values cannot be interpolated; the guard adds a
        // ridge so the fit averages them instead.
        let s = Surrogate::fit(&pts, 2, &vals, 0.0).unwrap();
        assert!(s.value(&[0.1, 0.2]).is_finite());
        assert!(Surrogate::fit(&pts[..4], 2, &vals[..2], 0.0).is_err());
    }
}
