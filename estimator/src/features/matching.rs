//! Feature matching: the k nearest model features of each scene key point by squared L2
//! distance between ECSAD descriptors, then the height check (a scene key point and its
//! model feature must sit at about the same height above the table). Descriptors are
//! compared exactly after quantisation to whole steps of pi/255 rad (see [`quantise`]).
//!
//! The search is a blocked brute force: model descriptors sit in blocks of 16 features laid
//! out dimension-major, so a group of 4 queries times 16 features is a register tile the
//! compiler turns into vector multiply-adds; groups of queries run in parallel and walk the
//! model in cache-sized tiles. Distances use |q|^2 + |m|^2 - 2 q.m, which is exact here:
//! every quantised value is a whole number and every sum stays below 2^24, so f32
//! arithmetic makes no rounding error in any order and the result equals a plain loop's.
//!
//! On CPUs with AVX-512 VNNI the dot products run on bytes instead: the model's quantised
//! values are bytes 0..=255, the query's are shifted to signed bytes q - 128, and one
//! `vpdpbusd` sums 4 dimensions of 16 features at once in exact 32-bit integers;
//! q.m = (q - 128).m + 128 sum(m) restores the product, with sum(m) stored per feature. The
//! distances are the same whole numbers, so every kernel returns the same matches. On CPUs
//! with AVX2 but not AVX-512 the products run on 16-bit words: one `vpmaddwd` multiplies 2
//! dimensions of 8 features and sums each feature's pair into an exact 32-bit integer,
//! twice the work of an 8-lane f32 multiply-add on half the bytes.

use rayon::prelude::*;
use std::f32::consts::PI;

use super::ecsad::{Descriptor, ECSAD_DIM};
#[cfg(target_arch = "x86_64")]
use crate::cpu::{Avx2, Avx512F, Avx512Vnni};
use crate::{Correspondence, Error, ErrorKind, Result};

/// Largest k the matcher keeps per scene key point.
pub const MAX_K: usize = 64;

/// Quantisation steps over 0..pi: 8 bits per bin, 0.7 degrees a step, far finer than the
/// bins' noise, and small enough that 30 squared differences sum exactly in f32.
pub const QUANTISATION_STEPS: f32 = 255.0;

/// Model features per block (one AVX-512 register, two AVX2 ones).
const LANES: usize = 16;

/// Scene key points per register tile.
const TILE_QUERIES: usize = 4;

/// Scene key points per parallel task.
const GROUP: usize = 32;

/// Model blocks per cache tile: 2048 features, about 256 KiB.
const TILE_BLOCKS: usize = 128;

/// Marks a dropped match in the output before compaction.
const DROPPED: u32 = u32::MAX;

/// A descriptor quantised to whole steps of pi/255 rad (values 0..=255 held as f32); a NaN
/// bin reads as flat (pi/2).
pub fn quantise(descriptor: &Descriptor) -> [f32; ECSAD_DIM] {
    descriptor.map(|v| {
        let v = if v.is_nan() { PI / 2.0 } else { v.clamp(0.0, PI) };
        (v * (QUANTISATION_STEPS / PI)).round()
    })
}

/// Squared distance in radians^2 of a squared distance in quantisation steps.
#[inline]
fn to_radians2(steps2: f32) -> f32 {
    steps2 * (PI / QUANTISATION_STEPS) * (PI / QUANTISATION_STEPS)
}

/// 16 model features, dimension-major, with their squared norms (+inf pads a short block).
#[derive(Clone, Copy)]
#[repr(C, align(64))]
struct ModelBlock {
    dims: [[f32; LANES]; ECSAD_DIM],
    norms: [f32; LANES],
}

/// Groups of 4 dimensions in a byte block (30 dimensions and 2 zero pads).
const BYTE_GROUPS: usize = ECSAD_DIM.div_ceil(4);

/// 16 model features as bytes for the VNNI kernel: group g holds dimensions 4g..4g+4 of
/// lane l at bytes 4l..4l+4.
#[derive(Clone, Copy)]
#[repr(C, align(64))]
struct ByteBlock {
    groups: [[u8; 4 * LANES]; BYTE_GROUPS],
    /// |m|^2 - 256 sum(m) per feature: the squared distance is |q|^2 + offset - 2 (q - 128).m.
    /// [`PAD_OFFSET`] for a pad lane of a short block.
    offsets: [i32; LANES],
}

