//! ELAS-style pixel descriptors, widened to 32 bytes: 3x3 Sobel responses (horizontal and
//! vertical) of a rectified image, contrast-normalised, offset to 128 and clamped to u8,
//! sampled at a fixed pattern (ELAS's 5x5 plus a sparse 9x9 ring); their SAD is the
//! matching cost. The matcher that uses them is `elas`.
//!
//! Contrast normalisation: the projected dots on dark items (albedo ~0.08) give Sobel
//! responses a few times weaker than on the bright tray, which a fixed byte scale quantises
//! to a few levels and which the plane prior then overrules. Each response is divided by
//! the local mean gradient magnitude (a box window), floored near the sensor noise so flat
//! or shadowed areas are not blown up into confident-looking noise. The window sums are
//! integers: a row pass sums shifted copies of each row, a column pass slides down bands
//! of rows; the float scaling is the same expression per pixel whichever way it is summed.
//!
//! Assembly: the 32 samples of a pixel sit at fixed offsets in the two byte planes, so on
//! x86_64 a row is done 16 pixels at a time: sample k of 16 neighbouring pixels is one
//! unaligned 16-byte load, and the 32 x 16 byte matrix of a block, transposed with SSE2
//! unpacks (two 16 x 16 byte transposes), is the block's 16 descriptors. Pixels at the row
//! ends that fill no whole block, and other targets, gather byte by byte.

use rayon::prelude::*;

use crate::GrayImage;

/// One pixel's descriptor.
pub type Descriptor = [u8; LEN];
/// Bytes per descriptor.
pub const LEN: usize = 32;

/// Zero response: what borders and flat areas hold.
const NEUTRAL: u8 = 128;
/// Pixels this close to the border have no full descriptor window (Sobel 1 + pattern 4).
pub const BORDER: usize = 5;

/// The sampling pattern (dx, dy): 11 horizontal-gradient samples, which carry the
/// disparity along rows, then 5 vertical-gradient ones, which tell vertical texture apart.
const DU_PATTERN: [(isize, isize); 11] =
    [(0, -2), (-2, -1), (0, -1), (2, -1), (-1, 0), (0, 0), (1, 0), (-2, 1), (0, 1), (2, 1), (0, 2)];
const DV_PATTERN: [(isize, isize); 5] = [(0, -1), (-1, 0), (0, 0), (1, 0), (0, 1)];
/// A sparse outer ring out to 4 px: ELAS's 5x5 window alone averages too little noise on
/// dark items, where the dots are a few grey levels; a second 16 bytes doubles the cost of
/// a SAD but widens the support to 9x9.
const DU_OUTER: [(isize, isize); 12] =
    [(-4, 0), (4, 0), (0, -4), (0, 4), (-3, -3), (3, -3), (-3, 3), (3, 3), (-4, -2), (4, -2), (-4, 2), (4, 2)];
const DV_OUTER: [(isize, isize); 4] = [(0, -3), (-3, 0), (3, 0), (0, 3)];

/// Half side of the box window whose mean gradient magnitude normalises the responses, px.
const NORM_RADIUS: usize = 4;
/// Mean |Sobel| (raw, per component) the normalisation maps every textured area to, in
/// descriptor units times 4: a bright random-dot area keeps roughly its old amplitude.
const NORM_TARGET: f32 = 64.0;
/// Local mean |Sobel| below which responses are no longer amplified: a few times the
/// response of the simulated sensor noise (std ~2 grey levels after its 3x3 mean).
const NORM_FLOOR: f32 = 12.0;

/// Alignment of the descriptors in a [`DescriptorBuffer`]: a cache line, so that no 32-byte
/// load of one straddles two lines.
const ALIGN: usize = 64;

/// `len` descriptors in 64-byte aligned storage, used as a slice of them. The storage is
/// allocated zeroed, which the allocator does by mapping pages on first use: the rows a
/// matcher never computes (it reads descriptors on some rows only) cost no memory.
#[derive(Debug)]
pub struct DescriptorBuffer {
    bytes: Vec<u8>,
    /// Where the first descriptor starts in `bytes` (below `ALIGN`).
    offset: usize,
    len: usize,
}

impl DescriptorBuffer {
    /// `len` descriptors of zeros.
    fn zeroed(len: usize) -> Self {
        let bytes = vec![0u8; len * LEN + ALIGN - 1];
        let offset = bytes.as_ptr().align_offset(ALIGN).min(ALIGN - 1);
        DescriptorBuffer { bytes, offset, len }
    }
}

impl Clone for DescriptorBuffer {
    fn clone(&self) -> Self {
        // A copy's storage may sit at another offset from a cache line.
        let mut copy = DescriptorBuffer::zeroed(self.len);
        copy.copy_from_slice(self);
        copy
    }
}

impl std::ops::Deref for DescriptorBuffer {
    type Target = [Descriptor];
    fn deref(&self) -> &[Descriptor] {
        // SAFETY: `bytes` holds offset + len x LEN bytes (offset < ALIGN), and a descriptor
        // is a byte array, which needs no alignment.
        unsafe { std::slice::from_raw_parts(self.bytes.as_ptr().add(self.offset).cast(), self.len) }
    }
}

