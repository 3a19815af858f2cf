//! `camplace calibrate`: the installed rig's `rig.json` from stereo pairs of a chessboard —
//! each camera's K and distortion and the pose between them from every view, the world frame
//! from the view of the board lying flat on the table. Reads the folder `capture` writes
//! (`frames/NNNN/left.png` + `right.png`, and `table/`); `render --board` writes the same.
//! With `--hand-eye`, then where the rig sits in the robot's frame (`hand_eye.rs`).

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Context};
use camplace_config::GrayImage;
use camplace_estimator::{
    calibrate_stereo, find_board_corners, BoardView, CalibrationBoard, HandEyeSetup, Rig, StereoCalibration,
    MIN_CALIBRATION_VIEWS,
};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rayon::prelude::*;

/// Flags of `camplace calibrate`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Folder of board images: frames/NNNN/left.png + right.png, and table/ with the board
    /// lying flat on the table (as `capture` and `capture --table` write them).
    #[arg(long, value_name = "DIR")]
    images: PathBuf,
    /// The board: inner corners across x down, and the square side, as COLSxROWS@SQUARE_MM.
    #[arg(long, value_name = "COLSxROWS@MM")]
    board: String,
    /// Where the table view's board lies in the world: its first corner's x, y, z (mm) and the
    /// turn of its x axis from the world's x about z (deg). Default: the board centred on the
    /// world origin with its axes along the world's.
    #[arg(long, value_name = "X,Y,Z,YAW", allow_hyphen_values = true)]
    board_in_world: Option<String>,
    /// The file to write: the rig.json (default `rig.json`), or with --hand-eye the `[robot]`
    /// table (default `robot.toml`).
    #[arg(long, value_name = "FILE")]
    out: Option<PathBuf>,
    /// Hand-eye calibration: where the rig sits in the robot's frame, from the board images
    /// paired by index with --robot-poses; writes the `[robot]` table the cell reads.
    #[arg(long, requires = "robot_poses")]
    hand_eye: bool,
    /// The robot's flange poses, one a line, line k with frames/k (docs/formats.md).
    #[arg(long, value_name = "FILE", requires = "hand_eye")]
    robot_poses: Option<PathBuf>,
    /// The rig on the robot's flange looking at a board fixed on the table (its pose in the
    /// world: --board-in-world); without it the rig is fixed and the board on the flange.
    #[arg(long, requires = "hand_eye")]
    eye_in_hand: bool,
    /// The calibrated rig for --hand-eye; without it the rig is calibrated from the same
    /// images first (with table/, as `calibrate` alone) and written to rig.json beside --out.
    #[arg(long, value_name = "FILE", requires = "hand_eye")]
    rig: Option<PathBuf>,
    #[command(flatten)]
    pose_format: super::hand_eye::PoseFormatArgs,
    /// With --hand-eye: the robot's accuracy, 1 σ per axis of a reported translation, mm;
    /// each pose's correction is held to it.
    #[arg(long, value_name = "MM", default_value_t = 0.1, requires = "hand_eye")]
    robot_accuracy_mm: f64,
    /// With --hand-eye: the robot's accuracy, 1 σ per axis of a reported rotation, degrees.
    #[arg(long, value_name = "DEG", default_value_t = 0.02, requires = "hand_eye")]
    robot_accuracy_deg: f64,
}

/// Parses `COLSxROWS@SQUARE_MM`, e.g. `9x6@25`.
pub fn parse_board(text: &str) -> anyhow::Result<CalibrationBoard> {
    let expected = "expected COLSxROWS@SQUARE_MM, e.g. 9x6@25 (inner corners, square side in mm)";
    let (counts, square) = text.split_once('@').with_context(|| format!("--board {text:?}: {expected}"))?;
    let (cols, rows) = counts.split_once(['x', 'X']).with_context(|| format!("--board {text:?}: {expected}"))?;
    let count = |s: &str| s.trim().parse::<usize>().ok().filter(|n| (2..=100).contains(n));
    let (Some(cols), Some(rows)) = (count(cols), count(rows)) else {
        bail!("--board {text:?}: {expected}, with 2 to 100 corners a side");
    };
    let square_mm = square.trim().parse::<f64>().ok().filter(|v| v.is_finite() && *v > 0.0 && *v <= 1000.0);
    let Some(square_mm) = square_mm else {
        bail!("--board {text:?}: {expected}, with a square side above 0 and up to 1000 mm");
    };
    if (cols + rows).is_multiple_of(2) {
        bail!(
            "--board {text:?}: a {cols}x{rows} board looks the same turned half way round, so its corners cannot be told apart; use one with an odd and an even corner count, e.g. 9x6"
        );
    }
    Ok(CalibrationBoard { cols, rows, square_mm })
}

