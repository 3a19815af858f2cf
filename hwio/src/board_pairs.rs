//! A folder of calibration board images read and searched (docs/formats.md): its stereo pairs
//! `frames/NNNN/` and the board lying on the table in `table/`, each pair's images read, the
//! board's corners found in them and the pixels dropped, so only the corners of every pair
//! are held (and a worker's pair at a time). The rig's calibration and the hand-eye
//! calibration list and read their views here alone; calibrating from them is the
//! estimator's, pairing views with robot poses the hand-eye command's.

use std::path::{Path, PathBuf};

use camplace_estimator::{calibration::find_board_corners, calibration::CalibrationBoard, calibration::FoundBoardPair};
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
    let mut folders = board_view_folders(images)?;
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
    let found: Vec<ReadPair> = folders.par_iter().map(|f| find_pair(images, f, board, None)).collect::<Result<_>>()?;
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

/// The board views of the calibration folder `images`, `frames/NNNN/` in order (without
/// `table/`).
pub fn board_view_folders(images: &Path) -> Result<Vec<PathBuf>> {
    camplace_config::frame_folders(images).map_err(|e| {
        let e = Error::from(e);
        Error::new(e.kind(), format!("cannot list the board views (frames/NNNN/): {e}"))
    })
}

/// Reads the pairs in `folders` (from [`board_view_folders`] of `images`) and finds `board`
/// in each image, in the folders' order; refuses an image that is not `width` x `height`,
/// the size of the calibrated rig's cameras, before searching it. The hand-eye calibration's
/// views, each taken at one robot pose.
pub fn find_board_views(
    images: &Path,
    folders: &[PathBuf],
    board: &CalibrationBoard,
    (width, height): (usize, usize),
) -> Result<Vec<FoundBoardPair>> {
    let found: Vec<ReadPair> =
        folders.par_iter().map(|f| find_pair(images, f, board, Some((width, height)))).collect::<Result<_>>()?;
    Ok(found.into_iter().map(|p| p.pair).collect())
}

/// One pair as read: its corners, its folder and its images' sizes (left, right).
struct ReadPair {
    pair: FoundBoardPair,
    folder: PathBuf,
    sizes: [(usize, usize); 2],
}

/// The pair in `folder` (`left.png` + `right.png`), named relative to `root`: both images
/// read and searched for the board, then dropped; with the folder and the images' sizes.
/// With `rig_size`, an image of another size is refused before it is searched.
fn find_pair(
    root: &Path,
    folder: &Path,
    board: &CalibrationBoard,
    rig_size: Option<(usize, usize)>,
) -> Result<ReadPair> {
    let name = folder.strip_prefix(root).unwrap_or(folder).display().to_string();
    let side = |side: &str| -> Result<_> {
        let path = folder.join(format!("{side}.png"));
        let image = camplace_config::read_gray(&path)?;
        let size = (image.width, image.height);
        if let Some((width, height)) = rig_size.filter(|&want| want != size) {
            return Err(Error::format(
                &path,
                format!("{}x{} pixels, expected {width}x{height} as the rig's cameras", size.0, size.1),
            ));
        }
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

#[cfg(test)]
mod tests {
    use super::*;

    fn write_pair(dir: &Path, (width, height): (usize, usize)) {
        std::fs::create_dir_all(dir).unwrap();
        for side in ["left", "right"] {
            camplace_config::write_gray(&dir.join(format!("{side}.png")), width, height, &vec![128; width * height])
                .unwrap();
        }
    }

    #[test]
    fn views_are_listed_in_order_and_an_image_not_the_rigs_size_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let board = CalibrationBoard { cols: 9, rows: 6, square_mm: 25.0 };
        for name in ["0001", "0000"] {
            write_pair(&dir.path().join("frames").join(name), (32, 24));
        }
        let folders = board_view_folders(dir.path()).unwrap();
        assert_eq!(folders, [dir.path().join("frames/0000"), dir.path().join("frames/0001")]);
        // Grey images hold no board: each side says so, named relative to the folder.
        let found = find_board_views(dir.path(), &folders, &board, (32, 24)).unwrap();
        assert_eq!(found.iter().map(|p| p.name.as_str()).collect::<Vec<_>>(), ["frames/0000", "frames/0001"]);
        assert!(found[1].left.as_ref().is_err_and(|e| e.starts_with("frames/0001/left.png: ")), "{:?}", found[1]);
        assert!(found[1].right.as_ref().is_err_and(|e| e.starts_with("frames/0001/right.png: ")));
        write_pair(&dir.path().join("frames/0001"), (30, 24));
        let e = find_board_views(dir.path(), &folders, &board, (32, 24)).unwrap_err().to_string();
        let want = format!(
            "{}: 30x24 pixels, expected 32x24 as the rig's cameras",
            dir.path().join("frames/0001/left.png").display()
        );
        assert_eq!(e, want);
    }

    #[test]
    fn a_folder_without_views_says_what_it_expected() {
        let dir = tempfile::tempdir().unwrap();
        let e = board_view_folders(&dir.path().join("nowhere")).unwrap_err().to_string();
        assert!(e.starts_with("cannot list the board views (frames/NNNN/): "), "{e}");
        assert!(e.contains("nowhere"), "{e}");
    }
}
