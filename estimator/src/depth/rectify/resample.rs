//! Resampling raw images onto the rectified canvas through a remap table: bilinear in
//! 8-bit fixed point, one pixel at a time (the reference), sixteen at a time with AVX-512
//! gathers or eight at a time with AVX2 gathers (the same bits). The shots of one frame go through the table together, so a
//! 12-shot frame reads each entry once instead of once a shot. Building the tables lives in
//! the parent module.

#[cfg(target_arch = "x86_64")]
use std::ops::Range;

use rayon::prelude::*;

use super::{RemapEntry, FRAC_BITS, FRAC_ONE, OUTSIDE};
use camplace_config::AsImageView;

use crate::GrayImage;

/// Shots resampled in one pass over the table; a frame with more takes several passes.
const SHOTS_PER_PASS: usize = 16;

/// One output image's pixels, shared by the row tasks of a pass, each of which writes only
/// its own row.
#[derive(Clone, Copy)]
struct SharedRows(*mut u8);

// SAFETY: the pointer is only turned into slices of disjoint rows (one task a row), and the
// image it points into outlives the pass, which borrows it mutably.
unsafe impl Send for SharedRows {}
// SAFETY: as for Send: no two tasks touch the same bytes.
unsafe impl Sync for SharedRows {}

/// Resamples `raws[i]` into `outs[i]` for every shot through `map` (a table of the `w` x `h`
/// canvas over `raw_w` x `raw_h` images). A raw image of the wrong size yields an all-black
/// canvas; shots beyond the shorter list are left alone. A raw view with padded rows is read
/// in place, one pixel at a time, to the same bits as its rows back to back would give.
pub(super) fn remap_shots<S: AsImageView<u8>>(
    map: &[RemapEntry],
    (raw_w, raw_h): (usize, usize),
    (w, h): (usize, usize),
    raws: &[S],
    outs: &mut [GrayImage],
) {
    #[cfg(target_arch = "x86_64")]
    let (wide, avx2) = (crate::cpu::Avx512::detect(), crate::cpu::Avx2::detect());
    for (raws, outs) in raws.chunks(SHOTS_PER_PASS).zip(outs.chunks_mut(SHOTS_PER_PASS)) {
        let mut srcs: heapless::Vec<&[u8], SHOTS_PER_PASS> = heapless::Vec::new();
        let mut strides: heapless::Vec<usize, SHOTS_PER_PASS> = heapless::Vec::new();
        let mut rows: heapless::Vec<SharedRows, SHOTS_PER_PASS> = heapless::Vec::new();
        for (raw, out) in raws.iter().zip(outs.iter_mut()) {
            let raw = raw.as_view();
            // The view holds at least this much when built by its constructor (an owned
            // image's fields may disagree); the reads stop at the last row's end.
            let used = if raw_h == 0 { 0 } else { (raw_h - 1) * raw.stride() + raw_w };
            if raw.width() != raw_w || raw.height() != raw_h || raw.data().len() < used {
                out.reset(w, h, 0);
                continue;
            }
            // Every pixel of a fitting shot is written below: no need to clear it first.
            if !(out.width == w && out.height == h && out.data.len() == w * h) {
                out.reset(w, h, 0);
            }
            // Every list holds at most SHOTS_PER_PASS entries: the chunks do.
            let _ = srcs.push(&raw.data()[..used]);
            let _ = strides.push(raw.stride());
            let _ = rows.push(SharedRows(out.data.as_mut_ptr()));
        }
        if srcs.is_empty() || w == 0 {
            continue;
        }
        let (srcs, strides, rows) = (&srcs[..], &strides[..], &rows[..]);
        let padded = strides.iter().any(|&s| s != raw_w);
        map.par_chunks(w).take(h).enumerate().for_each(|(y, entries)| {
            let mut out: heapless::Vec<&mut [u8], SHOTS_PER_PASS> = heapless::Vec::new();
            for shared in rows {
                // SAFETY: each output holds w * h bytes (sized above) and lives through the
                // pass; row y is written by this task alone.
                let row = unsafe { std::slice::from_raw_parts_mut(shared.0.add(y * w), w) };
                let _ = out.push(row);
            }
            if padded {
                for ((src, &stride), row) in srcs.iter().zip(strides).zip(out.iter_mut()) {
                    remap_pixels_strided(src, raw_w, stride, entries, row);
                }
                return;
            }
            #[cfg(target_arch = "x86_64")]
            if let Some(proof) = wide {
                return remap_row_wide(proof, srcs, raw_w, entries, &mut out);
            }
            #[cfg(target_arch = "x86_64")]
            if let Some(proof) = avx2 {
                return remap_row_avx2(proof, srcs, raw_w, entries, &mut out);
            }
            for (src, row) in srcs.iter().zip(out.iter_mut()) {
                remap_pixels(src, raw_w, entries, row);
            }
        });
    }
}

