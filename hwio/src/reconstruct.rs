//! Depth and clouds written to disk, as `camplace reconstruct` makes them: every frame of a
//! recorded dataset (beside each frame), one raw pair with its calibration, or one pair that
//! is already rectified (disparity and depth only, with the matcher's median time).

use std::path::{Path, PathBuf};

use camplace_config::{Cell, FloatImage, GrayImage, RectifiedFile, RigFile};
use camplace_estimator::{
    depth::method_for, depth::DisparityMatcher, depth::Elas, depth::Method, geometry::isometry_to_rows,
};
use camplace_estimator::{depth::Reconstruction, depth::Reconstructor, depth::RectifiedCamera, EstimatorConfig, Rig};
use rayon::prelude::*;

use crate::{Error, ErrorKind, FrameSource, Frames, RecordedSource, Result};

/// What reconstructing a recorded dataset gave.
#[derive(Debug, Clone, Copy)]
pub struct DatasetDepth {
    /// Frames reconstructed.
    pub frames: usize,
    /// The dataset's method, from its shots per frame.
    pub method: Method,
    /// Points per frame's cloud, on average.
    pub mean_points: f64,
}

/// Reconstructs every frame of the recorded dataset `dir`: the rectified images, disparity,
/// depth and cloud beside each frame, and the rectification added to the dataset's
/// `rig.json`. Frames run in parallel, one reconstructor per thread; the files are the same
/// whatever the thread count.
pub fn reconstruct_dataset(cell: &Cell, dir: &Path) -> Result<DatasetDepth> {
    let source = RecordedSource::open(dir)?;
    let method = method_for(source.shots());
    let rig = Rig::from_file(source.rig());
    let rig_path = dir.join("rig.json");
    let mut background = Frames::new(source.shots());
    let has_background = source.background(&mut background)?;
    let make = || -> Result<Reconstructor> {
        let mut rec = Reconstructor::new(&EstimatorConfig::from(cell), &rig, method)
            .map_err(|e| Error::from(e).in_file(&rig_path))?;
        if has_background {
            rec.set_background(&background.left, &background.right)?;
        }
        // The disparity and depth written are read by people and other tools: whole.
        rec.set_whole_image(true);
        Ok(rec)
    };
    let first = make()?;
    let mut rig_file = source.rig().clone();
    rig_file.rectified = Some(rectified_file(&first.rectification().camera));
    drop(first);
    let n = source.frame_dirs().len();
    // One block of frames per thread, so each thread builds one reconstructor (its maps and
    // matcher buffers are costly), not one per work split.
    let points: Vec<usize> = (0..n)
        .into_par_iter()
        .with_min_len(n.div_ceil(rayon::current_num_threads()).max(1))
        .map_init(
            || (make(), Frames::new(source.shots()), Reconstruction::default()),
            |(rec, frames, result), i| -> Result<usize> {
                let rec = rec.as_mut().map_err(|e| e.clone())?;
                source.read_into(i, frames)?;
                rec.process(&frames.left, &frames.right, result)?;
                write_outputs(&source.frame_dirs()[i], rec, result)?;
                Ok(result.cloud.points.len())
            },
        )
        .collect::<Result<_>>()?;
    rig_file.save(&rig_path)?;
    Ok(DatasetDepth { frames: n, method, mean_points: points.iter().sum::<usize>() as f64 / n.max(1) as f64 })
}

/// What reconstructing one raw pair gave.
#[derive(Debug, Clone, Copy)]
pub struct PairDepth {
    /// Points in the cloud.
    pub points: usize,
    /// Rectification, disparity and cloud, ms.
    pub ms: f64,
}

/// Reconstructs one raw frame (one image a side for one shot, twelve in shot order for
/// phase-12) seen by the rig of `rig_path`, into `out`: the frame's files and the rig with
/// its rectification.
pub fn reconstruct_pair(
    cell: &Cell,
    rig_path: &Path,
    left: &[PathBuf],
    right: &[PathBuf],
    out: &Path,
) -> Result<PairDepth> {
    let (left_images, right_images) = (read_all(left)?, read_all(right)?);
    let mut rig_file = RigFile::load(rig_path)?;
    let method = match (left.len(), right.len()) {
        (1, 1) => Method::OneShot,
        (12, 12) => Method::Phase12,
        (l, r) => {
            return Err(Error::input(format!(
                "{}: expected 1 or 12 images per side in shot order, got {l} left and {r} right",
                left.first().or(right.first()).map_or(String::new(), |p| p.display().to_string())
            )))
        }
    };
    let rig = Rig::from_file(&rig_file);
    for (paths, images, cam) in [(left, &left_images, &rig.left), (right, &right_images, &rig.right)] {
        for (p, img) in paths.iter().zip(images) {
            if (img.width, img.height) != (cam.width, cam.height) {
                return Err(Error::input(format!(
                    "{}: expected {} x {} pixels as {} says, got {} x {}",
                    p.display(),
                    cam.width,
                    cam.height,
                    rig_path.display(),
                    img.width,
                    img.height
                )));
            }
        }
    }
    let mut rec =
        Reconstructor::new(&EstimatorConfig::from(cell), &rig, method).map_err(|e| Error::from(e).in_file(rig_path))?;
    let mut result = Reconstruction::default();
    rec.process(&left_images, &right_images, &mut result)?;
    create_dir(out)?;
    write_outputs(out, &rec, &result)?;
    rig_file.rectified = Some(rectified_file(&rec.rectification().camera));
    rig_file.save(&out.join("rig.json"))?;
    let t = &result.timings;
    Ok(PairDepth { points: result.cloud.points.len(), ms: t.rectify_ms + t.disparity_ms + t.cloud_ms })
}

