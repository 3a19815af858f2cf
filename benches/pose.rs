//! Benches of the pose stages (RANSAC and ICP) on a synthetic tray scene: about 10k scene
//! points and 2k key points with 25 matches each, nearly all wrong; and ICP's set-up, whose
//! nearest-point grids are built once per model (per placement in a study).

use camplace_config::Cell;
use camplace_estimator::{pose::Icp, pose::IcpResult, pose::Ransac, pose::RansacResult};
use camplace_testing::{self as testing, Scene, SceneSpec};
use criterion::{criterion_group, Criterion};
use std::sync::Arc;

fn pose(c: &mut Criterion) {
    let params = Cell::default().estimator;
    let model = Arc::new(testing::tray(false, 1));
    let spec = SceneSpec {
        seed: 21,
        matches_per_keypoint: 25,
        correct_share: 0.8,
        keypoint_spacing_mm: 5.0,
        ..SceneSpec::default()
    };
    let scene = Scene::generate(&model, false, &spec);
    eprintln!(
        "pose: {} scene points, {} key points, {} matches ({} right)",
        scene.points.len(),
        scene.keypoints.len(),
        scene.correspondences.len(),
        scene.correct
    );
    let estimate = |ransac: &mut Ransac| {
        ransac
            .estimate(
                &scene.points,
                &scene.keypoints,
                &scene.keypoint_normals,
                &scene.correspondences,
                &scene.sensor_position,
            )
            .expect("valid inputs")
    };
    let mut icp = Icp::new(&params, model.clone(), testing::SENSOR_DISTANCE).expect("the synthetic model is usable");
    // 2-match samples (the default), then 1-match samples (`ransac_sample = 1`), the turn
    // from the normals, on the same scene.
    let mut one_params = params.clone();
    one_params.ransac_sample = 1;
    let mut found = [RansacResult::default(); 2];
    for ((name, p), out) in
        [("pose/ransac", &params), ("pose/ransac_one_match", &one_params)].into_iter().zip(&mut found)
    {
        let mut ransac = Ransac::new(p, model.clone()).expect("the synthetic model is usable");
        *out = estimate(&mut ransac);
        assert!(out.found, "{name}: the bench scene must be solvable");
        c.bench_function(name, |b| b.iter(|| *out = estimate(&mut ransac)));
    }
    let [coarse, one_coarse] = found;
    c.bench_function("pose/icp_new", |b| {
        b.iter(|| {
            Icp::new(&params, std::hint::black_box(model.clone()), testing::SENSOR_DISTANCE)
                .expect("the synthetic model is usable")
        })
    });
    let mut fine = IcpResult::default();
    c.bench_function("pose/icp", |b| {
        b.iter(|| {
            fine = icp
                .refine(&scene.points, coarse.view, &scene.sensor_position, &coarse.t_world_tray)
                .expect("valid inputs")
        })
    });
    eprintln!(
        "pose: RANSAC {} inliers in {} iterations (1-match samples: {} in {}); ICP {} iterations",
        coarse.inliers, coarse.iterations, one_coarse.inliers, one_coarse.iterations, fine.iterations
    );
}

criterion_group!(benches, pose);
