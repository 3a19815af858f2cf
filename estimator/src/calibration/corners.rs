//! Finding a chessboard's inner corners in one image, in the board's own order. The corner
//! detector and the grid labelling are the `calib-targets` crate's (ChESS X-junctions and
//! a grid proven by geometric invariants); this module turns its labels into board indices
//! and refines each corner to the saddle point of the grey levels.
//!
//! A detected grid is known up to the board's symmetries: which axis is which (settled by
//! the corner counts), a mirror (settled by the printed side facing the camera: the board's
//! x axis turns into its y axis anticlockwise as seen on screen) and a half
//! turn (settled by colour: the square between corners 0 and `cols + 1` is black). A board
//! whose half turn keeps the colours (both corner counts odd or both even) is refused.

use calib_targets::chessboard::ChessboardParams;
use calib_targets::detect::{default_chess_config, detect_chessboard_from_gray_u8};
use nalgebra::{Matrix2, Point2, Vector2};

use super::board::CalibrationBoard;
use crate::{Error, ErrorKind, GrayImage, Result};

/// Iterations of the saddle-point refinement, and the shift that ends it early, pixels.
const REFINE_ITERATIONS: usize = 20;
const REFINE_DONE_PX: f64 = 0.001;

/// The inner corners of `board` in `image`, index `row * cols + col`, refined to sub-pixel
/// saddle points. An error says what was found instead (no board, part of it).
pub fn find_board_corners(image: &GrayImage, board: &CalibrationBoard) -> Result<Vec<Point2<f64>>> {
    let (cols, rows) = (board.cols, board.rows);
    if (cols + rows).is_multiple_of(2) {
        return Err(Error::new(
            ErrorKind::Input,
            format!(
                "a {cols}x{rows} board looks the same turned half way round; use a board with one odd and one even corner count"
            ),
        ));
    }
    let (w, h) = (image.width, image.height);
    let detection = detect_chessboard_from_gray_u8(
        w as u32,
        h as u32,
        &image.data,
        &default_chess_config(),
        &ChessboardParams::default(),
    )
    .map_err(|e| Error::new(ErrorKind::Input, format!("no chessboard found ({e})")))?;
    let labels: Vec<(i64, i64, Point2<f64>)> = detection
        .corners
        .iter()
        .map(|c| (c.grid.u as i64, c.grid.v as i64, Point2::new(c.position.x as f64, c.position.y as f64)))
        .collect();
    let (u_max, v_max) = labels.iter().fold((0, 0), |(a, b), &(u, v, _)| (a.max(u), b.max(v)));
    let (span_u, span_v) = (u_max as usize + 1, v_max as usize + 1);
    let transposed = if (span_u, span_v) == (cols, rows) {
        false
    } else if (span_u, span_v) == (rows, cols) {
        true
    } else {
        return Err(Error::new(
            ErrorKind::Input,
            format!("found a {span_u}x{span_v} grid of corners, expected the whole {cols}x{rows} board"),
        ));
    };
    let mut corners = vec![None; cols * rows];
    for &(u, v, p) in &labels {
        let (i, j) = if transposed { (v as usize, u as usize) } else { (u as usize, v as usize) };
        corners[j * cols + i] = Some(p);
    }
    let found = corners.iter().flatten().count();
    if found != cols * rows {
        return Err(Error::new(
            ErrorKind::Input,
            format!("found {found} of the board's {} corners, expected all", cols * rows),
        ));
    }
    let mut corners: Vec<Point2<f64>> = corners.into_iter().flatten().collect();
    let at = |c: &[Point2<f64>], i: usize, j: usize| c[j * cols + i];
    // The mirror: x turns into y anticlockwise on screen, a negative cross product in
    // image coordinates (rows run down).
    let x_axis = at(&corners, cols - 1, 0) - at(&corners, 0, 0);
    let y_axis = at(&corners, 0, rows - 1) - at(&corners, 0, 0);
    if x_axis.x * y_axis.y - x_axis.y * y_axis.x > 0.0 {
        corners = (0..rows * cols).map(|k| at(&corners, k % cols, rows - 1 - k / cols)).collect();
    }
    // The half turn: squares with (i + j) even are black.
    let mut even_minus_odd = 0.0;
    for j in 0..rows - 1 {
        for i in 0..cols - 1 {
            let centre = (at(&corners, i, j).coords
                + at(&corners, i + 1, j).coords
                + at(&corners, i, j + 1).coords
                + at(&corners, i + 1, j + 1).coords)
                / 4.0;
            let g = bilinear(image, centre.x, centre.y);
            even_minus_odd += if (i + j) % 2 == 0 { g } else { -g };
        }
    }
    if even_minus_odd > 0.0 {
        corners.reverse();
    }
    let window = refine_window(&corners, cols);
    for c in &mut corners {
        *c = refine_saddle(image, *c, window);
    }
    Ok(corners)
}