impl std::ops::DerefMut for DescriptorBuffer {
    fn deref_mut(&mut self) -> &mut [Descriptor] {
        // SAFETY: as in `deref`, with the unique borrow of `bytes`.
        unsafe { std::slice::from_raw_parts_mut(self.bytes.as_mut_ptr().add(self.offset).cast(), self.len) }
    }
}

/// Descriptors of one image.
#[derive(Debug, Clone)]
pub struct DescriptorImage {
    pub width: usize,
    pub height: usize,
    pub data: DescriptorBuffer,
}

/// The Sobel and normalisation planes descriptors are sampled from, laid in working memory
/// the matcher lends (the sub-pixel refinement's planes use the same memory after them):
/// the two images of a pair are computed in turn, and every plane row a descriptor reads is
/// written by the same [`DescriptorImage::compute_rows`] call.
#[derive(Debug)]
pub struct SobelPlanes<'a> {
    width: usize,
    height: usize,
    /// Raw Sobel responses (x, y) per pixel.
    gx: &'a mut [i16],
    gy: &'a mut [i16],
    /// |gx| + |gy| per pixel (at most 2 x 4 x 255), the row sums' input.
    mag: &'a mut [u16],
    /// Row-wise box sums of `mag` (at most 9 x 2040).
    row_sum: &'a mut [u16],
    du: &'a mut [u8],
    dv: &'a mut [u8],
    /// Per column, 1 / (2 x the box window's column count there) ([`column_weights`]).
    inv_cols: &'a [f32],
}

/// Bytes of the planes per pixel: four 16-bit planes and two 8-bit ones.
const PLANE_BYTES: usize = 4 * 2 + 2;

impl<'a> SobelPlanes<'a> {
    /// The f32 words of working memory the planes of `width` x `height` images take.
    pub fn words_for(width: usize, height: usize) -> usize {
        (width * height * PLANE_BYTES).div_ceil(4)
    }

    /// The planes of `width` x `height` images in `words` (at least
    /// [`SobelPlanes::words_for`] of them; whatever they hold is overwritten where read),
    /// with the image width's [`column_weights`].
    pub fn in_words(words: &'a mut [f32], inv_cols: &'a [f32], width: usize, height: usize) -> Self {
        let n = width * height;
        let bytes: &mut [u8] = bytemuck::cast_slice_mut(words);
        // The 16-bit planes first, each at an even offset from the words' start.
        let (wide, narrow) = bytes[..n * PLANE_BYTES].split_at_mut(8 * n);
        let (gx, rest) = wide.split_at_mut(2 * n);
        let (gy, rest) = rest.split_at_mut(2 * n);
        let (mag, row_sum) = rest.split_at_mut(2 * n);
        let (du, dv) = narrow.split_at_mut(n);
        SobelPlanes {
            width,
            height,
            gx: bytemuck::cast_slice_mut(gx),
            gy: bytemuck::cast_slice_mut(gy),
            mag: bytemuck::cast_slice_mut(mag),
            row_sum: bytemuck::cast_slice_mut(row_sum),
            du,
            dv,
            inv_cols,
        }
    }
}

/// Per column of a `width`-pixel row, 1 / (2 x the normalisation window's column count
/// there): both components are summed, hence the 2.
pub fn column_weights(width: usize) -> Vec<f32> {
    (0..width).map(|x| 1.0 / (2 * (x.min(NORM_RADIUS) + (width - 1 - x).min(NORM_RADIUS) + 1)) as f32).collect()
}

impl DescriptorImage {
    /// Descriptors of `width` x `height` images.
    pub fn new(width: usize, height: usize) -> Self {
        DescriptorImage { width, height, data: DescriptorBuffer::zeroed(width * height) }
    }

    /// Fills the descriptors of `img` (same size as the buffers) on the rows `wanted`
    /// accepts; the other rows keep what they held (zeros until first computed, and no
    /// memory: see [`DescriptorBuffer`]). The matcher calls [`DescriptorImage::compute_rows`].
    #[cfg(test)]
    pub fn compute(&mut self, img: &GrayImage, planes: &mut SobelPlanes<'_>, wanted: impl Fn(usize) -> bool + Sync) {
        self.compute_rows(img, (0, self.height), planes, wanted);
    }

