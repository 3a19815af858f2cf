//! Rigid fit of point pairs (Kabsch with an SVD, reflection-safe): the pose that maps source
//! points onto target points in the least-squares sense. RANSAC fits its 3-point samples and
//! its consensus sets with it; nothing here allocates.

use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};

/// Running sums of point pairs, enough to fit the rigid pose without storing the pairs.
///
/// Sums are kept in f64 about the first source and target point (or about given origins,
/// see [`RigidFit::about`]), so coordinates of a few hundred mm do not lose the sub-mm
/// structure to cancellation.
#[derive(Debug, Clone, Copy, Default)]
pub struct RigidFit {
    count: u32,
    /// Whether the origins were given rather than taken from the first pair.
    anchored: bool,
    source_origin: Vector3<f64>,
    target_origin: Vector3<f64>,
    source_sum: Vector3<f64>,
    target_sum: Vector3<f64>,
    /// Sum of source · targetᵀ about the origins.
    cross: Matrix3<f64>,
}

impl RigidFit {
    /// An empty fit.
    pub fn new() -> Self {
        Self::default()
    }

    /// An empty fit whose sums are kept about the given points (near the pairs to come), so
    /// that fits of parts of one set of pairs can be merged.
    pub fn about(source_origin: &Point3<f32>, target_origin: &Point3<f32>) -> Self {
        RigidFit {
            anchored: true,
            source_origin: source_origin.coords.cast::<f64>(),
            target_origin: target_origin.coords.cast::<f64>(),
            ..Self::default()
        }
    }

    /// Pairs added so far.
    pub fn pairs(&self) -> u32 {
        self.count
    }

    /// Adds the pairs of `other`, which was made [`RigidFit::about`] the same origins.
    pub fn merge(&mut self, other: &RigidFit) {
        assert!(
            self.anchored
                && other.anchored
                && self.source_origin == other.source_origin
                && self.target_origin == other.target_origin,
            "rigid fits merge only when made about the same origins"
        );
        self.count += other.count;
        self.source_sum += other.source_sum;
        self.target_sum += other.target_sum;
        self.cross += other.cross;
    }

    /// Adds one pair: `source` should land on `target`.
    pub fn add(&mut self, source: &Point3<f32>, target: &Point3<f32>) {
        let s64 = source.coords.cast::<f64>();
        let t64 = target.coords.cast::<f64>();
        if self.count == 0 && !self.anchored {
            self.source_origin = s64;
            self.target_origin = t64;
        }
        let s = s64 - self.source_origin;
        let t = t64 - self.target_origin;
        self.count += 1;
        self.source_sum += s;
        self.target_sum += t;
        self.cross += s * t.transpose();
    }

    /// The pose `T_target_source` minimising the squared distances, or `None` with fewer than
    /// 3 pairs or when the source points are (nearly) collinear, so the rotation about their
    /// line is not determined.
    pub fn solve(&self) -> Option<Isometry3<f64>> {
        if self.count < 3 {
            return None;
        }
        let n = self.count as f64;
        let source_mean = self.source_sum / n;
        let target_mean = self.target_sum / n;
        let h = self.cross - n * source_mean * target_mean.transpose();
        if !h.iter().all(|v| v.is_finite()) {
            return None;
        }
        let svd = h.try_svd_unordered(true, true, 1e-12, 100)?;
        let (u, v_t) = (svd.u?, svd.v_t?);
        let sv = svd.singular_values;
        let (mut smallest, mut largest) = (0, 0);
        for i in 1..3 {
            if sv[i] < sv[smallest] {
                smallest = i;
            }
            if sv[i] > sv[largest] {
                largest = i;
            }
        }
        let middle = 3 - smallest - largest;
        // The rotation is unique while two singular values are clearly non-zero.
        if largest == smallest || sv[middle] <= 1e-9 * sv[largest] || sv[largest] <= 0.0 {
            return None;
        }
        let v = v_t.transpose();
        let mut flip = Matrix3::identity();
        // A reflection fits mirrored data better than any rotation; flipping the axis of the
        // smallest singular value gives the best proper rotation instead.
        if (v * u.transpose()).determinant() < 0.0 {
            flip[(smallest, smallest)] = -1.0;
        }
        let r = v * flip * u.transpose();
        let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r));
        let source_centroid = self.source_origin + source_mean;
        let target_centroid = self.target_origin + target_mean;
        let t = target_centroid - rotation * source_centroid;
        Some(Isometry3::from_parts(Translation3::from(t), rotation))
    }
}