/// [`remap_pixels`] over rows `stride` bytes apart: each table index (of rows back to
/// back) is moved to its row in the padded image.
fn remap_pixels_strided(src: &[u8], raw_w: usize, stride: usize, entries: &[RemapEntry], row: &mut [u8]) {
    if stride == raw_w {
        return remap_pixels(src, raw_w, entries, row);
    }
    for (o, e) in row.iter_mut().zip(entries) {
        if e.index == OUTSIDE {
            *o = 0;
            continue;
        }
        let (y, x) = (e.index as usize / raw_w, e.index as usize % raw_w);
        let i = y * stride + x;
        let (a, b) = (src[i] as u32, src[i + 1] as u32);
        let (c, d) = (src[i + stride] as u32, src[i + stride + 1] as u32);
        let (fx, fy) = (e.frac_x as u32, e.frac_y as u32);
        let top = a * (FRAC_ONE - fx) + b * fx;
        let bottom = c * (FRAC_ONE - fx) + d * fx;
        let v = top * (FRAC_ONE - fy) + bottom * fy;
        *o = ((v + (1 << (2 * FRAC_BITS - 1))) >> (2 * FRAC_BITS)) as u8;
    }
}

/// Resamples `entries` into `row` one pixel at a time: the reference the vector path
/// equals.
fn remap_pixels(src: &[u8], raw_w: usize, entries: &[RemapEntry], row: &mut [u8]) {
    for (o, e) in row.iter_mut().zip(entries) {
        if e.index == OUTSIDE {
            *o = 0;
            continue;
        }
        let i = e.index as usize;
        let (a, b) = (src[i] as u32, src[i + 1] as u32);
        let (c, d) = (src[i + raw_w] as u32, src[i + raw_w + 1] as u32);
        let (fx, fy) = (e.frac_x as u32, e.frac_y as u32);
        let top = a * (FRAC_ONE - fx) + b * fx;
        let bottom = c * (FRAC_ONE - fx) + d * fx;
        let v = top * (FRAC_ONE - fy) + bottom * fy;
        *o = ((v + (1 << (2 * FRAC_BITS - 1))) >> (2 * FRAC_BITS)) as u8;
    }
}

/// [`remap_pixels`] for every shot over the pixels `span` of the row.
#[cfg(target_arch = "x86_64")]
fn remap_span(srcs: &[&[u8]], raw_w: usize, entries: &[RemapEntry], rows: &mut [&mut [u8]], span: Range<usize>) {
    for (src, row) in srcs.iter().zip(rows.iter_mut()) {
        remap_pixels(src, raw_w, &entries[span.clone()], &mut row[span.clone()]);
    }
}

/// For the vector kernels: the pixels of the row (the shortest output row or the table),
/// and the bound every lane's index must stay below, or `None` when no step can read
/// safely. A lane reads src[i ..= i + 3] and src[i + raw_w ..= i + raw_w + 3]: inside when
/// i + raw_w + 3 < src.len(), which outside lanes (read at i = 0) need as well; the
/// shortest source bounds the reads of all, and the bound fits a 32-bit lane.
#[cfg(target_arch = "x86_64")]
fn vector_bounds(srcs: &[&[u8]], raw_w: usize, entries: &[RemapEntry], rows: &[&mut [u8]]) -> (usize, Option<usize>) {
    let n = rows.iter().map(|r| r.len()).min().unwrap_or(0).min(entries.len());
    let len = srcs.iter().map(|s| s.len()).min().unwrap_or(0);
    let limit = len.saturating_sub(raw_w + 3);
    (n, (limit > 0 && limit <= i32::MAX as usize).then_some(limit))
}

