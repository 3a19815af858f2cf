//! The 12-shot structured-light decoder: 4-step phase per fringe frequency, modulation and
//! saturation mask, hierarchical temporal unwrapping, and matching of equal absolute phase
//! along rectified rows with a left-right check. It works on rectified images only;
//! rectifying the raw shots is the caller's step.
//!
//! The projector shows `I_k = A + B cos(phi - k pi/2)`, `phi = 2 pi f x_p / W_proj`, for each
//! period count `f` (coarse to fine) and step `k = 0..3`, shots ordered frequency-major
//! (index `4 * fi + k`). The decoded absolute phase is stored as the projector coordinate
//! `x_p / W_proj` (a fraction of the projector width), NaN where a pixel is masked: where
//! the modulation `B = sqrt((I0 - I2)^2 + (I1 - I3)^2) / 2` of any frequency is below
//! `min_modulation`, or where any shot is clipped at 255.
//!
//! Matching looks up, per rectified row, the segments between neighbouring pixels whose
//! phase interval holds the wanted phase (a bin index built once per row), interpolates
//! linearly inside the segment, refuses a phase found at places more than a pixel apart,
//! and keeps a match only when matching back from the right image lands within
//! `lr_tolerance`. Pixels on a depth edge, where the camera blur mixes two surfaces'
//! fringes, can still match wrongly; the later stages must tolerate a few such points.

use camplace_config::PhaseParams;
use rayon::prelude::*;
use std::f32::consts::{FRAC_PI_2, PI, TAU};

use crate::{Error, ErrorKind, FloatImage, GrayImage, Result};

/// Rows handled by one parallel work item; each band owns its scratch, so the output does
/// not depend on how rayon schedules the bands.
const BAND_ROWS: usize = 16;

/// Phase bins of the per-row lookup index, per image column. Two bins per column keep the
/// few segments that cover one bin short lists at the usual projector/camera ratio (about
/// two projector pixels per camera pixel).
const BINS_PER_COLUMN: usize = 2;

/// A neighbouring pair of pixels whose phase differs by more than this many bins is taken to
/// straddle a depth edge and is never interpolated across (about seven times the phase slope
/// of a surface facing both projector and camera at the default sensor).
const MAX_STEP_BINS: usize = 16;

/// A grey level at which a shot is clipped: the sinusoid is cut off there and its phase is
/// wrong, so a pixel reaching it in any shot is masked.
const SATURATED: u8 = u8::MAX;

/// Scratch of one band of rows: the phase index of one row and the other side's disparities.
#[derive(Debug, Clone)]
struct BandScratch {
    index: PhaseIndex,
    /// Disparity found from the right image's side, per right column.
    right_disparity: Vec<f32>,
}

/// The segments of one row (neighbouring valid pixels rising the matched way, no larger
/// than a depth-edge step) listed by the phase bins their interval covers: bin `b` lists
/// its segments in `entries[bin_start[b]..bin_start[b + 1]]` for `b` in `lo..=hi`.
#[derive(Debug, Clone)]
struct PhaseIndex {
    bin_start: Vec<u32>,
    /// First column of every listed segment.
    entries: Vec<u16>,
    /// Bins `[first, last]` of the segment starting at each column; `first > last` when
    /// that segment is not matchable.
    segments: Vec<[u32; 2]>,
    lo: usize,
    hi: usize,
}

impl PhaseIndex {
    fn new(width: usize, bins: usize) -> Self {
        PhaseIndex {
            bin_start: vec![0; bins + 2],
            entries: vec![0; width * (MAX_STEP_BINS + 2)],
            segments: vec![[1, 0]; width],
            lo: 1,
            hi: 0,
        }
    }