/// Fits `T_target_source` to paired points (`target[i] ≈ T · source[i]`); `None` when the
/// slices differ in length, hold fewer than 3 pairs or the source points are collinear.
#[cfg(test)]
pub fn fit_rigid(source: &[Point3<f32>], target: &[Point3<f32>]) -> Option<Isometry3<f64>> {
    if source.len() != target.len() {
        return None;
    }
    let mut fit = RigidFit::new();
    for (s, t) in source.iter().zip(target) {
        fit.add(s, t);
    }
    fit.solve()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn random_pose(rng: &mut ChaCha8Rng) -> Isometry3<f64> {
        let axis = Vector3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
        let angle = rng.random_range(-3.1..3.1);
        let t = Vector3::new(
            rng.random_range(-500.0..500.0),
            rng.random_range(-500.0..500.0),
            rng.random_range(0.0..900.0),
        );
        Isometry3::new(t, axis.normalize() * angle)
    }

    fn random_points(rng: &mut ChaCha8Rng, n: usize) -> Vec<Point3<f32>> {
        (0..n)
            .map(|_| {
                Point3::new(
                    rng.random_range(-150.0..150.0),
                    rng.random_range(-100.0..100.0),
                    rng.random_range(0.0..60.0),
                )
            })
            .collect()
    }

    fn pose_gap(a: &Isometry3<f64>, b: &Isometry3<f64>) -> (f64, f64) {
        let d = a.inverse() * b;
        (d.translation.vector.norm(), d.rotation.angle())
    }

    #[test]
    fn recovers_a_known_transform_from_three_and_many_pairs() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        for trial in 0..200 {
            let truth = random_pose(&mut rng);
            let n = if trial % 2 == 0 { 3 } else { 50 };
            let source = random_points(&mut rng, n);
            let target: Vec<Point3<f32>> = source.iter().map(|p| (truth * p.cast::<f64>()).cast::<f32>()).collect();
            let fit = fit_rigid(&source, &target).expect("non-degenerate points fit");
            let (dt, dr) = pose_gap(&fit, &truth);
            assert!(dt < 1e-3 && dr < 1e-5, "trial {trial}: {dt} mm, {dr} rad");
        }
    }

    #[test]
    fn noisy_pairs_fit_no_worse_than_the_truth() {
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let cost = |pose: &Isometry3<f64>, s: &[Point3<f32>], t: &[Point3<f32>]| -> f64 {
            s.iter().zip(t).map(|(a, b)| (pose * a.cast::<f64>() - b.cast::<f64>()).norm_squared()).sum()
        };
        for _ in 0..50 {
            let truth = random_pose(&mut rng);
            let source = random_points(&mut rng, 30);
            let target: Vec<Point3<f32>> = source
                .iter()
                .map(|p| {
                    let noise = Vector3::new(
                        rng.random_range(-1.0..1.0),
                        rng.random_range(-1.0..1.0),
                        rng.random_range(-1.0..1.0),
                    );
                    (truth * p.cast::<f64>() + noise).cast::<f32>()
                })
                .collect();
            let fit = fit_rigid(&source, &target).unwrap();
            assert!(cost(&fit, &source, &target) <= cost(&truth, &source, &target) + 1e-6);
            // Small perturbations of the optimum only raise the cost.
            for _ in 0..10 {
                let nudge = Isometry3::new(
                    Vector3::new(rng.random_range(-0.1..0.1), rng.random_range(-0.1..0.1), rng.random_range(-0.1..0.1)),
                    Vector3::new(
                        rng.random_range(-1e-3..1e-3),
                        rng.random_range(-1e-3..1e-3),
                        rng.random_range(-1e-3..1e-3),
                    ),
                );
                assert!(cost(&fit, &source, &target) <= cost(&(nudge * fit), &source, &target) + 1e-6);
            }
        }
    }

    #[test]
    fn mirrored_points_give_a_proper_rotation() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let source = random_points(&mut rng, 20);
        let target: Vec<Point3<f32>> = source.iter().map(|p| Point3::new(-p.x, p.y, p.z)).collect();
        let fit = fit_rigid(&source, &target).unwrap();
        let r = fit.rotation.to_rotation_matrix();
        assert!((r.matrix().determinant() - 1.0).abs() < 1e-9);
        assert!((r.matrix() * r.matrix().transpose() - Matrix3::identity()).norm() < 1e-9);
    }

    #[test]
    fn degenerate_input_is_refused() {
        let line: Vec<Point3<f32>> = (0..5).map(|i| Point3::new(i as f32 * 10.0, 2.0 * i as f32, 1.0)).collect();
        assert!(fit_rigid(&line, &line).is_none());
        let two = [Point3::new(0.0, 0.0, 0.0), Point3::new(1.0, 0.0, 0.0)];
        assert!(fit_rigid(&two, &two).is_none());
        assert!(fit_rigid(&line[..3], &line[..4]).is_none());
    }

    #[test]
    fn fits_of_parts_merged_equal_the_fit_of_the_whole() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let truth = random_pose(&mut rng);
        let source = random_points(&mut rng, 300);
        let target: Vec<Point3<f32>> = source.iter().map(|p| truth.cast::<f32>() * p).collect();
        let whole = fit_rigid(&source, &target).unwrap();
        let (so, to) = (Point3::new(20.0, -10.0, 5.0), truth.cast::<f32>() * Point3::new(20.0, -10.0, 5.0));
        let mut merged = RigidFit::about(&so, &to);
        for (s, t) in source.chunks(37).zip(target.chunks(37)) {
            let mut part = RigidFit::about(&so, &to);
            for (a, b) in s.iter().zip(t) {
                part.add(a, b);
            }
            merged.merge(&part);
        }
        assert_eq!(merged.pairs(), 300);
        let merged = merged.solve().unwrap();
        let (dt, dr) = pose_gap(&merged, &whole);
        assert!(dt < 1e-6 && dr < 1e-6, "merged fit off by {dt} mm, {dr} rad");
        let (dt, dr) = pose_gap(&merged, &truth);
        assert!(dt < 1e-3 && dr < 1e-5, "merged fit off the truth by {dt} mm, {dr} rad");
    }
}
