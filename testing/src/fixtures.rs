//! The fixtures (see the crate's root). Compiled in two crates, this one and the
//! estimator's unit tests: the estimator's types are named through `super`, the root of
//! either.

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::{Correspondence, Model, ModelView, ECSAD_DIM};

/// Spacing of surface samples, mm (the paper's surface resolution).
pub const SPACING: f32 = 2.0;
/// Spacing of feature key points, mm.
pub const KEYPOINT_SPACING: f32 = 4.0;
/// Polar angle of the sensor that built the model's views, deg.
const VIEW_POLAR_DEG: f32 = 30.0;
/// Distance of the sensor from the tray origin, mm.
pub const SENSOR_DISTANCE: f32 = 800.0;

/// An axis-aligned cuboid `[min, max]` of the tray, tray frame.
type Cuboid = ([f32; 3], [f32; 3]);

/// The tray's solid parts: a 200 × 130 × 30 mm box with 4 mm walls and floor, a low
/// divider, and (unless `symmetric`) a tab on the +x wall that breaks the 180° symmetry.
pub fn tray_cuboids(symmetric: bool) -> Vec<Cuboid> {
    let mut c = vec![
        ([-100.0, -65.0, 0.0], [100.0, 65.0, 4.0]),
        ([96.0, -65.0, 4.0], [100.0, 65.0, 30.0]),
        ([-100.0, -65.0, 4.0], [-96.0, 65.0, 30.0]),
        ([-96.0, 61.0, 4.0], [96.0, 65.0, 30.0]),
        ([-96.0, -65.0, 4.0], [96.0, -61.0, 30.0]),
        ([-2.0, -61.0, 4.0], [2.0, 61.0, 18.0]),
    ];
    if !symmetric {
        c.push(([100.0, 15.0, 0.0], [116.0, 45.0, 15.0]));
    }
    c
}

/// Surface samples of the cuboids' union at `spacing`, with outward normals, tray frame.
pub fn surface(cuboids: &[Cuboid], spacing: f32) -> (Vec<Point3<f32>>, Vec<Vector3<f32>>) {
    let mut points = Vec::new();
    let mut normals = Vec::new();
    for (ci, (lo, hi)) in cuboids.iter().enumerate() {
        for axis in 0..3 {
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            let nu = ((hi[u] - lo[u]) / spacing).round().max(1.0) as usize;
            let nv = ((hi[v] - lo[v]) / spacing).round().max(1.0) as usize;
            for (side, plane) in [(-1.0f32, lo[axis]), (1.0, hi[axis])] {
                for i in 0..nu {
                    for j in 0..nv {
                        let mut p = [0.0; 3];
                        p[axis] = plane;
                        p[u] = lo[u] + (i as f32 + 0.5) * (hi[u] - lo[u]) / nu as f32;
                        p[v] = lo[v] + (j as f32 + 0.5) * (hi[v] - lo[v]) / nv as f32;
                        // A face shared with another part is inside the solid, not on its surface.
                        let buried = cuboids
                            .iter()
                            .enumerate()
                            .any(|(k, (a, b))| k != ci && (0..3).all(|d| p[d] >= a[d] - 1e-3 && p[d] <= b[d] + 1e-3));
                        if buried || (axis == 2 && side < 0.0 && plane <= 0.0) {
                            continue;
                        }
                        let mut n = Vector3::zeros();
                        n[axis] = side;
                        points.push(Point3::from(p));
                        normals.push(n);
                    }
                }
            }
        }
    }
    (points, normals)
}

