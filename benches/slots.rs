//! Bench of the slot judge: eight slots of the synthetic tray, four holding a 34 mm box,
//! judged from its scene cloud (about 10k tray points and the items' tops) under the true
//! pose, with the judge's buffers reused as the estimator reuses them.

use camplace_estimator::{pose::SlotJudge, pose::SlotLayout, pose::SlotState};
use camplace_testing::{self as testing, Scene, SceneSpec};
use criterion::{criterion_group, Criterion};
use nalgebra::Point3;

fn slots(c: &mut Criterion) {
    let model = testing::tray(false, 1);
    let scene = Scene::generate(&model, false, &SceneSpec { seed: 21, ..SceneSpec::default() });
    let layout = SlotLayout {
        slots: [-72.0, -24.0, 24.0, 72.0].iter().flat_map(|&x| [[x, -31.0, 4.0, 0.0], [x, 31.0, 4.0, 0.0]]).collect(),
        footprint_min_mm: [-15.0, -15.0],
        cell_mm: [3.75, 3.75],
        cols: 8,
        rows: 8,
        top_mm: vec![30.0; 64],
    };
    let mut cloud = scene.points.clone();
    // Every other slot holds an item: its top, sampled every 2 mm.
    for n in (0..8).step_by(2) {
        let slot = scene.t_world_tray * layout.slot_pose(n).expect("8 slots");
        for i in 0..17 {
            for j in 0..17 {
                let p = Point3::new(-16.0 + 2.0 * i as f64, -16.0 + 2.0 * j as f64, 30.0);
                cloud.push((slot * p).cast::<f32>());
            }
        }
    }
    let mut judge = SlotJudge::new(layout).expect("a valid layout");
    let filled = judge.judge(&cloud, &scene.t_world_tray).iter().filter(|r| r.state == SlotState::Filled).count();
    eprintln!("slots: {} scene points, {filled} of 8 slots filled", cloud.len());
    assert_eq!(filled, 4, "the bench scene's items are found");
    c.bench_function("pose/slots", |b| b.iter(|| judge.judge(&cloud, &scene.t_world_tray).len()));
}

criterion_group!(benches, slots);
