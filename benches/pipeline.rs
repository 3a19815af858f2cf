//! Bench of the whole deployed pipeline, camera to pose: one rendered one-shot stereo frame
//! at the paper's optimum, with the model built at that placement; and the pose stages alone
//! (down-sampling, normals, features, matching, RANSAC, ICP) on that frame's world cloud;
//! and the verification of that frame's pose alone (`pose/verify`); and `serve`'s drift
//! watch on that frame's disparity (`serve/drift_check`).

use std::hint::black_box;

use camplace_config::Cell;
use camplace_estimator::{Estimator, EstimatorConfig};
use camplace_serve::{DriftLimits, DriftWatch};
use camplace_sim::{background_scene, build_model, draw_scenario, noise_key, Frame, Method, Simulator};
use criterion::Criterion;

/// Registers the pipeline bench.
pub fn benches(c: &mut Criterion) {
    let cell = Cell::default();
    let placement = cell.placement.with_overrides("r=605,alpha=32,baseline=81,vergence=3.5").expect("valid placement");
    let seed = 1;
    let model = build_model(&cell, &placement, Method::OneShot, seed).expect("the model builds");
    let mut sim = Simulator::new(&cell, &placement, seed).expect("the sensor builds");
    let mut background = Frame::default();
    sim.render(&background_scene(&cell, seed), Method::OneShot, noise_key(seed, 0, true), &mut background);
    let mut frame = Frame::default();
    sim.render(&draw_scenario(&cell, seed, 2).scene(), Method::OneShot, noise_key(seed, 2, false), &mut frame);
    let mut estimator =
        Estimator::new(&EstimatorConfig::from(&cell), sim.rig(), model, Method::OneShot).expect("the estimator builds");
    estimator.set_background(&background.shots.left, &background.shots.right).expect("the background reconstructs");
    let pose = estimator.process(&frame.shots.left, &frame.shots.right).expect("the frame is valid");
    eprintln!("pipeline: found {}, {} inliers, stages {:?}", pose.found, pose.inliers, pose.timings);

    let mut group = c.benchmark_group("pipeline");
    group.sample_size(10);
    group.bench_function("one_shot_frame", |b| {
        b.iter(|| estimator.process(black_box(&frame.shots.left), black_box(&frame.shots.right)).expect("valid"))
    });
    let cloud = estimator.reconstruction().cloud.points.clone();
    group.bench_function("pose_from_cloud", |b| b.iter(|| estimator.process_cloud(black_box(&cloud)).expect("valid")));
    group.finish();
    // The last frame run was the cloud of the one-shot frame: its pose verified again.
    let pose = estimator.process_cloud(&cloud).expect("valid");
    eprintln!("pose/verify: {:?}", pose.verification);
    c.bench_function("pose/verify", |b| b.iter(|| estimator.verify(black_box(&pose.t_world_tray))));

    // The drift watch after a trigger: the table plane from the frame's disparity.
    estimator.process(&frame.shots.left, &frame.shots.right).expect("the frame is valid");
    let limits = DriftLimits { rotation_deg: 1.0, translation_mm: 5.0, from: "bench".into() };
    let mut watch = DriftWatch::new(limits);
    let (disparity, camera) = (&estimator.reconstruction().disparity, estimator.rectified_camera());
    eprintln!("serve/drift_check: {:?}", watch.check(disparity, camera));
    c.bench_function("serve/drift_check", |b| b.iter(|| watch.check(black_box(disparity), camera).warning));
}
