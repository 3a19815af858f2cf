//! Builds the tray model the estimator loads, after the paper §3: the tray alone, turned
//! about z in `model_viewpoints` steps (12 by default: 30° apart), each turn captured full and then with the items closest to the
//! sensor removed until empty — in the cell's `model_fill_states` steps, evenly apart, where
//! the paper takes one item at a time — every capture rendered and reconstructed by the very sensor
//! and estimator stages of the placement. Each capture's key points and descriptors are
//! the estimator's own (same spacing, radius and relief filter); a viewpoint's fill states
//! then share the features they agree on. The model carries the tray's slots and the item's
//! footprint profile, so the deployed estimator can judge them. The file format is the
//! estimator's.

use camplace_config::{Cell, Placement};
use camplace_estimator::features::MIN_NORMAL_NEIGHBOURS;
use camplace_estimator::{
    depth::Method, depth::Reconstruction, depth::Reconstructor, depth::Rectification, features::Descriptor,
    features::Downsampler, features::FeatureExtractor, features::NormalEstimator, geometry::Neighbours,
    pose::ModelOrigin, pose::ModelView, EstimatorConfig, Model,
};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use rayon::prelude::*;

use crate::render::{Frame, Simulator};
use crate::scene::tray::slot_layout;
use crate::scene::SceneSpec;
use crate::seeds::noise_key;
use crate::workers::each_index;
use crate::{Error, Result};

/// Margin around the tray and its items kept in a capture, mm (the sensor's depth noise and
/// a voxel's reach).
const CROP_MARGIN_MM: f32 = 4.0;

/// Noise keys of model captures sit far from a study's scenario indices.
const MODEL_NOISE_OFFSET: u64 = 1 << 40;

/// What [`build_model`] records a model was built from.
pub fn model_origin(cell: &Cell, placement: &Placement, method: Method, seed: u64) -> Result<ModelOrigin> {
    let hashes = cell.hashes()?;
    Ok(ModelOrigin {
        cell_hash: hashes.cell,
        tray: cell.tray_name(),
        tray_hash: hashes.tray,
        method: method.to_string(),
        seed,
        placement: placement.to_string(),
    })
}

/// One capture's contribution: its features and its down-sampled cloud, tray frame.
struct Capture {
    points: Vec<Point3<f32>>,
    normals: Vec<Vector3<f32>>,
    descriptors: Vec<Descriptor>,
    cloud: Vec<Point3<f32>>,
}

