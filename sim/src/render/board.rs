//! Calibration boards in simulation: a printed chessboard held in random poses in front of
//! the rig, and once lying flat on the table at the world origin, rendered by both cameras
//! through their lens distortion with the sensor's noise — the images `calibrate` reads,
//! with the truth (the rig, each board pose) beside them.
//!
//! The board is a flat sheet: `cols` x `rows` inner corners `square_mm` apart, the corner
//! squares black where (i + j) is even, counting the square whose far corner is inner
//! corner (0, 0) as (-1, -1), and a white margin of one square around the squares. Each
//! pixel's grey level is the mean over a grid of sub-pixel rays meeting the sheet, under
//! even light; the sensor's noise and mean filter follow, as for scene images.

use std::path::Path;

use camplace_config::{frame_name, Cell, GrayImage, Placement};
use camplace_estimator::{
    calibration::table_board_pose, calibration::CalibrationBoard, geometry::isometry_to_rows, geometry::rig_for,
    geometry::Camera, Rig,
};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::frame_files::write_rig;
use super::noise::{add_noise, mean_filter_to_u8};
use crate::seeds::image_key;
use crate::{Error, Result};

/// Sub-pixel rays per pixel side.
const SUBSAMPLES: usize = 6;
/// Grey level of the black squares and of the white paper under the light.
const BLACK: f32 = 25.0;
const WHITE: f32 = 215.0;
/// Grey level of what lies behind the board (the cell, out of focus and dim).
const BEHIND: f32 = 90.0;
/// How much of the outer squares a pose keeps in the image: the detector needs the squares
/// around each inner corner, not the whole rim, and corners close to the image's edges are
/// what pins the distortion down there.
const OUTER_SQUARES_SEEN: f64 = 0.6;
/// The most poses drawn for one view before giving up on fitting the board in both images.
const MAX_ATTEMPTS: usize = 10_000;

/// The truth of a board render (`board.json`): the board and where it lay in each view.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoardTruth {
    /// Inner corners along the board's x axis.
    pub cols: usize,
    /// Inner corners along its y axis.
    pub rows: usize,
    /// Side of a square, mm.
    pub square_mm: f64,
    /// Per view in `frames/`, in order: board frame -> world.
    #[serde(rename = "T_world_board")]
    pub t_world_board: Vec<[[f64; 4]; 4]>,
    /// The view in `table/`: the board lying on the table, centred on the world origin.
    #[serde(rename = "T_world_table_board")]
    pub t_world_table_board: [[f64; 4]; 4],
}

/// Renders `views` stereo pairs of `board` in random poses seen by the rig of `cell` at
/// `placement` (`seed` draws the poses and the noise), plus the table view, into `out`:
/// `frames/NNNN/left.png` + `right.png`, `table/`, `rig.json` and `board.json`.
pub fn render_board_views(
    out: &Path,
    cell: &Cell,
    placement: &Placement,
    board: &CalibrationBoard,
    views: usize,
    seed: u64,
) -> Result<BoardTruth> {
    let rig = rig_for(placement, &cell.sensor);
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xB0A2_D5EE_D000_0001);
    let poses = draw_board_poses(&rig, board, views, &mut rng).ok_or_else(|| {
        Error::Other(format!(
            "board {}x{}@{}: no pose shows the whole board to both cameras; use a smaller board",
            board.cols, board.rows, board.square_mm
        ))
    })?;
    let table = table_board_pose(board);
    if !fits(&rig, board, &table) {
        return Err(Error::Other(format!(
            "board {}x{}@{}: lying on the table at the world origin it is not wholly in both images; use a smaller board",
            board.cols, board.rows, board.square_mm
        )));
    }
    std::fs::create_dir_all(out).map_err(|e| camplace_config::Error::io(out, &e))?;
    let jobs: Vec<(std::path::PathBuf, Isometry3<f64>, u64)> = poses
        .iter()
        .enumerate()
        .map(|(i, p)| (out.join("frames").join(frame_name(i as u64)), *p, i as u64))
        .chain(std::iter::once((out.join("table"), table, views as u64)))
        .collect();
    render_board_pairs(&rig, &cell.sensor, board, &jobs, seed)?;
    write_rig(&out.join("rig.json"), &rig)?;
    let truth = BoardTruth {
        cols: board.cols,
        rows: board.rows,
        square_mm: board.square_mm,
        t_world_board: poses.iter().map(isometry_to_rows).collect(),
        t_world_table_board: isometry_to_rows(&table),
    };
    let text = serde_json::to_string_pretty(&truth).map_err(|e| Error::Other(e.to_string()))?;
    camplace_config::write_atomic(&out.join("board.json"), text.as_bytes())?;
    Ok(truth)
}