    /// Indexes `row`; only the bins the row's segments reach are touched.
    fn build(&mut self, m: &RowMatcher, row: &[f32]) {
        let (mut lo, mut hi) = (usize::MAX, 0);
        for (seg, pair) in self.segments.iter_mut().zip(row.windows(2)) {
            *seg = match m.segment_bins(pair) {
                Some((b0, b1)) => {
                    lo = lo.min(b0);
                    hi = hi.max(b1);
                    [b0 as u32, b1 as u32]
                }
                None => [1, 0],
            };
        }
        self.lo = lo;
        self.hi = hi;
        if lo > hi {
            return;
        }
        let segments = &self.segments[..row.len().saturating_sub(1)];
        let starts = &mut self.bin_start[lo..=hi + 1];
        starts.fill(0);
        for &[b0, b1] in segments {
            if b0 <= b1 {
                for c in &mut starts[b0 as usize - lo + 1..=b1 as usize - lo + 1] {
                    *c += 1;
                }
            }
        }
        for b in 0..starts.len() - 1 {
            starts[b + 1] += starts[b];
        }
        // Fill with starts[b] as bin b's cursor, then shift the cursors (now each bin's
        // end) back into starts.
        for (i, &[b0, b1]) in segments.iter().enumerate() {
            for b in b0 as usize..=b1 as usize {
                let c = &mut starts[b - lo];
                self.entries[*c as usize] = i as u16;
                *c += 1;
            }
        }
        for b in (1..starts.len()).rev() {
            starts[b] = starts[b - 1];
        }
        starts[0] = 0;
    }

    /// Columns of the segments that may hold phases of bin `b`.
    #[inline]
    fn candidates(&self, b: usize) -> &[u16] {
        if b < self.lo || b > self.hi {
            return &[];
        }
        let k = b - self.lo;
        &self.entries[self.bin_start[self.lo + k] as usize..self.bin_start[self.lo + k + 1] as usize]
    }
}

/// The 12-shot decoder: every buffer is allocated by [`PhaseDecoder::new`].
#[derive(Debug, Clone)]
pub struct PhaseDecoder {
    width: usize,
    height: usize,
    /// Fringe period counts across the projector width, coarse to fine.
    periods: Vec<f32>,
    /// Squared `2 * min_modulation`, compared against `(I0-I2)^2 + (I1-I3)^2`.
    min_modulation_sq4: i32,
    lr_tolerance: f32,
    bins: usize,
    left_phase: FloatImage,
    right_phase: FloatImage,
    bands: Vec<BandScratch>,
}

impl PhaseDecoder {
    /// A decoder for `width` x `height` rectified images and `periods` (the cell's
    /// `sensor.fringe_periods`: counts across the projector width, coarse to fine; the
    /// first should be 1 for a unique absolute phase).
    pub fn new(params: &PhaseParams, periods: &[f64], width: usize, height: usize) -> Result<Self> {
        if periods.is_empty() || periods.iter().any(|p| !(p.is_finite() && *p >= 1.0)) {
            return Err(Error::new(ErrorKind::Input, "fringe periods: expected one or more period counts >= 1"));
        }
        if periods.windows(2).any(|w| w[1] <= w[0]) {
            return Err(Error::new(ErrorKind::Input, "fringe periods: expected increasing period counts"));
        }
        let usable = |v: f64| v.is_finite() && v >= 0.0;
        if !usable(params.min_modulation) || !usable(params.lr_tolerance) {
            return Err(Error::new(ErrorKind::Input, "phase: expected min_modulation and lr_tolerance >= 0"));
        }
        if width == 0 || height == 0 || width > u16::MAX as usize {
            return Err(Error::new(ErrorKind::Input, format!("phase: unusable image size {width} x {height}")));
        }
        let bins = BINS_PER_COLUMN * width;
        let band_count = height.div_ceil(BAND_ROWS);
        let scratch = BandScratch { index: PhaseIndex::new(width, bins), right_disparity: vec![f32::INFINITY; width] };
        let m2 = 2.0 * params.min_modulation;
        Ok(PhaseDecoder {
            width,
            height,
            periods: periods.iter().map(|&p| p as f32).collect(),
            min_modulation_sq4: (m2 * m2).ceil().min(i32::MAX as f64) as i32,
            lr_tolerance: params.lr_tolerance as f32,
            bins,
            left_phase: FloatImage::new(width, height, f32::NAN),
            right_phase: FloatImage::new(width, height, f32::NAN),
            bands: vec![scratch; band_count],
        })
    }

    /// Number of shots per camera that [`PhaseDecoder::decode`] expects.
    pub fn shot_count(&self) -> usize {
        4 * self.periods.len()
    }

    /// The rectified-left absolute phase of the last decode, as a fraction of the projector
    /// width; NaN where masked (low modulation or saturated).
    pub fn left_phase(&self) -> &FloatImage {
        &self.left_phase
    }

    /// The rectified-right absolute phase of the last decode, as for [`Self::left_phase`].
    pub fn right_phase(&self) -> &FloatImage {
        &self.right_phase
    }

