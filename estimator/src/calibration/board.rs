//! The calibration target and what was seen of it: the chessboard's corner layout, one
//! view's detected corners in each camera that saw the board, and the checks that make them
//! usable. Finding the corners in images is not done here.

use nalgebra::{Isometry3, Point2, Point3};

use crate::error::{Error, ErrorKind, Result};

/// Fewest views of the whole board each camera must have: Zhang's closed form needs two tilted
/// views with zero skew, and a third keeps one bad view from deciding the camera alone.
pub const MIN_CALIBRATION_VIEWS: usize = 3;

/// A chessboard calibration target, counted by its inner corners.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CalibrationBoard {
    /// Inner corners along a row (the board's x axis).
    pub cols: usize,
    /// Inner corners along a column (the board's y axis).
    pub rows: usize,
    /// Side of one square, mm.
    pub square_mm: f64,
}

impl std::str::FromStr for CalibrationBoard {
    type Err = String;

    /// `COLSxROWS@SQUARE_MM`, e.g. `9x6@25`: 2 to 100 inner corners a side, an odd and an
    /// even count (a board with both even or both odd looks the same turned half way round,
    /// so its corners cannot be told apart), a square side above 0 and up to 1000 mm.
    fn from_str(text: &str) -> std::result::Result<CalibrationBoard, String> {
        let expected = "expected COLSxROWS@SQUARE_MM, e.g. 9x6@25 (inner corners, square side in mm)";
        let (counts, square) = text.split_once('@').ok_or(expected)?;
        let (cols, rows) = counts.split_once(['x', 'X']).ok_or(expected)?;
        let count = |s: &str| s.trim().parse::<usize>().ok().filter(|n| (2..=100).contains(n));
        let (Some(cols), Some(rows)) = (count(cols), count(rows)) else {
            return Err(format!("{expected}, with 2 to 100 corners a side"));
        };
        let square_mm = square.trim().parse::<f64>().ok().filter(|v| v.is_finite() && *v > 0.0 && *v <= 1000.0);
        let Some(square_mm) = square_mm else {
            return Err(format!("{expected}, with a square side above 0 and up to 1000 mm"));
        };
        if (cols + rows).is_multiple_of(2) {
            return Err(format!(
                "a {cols}x{rows} board looks the same turned half way round, so its corners cannot be told apart; use one with an odd and an even corner count, e.g. 9x6"
            ));
        }
        Ok(CalibrationBoard { cols, rows, square_mm })
    }
}

impl CalibrationBoard {
    /// Number of inner corners, `cols * rows`.
    pub fn corner_count(&self) -> usize {
        self.cols * self.rows
    }

    /// The inner corners in the board frame (mm, z = 0), corner `row * cols + col` at
    /// (col * square, row * square, 0).
    pub fn object_points(&self) -> Vec<Point3<f64>> {
        (0..self.rows)
            .flat_map(|row| {
                (0..self.cols)
                    .map(move |col| Point3::new(col as f64 * self.square_mm, row as f64 * self.square_mm, 0.0))
            })
            .collect()
    }

    /// The span of the inner corners along the board's x and y axes, mm.
    pub fn extent_mm(&self) -> (f64, f64) {
        ((self.cols - 1) as f64 * self.square_mm, (self.rows - 1) as f64 * self.square_mm)
    }

    fn check(&self) -> Result<()> {
        if self.cols < 2 || self.rows < 2 {
            return Err(Error::new(
                ErrorKind::Input,
                format!("calibration board: {}x{} inner corners, expected at least 2x2", self.cols, self.rows),
            ));
        }
        if !(self.square_mm.is_finite() && self.square_mm > 0.0) {
            return Err(Error::new(
                ErrorKind::Input,
                format!("calibration board: square_mm {}, expected a positive size", self.square_mm),
            ));
        }
        Ok(())
    }
}

/// Where the board lies for the table view: flat on the table (z up), its axes along the
/// world's, its centre on the world origin.
pub fn table_board_pose(board: &CalibrationBoard) -> Isometry3<f64> {
    let (w, h) = board.extent_mm();
    Isometry3::translation(-w / 2.0, -h / 2.0, 0.0)
}

/// The detected corners of one view of the board, pixels, in the board's index order
/// (`row * cols + col`), for each camera that saw the whole board; `None` for a camera that
/// did not. The cameras of a stereo rig share only the middle of their fields of view, so a
/// view seen by one camera alone is what reaches the outer strips and corners of its image.
#[derive(Debug, Clone, PartialEq)]
pub struct BoardView {
    /// Corners in the left image.
    pub left: Option<Vec<Point2<f64>>>,
    /// Corners in the right image.
    pub right: Option<Vec<Point2<f64>>>,
}