/// Renders one stereo pair of `board` per job (its folder, the board's pose in the world,
/// its index for the noise) through `rig` with the sensor's noise and blur:
/// `left.png` + `right.png` in each folder.
pub(super) fn render_board_pairs(
    rig: &Rig,
    sensor: &camplace_config::Sensor,
    board: &CalibrationBoard,
    jobs: &[(std::path::PathBuf, Isometry3<f64>, u64)],
    seed: u64,
) -> Result<()> {
    let rays = [CornerRays::new(&rig.left), CornerRays::new(&rig.right)];
    jobs.par_iter().try_for_each(|(dir, pose, index)| -> Result<()> {
        std::fs::create_dir_all(dir).map_err(|e| camplace_config::Error::io(dir, &e))?;
        for (side, (camera, rays)) in [(&rig.left, &rays[0]), (&rig.right, &rays[1])].into_iter().enumerate() {
            let mut grey = render_board(camera, rays, board, pose);
            let key = image_key(seed ^ 0xB0A2_D000, side as u64, *index);
            add_noise(&mut grey, key, sensor.noise_amplitude);
            let mut image = GrayImage::default();
            image.reset(camera.width, camera.height, 0);
            let mut scratch = Vec::new();
            mean_filter_to_u8(&grey, camera.width, sensor.blur as usize, &mut scratch, &mut image.data);
            let name = if side == 0 { "left.png" } else { "right.png" };
            camplace_config::write_gray(&dir.join(name), image.width, image.height, &image.data)?;
        }
        Ok(())
    })
}

/// Width and height of the squares' area, mm (inner corners plus one square each side).
pub(super) fn board_extent(board: &CalibrationBoard) -> (f64, f64) {
    board.extent_mm()
}

/// Whether the board's inner corners lie in both images with most of their outer squares.
pub(super) fn fits(rig: &Rig, board: &CalibrationBoard, t_world_board: &Isometry3<f64>) -> bool {
    fits_camera(&rig.left, board, t_world_board) && fits_camera(&rig.right, board, t_world_board)
}

/// Whether the board's inner corners lie in `cam`'s image with most of their outer squares
/// (what the corner detector needs), printed side on.
fn fits_camera(cam: &Camera, board: &CalibrationBoard, t_world_board: &Isometry3<f64>) -> bool {
    let (w, h) = board_extent(board);
    let m = OUTER_SQUARES_SEEN * board.square_mm;
    let corners = [(-m, -m), (w + m, -m), (-m, h + m), (w + m, h + m)];
    // The sheet must face the camera (its +z side is the printed one).
    let to_camera = cam.centre() - t_world_board.translation.vector;
    let facing = (t_world_board.rotation * Vector3::z()).dot(&to_camera.coords) > 0.0;
    facing
        && corners.iter().all(|&(x, y)| {
            let p = t_world_board * Point3::new(x, y, 0.0);
            cam.project(&p).is_some_and(|q| {
                q.x >= 4.0 && q.y >= 4.0 && q.x <= cam.width as f64 - 5.0 && q.y <= cam.height as f64 - 5.0
            })
        })
}

