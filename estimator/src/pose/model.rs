//! The tray model the estimator loads: features with tray-frame positions for matching, and
//! one ICP cloud per viewpoint for scoring and refinement, with the origin and the
//! verification threshold it carries. Its binary file is `model_file.rs`'s. Building a model
//! from rendered views is the simulator's job; the `testing` fixtures make a box tray and
//! scenes of it analytically, for tests and benches.
//!
//! Points are `f32` like every cloud; poses are `f64` like every calibrated transform.

use camplace_config::ContentHash;
use nalgebra::{Isometry3, Point3, Vector3};

use crate::error::{Error, ErrorKind, Result};
use crate::features::Descriptor;
use crate::pose::SlotLayout;

/// The tray as the estimator knows it.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Model {
    /// Voxel size the model clouds were down-sampled to, mm.
    pub surface_resolution: f32,
    /// Feature key points, tray frame, mm.
    pub feature_points: Vec<Point3<f32>>,
    /// Unit surface normal at each feature key point, tray frame.
    pub feature_normals: Vec<Vector3<f32>>,
    /// ECSAD descriptor of each feature key point.
    pub descriptors: Vec<Descriptor>,
    /// One ICP cloud per viewpoint.
    pub views: Vec<ModelView>,
    /// Rotations about tray z (deg) that map the tray onto itself; the identity is implied.
    pub symmetries_deg: Vec<f32>,
    /// What the model was built from; `None` for a model of unknown origin (a version 1
    /// file, a test fixture).
    pub origin: Option<ModelOrigin>,
    /// The verification threshold measured in simulation for this model; `None` when it was
    /// not measured (a file older than version 4, a test fixture).
    pub verification: Option<ModelVerification>,
    /// The tray's slots and the item they hold, so a frame's slots can be judged; `None`
    /// for a model without them (a file older than version 5, a test fixture).
    pub slots: Option<SlotLayout>,
}

/// The verification threshold a model carries and what it was measured on, so that the
/// deployed estimator applies exactly what simulation measured.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ModelVerification {
    /// Scores at or above this are accepted, in [0, 1].
    pub threshold: f32,
    /// The largest share of wrong poses among the accepted ones it was chosen for.
    pub max_wrong: f32,
    /// Scenes simulated.
    pub scenes: u32,
    /// Of them, poses accepted at the threshold.
    pub accepted: u32,
    /// Of those, wrong ones (outside the success limits).
    pub wrong_accepted: u32,
    /// One-sided 95 % upper bound (Clopper–Pearson) of the wrong share among accepted poses.
    pub wrong_upper: f32,
}

/// What a model was built from, so that a model of another tray or cell can be refused.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct ModelOrigin {
    /// The hash of the whole cell (every setting and its mesh files' bytes).
    pub cell_hash: ContentHash,
    /// The tray as the cell names it (`tray-8`, `tray-4`, `mesh NAME`).
    pub tray: String,
    /// The hash of the tray's and its items' geometry.
    pub tray_hash: ContentHash,
    /// The capture method (`one-shot`, `phase-12`).
    pub method: String,
    /// The seed of the pattern and the camera noise.
    pub seed: u64,
    /// The placement, as `r=..,alpha=..,baseline=..,vergence=..`.
    pub placement: String,
}

/// The tray seen from one viewpoint: its fill states merged and down-sampled.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ModelView {
    /// Unit direction from the tray towards the sensor, tray frame.
    pub view_direction: Vector3<f32>,
    /// Surface points, tray frame, mm.
    pub points: Vec<Point3<f32>>,
    /// Unit surface normal at each point, tray frame.
    pub normals: Vec<Vector3<f32>>,
}