    /// Decodes the rectified `left` and `right` shots (frequency-major, `4 * fi + k`) and
    /// writes the rectified-left disparity `x_left - x_right` into `out` (+inf where no
    /// consistent match lies within `range` = (min, max) disparity, px).
    pub fn decode(
        &mut self,
        left: &[GrayImage],
        right: &[GrayImage],
        range: (f32, f32),
        out: &mut FloatImage,
    ) -> Result<()> {
        let n = self.shot_count();
        if left.len() != n || right.len() != n {
            return Err(Error::new(
                ErrorKind::Input,
                format!("phase: expected {n} left and {n} right shots, got {} and {}", left.len(), right.len()),
            ));
        }
        if let Some(bad) = left.iter().chain(right).find(|im| im.width != self.width || im.height != self.height) {
            return Err(Error::new(
                ErrorKind::Input,
                format!(
                    "phase: expected {} x {} shots, got one of {} x {}",
                    self.width, self.height, bad.width, bad.height
                ),
            ));
        }
        let (d_min, d_max) = range;
        if !(d_min.is_finite() && d_max.is_finite() && d_min <= d_max) {
            return Err(Error::new(ErrorKind::Input, format!("phase: bad disparity range {d_min} .. {d_max}")));
        }
        out.reset(self.width, self.height, f32::INFINITY);

        let w = self.width;
        let periods = &self.periods[..];
        let min_sq4 = self.min_modulation_sq4;
        let slope_left: i64 = self
            .left_phase
            .data
            .par_chunks_mut(w * BAND_ROWS)
            .enumerate()
            .map(|(band, rows)| decode_band(left, periods, min_sq4, band * BAND_ROWS, rows))
            .sum();
        let slope_right: i64 = self
            .right_phase
            .data
            .par_chunks_mut(w * BAND_ROWS)
            .enumerate()
            .map(|(band, rows)| decode_band(right, periods, min_sq4, band * BAND_ROWS, rows))
            .sum();
        // The projector's x may run either way along rectified x; the majority of
        // neighbour steps over both images says which, and only segments rising that way are
        // matched, which drops the folds that noise makes in flat-phase regions.
        let increasing = slope_left + slope_right >= 0;

        let matcher =
            RowMatcher { width: w, bins: self.bins, increasing, d_min, d_max, lr_tolerance: self.lr_tolerance };
        let left_phase = &self.left_phase;
        let right_phase = &self.right_phase;
        out.data.par_chunks_mut(w * BAND_ROWS).zip(self.bands.par_iter_mut()).enumerate().for_each(
            |(band, (rows, scratch))| {
                for (r, out_row) in rows.chunks_mut(w).enumerate() {
                    let y = band * BAND_ROWS + r;
                    matcher.match_row(left_phase.row(y), right_phase.row(y), scratch, out_row);
                }
            },
        );
        Ok(())
    }
}

/// 1.5 * 2^23: adding and taking it away rounds an f32 of magnitude below 2^22 to an
/// integer.
const ROUNDING: f32 = 12_582_912.0;

/// Decodes the absolute phase of the rows starting at `y0` into `rows`; returns the sum of
/// the signs of horizontal phase steps between valid neighbours (which way phase runs).
fn decode_band(shots: &[GrayImage], periods: &[f32], min_sq4: i32, y0: usize, rows: &mut [f32]) -> i64 {
    let mut slope = 0i64;
    decode_rows(shots, periods, min_sq4, y0, rows, &mut slope);
    slope
}

crate::multiversion! {
    /// [`decode_band`], its slope added to `slope`, in the widest vector lanes this CPU has.
    fn decode_rows(
        shots: &[GrayImage],
        periods: &[f32],
        min_sq4: i32,
        y0: usize,
        rows: &mut [f32],
        slope: &mut i64,
    ) => decode_rows_body
}

#[inline(always)]
fn decode_rows_body(shots: &[GrayImage], periods: &[f32], min_sq4: i32, y0: usize, rows: &mut [f32], slope: &mut i64) {
    let w = shots[0].width;
    for (r, out) in rows.chunks_mut(w).enumerate() {
        let y = y0 + r;
        decode_row(shots, periods, min_sq4, y * w, out);
        for pair in out.windows(2) {
            let step = pair[1] - pair[0];
            // NaN steps compare false on both sides and count nothing.
            *slope += (step > 0.0) as i64 - (step < 0.0) as i64;
        }
    }
}