/// The table board's pose in the world from `X,Y,Z,YAW`.
fn parse_board_in_world(text: &str) -> anyhow::Result<Isometry3<f64>> {
    let v: Vec<f64> = text.split(',').map(|s| s.trim().parse::<f64>()).collect::<Result<_, _>>().unwrap_or_default();
    if v.len() != 4 || !v.iter().all(|x| x.is_finite()) {
        bail!("--board-in-world {text:?}: expected X,Y,Z,YAW (mm, mm, mm, deg), four numbers");
    }
    Ok(Isometry3::from_parts(
        Translation3::new(v[0], v[1], v[2]),
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), v[3].to_radians()),
    ))
}

/// The most board views `calibrate` takes: the joint refinement's time grows with the
/// square of the view count.
pub const MAX_CALIBRATION_VIEWS: usize = 100;

/// One stereo pair of the board: where it came from, its images' sizes and the corners
/// found in each image (or why the whole board was not found there).
struct FoundPair {
    name: String,
    folder: PathBuf,
    sizes: [(usize, usize); 2],
    corners: [Result<Vec<nalgebra::Point2<f64>>, String>; 2],
}

/// Runs `camplace calibrate`.
pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let board = parse_board(&a.board)?;
    let t_world_table_board = match &a.board_in_world {
        Some(text) => parse_board_in_world(text)?,
        None => camplace_estimator::table_board_pose(&board),
    };
    if !a.hand_eye {
        let out = a.out.clone().unwrap_or_else(|| PathBuf::from("rig.json"));
        calibrate_rig(&a, &board, &t_world_table_board, &out)?;
        return Ok(ExitCode::SUCCESS);
    }
    let out = a.out.clone().unwrap_or_else(|| PathBuf::from("robot.toml"));
    let (rig, rig_path) = match &a.rig {
        Some(path) => (super::hand_eye::load_rig(path)?, path.clone()),
        None => {
            let path = out.parent().unwrap_or(Path::new("")).join("rig.json");
            (calibrate_rig(&a, &board, &t_world_table_board, &path)?, path)
        }
    };
    let setup = if a.eye_in_hand { HandEyeSetup::EyeInHand } else { HandEyeSetup::EyeToHand };
    let args = super::hand_eye::HandEyeArgs {
        images: &a.images,
        robot_poses: a.robot_poses.as_deref().context("--hand-eye needs --robot-poses FILE")?,
        formats: &a.pose_format,
        setup,
        rig,
        rig_path,
        t_world_board: t_world_table_board,
        out: &out,
        robot_accuracy_mm: a.robot_accuracy_mm,
        robot_accuracy_deg: a.robot_accuracy_deg,
    };
    if !(a.robot_accuracy_mm.is_finite() && a.robot_accuracy_mm > 0.0 && a.robot_accuracy_mm <= 100.0) {
        bail!("--robot-accuracy-mm {}: expected a positive accuracy up to 100 mm", a.robot_accuracy_mm);
    }
    if !(a.robot_accuracy_deg.is_finite() && a.robot_accuracy_deg > 0.0 && a.robot_accuracy_deg <= 10.0) {
        bail!("--robot-accuracy-deg {}: expected a positive accuracy up to 10 degrees", a.robot_accuracy_deg);
    }
    super::hand_eye::run(args, &board)
}