    /// [`DescriptorImage::compute`] on the rows from `rows.0` to before `rows.1` alone: the
    /// Sobel and normalisation planes are formed only as far as those rows' descriptors
    /// read them.
    pub fn compute_rows(
        &mut self,
        img: &GrayImage,
        rows: (usize, usize),
        planes: &mut SobelPlanes<'_>,
        wanted: impl Fn(usize) -> bool + Sync,
    ) {
        let (w, h) = (self.width, self.height);
        debug_assert!(img.width == w && img.height == h);
        debug_assert!(planes.width == w && planes.height == h);
        if w < 2 * BORDER + 1 || h < 2 * BORDER + 1 {
            self.data.iter_mut().for_each(|d| *d = [NEUTRAL; LEN]);
            return;
        }
        let (lo, hi) = (rows.0.min(h), rows.1.min(h));
        if lo >= hi {
            return;
        }
        // A descriptor reads the planes 4 rows either side; a band of the planes reads the
        // Sobel rows NORM_RADIUS + 1 beyond it.
        let bands = (lo.saturating_sub(4) / BAND, (hi + 4).min(h).div_ceil(BAND));
        let sobel_rows = ((bands.0 * BAND).saturating_sub(NORM_RADIUS + 1), (bands.1 * BAND + NORM_RADIUS + 1).min(h));
        let src = &img.data;
        let sobel = planes.gx.par_chunks_mut(w).zip(planes.gy.par_chunks_mut(w)).zip(planes.mag.par_chunks_mut(w));
        sobel.zip(planes.row_sum.par_chunks_mut(w)).enumerate().for_each(|(y, (((gxr, gyr), magr), sumr))| {
            if (sobel_rows.0..sobel_rows.1).contains(&y) {
                sobel_row(src, w, h, y, gxr, gyr, magr, sumr);
            }
        });
        let (gx, gy) = (&*planes.gx, &*planes.gy);
        let (row_sum, inv_cols) = (&*planes.row_sum, planes.inv_cols);
        let normalised = planes.du.par_chunks_mut(BAND * w).zip(planes.dv.par_chunks_mut(BAND * w));
        normalised.enumerate().for_each(|(band, (du, dv))| {
            if (bands.0..bands.1).contains(&band) {
                normalise_band(gx, gy, row_sum, inv_cols, w, h, band * BAND, du, dv);
            }
        });
        let (du, dv) = (&*planes.du, &*planes.dv);
        let wanted = |y: usize| (lo..hi).contains(&y) && wanted(y);
        self.data.par_chunks_mut(w).enumerate().filter(|(y, _)| wanted(*y)).for_each(|(y, row)| {
            if y < BORDER || y + BORDER >= h {
                row.fill([NEUTRAL; LEN]);
                return;
            }
            row[..BORDER].fill([NEUTRAL; LEN]);
            row[w - BORDER..].fill([NEUTRAL; LEN]);
            // Rows y - 4 ..= y + 4 of both planes; a sample (dx, dy) of pixel x is
            // rows[dy + 4][x + dx].
            let du_rows: [&[u8]; 9] = std::array::from_fn(|k| &du[(y + k - 4) * w..(y + k - 3) * w]);
            let dv_rows: [&[u8]; 9] = std::array::from_fn(|k| &dv[(y + k - 4) * w..(y + k - 3) * w]);
            #[cfg(target_arch = "x86_64")]
            let x = assemble_blocks(&du_rows, &dv_rows, row);
            #[cfg(not(target_arch = "x86_64"))]
            let x = BORDER;
            for (x, d) in row.iter_mut().enumerate().take(w - BORDER).skip(x) {
                *d = gather(&du_rows, &dv_rows, x);
            }
        });
    }
}

multiversion! {
    /// Sobel responses, their magnitudes and the magnitudes' row box sums of row `y` of
    /// the `w` x `h` image `src`.
    #[allow(clippy::too_many_arguments)]
    fn sobel_row(
        src: &[u8],
        w: usize,
        h: usize,
        y: usize,
        gxr: &mut [i16],
        gyr: &mut [i16],
        magr: &mut [u16],
        sumr: &mut [u16],
    ) => sobel_row_body
}

#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn sobel_row_body(
    src: &[u8],
    w: usize,
    h: usize,
    y: usize,
    gxr: &mut [i16],
    gyr: &mut [i16],
    magr: &mut [u16],
    sumr: &mut [u16],
) {
    gxr.fill(0);
    gyr.fill(0);
    magr.fill(0);
    if y == 0 || y + 1 >= h {
        sumr.fill(0);
        return;
    }
    let (a, b, c) = (&src[(y - 1) * w..y * w], &src[y * w..(y + 1) * w], &src[(y + 1) * w..(y + 2) * w]);
    let inner = gxr[1..w - 1].iter_mut().zip(&mut gyr[1..w - 1]).zip(&mut magr[1..w - 1]);
    for (x, ((ox, oy), om)) in inner.enumerate() {
        // Pixel x + 1 of the row; its neighbours are x and x + 2.
        let p = |r: &[u8], i: usize| r[i] as i16;
        let gx = (p(a, x + 2) - p(a, x)) + 2 * (p(b, x + 2) - p(b, x)) + (p(c, x + 2) - p(c, x));
        let gy = (p(c, x) + 2 * p(c, x + 1) + p(c, x + 2)) - (p(a, x) + 2 * p(a, x + 1) + p(a, x + 2));
        *ox = gx;
        *oy = gy;
        *om = gx.unsigned_abs() + gy.unsigned_abs();
    }
    box_sums(magr, sumr);
}

/// Rows per band of the normalisation pass and columns per block within a band.
const BAND: usize = 16;
const BLOCK: usize = 64;

multiversion! {
    /// The normalised responses `du`, `dv` of the band of rows from `first`: the band
    /// walks its columns in blocks down the band with the block's vertical window sum kept
    /// on the stack, a row in and a row out per step (exact in integers, so the same sums as
    /// adding up each window).
    #[allow(clippy::too_many_arguments)]
    fn normalise_band(
        gx: &[i16],
        gy: &[i16],
        row_sum: &[u16],
        inv_cols: &[f32],
        w: usize,
        h: usize,
        first: usize,
        du: &mut [u8],
        dv: &mut [u8],
    ) => normalise_band_body
}

