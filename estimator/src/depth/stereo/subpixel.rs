//! Sub-pixel refinement of integer disparities: Gauss-Newton on the sum of squared
//! intensity differences over a small window, with the right image sampled linearly.
//! Runs of pixels whose integer disparities differ by at most one (most of a smooth
//! surface) are refined [`LANES`] at a time with contiguous loads (one AVX-512 register a
//! value, two with AVX2); the rest one by one, with the same arithmetic in the same order,
//! so both paths give the same bits.

use rayon::prelude::*;

use crate::GrayImage;

/// Gauss-Newton steps (the second removes the bias of the first on curved cost).
const STEPS: usize = 2;
/// Pixels refined together when their integer disparities differ by at most one.
const LANES: usize = 16;
/// Below this summed squared gradient the window has no texture to refine on.
const MIN_GRADIENT: f32 = 1e-3;

/// The f32 words of working memory per pixel the refinement takes: float copies of a
/// rectified pair and their horizontal gradients. The refinement reads every pixel
/// ~2 (2 r + 1)^2 times, so converting and differencing once per frame halves its
/// arithmetic.
pub const WORDS_PER_PIXEL: usize = 4;

/// Intensities as f32 and half the central difference along the row (0 at the row ends).
fn float_planes(img: &GrayImage, rows: (usize, usize), value: &mut [f32], grad: &mut [f32]) {
    let w = img.width;
    if w == 0 {
        return;
    }
    value.par_chunks_mut(w).zip(grad.par_chunks_mut(w)).enumerate().for_each(|(y, (v, g))| {
        if (rows.0..rows.1).contains(&y) {
            float_row(img.row(y), v, g);
        }
    });
}

multiversion! {
    /// One row of [`float_planes`].
    fn float_row(src: &[u8], value: &mut [f32], grad: &mut [f32]) => float_row_body
}

#[inline(always)]
fn float_row_body(src: &[u8], value: &mut [f32], grad: &mut [f32]) {
    for (o, &p) in value.iter_mut().zip(src) {
        *o = p as f32;
    }
    grad.fill(0.0);
    let w = src.len().min(grad.len());
    for x in 1..w.saturating_sub(1) {
        grad[x] = 0.5 * (src[x + 1] as f32 - src[x - 1] as f32);
    }
}

/// The four planes of `n` pixels in `scratch` (at least [`WORDS_PER_PIXEL`] x `n` words;
/// whatever they hold is overwritten where read).
fn split_planes(scratch: &mut [f32], n: usize) -> [&mut [f32]; 4] {
    let (left, right) = scratch[..WORDS_PER_PIXEL * n].split_at_mut(2 * n);
    let (lf, lg) = left.split_at_mut(n);
    let (rf, rg) = right.split_at_mut(n);
    [lf, lg, rf, rg]
}

/// The four planes and the window they are read through.
#[derive(Clone, Copy)]
struct Planes<'a> {
    lf: &'a [f32],
    lg: &'a [f32],
    rf: &'a [f32],
    rg: &'a [f32],
    width: usize,
    radius: usize,
}

/// Refines integer disparities to sub-pixel ones by Gauss-Newton on the sum of squared
/// intensity differences over a (2 `radius` + 1)^2 window: the right image is sampled
/// linearly at x - d and the gradient is the mean of both images' central differences.
/// Unlike a parabola through three SAD costs this has no pull towards integers. Pixels whose
/// window leaves the image, that lack gradient, whose first step reaches one pixel (the cost
/// is not locally quadratic there) or whose result moves more than one pixel keep their
/// integer disparity.
///
/// `disp` holds every `row_step`-th row of the images from row 0 (all of them at 1), as
/// dense matching with a row step leaves them. `scratch` is working memory of
/// [`WORDS_PER_PIXEL`] words a pixel.
pub fn refine_subpixel(
    left: &GrayImage,
    right: &GrayImage,
    disp: &mut [f32],
    row_step: usize,
    radius: usize,
    rows: (usize, usize),
    scratch: &mut [f32],
) {
    let (w, h) = (left.width, left.height);
    let planes = (rows.0.saturating_sub(radius), rows.1.saturating_add(radius + 1).min(h));
    let [lf, lg, rf, rg] = split_planes(scratch, w * h);
    float_planes(left, planes, lf, lg);
    float_planes(right, planes, rf, rg);
    let p = Planes { lf, lg, rf, rg, width: w, radius };
    let (x_lo, x_hi) = (radius + 1, w.saturating_sub(radius + 1));
    disp.par_chunks_mut(w).enumerate().for_each(|(j, row)| {
        let y = j * row_step;
        if y < radius || y + radius >= h || x_lo >= x_hi || !(rows.0..rows.1).contains(&y) {
            return;
        }
        refine_row_best(&p, y, row, x_lo, x_hi);
    });
}

