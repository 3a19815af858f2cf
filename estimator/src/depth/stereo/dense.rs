//! Dense matching, ELAS's step after the prior: every textured pixel of a row tries the
//! candidate disparities of its grid cell and a band around its prior disparity, and keeps
//! the one of lowest energy (descriptor SAD plus prior energy).
//!
//! Two kernels give the same disparities. The scalar one walks the candidates one by one.
//! On x86_64 with AVX2 the other scores four candidates a step: four 256-bit SADs reduced
//! together, the prior energies looked up in an 8-entry register table, and the first
//! lowest candidate kept as the minimum of a packed (energy, order) key, so ties go where
//! the scalar loop sends them.
//!
//! The vector kernels read the other image through raw pointers. What keeps those reads
//! inside it is checked rather than assumed: a vector [`Kernel`] holds the proof that the
//! CPU runs it, a [`DisparityRange`] starts at 0 or above, [`check_row`] asserts the row
//! and the buffer sizes, and every disparity read is clamped to the pixel's limit,
//! whatever the candidate lists hold.

use super::cost::{DisparityRange, Kernel};
use super::descriptor::{sad, texture, Descriptor, DescriptorImage, BORDER};
use super::triangulation::{CandidateGrid, LIST_PAD};

// The vector kernel's last band step reads up to three descriptors past the band.
const _: () = assert!(BORDER > 3);

/// Marks an invalid integer disparity.
pub const INVALID: f32 = f32::INFINITY;

/// Where one image's pixels look in the other: what differs between matching the left
/// image and matching the right one.
#[derive(Clone, Copy)]
pub struct Side<'a> {
    pub own: &'a DescriptorImage,
    pub other: &'a DescriptorImage,
    /// The prior disparity of every `prior_step`-th row from row 0 (row j holding image row
    /// j x `prior_step`).
    pub prior: &'a [f32],
    pub prior_step: usize,
    pub grid: &'a CandidateGrid,
    /// The columns of each row to match, from the first to one past the last (`(0, width)`
    /// for all); the others are left as they were.
    pub columns: (usize, usize),
}

/// What every pixel of one matching pass shares.
#[derive(Clone, Copy)]
pub struct Search<'a> {
    pub range: DisparityRange,
    /// Half width of the band tried around the prior, px.
    pub radius: i32,
    pub min_texture: i32,
    /// Prior energy by |d - prior| (at least one entry; the last one holds beyond).
    pub prior_energy: &'a [i32],
    /// The vector kernel's prior table and whether it may run (see [`VectorPrior`]).
    pub vector: VectorPrior,
}

/// Bits of a packed key that hold a candidate's order: a grid candidate d has d - d_min
/// (ascending, as the list), a band candidate d has [`BAND_ORDER`] + d - band start.
const ORDER_BITS: u32 = 10;
const BAND_ORDER: i32 = 1 << (ORDER_BITS - 1);
/// Largest |prior energy| the packed keys hold: (SAD + energy) << ORDER_BITS stays an i32.
const MAX_PACKED_ENERGY: i32 = 1 << 19;

/// The prior energies as the vector kernel reads them: entries 0 ..= 7, every later
/// |d - prior| sharing entry 7.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VectorPrior(Option<[i32; 8]>);

impl VectorPrior {
    /// The table for `prior_energy` and candidate lists of up to `max_list` entries, or
    /// none when the packed keys cannot represent them: entries after 7 that differ from
    /// entry 7, energies beyond [`MAX_PACKED_ENERGY`], or lists too long for the order
    /// bits.
    pub fn new(prior_energy: &[i32], max_list: usize) -> Self {
        let last = prior_energy.len().saturating_sub(1);
        let at = |k: usize| prior_energy[k.min(last)];
        let flat = prior_energy.iter().skip(7).all(|&e| e == at(7));
        let small = prior_energy.iter().all(|e| e.abs() <= MAX_PACKED_ENERGY);
        let fits = !prior_energy.is_empty() && max_list <= BAND_ORDER as usize;
        VectorPrior((flat && small && fits).then(|| std::array::from_fn(at)))
    }
}

/// Panics unless row `y` lies at least BORDER rows inside the image and both descriptor
/// images hold the same whole w x h buffers: what the vector kernels' pointer reads rely on
/// (with the disparity limits of [`disparity_limit`]).
#[inline]
fn check_row(s: &Side<'_>, y: usize) {
    let (w, h) = (s.own.width, s.own.height);
    assert!(
        s.other.width == w && s.other.height == h && s.own.data.len() == w * h && s.other.data.len() == w * h,
        "descriptor images of {w}x{h} and {}x{} with {} and {} descriptors",
        s.other.width,
        s.other.height,
        s.own.data.len(),
        s.other.data.len()
    );
    assert!(y >= BORDER && y + BORDER < h, "row {y} is not BORDER rows inside the image");
}