#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn normalise_band_body(
    gx: &[i16],
    gy: &[i16],
    row_sum: &[u16],
    inv_cols: &[f32],
    w: usize,
    h: usize,
    first: usize,
    du: &mut [u8],
    dv: &mut [u8],
) {
    let rows = first..first + du.len() / w;
    let row_of = move |y: usize, range: std::ops::Range<usize>| &row_sum[y * w..(y + 1) * w][range];
    let mut sum = [0u32; BLOCK];
    for start in (0..w).step_by(BLOCK) {
        let range = start..start + BLOCK.min(w - start);
        let sum = &mut sum[..range.len()];
        sum.fill(0);
        for yy in first.saturating_sub(NORM_RADIUS)..=(first + NORM_RADIUS).min(h - 1) {
            for (s, &r) in sum.iter_mut().zip(row_of(yy, range.clone())) {
                *s += r as u32;
            }
        }
        for y in rows.clone() {
            let (y0, y1) = (y.saturating_sub(NORM_RADIUS), (y + NORM_RADIUS).min(h - 1));
            let inv_rows = 1.0 / (y1 - y0 + 1) as f32;
            let (gxr, gyr) = (&gx[y * w..(y + 1) * w], &gy[y * w..(y + 1) * w]);
            let out = (y - first) * w..(y - first + 1) * w;
            let (du, dv) = (&mut du[out.clone()][range.clone()], &mut dv[out][range.clone()]);
            for ((((s, &ic), &gxv), &gyv), (ou, ov)) in sum
                .iter()
                .zip(&inv_cols[range.clone()])
                .zip(&gxr[range.clone()])
                .zip(&gyr[range.clone()])
                .zip(du.iter_mut().zip(dv.iter_mut()))
            {
                let mean = *s as f32 * (ic * inv_rows);
                let scale = NORM_TARGET / mean.max(NORM_FLOOR);
                *ou = sobel_byte(gxv as f32 * scale);
                *ov = sobel_byte(gyv as f32 * scale);
            }
            if y + NORM_RADIUS + 1 < h {
                for (s, &r) in sum.iter_mut().zip(row_of(y + NORM_RADIUS + 1, range.clone())) {
                    *s += r as u32;
                }
            }
            if y >= NORM_RADIUS {
                for (s, &r) in sum.iter_mut().zip(row_of(y - NORM_RADIUS, range.clone())) {
                    *s -= r as u32;
                }
            }
        }
    }
}

/// Sums of `m` over the windows of NORM_RADIUS either side, clamped at the row ends (the
/// window's size is divided out later). Inside, the sum of the window's shifted copies of
/// the row, which vectorises where a running sum would not.
#[inline(always)]
fn box_sums(m: &[u16], out: &mut [u16]) {
    let w = m.len();
    let clamped = |x: usize| -> u16 { m[x.saturating_sub(NORM_RADIUS)..=(x + NORM_RADIUS).min(w - 1)].iter().sum() };
    let ends = NORM_RADIUS.min(w.div_ceil(2));
    for x in (0..ends).chain(w - ends..w) {
        out[x] = clamped(x);
    }
    if w > 2 * NORM_RADIUS {
        let inner = &mut out[NORM_RADIUS..w - NORM_RADIUS];
        inner.fill(0);
        for shift in 0..=2 * NORM_RADIUS {
            for (o, &v) in inner.iter_mut().zip(&m[shift..]) {
                *o += v;
            }
        }
    }
}

/// Where byte k of a descriptor comes from: (from dv rather than du, dx, dy), the order of
/// DU_PATTERN, DV_PATTERN, DU_OUTER, DV_OUTER. Both assembly paths read the layout here.
const SAMPLES: [(bool, isize, isize); LEN] = {
    assert!(DU_PATTERN.len() + DV_PATTERN.len() == 16 && DU_OUTER.len() + DV_OUTER.len() == 16);
    let mut out = [(false, 0, 0); LEN];
    let mut k = 0;
    while k < LEN {
        out[k] = if k < DU_PATTERN.len() {
            (false, DU_PATTERN[k].0, DU_PATTERN[k].1)
        } else if k < 16 {
            (true, DV_PATTERN[k - DU_PATTERN.len()].0, DV_PATTERN[k - DU_PATTERN.len()].1)
        } else if k < 16 + DU_OUTER.len() {
            (false, DU_OUTER[k - 16].0, DU_OUTER[k - 16].1)
        } else {
            (true, DV_OUTER[k - 16 - DU_OUTER.len()].0, DV_OUTER[k - 16 - DU_OUTER.len()].1)
        };
        k += 1;
    }
    out
};

/// Pixels one block of the vector assembly fills: a 16-byte register holds one sample of
/// each.
#[cfg(target_arch = "x86_64")]
const LANES: usize = 16;

/// The descriptor of pixel `x` of a row, from that row's 9 neighbouring rows of each plane
/// (`x` at least 4 from both ends).
#[inline]
fn gather(du_rows: &[&[u8]; 9], dv_rows: &[&[u8]; 9], x: usize) -> Descriptor {
    // 9-wide windows centred on x: constant indices below, checked once here.
    let wu: [&[u8; 9]; 9] = du_rows.map(|r| r[x - 4..x + 5].try_into().expect("9 columns"));
    let wv: [&[u8; 9]; 9] = dv_rows.map(|r| r[x - 4..x + 5].try_into().expect("9 columns"));
    std::array::from_fn(|k| {
        let (from_dv, dx, dy) = SAMPLES[k];
        let win = if from_dv { wv[(dy + 4) as usize] } else { wu[(dy + 4) as usize] };
        win[(dx + 4) as usize]
    })
}