/// The tray model of `cell`'s tray seen by the sensor at `placement` with `method`; `seed`
/// draws the one-shot pattern and the camera noise.
pub fn build_model(cell: &Cell, placement: &Placement, method: Method, seed: u64) -> Result<Model> {
    let origin = model_origin(cell, placement, method, seed)?;
    let probe = Simulator::new(cell, placement, seed)?;
    let slots = probe.objects().tray.slots.len();
    let rectification = Rectification::new(probe.rig(), &cell.work_volume)?;
    let sensor_world = rectification.camera.t_world_rectified.translation.vector;
    let sensor_world = Point3::from(sensor_world);
    let light = &cell.lighting;
    let mid = |[lo, hi]: [f64; 2]| 0.5 * (lo + hi);
    // A plain, even light: the model should hold the tray's shape, not one scene's shadows.
    let base = SceneSpec {
        t_world_tray: Isometry3::identity(),
        filled: Vec::new(),
        table: false,
        tray: true,
        ambient: mid(light.ambient),
        lamp_strength: mid(light.lamp_strength),
        lamp_position: Point3::new(0.0, 0.0, light.lamp_distance),
        occluder: None,
    };
    // Turns of the tray about z, 360° / viewpoints apart.
    let viewpoints = cell.estimator.model_viewpoints as usize;
    let poses: Vec<Isometry3<f64>> = (0..viewpoints)
        .map(|v| {
            let yaw = (v as f64 * 360.0 / viewpoints as f64).to_radians();
            Isometry3::from_parts(Translation3::identity(), UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw))
        })
        .collect();
    // Per viewpoint, the slots in the order their items are taken out: closest to the sensor first.
    let removal: Vec<Vec<usize>> = poses
        .iter()
        .map(|pose| {
            let mut order: Vec<(usize, f64)> = (0..slots)
                .filter_map(|n| probe.objects().tray.slot_pose(n).map(|s| (n, s)))
                .map(|(n, s)| (n, ((pose * s).translation.vector - sensor_world.coords).norm()))
                .collect();
            order.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
            order.into_iter().map(|(n, _)| n).collect()
        })
        .collect();
    let params = &cell.estimator;
    let removed = fill_states(slots, params.model_fill_states as usize);
    let states = removed.len();
    // Without a table the stereo matcher may still fill the empty background with surfaces
    // interpolated across gaps; only what lies on the tray and its items belongs to the model.
    let (lo, hi) = tray_bounds(probe.objects(), slots, CROP_MARGIN_MM);
    // One worker per thread, each with its own sensor, reconstructor and feature buffers
    // (built once, not per capture), taking captures in turn.
    let setup = || -> Result<_> {
        let sim = probe.clone();
        let rec = Reconstructor::new(&EstimatorConfig::from(cell), probe.rig(), method)?;
        let features = FeatureExtractor::new(params, 1 << 16)?;
        Ok((sim, rec, features, Frame::default(), Reconstruction::default()))
    };
    let captures = each_index(viewpoints * states, setup, |(sim, rec, features, frame, reconstruction), index| {
        let (v, state) = (index / states, index % states);
        let mut filled: Vec<usize> = removal[v][removed[state]..].to_vec();
        filled.sort_unstable();
        let scene = SceneSpec { t_world_tray: poses[v], filled, ..base.clone() };
        sim.render(&scene, method, noise_key(seed, MODEL_NOISE_OFFSET + index as u64, false), frame);
        rec.process(&frame.shots.left, &frame.shots.right, reconstruction)?;
        let to_tray = poses[v].inverse().cast::<f32>();
        let raw: Vec<Point3<f32>> = reconstruction
            .cloud
            .points
            .iter()
            .map(|p| to_tray * p)
            .filter(|q| (0..3).all(|a| q[a] >= lo[a] && q[a] <= hi[a]))
            .collect();
        let eye = (poses[v].inverse() * sensor_world).cast::<f32>();
        describe(features, &raw, &eye)
    })?;

    // Footprint cells of two voxels hold a few scene points each wherever the slot is seen.
    let slot_cell_mm = 2.0 * params.surface_resolution;
    let mut model = Model {
        surface_resolution: params.surface_resolution as f32,
        symmetries_deg: cell.tray.symmetries.iter().map(|&s| s as f32).collect(),
        origin: Some(origin),
        slots: slot_layout(&probe.objects().tray, &probe.objects().item, slot_cell_mm),
        ..Model::default()
    };
    for v in 0..viewpoints {
        merge_fill_states(&captures[v * states..(v + 1) * states], params.surface_resolution as f32, &mut model);
    }
    let sres = params.surface_resolution as f32;
    let normal_estimator = NormalEstimator::new(params.normal_radius as f32, MIN_NORMAL_NEIGHBOURS)?;
    model.views = poses
        .par_iter()
        .enumerate()
        .map(|(v, pose)| -> Result<ModelView> {
            let merged: Vec<Point3<f32>> =
                captures[v * states..(v + 1) * states].iter().flat_map(|c| c.cloud.iter().copied()).collect();
            let mut points = Vec::new();
            Downsampler::new().downsample(&merged, sres, &mut points)?;
            let eye = (pose.inverse() * sensor_world).cast::<f32>();
            let mut grid = Neighbours::new();
            grid.build(&points, 2.0 * params.normal_radius as f32)?;
            let mut normals = Vec::new();
            normal_estimator.compute(&points, &grid, &eye, &mut normals);
            // ICP planes need a normal: points where none could be fitted are left out.
            let (points, normals): (Vec<_>, Vec<_>) = points
                .into_iter()
                .zip(normals)
                .filter(|(_, n)| camplace_estimator::features::is_valid_normal(n))
                .unzip();
            Ok(ModelView { view_direction: eye.coords.normalize(), points, normals })
        })
        .collect::<Result<_>>()?;
    // Too few points of a viewpoint: the tray is barely in view from this placement.
    model.validate().map_err(|e| Error::TrayNotSeen(format!("model: {e}")))?;
    if model.views.iter().any(|v| v.points.len() < 3) {
        return Err(Error::TrayNotSeen(
            "model: a viewpoint saw fewer than 3 points of the tray at this placement (is the tray in view?)"
                .to_string(),
        ));
    }
    if model.feature_points.is_empty() {
        return Err(Error::TrayNotSeen(
            "model: the sensor saw no tray features at this placement (is the tray in view?)".to_string(),
        ));
    }
    // The model as its file holds it (points and normals rounded to the file's steps), so a
    // model used as built and one read back from a file or a study's cache give the same
    // poses.
    Ok(Model::from_bytes(&model.to_bytes())?)
}

/// How many items each of `wanted` fill states of a tray with `slots` slots has taken out:
/// 0 (full) to `slots` (empty), evenly apart and rounded, ascending. With `wanted` above
/// `slots + 1` every state is taken; with 1, the full tray alone.
fn fill_states(slots: usize, wanted: usize) -> Vec<usize> {
    let n = wanted.clamp(1, slots + 1);
    if n == 1 {
        return vec![0];
    }
    // Steps of slots / (n - 1) >= 1 apart round to distinct counts.
    (0..n).map(|k| (k * slots + (n - 1) / 2) / (n - 1)).collect()
}

