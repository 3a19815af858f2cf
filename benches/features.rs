//! Benches of the cloud and feature stages (down-sampling, normals, key points + ECSAD,
//! matching) on a synthetic tray cloud as the sensor sees it from about 600 mm.

use std::hint::black_box;
use std::num::NonZero;

use camplace_estimator::{
    features::quantise, features::Descriptor, features::Downsampler, features::Ecsad, features::FeatureMatcher,
    features::KeypointSelector, features::NormalEstimator, features::ECSAD_DIM, features::QUANTISATION_STEPS,
    geometry::Neighbours,
};
use criterion::Criterion;
use kiddo::immutable::float::kdtree::ImmutableKdTree;
use kiddo::SquaredEuclidean;
use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

const SURFACE_RESOLUTION: f32 = 2.0;
const NORMAL_RADIUS: f32 = 5.0;
const KEYPOINT_SPACING: f32 = 4.0;
const FEATURE_RADIUS: f32 = 20.0;
const K: usize = 25;
const HEIGHT_BAND: f32 = 20.0;

/// Deterministic scatter in [0, 1)^2 (the R2 low-discrepancy sequence) and noise from a hash
/// of the index, so the cloud is the same on every run without a random generator.
fn r2(i: usize) -> (f32, f32) {
    let a = (i as f64 * 0.754_877_666_246_692_8).fract();
    let b = (i as f64 * 0.569_840_290_998_053_2).fract();
    (a as f32, b as f32)
}