multiversion! {
    /// [`refine_row`] with the widest registers this machine has.
    fn refine_row_best(p: &Planes<'_>, y: usize, row: &mut [f32], x_lo: usize, x_hi: usize) => refine_row
}

/// Refines columns `x_lo .. x_hi` of row `y`: groups of [`LANES`] pixels together where
/// they allow it, the rest one by one.
#[inline(always)]
fn refine_row(p: &Planes<'_>, y: usize, row: &mut [f32], x_lo: usize, x_hi: usize) {
    let mut x = x_lo;
    while x < x_hi {
        if x + LANES <= x_hi {
            let group: &mut [f32; LANES] = (&mut row[x..x + LANES]).try_into().expect("LANES pixels");
            if let Some(d0) = group_disparity(group) {
                if fits(p, x, d0) {
                    refine_lanes(p, x, y, d0, group);
                    x += LANES;
                    continue;
                }
            }
            for (i, out) in group.iter_mut().enumerate() {
                *out = refine_pixel(p, x + i, y, *out);
            }
            x += LANES;
            continue;
        }
        row[x] = refine_pixel(p, x, y, row[x]);
        x += 1;
    }
}

/// The smaller integer disparity D of a group whose valid pixels all hold D or D + 1 (a
/// surface slanted by up to one pixel of disparity over the group), when most of the group
/// is valid.
#[inline]
fn group_disparity(group: &[f32; LANES]) -> Option<usize> {
    let mut valid = 0;
    let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
    for &d in group {
        if d.is_finite() {
            valid += 1;
            lo = lo.min(d);
            hi = hi.max(d);
            if d.fract() != 0.0 {
                return None;
            }
        }
    }
    (valid > LANES / 2 && lo >= 0.0 && hi - lo <= 1.0).then_some(lo as usize)
}

/// Whether every right column either step may read, for every pixel of the group starting
/// at `x` with integer disparity D or D + 1, lies where [`refine_pixel`] would read it too.
#[inline]
fn fits(p: &Planes<'_>, x: usize, d: usize) -> bool {
    let r = p.radius;
    x >= r + d + 3 && x + LANES - 1 + r + 3 <= p.width + d
}

/// One pixel: its disparity after refinement (unchanged if it cannot be refined).
#[inline(always)]
fn refine_pixel(p: &Planes<'_>, x: usize, y: usize, d0: f32) -> f32 {
    if !d0.is_finite() {
        return d0;
    }
    let (w, radius) = (p.width, p.radius);
    let r = radius as isize;
    let n = 2 * radius + 1;
    let mut s = d0;
    for step in 0..STEPS {
        // Right samples at x + i - s: one integer offset and one fraction for the whole
        // window, since the window shares the disparity.
        let k0 = (-s).floor();
        let f = -s - k0;
        // Columns c - 1 ..= c + 2 of the right image must exist for every c.
        let start = x as isize - r + k0 as isize - 1;
        if start < 0 || start as usize + n + 3 > w {
            return d0;
        }
        let c0 = start as usize + 1;
        let (mut eg, mut gg) = (0.0f32, 0.0f32);
        for yy in y - radius..=y + radius {
            let o = yy * w;
            let (ls, lgs) = (&p.lf[o + x - radius..o + x + radius + 1], &p.lg[o + x - radius..o + x + radius + 1]);
            let (rs, rgs) = (&p.rf[o + c0..o + c0 + n + 1], &p.rg[o + c0..o + c0 + n + 1]);
            for i in 0..n {
                let rval = rs[i] + f * (rs[i + 1] - rs[i]);
                let gr = rgs[i] + f * (rgs[i + 1] - rgs[i]);
                let g = 0.5 * (lgs[i] + gr);
                let e = ls[i] - rval;
                eg += e * g;
                gg += g * g;
            }
        }
        if gg < MIN_GRADIENT {
            return d0;
        }
        s -= eg / gg;
        if step == 0 && (s - d0).abs() >= 1.0 {
            return d0;
        }
    }
    if (s - d0).abs() <= 1.0 {
        s
    } else {
        d0
    }
}

/// [`LANES`] neighbouring pixels with integer disparity `d` or `d + 1`: the arithmetic of
/// [`refine_pixel`] lane by lane. Every lane reads the right image at a fixed offset from
/// c = x - d (columns c - 2 ..= c + 1), chosen per lane, so all loads are contiguous.
#[inline(always)]
fn refine_lanes(p: &Planes<'_>, x: usize, y: usize, d: usize, out: &mut [f32; LANES]) {
    let (w, radius) = (p.width, p.radius);
    let n = 2 * radius + 1;
    // Per lane: its integer disparity and whether it is d + 1 (reads one column further left).
    let mut d0 = [d as f32; LANES];
    let mut far = [0u32; LANES];
    for l in 0..LANES {
        if out[l].is_finite() {
            d0[l] = out[l];
            far[l] = mask(out[l] != d as f32);
        }
    }
    // Step 1 at s = d0: the fraction is 0, so the samples are the columns themselves.
    let (mut eg, mut gg) = ([0.0f32; LANES], [0.0f32; LANES]);
    for yy in y - radius..=y + radius {
        let o = yy * w;
        for i in 0..n {
            let lc = o + x - radius + i;
            let rc = lc - d;
            let (ls, lgs) = (lanes(p.lf, lc), lanes(p.lg, lc));
            let (r0, r1) = (lanes(p.rf, rc), lanes(p.rf, rc - 1));
            let (g0, g1) = (lanes(p.rg, rc), lanes(p.rg, rc - 1));
            for l in 0..LANES {
                let (rval, gr) = (select(far[l], r1[l], r0[l]), select(far[l], g1[l], g0[l]));
                let g = 0.5 * (lgs[l] + gr);
                let e = ls[l] - rval;
                eg[l] += e * g;
                gg[l] += g * g;
            }
        }
    }
    let mut s1 = [0.0f32; LANES];
    let mut ok = [false; LANES];
    // Per lane: the fraction, and whether it interpolates from its column towards the next
    // (k0 = -d0) or from the previous column.
    let mut frac = [0.0f32; LANES];
    let mut upper = [0u32; LANES];
    for l in 0..LANES {
        s1[l] = d0[l] - eg[l] / gg[l];
        ok[l] = gg[l] >= MIN_GRADIENT && (s1[l] - d0[l]).abs() < 1.0;
        if ok[l] {
            let k0 = (-s1[l]).floor();
            frac[l] = -s1[l] - k0;
            upper[l] = mask(k0 == -d0[l]);
        }
    }
    let (mut eg, mut gg) = ([0.0f32; LANES], [0.0f32; LANES]);
    for yy in y - radius..=y + radius {
        let o = yy * w;
        for i in 0..n {
            let lc = o + x - radius + i;
            let rc = lc - d;
            let (ls, lgs) = (lanes(p.lf, lc), lanes(p.lg, lc));
            let (rm2, rm1, r0, r1) = (lanes(p.rf, rc - 2), lanes(p.rf, rc - 1), lanes(p.rf, rc), lanes(p.rf, rc + 1));
            let (gm2, gm1, g0, g1) = (lanes(p.rg, rc - 2), lanes(p.rg, rc - 1), lanes(p.rg, rc), lanes(p.rg, rc + 1));
            for l in 0..LANES {
                // The lane's columns c - 1, c, c + 1 for its own c = x - d0.
                let (lo, mid, hi) =
                    (select(far[l], rm2[l], rm1[l]), select(far[l], rm1[l], r0[l]), select(far[l], r0[l], r1[l]));
                let (glo, gmid, ghi) =
                    (select(far[l], gm2[l], gm1[l]), select(far[l], gm1[l], g0[l]), select(far[l], g0[l], g1[l]));
                let (a, b) = (select(upper[l], mid, lo), select(upper[l], hi, mid));
                let (ga, gb) = (select(upper[l], gmid, glo), select(upper[l], ghi, gmid));
                let f = frac[l];
                let rval = a + f * (b - a);
                let gr = ga + f * (gb - ga);
                let g = 0.5 * (lgs[l] + gr);
                let e = ls[l] - rval;
                eg[l] += e * g;
                gg[l] += g * g;
            }
        }
    }
    for l in 0..LANES {
        if !out[l].is_finite() || !ok[l] || gg[l] < MIN_GRADIENT {
            continue;
        }
        let s2 = s1[l] - eg[l] / gg[l];
        if (s2 - d0[l]).abs() <= 1.0 {
            out[l] = s2;
        }
    }
}

/// All ones for `true`, zero for `false`: a lane mask [`select`] reads.
#[inline(always)]
fn mask(b: bool) -> u32 {
    (b as u32).wrapping_neg()
}

/// `a` where `m` is set, else `b`: bitwise, so the lanes vectorise without branches.
#[inline(always)]
fn select(m: u32, a: f32, b: f32) -> f32 {
    f32::from_bits((m & a.to_bits()) | (!m & b.to_bits()))
}

/// The [`LANES`] values from `at` on.
#[inline(always)]
fn lanes(plane: &[f32], at: usize) -> &[f32; LANES] {
    plane[at..at + LANES].try_into().expect("LANES values")
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A smooth random texture, and the pair it gives at a constant disparity `shift`.
    fn shifted_pair(seed: u64, w: usize, h: usize, shift: f32) -> (GrayImage, GrayImage) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let freqs: Vec<(f32, f32, f32)> = (0..6)
            .map(|_| (rng.random_range(0.2..0.9), rng.random_range(0.0..6.0), rng.random_range(10.0..30.0)))
            .collect();
        let tex = |x: f32, y: f32| {
            let v: f32 = freqs.iter().map(|&(f, p, a)| a * (f * x + p + 0.3 * f * y).sin()).sum();
            (128.0 + v).clamp(0.0, 255.0)
        };
        let img = |dx: f32| {
            GrayImage::from_vec(
                w,
                h,
                (0..w * h).map(|i| tex((i % w) as f32 + dx, (i / w) as f32).round() as u8).collect(),
            )
            .unwrap()
        };
        (img(0.0), img(shift))
    }

    #[test]
    fn subpixel_recovers_a_fractional_shift() {
        let (w, h) = (64, 16);
        let shift = 7.3f32;
        let (left, right) = shifted_pair(11, w, h, shift);
        let mut d = vec![7.0f32; w * h];
        refine_subpixel(&left, &right, &mut d, 1, 2, (0, usize::MAX), &mut vec![0.0; WORDS_PER_PIXEL * w * h]);
        let mut errs: Vec<f32> = (4..h - 4)
            .flat_map(|y| (14..w - 6).map(move |x| (y, x)))
            .map(|(y, x)| (d[y * w + x] - shift).abs())
            .collect();
        errs.sort_by(f32::total_cmp);
        assert!(errs[errs.len() / 2] < 0.05, "median error {}", errs[errs.len() / 2]);
    }

    #[test]
    fn lanes_give_the_bits_of_one_pixel_at_a_time() {
        // Integer disparities in runs (some shared by a whole group, some not), with holes,
        // on noisy random texture: the grouped path must equal the per-pixel one exactly.
        let (w, h) = (97, 23);
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let noisy = |rng: &mut ChaCha8Rng| {
            GrayImage::from_vec(w, h, (0..w * h).map(|_| rng.random_range(0..=255u8)).collect()).unwrap()
        };
        for radius in [1, 2, 3] {
            let (left, right) = shifted_pair(radius as u64, w, h, 5.6);
            for (l, r) in [(left, right), (noisy(&mut rng), noisy(&mut rng))] {
                let mut d = vec![f32::INFINITY; w * h];
                for y in 0..h {
                    let mut x = 0;
                    while x < w {
                        let run = rng.random_range(1..20usize).min(w - x);
                        let v = if rng.random_range(0..6) == 0 { f32::INFINITY } else { rng.random_range(4..8) as f32 };
                        d[y * w + x..y * w + x + run].fill(v);
                        x += run;
                    }
                }
                let mut scratch = vec![0.0; WORDS_PER_PIXEL * w * h];
                let [lf, lg, rf, rg] = split_planes(&mut scratch, w * h);
                float_planes(&l, (0, usize::MAX), lf, lg);
                float_planes(&r, (0, usize::MAX), rf, rg);
                let p = Planes { lf, lg, rf, rg, width: w, radius };
                let slow: Vec<f32> = (0..w * h)
                    .map(|i| {
                        let (x, y) = (i % w, i / w);
                        if y < radius || y + radius >= h || x < radius + 1 || x + radius + 1 >= w {
                            d[i]
                        } else {
                            refine_pixel(&p, x, y, d[i])
                        }
                    })
                    .collect();
                let mut fast = d.clone();
                refine_subpixel(&l, &r, &mut fast, 1, radius, (0, usize::MAX), &mut vec![0.0; WORDS_PER_PIXEL * w * h]);
                let refined = slow.iter().zip(&d).filter(|(s, d)| s.is_finite() && s != d).count();
                assert!(refined > w * h / 4, "only {refined} pixels refined");
                for i in 0..w * h {
                    assert_eq!(fast[i].to_bits(), slow[i].to_bits(), "pixel {i}: {} vs {}", fast[i], slow[i]);
                }
                // Every row_step-th row alone, as dense matching with a row step leaves
                // them: each refined as in the whole map.
                for row_step in [2, 3] {
                    let mut rows: Vec<f32> = d.chunks_exact(w).step_by(row_step).flatten().copied().collect();
                    refine_subpixel(
                        &l,
                        &r,
                        &mut rows,
                        row_step,
                        radius,
                        (0, usize::MAX),
                        &mut vec![0.0; WORDS_PER_PIXEL * w * h],
                    );
                    for (j, row) in rows.chunks_exact(w).enumerate() {
                        let y = j * row_step;
                        for (x, v) in row.iter().enumerate() {
                            assert_eq!(v.to_bits(), slow[y * w + x].to_bits(), "row {y} / {row_step}, column {x}");
                        }
                    }
                }
            }
        }
    }
}