/// Whether the segment from `p` to `eye` passes through no cuboid.
fn unoccluded(cuboids: &[Cuboid], p: &Point3<f32>, n: &Vector3<f32>, eye: &Point3<f32>) -> bool {
    let start = p + n * 0.05;
    let d = eye - start;
    cuboids.iter().all(|(lo, hi)| {
        let (mut t0, mut t1) = (0.0f32, 1.0f32);
        for a in 0..3 {
            if d[a].abs() < 1e-9 {
                if start[a] < lo[a] || start[a] > hi[a] {
                    return true;
                }
            } else {
                let (mut ta, mut tb) = ((lo[a] - start[a]) / d[a], (hi[a] - start[a]) / d[a]);
                if ta > tb {
                    std::mem::swap(&mut ta, &mut tb);
                }
                t0 = t0.max(ta);
                t1 = t1.min(tb);
                if t0 > t1 {
                    return true;
                }
            }
        }
        false
    })
}

/// Indices of the surface samples an eye at `eye` (tray frame) sees.
pub fn visible(cuboids: &[Cuboid], points: &[Point3<f32>], normals: &[Vector3<f32>], eye: &Point3<f32>) -> Vec<usize> {
    (0..points.len())
        .filter(|&i| normals[i].dot(&(eye - points[i])) > 0.0 && unoccluded(cuboids, &points[i], &normals[i], eye))
        .collect()
}

/// One point per occupied voxel of size `spacing` (the first one met), as indices.
fn voxel_subsample(points: &[Point3<f32>], spacing: f32) -> Vec<usize> {
    let mut seen = std::collections::HashSet::new();
    (0..points.len())
        .filter(|&i| {
            let p = points[i];
            let key = ((p.x / spacing).floor() as i32, (p.y / spacing).floor() as i32, (p.z / spacing).floor() as i32);
            seen.insert(key)
        })
        .collect()
}

/// The synthetic tray model: 6 viewpoints (the tray turned about z in 60° steps under a
/// sensor at 30° from vertical), each an ICP cloud at [`SPACING`]; feature key points at
/// [`KEYPOINT_SPACING`] from every view, with seeded random descriptors.
pub fn tray(symmetric: bool, seed: u64) -> Model {
    let cuboids = tray_cuboids(symmetric);
    let (points, normals) = surface(&cuboids, SPACING);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut model = Model {
        surface_resolution: SPACING,
        symmetries_deg: if symmetric { vec![180.0] } else { Vec::new() },
        ..Model::default()
    };
    let polar = VIEW_POLAR_DEG.to_radians();
    for k in 0..6 {
        let turn = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), -(k as f32 * 60.0).to_radians());
        let view_direction = turn * Vector3::new(0.0, -polar.sin(), polar.cos());
        let eye = Point3::from(view_direction * SENSOR_DISTANCE);
        let seen = visible(&cuboids, &points, &normals, &eye);
        let view = ModelView {
            view_direction,
            points: seen.iter().map(|&i| points[i]).collect(),
            normals: seen.iter().map(|&i| normals[i]).collect(),
        };
        for i in voxel_subsample(&view.points, KEYPOINT_SPACING) {
            model.feature_points.push(view.points[i]);
            model.feature_normals.push(view.normals[i]);
            let mut d = [0.0; ECSAD_DIM];
            d.iter_mut().for_each(|v| *v = rng.random_range(0.0..1.0));
            model.descriptors.push(d);
        }
        model.views.push(view);
    }
    model
}

/// How a synthetic scene is drawn.
#[derive(Debug, Clone)]
pub struct SceneSpec {
    pub seed: u64,
    /// Uniform noise on each coordinate, ± mm.
    pub noise_mm: f32,
    /// Share of the visible tray cut away by a random vertical plane (0 .. 1).
    pub cut_share: f32,
    /// Matches listed per scene key point.
    pub matches_per_keypoint: usize,
    /// Share of key points on the tray whose matches include the right model feature.
    pub correct_share: f32,
    /// Points of a clutter box beside the tray.
    pub clutter_points: usize,
    /// Whether the tray is in the scene at all.
    pub with_tray: bool,
    /// Tilt of the tray about its x axis, deg (0: resting on the table).
    pub tilt_deg: f32,
    /// Spacing of the scene's key points, mm.
    pub keypoint_spacing_mm: f32,
}