/// The descriptors of pixels BORDER .. w - BORDER of `row` in blocks of LANES, as far as
/// whole blocks fit; returns the first pixel left for [`gather`].
#[cfg(target_arch = "x86_64")]
fn assemble_blocks(du_rows: &[&[u8]; 9], dv_rows: &[&[u8]; 9], row: &mut [Descriptor]) -> usize {
    let mut x = BORDER;
    while x + LANES + BORDER <= row.len() {
        assemble_block(du_rows, dv_rows, x, (&mut row[x..x + LANES]).try_into().expect("LANES pixels"));
        x += LANES;
    }
    x
}

/// The descriptors of pixels `x .. x + LANES` of a row (as [`gather`], `x + LANES + 4` at
/// most the row length): sample k of the block is one 16-byte load, so the block is a
/// 32 x 16 byte matrix whose transpose is the 16 descriptors.
#[cfg(target_arch = "x86_64")]
#[inline]
fn assemble_block(du_rows: &[&[u8]; 9], dv_rows: &[&[u8]; 9], x: usize, out: &mut [Descriptor; LANES]) {
    use std::arch::x86_64::{__m128i, _mm_loadu_si128, _mm_storeu_si128};
    // Columns x - 4 .. x + LANES + 4: every sample's 16 bytes, checked once here.
    let wu: [&[u8; LANES + 8]; 9] =
        std::array::from_fn(|i| du_rows[i][x - 4..x + LANES + 4].try_into().expect("window"));
    let wv: [&[u8; LANES + 8]; 9] =
        std::array::from_fn(|i| dv_rows[i][x - 4..x + LANES + 4].try_into().expect("window"));
    let load = |k: usize| -> __m128i {
        let (from_dv, dx, dy) = SAMPLES[k];
        let win = if from_dv { wv[(dy + 4) as usize] } else { wu[(dy + 4) as usize] };
        // SAFETY: SSE2 is part of the x86_64 baseline; |dx| <= 4, so the unaligned 16-byte
        // read starts at offset 0 ..= 8 of a 24-byte window.
        unsafe { _mm_loadu_si128(win.as_ptr().add((dx + 4) as usize).cast()) }
    };
    let mut store = |half: usize, rows: &[__m128i; 16]| {
        for (i, d) in out.iter_mut().enumerate() {
            // SAFETY: an unaligned 16-byte write at offset 0 or 16 of a 32-byte descriptor.
            unsafe { _mm_storeu_si128(d.as_mut_ptr().add(16 * half).cast(), rows[i]) };
        }
    };
    // The halves and their samples spelt out rather than looped over, so that every
    // sample's row and column is a constant and the registers are never copied as arrays.
    let first = [
        load(0),
        load(1),
        load(2),
        load(3),
        load(4),
        load(5),
        load(6),
        load(7),
        load(8),
        load(9),
        load(10),
        load(11),
        load(12),
        load(13),
        load(14),
        load(15),
    ];
    store(0, &transpose16(first));
    let second = [
        load(16),
        load(17),
        load(18),
        load(19),
        load(20),
        load(21),
        load(22),
        load(23),
        load(24),
        load(25),
        load(26),
        load(27),
        load(28),
        load(29),
        load(30),
        load(31),
    ];
    store(1, &transpose16(second));
}

/// Transposes a 16 x 16 byte matrix held one row per register. Interleaving rows i and
/// i + 8 into rows 2i and 2i + 1 rotates the 8-bit (row, column) index of every byte left
/// by one bit; four rounds swap row and column.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn transpose16(r: [std::arch::x86_64::__m128i; 16]) -> [std::arch::x86_64::__m128i; 16] {
    interleave16(&interleave16(&interleave16(&interleave16(&r))))
}

/// One round of [`transpose16`], spelt out as an array literal of constant indices so the
/// sixteen registers stay registers (an array built in a loop was copied through memory).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn interleave16(r: &[std::arch::x86_64::__m128i; 16]) -> [std::arch::x86_64::__m128i; 16] {
    use std::arch::x86_64::{_mm_unpackhi_epi8 as hi, _mm_unpacklo_epi8 as lo};
    // SAFETY: SSE2 is part of the x86_64 baseline; register-only operations.
    unsafe {
        [
            lo(r[0], r[8]),
            hi(r[0], r[8]),
            lo(r[1], r[9]),
            hi(r[1], r[9]),
            lo(r[2], r[10]),
            hi(r[2], r[10]),
            lo(r[3], r[11]),
            hi(r[3], r[11]),
            lo(r[4], r[12]),
            hi(r[4], r[12]),
            lo(r[5], r[13]),
            hi(r[5], r[13]),
            lo(r[6], r[14]),
            hi(r[6], r[14]),
            lo(r[7], r[15]),
            hi(r[7], r[15]),
        ]
    }
}