/// Pairs of dimensions in a word block (30 dimensions, 15 pairs).
const WORD_PAIRS: usize = ECSAD_DIM.div_ceil(2);

/// 16 model features as 16-bit words for the AVX2 kernel: pair p holds dimensions 2p and
/// 2p + 1 of lane l at words 2l and 2l + 1.
#[derive(Clone, Copy)]
#[repr(C, align(32))]
struct WordBlock {
    pairs: [[i16; 2 * LANES]; WORD_PAIRS],
    /// |m|^2 per feature: the squared distance is |q|^2 + norm - 2 q.m. [`PAD_OFFSET`] for
    /// a pad lane of a short block.
    norms: [i32; LANES],
}

// The word kernel reads every half row and both halves of the norms with aligned 32-byte loads.
const _: () = assert!((2 * LANES * 2).is_multiple_of(64) && std::mem::offset_of!(WordBlock, norms).is_multiple_of(32));

/// A pad lane's offset: its distance is at least 2^28 - 2^21, beyond [`UNBOUNDED`], so it
/// never enters a top list. (A real squared distance is at most 30 x 255^2 < 2^21, and
/// 2 (q - 128).m lies within ±2^21.)
const PAD_OFFSET: i32 = 1 << 28;

/// The bound a top list that holds fewer than k matches sets: above every real distance,
/// below every pad lane's.
#[cfg(target_arch = "x86_64")]
const UNBOUNDED: i32 = 1 << 26;

// The VNNI kernel reads every row and both per-lane arrays with aligned 64-byte loads.
const _: () = assert!((4 * LANES).is_multiple_of(64) && std::mem::offset_of!(ByteBlock, offsets).is_multiple_of(64));

/// Which build of the search kernel the CPU runs. Each vector build holds the proof that
/// this machine runs its instructions, which only run-time detection makes.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Kernel {
    Baseline,
    #[cfg(target_arch = "x86_64")]
    Avx2(Avx2),
    #[cfg(target_arch = "x86_64")]
    Avx512(Avx512F),
    #[cfg(target_arch = "x86_64")]
    Avx512Vnni(Avx512Vnni),
}

/// Which layout of the model's blocks a kernel reads.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Layout {
    Floats,
    Words,
    Bytes,
}

impl Kernel {
    fn layout(self) -> Layout {
        match self {
            Kernel::Baseline => Layout::Floats,
            #[cfg(target_arch = "x86_64")]
            Kernel::Avx2(_) => Layout::Words,
            #[cfg(target_arch = "x86_64")]
            Kernel::Avx512(_) => Layout::Floats,
            #[cfg(target_arch = "x86_64")]
            Kernel::Avx512Vnni(_) => Layout::Bytes,
        }
    }
}

/// The k best matches of one query so far, sorted by (distance, model index).
#[derive(Clone, Copy)]
struct TopK {
    distance2: [f32; MAX_K],
    model: [u32; MAX_K],
    len: usize,
    /// Distance a candidate must beat: the k-th best, or +inf until k are held.
    worst: f32,
}

impl TopK {
    const EMPTY: TopK = TopK { distance2: [0.0; MAX_K], model: [0; MAX_K], len: 0, worst: f32::INFINITY };

    /// Inserts a candidate that beats `worst`. Candidates arrive in increasing model index,
    /// so placing it after every equal distance keeps ties in index order.
    #[inline]
    fn insert(&mut self, k: usize, d2: f32, model: u32) {
        // Insertion sort's step: each farther entry moves one slot back as the scan passes
        // it (the k-th falls off a full list), in one pass without a call to memmove.
        let mut at = self.len.min(k - 1);
        while at > 0 && self.distance2[at - 1] > d2 {
            self.distance2[at] = self.distance2[at - 1];
            self.model[at] = self.model[at - 1];
            at -= 1;
        }
        self.distance2[at] = d2;
        self.model[at] = model;
        self.len = (self.len + 1).min(k);
        if self.len == k {
            self.worst = self.distance2[k - 1];
        }
    }

