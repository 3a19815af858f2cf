//! SplitMix64 (Steele, Lea and Flood, 2014): the one definition of its step and its
//! finaliser. The simulator keys its scenes, noise and search steps with the finaliser
//! ([`mix`]); config's tests draw seeded cases from the stream ([`SplitMix64`]). Changing a
//! constant here changes every study ever run.

/// The golden-ratio increment of the stream's state, 2^64 / φ.
pub const GOLDEN_GAMMA: u64 = 0x9E37_79B9_7F4A_7C15;

/// SplitMix64's finaliser: a bijective mix of 64 bits with good avalanche.
#[inline(always)]
pub fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A SplitMix64 stream: the state steps by [`GOLDEN_GAMMA`] and each output is its
/// [`mix`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SplitMix64(pub u64);

impl SplitMix64 {
    /// The next 64 random bits.
    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(GOLDEN_GAMMA);
        mix(self.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The outputs of the stream seeded 1234567 as usually quoted for SplitMix64, checked
    /// with big-integer arithmetic.
    #[test]
    fn the_stream_gives_the_reference_outputs() {
        let mut s = SplitMix64(1234567);
        let got: Vec<u64> = (0..5).map(|_| s.next_u64()).collect();
        assert_eq!(
            got,
            [6457827717110365317, 3203168211198807973, 9817491932198370423, 4593380528125082431, 16408922859458223821]
        );
    }

    /// The finaliser against the same steps written in 128-bit arithmetic, modulo 2^64.
    #[test]
    fn the_finaliser_matches_wide_arithmetic() {
        let wide = |z: u64| {
            let m = |a: u64, b: u64| ((u128::from(a) * u128::from(b)) % (1u128 << 64)) as u64;
            let z = m(z ^ (z >> 30), 0xBF58_476D_1CE4_E5B9);
            let z = m(z ^ (z >> 27), 0x94D0_49BB_1331_11EB);
            z ^ (z >> 31)
        };
        let mut s = SplitMix64(7);
        for z in [0, 1, u64::MAX].into_iter().chain((0..1000).map(|_| s.next_u64())) {
            assert_eq!(mix(z), wide(z), "{z:#x}");
        }
    }
}