impl Default for SceneSpec {
    fn default() -> Self {
        SceneSpec {
            seed: 1,
            noise_mm: 0.3,
            cut_share: 0.2,
            matches_per_keypoint: 5,
            correct_share: 0.5,
            clutter_points: 1000,
            with_tray: true,
            tilt_deg: 0.0,
            keypoint_spacing_mm: KEYPOINT_SPACING,
        }
    }
}

/// A scene of the synthetic tray with its ground truth.
#[derive(Debug, Clone)]
pub struct Scene {
    /// The true pose of the tray.
    pub t_world_tray: Isometry3<f64>,
    /// Where the sensor is, world frame.
    pub sensor_position: Point3<f32>,
    /// The scene cloud, world frame.
    pub points: Vec<Point3<f32>>,
    /// Feature key points, world frame.
    pub keypoints: Vec<Point3<f32>>,
    /// Their unit normals, world frame: the surface's, turned by up to about 2°.
    pub keypoint_normals: Vec<Vector3<f32>>,
    /// Matches of key points to model features, most of them wrong.
    pub correspondences: Vec<Correspondence>,
    /// Correspondences that are right under the true pose.
    pub correct: usize,
}

impl Scene {
    /// Draws a scene of `model`'s tray (built by [`tray`] with the same symmetry) resting
    /// on the table at a random x, y and yaw, seen from above at 30° from vertical.
    pub fn generate(model: &Model, symmetric: bool, spec: &SceneSpec) -> Scene {
        let mut rng = ChaCha8Rng::seed_from_u64(spec.seed);
        let yaw = rng.random_range(-std::f32::consts::PI..std::f32::consts::PI);
        let (x, y) = (rng.random_range(-100.0..100.0), rng.random_range(-100.0..100.0));
        let tilt = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), spec.tilt_deg.to_radians());
        let rotation = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw) * tilt;
        let lift = if spec.tilt_deg != 0.0 { 40.0 } else { 0.0 };
        let t_world_tray = Isometry3::from_parts(Translation3::new(x, y, lift), rotation).cast::<f64>();
        let polar = VIEW_POLAR_DEG.to_radians();
        let sensor_position = Point3::new(0.0, -polar.sin(), polar.cos()) * SENSOR_DISTANCE;
        let pose = t_world_tray.cast::<f32>();

        let mut points = Vec::new();
        let mut normals = Vec::new();
        if spec.with_tray {
            let cuboids = tray_cuboids(symmetric);
            let (surface_points, surface_normals) = surface(&cuboids, SPACING);
            let eye = pose.inverse_transform_point(&sensor_position);
            let seen = visible(&cuboids, &surface_points, &surface_normals, &eye);
            let cut_dir = {
                let a = rng.random_range(0.0..std::f32::consts::TAU);
                Vector3::new(a.cos(), a.sin(), 0.0)
            };
            let mut order: Vec<(f32, usize)> =
                seen.iter().map(|&i| (surface_points[i].coords.dot(&cut_dir), i)).collect();
            order.sort_by(|a, b| a.0.total_cmp(&b.0));
            let keep = ((1.0 - spec.cut_share.clamp(0.0, 1.0)) * order.len() as f32) as usize;
            for &(_, i) in &order[..keep] {
                points.push(pose * surface_points[i]);
                normals.push(pose.rotation * surface_normals[i]);
            }
        }
        // A box-shaped item lying on the table beside the tray.
        let centre = Vector3::new(x + 190.0 * (yaw + 1.0).cos(), y + 190.0 * (yaw + 1.0).sin(), 0.0);
        for _ in 0..spec.clutter_points {
            let mut p: Vector3<f32> = Vector3::new(rng.random_range(-25.0..25.0), rng.random_range(-25.0..25.0), 35.0);
            let normal = match rng.random_range(0..3) {
                0 => Vector3::z(),
                1 => {
                    p.x = if p.x > 0.0 { 25.0 } else { -25.0 };
                    Vector3::x() * p.x.signum()
                }
                _ => {
                    p.y = if p.y > 0.0 { 25.0 } else { -25.0 };
                    Vector3::y() * p.y.signum()
                }
            };
            normals.push(normal);
            if p.z != 35.0 || rng.random_range(0..2) == 0 {
                p.z = rng.random_range(0.0..35.0);
            }
            points.push(Point3::from(centre + p));
        }
        for p in &mut points {
            for a in 0..3 {
                p[a] += rng.random_range(-1.0..=1.0) * spec.noise_mm;
            }
        }

        let keys = voxel_subsample(&points, spec.keypoint_spacing_mm);
        let keypoints: Vec<Point3<f32>> = keys.iter().map(|&i| points[i]).collect();
        // The normals' noise has a stream of its own, so the scene's other draws do not move.
        let mut normal_rng = ChaCha8Rng::seed_from_u64(spec.seed ^ 0x6e6f_726d);
        let keypoint_normals = keys
            .iter()
            .map(|&i| {
                let n = normals[i] + Vector3::from_fn(|_, _| normal_rng.random_range(-0.02..=0.02));
                n.normalize()
            })
            .collect();
        let mut correspondences = Vec::new();
        let mut correct = 0;
        let n_model = model.feature_points.len() as u32;
        for (si, kp) in keypoints.iter().enumerate() {
            let local = pose.inverse_transform_point(kp);
            let nearest = model
                .feature_points
                .iter()
                .enumerate()
                .map(|(i, f)| (i, (f - local).norm_squared()))
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .filter(|&(_, d2)| spec.with_tray && d2 < 3.0 * 3.0);
            let right = nearest.filter(|_| rng.random_range(0.0..1.0) < spec.correct_share).map(|(i, _)| i as u32);
            let slot = rng.random_range(0..spec.matches_per_keypoint.max(1));
            for m in 0..spec.matches_per_keypoint {
                let model_index = match right {
                    Some(i) if m == slot => {
                        correct += 1;
                        i
                    }
                    _ => rng.random_range(0..n_model),
                };
                let distance2 = rng.random_range(0.0..1.0);
                correspondences.push(Correspondence { scene: si as u32, model: model_index, distance2 });
            }
        }
        Scene { t_world_tray, sensor_position, points, keypoints, keypoint_normals, correspondences, correct }
    }
}