    /// The bound of the VNNI kernel's integer compare: the k-th best distance (a whole
    /// number), or [`UNBOUNDED`] until k are held.
    #[cfg(target_arch = "x86_64")]
    #[inline]
    fn bound(&self) -> i32 {
        if self.worst.is_finite() {
            self.worst as i32
        } else {
            UNBOUNDED
        }
    }

    /// Inserts the features of a block whose lanes are set in `below`, in lane order (so
    /// in model index order from `base`), each while it still beats the k-th best; lane l's
    /// distance is `partial[l] + norm`.
    #[cfg(target_arch = "x86_64")]
    #[inline]
    fn insert_lanes(&mut self, k: usize, below: u16, partial: &[i32; LANES], norm: i32, base: u32) {
        let mut lanes = below;
        while lanes != 0 {
            let l = lanes.trailing_zeros() as usize;
            lanes &= lanes - 1;
            // Below 2^24, so exact in f32.
            let d2 = (partial[l] + norm) as f32;
            if d2 < self.worst {
                self.insert(k, d2, base + l as u32);
            }
        }
    }
}

/// k-nearest-neighbour matcher over a model's descriptors, built once per model.
#[derive(Clone)]
pub struct FeatureMatcher {
    blocks: Vec<ModelBlock>,
    word_blocks: Vec<WordBlock>,
    byte_blocks: Vec<ByteBlock>,
    heights: Vec<f32>,
    kernel: Kernel,
    /// Quantised scene descriptors and their squared norms, reused from frame to frame.
    queries: Vec<[f32; ECSAD_DIM]>,
    query_norms: Vec<f32>,
}

impl std::fmt::Debug for FeatureMatcher {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FeatureMatcher").field("features", &self.heights.len()).field("kernel", &self.kernel).finish()
    }
}

impl FeatureMatcher {
    /// A matcher over model `descriptors`, each with its feature's height above the table
    /// (z in the tray frame), mm, searched by the fastest kernel this CPU runs.
    pub fn new(descriptors: &[Descriptor], heights: &[f32]) -> Result<Self> {
        Self::with_kernel(descriptors, heights, Self::detect())
    }

    /// [`FeatureMatcher::new`] with `kernel`; only the blocks it reads are laid out (bytes
    /// for the VNNI kernel, words for the AVX2 one, f32 for the others).
    fn with_kernel(descriptors: &[Descriptor], heights: &[f32], kernel: Kernel) -> Result<Self> {
        if descriptors.len() != heights.len() {
            return Err(Error::new(
                ErrorKind::Model,
                format!("matcher: {} model descriptors but {} heights", descriptors.len(), heights.len()),
            ));
        }
        if descriptors.len() >= u32::MAX as usize {
            return Err(Error::new(ErrorKind::Model, "matcher: too many model features for u32 indices"));
        }
        let layout = kernel.layout();
        let count = |l: Layout| if layout == l { descriptors.len().div_ceil(LANES) } else { 0 };
        let empty = ModelBlock { dims: [[0.0; LANES]; ECSAD_DIM], norms: [f32::INFINITY; LANES] };
        let mut blocks = vec![empty; count(Layout::Floats)];
        let empty = WordBlock { pairs: [[0; 2 * LANES]; WORD_PAIRS], norms: [PAD_OFFSET; LANES] };
        let mut word_blocks = vec![empty; count(Layout::Words)];
        let empty = ByteBlock { groups: [[0; 4 * LANES]; BYTE_GROUPS], offsets: [PAD_OFFSET; LANES] };
        let mut byte_blocks = vec![empty; count(Layout::Bytes)];
        for (i, d) in descriptors.iter().enumerate() {
            let (q, lane) = (quantise(d), i % LANES);
            let norm = q.iter().fold(0i32, |n, &v| n + (v * v) as i32);
            match layout {
                Layout::Bytes => {
                    let block = &mut byte_blocks[i / LANES];
                    for (dim, &v) in q.iter().enumerate() {
                        block.groups[dim / 4][4 * lane + dim % 4] = v as u8;
                    }
                    block.offsets[lane] = norm - 256 * q.iter().fold(0i32, |s, &v| s + v as i32);
                }
                Layout::Words => {
                    let block = &mut word_blocks[i / LANES];
                    for (dim, &v) in q.iter().enumerate() {
                        block.pairs[dim / 2][2 * lane + dim % 2] = v as i16;
                    }
                    block.norms[lane] = norm;
                }
                Layout::Floats => {
                    let block = &mut blocks[i / LANES];
                    for (dim, &v) in q.iter().enumerate() {
                        block.dims[dim][lane] = v;
                    }
                    block.norms[lane] = q.iter().map(|v| v * v).sum();
                }
            }
        }
        Ok(FeatureMatcher {
            blocks,
            word_blocks,
            byte_blocks,
            heights: heights.to_vec(),
            kernel,
            queries: Vec::new(),
            query_norms: Vec::new(),
        })
    }