/// Matches row `y` of one image into `out`: each pixel's energy minimiser, or [`INVALID`].
/// `LEFT` says which image: its pixels look at x - d in the other (the right image's at
/// x + d). Row `y` lies at least BORDER rows inside the image. Runs `kernel` (a vector one
/// only where the prior allows it, see [`VectorPrior`]).
pub fn match_row<const LEFT: bool>(s: &Side<'_>, q: &Search<'_>, y: usize, out: &mut [f32], kernel: Kernel) {
    check_row(s, y);
    #[cfg(target_arch = "x86_64")]
    if let VectorPrior(Some(table)) = q.vector {
        match kernel {
            // SAFETY: the proof in the kernel shows this machine runs AVX2, and `check_row`
            // passed.
            Kernel::Avx2(_) => return unsafe { avx2::match_row::<LEFT>(s, q, y, out, &table) },
            // SAFETY: the proof in the kernel shows this machine runs AVX2 and AVX-512 F, BW
            // and VL, and `check_row` passed.
            Kernel::Avx512(_) => return unsafe { avx2::match_row_wide::<LEFT>(s, q, y, out, &table) },
            Kernel::Scalar => {}
        }
    }
    let _ = kernel;
    match_row_scalar::<LEFT>(s, q, y, out);
}

/// The cells of row `y` in order that overlap `columns` (within a `w`-wide row): the
/// columns of each inside `columns` and its padded list.
#[inline(always)]
fn cells(
    grid: &CandidateGrid,
    w: usize,
    (lo, hi): (usize, usize),
    y: usize,
) -> impl Iterator<Item = (std::ops::Range<usize>, &[u16])> {
    let hi = hi.min(w);
    let first = lo / grid.cell * grid.cell;
    (first..hi)
        .step_by(grid.cell)
        .map(move |start| (start.max(lo)..(start + grid.cell).min(hi), grid.padded_at(start, y)))
}

/// [`match_row`] with the scalar kernel; the reference the vector kernel is tested against.
pub fn match_row_scalar<const LEFT: bool>(s: &Side<'_>, q: &Search<'_>, y: usize, out: &mut [f32]) {
    let w = s.own.width;
    let (row, held) = (y * w, y / s.prior_step * w);
    let (own, other, prior) = (&s.own.data[row..row + w], &s.other.data[row..row + w], &s.prior[held..held + w]);
    for (columns, padded) in cells(s.grid, w, s.columns, y) {
        let list = &padded[..padded.len() - LIST_PAD];
        for x in columns {
            out[x] = match_pixel::<LEFT>(own, other, prior[x], list, x, q);
        }
    }
}

/// The largest disparity pixel `x` of a `w`-wide row may take, so that the other pixel's
/// descriptor window stays inside the image: negative where there is none, as in rows
/// narrower than 2 BORDER + 1 px (signed arithmetic, so no width wraps around).
#[inline(always)]
fn disparity_limit<const LEFT: bool>(x: usize, w: usize, d_max: i32) -> i32 {
    let (x, w, border) = (x as isize, w as isize, BORDER as isize);
    let d_hi = if LEFT { x - border } else { w - 1 - border - x };
    // Between -BORDER - 1 and d_max, so an i32.
    d_hi.min(d_max as isize) as i32
}