/// Absolute phase (fraction of the projector width) of the row starting at pixel `start`,
/// NaN where masked. One pass per frequency over the whole row, with selects instead of
/// branches, so that the compiler vectorises it; a masked pixel is NaN from the first
/// frequency that masks it, and NaN survives the later passes.
#[inline(always)]
fn decode_row(shots: &[GrayImage], periods: &[f32], min_sq4: i32, start: usize, out: &mut [f32]) {
    let w = out.len();
    let min_sq4 = min_sq4 as f32;
    for (fi, &f) in periods.iter().enumerate() {
        let row = |k: usize| &shots[4 * fi + k].data[start..start + w];
        let ratio = if fi == 0 { 0.0 } else { f / periods[fi - 1] };
        let pixels = out.iter_mut().zip(row(0)).zip(row(1)).zip(row(2)).zip(row(3));
        for ((((o, &i0), &i1), &i2), &i3) in pixels {
            let clipped = i0.max(i1).max(i2).max(i3) == SATURATED;
            // Differences of 8-bit values and their squares are exact in f32, and f32
            // multiplies vectorise where 32-bit integer ones need SSE4.1.
            let c = i0 as f32 - i2 as f32;
            let s = i1 as f32 - i3 as f32;
            let weak = c * c + s * s < min_sq4;
            let mut wrapped = atan2_fast(s, c);
            wrapped += if wrapped < 0.0 { TAU } else { 0.0 };
            // The coarser absolute phase predicts this one; the wrapped phase supplies the
            // precision and the prediction the period number. Adding and taking away 1.5 *
            // 2^23 rounds to the nearest integer in plain f32 arithmetic, which vectorises
            // where `round` (a library call without SSE4.1) and saturating casts do not.
            let predicted = *o * ratio;
            let order = ((predicted - wrapped) * (1.0 / TAU) + ROUNDING) - ROUNDING;
            let absolute = if fi == 0 { wrapped } else { wrapped + order * TAU };
            *o = if clipped || weak || (fi > 0 && o.is_nan()) { f32::NAN } else { absolute };
        }
    }
    let scale = 1.0 / (TAU * periods[periods.len() - 1]);
    for o in out.iter_mut() {
        *o *= scale;
    }
}

/// atan2 within about 1e-6 rad and no branches the compiler cannot turn into selects;
/// the phase noise of an 8-bit camera is orders of magnitude larger.
#[inline(always)]
pub(crate) fn atan2_fast(y: f32, x: f32) -> f32 {
    let ax = x.abs();
    let ay = y.abs();
    let hi = ax.max(ay);
    let lo = ax.min(ay);
    let a = if hi > 0.0 { lo / hi } else { 0.0 };
    let s = a * a;
    // Abramowitz and Stegun 4.4.49: atan on [0, 1] within 2e-8.
    let p = ((((((0.002_866_225_7 * s - 0.016_165_737) * s + 0.042_909_614) * s - 0.075_289_64) * s + 0.106_562_64)
        * s
        - 0.142_089)
        * s
        + 0.199_935_51)
        * s
        - 0.333_331_45;
    let mut r = p * s * a + a;
    if ay > ax {
        r = FRAC_PI_2 - r;
    }
    if x < 0.0 {
        r = PI - r;
    }
    if y < 0.0 {
        -r
    } else {
        r
    }
}

/// Matching of equal phase along one rectified row pair.
#[derive(Debug, Clone, Copy)]
struct RowMatcher {
    width: usize,
    bins: usize,
    increasing: bool,
    d_min: f32,
    d_max: f32,
    lr_tolerance: f32,
}

impl RowMatcher {
    /// Left-to-right and right-to-left matching of one row, then the left-right check.
    fn match_row(&self, left: &[f32], right: &[f32], scratch: &mut BandScratch, out: &mut [f32]) {
        let BandScratch { index, right_disparity } = scratch;
        // Right-to-left first: its disparities are what the check compares against.
        index.build(self, left);
        for (xr, d) in right_disparity.iter_mut().enumerate() {
            *d = match self.find(right[xr], left, index, xr as f32, -1.0) {
                Some(xl) => xl - xr as f32,
                None => f32::INFINITY,
            };
        }
        index.build(self, right);
        for (xl, o) in out.iter_mut().enumerate() {
            *o = f32::INFINITY;
            let Some(xr) = self.find(left[xl], right, index, xl as f32, 1.0) else {
                continue;
            };
            let d = xl as f32 - xr;
            let back = right_disparity[(xr.round() as usize).min(self.width - 1)];
            if (back - d).abs() <= self.lr_tolerance {
                *o = d;
            }
        }
    }

