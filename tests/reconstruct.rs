//! Reconstruction against the simulator's ground truth: depth error and coverage on the
//! tray and item pixels that both cameras see (on the rows the method matches), for
//! one-shot and 12-shot captures.

use camplace_config::{Cell, Placement};
use camplace_estimator::{depth::Method, depth::Reconstruction, depth::Reconstructor, EstimatorConfig};
use camplace_sim::{background_scene, draw_scenario, noise_key, Frame, Simulator};
use nalgebra::Point3;

/// Depth error figures over the tray and item pixels seen by both cameras.
struct Score {
    pixels: usize,
    coverage: f64,
    median_mm: f64,
}

fn placement(text: &str) -> (Cell, Placement) {
    let cell = Cell::default();
    let p = cell.placement.with_overrides(text).unwrap();
    (cell, p)
}

/// Renders scenarios `0..n` of seed 1, reconstructs them and scores them.
fn score(text: &str, method: Method, n: u64) -> Score {
    let (cell, p) = placement(text);
    let seed = 1;
    let mut sim = Simulator::new(&cell, &p, seed).unwrap();
    let rig = sim.rig().clone();
    let mut rec = Reconstructor::new(&EstimatorConfig::from(&cell), &rig, method).unwrap();
    let mut frame = Frame::default();
    sim.render(&background_scene(&cell, seed), method, noise_key(seed, 0, true), &mut frame);
    rec.set_background(&frame.shots.left, &frame.shots.right).unwrap();
    let mut out = Reconstruction::default();
    let mut truth = camplace_config::FloatImage::default();
    let (mut errors, mut pixels) = (Vec::new(), 0usize);
    for i in 0..n {
        let scenario = draw_scenario(&cell, seed, i);
        sim.render(&scenario.scene(), method, noise_key(seed, i, false), &mut frame);
        rec.process(&frame.shots.left, &frame.shots.right, &mut out).unwrap();
        let rect = rec.rectification();
        let cam = &rect.camera;
        rect.disparity_truth(&rig.left, &frame.depth_left, &mut truth);
        // The one-shot matcher matches every row_step-th row; the phase decoder every row.
        let row_step = if method == Method::OneShot { cell.stereo.row_step as usize } else { 1 };
        for y in (0..cam.height).step_by(row_step) {
            for x in 0..cam.width {
                let dt = truth.get(x, y);
                if !dt.is_finite() {
                    continue;
                }
                // Tray or item pixel? (ids live in raw-left pixels)
                let Some((u, v)) = rect.rectified_to_raw(true, x as f64, y as f64) else { continue };
                let (ui, vi) = (u.round(), v.round());
                if ui < 0.0 || vi < 0.0 || ui >= rig.left.width as f64 || vi >= rig.left.height as f64 {
                    continue;
                }
                if frame.ids_left.get(ui as usize, vi as usize) == 0 {
                    continue;
                }
                let world = cam.t_world_rectified.transform_point(&cam.point_in_camera(x as f64, y as f64, dt as f64));
                if !seen_by_right(&rig.right, &frame, &world) {
                    continue;
                }
                pixels += 1;
                let truth_z = cam.depth_from_disparity(dt) as f64;
                let d = out.disparity.get(x, y);
                if d.is_finite() && d > 0.0 {
                    errors.push((cam.depth_from_disparity(d) as f64 - truth_z).abs());
                }
            }
        }
    }
    errors.sort_by(f64::total_cmp);
    let median_mm = errors.get(errors.len() / 2).copied().unwrap_or(f64::INFINITY);
    Score { pixels, coverage: errors.len() as f64 / pixels.max(1) as f64, median_mm }
}

/// Depth of a world point along a camera's z axis.
fn world_depth(cam: &camplace_estimator::geometry::Camera, p: &Point3<f64>) -> f64 {
    cam.t_world_camera.inverse_transform_point(p).z
}

/// Whether the right camera sees `p` (in its image, not occluded: its true depth there agrees).
fn seen_by_right(right: &camplace_estimator::geometry::Camera, frame: &Frame, p: &Point3<f64>) -> bool {
    let Some(px) = right.project(p) else { return false };
    let (u, v) = (px.x.round(), px.y.round());
    if u < 0.0 || v < 0.0 || u >= right.width as f64 || v >= right.height as f64 {
        return false;
    }
    let seen = frame.depth_right.get(u as usize, v as usize) as f64;
    (seen - world_depth(right, p)).abs() < 2.0
}

fn report(name: &str, s: &Score) {
    println!("{name}: {} pixels, coverage {:.3}, median |dz| {:.3} mm", s.pixels, s.coverage, s.median_mm);
}

const OPTIMUM: &str = "r=605,alpha=32,baseline=81,vergence=3.5";
const DEFAULT: &str = "r=605,alpha=32,baseline=120,vergence=auto";

#[test]
fn one_shot_depth_at_the_papers_optimum() {
    let s = score(OPTIMUM, Method::OneShot, 3);
    report("one-shot, optimum", &s);
    assert!(s.pixels > 50_000, "enough tray and item pixels: {}", s.pixels);
    assert!(s.coverage >= 0.90, "coverage {:.3}", s.coverage);
    assert!(s.median_mm <= 1.0, "median {:.3} mm", s.median_mm);
}

#[test]
fn one_shot_depth_at_the_default_placement() {
    let s = score(DEFAULT, Method::OneShot, 3);
    report("one-shot, default", &s);
    assert!(s.pixels > 50_000, "enough tray and item pixels: {}", s.pixels);
    assert!(s.coverage >= 0.90, "coverage {:.3}", s.coverage);
    assert!(s.median_mm <= 1.0, "median {:.3} mm", s.median_mm);
}

#[test]
fn twelve_shot_depth_at_both_placements() {
    for p in [OPTIMUM, DEFAULT] {
        let s = score(p, Method::Phase12, 2);
        report(&format!("12-shot, {p}"), &s);
        assert!(s.pixels > 30_000, "enough tray and item pixels: {}", s.pixels);
        assert!(s.median_mm <= 0.5, "median {:.3} mm", s.median_mm);
    }
}
