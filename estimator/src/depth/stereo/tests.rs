//! Matcher tests on synthetic rectified pairs with exact ground truth: random-dot surfaces
//! rendered by exact area integration, warped by known disparity planes, with the paper's
//! noise (uniform integer +-10, then a 3x3 mean). A brute-force window-SAD matcher with a
//! left-right check is the slow sanity reference.

use camplace_config::{Cell, StereoParams};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::cost::Kernel;
use super::dense::INVALID;
use super::{DisparityMatcher, Elas};
use crate::cpu::{Avx2, Avx512};
use crate::{FloatImage, GrayImage};

/// A disparity plane d = c + a x + b y in left-image pixels.
#[derive(Clone, Copy)]
struct Plane {
    a: f64,
    b: f64,
    c: f64,
}

impl Plane {
    fn at(&self, x: f64, y: f64) -> f64 {
        self.c + self.a * x + self.b * y
    }

    /// Left column of right column `xr` on row `y`: x - d(x, y) = xr.
    fn left_of(&self, xr: f64, y: f64) -> f64 {
        (xr + self.b * y + self.c) / (1.0 - self.a)
    }
}

/// A surface: its disparity plane and a random-dot texture fixed to left-image coordinates
/// (cells of `cell` px, each lit or not), shown as `base + contrast * lit`.
#[derive(Clone, Copy)]
struct Surface {
    plane: Plane,
    seed: u64,
    cell: f64,
    base: f64,
    contrast: f64,
}

impl Surface {
    fn lit(&self, i: i64, j: i64) -> f64 {
        let mut h =
            self.seed ^ (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ (j as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F);
        h ^= h >> 31;
        h = h.wrapping_mul(0xBF58_476D_1CE4_E5B9);
        h ^= h >> 29;
        (h & 1) as f64
    }

    /// Mean intensity over left columns [x0, x1] on row y (exact for the cell texture).
    fn mean_over(&self, x0: f64, x1: f64, y: f64) -> f64 {
        let j = (y / self.cell).floor() as i64;
        let mut sum = 0.0;
        for i in (x0 / self.cell).floor() as i64..=(x1 / self.cell).floor() as i64 {
            let overlap = x1.min((i + 1) as f64 * self.cell) - x0.max(i as f64 * self.cell);
            sum += self.lit(i, j) * overlap.max(0.0);
        }
        self.base + self.contrast * sum / (x1 - x0).max(1e-12)
    }
}

/// A scene: a background surface and optionally a box (a surface over a left-image
/// rectangle with half-integer edges, in front of the background).
struct Scene {
    width: usize,
    height: usize,
    background: Surface,
    block: Option<(Surface, [f64; 4])>,
}

const SUB_ROWS: usize = 4;

impl Scene {
    fn in_block(&self, x: f64, y: f64) -> Option<&Surface> {
        self.block.as_ref().filter(|(_, r)| x >= r[0] && x < r[1] && y >= r[2] && y < r[3]).map(|(s, _)| s)
    }

    fn render(&self, right: bool, rng: &mut ChaCha8Rng) -> GrayImage {
        let (w, h) = (self.width, self.height);
        let mut ideal = vec![0.0f64; w * h];
        for y in 0..h {
            for x in 0..w {
                let mut acc = 0.0;
                for s in 0..SUB_ROWS {
                    let yy = y as f64 - 0.5 + (s as f64 + 0.5) / SUB_ROWS as f64;
                    acc += if right { self.right_mean(x as f64, yy) } else { self.left_mean(x as f64, yy) };
                }
                ideal[y * w + x] = acc / SUB_ROWS as f64;
            }
        }
        add_noise(&ideal, w, h, rng)
    }

    fn left_mean(&self, x: f64, y: f64) -> f64 {
        let s = self.in_block(x, y).unwrap_or(&self.background);
        s.mean_over(x - 0.5, x + 0.5, y)
    }

    /// The right pixel's footprint [xr - 0.5, xr + 0.5] split where the block starts and
    /// ends, each part integrated on its own surface.
    fn right_mean(&self, xr: f64, y: f64) -> f64 {
        let (a, b) = (xr - 0.5, xr + 0.5);
        let bg = |a: f64, b: f64| {
            let p = &self.background.plane;
            self.background.mean_over(p.left_of(a, y), p.left_of(b, y), y) * (b - a)
        };
        if let Some((s, r)) = &self.block {
            if y >= r[2] && y < r[3] {
                let p = &s.plane;
                // Right columns where the block shows.
                let (s0, s1) = (r[0] - p.at(r[0], y), r[1] - p.at(r[1], y));
                let (lo, hi) = (a.max(s0), b.min(s1));
                if lo < hi {
                    let mut sum = s.mean_over(p.left_of(lo, y), p.left_of(hi, y), y) * (hi - lo);
                    if a < lo {
                        sum += bg(a, lo);
                    }
                    if hi < b {
                        sum += bg(hi, b);
                    }
                    return sum;
                }
            }
        }
        bg(a, b)
    }

