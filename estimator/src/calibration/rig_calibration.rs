//! The installed rig from stereo pairs of a chessboard: every pair whose board was found in
//! at least one image calibrated jointly (`stereo.rs`), then the world frame from the last
//! pair, the board lying flat on the table at a known pose. Reading the images and finding
//! their corners is the caller's.

use std::time::Instant;

use nalgebra::{Isometry3, Point2};

use super::board::{BoardView, CalibrationBoard, MIN_CALIBRATION_VIEWS};
use super::stereo::{calibrate_stereo, StereoCalibration};
use crate::error::{Error, ErrorKind, Result};
use crate::Rig;

/// One stereo pair of the board: its name (the folder it came from) and the corners found in
/// each image, or why the whole board was not found there.
#[derive(Debug, Clone)]
pub struct FoundBoardPair {
    /// The pair's name, as messages give it (`frames/0003`, `table`).
    pub name: String,
    /// The inner corners in the left image, or why the whole board is not in it.
    pub left: std::result::Result<Vec<Point2<f64>>, String>,
    /// The same in the right image.
    pub right: std::result::Result<Vec<Point2<f64>>, String>,
}

/// What calibrating the installed rig gave.
#[derive(Debug, Clone)]
pub struct RigCalibration {
    /// The calibrated cameras placed in the world (no projector).
    pub rig: Rig,
    /// The stereo calibration behind it: per-view errors, the dropped views, the RMS.
    pub stereo: StereoCalibration,
    /// The name of each pair passed on, by the calibration's view index.
    pub names: Vec<String>,
    /// Why the board was not found, one line per image without it.
    pub not_in_view: Vec<String>,
    /// The calibration's time, s.
    pub seconds: f64,
}

/// Calibrates the rig from `pairs` of `board` images of `width` x `height` pixels, the last
/// pair the table view, whose board lies at `t_world_table_board`. A pair with the board in
/// neither image is left out (its reasons kept in `not_in_view`); the table view must show
/// it whole and must not be dropped as an outlier.
pub fn calibrate_rig(
    pairs: Vec<FoundBoardPair>,
    board: &CalibrationBoard,
    width: usize,
    height: usize,
    t_world_table_board: &Isometry3<f64>,
) -> Result<RigCalibration> {
    let table_name = pairs.last().map(|p| p.name.clone()).unwrap_or_default();
    let mut views = Vec::new();
    let mut names = Vec::new();
    let mut not_in_view = Vec::new();
    for p in pairs {
        // A board wholly in one image only still calibrates that camera (the cameras share
        // only the middle of their views, and the distortion is largest outside it).
        for side in [&p.left, &p.right] {
            if let Err(e) = side {
                not_in_view.push(e.clone());
            }
        }
        if p.left.is_err() && p.right.is_err() {
            if p.name == table_name {
                return Err(Error::new(
                    ErrorKind::Calibration,
                    format!("{}: the table view must show the whole board", p.name),
                ));
            }
            continue;
        }
        views.push(BoardView { left: p.left.ok(), right: p.right.ok() });
        names.push(p.name);
    }
    if views.len() < MIN_CALIBRATION_VIEWS {
        return Err(Error::new(
            ErrorKind::Input,
            format!(
                "the whole board was found in {} pairs (with the table view), expected at least {MIN_CALIBRATION_VIEWS}",
                views.len()
            ),
        ));
    }
    let started = Instant::now();
    let stereo = calibrate_stereo(board, &views, width, height)?;
    let seconds = started.elapsed().as_secs_f64();
    let table_index = names.len() - 1;
    if stereo.views[table_index].dropped {
        return Err(Error::new(
            ErrorKind::Calibration,
            format!("{table_name}: the table view's corners do not fit the calibration; capture it again"),
        ));
    }
    // Kept views keep their order, so the table view, last of all, is the last pose.
    let t_left_table_board =
        *stereo.t_left_board.last().ok_or_else(|| Error::new(ErrorKind::Calibration, "no board pose"))?;
    let t_world_left = t_world_table_board * t_left_table_board.inverse();
    let rig = world_rig(&stereo, &t_world_left);
    Ok(RigCalibration { rig, stereo, names, not_in_view, seconds })
}

/// The calibrated cameras placed in the world by the left camera's pose.
fn world_rig(cal: &StereoCalibration, t_world_left: &Isometry3<f64>) -> Rig {
    let mut left = cal.left.clone();
    left.t_world_camera = *t_world_left;
    let mut right = cal.right.clone();
    right.t_world_camera = t_world_left * cal.right.t_world_camera;
    Rig { left, right, projector: None }
}
