//! The seeded stream the crate's own tests draw their cases from: the same cases on every
//! run, without a dependency. The bits are SplitMix64's (`splitmix.rs`); this adds the
//! ranges the tests draw.

use crate::splitmix::SplitMix64;

/// A SplitMix64 stream from its seed.
pub(crate) struct Draw(SplitMix64);

impl Draw {
    /// The stream seeded `seed`.
    pub(crate) fn new(seed: u64) -> Self {
        Draw(SplitMix64(seed))
    }

    /// The next 64 random bits.
    pub(crate) fn next(&mut self) -> u64 {
        self.0.next_u64()
    }

    /// Uniform in `0..n`.
    pub(crate) fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }

    /// Uniform in [lo, hi).
    pub(crate) fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
}
