//! The seeds of a study: every random stream is keyed by SplitMix64's finaliser over its
//! inputs, so scenario i of seed S is the same scene (and the same camera noise) for every
//! placement — the common random numbers the study's comparisons rest on — and the search's
//! steps draw from streams that depend only on its seed.

use camplace_config::splitmix::mix;

/// The RNG seed of scenario `index` of `seed`: nearby seeds and indices give unrelated
/// streams.
pub(crate) fn scenario_key(seed: u64, index: u64) -> u64 {
    mix(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ index.wrapping_add(0xD1B5_4A32_D192_ED03))
}

/// The RNG seed of scenario `index`'s occluder, apart from its other draws.
pub(crate) fn occluder_key(seed: u64, index: u64) -> u64 {
    mix(scenario_key(seed, index) ^ 0x4F43_434C_5544_4552)
}

/// The RNG seed of scenario `index`'s calibration error, apart from its other draws.
pub(crate) fn calibration_key(seed: u64, index: u64) -> u64 {
    mix(scenario_key(seed, index) ^ 0x4341_4C49_4252_4154)
}

/// Noise key of scenario `index` of `seed` (`background` for its background capture).
pub fn noise_key(seed: u64, index: u64, background: bool) -> u64 {
    // Packed inputs, then the finaliser: distinct, well-mixed keys.
    mix(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ index.rotate_left(21) ^ (background as u64) << 63)
}

/// The key of one image: a frame's noise key, the camera (0 left, 1 right) and the shot.
pub(crate) fn image_key(noise_key: u64, camera: u64, shot: u64) -> u64 {
    mix(mix(mix(noise_key) ^ camera.wrapping_mul(0x9E37_79B9_7F4A_7C15)) ^ shot.wrapping_add(0x632B_E59B_D9B4_E019))
}

/// The hash of `pixel` in the image of `key`, from which its noise is drawn.
#[inline(always)]
pub(crate) fn pixel_hash(key: u64, pixel: u64) -> u64 {
    mix(key ^ pixel.wrapping_mul(0x9E37_79B9_7F4A_7C15))
}

/// The RNG seed of step `k` of the search seeded `seed`.
pub(crate) fn search_step_seed(seed: u64, k: u64) -> u64 {
    mix(seed ^ k.wrapping_add(0x9E37_79B9_7F4A_7C15).wrapping_mul(0xBF58_476D_1CE4_E5B9))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every study ever run drew its scenes, noise and search steps from these numbers.
    #[test]
    fn keys_are_pinned() {
        assert_eq!(mix(0), 0);
        assert_eq!(mix(1), 0x5692_161d_100b_05e5);
        assert_eq!(mix(0xDEAD_BEEF), 0x4e06_2702_ec92_9eea);
        assert_eq!(noise_key(1, 0, false), 0xe220_a839_7b1d_cdaf);
        assert_eq!(noise_key(1, 0, true), 0x481e_c0a2_12a9_f3db);
        assert_eq!(noise_key(1, 5, false), 0x2a3d_7e30_afe9_6313);
        assert_eq!(noise_key(42, 249, false), 0x4cb3_25da_3192_9ce4);
        assert_eq!(scenario_key(1, 0), 0xd28f_0491_68bd_d34c);
        assert_eq!(scenario_key(1, 5), 0x29d1_951c_39db_8b8a);
        assert_eq!(scenario_key(42, 249), 0xbb6a_0e70_ef88_8e6c);
        assert_eq!(image_key(0x1234, 0, 0), 0x8af5_e8ed_0f7c_ab50);
        assert_eq!(image_key(0x1234, 1, 11), 0x63b7_a596_bea1_edb8);
        assert_eq!(search_step_seed(1, 0), 0xda9d_3b5c_5639_f422);
        assert_eq!(search_step_seed(1, u64::MAX), 0xc444_fde7_7584_86ba);
        assert_eq!(search_step_seed(7, u64::MAX - 3), 0xba2a_7144_fcd9_0d05);
    }

    #[test]
    fn noise_keys_differ_by_every_input() {
        let k = noise_key(1, 5, false);
        assert_ne!(k, noise_key(2, 5, false));
        assert_ne!(k, noise_key(1, 6, false));
        assert_ne!(k, noise_key(1, 5, true));
        assert_eq!(k, noise_key(1, 5, false));
    }
}