/// The stereo calibration from the board images: prints each view's error and the
/// cameras, writes the rig to `out` and returns it.
fn calibrate_rig(
    a: &Args,
    board: &CalibrationBoard,
    t_world_table_board: &Isometry3<f64>,
    out: &Path,
) -> anyhow::Result<Rig> {
    let board = *board;
    let mut folders =
        camplace_config::frame_folders(&a.images).context("cannot list the board views (frames/NNNN/)")?;
    let table = a.images.join("table");
    if !table.is_dir() {
        bail!(
            "{}: missing: the world frame comes from one pair of the board lying flat on the table (camplace capture --table)",
            table.display()
        );
    }
    if folders.len() > MAX_CALIBRATION_VIEWS {
        bail!(
            "{}: {} board views, expected at most {MAX_CALIBRATION_VIEWS} (the joint refinement's time grows with the square of the view count; 20 to 40 views spread over the image calibrate well)",
            a.images.join("frames").display(),
            folders.len()
        );
    }
    folders.push(table.clone());
    // One view at a time: its images are read, searched for the board's corners and dropped,
    // so only the corners of every view are held (and a worker's pair at a time).
    let found: Vec<FoundPair> =
        folders.par_iter().map(|f| find_pair(&a.images, f, &board)).collect::<anyhow::Result<_>>()?;
    let (width, height) = found[0].sizes[0];
    for p in &found {
        for (side, size) in ["left", "right"].iter().zip(p.sizes) {
            if size != (width, height) {
                bail!(
                    "{}: {}x{} pixels, expected {width}x{height} as {}",
                    p.folder.join(format!("{side}.png")).display(),
                    size.0,
                    size.1,
                    found[0].folder.join("left.png").display()
                );
            }
        }
    }
    let table_name = found.last().map(|p| p.name.clone()).unwrap_or_default();
    let mut views = Vec::new();
    let mut names = Vec::new();
    let mut not_in_view = Vec::new();
    for p in found {
        let [left, right] = p.corners;
        // A board wholly in one image only still calibrates that camera (the cameras share
        // only the middle of their views, and the distortion is largest outside it).
        for side in [&left, &right] {
            if let Err(e) = side {
                not_in_view.push(format!("not in view: {e}"));
            }
        }
        if left.is_err() && right.is_err() {
            if p.name == table_name {
                bail!("{}: the table view must show the whole board", p.name);
            }
            continue;
        }
        views.push(BoardView { left: left.ok(), right: right.ok() });
        names.push(p.name);
    }
    if views.len() < MIN_CALIBRATION_VIEWS {
        bail!(
            "{}: the whole board was found in {} pairs (with the table view), expected at least {MIN_CALIBRATION_VIEWS}",
            a.images.display(),
            views.len()
        );
    }
    let started = std::time::Instant::now();
    let cal = calibrate_stereo(&board, &views, width, height).with_context(|| a.images.display().to_string())?;
    let seconds = started.elapsed().as_secs_f64();
    let table_index = names.len() - 1;
    if cal.views[table_index].dropped {
        bail!("{table_name}: the table view's corners do not fit the calibration; capture it again");
    }
    // Kept views keep their order, so the table view, last of all, is the last pose.
    let t_left_table_board = *cal.t_left_board.last().context("no board pose")?;
    let t_world_left = t_world_table_board * t_left_table_board.inverse();
    let rig = world_rig(&cal, &t_world_left);
    let file = rig.to_file();
    file.check().map_err(|e| anyhow::anyhow!("the calibrated rig: {e}"))?;
    file.save(out)?;
    // Printed once rig.json is written: a reader that stops early loses nothing.
    for line in &not_in_view {
        outln!("{line}");
    }
    print_views(&cal, &names);
    let b = rig.baseline();
    outln!(
        "calibrated from {} views in {seconds:.3} s: reprojection RMS {:.3} px, baseline {b:.2} mm; wrote {}",
        cal.views.iter().filter(|v| !v.dropped).count(),
        cal.rms_px,
        out.display()
    );
    outln!(
        "k3: {}",
        if cal.k3_estimated {
            "refined (freeing it lowered the error beyond what noise explains)"
        } else {
            "held at 0 (freeing it did not lower the error beyond what noise explains)"
        }
    );
    for (side, c) in [("left", &rig.left), ("right", &rig.right)] {
        let d = c.dist;
        outln!(
            "{side:<5} fx {:.2} fy {:.2} cx {:.2} cy {:.2}  k1 {:.5} k2 {:.5} p1 {:.6} p2 {:.6} k3 {:.5}",
            c.k[(0, 0)],
            c.k[(1, 1)],
            c.k[(0, 2)],
            c.k[(1, 2)],
            d[0],
            d[1],
            d[2],
            d[3],
            d[4]
        );
    }
    Ok(rig)
}

/// The pair in `folder` (`left.png` + `right.png`), named relative to `root`: both images
/// read and searched for the board, then dropped.
fn find_pair(root: &Path, folder: &Path, board: &CalibrationBoard) -> anyhow::Result<FoundPair> {
    let name = folder.strip_prefix(root).unwrap_or(folder).display().to_string();
    let mut sizes = [(0, 0); 2];
    let mut corners = Vec::with_capacity(2);
    for (i, side) in ["left", "right"].into_iter().enumerate() {
        let path = folder.join(format!("{side}.png"));
        let g = camplace_config::read_gray(&path)?;
        sizes[i] = (g.width, g.height);
        let mut image = GrayImage::default();
        image.reset(g.width, g.height, 0);
        image.data = g.data;
        corners.push(find_board_corners(&image, board).map_err(|e| format!("{name}/{side}.png: {e}")));
    }
    let right = corners.pop().expect("two sides");
    let left = corners.pop().expect("two sides");
    Ok(FoundPair { name, folder: folder.to_path_buf(), sizes, corners: [left, right] })
}

/// Each view's reprojection error, the dropped ones marked.
fn print_views(cal: &StereoCalibration, names: &[String]) {
    outln!("{:<14} {:>9} {:>9}", "view", "left px", "right px");
    let px = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.3}"));
    for v in &cal.views {
        let mark = if v.dropped { "  dropped: its error stands out" } else { "" };
        outln!("{:<14} {:>9} {:>9}{mark}", names[v.index], px(v.rms_left_px), px(v.rms_right_px));
    }
}

/// The calibrated cameras placed in the world by the left camera's pose.
fn world_rig(cal: &StereoCalibration, t_world_left: &Isometry3<f64>) -> Rig {
    let mut left = cal.left.clone();
    left.t_world_camera = *t_world_left;
    let mut right = cal.right.clone();
    right.t_world_camera = t_world_left * cal.right.t_world_camera;
    Rig { left, right, projector: None }
}