/// One pair that is already rectified (Middlebury style) and how to match it.
#[derive(Debug, Clone, Copy)]
pub struct RectifiedPair {
    /// Focal length, px.
    pub focal_px: f64,
    /// Baseline, mm.
    pub baseline_mm: f64,
    /// The disparity search range, px; `None`: from 0 to a third of the width.
    pub disparity_range: Option<(f32, f32)>,
    /// How many timed runs of the matcher (after one untimed run that warms its buffers).
    pub runs: u32,
}

/// What matching a rectified pair gave.
#[derive(Debug, Clone, Copy)]
pub struct RectifiedDepth {
    /// Share of pixels with a disparity.
    pub valid_fraction: f64,
    /// The matcher's median time over the timed runs, ms.
    pub median_ms: f64,
}

/// Matches a rectified pair and writes `disparity.pfm` and `depth.pfm` into `out`.
pub fn match_rectified(
    cell: &Cell,
    left: &Path,
    right: &Path,
    pair: &RectifiedPair,
    out: &Path,
) -> Result<RectifiedDepth> {
    for (flag, v) in [("--focal-px", pair.focal_px), ("--baseline-mm", pair.baseline_mm)] {
        if !(v.is_finite() && v > 0.0) {
            return Err(Error::input(format!("{flag}: expected a positive finite number, got {v}")));
        }
    }
    if pair.runs == 0 {
        return Err(Error::input("--runs: expected at least one run"));
    }
    let l = camplace_config::read_gray(left)?;
    let r = camplace_config::read_gray(right)?;
    if !l.same_size(&r) {
        return Err(Error::input(format!(
            "{}: expected the size of {} ({} x {}), got {} x {}",
            right.display(),
            left.display(),
            l.width,
            l.height,
            r.width,
            r.height
        )));
    }
    // A disparity of the image's width or more cannot be seen, and the matcher stores
    // disparities as i16 pixels.
    let most = (l.width as f32).min(i16::MAX as f32);
    let range = pair.disparity_range.unwrap_or((0.0, (l.width / 3) as f32));
    if !(range.0.is_finite() && range.1.is_finite() && 0.0 <= range.0 && range.0 < range.1 && range.1 <= most) {
        return Err(Error::input(format!(
            "--disparity-range: expected MIN:MAX in pixels with 0 <= MIN < MAX <= {most} (the image width), got {}:{}",
            range.0, range.1
        )));
    }
    let span = (range.1 - range.0).ceil() as usize + 1;
    // A rectified pair is matched to be looked at and scored against other matchers: every
    // row, whatever row step the estimator's cell sets.
    let params = camplace_config::StereoParams { row_step: 1, ..cell.stereo.clone() };
    let mut elas = Elas::new(&params, l.width, l.height, span);
    let mut disparity = FloatImage::default();
    elas.compute(&l, &r, range, &mut disparity)?;
    let mut times = Vec::with_capacity(pair.runs as usize);
    for _ in 0..pair.runs {
        let t = std::time::Instant::now();
        elas.compute(&l, &r, range, &mut disparity)?;
        times.push(t.elapsed().as_secs_f64() * 1e3);
    }
    times.sort_by(f64::total_cmp);
    create_dir(out)?;
    camplace_config::write_pfm(&out.join("disparity.pfm"), disparity.width, disparity.height, &disparity.data)?;
    let fb = (pair.focal_px * pair.baseline_mm) as f32;
    let depth: Vec<f32> =
        disparity.data.iter().map(|&d| if d.is_finite() && d > 0.0 { fb / d } else { f32::INFINITY }).collect();
    camplace_config::write_pfm(&out.join("depth.pfm"), disparity.width, disparity.height, &depth)?;
    let valid = disparity.data.iter().filter(|d| d.is_finite()).count();
    Ok(RectifiedDepth {
        valid_fraction: valid as f64 / disparity.data.len().max(1) as f64,
        median_ms: times[times.len() / 2],
    })
}

fn create_dir(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir)
        .map_err(|e| Error::new(ErrorKind::Io, format!("{}: cannot create the folder: {e}", dir.display())))
}

fn read_all(paths: &[PathBuf]) -> Result<Vec<GrayImage>> {
    paths.iter().map(|p| Ok(camplace_config::read_gray(p)?)).collect()
}

/// Writes the rectified images, disparity, depth and cloud of one frame into `dir`.
fn write_outputs(dir: &Path, rec: &Reconstructor, r: &Reconstruction) -> Result<()> {
    let (rl, rr) = rec.rectified();
    camplace_config::write_gray(&dir.join("rectified_left.png"), rl[0].width, rl[0].height, &rl[0].data)?;
    camplace_config::write_gray(&dir.join("rectified_right.png"), rr[0].width, rr[0].height, &rr[0].data)?;
    camplace_config::write_pfm(&dir.join("disparity.pfm"), r.disparity.width, r.disparity.height, &r.disparity.data)?;
    let d = &r.cloud.depth;
    camplace_config::write_pfm(&dir.join("depth.pfm"), d.width, d.height, &d.data)?;
    let pts: Vec<[f32; 3]> = r.cloud.points.iter().map(|p| [p.x, p.y, p.z]).collect();
    camplace_config::write_cloud(&dir.join("cloud.ply"), &pts, None)?;
    Ok(())
}

/// The `rectified` section of `rig.json`.
fn rectified_file(cam: &RectifiedCamera) -> RectifiedFile {
    RectifiedFile {
        width: cam.width as u32,
        height: cam.height as u32,
        k: std::array::from_fn(|r| std::array::from_fn(|c| cam.k[(r, c)])),
        baseline: cam.baseline,
        t_world_rectified: isometry_to_rows(&cam.t_world_rectified),
    }
}
