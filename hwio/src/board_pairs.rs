//! A folder of calibration board images read and searched (docs/formats.md): its stereo pairs
//! `frames/NNNN/` and the board lying on the table in `table/`, each pair's images read, the
//! board's corners found in them and the pixels dropped, so only the corners of every pair
//! are held (and a worker's pair at a time). Calibrating from them is the estimator's.

use std::path::{Path, PathBuf};

use camplace_config::GrayImage;
use camplace_estimator::{find_board_corners, CalibrationBoard, FoundBoardPair};
use rayon::prelude::*;

use crate::{Error, Result};

/// The most board views a calibration takes: the joint refinement's time grows with the
/// square of the view count.
pub const MAX_CALIBRATION_VIEWS: usize = 100;

/// The board pairs of a folder, the table view last, all of one image size.
#[derive(Debug, Clone)]
pub struct BoardPairs {
    /// Every pair with its corners, in folder order, `table` last.
    pub pairs: Vec<FoundBoardPair>,
    /// The images' width, pixels.
    pub width: usize,
    /// The images' height, pixels.
    pub height: usize,
}

/// Reads the board pairs of `images` (`frames/NNNN/left.png` + `right.png` and `table/`, as
/// `capture` and `capture --table` write them) and finds `board` in each image; refuses a
/// folder without `table/`, with more than [`MAX_CALIBRATION_VIEWS`] pairs, or with images of
/// different sizes.
pub fn find_board_pairs(images: &Path, board: &CalibrationBoard) -> Result<BoardPairs> {
    let mut folders = camplace_config::frame_folders(images).map_err(|e| {
        let e = Error::from(e);
        Error::new(e.kind(), format!("cannot list the board views (frames/NNNN/): {e}"))
    })?;
    let table = images.join("table");
    if !table.is_dir() {
        return Err(Error::format(
            &table,
            "missing: the world frame comes from one pair of the board lying flat on the table (camplace capture --table)",
        ));
    }
    if folders.len() > MAX_CALIBRATION_VIEWS {
        return Err(Error::format(
            &images.join("frames"),
            format!(
                "{} board views, expected at most {MAX_CALIBRATION_VIEWS} (the joint refinement's time grows with the square of the view count; 20 to 40 views spread over the image calibrate well)",
                folders.len()
            ),
        ));
    }
    folders.push(table);
    let found: Vec<ReadPair> = folders.par_iter().map(|f| find_pair(images, f, board)).collect::<Result<_>>()?;
    let (width, height) = found[0].sizes[0];
    for ReadPair { folder, sizes, .. } in &found {
        for (side, size) in ["left", "right"].iter().zip(sizes) {
            if *size != (width, height) {
                return Err(Error::format(
                    &folder.join(format!("{side}.png")),
                    format!(
                        "{}x{} pixels, expected {width}x{height} as {}",
                        size.0,
                        size.1,
                        found[0].folder.join("left.png").display()
                    ),
                ));
            }
        }
    }
    Ok(BoardPairs { pairs: found.into_iter().map(|p| p.pair).collect(), width, height })
}

/// One pair as read: its corners, its folder and its images' sizes (left, right).
struct ReadPair {
    pair: FoundBoardPair,
    folder: PathBuf,
    sizes: [(usize, usize); 2],
}

/// The pair in `folder` (`left.png` + `right.png`), named relative to `root`: both images
/// read and searched for the board, then dropped; with the folder and the images' sizes.
fn find_pair(root: &Path, folder: &Path, board: &CalibrationBoard) -> Result<ReadPair> {
    let name = folder.strip_prefix(root).unwrap_or(folder).display().to_string();
    let side = |side: &str| -> Result<_> {
        let path = folder.join(format!("{side}.png"));
        let g = camplace_config::read_gray(&path)?;
        let size = (g.width, g.height);
        let mut image = GrayImage::default();
        image.reset(g.width, g.height, 0);
        image.data = g.data;
        Ok((find_board_corners(&image, board).map_err(|e| format!("{name}/{side}.png: {e}")), size))
    };
    let (left, left_size) = side("left")?;
    let (right, right_size) = side("right")?;
    Ok(ReadPair {
        pair: FoundBoardPair { name, left, right },
        folder: folder.to_path_buf(),
        sizes: [left_size, right_size],
    })
}