    fn detect() -> Kernel {
        #[cfg(target_arch = "x86_64")]
        {
            if let Some(proof) = Avx512Vnni::detect() {
                return Kernel::Avx512Vnni(proof);
            }
            if let Some(proof) = Avx512F::detect() {
                return Kernel::Avx512(proof);
            }
            if let Some(proof) = Avx2::detect() {
                return Kernel::Avx2(proof);
            }
        }
        Kernel::Baseline
    }

    /// Number of model features.
    pub fn len(&self) -> usize {
        self.heights.len()
    }

    /// Whether the model has no features.
    pub fn is_empty(&self) -> bool {
        self.heights.is_empty()
    }

    /// Replaces `out` with the matches of every scene key point: its `k` nearest model
    /// features (squared L2, ties to the lower model index) whose height differs from
    /// `scene_heights` by at most `height_band` mm; grouped by scene key point in order,
    /// nearest first. `distance2` is in radians^2 of the quantised descriptors.
    pub fn match_into(
        &mut self,
        scene: &[Descriptor],
        scene_heights: &[f32],
        k: usize,
        height_band: f32,
        out: &mut Vec<Correspondence>,
    ) -> Result<()> {
        if scene.len() != scene_heights.len() {
            return Err(Error::new(
                ErrorKind::Input,
                format!("matcher: {} scene descriptors but {} heights", scene.len(), scene_heights.len()),
            ));
        }
        if k == 0 || k > MAX_K {
            return Err(Error::new(ErrorKind::Input, format!("matcher: expected k from 1 to {MAX_K}, got {k}")));
        }
        if scene.len() >= u32::MAX as usize {
            return Err(Error::new(ErrorKind::Input, "matcher: too many scene descriptors for u32 indices"));
        }
        out.clear();
        if scene.is_empty() || self.is_empty() {
            return Ok(());
        }
        self.queries.clear();
        self.query_norms.clear();
        for d in scene {
            let q = quantise(d);
            self.query_norms.push(q.iter().map(|v| v * v).sum());
            self.queries.push(q);
        }
        out.resize(scene.len() * k, Correspondence { scene: DROPPED, model: 0, distance2: 0.0 });
        let blocks = Blocks { floats: &self.blocks, words: &self.word_blocks, bytes: &self.byte_blocks };
        let (heights, kernel) = (&self.heights, self.kernel);
        out.par_chunks_mut(GROUP * k)
            .zip(self.queries.par_chunks(GROUP))
            .zip(self.query_norms.par_chunks(GROUP))
            .zip(scene_heights.par_chunks(GROUP))
            .enumerate()
            .for_each(|(group, (((slots, queries), norms), scene_heights))| {
                let mut tops = [TopK::EMPTY; GROUP];
                search(kernel, blocks, queries, norms, k, &mut tops);
                let first = group * GROUP;
                for (qi, top) in tops.iter().take(queries.len()).enumerate() {
                    let h = scene_heights[qi];
                    for j in 0..top.len {
                        let model = top.model[j];
                        if (h - heights[model as usize]).abs() <= height_band {
                            slots[qi * k + j] = Correspondence {
                                scene: (first + qi) as u32,
                                model,
                                distance2: to_radians2(top.distance2[j]),
                            };
                        }
                    }
                }
            });
        out.retain(|c| c.scene != DROPPED);
        Ok(())
    }
}

/// The model's blocks in every layout (only the chosen kernel's is filled).
#[derive(Clone, Copy)]
struct Blocks<'a> {
    floats: &'a [ModelBlock],
    words: &'a [WordBlock],
    bytes: &'a [ByteBlock],
}