/// A normalised Sobel response scaled by 1/4 around 128, rounded half up and clamped.
/// Truncating after + 0.5 rather than `round`, a library call per sample on baseline
/// x86_64; clamped in float before an unchecked conversion, because a saturating `as`
/// (to i32 or u8, the same bytes for every f32) is converted one lane at a time there.
#[inline(always)]
// `clamp` would keep a NaN, which the unchecked conversion must not see.
#[allow(clippy::manual_clamp)]
fn sobel_byte(g: f32) -> u8 {
    let v = (g * 0.25 + (NEUTRAL as f32 + 0.5)).max(0.0).min(255.0);
    // SAFETY: v is in 0 ..= 255 (`max` turns NaN into 0).
    unsafe { v.to_int_unchecked::<i32>() as u8 }
}

/// Sum of absolute differences of two descriptors.
#[inline(always)]
pub fn sad(a: &Descriptor, b: &Descriptor) -> i32 {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_add_epi64, _mm_cvtsi128_si32, _mm_loadu_si128, _mm_sad_epu8, _mm_unpackhi_epi64};
        // SAFETY: SSE2 is part of the x86_64 baseline; the loads are unaligned 16-byte reads
        // at offsets 0 and 16 of two 32-byte arrays.
        unsafe {
            let s0 = _mm_sad_epu8(_mm_loadu_si128(a.as_ptr().cast()), _mm_loadu_si128(b.as_ptr().cast()));
            let s1 =
                _mm_sad_epu8(_mm_loadu_si128(a.as_ptr().add(16).cast()), _mm_loadu_si128(b.as_ptr().add(16).cast()));
            let s = _mm_add_epi64(s0, s1);
            _mm_cvtsi128_si32(_mm_add_epi64(s, _mm_unpackhi_epi64(s, s)))
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        a.iter().zip(b).map(|(&x, &y)| x.abs_diff(y) as i32).sum()
    }
}