/// Bounding box, tray frame, of the tray with every slot filled, grown by `margin` mm.
fn tray_bounds(objects: &crate::scene::Objects, slots: usize, margin: f32) -> (Point3<f32>, Point3<f32>) {
    let spec = SceneSpec {
        t_world_tray: Isometry3::identity(),
        filled: (0..slots).collect(),
        table: false,
        tray: true,
        ambient: 0.0,
        lamp_strength: 0.0,
        lamp_position: Point3::origin(),
        occluder: None,
    };
    let mut triangles = Vec::new();
    objects.triangles(&spec, &mut triangles);
    let mut lo = Point3::from(Vector3::repeat(f32::INFINITY));
    let mut hi = Point3::from(Vector3::repeat(f32::NEG_INFINITY));
    for v in triangles.iter().flat_map(|t| t.vertices) {
        let v = v.cast::<f32>();
        lo = lo.inf(&v);
        hi = hi.sup(&v);
    }
    (lo - Vector3::repeat(margin), hi + Vector3::repeat(margin))
}

/// Down-samples one tray-frame capture and describes its key points, as the estimator
/// describes a scene.
fn describe(features: &mut FeatureExtractor, raw: &[Point3<f32>], eye: &Point3<f32>) -> Result<Capture> {
    features.extract(raw, eye)?;
    let normals = features.normals();
    Ok(Capture {
        points: features.keypoint_points().to_vec(),
        normals: features.keypoints().iter().map(|&i| normals[i as usize]).collect(),
        descriptors: features.descriptors().to_vec(),
        cloud: features.cloud().to_vec(),
    })
}

/// Descriptors of one place closer than this (L2, rad) count as the same for matching.
/// Two fill states' descriptors of one place lie a median 1.4 rad apart (stereo noise
/// moves bins' centroids); 1.0 merges about a fifth of the model's features without
/// losing correct matches (measured at the optimum: 65 k to 53 k features, success
/// unchanged), where merging every same-place pair (25 k) loses a third of them.
const SAME_DESCRIPTOR_RAD: f32 = 1.0;

/// Appends the features of one viewpoint's fill states to `model`, leaving out each feature
/// that an earlier state already holds: within `radius` mm in the tray frame and with a
/// descriptor within [`SAME_DESCRIPTOR_RAD`]. Most of the tray looks the same whatever the
/// filling; only the surroundings of the items change, and only there do states add
/// features. Fewer near-duplicates make matching faster and leave room among the k nearest
/// neighbours for other candidate places.
fn merge_fill_states(captures: &[Capture], radius: f32, model: &mut Model) {
    let inv = 1.0 / radius;
    let cell = |p: &Point3<f32>| [p.x, p.y, p.z].map(|c| (c * inv).floor() as i32);
    let mut grid: std::collections::HashMap<[i32; 3], Vec<usize>> = std::collections::HashMap::new();
    let limit2 = SAME_DESCRIPTOR_RAD * SAME_DESCRIPTOR_RAD;
    for c in captures {
        for ((p, n), d) in c.points.iter().zip(&c.normals).zip(&c.descriptors) {
            let at = cell(p);
            let mut best = f32::INFINITY;
            for dz in -1..=1 {
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        let Some(list) = grid.get(&[at[0] + dx, at[1] + dy, at[2] + dz]) else { continue };
                        for &i in list {
                            if (model.feature_points[i] - p).norm_squared() <= radius * radius {
                                let d2: f32 = model.descriptors[i].iter().zip(d).map(|(a, b)| (a - b) * (a - b)).sum();
                                best = best.min(d2);
                            }
                        }
                    }
                }
            }
            if best <= limit2 {
                continue;
            }
            grid.entry(at).or_default().push(model.feature_points.len());
            model.feature_points.push(*p);
            model.feature_normals.push(*n);
            model.descriptors.push(*d);
        }
    }
}

/// Every ICP point of the model, tray frame (what `model.ply` shows).
pub fn model_points(model: &Model) -> Vec<[f32; 3]> {
    model.views.iter().flat_map(|v| v.points.iter().map(|p| [p.x, p.y, p.z])).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fill_states_run_from_full_to_empty_evenly_apart() {
        assert_eq!(fill_states(8, 3), vec![0, 4, 8]);
        assert_eq!(fill_states(8, 5), vec![0, 2, 4, 6, 8]);
        assert_eq!(fill_states(8, 2), vec![0, 8]);
        assert_eq!(fill_states(4, 3), vec![0, 2, 4]);
        assert_eq!(fill_states(7, 3), vec![0, 4, 7]);
        assert_eq!(fill_states(8, 1), vec![0]);
        assert_eq!(fill_states(0, 3), vec![0]);
        // More states than the tray has: every one, as the paper builds it.
        assert_eq!(fill_states(4, 1000), vec![0, 1, 2, 3, 4]);
        for slots in 0..40 {
            for wanted in 1..45 {
                let s = fill_states(slots, wanted);
                assert_eq!(s.len(), wanted.min(slots + 1), "{slots} slots, {wanted} wanted");
                assert_eq!((s[0], *s.last().unwrap()), (0, if s.len() > 1 { slots } else { 0 }));
                assert!(s.windows(2).all(|w| w[0] < w[1]), "{slots} slots, {wanted} wanted: {s:?}");
            }
        }
    }
}