/// The energy minimiser of pixel `x` of a row, or [`INVALID`]: the grid candidates `list`
/// (ascending) outside the band around the prior first, then the band, a later candidate
/// winning only with a strictly lower energy; without a prior, the grid candidates alone.
#[inline(always)]
fn match_pixel<const LEFT: bool>(
    own: &[Descriptor],
    other: &[Descriptor],
    mu: f32,
    list: &[u16],
    x: usize,
    q: &Search<'_>,
) -> f32 {
    let desc = &own[x];
    if texture(desc) < q.min_texture {
        return INVALID;
    }
    let d_hi = disparity_limit::<LEFT>(x, own.len(), q.range.d_max());
    if d_hi < q.range.d_min() {
        return INVALID;
    }
    let cost = |d: i32| sad(desc, &other[if LEFT { x - d as usize } else { x + d as usize }]);
    let (mut best_e, mut best_d) = (i32::MAX, -1);
    if mu.is_finite() {
        let mu_i = mu.round() as i32;
        let pe = q.prior_energy;
        let p = |d: i32| pe[((d - mu_i).unsigned_abs() as usize).min(pe.len() - 1)];
        for &d in list {
            let d = d as i32;
            if d > d_hi {
                break;
            }
            // The band around the prior below tries these anyway.
            if (d - mu_i).abs() <= q.radius {
                continue;
            }
            let e = cost(d) + p(d);
            if e < best_e {
                best_e = e;
                best_d = d;
            }
        }
        for d in (mu_i - q.radius).max(q.range.d_min())..=(mu_i + q.radius).min(d_hi) {
            let e = cost(d) + p(d);
            if e < best_e {
                best_e = e;
                best_d = d;
            }
        }
    } else {
        for &d in list {
            let d = d as i32;
            if d > d_hi {
                break;
            }
            let e = cost(d);
            if e < best_e {
                best_e = e;
                best_d = d;
            }
        }
    }
    if best_d < 0 {
        INVALID
    } else {
        best_d as f32
    }
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use std::arch::x86_64::*;

    use super::super::cost::avx512::{sad16, WIDE_LEFT, WIDE_RIGHT};
    use super::*;

    /// [`super::match_row`]'s vector kernel with AVX2: the same disparities as the scalar one.
    ///
    /// # Safety
    ///
    /// The machine runs AVX2, and `s` and `y` pass [`check_row`].
    #[target_feature(enable = "avx2")]
    pub unsafe fn match_row<const LEFT: bool>(
        s: &Side<'_>,
        q: &Search<'_>,
        y: usize,
        out: &mut [f32],
        table: &[i32; 8],
    ) {
        // SAFETY: AVX2 is enabled here and the caller ran `check_row`.
        unsafe { row::<LEFT, false>(s, q, y, out, table) }
    }

    /// The same with AVX-512 (BW, VL) as well: runs of candidates sixteen at a time.
    ///
    /// # Safety
    ///
    /// The machine runs AVX2 and AVX-512 F, BW and VL, and `s` and `y` pass [`check_row`].
    #[target_feature(enable = "avx2,avx512f,avx512bw,avx512vl")]
    pub unsafe fn match_row_wide<const LEFT: bool>(
        s: &Side<'_>,
        q: &Search<'_>,
        y: usize,
        out: &mut [f32],
        table: &[i32; 8],
    ) {
        // SAFETY: AVX2 and AVX-512 F, BW and VL are enabled here and the caller ran
        // `check_row`.
        unsafe { row::<LEFT, true>(s, q, y, out, table) }
    }

    /// The row loop of both vector kernels.
    ///
    /// # Safety
    ///
    /// Inlined into a caller that enables AVX2, and AVX-512 F, BW and VL when `WIDE`, on a
    /// machine that runs them; `s` and `y` pass [`check_row`].
    #[inline(always)]
    unsafe fn row<const LEFT: bool, const WIDE: bool>(
        s: &Side<'_>,
        q: &Search<'_>,
        y: usize,
        out: &mut [f32],
        table: &[i32; 8],
    ) {
        let w = s.own.width;
        let (row, held) = (y * w, y / s.prior_step * w);
        let (own, prior) = (&s.own.data[row..row + w], &s.prior[held..held + w]);
        // SAFETY: an unaligned 32-byte read of an [i32; 8].
        let table = unsafe { _mm256_loadu_si256(table.as_ptr().cast()) };
        for (columns, padded) in cells(s.grid, w, s.columns, y) {
            // The wide kernel's membership bits: bit d - d_min for each list entry d. A plain
            // array, so that the AVX2 kernel never touches a 512-bit register.
            let mut member = [0u32; 16];
            if WIDE {
                for &d in &padded[..padded.len() - LIST_PAD] {
                    let k = (d as i32 - q.range.d_min()) as usize;
                    member[k >> 5] |= 1 << (k & 31);
                }
            }
            for x in columns {
                // SAFETY: the caller enabled the features and ran `check_row`, which
                // `match_pixel` needs of `own`, `other`, `row` and `x` (x < w).
                out[x] = unsafe {
                    match_pixel::<LEFT, WIDE>(own, &s.other.data, row, prior[x], padded, x, q, table, &member)
                };
            }
        }
    }

    /// The best packed key of the candidates in `start ..= end`, sixteen disparities a step:
    /// the band `lo ..= hi` (when `band`) in band order, and the cell's list entries (bit
    /// d - d_min of the sixteen 32-bit words `member`) in grid order.
    ///
    /// # Safety
    ///
    /// The caller enabled AVX-512 F, BW and VL on a machine that runs them, and the sixteen
    /// descriptors at every disparity from `start` to `end + 15` lie inside the buffer
    /// `base` points into: `base - d` for the left image, `base + d` for the right one. (A
    /// pixel's `end` at most its disparity limit, in a row BORDER rows inside a whole image
    /// at least BORDER + 1 px wide, leaves those reads inside the image.)
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    unsafe fn window16<const LEFT: bool>(
        base: *const Descriptor,
        own: __m256i,
        table: __m256i,
        mu_i: i32,
        (start, end): (i32, i32),
        (lo, hi): (i32, i32),
        band: bool,
        d_min: i32,
        member: &[u32; 16],
    ) -> __m128i {
        // SAFETY: the caller enabled AVX-512 F, BW and VL; the reads are those the caller
        // vouches for (see `sad16`), and `member` is 64 readable bytes.
        unsafe {
            let member = _mm512_loadu_si512(member.as_ptr().cast());
            let own = _mm512_broadcast_i64x4(own);
            // Indices below 8 read the low half.
            let table = _mm512_broadcast_i64x4(table);
            let pattern = _mm512_loadu_si512(if LEFT { WIDE_LEFT.as_ptr() } else { WIDE_RIGHT.as_ptr() }.cast());
            let (mu, seven) = (_mm512_set1_epi32(mu_i), _mm512_set1_epi32(7));
            let (lo_v, hi_v, end_v) =
                (_mm512_set1_epi32(lo - 1), _mm512_set1_epi32(hi + 1), _mm512_set1_epi32(end + 1));
            let (band_shift, grid_shift) = (_mm512_set1_epi32(BAND_ORDER - lo), _mm512_set1_epi32(-d_min));
            let (bits, one) = (_mm512_set1_epi32(31), _mm512_set1_epi32(1));
            let mut best = _mm512_set1_epi32(i32::MAX);
            let mut d0 = start;
            while d0 <= end {
                let from = if LEFT { base.wrapping_sub(d0 as usize + 15) } else { base.wrapping_add(d0 as usize) };
                let sad = sad16(own, from);
                let d = _mm512_add_epi32(_mm512_set1_epi32(d0), pattern);
                let delta = _mm512_abs_epi32(_mm512_sub_epi32(d, mu));
                let e = _mm512_add_epi32(sad, _mm512_permutexvar_epi32(_mm512_min_epi32(delta, seven), table));
                let in_band =
                    if band { _mm512_cmpgt_epi32_mask(d, lo_v) & _mm512_cmpgt_epi32_mask(hi_v, d) } else { 0 };
                // Bit k = d - d_min of the words (lanes past `end` may read any word).
                let k = _mm512_add_epi32(d, grid_shift);
                let word = _mm512_permutexvar_epi32(_mm512_srli_epi32::<5>(k), member);
                let listed = _mm512_test_epi32_mask(_mm512_srlv_epi32(word, _mm512_and_si512(k, bits)), one);
                let order = _mm512_mask_blend_epi32(in_band, k, _mm512_add_epi32(d, band_shift));
                let key = _mm512_or_si512(_mm512_slli_epi32::<ORDER_BITS>(e), order);
                let keep = _mm512_cmpgt_epi32_mask(end_v, d) & (in_band | listed);
                best = _mm512_mask_min_epi32(best, keep, best, key);
                d0 += 16;
            }
            let m = _mm256_min_epi32(_mm512_castsi512_si256(best), _mm512_extracti64x4_epi64::<1>(best));
            _mm_min_epi32(_mm256_castsi256_si128(m), _mm256_extracti128_si256::<1>(m))
        }
    }

    /// SADs of `own` against four descriptors, as four i32.
    ///
    /// Each 64-bit lane of a 256-bit SAD holds a partial sum below 2^11. Candidates 0 and 1
    /// (2 and 3) share 64-bit lanes, one in each half; unpacking and adding the two registers
    /// lines up the four candidates' partial sums, and adding the 128-bit halves totals them.
    ///
    /// # Safety
    ///
    /// The caller enabled AVX2 on a machine that runs it, and each pointer is to a whole
    /// descriptor inside a buffer.
    #[inline(always)]
    unsafe fn sad4(own: __m256i, c: [*const Descriptor; 4]) -> __m128i {
        // SAFETY: the caller enabled AVX2 and vouches for four whole descriptors.
        unsafe {
            let s = |p: *const Descriptor| _mm256_sad_epu8(own, _mm256_loadu_si256(p.cast()));
            let a = _mm256_or_si256(s(c[0]), _mm256_slli_epi64::<32>(s(c[1])));
            let b = _mm256_or_si256(s(c[2]), _mm256_slli_epi64::<32>(s(c[3])));
            let e = _mm256_add_epi32(_mm256_unpacklo_epi64(a, b), _mm256_unpackhi_epi64(a, b));
            _mm_add_epi32(_mm256_castsi256_si128(e), _mm256_extracti128_si256::<1>(e))
        }
    }

    /// The scalar [`super::match_pixel`] four candidates at a time (runs sixteen at a time
    /// when `WIDE`); `padded` is the cell's list with its LIST_PAD trailing entries, `other`
    /// the other image's whole descriptor buffer and `row` the offset of this row in it.
    ///
    /// Every read of the other image is at a disparity from 0 (the range starts there or
    /// above) to the pixel's limit d_hi (the list is read clamped to it) plus three (plus
    /// fifteen when `WIDE`): inside the row for the four-wide steps, since d_hi keeps x - d
    /// or x + d BORDER > 3 px inside it; inside the image for the sixteen-wide ones.
    /// Whatever the list holds, the reads stay there; only the result depends on its order.
    ///
    /// # Safety
    ///
    /// The caller enabled AVX2 (and AVX-512 F, BW and VL when `WIDE`) on a machine that runs
    /// them; `own` is row `row / own.len()` of an image whose rows `other_image` holds whole,
    /// as [`check_row`] ensures, and `x < own.len()`.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    unsafe fn match_pixel<const LEFT: bool, const WIDE: bool>(
        own: &[Descriptor],
        other_image: &[Descriptor],
        row: usize,
        mu: f32,
        padded: &[u16],
        x: usize,
        q: &Search<'_>,
        table: __m256i,
        member: &[u32; 16],
    ) -> f32 {
        // SAFETY: the caller enabled AVX2 (and AVX-512 F, BW, VL when WIDE) on a machine
        // that runs them; the pointer reads stay where the comment above says, because the
        // range starts at 0 or above and every disparity read is clamped to d_hi.
        unsafe {
            let other = &other_image[row..row + own.len()];
            let desc = &own[x];
            if texture(desc) < q.min_texture {
                return INVALID;
            }
            let d_min = q.range.d_min();
            let d_hi = disparity_limit::<LEFT>(x, own.len(), q.range.d_max());
            if d_hi < d_min {
                return INVALID;
            }
            let list = &padded[..padded.len() - LIST_PAD];
            // The list is ascending: the candidates the window allows are a prefix.
            let n = match list.last() {
                Some(&d) if d as i32 > d_hi => list.partition_point(|&d| d as i32 <= d_hi),
                _ => list.len(),
            };
            // The other image's descriptor at disparity d is base - d (left) or base + d
            // (right).
            let base = other.as_ptr().wrapping_add(x);
            // Only called with 0 <= d <= d_hi + 3, which d_hi keeps inside the row (see above).
            let at = |d: i32| -> *const Descriptor {
                debug_assert!(d >= 0 && d <= d_hi + 3);
                if LEFT {
                    base.wrapping_sub(d as usize)
                } else {
                    base.wrapping_add(d as usize)
                }
            };
            let has_prior = mu.is_finite();
            let (mu_i, radius, table) =
                if has_prior { (mu.round() as i32, q.radius, table) } else { (0, -1, _mm256_setzero_si256()) };
            let (mu_v, radius_v) = (_mm_set1_epi32(mu_i), _mm_set1_epi32(radius));
            let (lanes, four) = (_mm_setr_epi32(0, 1, 2, 3), _mm_set1_epi32(4));
            let invalid = _mm_set1_epi32(i32::MAX);
            // SAFETY: an unaligned 32-byte read of one descriptor.
            let own_v = _mm256_loadu_si256(desc.as_ptr().cast());
            // Energy of four candidates with disparities `d` and SADs `sad`, and |d - prior|.
            let energy = |d: __m128i, sad: __m128i| -> (__m128i, __m128i) {
                let delta = _mm_abs_epi32(_mm_sub_epi32(d, mu_v));
                let index = _mm256_castsi128_si256(_mm_min_epi32(delta, _mm_set1_epi32(7)));
                let prior = _mm256_castsi256_si128(_mm256_permutevar8x32_epi32(table, index));
                (_mm_add_epi32(sad, prior), delta)
            };
            let pack = |e: __m128i, order: __m128i| _mm_or_si128(_mm_slli_epi32::<{ ORDER_BITS as i32 }>(e), order);
            let mut best = invalid;
            // The band around the prior (empty without one) and the prefix of the list.
            let (lo, hi) = ((mu_i - radius).max(d_min), (mu_i + radius).min(d_hi));
            let (first, last) =
                (list.first().map_or(0, |&d| d as i32), list.get(n.wrapping_sub(1)).map_or(0, |&d| d as i32));
            let band = has_prior && lo <= hi;
            let run = n == 0 || last - first + 1 == n as i32;
            let band_touches = !band || n == 0 || (lo <= last + 1 && hi + 1 >= first);
            if WIDE {
                // Every candidate lies between the lower start and the higher end of the
                // prefix and the band.
                if n > 0 || band {
                    let (start, end) = match (n > 0, band) {
                        (true, true) => (first.min(lo), last.max(hi)),
                        (true, false) => (first, last),
                        _ => (lo, hi),
                    };
                    // An ascending list's prefix ends at d_hi at most: the clamp changes
                    // nothing then and bounds the reads whatever the list holds.
                    let end = end.min(d_hi);
                    let base = other_image.as_ptr().wrapping_add(row + x);
                    best = window16::<LEFT>(base, own_v, table, mu_i, (start, end), (lo, hi), band, d_min, member);
                }
            } else if run && band_touches && (n > 0 || band) {
                // The prefix is a run of consecutive disparities that the band overlaps or
                // touches: every disparity from the lower start to the higher end is a
                // candidate, the band's ones in band order, the rest in grid order (d - d_min).
                let (start, end) = match (n > 0, band) {
                    (true, true) => (first.min(lo), last.max(hi)),
                    (true, false) => (first, last),
                    _ => (lo, hi),
                };
                // As above: no change for an ascending list, and bounded reads for any.
                let end = end.min(d_hi);
                let (mut d0, mut d) = (start, _mm_add_epi32(_mm_set1_epi32(start), lanes));
                let (lo_v, hi_v, end_v) = (_mm_set1_epi32(lo - 1), _mm_set1_epi32(hi + 1), _mm_set1_epi32(end + 1));
                let (band_shift, grid_shift) = (_mm_set1_epi32(BAND_ORDER - lo), _mm_set1_epi32(-d_min));
                while d0 <= end {
                    let sad = sad4(own_v, [at(d0), at(d0 + 1), at(d0 + 2), at(d0 + 3)]);
                    let (e, _) = energy(d, sad);
                    let in_band = _mm_and_si128(_mm_cmpgt_epi32(d, lo_v), _mm_cmpgt_epi32(hi_v, d));
                    let in_band = if band { in_band } else { _mm_setzero_si128() };
                    let order = _mm_blendv_epi8(_mm_add_epi32(d, grid_shift), _mm_add_epi32(d, band_shift), in_band);
                    let keep = _mm_cmpgt_epi32(end_v, d);
                    best = _mm_min_epi32(best, _mm_blendv_epi8(invalid, pack(e, order), keep));
                    d = _mm_add_epi32(d, four);
                    d0 += 4;
                }
            } else {
                // Grid candidates in the prefix and outside the band (which tries the rest). Past
                // the list come LIST_PAD entries of d_min; entries past the prefix are scored at
                // d_hi (only near the image border) and ignored. Reading every entry clamped to
                // d_hi changes no score of an ascending list (its prefix and the pads lie at
                // d_hi or below) and keeps the reads inside the row for any list.
                let (mut i, mut index, n_v) = (0, lanes, _mm_set1_epi32(n as i32));
                let grid_shift = _mm_set1_epi32(-d_min);
                while i < n {
                    let p = &padded[i..i + 4];
                    let c = |k: usize| at((p[k] as i32).min(d_hi));
                    let sad = sad4(own_v, [c(0), c(1), c(2), c(3)]);
                    // SAFETY: an unaligned 8-byte read of four list entries.
                    let d = _mm_cvtepu16_epi32(_mm_loadl_epi64(p.as_ptr().cast()));
                    let (e, delta) = energy(d, sad);
                    let keep = _mm_and_si128(_mm_cmpgt_epi32(n_v, index), _mm_cmpgt_epi32(delta, radius_v));
                    let order = _mm_add_epi32(d, grid_shift);
                    best = _mm_min_epi32(best, _mm_blendv_epi8(invalid, pack(e, order), keep));
                    index = _mm_add_epi32(index, four);
                    i += 4;
                }
                // The band, four disparities a step; the last step may score up to three past its
                // end, which the BORDER margin leaves inside the row.
                if has_prior {
                    let (mut d0, mut d) = (lo, _mm_add_epi32(_mm_set1_epi32(lo), lanes));
                    let mut order = _mm_add_epi32(_mm_set1_epi32(BAND_ORDER), lanes);
                    let end = _mm_set1_epi32(hi + 1);
                    while d0 <= hi {
                        let sad = sad4(own_v, [at(d0), at(d0 + 1), at(d0 + 2), at(d0 + 3)]);
                        let (e, _) = energy(d, sad);
                        let keep = _mm_cmpgt_epi32(end, d);
                        best = _mm_min_epi32(best, _mm_blendv_epi8(invalid, pack(e, order), keep));
                        d = _mm_add_epi32(d, four);
                        order = _mm_add_epi32(order, four);
                        d0 += 4;
                    }
                }
            }
            let m = _mm_min_epi32(best, _mm_shuffle_epi32::<0b01_00_11_10>(best));
            let key = _mm_cvtsi128_si32(_mm_min_epi32(m, _mm_shuffle_epi32::<0b10_11_00_01>(m)));
            if key == i32::MAX {
                return INVALID;
            }
            let order = key & ((1 << ORDER_BITS) - 1);
            let d = if order >= BAND_ORDER { lo + order - BAND_ORDER } else { d_min + order };
            d as f32
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::{Avx2, Avx512};
    use crate::depth::stereo::cost::run_costs;
    use crate::depth::stereo::support::SupportPoint;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Random descriptors of a `w` x `h` image whose right view repeats the left one shifted
    /// by about `shift` px, plus noise: costs with real minima and real ties.
    fn images(rng: &mut ChaCha8Rng, w: usize, h: usize, shift: usize) -> (DescriptorImage, DescriptorImage) {
        let (mut l, mut r) = (DescriptorImage::new(w, h), DescriptorImage::new(w, h));
        for d in l.data.iter_mut() {
            *d = std::array::from_fn(|_| 128u8.wrapping_add(rng.random_range(0..24)) - 12);
        }
        for y in 0..h {
            for x in 0..w {
                let src = l.data[y * w + (x + shift).min(w - 1)];
                r.data[y * w + x] = src.map(|b| b.saturating_add(rng.random_range(0..3)));
            }
        }
        (l, r)
    }

    /// The vector kernels this machine runs.
    fn vector_kernels() -> Vec<Kernel> {
        let mut kernels: Vec<Kernel> = Avx2::detect().map(Kernel::Avx2).into_iter().collect();
        kernels.extend(Avx512::detect().map(Kernel::Avx512));
        kernels
    }

    /// Row `y` of the left image (`left`) or the right one, by `kernel`, or by the scalar
    /// reference without one.
    fn row_of(left: bool, s: &Side<'_>, q: &Search<'_>, y: usize, out: &mut [f32], kernel: Option<Kernel>) {
        match (left, kernel) {
            (true, Some(kernel)) => match_row::<true>(s, q, y, out, kernel),
            (false, Some(kernel)) => match_row::<false>(s, q, y, out, kernel),
            (true, None) => match_row_scalar::<true>(s, q, y, out),
            (false, None) => match_row_scalar::<false>(s, q, y, out),
        }
    }

    #[test]
    fn vector_kernels_match_scalar_kernel() {
        let kernels = vector_kernels();
        if kernels.is_empty() {
            eprintln!("no AVX2 here: only the scalar kernel runs");
            return;
        }
        let mut rng = ChaCha8Rng::seed_from_u64(17);
        let (w, h) = (96, 24);
        for trial in 0..60 {
            let (d_min, span) = (rng.random_range(0..20), rng.random_range(4..40));
            let d_max = d_min + span;
            let range = DisparityRange::new(d_min, d_max).unwrap();
            let (left, right) = images(&mut rng, w, h, (d_min + span / 2) as usize);
            let points: Vec<SupportPoint> = (0..rng.random_range(0..40))
                .map(|_| SupportPoint {
                    u: rng.random_range(0..w as i32),
                    v: rng.random_range(0..h as i32),
                    d: rng.random_range(d_min - 2..=d_max + 2),
                })
                .collect();
            let mut grid = CandidateGrid::new(w, h, rng.random_range(4..30), span as usize);
            grid.compute(&points, range, trial % 2 == 1);
            // Priors: planes, holes and values off the range.
            let prior: Vec<f32> = (0..w * h)
                .map(|i| match rng.random_range(0..10) {
                    0 => f32::NAN,
                    1 => f32::INFINITY,
                    2 => rng.random_range(-5.0..70.0),
                    _ => (d_min + span / 2) as f32 + 0.1 * (i % w) as f32 - 4.0,
                })
                .collect();
            let energy: Vec<i32> = match trial % 3 {
                0 => vec![-14, -9, -2, 0, 0],
                1 => vec![rng.random_range(-40..0); 1],
                _ => (0..12).map(|k| if k < 7 { rng.random_range(-30..5) } else { 3 }).collect(),
            };
            let q = Search {
                range,
                radius: rng.random_range(0..5),
                min_texture: rng.random_range(0..60),
                prior_energy: &energy,
                vector: VectorPrior::new(&energy, span as usize + 1),
            };
            assert!(q.vector.0.is_some(), "table {energy:?} should fit the vector kernel");
            let side = Side { own: &left, other: &right, prior: &prior, prior_step: 1, grid: &grid, columns: (0, w) };
            let left_image = trial % 2 == 0;
            for y in BORDER..h - BORDER {
                let mut slow = vec![0.0; w];
                row_of(left_image, &side, &q, y, &mut slow, None);
                for &kernel in &kernels {
                    let mut fast = vec![-1.0; w];
                    row_of(left_image, &side, &q, y, &mut fast, Some(kernel));
                    assert_eq!(slow, fast, "{kernel:?}, trial {trial}, row {y}");
                }
                assert!(slow.iter().any(|d| d.is_finite()), "trial {trial}, row {y} matched nothing");
            }
        }
    }

    #[test]
    fn narrow_rows_agree_in_every_kernel() {
        // Rows with no room for a disparity on either side of the other pixel's descriptor
        // window (under 2 BORDER + 1 px, down to none), and a little wider. Every kernel
        // gives the scalar one's disparities, and each lands on a pixel whose window lies
        // inside the row, whatever the prior, the candidates and the texture threshold.
        let mut rng = ChaCha8Rng::seed_from_u64(29);
        let kernels: Vec<Option<Kernel>> =
            [None, Some(Kernel::Scalar)].into_iter().chain(vector_kernels().into_iter().map(Some)).collect();
        let energy = [-14, -9, -2, 0, 0];
        for w in 0..=24 {
            for h in [11, 12, 14] {
                for trial in 0..8 {
                    let (d_min, span) = (rng.random_range(0..6), rng.random_range(0..12));
                    let range = DisparityRange::new(d_min, d_min + span).unwrap();
                    let (left, right) = images(&mut rng, w, h, 1);
                    let points: Vec<SupportPoint> = (0..rng.random_range(0..12))
                        .map(|_| SupportPoint {
                            u: rng.random_range(-2..w as i32 + 2),
                            v: rng.random_range(0..h as i32),
                            d: rng.random_range(d_min - 2..=d_min + span + 2),
                        })
                        .collect();
                    let mut grid = CandidateGrid::new(w, h, rng.random_range(1..8), span as usize);
                    grid.compute(&points, range, trial % 2 == 1);
                    let prior: Vec<f32> = (0..w * h)
                        .map(|_| match rng.random_range(0..4) {
                            0 => f32::NAN,
                            _ => rng.random_range(-3.0..20.0),
                        })
                        .collect();
                    let q = Search {
                        range,
                        radius: rng.random_range(0..4),
                        min_texture: if trial < 4 { 0 } else { rng.random_range(0..200) },
                        prior_energy: &energy,
                        vector: VectorPrior::new(&energy, span as usize + 1),
                    };
                    let side =
                        Side { own: &left, other: &right, prior: &prior, prior_step: 1, grid: &grid, columns: (0, w) };
                    let left_image = trial % 2 == 0;
                    for y in BORDER..h - BORDER {
                        let mut slow = vec![0.0; w];
                        row_of(left_image, &side, &q, y, &mut slow, None);
                        for (x, &d) in slow.iter().enumerate().filter(|(_, d)| d.is_finite()) {
                            // The pixel looked at keeps BORDER px to the row end it moves to.
                            let (x, border) = (x as f32, BORDER as f32);
                            let inside = if left_image { x - d >= border } else { x + d <= w as f32 - 1.0 - border };
                            assert!(inside && d >= d_min as f32, "{w}x{h}: pixel {x} took {d}");
                        }
                        for &kernel in &kernels {
                            let mut fast = vec![-1.0; w];
                            row_of(left_image, &side, &q, y, &mut fast, kernel);
                            assert_eq!(slow, fast, "{kernel:?}, {w}x{h}, trial {trial}, row {y}");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn negative_disparities_are_refused() {
        assert_eq!(DisparityRange::new(-1, 5), None);
        assert_eq!(DisparityRange::new(4, 3), None);
        assert_eq!(DisparityRange::new(0, 0).map(|r| (r.d_min(), r.d_max())), Some((0, 0)));
        let mut rng = ChaCha8Rng::seed_from_u64(31);
        let (w, h) = (40, 12);
        let (left, right) = images(&mut rng, w, h, 3);
        let at = 6 * w + 20;
        for kernel in [Kernel::Scalar].into_iter().chain(vector_kernels()) {
            for d0 in [-1, -16, i32::MIN] {
                let run = std::panic::AssertUnwindSafe(|| {
                    let mut costs = [0; 4];
                    run_costs::<true>(&left.data[at], &right.data, at, d0, &mut costs, kernel);
                });
                assert!(std::panic::catch_unwind(run).is_err(), "{kernel:?} ran from disparity {d0}");
            }
        }
    }

    #[test]
    fn wide_run_costs_match_scalar_ones() {
        let Some(proof) = Avx512::detect() else {
            eprintln!("no AVX-512 here: only the scalar costs run");
            return;
        };
        let mut rng = ChaCha8Rng::seed_from_u64(23);
        let (w, h) = (120, 16);
        let (left, right) = images(&mut rng, w, h, 20);
        for _ in 0..500 {
            let y = rng.random_range(BORDER..h - BORDER);
            let x = rng.random_range(BORDER..w - BORDER);
            let d0 = rng.random_range(0..8);
            // The disparities keep the other pixel BORDER px inside the row.
            let left_side = rng.random_bool(0.5);
            let room = if left_side { x - BORDER } else { w - 1 - BORDER - x };
            if room < d0 as usize {
                continue;
            }
            let n = rng.random_range(1..=room - d0 as usize + 1);
            let (mut slow, mut fast) = (vec![0; n], vec![-1; n]);
            let (own, other) = if left_side { (&left, &right) } else { (&right, &left) };
            let at = y * w + x;
            if left_side {
                run_costs::<true>(&own.data[at], &other.data, at, d0, &mut slow, Kernel::Scalar);
                run_costs::<true>(&own.data[at], &other.data, at, d0, &mut fast, Kernel::Avx512(proof));
            } else {
                run_costs::<false>(&own.data[at], &other.data, at, d0, &mut slow, Kernel::Scalar);
                run_costs::<false>(&own.data[at], &other.data, at, d0, &mut fast, Kernel::Avx512(proof));
            }
            assert_eq!(slow, fast, "pixel ({x}, {y}), d0 {d0}, {n} disparities");
        }
    }

    #[test]
    fn vector_prior_refuses_tables_it_cannot_pack() {
        assert!(VectorPrior::new(&[-14, -9, -2, 0, 0], 51).0.is_some());
        assert_eq!(VectorPrior::new(&[-5, -1], 51).0, Some([-5, -1, -1, -1, -1, -1, -1, -1]));
        assert!(VectorPrior::new(&[0, 1, 2, 3, 4, 5, 6, 7, 8], 51).0.is_none(), "no flat tail after entry 7");
        assert!(VectorPrior::new(&[-(1 << 20), 0], 51).0.is_none(), "energy too large to pack");
        assert!(VectorPrior::new(&[-14, 0], 600).0.is_none(), "lists too long for the order bits");
        assert!(VectorPrior::new(&[], 51).0.is_none());
    }
}
