//! Surface normals by PCA: the direction of least spread of each point's neighbourhood
//! within a radius, turned towards the viewpoint (the sensor). A point whose normal cannot
//! be fitted (too few neighbours, or neighbours along a line) gets the zero vector.

use nalgebra::{Matrix3, Point3, Vector3};
use rayon::prelude::*;

use crate::Neighbours;
use crate::{Error, ErrorKind, Result};

/// Fewest neighbours (the point included) a normal is fitted to by default.
pub const MIN_NORMAL_NEIGHBOURS: usize = 6;

/// A neighbourhood is a line, not a surface, when its middle spread is below this share of
/// its largest.
const LINE_RATIO: f64 = 1e-3;

/// Fits normals over a fixed radius.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NormalEstimator {
    radius: f32,
    min_neighbours: usize,
}

/// Whether a normal from [`NormalEstimator::compute`] was fitted (invalid ones are zero).
#[inline]
pub fn is_valid_normal(normal: &Vector3<f32>) -> bool {
    normal.x != 0.0 || normal.y != 0.0 || normal.z != 0.0
}

impl NormalEstimator {
    /// Fits over `radius` mm (about 2.5 x SRes) and needs `min_neighbours` points.
    pub fn new(radius: f32, min_neighbours: usize) -> Result<Self> {
        if !(radius.is_finite() && radius > 0.0) {
            return Err(Error::new(
                ErrorKind::Input,
                format!("normals: expected a positive radius in mm, got {radius}"),
            ));
        }
        Ok(NormalEstimator { radius, min_neighbours: min_neighbours.max(3) })
    }

    /// Radius of the fitted neighbourhood, mm.
    pub fn radius(&self) -> f32 {
        self.radius
    }

    /// Replaces `normals` with one unit normal per point of `cloud` facing `viewpoint`, or
    /// zero where none can be fitted; returns how many were fitted. `neighbours` must have
    /// been built on `cloud` (cells of twice `radius` are fastest: a query reads 8 of them).
    pub fn compute(
        &self,
        cloud: &[Point3<f32>],
        neighbours: &Neighbours,
        viewpoint: &Point3<f32>,
        normals: &mut Vec<Vector3<f32>>,
    ) -> usize {
        normals.clear();
        normals.resize(cloud.len(), Vector3::zeros());
        normals
            .par_iter_mut()
            .zip(cloud.par_iter())
            .with_min_len(256)
            .map(|(n, p)| {
                *n = self.fit(p, neighbours, viewpoint).unwrap_or_else(Vector3::zeros);
                usize::from(is_valid_normal(n))
            })
            .sum()
    }

    fn fit(&self, p: &Point3<f32>, neighbours: &Neighbours, viewpoint: &Point3<f32>) -> Option<Vector3<f32>> {
        if !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()) {
            return None;
        }
        // Moments about p itself, so f32 sums stay small whatever the cloud's offset.
        let mut count = 0usize;
        let mut s = [0.0f32; 3];
        let mut ss = [0.0f32; 6];
        neighbours.for_each_within(p, self.radius, |_, q, _| {
            let d = q - p;
            count += 1;
            s[0] += d.x;
            s[1] += d.y;
            s[2] += d.z;
            ss[0] += d.x * d.x;
            ss[1] += d.x * d.y;
            ss[2] += d.x * d.z;
            ss[3] += d.y * d.y;
            ss[4] += d.y * d.z;
            ss[5] += d.z * d.z;
        });
        if count < self.min_neighbours {
            return None;
        }
        let c = count as f64;
        let m = [s[0] as f64 / c, s[1] as f64 / c, s[2] as f64 / c];
        let cov = Matrix3::new(
            ss[0] as f64 / c - m[0] * m[0],
            ss[1] as f64 / c - m[0] * m[1],
            ss[2] as f64 / c - m[0] * m[2],
            ss[1] as f64 / c - m[1] * m[0],
            ss[3] as f64 / c - m[1] * m[1],
            ss[4] as f64 / c - m[1] * m[2],
            ss[2] as f64 / c - m[2] * m[0],
            ss[4] as f64 / c - m[2] * m[1],
            ss[5] as f64 / c - m[2] * m[2],
        );
        let n = least_spread(&cov)?;
        let n = Vector3::new(n.x as f32, n.y as f32, n.z as f32);
        Some(if n.dot(&(viewpoint - p)) < 0.0 { -n } else { n })
    }
}