/// One camera of the pair, for picking a view's corners and naming it in messages.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Side {
    Left,
    Right,
}

impl Side {
    pub(super) fn name(self) -> &'static str {
        match self {
            Side::Left => "left",
            Side::Right => "right",
        }
    }

    /// The view's corners in this camera's image, if it saw the board.
    pub(super) fn corners(self, view: &BoardView) -> Option<&[Point2<f64>]> {
        match self {
            Side::Left => view.left.as_deref(),
            Side::Right => view.right.as_deref(),
        }
    }
}

/// Checks the board, the image size and every view: at least one camera saw it, and each
/// side present has the count of corners the board has, finite and inside the image (pixel
/// centres at integer coordinates). Then the counts the calibration needs: each camera saw
/// the board in at least `MIN_CALIBRATION_VIEWS` views, and at least one view shows it to
/// both, which is what ties the cameras' frames together.
pub(super) fn check_inputs(board: &CalibrationBoard, views: &[BoardView], width: usize, height: usize) -> Result<()> {
    if width == 0 || height == 0 {
        return Err(Error::new(
            ErrorKind::Input,
            format!("calibration: image size {width}x{height}, expected a width and height of at least 1 pixel"),
        ));
    }
    board.check()?;
    let expected = board.corner_count();
    let (max_x, max_y) = (width as f64 - 0.5, height as f64 - 0.5);
    for (index, view) in views.iter().enumerate() {
        if view.left.is_none() && view.right.is_none() {
            return Err(Error::new(
                ErrorKind::Input,
                format!("calibration view {index}: no corners in either image; expected the board seen by at least one camera"),
            ));
        }
        for side in [Side::Left, Side::Right] {
            let Some(corners) = side.corners(view) else { continue };
            let name = side.name();
            if corners.len() != expected {
                return Err(Error::new(
                    ErrorKind::Input,
                    format!(
                        "calibration view {index} {name}: {} corners, expected {expected} ({}x{} board)",
                        corners.len(),
                        board.cols,
                        board.rows
                    ),
                ));
            }
            for (corner, p) in corners.iter().enumerate() {
                if !(p.x.is_finite() && p.y.is_finite()) {
                    return Err(Error::new(
                        ErrorKind::Input,
                        format!(
                            "calibration view {index} {name} corner {corner}: ({}, {}), expected finite pixel coordinates",
                            p.x, p.y
                        ),
                    ));
                }
                if p.x < -0.5 || p.y < -0.5 || p.x > max_x || p.y > max_y {
                    return Err(Error::new(
                        ErrorKind::Input,
                        format!(
                            "calibration view {index} {name} corner {corner}: ({}, {}), expected a pixel inside the \
                             {width}x{height} image",
                            p.x, p.y
                        ),
                    ));
                }
            }
        }
    }
    for side in [Side::Left, Side::Right] {
        let seen = views.iter().filter(|v| side.corners(v).is_some()).count();
        if seen < MIN_CALIBRATION_VIEWS {
            return Err(Error::new(
                ErrorKind::Input,
                format!(
                    "calibration: the {} camera saw the whole board in {seen} views, expected at least \
                     {MIN_CALIBRATION_VIEWS}",
                    side.name()
                ),
            ));
        }
    }
    if !views.iter().any(|v| v.left.is_some() && v.right.is_some()) {
        return Err(Error::new(
            ErrorKind::Input,
            "calibration: no view shows the board to both cameras; the pose between them needs one",
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_board_parses_from_its_counts_and_square_and_refuses_what_it_cannot_be() {
        assert_eq!("9x6@25".parse(), Ok(CalibrationBoard { cols: 9, rows: 6, square_mm: 25.0 }));
        assert_eq!("7X4@ 12.5".parse(), Ok(CalibrationBoard { cols: 7, rows: 4, square_mm: 12.5 }));
        for (text, said) in [
            ("9x6", "expected COLSxROWS@SQUARE_MM"),
            ("96@25", "expected COLSxROWS@SQUARE_MM"),
            ("1x6@25", "2 to 100 corners a side"),
            ("9x101@25", "2 to 100 corners a side"),
            ("9x6@0", "a square side above 0"),
            ("9x6@1001", "up to 1000 mm"),
            ("9x6@inf", "a square side above 0"),
            ("8x6@25", "a 8x6 board looks the same turned half way round"),
            ("9x7@25", "a 9x7 board"),
        ] {
            let e = text.parse::<CalibrationBoard>().unwrap_err();
            assert!(e.contains(said), "{text}: {e}");
        }
    }
}
