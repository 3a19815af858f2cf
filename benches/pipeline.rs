//! Bench of the whole deployed pipeline, camera to pose: one rendered one-shot stereo frame
//! at the paper's optimum, with the model built at that placement; and the pose stages alone
//! (down-sampling, normals, features, matching, RANSAC, ICP) on that frame's world cloud;
//! and the verification of that frame's pose alone (`pose/verify`, from its cloud;
//! `pose/verify_frame`, against the frame with its depth map); and `serve`'s drift
//! watch on that frame's disparity (`serve/drift_check`); and the frame's reconstruction
//! alone, with its disparity in the region that differs from the background
//! (`reconstruct/one_shot_in_foreground`), against the whole image
//! (`reconstruct/one_shot_whole_image`), and the finding of that region
//! (`reconstruct/foreground_region`).

use std::hint::black_box;

use camplace_config::Cell;
use camplace_estimator::depth::{Foreground, Reconstruction, Reconstructor};
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

    // The one-shot frame's own pose verified against the frame, its depth map included: the
    // see-through evidence of the pose, of its shifts by a slot's pitch and of its turns.
    let framed = estimator.process(&frame.shots.left, &frame.shots.right).expect("the frame is valid");
    eprintln!("pose/verify_frame: {:?}", framed.verification);
    c.bench_function("pose/verify_frame", |b| b.iter(|| estimator.verify(black_box(&framed.t_world_tray))));

    // The drift watch after a trigger: the table plane from the frame's disparity.
    let limits = DriftLimits { rotation_deg: 1.0, translation_mm: 5.0, from: "bench".into() };
    let mut watch = DriftWatch::new(limits);
    let (disparity, camera) = estimator.whole_disparity().expect("the frame matches whole");
    eprintln!("serve/drift_check: {:?}", watch.check(disparity, camera));
    c.bench_function("serve/drift_check", |b| b.iter(|| watch.check(black_box(disparity), camera).warning));

    // Reconstruction alone: with the background's region, and without a background.
    let config = EstimatorConfig::from(&cell);
    let mut with = Reconstructor::new(&config, sim.rig(), Method::OneShot).expect("the rig rectifies");
    with.set_background(&background.shots.left, &background.shots.right).expect("the background reconstructs");
    let mut whole = Reconstructor::new(&config, sim.rig(), Method::OneShot).expect("the rig rectifies");
    let mut out = Reconstruction::default();
    with.process(&frame.shots.left, &frame.shots.right, &mut out).expect("the frame is valid");
    let region = with.last_region();
    let (w, h) = (with.rectification().camera.width, with.rectification().camera.height);
    eprintln!("reconstruct: region {region:?}, {:.1} % of the image", 100.0 * region.area() as f64 / (w * h) as f64);
    let mut group = c.benchmark_group("reconstruct");
    group.bench_function("one_shot_in_foreground", |b| {
        b.iter(|| with.process(black_box(&frame.shots.left), &frame.shots.right, &mut out).expect("valid"))
    });
    group.bench_function("one_shot_whole_image", |b| {
        b.iter(|| whole.process(black_box(&frame.shots.left), &frame.shots.right, &mut out).expect("valid"))
    });
    let mut empty = Reconstructor::new(&config, sim.rig(), Method::OneShot).expect("the rig rectifies");
    empty.process(&background.shots.left, &background.shots.right, &mut out).expect("the background is valid");
    let mut finder = Foreground::new(empty.rectified().0[0].clone());
    with.process(&frame.shots.left, &frame.shots.right, &mut out).expect("the frame is valid");
    let rectified = with.rectified().0[0].clone();
    group.bench_function("foreground_region", |b| b.iter(|| finder.region(black_box(&rectified))));
    group.finish();
}