/// Runs the kernel build chosen for this CPU.
fn search(
    kernel: Kernel,
    blocks: Blocks<'_>,
    queries: &[[f32; ECSAD_DIM]],
    norms: &[f32],
    k: usize,
    tops: &mut [TopK],
) {
    match kernel {
        Kernel::Baseline => search_tiles::<false>(blocks.floats, queries, norms, k, tops),
        // SAFETY: the proof shows this machine runs AVX2, all `search_words` enables.
        #[cfg(target_arch = "x86_64")]
        Kernel::Avx2(_) => unsafe { search_words(blocks.words, queries, norms, k, tops) },
        // SAFETY: the proof shows this machine runs AVX-512 F with AVX2 and FMA, all
        // `search_avx512` enables.
        #[cfg(target_arch = "x86_64")]
        Kernel::Avx512(_) => unsafe { search_avx512(blocks.floats, queries, norms, k, tops) },
        // SAFETY: the proof shows this machine runs AVX-512 F, BW and VNNI, all
        // `search_vnni` enables.
        #[cfg(target_arch = "x86_64")]
        Kernel::Avx512Vnni(_) => unsafe { search_vnni(blocks.bytes, queries, norms, k, tops) },
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (blocks.words, blocks.bytes);
}

/// The k nearest model features of up to GROUP queries from byte blocks, walking the model
/// tile by tile as [`search_tiles`] does, 4 dimensions per instruction. Each query sums its
/// even and its odd dimension groups in two registers, so the multiply-adds of a block
/// form eight short independent chains instead of four long ones (measured: a fifth less
/// time than one register a query; eight queries a tile spill registers and lose). Distances
/// are compared as the exact integers they are.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw,avx512vnni")]
// Indexed loops over fixed-size arrays are the shape that keeps the accumulators in registers.
#[allow(clippy::needless_range_loop)]
fn search_vnni(blocks: &[ByteBlock], queries: &[[f32; ECSAD_DIM]], norms: &[f32], k: usize, tops: &mut [TopK]) {
    use std::arch::x86_64::*;
    for (tile, tile_blocks) in blocks.chunks(TILE_BLOCKS).enumerate() {
        let first_block = tile * TILE_BLOCKS;
        for (sub, (qs, ns)) in queries.chunks(TILE_QUERIES).zip(norms.chunks(TILE_QUERIES)).enumerate() {
            // Each query's q - 128 as signed bytes, 4 dimensions to an i32 (pads 0).
            let mut q = [[0i32; BYTE_GROUPS]; TILE_QUERIES];
            for (qi, query) in qs.iter().enumerate() {
                for (g, word) in q[qi].iter_mut().enumerate() {
                    let byte = |j: usize| query.get(4 * g + j).map_or(0, |&v| (v as i32 - 128) as i8 as u8);
                    *word = i32::from_le_bytes([byte(0), byte(1), byte(2), byte(3)]);
                }
            }
            // |q|^2 as the whole number it is (at most 30 x 255^2), and the bound a feature
            // must beat less it: d = |q|^2 + offset - 2 (q - 128).m < bound exactly when
            // offset - 2 (q - 128).m < bound - |q|^2.
            let (n, tops) = (qs.len(), &mut tops[sub * TILE_QUERIES..sub * TILE_QUERIES + qs.len()]);
            let (mut norm, mut rest) = ([0i32; TILE_QUERIES], [0i32; TILE_QUERIES]);
            for qi in 0..n {
                norm[qi] = ns[qi] as i32;
                rest[qi] = tops[qi].bound() - norm[qi];
            }
            for (b, block) in tile_blocks.iter().enumerate() {
                let mut acc = [[_mm512_setzero_si512(); 2]; TILE_QUERIES];
                for g in 0..BYTE_GROUPS {
                    // SAFETY: a 64-byte row of a block, 64-byte aligned (the block is, and its
                    // rows are 64 bytes long; asserted with the type).
                    let m = unsafe { _mm512_load_si512(block.groups[g].as_ptr().cast()) };
                    for qi in 0..TILE_QUERIES {
                        acc[qi][g & 1] = _mm512_dpbusd_epi32(acc[qi][g & 1], m, _mm512_set1_epi32(q[qi][g]));
                    }
                }
                // SAFETY: 16 i32 of a block, 64-byte aligned (asserted with the type).
                let offsets = unsafe { _mm512_load_si512(block.offsets.as_ptr().cast()) };
                // A fixed count of queries, so that the accumulators stay in registers.
                for qi in 0..TILE_QUERIES {
                    if qi >= n {
                        break;
                    }
                    let dot = _mm512_add_epi32(acc[qi][0], acc[qi][1]);
                    let e = _mm512_sub_epi32(offsets, _mm512_slli_epi32::<1>(dot));
                    let below = _mm512_cmplt_epi32_mask(e, _mm512_set1_epi32(rest[qi]));
                    if below != 0 {
                        let mut partial = [0i32; LANES];
                        // SAFETY: 16 i32 into a 16-i32 array.
                        unsafe { _mm512_storeu_si512(partial.as_mut_ptr().cast(), e) };
                        let top = &mut tops[qi];
                        top.insert_lanes(k, below, &partial, norm[qi], ((first_block + b) * LANES) as u32);
                        rest[qi] = top.bound() - norm[qi];
                    }
                }
            }
        }
    }
}

/// The k nearest model features of up to GROUP queries from word blocks, walking the model
/// tile by tile as [`search_tiles`] does, 2 dimensions of 8 features per instruction, each
/// query's 16 lanes in two registers (8 accumulators of the 16 AVX2 registers). Distances
/// are compared as the exact integers they are.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
// Indexed loops over fixed-size arrays are the shape that keeps the accumulators in registers.
#[allow(clippy::needless_range_loop)]
fn search_words(blocks: &[WordBlock], queries: &[[f32; ECSAD_DIM]], norms: &[f32], k: usize, tops: &mut [TopK]) {
    use std::arch::x86_64::*;
    const HALF: usize = LANES / 2;
    for (tile, tile_blocks) in blocks.chunks(TILE_BLOCKS).enumerate() {
        let first_block = tile * TILE_BLOCKS;
        for (sub, (qs, ns)) in queries.chunks(TILE_QUERIES).zip(norms.chunks(TILE_QUERIES)).enumerate() {
            // Each query's values (whole numbers 0..=255) as words, 2 dimensions to an i32.
            let mut q = [[0i32; WORD_PAIRS]; TILE_QUERIES];
            for (qi, query) in qs.iter().enumerate() {
                for (p, pair) in q[qi].iter_mut().enumerate() {
                    let word = |j: usize| query.get(2 * p + j).map_or(0, |&v| v as u32);
                    *pair = (word(0) | word(1) << 16) as i32;
                }
            }
            // As in the VNNI kernel: d = |q|^2 + norm - 2 q.m < bound exactly when
            // norm - 2 q.m < bound - |q|^2.
            let (n, tops) = (qs.len(), &mut tops[sub * TILE_QUERIES..sub * TILE_QUERIES + qs.len()]);
            let (mut norm, mut rest) = ([0i32; TILE_QUERIES], [0i32; TILE_QUERIES]);
            for qi in 0..n {
                norm[qi] = ns[qi] as i32;
                rest[qi] = tops[qi].bound() - norm[qi];
            }
            for (b, block) in tile_blocks.iter().enumerate() {
                let mut acc = [[_mm256_setzero_si256(); 2]; TILE_QUERIES];
                for p in 0..WORD_PAIRS {
                    // SAFETY: two 32-byte halves of a 64-byte row of a block, 32-byte aligned
                    // (the block is, and its rows are 64 bytes long; asserted with the type).
                    let (lo, hi) = unsafe {
                        let row = block.pairs[p].as_ptr();
                        (_mm256_load_si256(row.cast()), _mm256_load_si256(row.add(LANES).cast()))
                    };
                    for qi in 0..TILE_QUERIES {
                        let word = _mm256_set1_epi32(q[qi][p]);
                        acc[qi][0] = _mm256_add_epi32(acc[qi][0], _mm256_madd_epi16(lo, word));
                        acc[qi][1] = _mm256_add_epi32(acc[qi][1], _mm256_madd_epi16(hi, word));
                    }
                }
                // SAFETY: 8 i32 halves of a block's norms, 32-byte aligned (asserted with the type).
                let (norm_lo, norm_hi) = unsafe {
                    let norms = block.norms.as_ptr();
                    (_mm256_load_si256(norms.cast()), _mm256_load_si256(norms.add(HALF).cast()))
                };
                // A fixed count of queries, so that the accumulators stay in registers.
                for qi in 0..TILE_QUERIES {
                    if qi >= n {
                        break;
                    }
                    let bound = _mm256_set1_epi32(rest[qi]);
                    let e_lo = _mm256_sub_epi32(norm_lo, _mm256_slli_epi32::<1>(acc[qi][0]));
                    let e_hi = _mm256_sub_epi32(norm_hi, _mm256_slli_epi32::<1>(acc[qi][1]));
                    let below_lo = _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpgt_epi32(bound, e_lo))) as u16;
                    let below_hi = _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpgt_epi32(bound, e_hi))) as u16;
                    let below = below_lo | below_hi << HALF;
                    if below != 0 {
                        let mut partial = [0i32; LANES];
                        // SAFETY: twice 8 i32 into a 16-i32 array.
                        unsafe {
                            _mm256_storeu_si256(partial.as_mut_ptr().cast(), e_lo);
                            _mm256_storeu_si256(partial.as_mut_ptr().add(HALF).cast(), e_hi);
                        }
                        let top = &mut tops[qi];
                        top.insert_lanes(k, below, &partial, norm[qi], ((first_block + b) * LANES) as u32);
                        rest[qi] = top.bound() - norm[qi];
                    }
                }
            }
        }
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx2,fma")]
fn search_avx512(blocks: &[ModelBlock], queries: &[[f32; ECSAD_DIM]], norms: &[f32], k: usize, tops: &mut [TopK]) {
    search_tiles::<true>(blocks, queries, norms, k, tops)
}