/// Half side of the refinement window, pixels: a third of the smallest square side seen,
/// so the window never reaches a neighbouring corner, and at least 2.
fn refine_window(corners: &[Point2<f64>], cols: usize) -> usize {
    let mut smallest = f64::INFINITY;
    for (k, c) in corners.iter().enumerate() {
        if k % cols + 1 < cols {
            smallest = smallest.min((corners[k + 1] - c).norm());
        }
        if k + cols < corners.len() {
            smallest = smallest.min((corners[k + cols] - c).norm());
        }
    }
    ((smallest / 3.0).floor() as usize).clamp(2, 12)
}

/// The grey level at (x, y), bilinear; 0 outside the image.
fn bilinear(image: &GrayImage, x: f64, y: f64) -> f64 {
    let (w, h) = (image.width, image.height);
    if !(x >= 0.0 && y >= 0.0 && x < (w - 1) as f64 && y < (h - 1) as f64) {
        return 0.0;
    }
    let (x0, y0) = (x.floor() as usize, y.floor() as usize);
    let (a, b) = (x - x0 as f64, y - y0 as f64);
    let g = |x: usize, y: usize| image.data[y * w + x] as f64;
    let top = g(x0, y0) + a * (g(x0 + 1, y0) - g(x0, y0));
    let bottom = g(x0, y0 + 1) + a * (g(x0 + 1, y0 + 1) - g(x0, y0 + 1));
    top + b * (bottom - top)
}

/// The saddle point near `start`: the point p where every image gradient in the window is
/// orthogonal to the line from p to its pixel, i.e. p minimises
/// sum_q (g_q . (q - p))^2 with Gaussian weights — the same condition OpenCV's cornerSubPix
/// iterates. A corner whose window leaves the image, or whose system is singular, is left
/// where the detector put it.
fn refine_saddle(image: &GrayImage, start: Point2<f64>, half: usize) -> Point2<f64> {
    let (w, h) = (image.width as i64, image.height as i64);
    let r = half as i64;
    let sigma2 = (half as f64 / 1.5).powi(2);
    let mut p = start;
    for _ in 0..REFINE_ITERATIONS {
        let (cx, cy) = (p.x.round() as i64, p.y.round() as i64);
        if cx - r - 1 < 0 || cy - r - 1 < 0 || cx + r + 1 >= w || cy + r + 1 >= h {
            return p;
        }
        let mut a = Matrix2::zeros();
        let mut b = Vector2::zeros();
        for y in cy - r..=cy + r {
            for x in cx - r..=cx + r {
                let (qx, qy) = (x as f64, y as f64);
                // The pixel's gradient at its position; weights centred on the estimate.
                let gx = bilinear(image, qx + 1.0, qy) - bilinear(image, qx - 1.0, qy);
                let gy = bilinear(image, qx, qy + 1.0) - bilinear(image, qx, qy - 1.0);
                let d2 = (qx - p.x).powi(2) + (qy - p.y).powi(2);
                let wgt = (-d2 / (2.0 * sigma2)).exp();
                let gg = Matrix2::new(gx * gx, gx * gy, gx * gy, gy * gy) * wgt;
                a += gg;
                b += gg * Vector2::new(qx, qy);
            }
        }
        let Some(next) = a.try_inverse().map(|inv| inv * b) else {
            return p;
        };
        let next = Point2::from(next);
        let shift = (next - p).norm();
        if !shift.is_finite() || (next - start).norm() > half as f64 {
            return start;
        }
        p = next;
        if shift < REFINE_DONE_PX {
            break;
        }
    }
    p
}