/// [`remap_pixels`] for every shot, sixteen pixels a step with AVX-512: the step's entries
/// are read and unpacked once, then each shot takes two gathers of four bytes per pixel
/// (the raw row pair's neighbours) and the same 32-bit arithmetic, for the same bits. A
/// step whose reads might pass the end of a source (a lane within a row and 3 bytes of it)
/// and the row's last pixels go one at a time; the shortest source bounds the reads of all.
#[cfg(target_arch = "x86_64")]
fn remap_row_wide(
    _proof: crate::cpu::Avx512,
    srcs: &[&[u8]],
    raw_w: usize,
    entries: &[RemapEntry],
    rows: &mut [&mut [u8]],
) {
    // SAFETY: the proof shows this machine runs AVX-512 F and BW.
    unsafe { remap_row_avx512(srcs, raw_w, entries, rows) }
}

/// # Safety
///
/// The machine runs AVX-512 F and BW.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw")]
fn remap_row_avx512(srcs: &[&[u8]], raw_w: usize, entries: &[RemapEntry], rows: &mut [&mut [u8]]) {
    use std::arch::x86_64::*;
    const LANES: usize = 16;
    let one_at_a_time = |entries: &[RemapEntry], rows: &mut [&mut [u8]], from: usize, to: usize| {
        remap_span(srcs, raw_w, entries, rows, from..to)
    };
    let (n, limit) = vector_bounds(srcs, raw_w, entries, rows);
    let Some(limit) = limit else { return one_at_a_time(entries, rows, 0, n) };
    let (even, odd) = (
        _mm512_setr_epi32(0, 2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 22, 24, 26, 28, 30),
        _mm512_setr_epi32(1, 3, 5, 7, 9, 11, 13, 15, 17, 19, 21, 23, 25, 27, 29, 31),
    );
    let (one, byte, low16) = (_mm512_set1_epi32(FRAC_ONE as i32), _mm512_set1_epi32(0xff), _mm512_set1_epi32(0xffff));
    let round = _mm512_set1_epi32(1 << (2 * FRAC_BITS - 1));
    let (outside, below) = (_mm512_set1_epi32(OUTSIDE as i32), _mm512_set1_epi32(limit as i32));
    let down = _mm512_set1_epi32(raw_w as i32);
    let mut x = 0;
    while x + LANES <= n {
        // SAFETY: 16 entries of 8 bytes (repr(C): index, frac_x, frac_y) from x, inside
        // `entries` as x + 16 <= n.
        let (lo, hi) = unsafe {
            let at = entries.as_ptr().add(x).cast::<i32>();
            (_mm512_loadu_si512(at.cast()), _mm512_loadu_si512(at.add(LANES).cast()))
        };
        let index = _mm512_permutex2var_epi32(lo, even, hi);
        let frac = _mm512_permutex2var_epi32(lo, odd, hi);
        let out_mask = _mm512_cmpeq_epi32_mask(index, outside);
        // Unsigned, so OUTSIDE (all ones) is not below anything.
        let safe = _mm512_cmplt_epu32_mask(index, below) | out_mask;
        if safe != 0xffff {
            one_at_a_time(entries, rows, x, x + LANES);
            x += LANES;
            continue;
        }
        let index = _mm512_maskz_mov_epi32(!out_mask, index);
        let index_down = _mm512_add_epi32(index, down);
        let (fx, fy) = (_mm512_and_si512(frac, low16), _mm512_srli_epi32::<16>(frac));
        let (gx, gy) = (_mm512_sub_epi32(one, fx), _mm512_sub_epi32(one, fy));
        for (src, row) in srcs.iter().zip(rows.iter_mut()) {
            // SAFETY: every lane's index is below `limit` (outside lanes read at 0), so
            // both four-byte reads lie inside `src`, which holds at least `len` bytes.
            let (top, bottom) = unsafe {
                (
                    _mm512_i32gather_epi32::<1>(index, src.as_ptr().cast()),
                    _mm512_i32gather_epi32::<1>(index_down, src.as_ptr().cast()),
                )
            };
            let (a, b) = (_mm512_and_si512(top, byte), _mm512_and_si512(_mm512_srli_epi32::<8>(top), byte));
            let (c, d) = (_mm512_and_si512(bottom, byte), _mm512_and_si512(_mm512_srli_epi32::<8>(bottom), byte));
            let upper = _mm512_add_epi32(_mm512_mullo_epi32(a, gx), _mm512_mullo_epi32(b, fx));
            let lower = _mm512_add_epi32(_mm512_mullo_epi32(c, gx), _mm512_mullo_epi32(d, fx));
            let v = _mm512_add_epi32(_mm512_mullo_epi32(upper, gy), _mm512_mullo_epi32(lower, fy));
            let v = _mm512_srli_epi32::<{ 2 * FRAC_BITS }>(_mm512_add_epi32(v, round));
            let v = _mm512_maskz_mov_epi32(!out_mask, v);
            // SAFETY: 16 bytes into row[x .. x + 16], inside as x + 16 <= n <= row.len().
            unsafe { _mm_storeu_si128(row.as_mut_ptr().add(x).cast(), _mm512_cvtepi32_epi8(v)) };
        }
        x += LANES;
    }
    one_at_a_time(entries, rows, x, n);
}