impl Model {
    /// Checks that the parallel arrays agree and every number is usable.
    pub fn validate(&self) -> Result<()> {
        let bad = |msg: String| Err(Error::new(ErrorKind::Model, format!("model: {msg}")));
        if !(self.surface_resolution.is_finite() && self.surface_resolution > 0.0) {
            return bad(format!("expected a positive surface_resolution, found {}", self.surface_resolution));
        }
        let n = self.feature_points.len();
        if self.feature_normals.len() != n || self.descriptors.len() != n {
            return bad(format!(
                "expected as many feature normals and descriptors as feature points ({n}), found {} and {}",
                self.feature_normals.len(),
                self.descriptors.len()
            ));
        }
        if let Some(i) = self.feature_points.iter().position(|p| !finite3(&p.coords)) {
            return bad(format!("expected finite feature points, point {i} is not"));
        }
        if let Some(i) = self.feature_normals.iter().position(|v| !finite3(v)) {
            return bad(format!("expected finite feature normals, normal {i} is not"));
        }
        if let Some(i) = self.descriptors.iter().position(|d| !d.iter().all(|v| v.is_finite())) {
            return bad(format!("expected finite descriptors, descriptor {i} is not"));
        }
        for (k, view) in self.views.iter().enumerate() {
            let norm = view.view_direction.norm();
            if !(norm - 1.0).abs().lt(&1e-3) {
                return bad(format!("expected a unit view direction in view {k}, found length {norm}"));
            }
            if view.normals.len() != view.points.len() {
                return bad(format!(
                    "expected as many normals as points in view {k} ({}), found {}",
                    view.points.len(),
                    view.normals.len()
                ));
            }
            if view.points.iter().any(|p| !finite3(&p.coords)) || view.normals.iter().any(|v| !finite3(v)) {
                return bad(format!("expected finite points and normals in view {k}"));
            }
        }
        if let Some(s) = self.symmetries_deg.iter().find(|s| !s.is_finite()) {
            return bad(format!("expected finite symmetry angles, found {s}"));
        }
        if let Some(v) = &self.verification {
            let share = |x: f32| (0.0..=1.0).contains(&x);
            if !(share(v.threshold) && share(v.max_wrong) && share(v.wrong_upper)) {
                return bad(format!(
                    "expected the verification's threshold, max wrong and upper bound in [0, 1], found {}, {} and {}",
                    v.threshold, v.max_wrong, v.wrong_upper
                ));
            }
            if v.accepted > v.scenes || v.wrong_accepted > v.accepted {
                return bad(format!(
                    "expected wrong accepted <= accepted <= scenes in the verification, found {} <= {} <= {}",
                    v.wrong_accepted, v.accepted, v.scenes
                ));
            }
        }
        if let Some(slots) = &self.slots {
            slots.validate()?;
        }
        Ok(())
    }

    /// The viewpoint whose view direction is closest to the direction from the tray, posed at
    /// `t_world_tray`, towards the sensor.
    pub fn closest_view(&self, t_world_tray: &Isometry3<f64>, sensor_position_world: &Point3<f32>) -> usize {
        let towards_sensor = t_world_tray.inverse_transform_point(&sensor_position_world.cast::<f64>()).coords;
        let mut best = (0, f64::NEG_INFINITY);
        for (k, view) in self.views.iter().enumerate() {
            let score = view.view_direction.cast::<f64>().dot(&towards_sensor);
            if score > best.1 {
                best = (k, score);
            }
        }
        best.0
    }
}

