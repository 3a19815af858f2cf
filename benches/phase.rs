//! Benches of the 12-shot phase decoder and the point-cloud stage on a seeded synthetic
//! frame: a slanted plane lit by fringes, with 8-bit noise.

use camplace_config::{FloatImage, GrayImage};
use camplace_config::{PhaseParams, ReconstructionParams, WorkVolume};
use camplace_estimator::{
    depth::Background, depth::Cloud, depth::CloudBuilder, depth::PhaseDecoder, depth::RectifiedCamera,
};
use criterion::Criterion;
use nalgebra::{Isometry3, Matrix3, Translation3, UnitQuaternion};
use std::hint::black_box;

const WIDTH: usize = 640;
const HEIGHT: usize = 480;
const PERIODS: [f64; 3] = [1.0, 8.0, 64.0];

/// Disparity of the slanted plane at rectified-left pixel (x, y): `a + b x + c y`.
fn plane(x: f64, y: f64) -> f64 {
    150.0 + 0.03 * x + 0.02 * y
}

/// Projector coordinate (fraction of its width) seen at rectified-left column `x`.
fn projector(x_left: f64) -> f64 {
    (x_left + 120.0) / 900.0
}

/// Seeded xorshift noise in [-10, 10] grey levels.
struct Noise(u64);

impl Noise {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 % 21) as f64 - 10.0
    }
}

/// The 12 rectified shots of one camera; `right` maps each pixel back to the left column
/// that sees the same point.
fn shots(right: bool, noise: &mut Noise) -> Vec<GrayImage> {
    let mut out = Vec::new();
    for &f in &PERIODS {
        for k in 0..4 {
            let mut im = GrayImage::new(WIDTH, HEIGHT, 0);
            for y in 0..HEIGHT {
                for x in 0..WIDTH {
                    let (x, yf) = (x as f64, y as f64);
                    // Right pixel x sees left column x_l = x + d(x_l), d linear in x_l.
                    let x_left = if right { (x + 150.0 + 0.02 * yf) / (1.0 - 0.03) } else { x };
                    let phase = std::f64::consts::TAU * f * projector(x_left) - k as f64 * std::f64::consts::FRAC_PI_2;
                    let v = 40.0 + 120.0 * (0.5 + 0.5 * phase.cos()) + noise.next() / 3.0;
                    im.set(x as usize, y, v.round().clamp(0.0, 254.0) as u8);
                }
            }
            out.push(im);
        }
    }
    out
}

fn camera() -> RectifiedCamera {
    RectifiedCamera {
        width: WIDTH,
        height: HEIGHT,
        k: Matrix3::new(812.4, 0.0, 320.0, 0.0, 812.4, 240.0, 0.0, 0.0, 1.0),
        baseline: 120.0,
        t_world_rectified: Isometry3::from_parts(
            Translation3::new(320.0, 0.0, 510.0),
            UnitQuaternion::from_euler_angles(std::f64::consts::PI - 0.56, 0.0, -std::f64::consts::FRAC_PI_2),
        ),
    }
}

/// Benches of the 12-shot decode and the cloud stage.
pub fn benches(c: &mut Criterion) {
    let mut noise = Noise(0x9e37_79b9_7f4a_7c15);
    let left = shots(false, &mut noise);
    let right = shots(true, &mut noise);
    let params = PhaseParams { min_modulation: 4.0, lr_tolerance: 1.0 };
    let mut decoder = PhaseDecoder::new(&params, &PERIODS, WIDTH, HEIGHT).expect("valid decoder");
    let mut disparity = FloatImage::new(WIDTH, HEIGHT, f32::INFINITY);
    decoder.decode(&left, &right, (100.0, 200.0), &mut disparity).expect("decodes");
    let decoded = disparity.data.iter().filter(|d| d.is_finite()).count();
    assert!(decoded > WIDTH * HEIGHT / 2, "the bench frame decodes only {decoded} pixels");
    c.bench_function("phase/decode_640x480", |b| {
        b.iter(|| decoder.decode(black_box(&left), black_box(&right), (100.0, 200.0), &mut disparity).unwrap())
    });

    let cam = camera();
    let recon = ReconstructionParams { background_margin: 4.0, background_dilation: 2 };
    let mut bg_disparity = FloatImage::new(WIDTH, HEIGHT, f32::INFINITY);
    for y in 0..HEIGHT {
        for x in 0..WIDTH {
            // The background lies 6 px of disparity behind the plane on the left half only,
            // so about half the points survive removal.
            let d = plane(x as f64, y as f64) - if x < WIDTH / 2 { 6.0 } else { 0.0 };
            bg_disparity.set(x, y, d as f32);
        }
    }
    let background = Background::from_disparity(&cam, &bg_disparity, &recon).expect("valid background");
    let volume = WorkVolume { x: [-1e4, 1e4], y: [-1e4, 1e4], z: [-1e4, 1e4] };
    let builder = CloudBuilder::new(&cam, &volume, &recon);
    let mut cloud = Cloud::with_capacity(WIDTH, HEIGHT);
    c.bench_function("cloud/from_disparity_640x480", |b| {
        b.iter(|| builder.build(black_box(&disparity), Some(&background), &mut cloud).unwrap())
    });
}
