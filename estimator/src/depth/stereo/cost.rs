//! Matching costs, the first step of dense stereo: the SAD of one pixel's descriptor against
//! the other image's at a run of disparities ([`run_costs`], which the support points and
//! the dense pass both score with), the disparity range a search may cover, and the kernel
//! (scalar, AVX2, AVX-512) that runs it. The support points, the prior and the dense pass
//! build on this module; it builds on the descriptors alone.

use super::descriptor::{sad, Descriptor};
use crate::cpu::{Avx2, Avx512};

/// A disparity search range `d_min ..= d_max` that starts at 0 or above. The vector kernels
/// read the other image at x - d (left image) or x + d (right image) through raw pointers,
/// which stay inside the row only for d >= 0, so only [`DisparityRange::new`] makes one.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DisparityRange {
    d_min: i32,
    d_max: i32,
}

impl DisparityRange {
    /// The range, or none unless 0 <= `d_min` <= `d_max`.
    pub fn new(d_min: i32, d_max: i32) -> Option<DisparityRange> {
        (0 <= d_min && d_min <= d_max).then_some(DisparityRange { d_min, d_max })
    }

    /// The lowest disparity searched, px (never negative).
    #[inline(always)]
    pub fn d_min(self) -> i32 {
        self.d_min
    }

    /// The highest disparity searched, px.
    #[inline(always)]
    pub fn d_max(self) -> i32 {
        self.d_max
    }
}

/// Which kernel the dense pass's `match_row` and [`run_costs`] run. A vector kernel holds the proof that
/// this machine runs its instructions, which only run-time detection makes, so no caller
/// can choose one the machine lacks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kernel {
    Scalar,
    /// x86_64 with AVX2.
    Avx2(Avx2),
    /// x86_64 with AVX2 and AVX-512 F, BW, DQ and VL: runs of candidates sixteen at a time.
    Avx512(Avx512),
}

impl Kernel {
    /// The fastest kernel this machine runs.
    pub fn detect() -> Kernel {
        if let Some(proof) = Avx512::detect() {
            return Kernel::Avx512(proof);
        }
        if let Some(proof) = Avx2::detect() {
            return Kernel::Avx2(proof);
        }
        Kernel::Scalar
    }
}

/// SADs of `own` against the other image's descriptors at disparities `d0 ..` into
/// `costs` (one per entry): `other[at - d]` for the left image (`LEFT`), `other[at + d]` for
/// the right one. `other` is the whole image and `at` a pixel of a row at least BORDER rows
/// inside it whose disparities up to d0 + costs.len() - 1 keep the descriptor window
/// inside the row (the wide kernel reads up to fifteen further, still inside the buffer).
/// Panics on a negative `d0` or a read outside `other`.
pub fn run_costs<const LEFT: bool>(
    own: &Descriptor,
    other: &[Descriptor],
    at: usize,
    d0: i32,
    costs: &mut [i32],
    kernel: Kernel,
) {
    assert!(d0 >= 0, "disparity {d0} is negative");
    #[cfg(target_arch = "x86_64")]
    if let Kernel::Avx512(_) = kernel {
        // SAFETY: the proof in the kernel shows this machine runs AVX2 and AVX-512 F, BW and
        // VL; the function checks its reads itself.
        return unsafe { avx512::run_costs_wide::<LEFT>(own, other, at, d0, costs) };
    }
    let _ = kernel;
    for (k, c) in costs.iter_mut().enumerate() {
        let d = d0 as usize + k;
        *c = sad(own, &other[if LEFT { at - d } else { at + d }]);
    }
}

#[cfg(target_arch = "x86_64")]
pub(super) mod avx512 {
    use std::arch::x86_64::*;

    use super::Descriptor;