/// Texture of a descriptor: the summed Sobel magnitude of its samples.
#[inline(always)]
pub fn texture(a: &Descriptor) -> i32 {
    sad(a, &[NEUTRAL; LEN])
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn sad_matches_plain_loop() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for _ in 0..1000 {
            let a: Descriptor = std::array::from_fn(|_| rng.random());
            let b: Descriptor = std::array::from_fn(|_| rng.random());
            let slow: i32 = a.iter().zip(&b).map(|(&x, &y)| (x as i32 - y as i32).abs()).sum();
            assert_eq!(sad(&a, &b), slow);
        }
    }

    #[test]
    fn descriptor_samples_normalised_sobel_of_a_ramp() {
        // A horizontal ramp of slope 2 has Sobel x response 8 * 2 = 16 everywhere inside and
        // no vertical response; its mean magnitude (16 + 0) / 2 sits below the floor.
        let (w, h) = (20, 12);
        let img = GrayImage::from_vec(w, h, (0..w * h).map(|i| (2 * (i % w)) as u8).collect()).unwrap();
        let mut d = DescriptorImage::new(w, h);
        let (mut words, cols) = (vec![0.0; SobelPlanes::words_for(w, h)], column_weights(w));
        let mut planes = SobelPlanes::in_words(&mut words, &cols, w, h);
        d.compute(&img, &mut planes, |_| true);
        let inner = d.data[5 * w + 9];
        let expect = sobel_byte(16.0 * NORM_TARGET / 8.0f32.max(NORM_FLOOR));
        assert_eq!(&inner[..11], &[expect; 11]);
        assert_eq!(&inner[11..16], &[128; 5]);
        assert_eq!(&inner[16..28], &[expect; 12]);
        assert_eq!(&inner[28..], &[128; 4]);
        assert_eq!(d.data[w + 7], [128; LEN], "border rows are neutral");
        assert_eq!(texture(&inner), 23 * (expect as i32 - 128));
    }

    /// The 3x3 Sobel responses (x, y) of pixel (x, y) from their definition; zero on the
    /// image border.
    fn sobel_at(img: &GrayImage, x: usize, y: usize) -> (i32, i32) {
        let (w, h) = (img.width, img.height);
        if x == 0 || y == 0 || x + 1 >= w || y + 1 >= h {
            return (0, 0);
        }
        let px = |x: usize, y: usize| img.get(x, y) as i32;
        let gx = px(x + 1, y - 1) - px(x - 1, y - 1) + 2 * (px(x + 1, y) - px(x - 1, y)) + px(x + 1, y + 1)
            - px(x - 1, y + 1);
        let gy = px(x - 1, y + 1) + 2 * px(x, y + 1) + px(x + 1, y + 1)
            - (px(x - 1, y - 1) + 2 * px(x, y - 1) + px(x + 1, y - 1));
        (gx, gy)
    }

    #[test]
    fn descriptors_match_a_per_pixel_definition() {
        // Every byte from its definition: Sobel at the sample, divided by the window's mean
        // magnitude (clamped to the image), on random images of awkward sizes.
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        for (w, h) in [(11, 11), (37, 19), (70, 23)] {
            let img = GrayImage::from_vec(w, h, (0..w * h).map(|_| rng.random_range(0..=255u8)).collect()).unwrap();
            let mut d = DescriptorImage::new(w, h);
            let (mut words, cols) = (vec![0.0; SobelPlanes::words_for(w, h)], column_weights(w));
            let mut planes = SobelPlanes::in_words(&mut words, &cols, w, h);
            d.compute(&img, &mut planes, |_| true);
            let sobel = |x: usize, y: usize| sobel_at(&img, x, y);
            let bytes = |x: usize, y: usize| -> (u8, u8) {
                let (mut sum, mut count) = (0, 0);
                for yy in y.saturating_sub(NORM_RADIUS)..=(y + NORM_RADIUS).min(h - 1) {
                    for xx in x.saturating_sub(NORM_RADIUS)..=(x + NORM_RADIUS).min(w - 1) {
                        let (gx, gy) = sobel(xx, yy);
                        sum += gx.abs() + gy.abs();
                        count += 2;
                    }
                }
                let scale = NORM_TARGET / (sum as f32 / count as f32).max(NORM_FLOOR);
                let (gx, gy) = sobel(x, y);
                (sobel_byte(gx as f32 * scale), sobel_byte(gy as f32 * scale))
            };
            let mut differ = 0;
            for y in BORDER..h - BORDER {
                for x in BORDER..w - BORDER {
                    let at = |(dx, dy): (isize, isize)| ((x as isize + dx) as usize, (y as isize + dy) as usize);
                    let mut expect = [NEUTRAL; LEN];
                    for (k, &o) in DU_PATTERN.iter().enumerate() {
                        expect[k] = bytes(at(o).0, at(o).1).0;
                    }
                    for (k, &o) in DV_PATTERN.iter().enumerate() {
                        expect[DU_PATTERN.len() + k] = bytes(at(o).0, at(o).1).1;
                    }
                    for (k, &o) in DU_OUTER.iter().enumerate() {
                        expect[16 + k] = bytes(at(o).0, at(o).1).0;
                    }
                    for (k, &o) in DV_OUTER.iter().enumerate() {
                        expect[16 + DU_OUTER.len() + k] = bytes(at(o).0, at(o).1).1;
                    }
                    // The fast path multiplies by reciprocals: a byte may round the other way.
                    let got = &d.data[y * w + x];
                    assert!(got.iter().zip(&expect).all(|(a, b)| a.abs_diff(*b) <= 1), "({x}, {y})");
                    differ += got.iter().zip(&expect).filter(|(a, b)| a != b).count();
                }
            }
            assert!(differ * 100 < (w - 2 * BORDER) * (h - 2 * BORDER) * LEN, "{differ} bytes off by one");
            // Some rows only: those rows as in the whole image, the others untouched.
            let mut some = DescriptorImage::new(w, h);
            let marker = [7u8; LEN];
            some.data.fill(marker);
            some.compute(&img, &mut planes, |y| y % 3 == 0);
            for (y, (got, all)) in some.data.chunks_exact(w).zip(d.data.chunks_exact(w)).enumerate() {
                if y % 3 == 0 {
                    assert_eq!(got, all, "row {y}");
                } else {
                    assert!(got.iter().all(|g| *g == marker), "row {y} written");
                }
            }
            // A span of rows only (a foreground region), with stale planes from another
            // image: those rows as in the whole image, the others untouched.
            for span in [(0, h / 3), (h / 4, h / 2 + 3), (h / 2, h), (h - 1, h + 5), (3, 3)] {
                let mut part = DescriptorImage::new(w, h);
                part.compute(&GrayImage::from_vec(w, h, vec![99; w * h]).unwrap(), &mut planes, |_| true);
                part.data.fill(marker);
                part.compute_rows(&img, span, &mut planes, |y| y % 2 == 0);
                for (y, (got, all)) in part.data.chunks_exact(w).zip(d.data.chunks_exact(w)).enumerate() {
                    if (span.0..span.1).contains(&y) && y % 2 == 0 {
                        assert_eq!(got, all, "row {y} of span {span:?}");
                    } else {
                        assert!(got.iter().all(|g| *g == marker), "row {y} written, span {span:?}");
                    }
                }
            }
        }
    }

    #[test]
    fn normalised_planes_match_their_definition_exactly() {
        // The planes the descriptors sample, from a brute-force window sum per pixel and the
        // same float expression, with the saturating conversion written out; sizes that end
        // the column blocks and row bands at different places.
        let byte = |g: f32| ((g * 0.25 + (NEUTRAL as f32 + 0.5)) as i32).clamp(0, 255) as u8;
        let mut rng = ChaCha8Rng::seed_from_u64(13);
        for (w, h) in [(11, 11), (37, 19), (65, 33), (70, 23), (129, 17), (640, 48)] {
            let img = GrayImage::from_vec(w, h, (0..w * h).map(|_| rng.random_range(0..=255u8)).collect()).unwrap();
            let mut d = DescriptorImage::new(w, h);
            let (mut words, cols) = (vec![0.0; SobelPlanes::words_for(w, h)], column_weights(w));
            let mut planes = SobelPlanes::in_words(&mut words, &cols, w, h);
            d.compute(&img, &mut planes, |_| true);
            let sobel = |x: usize, y: usize| sobel_at(&img, x, y);
            for y in 0..h {
                for x in 0..w {
                    let rows = y.saturating_sub(NORM_RADIUS)..=(y + NORM_RADIUS).min(h - 1);
                    let cols = x.saturating_sub(NORM_RADIUS)..=(x + NORM_RADIUS).min(w - 1);
                    let sum: i32 = rows
                        .clone()
                        .flat_map(|yy| cols.clone().map(move |xx| (xx, yy)))
                        .map(|(xx, yy)| sobel(xx, yy).0.abs() + sobel(xx, yy).1.abs())
                        .sum();
                    let inv_cols = 1.0 / (2 * cols.count()) as f32;
                    let inv_rows = 1.0 / rows.count() as f32;
                    let scale = NORM_TARGET / (sum as f32 * (inv_cols * inv_rows)).max(NORM_FLOOR);
                    let (gx, gy) = sobel(x, y);
                    let expect = (byte(gx as f32 * scale), byte(gy as f32 * scale));
                    assert_eq!((planes.du[y * w + x], planes.dv[y * w + x]), expect, "{w}x{h} at ({x}, {y})");
                }
            }
        }
    }

    #[test]
    fn assembly_gathers_the_pattern_from_the_planes() {
        // The block assembly against the pattern read one byte at a time, on widths whose
        // 16-pixel blocks end at every kind of place, and on rows too short for one block.
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        for (w, h) in [(11, 11), (20, 12), (25, 13), (26, 13), (37, 19), (41, 16), (70, 23), (100, 40), (640, 48)] {
            let img = GrayImage::from_vec(w, h, (0..w * h).map(|_| rng.random_range(0..=255u8)).collect()).unwrap();
            let mut d = DescriptorImage::new(w, h);
            let (mut words, cols) = (vec![0.0; SobelPlanes::words_for(w, h)], column_weights(w));
            let mut planes = SobelPlanes::in_words(&mut words, &cols, w, h);
            d.compute(&img, &mut planes, |_| true);
            for y in 0..h {
                for x in 0..w {
                    let mut expect = [NEUTRAL; LEN];
                    if (BORDER..w - BORDER).contains(&x) && (BORDER..h - BORDER).contains(&y) {
                        let at = |plane: &[u8], (dx, dy): (isize, isize)| {
                            plane[(y as isize + dy) as usize * w + (x as isize + dx) as usize]
                        };
                        for (k, &o) in DU_PATTERN.iter().enumerate() {
                            expect[k] = at(planes.du, o);
                        }
                        for (k, &o) in DV_PATTERN.iter().enumerate() {
                            expect[DU_PATTERN.len() + k] = at(planes.dv, o);
                        }
                        for (k, &o) in DU_OUTER.iter().enumerate() {
                            expect[16 + k] = at(planes.du, o);
                        }
                        for (k, &o) in DV_OUTER.iter().enumerate() {
                            expect[16 + DU_OUTER.len() + k] = at(planes.dv, o);
                        }
                    }
                    assert_eq!(d.data[y * w + x], expect, "{w}x{h} at ({x}, {y})");
                }
            }
        }
    }

    #[test]
    fn buffers_start_on_a_cache_line_and_copy_whole() {
        for len in [0, 1, 2, 7, 1001] {
            let mut a = DescriptorBuffer::zeroed(len);
            assert_eq!(a.len(), len);
            assert!(a.iter().all(|d| *d == [0; LEN]), "a new buffer holds zeros");
            assert_eq!(a.as_ptr() as usize % ALIGN, 0, "{len} descriptors");
            for (i, d) in a.iter_mut().enumerate() {
                *d = std::array::from_fn(|k| (i * 7 + k) as u8);
            }
            let b = a.clone();
            assert_eq!(b.as_ptr() as usize % ALIGN, 0);
            assert_eq!(&a[..], &b[..]);
        }
    }

    #[test]
    fn descriptors_do_not_depend_on_contrast() {
        // A random texture and a copy at a quarter of its contrast (a dark surface under the
        // same pattern) must give nearly the same descriptors wherever the texture is above
        // the noise floor, unlike a fixed byte scale.
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let (w, h) = (48, 32);
        let coarse: Vec<f32> = (0..(w / 2) * (h / 2)).map(|_| rng.random_range(0.0..200.0)).collect();
        let bright: Vec<f32> = (0..w * h).map(|i| coarse[(i / w / 2) * (w / 2) + (i % w) / 2]).collect();
        let to_img = |scale: f32, off: f32| {
            GrayImage::from_vec(w, h, bright.iter().map(|&v| (off + scale * v).round() as u8).collect()).unwrap()
        };
        let (mut a, mut b) = (DescriptorImage::new(w, h), DescriptorImage::new(w, h));
        let (mut words, cols) = (vec![0.0; SobelPlanes::words_for(w, h)], column_weights(w));
        let mut planes = SobelPlanes::in_words(&mut words, &cols, w, h);
        a.compute(&to_img(1.0, 20.0), &mut planes, |_| true);
        b.compute(&to_img(0.25, 10.0), &mut planes, |_| true);
        let mut worst = 0;
        for y in BORDER + NORM_RADIUS..h - BORDER - NORM_RADIUS {
            for x in BORDER + NORM_RADIUS..w - BORDER - NORM_RADIUS {
                let (da, db) = (&a.data[y * w + x], &b.data[y * w + x]);
                assert!(texture(da) > 48, "the test texture is strong");
                worst = worst.max(sad(da, db));
            }
        }
        // Rounding the quarter-contrast image to integers is the only difference.
        assert!(worst < LEN as i32 * 12, "descriptor SAD between contrasts {worst}");
    }
}