    /// Bin of phase `u` (clamped: out-of-range phases share the end bins and are told apart
    /// by the exact interval test).
    #[inline]
    fn bin(&self, u: f32) -> usize {
        ((u * self.bins as f32).max(0.0) as usize).min(self.bins)
    }

    /// The bins covered by a segment, or `None` when it is not matchable.
    #[inline]
    fn segment_bins(&self, pair: &[f32]) -> Option<(usize, usize)> {
        let (a, b) = (pair[0], pair[1]);
        let rising = if self.increasing { b > a } else { b < a };
        if !rising {
            return None;
        }
        let (b0, b1) = (self.bin(a.min(b)), self.bin(a.max(b)));
        (b1 - b0 <= MAX_STEP_BINS).then_some((b0, b1))
    }

    /// Sub-pixel column in `other` where its phase equals `u`, searching disparities
    /// `sign * (x - x_other)` within the range; `None` when there is none or when the phase
    /// appears at places more than a pixel apart (an unwrapping error somewhere).
    #[inline]
    fn find(&self, u: f32, other: &[f32], index: &PhaseIndex, x: f32, sign: f32) -> Option<f32> {
        if u.is_nan() {
            return None;
        }
        let b = self.bin(u);
        let (mut lo, mut hi, mut sum, mut n) = (f32::INFINITY, f32::NEG_INFINITY, 0.0f32, 0u32);
        for &seg in index.candidates(b) {
            let i = seg as usize;
            let (a, c) = (other[i], other[i + 1]);
            if !(a.min(c) <= u && u <= a.max(c)) {
                continue;
            }
            let xo = i as f32 + (u - a) / (c - a);
            let d = sign * (x - xo);
            if d < self.d_min || d > self.d_max {
                continue;
            }
            lo = lo.min(xo);
            hi = hi.max(xo);
            sum += xo;
            n += 1;
        }
        (n > 0 && hi - lo <= 1.0).then(|| sum / n as f32)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::depth::fixture::{away_from_edges, params, Scene, DARK, HEIGHT, PERIODS, RANGE, TABLE, WIDTH};
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn median(v: Vec<f64>) -> f64 {
        crate::scoring::median(&v).expect("decoded pixels")
    }

    /// Decodes a frame; returns (median error over bright, clean pixels, share of those
    /// decoded, share of all decoded pixels off by more than 1 px).
    fn check(scene: Scene, seed: u64) -> (f64, f64, f64) {
        let f = scene.render(&PERIODS, seed);
        let mut dec = PhaseDecoder::new(&params(), &PERIODS, WIDTH, HEIGHT).unwrap();
        let mut out = FloatImage::default();
        dec.decode(&f.left, &f.right, RANGE, &mut out).unwrap();
        let mut errors = Vec::new();
        let mut clean = 0;
        let (mut decoded, mut gross) = (0, 0);
        for i in 0..WIDTH * HEIGHT {
            let d = out.data[i] as f64;
            if d.is_finite() {
                decoded += 1;
                if (d - f.disparity[i]).abs() > 1.0 {
                    gross += 1;
                }
            }
            if f.albedo[i] >= TABLE && !f.saturated[i] && f.seen_by_right[i] && away_from_edges(&f, i) {
                clean += 1;
                if d.is_finite() {
                    errors.push((d - f.disparity[i]).abs());
                }
            }
        }
        assert!(clean > 50_000, "the scene should show the projector on most of the image");
        let share = errors.len() as f64 / clean as f64;
        eprintln!("median {} share {share} gross {gross} of {decoded}", median(errors.clone()));
        (median(errors), share, gross as f64 / decoded as f64)
    }

    #[test]
    fn fast_atan2_agrees_with_std() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        for _ in 0..100_000 {
            let (y, x) = (rng.random_range(-255..=255) as f32, rng.random_range(-255..=255) as f32);
            let want = if x == 0.0 && y == 0.0 { 0.0 } else { y.atan2(x) };
            assert!((atan2_fast(y, x) - want).abs() < 1e-6, "atan2({y}, {x})");
        }
    }

    #[test]
    fn disparity_of_a_box_on_a_slanted_table() {
        let (median, share, gross) = check(Scene { with_box: true, mirrored: false }, 7);
        assert!(median < 0.1, "median error {median} px");
        assert!(share > 0.95, "only {share} of the bright pixels decoded");
        assert!(gross < 0.005, "{gross} of decoded pixels off by more than 1 px");
    }