/// [`remap_row_wide`] for machines with AVX2 and not AVX-512: eight pixels a step, the
/// same reads, arithmetic and bits.
#[cfg(target_arch = "x86_64")]
fn remap_row_avx2(
    _proof: crate::cpu::Avx2,
    srcs: &[&[u8]],
    raw_w: usize,
    entries: &[RemapEntry],
    rows: &mut [&mut [u8]],
) {
    // SAFETY: the proof shows this machine runs AVX2.
    unsafe { remap_row_avx2_inner(srcs, raw_w, entries, rows) }
}

/// # Safety
///
/// The machine runs AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn remap_row_avx2_inner(srcs: &[&[u8]], raw_w: usize, entries: &[RemapEntry], rows: &mut [&mut [u8]]) {
    use std::arch::x86_64::*;
    const LANES: usize = 8;
    let one_at_a_time = |entries: &[RemapEntry], rows: &mut [&mut [u8]], from: usize, to: usize| {
        remap_span(srcs, raw_w, entries, rows, from..to)
    };
    let (n, limit) = vector_bounds(srcs, raw_w, entries, rows);
    let Some(limit) = limit else { return one_at_a_time(entries, rows, 0, n) };
    // Entries as eight 32-bit words (index, frac) per four entries: even words to the low
    // half, odd to the high half.
    let split = _mm256_setr_epi32(0, 2, 4, 6, 1, 3, 5, 7);
    let (one, byte, low16) = (_mm256_set1_epi32(FRAC_ONE as i32), _mm256_set1_epi32(0xff), _mm256_set1_epi32(0xffff));
    let round = _mm256_set1_epi32(1 << (2 * FRAC_BITS - 1));
    let outside = _mm256_set1_epi32(OUTSIDE as i32);
    // index < limit, unsigned: min(index, limit - 1) == index.
    let last = _mm256_set1_epi32((limit - 1) as i32);
    let down = _mm256_set1_epi32(raw_w as i32);
    // The low byte of each 32-bit lane to the lane's first four bytes, in each 128-bit half.
    let bytes = _mm256_setr_epi8(
        0, 4, 8, 12, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, 0, 4, 8, 12, -1, -1, -1, -1, -1, -1, -1, -1, -1,
        -1, -1, -1,
    );
    let mut x = 0;
    while x + LANES <= n {
        // SAFETY: 8 entries of 8 bytes (repr(C): index, frac_x, frac_y) from x, inside
        // `entries` as x + 8 <= n.
        let (lo, hi) = unsafe {
            let at = entries.as_ptr().add(x).cast::<__m256i>();
            (_mm256_loadu_si256(at), _mm256_loadu_si256(at.add(1)))
        };
        let (lo, hi) = (_mm256_permutevar8x32_epi32(lo, split), _mm256_permutevar8x32_epi32(hi, split));
        let index = _mm256_permute2x128_si256::<0x20>(lo, hi);
        let frac = _mm256_permute2x128_si256::<0x31>(lo, hi);
        let out = _mm256_cmpeq_epi32(index, outside);
        let inside = _mm256_cmpeq_epi32(_mm256_min_epu32(index, last), index);
        if _mm256_movemask_epi8(_mm256_or_si256(out, inside)) != -1 {
            one_at_a_time(entries, rows, x, x + LANES);
            x += LANES;
            continue;
        }
        let index = _mm256_andnot_si256(out, index);
        let index_down = _mm256_add_epi32(index, down);
        let (fx, fy) = (_mm256_and_si256(frac, low16), _mm256_srli_epi32::<16>(frac));
        let (gx, gy) = (_mm256_sub_epi32(one, fx), _mm256_sub_epi32(one, fy));
        for (src, row) in srcs.iter().zip(rows.iter_mut()) {
            // SAFETY: every lane's index is below `limit` (outside lanes read at 0), so
            // both four-byte reads lie inside `src`, which holds at least `len` bytes.
            let (top, bottom) = unsafe {
                (
                    _mm256_i32gather_epi32::<1>(src.as_ptr().cast(), index),
                    _mm256_i32gather_epi32::<1>(src.as_ptr().cast(), index_down),
                )
            };
            let (a, b) = (_mm256_and_si256(top, byte), _mm256_and_si256(_mm256_srli_epi32::<8>(top), byte));
            let (c, d) = (_mm256_and_si256(bottom, byte), _mm256_and_si256(_mm256_srli_epi32::<8>(bottom), byte));
            let upper = _mm256_add_epi32(_mm256_mullo_epi32(a, gx), _mm256_mullo_epi32(b, fx));
            let lower = _mm256_add_epi32(_mm256_mullo_epi32(c, gx), _mm256_mullo_epi32(d, fx));
            let v = _mm256_add_epi32(_mm256_mullo_epi32(upper, gy), _mm256_mullo_epi32(lower, fy));
            let v = _mm256_srli_epi32::<{ 2 * FRAC_BITS as i32 }>(_mm256_add_epi32(v, round));
            let v = _mm256_shuffle_epi8(_mm256_andnot_si256(out, v), bytes);
            let packed = _mm_unpacklo_epi32(_mm256_castsi256_si128(v), _mm256_extracti128_si256::<1>(v));
            // SAFETY: 8 bytes into row[x .. x + 8], inside as x + 8 <= n <= row.len().
            unsafe { _mm_storel_epi64(row.as_mut_ptr().add(x).cast(), packed) };
        }
        x += LANES;
    }
    one_at_a_time(entries, rows, x, n);
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A random table over `raw_w` x `raw_h` images: outside entries, indices up to the last
    /// pixel whose 2 x 2 neighbourhood exists (so near the end of the buffer, where the
    /// vector reads would pass it), every fraction.
    fn random_entries(rng: &mut ChaCha8Rng, raw_w: usize, raw_h: usize, len: usize) -> Vec<RemapEntry> {
        (0..len)
            .map(|_| {
                let (x, y) = (rng.random_range(0..raw_w - 1), rng.random_range(0..raw_h - 1));
                // Rare, so that most steps of 16 run the vector path.
                let near_end = rng.random_range(0..40) == 0;
                let (x, y) = if near_end { (raw_w - 2, raw_h - 2) } else { (x, y) };
                let index = if rng.random_range(0..5) == 0 { OUTSIDE } else { (y * raw_w + x) as u32 };
                let frac = |rng: &mut ChaCha8Rng| rng.random_range(0..=FRAC_ONE) as u16;
                RemapEntry { index, frac_x: frac(rng), frac_y: frac(rng) }
            })
            .collect()
    }

    /// A row kernel: the sources, the raw width, the row's entries and the output rows.
    type RowKernel = dyn Fn(&[&[u8]], usize, &[RemapEntry], &mut [&mut [u8]]);

    /// The vector kernels this machine runs, each with its lane count.
    type Kernel = (&'static str, usize, Box<RowKernel>);

    fn kernels() -> Vec<Kernel> {
        let mut kernels: Vec<Kernel> = Vec::new();
        #[cfg(target_arch = "x86_64")]
        {
            if let Some(proof) = crate::cpu::Avx512::detect() {
                kernels.push(("avx512", 16, Box::new(move |s, w, e, r| remap_row_wide(proof, s, w, e, r))));
            }
            if let Some(proof) = crate::cpu::Avx2::detect() {
                kernels.push(("avx2", 8, Box::new(move |s, w, e, r| remap_row_avx2(proof, s, w, e, r))));
            }
        }
        kernels
    }

    #[test]
    fn vector_resampling_gives_the_bits_of_one_pixel_at_a_time() {
        for (name, lanes, kernel) in kernels() {
            vector_kernel_gives_the_bits_of_one_pixel_at_a_time(name, lanes, &*kernel);
        }
    }

    fn vector_kernel_gives_the_bits_of_one_pixel_at_a_time(name: &str, lanes: usize, kernel: &RowKernel) {
        // Rows of awkward lengths, one shot and several at once.
        let mut rng = ChaCha8Rng::seed_from_u64(17);
        let mut vector_steps = 0;
        for (raw_w, raw_h) in [(2usize, 2usize), (3, 2), (17, 5), (64, 48), (5, 40)] {
            for shots in [1usize, 3, 12] {
                let srcs: Vec<Vec<u8>> =
                    (0..shots).map(|_| (0..raw_w * raw_h).map(|_| rng.random_range(0..=255u8)).collect()).collect();
                let views: Vec<&[u8]> = srcs.iter().map(|s| &s[..]).collect();
                for len in [0usize, 1, 15, 16, 17, 33, 64, 100] {
                    let entries = random_entries(&mut rng, raw_w, raw_h, len);
                    let mut fast: Vec<Vec<u8>> = vec![vec![9u8; len]; shots];
                    let mut fast_rows: Vec<&mut [u8]> = fast.iter_mut().map(|r| &mut r[..]).collect();
                    kernel(&views, raw_w, &entries, &mut fast_rows);
                    for (s, src) in srcs.iter().enumerate() {
                        let mut slow = vec![7u8; len];
                        remap_pixels(src, raw_w, &entries, &mut slow);
                        assert_eq!(fast[s], slow, "{name}: {raw_w} x {raw_h}, {len} pixels, shot {s} of {shots}");
                    }
                    let limit = (raw_w * raw_h).saturating_sub(raw_w + 3);
                    let fits = |e: &RemapEntry| e.index == OUTSIDE || (e.index as usize) < limit;
                    vector_steps += entries.chunks_exact(lanes).filter(|c| limit > 0 && c.iter().all(fits)).count();
                }
            }
        }
        assert!(vector_steps > 60, "{name}: only {vector_steps} steps of {lanes} took the vector path");
    }

    #[test]
    fn shots_resampled_together_are_each_resampled_alone() {
        // More shots than one pass takes, one raw image of the wrong size (black), and
        // outputs that start at other sizes or hold stale pixels.
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let (raw_w, raw_h) = (37usize, 29usize);
        let (w, h) = (41usize, 23usize);
        let map = random_entries(&mut rng, raw_w, raw_h, w * h);
        let shots = SHOTS_PER_PASS + 3;
        let mut raws: Vec<GrayImage> = (0..shots)
            .map(|_| {
                let data = (0..raw_w * raw_h).map(|_| rng.random_range(0..=255u8)).collect();
                GrayImage::from_vec(raw_w, raw_h, data).unwrap()
            })
            .collect();
        raws[4] = GrayImage::new(raw_w + 1, raw_h, 200);
        let mut outs: Vec<GrayImage> = (0..shots).map(|i| GrayImage::new(i % 3, 5, 99)).collect();
        outs[7] = GrayImage::new(w, h, 99);
        remap_shots(&map, (raw_w, raw_h), (w, h), &raws, &mut outs);
        for (s, (raw, out)) in raws.iter().zip(&outs).enumerate() {
            assert_eq!((out.width, out.height), (w, h), "shot {s}");
            let mut expected = vec![0u8; w * h];
            if s != 4 {
                for (row, entries) in expected.chunks_mut(w).zip(map.chunks(w)) {
                    remap_pixels(&raw.data, raw_w, entries, row);
                }
            }
            assert_eq!(out.data, expected, "shot {s}");
        }
    }

    #[test]
    fn padded_views_resample_to_the_bits_of_their_rows_back_to_back() {
        use camplace_config::ImageView;
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let (raw_w, raw_h) = (37usize, 29usize);
        let (w, h) = (41usize, 23usize);
        let map = random_entries(&mut rng, raw_w, raw_h, w * h);
        let raws: Vec<GrayImage> = (0..3)
            .map(|_| {
                let data = (0..raw_w * raw_h).map(|_| rng.random_range(0..=255u8)).collect();
                GrayImage::from_vec(raw_w, raw_h, data).unwrap()
            })
            .collect();
        // The same pixels in rows of raw_w + 11 bytes, the padding 255.
        let stride = raw_w + 11;
        let padded: Vec<Vec<u8>> =
            raws.iter().map(|r| (0..raw_h).flat_map(|y| r.row(y).iter().copied().chain([255; 11])).collect()).collect();
        let views: Vec<ImageView<'_, u8>> =
            padded.iter().map(|p| ImageView::new(&p[..p.len() - 11], raw_w, raw_h, stride).unwrap()).collect();
        let mut expected: Vec<GrayImage> = vec![GrayImage::default(); 3];
        let mut got: Vec<GrayImage> = vec![GrayImage::default(); 3];
        remap_shots(&map, (raw_w, raw_h), (w, h), &raws, &mut expected);
        remap_shots(&map, (raw_w, raw_h), (w, h), &views, &mut got);
        assert_eq!(got, expected);
        assert!(expected[0].data.iter().any(|&v| v != 0));
    }
}
