//! Benches of the simulated sensor: a one-shot stereo pair and a 12-shot set at 640x480 at
//! the default placement, each a full frame (geometry, shading, noise), buffers reused; and
//! the one-shot pair through lens distortion (a wider canvas and the warp to the image);
//! and the one-shot pair with every simulated effect off, so the effects' cost shows beside
//! the first.

use camplace_config::{Cell, Effects};
use camplace_sim::{draw_scenario, Frame, Method, Simulator};
use criterion::{criterion_group, Criterion};
use std::hint::black_box;

fn render(c: &mut Criterion) {
    let cell = Cell::default();
    let mut sim = Simulator::new(&cell, &cell.placement, 1).expect("the default cell renders");
    let scenes: Vec<_> = (0..8).map(|i| draw_scenario(&cell, 1, i).scene()).collect();
    let mut frame = Frame::default();
    let mut group = c.benchmark_group("render");
    let mut i = 0;
    group.bench_function("one_shot_pair", |b| {
        b.iter(|| {
            i += 1;
            sim.render(&scenes[i % scenes.len()], Method::OneShot, i as u64, &mut frame);
            black_box(&frame.shots.left[0].data[0]);
        })
    });
    group.bench_function("phase12_set", |b| {
        b.iter(|| {
            i += 1;
            sim.render(&scenes[i % scenes.len()], Method::Phase12, i as u64, &mut frame);
            black_box(&frame.shots.left[11].data[0]);
        })
    });
    let mut distorted = cell.clone();
    distorted.sensor.camera_dist = [-0.1, 0.05, 0.0005, -0.0003, 0.0];
    let mut lens_sim = Simulator::new(&distorted, &cell.placement, 1).expect("the distorted cell renders");
    group.bench_function("one_shot_pair_distorted", |b| {
        b.iter(|| {
            i += 1;
            lens_sim.render(&scenes[i % scenes.len()], Method::OneShot, i as u64, &mut frame);
            black_box(&frame.shots.left[0].data[0]);
        })
    });
    let mut plain = cell.clone();
    plain.effects = Effects { defocus: false, specular: false, calibration_error: false, occluder: false };
    let mut plain_sim = Simulator::new(&plain, &cell.placement, 1).expect("the default cell renders");
    group.bench_function("one_shot_pair_without_effects", |b| {
        b.iter(|| {
            i += 1;
            plain_sim.render(&scenes[i % scenes.len()], Method::OneShot, i as u64, &mut frame);
            black_box(&frame.shots.left[0].data[0]);
        })
    });
    group.finish();
}

criterion_group!(benches, render);