    #[test]
    fn projector_running_against_rectified_x() {
        let (median, share, gross) = check(Scene { with_box: true, mirrored: true }, 8);
        assert!(median < 0.1, "median error {median} px");
        assert!(share > 0.95, "only {share} of the bright pixels decoded");
        assert!(gross < 0.005, "{gross} of decoded pixels off by more than 1 px");
    }

    #[test]
    fn masks_saturated_and_weakly_modulated_pixels() {
        let f = Scene { with_box: true, mirrored: false }.render(&PERIODS, 9);
        // The dark stripe's modulation is 255 * 0.08 * 0.6 / 2 = 6.1 grey levels; the
        // table's 34 and the box's 65.
        let strict = PhaseParams { min_modulation: 12.0, lr_tolerance: 1.0 };
        let mut dec = PhaseDecoder::new(&strict, &PERIODS, WIDTH, HEIGHT).unwrap();
        let mut out = FloatImage::default();
        dec.decode(&f.left, &f.right, RANGE, &mut out).unwrap();
        let phase = dec.left_phase();
        let (mut dark, mut dark_kept, mut hot, mut hot_kept, mut bright, mut bright_kept) = (0, 0, 0, 0, 0, 0);
        for i in 0..WIDTH * HEIGHT {
            if !f.lit[i] || !away_from_edges(&f, i) {
                continue;
            }
            let kept = phase.data[i].is_finite() as usize;
            if f.saturated[i] {
                hot += 1;
                hot_kept += kept;
            } else if f.albedo[i] == DARK {
                dark += 1;
                dark_kept += kept;
            } else {
                bright += 1;
                bright_kept += kept;
            }
        }
        eprintln!("dark {dark_kept}/{dark} hot {hot_kept}/{hot} bright {bright_kept}/{bright}");
        assert!(dark > 1000 && hot > 1000 && bright > 10_000, "{dark} {hot} {bright}");
        assert_eq!(hot_kept, 0, "saturated pixels decoded");
        assert!((dark_kept as f64) < 0.001 * dark as f64, "{dark_kept} of {dark} dark pixels decoded");
        assert!(bright_kept as f64 > 0.999 * bright as f64, "{bright_kept} of {bright} bright pixels masked");
    }

    #[test]
    fn occluded_pixels_stay_unmatched() {
        let f = Scene { with_box: true, mirrored: false }.render(&PERIODS, 10);
        let mut dec = PhaseDecoder::new(&params(), &PERIODS, WIDTH, HEIGHT).unwrap();
        let mut out = FloatImage::default();
        dec.decode(&f.left, &f.right, RANGE, &mut out).unwrap();
        let (mut occluded, mut matched) = (0, 0);
        for i in 0..WIDTH * HEIGHT {
            if f.lit[i] && f.occluded[i] {
                occluded += 1;
                matched += out.data[i].is_finite() as usize;
            }
        }
        eprintln!("occluded {occluded} matched {matched}");
        assert!(occluded > 1000, "the box should hide part of the table from the right camera");
        // The few that match face the box's edge in the right image, where the 3x3 blur
        // mixes the box's fringes with the table's into the phases of the hidden strip.
        assert!((matched as f64) < 0.05 * occluded as f64, "{matched} of {occluded} occluded pixels matched");
    }

    #[test]
    fn refuses_wrong_inputs() {
        let mut dec = PhaseDecoder::new(&params(), &PERIODS, 8, 4).unwrap();
        let shot = GrayImage::new(8, 4, 100);
        let shots = vec![shot.clone(); 12];
        let mut out = FloatImage::default();
        assert!(dec.decode(&shots[..11], &shots, RANGE, &mut out).is_err());
        let mut odd = shots.clone();
        odd[5] = GrayImage::new(8, 5, 100);
        assert!(dec.decode(&shots, &odd, RANGE, &mut out).is_err());
        assert!(dec.decode(&shots, &shots, (5.0, 1.0), &mut out).is_err());
        assert!(PhaseDecoder::new(&params(), &[8.0, 1.0], 8, 4).is_err());
        assert!(PhaseDecoder::new(&params(), &[], 8, 4).is_err());
        // Flat shots have no modulation: everything is masked.
        dec.decode(&shots, &shots, RANGE, &mut out).unwrap();
        assert!(out.data.iter().all(|d| *d == f32::INFINITY));
    }
}