    /// Disparity of each left pixel centre; +inf where the right camera cannot see it
    /// (occluded by the block) or it leaves the right image.
    fn truth(&self) -> FloatImage {
        let (w, h) = (self.width, self.height);
        let mut out = FloatImage::new(w, h, f32::INFINITY);
        for y in 0..h {
            for x in 0..w {
                let (xf, yf) = (x as f64, y as f64);
                let (d, on_block) = match self.in_block(xf, yf) {
                    Some(s) => (s.plane.at(xf, yf), true),
                    None => (self.background.plane.at(xf, yf), false),
                };
                let xr = xf - d;
                if xr < 0.0 {
                    continue;
                }
                if !on_block {
                    if let Some((s, r)) = &self.block {
                        let p = &s.plane;
                        if yf >= r[2] && yf < r[3] && xr >= r[0] - p.at(r[0], yf) && xr < r[1] - p.at(r[1], yf) {
                            continue;
                        }
                    }
                }
                out.set(x, y, d as f32);
            }
        }
        out
    }
}

/// The paper's sensor noise: uniform integer noise in [-10, 10], a 3x3 mean, round, clamp.
fn add_noise(ideal: &[f64], w: usize, h: usize, rng: &mut ChaCha8Rng) -> GrayImage {
    let noisy: Vec<f64> =
        ideal.iter().map(|&v| (v.round() + rng.random_range(-10i32..=10) as f64).clamp(0.0, 255.0)).collect();
    let mut out = GrayImage::new(w, h, 0);
    for y in 0..h {
        for x in 0..w {
            let (mut s, mut n) = (0.0, 0.0);
            for yy in y.saturating_sub(1)..(y + 2).min(h) {
                for xx in x.saturating_sub(1)..(x + 2).min(w) {
                    s += noisy[yy * w + xx];
                    n += 1.0;
                }
            }
            out.set(x, y, (s / n).round().clamp(0.0, 255.0) as u8);
        }
    }
    out
}

/// Coverage (share of truth pixels with an estimate), bad-2 rate and median absolute error
/// (over estimated truth pixels), ignoring a `margin` px border.
struct Score {
    coverage: f64,
    bad2: f64,
    median: f64,
}

/// Accuracy over the pixels with a true disparity, `margin` px inside the image, on the
/// rows a matcher with `row_step` matches.
fn score(est: &FloatImage, truth: &FloatImage, margin: usize, row_step: usize) -> Score {
    let mut errs = Vec::new();
    let mut total = 0usize;
    for y in (margin..truth.height - margin).filter(|y| y % row_step == 0) {
        for x in margin..truth.width - margin {
            let t = truth.get(x, y);
            if !t.is_finite() {
                continue;
            }
            total += 1;
            let e = est.get(x, y);
            if e.is_finite() {
                errs.push((e - t).abs());
            }
        }
    }
    errs.sort_by(f32::total_cmp);
    let n = errs.len().max(1) as f64;
    Score {
        coverage: errs.len() as f64 / total.max(1) as f64,
        bad2: errs.iter().filter(|&&e| e > 2.0).count() as f64 / n,
        median: errs.get(errs.len() / 2).copied().unwrap_or(f32::INFINITY) as f64,
    }
}

/// The slow obvious matcher: 7x7 intensity SAD, winner takes all over the whole range,
/// left-right check, parabola sub-pixel.
fn brute_force(left: &GrayImage, right: &GrayImage, range: (f32, f32)) -> FloatImage {
    let (w, h) = (left.width, left.height);
    let r = 3i64;
    let (d0, d1) = (range.0.floor() as i64, range.1.ceil() as i64);
    let cost = |a: &GrayImage, b: &GrayImage, x: i64, y: i64, xb: i64| -> Option<i64> {
        if x - r < 0 || xb - r < 0 || x + r >= w as i64 || xb + r >= w as i64 || y - r < 0 || y + r >= h as i64 {
            return None;
        }
        let mut s = 0;
        for j in -r..=r {
            for i in -r..=r {
                s += (a.get((x + i) as usize, (y + j) as usize) as i64
                    - b.get((xb + i) as usize, (y + j) as usize) as i64)
                    .abs();
            }
        }
        Some(s)
    };
    let best = |a: &GrayImage, b: &GrayImage, x: i64, y: i64, sign: i64| -> Option<(i64, [i64; 3])> {
        let costs: Vec<Option<i64>> = (d0..=d1).map(|d| cost(a, b, x, y, x + sign * d)).collect();
        let (k, c) = costs.iter().enumerate().filter_map(|(k, c)| c.map(|c| (k, c))).min_by_key(|&(_, c)| c)?;
        let side = |k: Option<usize>| k.and_then(|k| costs.get(k).copied().flatten()).unwrap_or(c);
        Some((d0 + k as i64, [side(k.checked_sub(1)), c, side(Some(k + 1))]))
    };
    let mut out = FloatImage::new(w, h, f32::INFINITY);
    for y in 0..h as i64 {
        for x in 0..w as i64 {
            let Some((d, c)) = best(left, right, x, y, -1) else { continue };
            let Some((dr, _)) = best(right, left, x - d, y, 1) else { continue };
            if (dr - d).abs() > 1 {
                continue;
            }
            let den = (c[0] - 2 * c[1] + c[2]) as f64;
            let sub = if den > 0.0 { 0.5 * (c[0] - c[2]) as f64 / den } else { 0.0 };
            out.set(x as usize, y as usize, (d as f64 + sub) as f32);
        }
    }
    out
}

fn params() -> StereoParams {
    Cell::default().stereo
}

fn slanted_plane_scene(seed: u64, base: f64, contrast: f64) -> Scene {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let plane =
        Plane { a: rng.random_range(0.03..0.08), b: rng.random_range(-0.03..0.03), c: rng.random_range(95.0..110.0) };
    Scene {
        width: 320,
        height: 240,
        background: Surface { plane, seed: rng.random(), cell: rng.random_range(1.6..2.6), base, contrast },
        block: None,
    }
}

fn box_scene(seed: u64) -> Scene {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let bg = Plane { a: 0.04, b: 0.02, c: 95.0 };
    let top = Plane { a: 0.04, b: 0.02, c: 95.0 + rng.random_range(12.0..20.0) };
    Scene {
        width: 320,
        height: 240,
        background: Surface { plane: bg, seed: rng.random(), cell: 2.2, base: 50.0, contrast: 120.0 },
        block: Some((
            Surface { plane: top, seed: rng.random(), cell: 2.0, base: 40.0, contrast: 150.0 },
            [150.5, 250.5, 70.5, 170.5],
        )),
    }
}

/// The row steps every accuracy test runs at: every row, and the default.
const ROW_STEPS: [u32; 2] = [1, 2];

fn run(scene: &Scene, seed: u64, range: (f32, f32), row_step: u32) -> (FloatImage, FloatImage, GrayImage, GrayImage) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let left = scene.render(false, &mut rng);
    let right = scene.render(true, &mut rng);
    let mut elas = Elas::new(&StereoParams { row_step, ..params() }, scene.width, scene.height, 128);
    let mut out = FloatImage::default();
    elas.compute(&left, &right, range, &mut out).unwrap();
    // The rows between the matched ones hold nothing.
    for (y, row) in out.data.chunks_exact(scene.width).enumerate() {
        if y % row_step as usize != 0 {
            assert!(row.iter().all(|d| *d == INVALID), "row {y} of a map with row step {row_step}");
        }
    }
    (out, scene.truth(), left, right)
}