/// A `tolerance.json` as a study writes it around `placement`, with `(parameter, minus,
/// plus)` measured for each listed parameter (each side ended by a drop, walked to 30 at
/// most) and every point at 90 % success on 44 scenes.
pub fn tolerance_report(
    placement: &str,
    axes: &[(camplace_config::PlacementParam, f64, f64)],
) -> camplace_config::ToleranceReport {
    use camplace_config::{AxisTolerance, TolerancePoint, ToleranceReport, WalkEnd};
    let point = TolerancePoint {
        offset: 0.0,
        success_rate: 0.9,
        success_interval: [0.8, 0.95],
        scenes: 44,
        lost: 0,
        gained: 0,
        p_lower: 1.0,
    };
    let axis = |&(param, minus, plus): &(camplace_config::PlacementParam, f64, f64)| AxisTolerance {
        parameter: param.name().to_string(),
        unit: param.unit().to_string(),
        resolution: 1.0,
        limit: 30.0,
        minus,
        minus_end: WalkEnd::Drop,
        minus_inside: point.clone(),
        minus_outside: None,
        minus_range: -30.0,
        plus,
        plus_end: WalkEnd::Drop,
        plus_inside: point.clone(),
        plus_outside: None,
        plus_range: 30.0,
        points: Vec::new(),
    };
    ToleranceReport {
        placement: placement.to_string(),
        method: "one-shot".into(),
        seed: 0,
        scenarios: 44,
        margin: 0.15,
        level: 0.05,
        power: 0.8,
        nominal: point.clone(),
        axes: axes.iter().map(axis).collect(),
        corner_fraction: 1.0,
        corners: Vec::new(),
        corner_screen: 0,
    }
}
