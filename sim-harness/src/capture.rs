//! What each capture of a study is: the noise key of a scenario's frame and the background
//! capture (the scene without tray and items). Both depend only on (seed, scenario), so
//! `render --dataset`, `evaluate` and `replay` see the very same frames.

use camplace_config::Cell;

use crate::scenario::draw_scenario;
use crate::scene::SceneSpec;

/// Noise key of scenario `index` of `seed` (`background` for its background capture).
pub fn noise_key(seed: u64, index: u64, background: bool) -> u64 {
    // SplitMix64 finaliser over the packed inputs: distinct, well-mixed keys.
    let mut z = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ index.rotate_left(21) ^ (background as u64) << 63;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The background capture of a study: scenario 0's lighting without tray and items. The
/// background is captured once per placement, as on a real cell before the first tray.
pub fn background_scene(cell: &Cell, seed: u64) -> SceneSpec {
    draw_scenario(cell, seed, 0).scene().background()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_differ_by_every_input() {
        let k = noise_key(1, 5, false);
        assert_ne!(k, noise_key(2, 5, false));
        assert_ne!(k, noise_key(1, 6, false));
        assert_ne!(k, noise_key(1, 5, true));
        assert_eq!(k, noise_key(1, 5, false));
    }
}
