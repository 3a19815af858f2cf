//! Names inside a recorded dataset (docs/design/interchange-formats.md): `frames/NNNN/` folders and
//! the camera images `left.png` (one shot) or `left_00.png` ... `left_11.png`. The
//! simulator writes them and hwio reads them, so both take the names from here. Also the
//! other files camplace writes into a dataset, so a folder can be told to hold only those.

use std::path::{Path, PathBuf};

/// The frame folders of the dataset `dir` (`frames/NNNN/`), in name order; hidden folders (a
/// frame still being written) are not frames.
pub fn frame_folders(dir: &Path) -> Result<Vec<PathBuf>, crate::Error> {
    let frames = dir.join("frames");
    let entries = std::fs::read_dir(&frames).map_err(|e| crate::Error::io(&frames, &e))?;
    let mut folders: Vec<PathBuf> = entries
        .flatten()
        .filter(|e| !e.file_name().to_string_lossy().starts_with('.'))
        .map(|e| e.path())
        .filter(|p| p.is_dir())
        .collect();
    folders.sort();
    Ok(folders)
}

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

/// The summary of a dataset's poses (`replay`), beside `poses.jsonl`.
pub const DATASET_SUMMARY: &str = "summary.json";

/// Files camplace writes at the top of a dataset besides `background/` and `frames/`: the
/// calibration, and the poses and summary of `estimate --dataset` and `replay`.
pub const DATASET_FILES: [&str; 3] = ["rig.json", "poses.jsonl", "summary.json"];

/// The scene cloud a frame's pose was sought in, written beside its images by `estimate
/// --dataset` and `replay` (world mm, at most [`SCENE_CLOUD_POINTS`] points): what the review
/// page draws in 3D.
pub const SCENE_CLOUD: &str = "scene.ply";
/// Most points a frame's [`SCENE_CLOUD`] keeps.
pub const SCENE_CLOUD_POINTS: usize = 8000;

/// Files camplace writes into a frame folder besides the camera images: the simulator's
/// truth and preview, `reconstruct --dataset`'s outputs and the scene cloud of `estimate`.
pub const FRAME_FILES: [&str; 13] = [
    "truth.json",
    "depth_left.pfm",
    "depth_right.pfm",
    "ids_left.png",
    "ids_right.png",
    "disparity_truth.pfm",
    "preview.png",
    "rectified_left.png",
    "rectified_right.png",
    "disparity.pfm",
    "depth.pfm",
    "cloud.ply",
    SCENE_CLOUD,
];

/// Whether `name` is a camera image's file name as [`image_name`] gives it (`left.png`,
/// `right_07.png`).
pub fn is_image_name(name: &str) -> bool {
    let Some(stem) = name.strip_suffix(".png") else { return false };
    let Some(rest) = stem.strip_prefix("left").or_else(|| stem.strip_prefix("right")) else { return false };
    rest.is_empty() || rest.strip_prefix('_').is_some_and(|n| n.len() == 2 && n.bytes().all(|b| b.is_ascii_digit()))
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
        for shots in [1, 12] {
            for shot in 0..shots {
                assert!(is_image_name(&image_name("left", shot, shots)));
                assert!(is_image_name(&image_name("right", shot, shots)));
            }
        }
        for other in ["left.jpg", "middle.png", "left_1.png", "right_123.png", "left_ab.png", "lefty.png"] {
            assert!(!is_image_name(other), "{other}");
        }
    }
}