/// The k nearest model features of up to GROUP queries, walking the model tile by tile.
/// `FMA` fuses the multiply-adds, which changes nothing in exact whole-number arithmetic.
// Indexed loops over fixed-size arrays are the shape the vectoriser turns into registers.
#[allow(clippy::needless_range_loop)]
#[inline(always)]
fn search_tiles<const FMA: bool>(
    blocks: &[ModelBlock],
    queries: &[[f32; ECSAD_DIM]],
    norms: &[f32],
    k: usize,
    tops: &mut [TopK],
) {
    for (tile, tile_blocks) in blocks.chunks(TILE_BLOCKS).enumerate() {
        let first_block = tile * TILE_BLOCKS;
        for (sub, (qs, ns)) in queries.chunks(TILE_QUERIES).zip(norms.chunks(TILE_QUERIES)).enumerate() {
            let mut q = [[0.0f32; ECSAD_DIM]; TILE_QUERIES];
            q[..qs.len()].copy_from_slice(qs);
            let tops = &mut tops[sub * TILE_QUERIES..sub * TILE_QUERIES + qs.len()];
            for (b, block) in tile_blocks.iter().enumerate() {
                let mut acc = [[0.0f32; LANES]; TILE_QUERIES];
                for dim in 0..ECSAD_DIM {
                    let m = &block.dims[dim];
                    for qi in 0..TILE_QUERIES {
                        let v = q[qi][dim];
                        for l in 0..LANES {
                            acc[qi][l] = if FMA { v.mul_add(m[l], acc[qi][l]) } else { acc[qi][l] + v * m[l] };
                        }
                    }
                }
                let base = ((first_block + b) * LANES) as u32;
                for (qi, top) in tops.iter_mut().enumerate() {
                    let mut dist = [0.0f32; LANES];
                    let mut any = false;
                    for l in 0..LANES {
                        dist[l] = ns[qi] + block.norms[l] - 2.0 * acc[qi][l];
                        any |= dist[l] < top.worst;
                    }
                    if any {
                        for (l, &d2) in dist.iter().enumerate() {
                            if d2 < top.worst {
                                top.insert(k, d2, base + l as u32);
                            }
                        }
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// The plain obvious version: every distance, a full sort, the first k, the band.
    fn plain(
        model: &[Descriptor],
        model_heights: &[f32],
        scene: &[Descriptor],
        scene_heights: &[f32],
        k: usize,
        band: f32,
    ) -> Vec<Correspondence> {
        let model_q: Vec<_> = model.iter().map(quantise).collect();
        let mut out = Vec::new();
        for (s, d) in scene.iter().enumerate() {
            let q = quantise(d);
            let mut all: Vec<(u64, u32)> = model_q
                .iter()
                .enumerate()
                .map(|(m, v)| (q.iter().zip(v).map(|(a, b)| ((a - b) as i64).pow(2) as u64).sum(), m as u32))
                .collect();
            all.sort_unstable();
            for &(d2, m) in all.iter().take(k) {
                if (scene_heights[s] - model_heights[m as usize]).abs() <= band {
                    out.push(Correspondence { scene: s as u32, model: m, distance2: to_radians2(d2 as f32) });
                }
            }
        }
        out
    }

    fn random_descriptors(rng: &mut ChaCha8Rng, n: usize, centres: &[Descriptor]) -> Vec<Descriptor> {
        // Clustered around a few centres, so near ties and exact ties both occur.
        (0..n)
            .map(|_| {
                let c = centres[rng.random_range(0..centres.len())];
                c.map(|v| (v + rng.random_range(-0.05..0.05f32)).clamp(0.0, PI))
            })
            .collect()
    }

    /// Every kernel build this CPU can run.
    fn supported_kernels() -> Vec<Kernel> {
        #[allow(unused_mut)]
        let mut kernels = vec![Kernel::Baseline];
        #[cfg(target_arch = "x86_64")]
        {
            kernels.extend(Avx2::detect().map(Kernel::Avx2));
            kernels.extend(Avx512F::detect().map(Kernel::Avx512));
            kernels.extend(Avx512Vnni::detect().map(Kernel::Avx512Vnni));
        }
        assert!(kernels.contains(&FeatureMatcher::detect()));
        kernels
    }

    #[test]
    fn fast_search_equals_the_plain_loop() {
        let mut rng = ChaCha8Rng::seed_from_u64(31);
        let centres: Vec<Descriptor> =
            (0..20).map(|_| std::array::from_fn(|_| rng.random_range(0.8..2.3f32))).collect();
        for &(n_model, n_scene, k, band) in
            &[(3001usize, 150usize, 25usize, 20.0f32), (37, 70, 64, 5.0), (5, 9, 25, 100.0), (1000, 33, 1, 1e9)]
        {
            let mut model = random_descriptors(&mut rng, n_model, &centres);
            // The ends of the quantised range, where the byte kernel's shift to signed bytes
            // reaches -128 and +127.
            model[0] = [PI; ECSAD_DIM];
            model[1] = [0.0; ECSAD_DIM];
            let model_heights: Vec<f32> = (0..n_model).map(|_| rng.random_range(0.0..60.0)).collect();
            let mut scene = random_descriptors(&mut rng, n_scene, &centres);
            scene[0] = model[n_model / 2];
            scene[1][3] = f32::NAN;
            scene[2] = [0.0; ECSAD_DIM];
            scene[3] = [PI; ECSAD_DIM];
            scene[4] = std::array::from_fn(|d| if d % 2 == 0 { 0.0 } else { PI });
            let scene_heights: Vec<f32> = (0..n_scene).map(|_| rng.random_range(-10.0..70.0)).collect();
            let mut got = Vec::new();
            let want = plain(&model, &model_heights, &scene, &scene_heights, k, band);
            for kernel in supported_kernels() {
                let mut matcher = FeatureMatcher::with_kernel(&model, &model_heights, kernel).unwrap();
                matcher.match_into(&scene, &scene_heights, k, band, &mut got).unwrap();
                assert_eq!(got, want, "kernel {kernel:?}, model {n_model}, scene {n_scene}, k {k}");
            }
            if band > 1e6 {
                assert_eq!(got.len(), n_scene * k.min(n_model));
            }
        }
    }

    #[test]
    fn bad_inputs_are_errors() {
        let model = vec![[1.0; ECSAD_DIM]; 4];
        assert!(FeatureMatcher::new(&model, &[0.0; 3]).is_err());
        let mut m = FeatureMatcher::new(&model, &[0.0; 4]).unwrap();
        let mut out = Vec::new();
        assert!(m.match_into(&model, &[0.0; 4], 0, 20.0, &mut out).is_err());
        assert!(m.match_into(&model, &[0.0; 4], MAX_K + 1, 20.0, &mut out).is_err());
        assert!(m.match_into(&model, &[0.0; 2], 5, 20.0, &mut out).is_err());
    }
}