/// Where in an image the views push the board, as fractions of its width and height: the
/// corners first, then the edges' middles and the centre.
const ANCHORS: [(f64, f64); 9] =
    [(0.0, 0.0), (1.0, 1.0), (1.0, 0.0), (0.0, 1.0), (0.5, 0.0), (0.5, 1.0), (0.0, 0.5), (1.0, 0.5), (0.5, 0.5)];
/// Candidate poses drawn per view, of which the one reaching closest to its anchor is kept.
const CANDIDATES: usize = 40;

/// The poses of `views` boards, as a careful person holds them: view k pushes the board
/// towards anchor k of one camera's image (the cameras take turns), so that together the
/// views reach both images' corners and edges, where the distortion is largest and a
/// calibration from central views would only guess. A board pushed into a corner is often
/// wholly in that camera's image only, as in a real cell, where the cameras share just the
/// middle of their views; the centre anchors give views both cameras see whole.
fn draw_board_poses(
    rig: &Rig,
    board: &CalibrationBoard,
    views: usize,
    rng: &mut ChaCha8Rng,
) -> Option<Vec<Isometry3<f64>>> {
    let points = board.object_points();
    let mut poses = Vec::with_capacity(views);
    for k in 0..views {
        let cam = if k % 2 == 0 { &rig.left } else { &rig.right };
        let (fx, fy) = ANCHORS[(k / 2) % ANCHORS.len()];
        let anchor = nalgebra::Point2::new(fx * (cam.width - 1) as f64, fy * (cam.height - 1) as f64);
        let reach = |pose: &Isometry3<f64>| {
            points
                .iter()
                .filter_map(|p| cam.project(&(pose * p)))
                .map(|q| (q - anchor).norm())
                .fold(f64::INFINITY, f64::min)
        };
        let mut best: Option<(f64, Isometry3<f64>)> = None;
        for _ in 0..CANDIDATES {
            let pose = draw_board_pose(cam, board, rng)?;
            let d = reach(&pose);
            if best.is_none_or(|(b, _)| d < b) {
                best = Some((d, pose));
            }
        }
        poses.push(best?.1);
    }
    Some(poses)
}

/// A random board pose wholly in `cam`'s view: its centre on a random ray of the camera at
/// 50 to 100 % of the distance to the table's centre, facing the camera, tilted up to 40
/// degrees and turned up to 30 degrees about its normal.
fn draw_board_pose(cam: &Camera, board: &CalibrationBoard, rng: &mut ChaCha8Rng) -> Option<Isometry3<f64>> {
    let reach = cam.centre().coords.norm();
    let (w, h) = board_extent(board);
    for _ in 0..MAX_ATTEMPTS {
        let u = rng.random_range(0.05..0.95) * cam.width as f64;
        let v = rng.random_range(0.05..0.95) * cam.height as f64;
        let distance = rng.random_range(0.5..1.0) * reach;
        let ray = cam.t_world_camera.rotation * cam.ray(u, v).normalize();
        let centre = cam.centre() + ray * distance;
        // Facing the camera: the board's z axis points back along the ray, then a tilt
        // about a random in-plane axis and a turn about the normal.
        let facing = UnitQuaternion::rotation_between(&Vector3::z(), &-ray)?;
        let tilt_axis = rng.random_range(0.0..std::f64::consts::TAU);
        let tilt = UnitQuaternion::from_axis_angle(
            &nalgebra::Unit::new_normalize(Vector3::new(tilt_axis.cos(), tilt_axis.sin(), 0.0)),
            rng.random_range(0.0..40f64).to_radians(),
        );
        // Start from the camera's own axes so "turned" is relative to the image rows.
        let camera_aligned =
            UnitQuaternion::rotation_between(&(facing * Vector3::x()), &(cam.t_world_camera.rotation * Vector3::x()))
                .map(|r| r * facing)
                .unwrap_or(facing);
        let spin = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), rng.random_range(-30f64..30.0).to_radians());
        let rotation = camera_aligned * tilt * spin;
        let origin = centre - rotation * Vector3::new(w / 2.0, h / 2.0, 0.0);
        let pose = Isometry3::from_parts(Translation3::from(origin.coords), rotation);
        if fits_camera(cam, board, &pose) {
            return Some(pose);
        }
    }
    None
}