fn noise(i: usize) -> f32 {
    let h = (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 40;
    (h as f32 / (1u64 << 24) as f32 - 0.5) * 0.6
}

/// Samples the parallelogram `origin + a u + b v` at one point per `spacing`^2 mm^2.
fn patch(cloud: &mut Vec<Point3<f32>>, origin: Point3<f32>, u: Vector3<f32>, v: Vector3<f32>, spacing: f32) {
    let n = (u.cross(&v).norm() / (spacing * spacing)) as usize;
    let normal = u.cross(&v).normalize();
    let start = cloud.len();
    for i in 0..n {
        let (a, b) = r2(i + start);
        cloud.push(origin + u * a + v * b + normal * noise(i + start));
    }
}

/// The faces of an axis-aligned box from `lo` to `hi` a sensor above and in front (-y)
/// sees: the top, the -y side, and the -x or +x side facing the tray's centre line.
fn visible_box(cloud: &mut Vec<Point3<f32>>, lo: Point3<f32>, hi: Point3<f32>, spacing: f32) {
    let (dx, dy, dz) = (hi.x - lo.x, hi.y - lo.y, hi.z - lo.z);
    patch(cloud, Point3::new(lo.x, lo.y, hi.z), Vector3::x() * dx, Vector3::y() * dy, spacing);
    patch(cloud, Point3::new(lo.x, lo.y, lo.z), Vector3::x() * dx, Vector3::z() * dz, spacing);
    let x = if lo.x + hi.x > 0.0 { lo.x } else { hi.x };
    patch(cloud, Point3::new(x, lo.y, lo.z), Vector3::y() * dy, Vector3::z() * dz, spacing);
}

/// A 200 x 140 mm tray with 15 mm walls and a chamfered corner, holding `items` boxes,
/// sampled about 0.9 mm apart as a sensor at some 600 mm sees it (about 60k points full).
fn tray_cloud(items: usize) -> Vec<Point3<f32>> {
    let mut cloud = Vec::new();
    let s = 0.9;
    // Floor at z = 3, inside the walls.
    patch(&mut cloud, Point3::new(-96.0, -66.0, 3.0), Vector3::x() * 192.0, Vector3::y() * 132.0, s);
    // Walls (4 mm thick): rim and the faces turned to the sensor.
    for (lo, hi) in [
        ([-100.0, -70.0], [100.0, -66.0]),
        ([-100.0, 66.0], [100.0, 70.0]),
        ([-100.0, -66.0], [-96.0, 66.0]),
        ([96.0, -66.0], [100.0, 66.0]),
    ] {
        visible_box(&mut cloud, Point3::new(lo[0], lo[1], 0.0), Point3::new(hi[0], hi[1], 15.0), s);
    }
    // The chamfer breaking the tray's symmetry.
    patch(&mut cloud, Point3::new(80.0, 70.0, 0.0), Vector3::new(20.0, -20.0, 0.0), Vector3::z() * 15.0, s);
    for slot in 0..items {
        let (x, y) = (-60.0 + 40.0 * (slot % 4) as f32, if slot < 4 { -30.0 } else { 30.0 });
        visible_box(&mut cloud, Point3::new(x - 15.0, y - 22.0, 3.0), Point3::new(x + 15.0, y + 22.0, 23.0), s);
    }
    cloud
}

/// Everything a frame carries from the down-sampled cloud to its descriptors.
struct Frame {
    cloud: Vec<Point3<f32>>,
    normals: Vec<Vector3<f32>>,
    keypoints: Vec<u32>,
    descriptors: Vec<Descriptor>,
    heights: Vec<f32>,
}

fn describe(raw: &[Point3<f32>], all_points: bool) -> Frame {
    let viewpoint = Point3::new(0.0, -250.0, 550.0);
    let mut cloud = Vec::new();
    Downsampler::new().downsample(raw, SURFACE_RESOLUTION, &mut cloud).unwrap();
    let mut grid = Neighbours::new();
    grid.build(&cloud, 2.0 * NORMAL_RADIUS).unwrap();
    let mut normals = Vec::new();
    NormalEstimator::new(NORMAL_RADIUS, 6).unwrap().compute(&cloud, &grid, &viewpoint, &mut normals);
    let mut keypoints = Vec::new();
    let spacing = if all_points { SURFACE_RESOLUTION * 0.999 } else { KEYPOINT_SPACING };
    KeypointSelector::new().select(&cloud, &normals, spacing, &mut keypoints).unwrap();
    grid.build(&cloud, FEATURE_RADIUS / 2.0).unwrap();
    let mut descriptors = Vec::new();
    Ecsad::new(FEATURE_RADIUS).unwrap().compute(&cloud, &normals, &grid, &keypoints, &mut descriptors).unwrap();
    let heights = keypoints.iter().map(|&i| cloud[i as usize].z).collect();
    Frame { cloud, normals, keypoints, descriptors, heights }
}

/// Registers the feature benches.
pub fn benches(c: &mut Criterion) {
    let raw = tray_cloud(4);
    let scene = describe(&raw, false);
    // A model the size the paper's would have: every SRes point of a full and an empty tray.
    let full = describe(&raw, true);
    let empty = describe(&tray_cloud(0), true);
    let model: Vec<Descriptor> = full.descriptors.iter().chain(&empty.descriptors).copied().collect();
    let model_heights: Vec<f32> = full.heights.iter().chain(&empty.heights).copied().collect();
    eprintln!(
        "features: {} raw points, {} at SRes, {} key points, {} model features",
        raw.len(),
        scene.cloud.len(),
        scene.keypoints.len(),
        model.len()
    );

    let mut group = c.benchmark_group("features");
    let viewpoint = Point3::new(0.0, -250.0, 550.0);

    let mut downsampler = Downsampler::with_capacity(raw.len());
    let mut cloud = Vec::with_capacity(raw.len());
    group.bench_function("downsample", |b| {
        b.iter(|| downsampler.downsample(black_box(&raw), SURFACE_RESOLUTION, &mut cloud).unwrap())
    });

    let mut grid = Neighbours::with_capacity(scene.cloud.len());
    let mut normals = Vec::with_capacity(scene.cloud.len());
    let estimator = NormalEstimator::new(NORMAL_RADIUS, 6).unwrap();
    group.bench_function("normals", |b| {
        b.iter(|| {
            grid.build(black_box(&scene.cloud), 2.0 * NORMAL_RADIUS).unwrap();
            estimator.compute(&scene.cloud, &grid, &viewpoint, &mut normals)
        })
    });

    let mut selector = KeypointSelector::new();
    let mut keypoints = Vec::new();
    let mut ecsad = Ecsad::new(FEATURE_RADIUS).unwrap();
    let mut descriptors = Vec::new();
    group.bench_function("ecsad", |b| {
        b.iter(|| {
            selector.select(black_box(&scene.cloud), &scene.normals, KEYPOINT_SPACING, &mut keypoints).unwrap();
            grid.build(&scene.cloud, FEATURE_RADIUS / 2.0).unwrap();
            ecsad.compute(&scene.cloud, &scene.normals, &grid, &keypoints, &mut descriptors).unwrap();
        })
    });

    let mut matcher = FeatureMatcher::new(&model, &model_heights).unwrap();
    let mut matches = Vec::new();
    group.bench_function("match", |b| {
        b.iter(|| {
            matcher.match_into(black_box(&scene.descriptors), &scene.heights, K, HEIGHT_BAND, &mut matches).unwrap()
        })
    });

    // The same exact search with kiddo's k-d tree over the same quantised descriptors (the
    // matcher compares whole quantisation steps), each query in parallel, then the same
    // height check: the alternative the matcher's blocked brute force was measured against.
    let tree: ImmutableKdTree<f32, u32, ECSAD_DIM, 32> =
        ImmutableKdTree::new_from_slice(&model.iter().map(quantise).collect::<Vec<_>>());
    let queries: Vec<[f32; ECSAD_DIM]> = scene.descriptors.iter().map(quantise).collect();
    let k = NonZero::new(K).expect("K is positive");
    let kiddo_matches = |band: f32| -> Vec<Vec<f32>> {
        queries
            .par_iter()
            .zip(&scene.heights)
            .map(|(q, &h)| {
                let near = tree.nearest_n::<SquaredEuclidean>(q, k);
                near.iter().filter(|n| (h - model_heights[n.item as usize]).abs() <= band).map(|n| n.distance).collect()
            })
            .collect()
    };
    // Both find the same neighbours: the same distances (ties may pick other features at an
    // equal distance, so the check runs before the height filter).
    matcher.match_into(&scene.descriptors, &scene.heights, K, f32::INFINITY, &mut matches).unwrap();
    let step2 = (std::f32::consts::PI / QUANTISATION_STEPS).powi(2);
    for (i, found) in kiddo_matches(f32::INFINITY).iter().enumerate() {
        let ours: Vec<f32> =
            matches.iter().filter(|m| m.scene as usize == i).map(|m| (m.distance2 / step2).round()).collect();
        assert_eq!(&ours, found, "key point {i}: the matcher and kiddo disagree");
    }
    group.bench_function("match_kiddo", |b| b.iter(|| black_box(kiddo_matches(HEIGHT_BAND))));
    group.finish();
}
