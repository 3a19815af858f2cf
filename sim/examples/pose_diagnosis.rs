//! Why the pose estimator succeeds or fails at one placement: builds (or loads) the tray
//! model, renders scenarios 0..N of a seed, runs the estimator on each and prints, per
//! scene and in total, the success, the errors of the coarse and the refined pose, the
//! correct matches, the inliers of the found and of the true pose, and the stage timings.
//!
//! ```text
//! cargo run --release -p camplace-sim --example pose_diagnosis -- \
//!     [--placement r=605,alpha=32,baseline=81,vergence=3.5] [--count 50] [--seed 1] \
//!     [--cell cell.toml] [--model tray.model] [--quiet]
//! ```
//! `--model F` loads F when it exists and writes the built model there otherwise.

use std::path::PathBuf;
use std::time::Instant;

use camplace_config::Cell;
use camplace_estimator::{geometry::Neighbours, Estimator, EstimatorConfig, Model};
use camplace_estimator::{pose::correct_matches, pose::pose_errors};
use camplace_sim::{background_scene, build_model, draw_scenario, noise_key, Frame, Method, Simulator};
use nalgebra::{Isometry3, Point3};

struct Args {
    placement: String,
    count: u64,
    seed: u64,
    cell: Option<PathBuf>,
    model: Option<PathBuf>,
    quiet: bool,
}

fn parse() -> Args {
    let mut a = Args {
        placement: "r=605,alpha=32,baseline=81,vergence=3.5".into(),
        count: 50,
        seed: 1,
        cell: None,
        model: None,
        quiet: false,
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let mut value = || it.next().unwrap_or_else(|| panic!("{flag} needs a value"));
        match flag.as_str() {
            "--placement" => a.placement = value(),
            "--count" => a.count = value().parse().expect("--count: a number"),
            "--seed" => a.seed = value().parse().expect("--seed: a number"),
            "--cell" => a.cell = Some(value().into()),
            "--model" => a.model = Some(value().into()),
            "--quiet" => a.quiet = true,
            other => panic!("unknown flag {other}"),
        }
    }
    a
}

/// Points of the view closest to the sensor under `pose` with a scene point within `reach`.
fn inliers(model: &Model, grid: &Neighbours, pose: &Isometry3<f64>, sensor: &Point3<f32>, reach: f32) -> u32 {
    let view = &model.views[model.closest_view(pose, sensor)];
    let pose = pose.cast::<f32>();
    let mut hit = 0;
    for p in &view.points {
        let mut any = false;
        grid.for_each_within(&(pose * p), reach, |_, _, _| any = true);
        hit += u32::from(any);
    }
    hit
}