/// Whether every coordinate of `v` is finite.
fn finite3(v: &Vector3<f32>) -> bool {
    v.iter().all(|x| x.is_finite())
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::features::ECSAD_DIM;
    use crate::testing;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A small valid model of seed `seed` (with a verification threshold for even seeds).
    pub(crate) fn small_model(seed: u64) -> Model {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut p =
            || Point3::new(rng.random_range(-9.0..9.0), rng.random_range(-9.0..9.0), rng.random_range(0.0..9.0));
        let feature_points: Vec<Point3<f32>> = (0..7).map(|_| p()).collect();
        let views = (0..3)
            .map(|k| ModelView {
                view_direction: Vector3::new(k as f32, 1.0, 2.0).normalize(),
                points: (0..5 + k).map(|_| p()).collect(),
                normals: (0..5 + k).map(|i| Vector3::new(0.0, i as f32, 1.0).normalize()).collect(),
            })
            .collect();
        Model {
            surface_resolution: 2.0,
            feature_normals: feature_points.iter().map(|q| q.coords.normalize()).collect(),
            descriptors: (0..7).map(|i| [i as f32 * 0.25; ECSAD_DIM]).collect(),
            feature_points,
            views,
            symmetries_deg: vec![90.0, 180.0, 270.0],
            origin: Some(ModelOrigin {
                cell_hash: ContentHash::of(&seed.to_le_bytes()),
                tray: "tray-8".to_string(),
                tray_hash: ContentHash::of(b"tray"),
                method: "one-shot".to_string(),
                seed,
                placement: "r=605,alpha=32,baseline=81,vergence=3.5".to_string(),
            }),
            verification: seed.is_multiple_of(2).then_some(ModelVerification {
                threshold: 0.625,
                max_wrong: 0.005,
                scenes: 300,
                accepted: 280,
                wrong_accepted: 1,
                wrong_upper: 0.0166,
            }),
            slots: seed.is_multiple_of(3).then(|| SlotLayout {
                slots: vec![[-25.0, 0.0, 5.0, 0.0], [25.0, 0.0, 5.0, 90.0 + seed as f64]],
                footprint_min_mm: [-15.0, -14.0],
                cell_mm: [3.75, 3.5],
                cols: 8,
                rows: 8,
                top_mm: (0..64).map(|i| if i % 8 == 0 { crate::pose::EDGE_CELL } else { 30.0 }).collect(),
            }),
        }
    }

    /// A threshold out of [0, 1], or counts that contradict each other, are refused.
    #[test]
    fn a_verification_out_of_range_is_refused() {
        let good = small_model(2);
        assert!(good.validate().is_ok() && good.verification.is_some());
        let v = good.verification.unwrap();
        for bad in [
            ModelVerification { threshold: 1.5, ..v },
            ModelVerification { wrong_upper: f32::NAN, ..v },
            ModelVerification { accepted: v.scenes + 1, ..v },
            ModelVerification { wrong_accepted: v.accepted + 1, ..v },
        ] {
            let m = Model { verification: Some(bad), ..good.clone() };
            assert!(m.validate().unwrap_err().to_string().contains("verification"), "{bad:?}");
        }
    }

    #[test]
    fn inconsistent_models_fail_validation() {
        // Each refused for what is wrong with it, named in the message.
        let refusal = |m: Model| m.validate().unwrap_err().to_string();
        assert!(small_model(5).validate().is_ok());
        let mut m = small_model(5);
        m.descriptors.pop();
        assert!(refusal(m).contains("as many feature normals and descriptors as feature points"));
        let mut m = small_model(5);
        m.views[1].normals.pop();
        assert!(refusal(m).contains("as many normals as points in view 1"));
        let mut m = small_model(5);
        m.views[0].points[2].x = f32::NAN;
        let r = refusal(m);
        assert!(r.contains("finite points and normals in view 0"), "{r}");
        let mut m = small_model(5);
        m.views[0].view_direction *= 2.0;
        let r = refusal(m);
        assert!(r.contains("unit view direction in view 0, found length 1.99"), "{r}");
    }

    #[test]
    fn closest_view_matches_brute_force_angles() {
        let model = testing::tray(false, 1);
        let mut rng = ChaCha8Rng::seed_from_u64(6);
        for _ in 0..200 {
            let pose = Isometry3::new(
                nalgebra::Vector3::new(rng.random_range(-200.0..200.0), rng.random_range(-200.0..200.0), 0.0),
                nalgebra::Vector3::z() * rng.random_range(-3.2..3.2),
            );
            let sensor = Point3::new(
                rng.random_range(-500.0..500.0),
                rng.random_range(-500.0..500.0),
                rng.random_range(300.0..900.0),
            );
            let dir = sensor.cast::<f64>().coords - pose.translation.vector;
            let angle = |k: usize| (pose.rotation * model.views[k].view_direction.cast::<f64>()).angle(&dir);
            let k = model.closest_view(&pose, &sensor);
            assert!((0..6).all(|j| angle(k) <= angle(j) + 1e-9));
        }
    }

    #[test]
    fn synthetic_tray_is_seen_from_six_directions() {
        let m = testing::tray(false, 1);
        m.validate().unwrap();
        assert_eq!(m.views.len(), 6);
        for v in &m.views {
            assert!(v.points.len() > 5000, "{}", v.points.len());
            // Every kept sample faces the sensor that saw it.
            let eye = Point3::from(v.view_direction * 800.0);
            assert!(v.points.iter().zip(&v.normals).all(|(p, n)| n.dot(&(eye - p)) > 0.0));
        }
    }
}