/// A camera's rays through its pixel corners (x - 0.5, y - 0.5), in the camera frame with
/// unit depth: the lens distortion is undone once per camera, not once per view.
struct CornerRays {
    width: usize,
    rays: Vec<Vector3<f64>>,
}

impl CornerRays {
    fn new(camera: &Camera) -> CornerRays {
        let (w, h) = (camera.width + 1, camera.height + 1);
        let rays = (0..w * h).map(|i| camera.ray((i % w) as f64 - 0.5, (i / w) as f64 - 0.5)).collect();
        CornerRays { width: w, rays }
    }
}

/// The board's clean grey levels in one camera (before noise).
fn render_board(
    camera: &Camera,
    rays: &CornerRays,
    board: &CalibrationBoard,
    t_world_board: &Isometry3<f64>,
) -> Vec<f32> {
    let t_board_camera = t_world_board.inverse() * camera.t_world_camera;
    let origin = t_board_camera.translation.vector;
    let rotation = t_board_camera.rotation.to_rotation_matrix();
    // Board coordinates (x, y) where each pixel corner's ray meets the sheet z = 0.
    let hits: Vec<Option<[f64; 2]>> = rays
        .rays
        .iter()
        .map(|r| {
            let d = rotation * r;
            let t = -origin.z / d.z;
            (t.is_finite() && t > 0.0).then(|| [origin.x + t * d.x, origin.y + t * d.y])
        })
        .collect();
    let (w, h) = (camera.width, camera.height);
    let stride = rays.width;
    let (bw, bh) = board_extent(board);
    let s = board.square_mm;
    let shade = |x: f64, y: f64| -> f32 {
        if x < -2.0 * s || y < -2.0 * s || x > bw + 2.0 * s || y > bh + 2.0 * s {
            return BEHIND;
        }
        if x < -s || y < -s || x > bw + s || y > bh + s {
            return WHITE;
        }
        let (i, j) = ((x / s).floor() as i64, (y / s).floor() as i64);
        if (i + j).rem_euclid(2) == 0 {
            BLACK
        } else {
            WHITE
        }
    };
    let mut out = vec![0.0f32; w * h];
    out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        for (x, o) in row.iter_mut().enumerate() {
            let c = [y * stride + x, y * stride + x + 1, (y + 1) * stride + x, (y + 1) * stride + x + 1];
            let [Some(a), Some(b), Some(c), Some(d)] = c.map(|i| hits[i]) else {
                *o = BEHIND;
                continue;
            };
            // Within one pixel the map to the sheet is bilinear to far below a pixel.
            let mut sum = 0.0;
            for sy in 0..SUBSAMPLES {
                let fy = (sy as f64 + 0.5) / SUBSAMPLES as f64;
                for sx in 0..SUBSAMPLES {
                    let fx = (sx as f64 + 0.5) / SUBSAMPLES as f64;
                    let top = [a[0] + fx * (b[0] - a[0]), a[1] + fx * (b[1] - a[1])];
                    let bottom = [c[0] + fx * (d[0] - c[0]), c[1] + fx * (d[1] - c[1])];
                    sum += shade(top[0] + fy * (bottom[0] - top[0]), top[1] + fy * (bottom[1] - top[1]));
                }
            }
            *o = sum / (SUBSAMPLES * SUBSAMPLES) as f32;
        }
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each inner corner is a saddle of the grey levels: on a clean render the four
    /// quadrants around its projection alternate dark and light.
    #[test]
    fn corners_land_where_the_camera_projects_them() {
        let mut cell = Cell::default();
        cell.sensor.camera_dist = [-0.15, 0.05, 0.0008, -0.0005, 0.0];
        let rig = rig_for(&cell.placement, &cell.sensor);
        let board = CalibrationBoard { cols: 9, rows: 6, square_mm: 25.0 };
        let pose = table_board_pose(&board);
        assert!(fits(&rig, &board, &pose));
        let rays = CornerRays::new(&rig.left);
        let grey = render_board(&rig.left, &rays, &board, &pose);
        let w = rig.left.width;
        let at = |x: f64, y: f64| grey[y.round() as usize * w + x.round() as usize];
        for p in board.object_points() {
            let q = rig.left.project(&(pose * p)).unwrap();
            let (dx, dy) = (3.0, 3.0);
            let quadrants =
                [at(q.x - dx, q.y - dy), at(q.x + dx, q.y - dy), at(q.x - dx, q.y + dy), at(q.x + dx, q.y + dy)];
            let dark = quadrants.map(|g| g < (BLACK + WHITE) / 2.0);
            assert!(dark[0] == dark[3] && dark[1] == dark[2] && dark[0] != dark[1], "corner at {q}: {quadrants:?}");
        }
    }

    /// The detector finds every corner, in the board's order (the table view fixes which
    /// way round), within a small fraction of a pixel of where the camera projects it.
    #[test]
    fn detected_corners_match_the_truth() {
        let dir = tempfile::tempdir().unwrap();
        let mut cell = Cell::default();
        cell.sensor.camera_dist = [-0.15, 0.05, 0.0008, -0.0005, 0.0];
        let board = CalibrationBoard { cols: 9, rows: 6, square_mm: 25.0 };
        let truth = render_board_views(dir.path(), &cell, &cell.placement, &board, 4, 7).unwrap();
        let rig = rig_for(&cell.placement, &cell.sensor);
        let views = truth
            .t_world_board
            .iter()
            .enumerate()
            .map(|(i, t)| (dir.path().join("frames").join(frame_name(i as u64)), *t));
        let mut errors = Vec::new();
        for (folder, t) in views.chain(std::iter::once((dir.path().join("table"), truth.t_world_table_board))) {
            let pose = camplace_estimator::geometry::isometry_from_rows(&t);
            for (name, cam) in [("left.png", &rig.left), ("right.png", &rig.right)] {
                if !fits_camera(cam, &board, &pose) {
                    continue;
                }
                let image = camplace_config::read_gray(&folder.join(name)).unwrap();
                let found = camplace_estimator::calibration::find_board_corners(&image, &board).unwrap();
                for (p, q) in board.object_points().iter().zip(&found) {
                    let want = cam.project(&(pose * p)).unwrap();
                    errors.push((want - q).norm());
                }
            }
        }
        errors.sort_by(f64::total_cmp);
        let rms = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
        let worst = errors[errors.len() - 1];
        eprintln!("corner error rms {rms} px, worst {worst} px");
        assert!(rms < 0.15 && worst < 0.5, "corner error rms {rms} px, worst {worst} px");
    }

    #[test]
    fn random_poses_show_the_whole_board_to_their_camera() {
        let cell = Cell::default();
        let rig = rig_for(&cell.placement, &cell.sensor);
        let board = CalibrationBoard { cols: 9, rows: 6, square_mm: 25.0 };
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let poses: Vec<_> = (0..10).map(|_| draw_board_pose(&rig.left, &board, &mut rng).unwrap()).collect();
        assert!(poses.iter().all(|p| fits_camera(&rig.left, &board, p)));
        // The poses differ in tilt, or Zhang's method has nothing to work with.
        let normals: Vec<Vector3<f64>> = poses.iter().map(|p| p.rotation * Vector3::z()).collect();
        let spread = normals.iter().map(|n| n.angle(&normals[0]).to_degrees()).fold(0.0, f64::max);
        assert!(spread > 15.0, "board normals within {spread} degrees of each other");
    }
}