#[test]
fn slanted_plane_bright_texture() {
    for (seed, row_step) in (0..3).flat_map(|seed| ROW_STEPS.map(|r| (seed, r))) {
        let scene = slanted_plane_scene(seed, 60.0, 140.0);
        let (est, truth, _, _) = run(&scene, 100 + seed, (80.0, 150.0), row_step);
        let s = score(&est, &truth, 8, row_step as usize);
        eprintln!(
            "bright plane {seed}/{row_step}: coverage {:.4} bad2 {:.5} median {:.4}",
            s.coverage, s.bad2, s.median
        );
        assert!(s.coverage > 0.95, "coverage {}", s.coverage);
        assert!(s.bad2 < 0.002, "bad-2 {}", s.bad2);
        assert!(s.median < 0.1, "median {}", s.median);
    }
}

#[test]
fn slanted_plane_dark_texture() {
    // The dark items: albedo 0.08 under the projector leaves a contrast of about 15 grey
    // levels against noise of +-10.
    for (seed, row_step) in (0..2).flat_map(|seed| ROW_STEPS.map(|r| (seed, r))) {
        let scene = slanted_plane_scene(10 + seed, 8.0, 16.0);
        let (est, truth, _, _) = run(&scene, 200 + seed, (80.0, 150.0), row_step);
        let s = score(&est, &truth, 8, row_step as usize);
        eprintln!("dark plane {seed}/{row_step}: coverage {:.4} bad2 {:.5} median {:.4}", s.coverage, s.bad2, s.median);
        assert!(s.coverage > 0.85, "coverage {}", s.coverage);
        assert!(s.bad2 < 0.015, "bad-2 {}", s.bad2);
        assert!(s.median < 0.4, "median {}", s.median);
    }
}