/// Unit eigenvector of the smallest eigenvalue of a symmetric 3x3 matrix: eigenvalues in
/// closed form (the trigonometric solution of the characteristic cubic), the eigenvector
/// as the longest cross product of two rows of A - lambda I. `None` when the two largest
/// eigenvalues do not span a surface (a line or a single point).
fn least_spread(a: &Matrix3<f64>) -> Option<Vector3<f64>> {
    let q = a.trace() / 3.0;
    let p1 = a[(0, 1)].powi(2) + a[(0, 2)].powi(2) + a[(1, 2)].powi(2);
    let p2 = (a[(0, 0)] - q).powi(2) + (a[(1, 1)] - q).powi(2) + (a[(2, 2)] - q).powi(2) + 2.0 * p1;
    let p = (p2 / 6.0).sqrt();
    if p.is_nan() || p <= 1e-12 * q.abs().max(1e-30) {
        // All three spreads equal: a blob or a single point, no surface direction.
        return None;
    }
    let b = (a - Matrix3::from_diagonal_element(q)) / p;
    let r = (b.determinant() / 2.0).clamp(-1.0, 1.0);
    let phi = r.acos() / 3.0;
    let largest = q + 2.0 * p * phi.cos();
    let smallest = q + 2.0 * p * (phi + 2.0 * std::f64::consts::FRAC_PI_3).cos();
    let middle = 3.0 * q - largest - smallest;
    if middle.is_nan() || middle - smallest <= LINE_RATIO * largest {
        return None;
    }
    let m = a - Matrix3::from_diagonal_element(smallest);
    let (r0, r1, r2) = (m.row(0).transpose(), m.row(1).transpose(), m.row(2).transpose());
    let candidates = [r0.cross(&r1), r0.cross(&r2), r1.cross(&r2)];
    let best = candidates.iter().max_by(|x, y| x.norm_squared().total_cmp(&y.norm_squared()))?;
    let norm = best.norm();
    (norm > 0.0 && norm.is_finite()).then(|| best / norm)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Rotation3, SymmetricEigen, Unit};
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn closed_form_eigenvector_matches_a_general_solver() {
        let mut rng = ChaCha8Rng::seed_from_u64(21);
        for _ in 0..2000 {
            // Flattened random blobs: the shape a surface neighbourhood has.
            let scale =
                Vector3::new(rng.random_range(1.0..5.0), rng.random_range(1.0..5.0), rng.random_range(0.01..0.5));
            let axis = Unit::new_normalize(Vector3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            ));
            let rot = Rotation3::from_axis_angle(&axis, rng.random_range(0.0..6.0));
            let cov = rot.matrix() * Matrix3::from_diagonal(&scale.component_mul(&scale)) * rot.matrix().transpose();
            let got = least_spread(&cov).unwrap();
            let eig = SymmetricEigen::new(cov);
            let i = eig.eigenvalues.imin();
            let want = eig.eigenvectors.column(i);
            assert!(got.dot(&want).abs() > 1.0 - 1e-9, "{got} vs {want}");
        }
        assert!(least_spread(&Matrix3::identity()).is_none());
        assert!(least_spread(&Matrix3::from_diagonal(&Vector3::new(4.0, 0.0, 0.0))).is_none());
    }

    #[test]
    fn sphere_normals_point_out_to_the_viewer_and_sparse_points_are_invalid() {
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let radius = 40.0f32;
        let centre = Point3::new(10.0, -20.0, 0.0);
        // The upper cap of a sphere, seen from above.
        let mut cloud: Vec<Point3<f32>> = (0..20000)
            .filter_map(|_| {
                let v =
                    Vector3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(0.3..1.0));
                (v.norm() <= 1.0).then(|| centre + v.normalize() * radius)
            })
            .collect();
        let lonely = cloud.len();
        cloud.push(Point3::new(500.0, 500.0, 500.0));
        let mut grid = Neighbours::new();
        grid.build(&cloud, 4.0).unwrap();
        let est = NormalEstimator::new(4.0, MIN_NORMAL_NEIGHBOURS).unwrap();
        let mut normals = Vec::new();
        let viewpoint = Point3::new(0.0, 0.0, 600.0);
        let fitted = est.compute(&cloud, &grid, &viewpoint, &mut normals);
        assert_eq!(normals.len(), cloud.len());
        assert!(!is_valid_normal(&normals[lonely]));
        assert!(fitted >= lonely * 99 / 100, "{fitted} of {lonely}");
        for (p, n) in cloud.iter().zip(&normals).take(lonely).filter(|(_, n)| is_valid_normal(n)) {
            let truth = (p - centre).normalize();
            assert!(n.dot(&truth) > 0.995, "{n} vs {truth} at {p}");
            assert!((n.norm() - 1.0).abs() < 1e-5);
        }
    }
}
