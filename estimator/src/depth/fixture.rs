//! A synthetic 12-shot phase-shift scene with exact truth per pixel, for the depth stage's
//! tests: a slanted table and an optional box in front of it, lit by a pinhole projector at
//! the middle of the baseline, rendered with the paper's sensor noise.

use std::f32::consts::FRAC_PI_2;

use camplace_config::PhaseParams;
use nalgebra::{Matrix3, Point3, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::GrayImage;

pub(crate) const WIDTH: usize = 640;
pub(crate) const HEIGHT: usize = 480;
const FOCAL: f64 = 812.4;
const BASELINE: f64 = 120.0;
const PROJECTOR_WIDTH: f64 = 1280.0;
const AMBIENT: f64 = 0.2;
const GAIN: f64 = 0.6;
const BRIGHT: f64 = 0.85;
pub(crate) const DARK: f64 = 0.08;
pub(crate) const TABLE: f64 = 0.45;

/// What a camera ray hits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Surface {
    Table,
    Box,
}

/// A slanted table plane with an optional box in front of it, in the rectified-left
/// camera frame; the projector is a pinhole at the middle of the baseline.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Scene {
    pub with_box: bool,
    /// The projector's x runs against the rectified x axis.
    pub mirrored: bool,
}

/// A rendered 12-shot stereo frame and its truth per rectified-left pixel.
pub(crate) struct Frame {
    pub left: Vec<GrayImage>,
    pub right: Vec<GrayImage>,
    pub disparity: Vec<f64>,
    pub surface: Vec<Option<Surface>>,
    pub albedo: Vec<f64>,
    pub lit: Vec<bool>,
    pub seen_by_right: Vec<bool>,
    /// Inside the right image but hidden from the right camera by the box.
    pub occluded: Vec<bool>,
    pub saturated: Vec<bool>,
}

pub(crate) fn camera() -> crate::RectifiedCamera {
    crate::RectifiedCamera {
        width: WIDTH,
        height: HEIGHT,
        k: Matrix3::new(FOCAL, 0.0, 320.0, 0.0, FOCAL, 240.0, 0.0, 0.0, 1.0),
        baseline: BASELINE,
        t_world_rectified: table_frame(),
    }
}

/// Table plane: n . p = TABLE_OFFSET, facing the camera.
fn table_normal() -> Vector3<f64> {
    Vector3::new(0.12, -0.35, -1.0).normalize()
}
const TABLE_DEPTH: f64 = 700.0;

/// Rectified-left -> a world frame whose z = 0 is the table, z up (towards the camera).
pub(crate) fn table_frame() -> nalgebra::Isometry3<f64> {
    let z = table_normal();
    let x = (Vector3::x() - z * z.x).normalize();
    let y = z.cross(&x);
    let r =
        nalgebra::Rotation3::from_matrix_unchecked(Matrix3::from_rows(&[x.transpose(), y.transpose(), z.transpose()]));
    let origin = Point3::new(0.0, 0.0, TABLE_DEPTH);
    let rot = nalgebra::UnitQuaternion::from_rotation_matrix(&r);
    nalgebra::Isometry3::from_parts((-(rot * origin.coords)).into(), rot)
}

/// Box in the camera frame: x, y, z ranges.
const BOX: [[f64; 2]; 3] = [[-90.0, 30.0], [-70.0, 60.0], [590.0, 640.0]];

impl Scene {
    /// Nearest hit along `origin + t dir`, t > 0.
    fn cast(&self, origin: Point3<f64>, dir: Vector3<f64>) -> Option<(f64, Surface)> {
        let n = table_normal();
        let mut best: Option<(f64, Surface)> = None;
        let denom = n.dot(&dir);
        if denom.abs() > 1e-12 {
            let t = (n.dot(&Vector3::new(0.0, 0.0, TABLE_DEPTH)) - n.dot(&origin.coords)) / denom;
            if t > 1e-9 {
                best = Some((t, Surface::Table));
            }
        }
        if self.with_box {
            let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
            for a in 0..3 {
                let (o, d) = (origin[a], dir[a]);
                if d.abs() < 1e-15 {
                    if o < BOX[a][0] || o > BOX[a][1] {
                        t0 = f64::INFINITY;
                    }
                    continue;
                }
                let (ta, tb) = ((BOX[a][0] - o) / d, (BOX[a][1] - o) / d);
                t0 = t0.max(ta.min(tb));
                t1 = t1.min(ta.max(tb));
            }
            if t0 <= t1 && t0 > 1e-9 && best.is_none_or(|(t, _)| t0 < t) {
                best = Some((t0, Surface::Box));
            }
        }
        best
    }

    /// Albedo and whether a lamp saturates the spot.
    fn material(&self, p: &Point3<f64>, s: Surface) -> (f64, bool) {
        match s {
            Surface::Box => (BRIGHT, false),
            // A dark stripe (items) and a lamp hot spot on the table.
            Surface::Table if (-260.0..-170.0).contains(&p.x) => (DARK, false),
            Surface::Table if p.x > 170.0 && p.y < -80.0 => (1.0, true),
            Surface::Table => (TABLE, false),
        }
    }

    /// Projector coordinate (fraction of its width) of a point, or `None` when the
    /// projector does not light it.
    fn projector(&self, p: &Point3<f64>) -> Option<f64> {
        let c = Point3::new(BASELINE / 2.0, 0.0, 0.0);
        let (t, _) = self.cast(c, p - c)?;
        if (t - 1.0).abs() > 1e-6 {
            return None;
        }
        let fp = PROJECTOR_WIDTH / 2.0 / (20f64.to_radians()).tan();
        let xp = fp * (p.x - c.x) / p.z + PROJECTOR_WIDTH / 2.0;
        let u = xp / PROJECTOR_WIDTH;
        (0.0..1.0).contains(&u).then_some(if self.mirrored { 1.0 - u } else { u })
    }