#[test]
fn box_on_plane_against_brute_force() {
    for row_step in ROW_STEPS {
        box_on_plane_against_brute_force_at(row_step);
    }
}

fn box_on_plane_against_brute_force_at(row_step: u32) {
    let scene = box_scene(4);
    let range = (85.0, 135.0);
    let (est, truth, left, right) = run(&scene, 300, range, row_step);
    let step = row_step as usize;
    let s = score(&est, &truth, 8, step);
    let reference = brute_force(&left, &right, range);
    let r = score(&reference, &truth, 8, step);
    eprintln!("box elas {row_step}: coverage {:.4} bad2 {:.5} median {:.4}", s.coverage, s.bad2, s.median);
    eprintln!("box brute force: coverage {:.4} bad2 {:.5} median {:.4}", r.coverage, r.bad2, r.median);
    assert!(s.coverage > 0.93, "coverage {}", s.coverage);
    assert!(s.bad2 < 0.01, "bad-2 {}", s.bad2);
    assert!(s.median < 0.1, "median {}", s.median);
    // The prior must not cost accuracy against exhaustive search.
    assert!(s.bad2 <= r.bad2 + 0.005, "elas bad-2 {} vs brute force {}", s.bad2, r.bad2);
    assert!(s.median <= r.median, "elas median {} vs brute force {}", s.median, r.median);
    // The box's top is found as the box, edges included.
    let mut on_top = 0;
    let mut right_top = 0;
    for y in (75..166).filter(|y| y % step == 0) {
        for x in 155..246 {
            on_top += 1;
            let (e, t) = (est.get(x, y), truth.get(x, y));
            if e.is_finite() && (e - t).abs() < 1.0 {
                right_top += 1;
            }
        }
    }
    assert!(right_top as f64 > 0.95 * on_top as f64, "{right_top} of {on_top} box pixels");
}

#[test]
fn rejects_wrong_sizes_and_ranges() {
    let mut elas = Elas::new(&params(), 64, 48, 32);
    let img = GrayImage::new(64, 48, 0);
    let small = GrayImage::new(32, 48, 0);
    let mut out = FloatImage::default();
    assert!(elas.compute(&img, &small, (0.0, 10.0), &mut out).is_err());
    assert!(elas.compute(&img, &img, (0.0, 100.0), &mut out).is_err());
    assert!(elas.compute(&img, &img, (10.0, f32::NAN), &mut out).is_err());
    // A flat pair has no texture: nothing is matched, nothing fails.
    elas.compute(&img, &img, (0.0, 20.0), &mut out).unwrap();
    assert!(out.data.iter().all(|d| d.is_infinite()));
}

/// Every dense-matching kernel this machine runs, the scalar one first.
fn kernels() -> Vec<Kernel> {
    let vector = Avx2::detect().map(Kernel::Avx2).into_iter().chain(Avx512::detect().map(Kernel::Avx512));
    std::iter::once(Kernel::Scalar).chain(vector).collect()
}

/// The map of `left` and `right` by a matcher for spans up to 128 px with `kernel`, as bits.
fn map_bits(p: &StereoParams, kernel: Kernel, left: &GrayImage, right: &GrayImage, range: (f32, f32)) -> Vec<u32> {
    let mut elas = Elas::new(p, left.width, left.height, 128);
    elas.set_kernel(kernel);
    let mut out = FloatImage::default();
    elas.compute(left, right, range, &mut out).unwrap();
    assert_eq!((out.width, out.height), (left.width, left.height));
    out.data.iter().map(|d| d.to_bits()).collect()
}