fn main() {
    let a = parse();
    let cell = match &a.cell {
        Some(p) => Cell::load(p).expect("cell file"),
        None => Cell::default(),
    };
    let placement = cell.placement.with_overrides(&a.placement).expect("placement");
    let t = Instant::now();
    let model = match &a.model {
        Some(p) if p.exists() => Model::from_bytes(&std::fs::read(p).expect("model file")).expect("model"),
        _ => {
            let m = build_model(&cell, &placement, Method::OneShot, a.seed).expect("model builds");
            if let Some(p) = &a.model {
                std::fs::write(p, m.to_bytes()).expect("model written");
            }
            m
        }
    };
    eprintln!(
        "model: {} features, views {:?}, {:.1} s",
        model.feature_points.len(),
        model.views.iter().map(|v| v.points.len()).collect::<Vec<_>>(),
        t.elapsed().as_secs_f64()
    );
    let symmetries = model.symmetries_deg.clone();
    let feature_points = model.feature_points.clone();
    let mut sim = Simulator::new(&cell, &placement, a.seed).expect("simulator");
    let mut frame = Frame::default();
    sim.render(&background_scene(&cell, a.seed), Method::OneShot, noise_key(a.seed, 0, true), &mut frame);
    let mut estimator =
        Estimator::new(&EstimatorConfig::from(&cell), sim.rig(), model, Method::OneShot).expect("estimator");
    estimator.set_background(&frame.shots.left, &frame.shots.right).expect("background");
    let sensor = estimator.sensor_position();
    let reach = cell.estimator.inlier_distance as f32;
    let mut grid = Neighbours::new();
    let (mut successes, mut no_pose, mut coarse_wrong, mut refine_lost) = (0, 0, 0, 0);
    let mut sums = [0.0f64; 6];
    let mut rank_hits = [0u32; 25];
    let mut ms: Vec<[f64; 6]> = Vec::new();
    if !a.quiet {
        println!("scene found ok  pos_mm  rot_deg  coarse_mm coarse_deg  keys  matches correct keys_ok  inl  inl_true  iters");
    }
    for i in 0..a.count {
        let scenario = draw_scenario(&cell, a.seed, i);
        sim.render(&scenario.scene(), Method::OneShot, noise_key(a.seed, i, false), &mut frame);
        let pose = estimator.process(&frame.shots.left, &frame.shots.right).expect("process");
        let truth = scenario.t_world_tray;
        let e = pose_errors(&pose.t_world_tray, &truth, &symmetries, &cell.metrics);
        let c = pose_errors(&pose.ransac.t_world_tray, &truth, &symmetries, &cell.metrics);
        let matches = estimator.correspondences();
        let keys = estimator.scene_keypoints();
        let correct = correct_matches(keys, &feature_points, matches, &truth, &symmetries, 4.5);
        let mut good_keys = std::collections::BTreeSet::new();
        let mut rank = 0;
        for (j, m) in matches.iter().enumerate() {
            rank = if j > 0 && matches[j - 1].scene == m.scene { rank + 1 } else { 0 };
            if correct_matches(keys, &feature_points, std::slice::from_ref(m), &truth, &symmetries, 4.5) > 0 {
                good_keys.insert(m.scene);
                rank_hits[rank.min(rank_hits.len() - 1)] += 1;
            }
        }
        grid.build(estimator.scene_cloud(), 2.0 * reach).expect("grid");
        let true_inliers = inliers(estimator.model(), &grid, &truth, &sensor, reach);
        let ok = pose.found && e.success;
        successes += usize::from(ok);
        if !pose.found {
            no_pose += 1;
        } else if !ok {
            if c.position_mm < 6.0 && c.rotation_deg < 8.0 {
                refine_lost += 1;
            } else {
                coarse_wrong += 1;
            }
        }
        sums[0] += correct as f64;
        sums[1] += good_keys.len() as f64;
        sums[2] += pose.keypoints as f64;
        sums[3] += pose.matches as f64;
        sums[4] += pose.scene_points as f64;
        sums[5] += pose.ransac.iterations as f64;
        let t = pose.timings;
        ms.push([t.normals_ms + t.downsample_ms, t.features_ms, t.matching_ms, t.ransac_ms, t.icp_ms, t.total_ms]);
        if !a.quiet {
            println!(
                "{i:5} {:5} {:2} {:7.2} {:8.2} {:9.1} {:10.1} {:5} {:8} {:7} {:7} {:5} {:8} {:6}",
                u8::from(pose.found),
                u8::from(ok),
                e.position_mm,
                e.rotation_deg,
                c.position_mm,
                c.rotation_deg,
                pose.keypoints,
                pose.matches,
                correct,
                good_keys.len(),
                pose.inliers,
                true_inliers,
                pose.ransac.iterations,
            );
        }
    }
    let n = a.count as f64;
    let median = |k: usize| {
        let mut v: Vec<f64> = ms.iter().map(|m| m[k]).collect();
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    println!(
        "placement {}: success {successes}/{} ({:.0} %), no pose {no_pose}, coarse wrong {coarse_wrong}, lost in refinement {refine_lost}",
        a.placement,
        a.count,
        100.0 * successes as f64 / n
    );
    println!(
        "mean per scene: {:.0} cloud points, {:.0} key points, {:.0} matches, {:.1} correct, {:.1} key points with a correct match, {:.0} RANSAC iterations",
        sums[4] / n,
        sums[2] / n,
        sums[3] / n,
        sums[0] / n,
        sums[1] / n,
        sums[5] / n
    );
    println!("correct matches by rank among a key point's matches: {rank_hits:?}");
    println!(
        "median ms: down-sampling and normals {:.1}, features {:.1}, matching {:.1}, RANSAC {:.1}, ICP {:.1}, whole frame {:.1}",
        median(0),
        median(1),
        median(2),
        median(3),
        median(4),
        median(5)
    );
}