    /// Renders the 12 shots of both cameras with the paper's noise.
    pub(crate) fn render(&self, periods: &[f64], seed: u64) -> Frame {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let n = WIDTH * HEIGHT;
        let mut truth = Frame {
            left: Vec::new(),
            right: Vec::new(),
            disparity: vec![f64::INFINITY; n],
            surface: vec![None; n],
            albedo: vec![0.0; n],
            lit: vec![false; n],
            seen_by_right: vec![false; n],
            occluded: vec![false; n],
            saturated: vec![false; n],
        };
        // Per camera and pixel: (albedo, lamp, projector coordinate).
        let mut gbuffers = Vec::new();
        for (cam, cx) in [(0, 0.0), (1, BASELINE)] {
            let origin = Point3::new(cx, 0.0, 0.0);
            let mut g = vec![(0.0, 0.0, None); n];
            for y in 0..HEIGHT {
                for x in 0..WIDTH {
                    let dir = Vector3::new((x as f64 - 320.0) / FOCAL, (y as f64 - 240.0) / FOCAL, 1.0);
                    let Some((t, s)) = self.cast(origin, dir) else { continue };
                    let p = origin + t * dir;
                    let (albedo, hot) = self.material(&p, s);
                    let u = self.projector(&p);
                    g[y * WIDTH + x] = (albedo, if hot { 1.0 } else { 0.0 }, u);
                    if cam == 0 {
                        let i = y * WIDTH + x;
                        truth.disparity[i] = FOCAL * BASELINE / p.z;
                        truth.surface[i] = Some(s);
                        truth.albedo[i] = albedo;
                        truth.lit[i] = u.is_some();
                        truth.saturated[i] = hot;
                        let r = Point3::new(BASELINE, 0.0, 0.0);
                        let xr = FOCAL * (p.x - BASELINE) / p.z + 320.0;
                        let inside = (0.0..(WIDTH - 1) as f64).contains(&xr);
                        let unblocked = self.cast(r, p - r).is_some_and(|(tr, _)| (tr - 1.0).abs() < 1e-6);
                        truth.seen_by_right[i] = inside && unblocked;
                        truth.occluded[i] = inside && !unblocked;
                    }
                }
            }
            gbuffers.push(g);
        }
        for (cam, g) in gbuffers.iter().enumerate() {
            for &f in periods {
                for k in 0..4 {
                    let clean: Vec<f64> = g
                        .iter()
                        .map(|&(albedo, lamp, u)| {
                            let pattern = u.map_or(0.0, |u: f64| {
                                0.5 + 0.5 * (std::f64::consts::TAU * f * u - k as f64 * FRAC_PI_2 as f64).cos()
                            });
                            255.0 * albedo * (AMBIENT + lamp + GAIN * pattern)
                        })
                        .collect();
                    let shot = noisy(&clean, &mut rng);
                    if cam == 0 {
                        truth.left.push(shot);
                    } else {
                        truth.right.push(shot);
                    }
                }
            }
        }
        truth
    }
}

/// The paper's sensor noise: uniform integer noise in [-10, 10], a 3x3 mean, round and
/// clamp to 8 bits.
fn noisy(clean: &[f64], rng: &mut ChaCha8Rng) -> GrayImage {
    let noisy: Vec<f64> = clean.iter().map(|v| v + rng.random_range(-10..=10) as f64).collect();
    let mut out = GrayImage::new(WIDTH, HEIGHT, 0);
    for y in 0..HEIGHT {
        for x in 0..WIDTH {
            let mut sum = 0.0;
            for dy in -1i64..=1 {
                for dx in -1i64..=1 {
                    let xx = (x as i64 + dx).clamp(0, WIDTH as i64 - 1) as usize;
                    let yy = (y as i64 + dy).clamp(0, HEIGHT as i64 - 1) as usize;
                    sum += noisy[yy * WIDTH + xx];
                }
            }
            out.set(x, y, (sum / 9.0).round().clamp(0.0, 255.0) as u8);
        }
    }
    out
}

pub(crate) fn params() -> PhaseParams {
    PhaseParams { min_modulation: 4.0, lr_tolerance: 1.0 }
}

pub(crate) const PERIODS: [f64; 3] = [1.0, 8.0, 64.0];
pub(crate) const RANGE: (f32, f32) = (100.0, 200.0);

/// Whether the truth is smooth around pixel `i` (no depth, shadow or material edge
/// within 2 px).
pub(crate) fn away_from_edges(f: &Frame, i: usize) -> bool {
    let (x, y) = ((i % WIDTH) as i64, (i / WIDTH) as i64);
    for dy in -2..=2 {
        for dx in -2..=2 {
            let (xx, yy) = (x + dx, y + dy);
            if xx < 0 || yy < 0 || xx >= WIDTH as i64 || yy >= HEIGHT as i64 {
                return false;
            }
            let j = yy as usize * WIDTH + xx as usize;
            if (f.disparity[j] - f.disparity[i]).abs() > 1.0
                || !f.lit[j]
                || f.surface[j] != f.surface[i]
                || f.albedo[j] != f.albedo[i]
                || f.saturated[j] != f.saturated[i]
            {
                return false;
            }
        }
    }
    true
}
