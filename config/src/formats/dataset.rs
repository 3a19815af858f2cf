//! Names inside a recorded dataset (docs/architecture.md §3): `frames/NNNN/` folders and
//! the camera images `left.png` (one shot) or `left_00.png` ... `left_11.png`. The
//! simulator writes them and hwio reads them, so both take the names from here.

/// Name of frame `index`'s folder inside `frames/` (`7` -> `"0007"`).
pub fn frame_name(index: u64) -> String {
    format!("{index:04}")
}

/// File name of `side`'s (`"left"`/`"right"`) image `shot` of a frame with `shots` shots.
pub fn image_name(side: &str, shot: usize, shots: usize) -> String {
    if shots == 1 {
        format!("{side}.png")
    } else {
        format!("{side}_{shot:02}.png")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_follow_the_layout() {
        assert_eq!(frame_name(7), "0007");
        assert_eq!(frame_name(12345), "12345");
        assert_eq!(image_name("left", 0, 1), "left.png");
        assert_eq!(image_name("right", 11, 12), "right_11.png");
    }
}