#[test]
fn every_kernel_gives_the_same_map() {
    let scene = box_scene(5);
    let mut rng = ChaCha8Rng::seed_from_u64(400);
    let (left, right) = (scene.render(false, &mut rng), scene.render(true, &mut rng));
    for row_step in ROW_STEPS {
        let p = StereoParams { row_step, ..params() };
        let maps: Vec<Vec<u32>> =
            kernels().into_iter().map(|k| map_bits(&p, k, &left, &right, (85.0, 135.0))).collect();
        assert!(maps.iter().all(|m| *m == maps[0]), "{} kernels differ at row step {row_step}", maps.len());
        let matched = maps[0].iter().filter(|&&d| f32::from_bits(d).is_finite()).count();
        assert!(matched > left.data.len() / 2 / row_step as usize, "{matched} matched at row step {row_step}");
    }
}

#[test]
fn tiny_images_match_nothing_in_every_kernel() {
    // Images narrower than a descriptor window on both sides of a pixel (2 BORDER + 1 px),
    // down to none, and too low for one or just high enough for a row or two: the whole
    // path (descriptors, support points, prior, dense matching of both images, the checks
    // and the post-processing) returns a map of their size without a panic, the same in
    // every kernel. No pixel is a support point, so nothing is matched, even without a
    // texture threshold and with ranges that start below 0 or beyond the image.
    let mut rng = ChaCha8Rng::seed_from_u64(41);
    for w in 0..=8 {
        for h in (0..=4).chain([11, 12, 13]) {
            let mut image = || {
                let pixels = (0..w * h).map(|_| rng.random_range(0..=255u8)).collect();
                GrayImage::from_vec(w, h, pixels).unwrap()
            };
            let (left, right) = (image(), image());
            for min_texture in [params().min_texture, 0] {
                let p = StereoParams { min_texture, ..params() };
                for range in [(0.0, 4.0), (-6.0, 3.0), (2.5, 9.0), (40.0, 50.0), (0.0, 0.0)] {
                    for kernel in kernels() {
                        let map = map_bits(&p, kernel, &left, &right, range);
                        assert!(map.iter().all(|&d| d == f32::INFINITY.to_bits()), "{w}x{h} {range:?} {kernel:?}");
                    }
                }
            }
        }
    }
}

#[test]
fn a_range_below_zero_is_searched_from_zero() {
    // Disparities below 0 cannot occur on a rectified pair: the search starts at 0, and
    // the map is that of the range clipped there, in every kernel.
    let scene = box_scene(6);
    let mut rng = ChaCha8Rng::seed_from_u64(500);
    let (left, right) = (scene.render(false, &mut rng), scene.render(true, &mut rng));
    for kernel in kernels() {
        let clipped = map_bits(&params(), kernel, &left, &right, (0.0, 120.0));
        assert_eq!(map_bits(&params(), kernel, &left, &right, (-8.0, 120.0)), clipped, "{kernel:?}");
        assert_eq!(map_bits(&params(), kernel, &left, &right, (-0.5, 120.0)), clipped, "{kernel:?}");
    }
}

/// Matching in a region (the box around the block, as the foreground would give it):
/// nothing outside it, and inside it the block and the plane around it as the whole-image
/// map has them, against the truth with the same accuracy.
#[test]
fn a_region_is_matched_as_the_whole_image_is_there() {
    for row_step in ROW_STEPS {
        let scene = box_scene(4);
        let range = (85.0, 135.0);
        let (whole, truth, left, right) = run(&scene, 300, range, row_step);
        let region = crate::depth::PixelRegion { x0: 126, x1: 275, y0: 46, y1: 195 };
        let mut elas = Elas::new(&StereoParams { row_step, ..params() }, scene.width, scene.height, 128);
        let mut part = FloatImage::default();
        elas.compute_in(&left, &right, range, region, &mut part).unwrap();
        let (mut inside, mut agree, mut right_part, mut right_whole) = (0, 0, 0, 0);
        for y in 0..scene.height {
            for x in 0..scene.width {
                let (p, q, t) = (part.get(x, y), whole.get(x, y), truth.get(x, y));
                if !region.contains(x, y) {
                    assert_eq!(p, INVALID, "({x}, {y}) outside the region matched");
                    continue;
                }
                if !q.is_finite() {
                    continue;
                }
                inside += 1;
                agree += usize::from(p.is_finite() && (p - q).abs() <= 0.5);
                right_part += usize::from(p.is_finite() && (p - t).abs() < 1.0);
                right_whole += usize::from((q - t).abs() < 1.0);
            }
        }
        eprintln!("row step {row_step}: {agree} of {inside} pixels agree, right {right_part} against {right_whole}");
        assert!(inside > 5000, "{inside} pixels matched in the region");
        assert!(agree as f64 >= 0.97 * inside as f64, "{agree} of {inside} agree");
        assert!(right_part as f64 >= 0.99 * right_whole as f64, "right {right_part} against {right_whole}");
    }
}
