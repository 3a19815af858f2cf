//! Benches of the one-shot stereo stage at the default placement: setting up the
//! rectification (its remap tables; a study does it once per scenario's miscalibrated rig),
//! rectifying a raw 640x480 pair, and ELAS on the rectified pair (a ~110 px search range),
//! buffers reused.

use camplace_config::Cell;
use camplace_config::{FloatImage, GrayImage};
use camplace_estimator::geometry::rig_for;
use camplace_estimator::{depth::DisparityMatcher, depth::Elas, depth::Rectification, geometry::Camera};
use criterion::{criterion_group, Criterion};
use nalgebra::{Point3, Vector3};
use std::hint::black_box;

/// A random-dot table with a 40 mm block on it, as `cam` sees it, with the paper's noise.
fn render(cam: &Camera, seed: u64) -> GrayImage {
    let (w, h) = (cam.width, cam.height);
    let dot = |p: &Point3<f64>| {
        let (i, j) = ((p.x / 1.6).floor() as i64, (p.y / 1.6).floor() as i64);
        let mut k = (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ (j as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F);
        k ^= k >> 29;
        k = k.wrapping_mul(0xBF58_476D_1CE4_E5B9);
        k ^= k >> 32;
        if k & 1 == 1 {
            190.0
        } else {
            50.0
        }
    };
    // A seeded xorshift: the noise only has to be repeatable, not good.
    let mut state = seed.wrapping_mul(0x2545_F491_4F6C_DD1D) | 1;
    let mut noise = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state % 21) as f64 - 10.0
    };
    let mut noisy = vec![0.0f64; w * h];
    for v in 0..h {
        for u in 0..w {
            let dir: Vector3<f64> = cam.t_world_camera.rotation * cam.ray(u as f64, v as f64);
            let o = cam.centre();
            let top = (o.z - 40.0) / -dir.z;
            let p_top = o + dir * top;
            let p = if p_top.x.abs() < 60.0 && p_top.y.abs() < 45.0 { p_top } else { o + dir * (o.z / -dir.z) };
            noisy[v * w + u] = (dot(&p) + noise()).clamp(0.0, 255.0);
        }
    }
    let mut img = GrayImage::new(w, h, 0);
    for v in 0..h {
        for u in 0..w {
            let (mut s, mut n) = (0.0, 0.0);
            for y in v.saturating_sub(1)..(v + 2).min(h) {
                for x in u.saturating_sub(1)..(u + 2).min(w) {
                    s += noisy[y * w + x];
                    n += 1.0;
                }
            }
            img.set(u, v, (s / n).round() as u8);
        }
    }
    img
}

fn stereo(c: &mut Criterion) {
    let cell = Cell::default();
    let rig = rig_for(&cell.placement, &cell.sensor);
    let rect = Rectification::new(&rig, &cell.work_volume).expect("the default placement rectifies");
    let (raw_left, raw_right) = (render(&rig.left, 1), render(&rig.right, 2));
    let (mut left, mut right) = (GrayImage::default(), GrayImage::default());
    rect.rectify_left(&raw_left, &mut left);
    rect.rectify_right(&raw_right, &mut right);
    let range = rect.disparity_range();
    let span = (range.1.ceil() - range.0.floor()) as usize;
    let mut elas = Elas::new(&cell.stereo, left.width, left.height, span);
    let mut disparity = FloatImage::default();
    elas.compute(&left, &right, range, &mut disparity).expect("the pair matches");

    let mut group = c.benchmark_group("stereo");
    group.bench_function("rectification_new", |b| {
        b.iter(|| Rectification::new(black_box(&rig), &cell.work_volume).expect("the default placement rectifies"))
    });
    group.bench_function("rectify_pair", |b| {
        b.iter(|| {
            rect.rectify_left(black_box(&raw_left), &mut left);
            rect.rectify_right(black_box(&raw_right), &mut right);
        })
    });
    group.bench_function("elas_640x480", |b| {
        b.iter(|| {
            elas.compute(black_box(&left), black_box(&right), range, &mut disparity).expect("the pair matches");
            black_box(&disparity.data[0]);
        })
    });
    group.finish();
}

criterion_group!(benches, stereo);