    /// [`super::run_costs`] sixteen disparities a step. Panics when a read would leave
    /// `other` (the last step reads up to fifteen disparities past the run).
    ///
    /// # Safety
    ///
    /// The machine runs AVX2 and AVX-512 F, BW and VL.
    #[target_feature(enable = "avx2,avx512f,avx512bw,avx512vl")]
    pub(in crate::depth::stereo) unsafe fn run_costs_wide<const LEFT: bool>(
        own: &Descriptor,
        other: &[Descriptor],
        at: usize,
        d0: i32,
        costs: &mut [i32],
    ) {
        let n = costs.len();
        let last = at as i64 + if LEFT { -(d0 as i64 + n as i64 + 15) } else { d0 as i64 + n as i64 + 15 };
        // The reads span `other[at - d0 - n - 14 ..= at - d0]` (left) or
        // `other[at + d0 ..= at + d0 + n + 14]` (right): inside when d0 >= 0 and both ends are.
        assert!(d0 >= 0 && last >= 0 && (last as usize) < other.len() && at < other.len(), "run leaves the image");
        // SAFETY: an unaligned 32-byte read of one descriptor.
        let own = _mm512_broadcast_i64x4(unsafe { _mm256_loadu_si256(own.as_ptr().cast()) });
        let pattern = if LEFT { &WIDE_LEFT } else { &WIDE_RIGHT };
        let base = other.as_ptr().wrapping_add(at);
        let mut lanes = [0i32; 16];
        let mut k0 = 0;
        while k0 < n {
            let d = d0 as usize + k0;
            let from = if LEFT { base.wrapping_sub(d + 15) } else { base.wrapping_add(d) };
            // SAFETY: the sixteen descriptors from `from` lie inside `other` (asserted above).
            let sad = unsafe { sad16(own, from) };
            // SAFETY: an unaligned 64-byte write of [i32; 16].
            unsafe { _mm512_storeu_si512(lanes.as_mut_ptr().cast(), sad) };
            for (l, &off) in pattern.iter().enumerate() {
                if let Some(c) = costs.get_mut(k0 + off as usize) {
                    *c = lanes[l];
                }
            }
            k0 += 16;
        }
    }

    /// Disparity offsets of the sixteen lanes [`sad16`] returns, from its first disparity:
    /// lane 4 Q + m holds register k = m (+ 4 for Q >= 2), its low half for even Q.
    pub(in crate::depth::stereo) const WIDE_RIGHT: [i32; 16] = {
        let mut out = [0; 16];
        let mut lane = 0;
        while lane < 16 {
            let (q, m) = (lane / 4, lane % 4);
            let k = m + if q >= 2 { 4 } else { 0 };
            out[lane] = (2 * k + q % 2) as i32;
            lane += 1;
        }
        out
    };
    /// The same for the left image, whose sixteen descriptors lie in reverse order.
    pub(in crate::depth::stereo) const WIDE_LEFT: [i32; 16] = {
        let mut out = [0; 16];
        let mut lane = 0;
        while lane < 16 {
            out[lane] = 15 - WIDE_RIGHT[lane];
            lane += 1;
        }
        out
    };

    /// SADs of `own` (one descriptor in both 256-bit halves) against the sixteen consecutive
    /// descriptors from `first`, as sixteen i32 in the lane order of [`WIDE_RIGHT`].
    ///
    /// Register k holds descriptors 2k (low half) and 2k + 1 (high half); its SAD has four
    /// 64-bit partial sums per descriptor. Pairs of registers share 64-bit lanes, unpacking
    /// lines up four registers' partial sums per 128-bit lane, and adding 128-bit lanes 0 + 1
    /// (low halves) and 2 + 3 (high halves) totals them.
    ///
    /// # Safety
    ///
    /// The caller enabled AVX-512 F and BW on a machine that runs them, and the sixteen
    /// descriptors from `first` lie inside one buffer.
    #[inline(always)]
    pub(in crate::depth::stereo) unsafe fn sad16(own: __m512i, first: *const Descriptor) -> __m512i {
        // SAFETY: the caller enabled AVX-512 F and BW and vouches for sixteen whole
        // descriptors from `first`.
        unsafe {
            let s = |k: usize| _mm512_sad_epu8(own, _mm512_loadu_si512(first.add(2 * k).cast()));
            let pair = |k: usize| _mm512_or_si512(s(k), _mm512_slli_epi64::<32>(s(k + 1)));
            let (a0, a1, a2, a3) = (pair(0), pair(2), pair(4), pair(6));
            let e0 = _mm512_add_epi32(_mm512_unpacklo_epi64(a0, a1), _mm512_unpackhi_epi64(a0, a1));
            let e1 = _mm512_add_epi32(_mm512_unpacklo_epi64(a2, a3), _mm512_unpackhi_epi64(a2, a3));
            let f = _mm512_shuffle_i64x2::<0b10_00_10_00>(e0, e1);
            let g = _mm512_shuffle_i64x2::<0b11_01_11_01>(e0, e1);
            _mm512_add_epi32(f, g)
        }
    }
}
