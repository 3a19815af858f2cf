//! `camplace reconstruct`: depth and clouds from stereo frames — every frame of a recorded
//! dataset, one raw pair with its `rig.json`, or one already rectified pair.

use anyhow::{bail, Context};
use camplace_config::RigFile;
use camplace_config::{FloatImage, GrayImage};
use camplace_estimator::DisparityMatcher;
use camplace_estimator::{Elas, Method, Reconstruction, Reconstructor, RectifiedCamera, Rig};
use camplace_hwio::{FrameSource, Frames, RecordedSource};
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use super::cell_args::CellArgs;

/// Flags of `camplace reconstruct`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    cell: CellArgs,
    /// A recorded dataset: writes the results beside each frame.
    #[arg(long, conflicts_with_all = ["left", "right", "rig"])]
    dataset: Option<PathBuf>,
    /// Left image(s) of one frame: one (one-shot) or twelve (phase-12), in shot order.
    #[arg(long, num_args = 1.., requires = "right")]
    left: Vec<PathBuf>,
    /// Right image(s) of the same frame.
    #[arg(long, num_args = 1.., requires = "left")]
    right: Vec<PathBuf>,
    /// Calibration of the raw pair.
    #[arg(long)]
    rig: Option<PathBuf>,
    /// The pair is already rectified (Middlebury style): give --focal-px and --baseline-mm.
    #[arg(long, requires_all = ["focal_px", "baseline_mm"], conflicts_with = "rig")]
    rectified: bool,
    /// Focal length of a rectified pair, px.
    #[arg(long)]
    focal_px: Option<f64>,
    /// Baseline of a rectified pair, mm.
    #[arg(long)]
    baseline_mm: Option<f64>,
    /// Disparity search range of a rectified pair, MIN:MAX px (default 0 to a third of the width).
    #[arg(long, value_name = "MIN:MAX")]
    disparity_range: Option<String>,
    /// Times the matcher this many times on a rectified pair and reports the median.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    runs: u32,
    /// Output folder for a single pair.
    #[arg(long)]
    out: Option<PathBuf>,
}

/// Runs `camplace reconstruct`.
pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let (cell, _) = a.cell.load()?;
    if let Some(dir) = &a.dataset {
        return dataset(&cell, dir);
    }
    if a.left.is_empty() {
        bail!("give --dataset DIR, or --left and --right with --rig (or --rectified)");
    }
    let out = a.out.as_ref().context("--out: expected the output folder for a single pair")?;
    std::fs::create_dir_all(out).with_context(|| format!("{}: cannot create the folder", out.display()))?;
    let left = read_all(&a.left)?;
    let right = read_all(&a.right)?;
    if a.rectified {
        return rectified_pair(&a, &cell, &left, &right, out);
    }
    let rig_path = a.rig.as_ref().context("--rig: expected the rig.json of the pair (or --rectified)")?;
    let rig_file = RigFile::load(rig_path)?;
    let method = method_for(left.len(), right.len(), &a.left[0])?;
    let rig = Rig::from_file(&rig_file);
    for (paths, imgs, cam) in [(&a.left, &left, &rig.left), (&a.right, &right, &rig.right)] {
        for (p, img) in paths.iter().zip(imgs) {
            if (img.width, img.height) != (cam.width, cam.height) {
                bail!(
                    "{}: expected {} x {} pixels as {} says, got {} x {}",
                    p.display(),
                    cam.width,
                    cam.height,
                    rig_path.display(),
                    img.width,
                    img.height
                );
            }
        }
    }
    let mut rec = Reconstructor::new(&cell, &rig, method).with_context(|| rig_path.display().to_string())?;
    let mut result = Reconstruction::default();
    rec.process(&left, &right, &mut result)?;
    write_outputs(out, &rec, &result)?;
    let mut with_rect = rig_file.clone();
    with_rect.rectified = Some(rectified_file(&rec.rectification().camera));
    with_rect.save(&out.join("rig.json"))?;
    println!("{} points, {:.1} ms; wrote {}", result.cloud.points.len(), total_ms(&result), out.display());
    Ok(ExitCode::SUCCESS)
}

fn dataset(cell: &camplace_config::Cell, dir: &Path) -> anyhow::Result<ExitCode> {
    let source = RecordedSource::open(dir)?;
    let method = camplace_sim::method_for(source.shots());
    let rig = Rig::from_file(source.rig());
    let mut background = Frames::new(source.shots());
    let has_background = source.background(&mut background)?;
    let make = || -> anyhow::Result<Reconstructor> {
        let mut rec =
            Reconstructor::new(cell, &rig, method).with_context(|| dir.join("rig.json").display().to_string())?;
        if has_background {
            rec.set_background(&background.left, &background.right)?;
        }
        Ok(rec)
    };
    let first = make()?;
    let mut rig_file = source.rig().clone();
    rig_file.rectified = Some(rectified_file(&first.rectification().camera));
    let n = source.frame_dirs().len();
    // One block of frames per thread, so each thread builds one reconstructor (its maps and
    // matcher buffers are costly), not one per work split.
    let points: Vec<usize> = (0..n)
        .into_par_iter()
        .with_min_len(n.div_ceil(rayon::current_num_threads()).max(1))
        .map_init(
            || (make(), Frames::new(source.shots()), Reconstruction::default()),
            |(rec, frames, result), i| -> anyhow::Result<usize> {
                let rec = rec.as_mut().map_err(|e| anyhow::anyhow!("{e:#}"))?;
                source.read_into(i, frames)?;
                rec.process(&frames.left, &frames.right, result)?;
                write_outputs(&source.frame_dirs()[i], rec, result)?;
                Ok(result.cloud.points.len())
            },
        )
        .collect::<anyhow::Result<_>>()?;
    rig_file.save(&dir.join("rig.json"))?;
    let mean = points.iter().sum::<usize>() as f64 / n.max(1) as f64;
    println!("reconstructed {n} frames ({method}), {mean:.0} points per frame on average, into {}", dir.display());
    Ok(ExitCode::SUCCESS)
}

fn rectified_pair(
    a: &Args,
    cell: &camplace_config::Cell,
    left: &[GrayImage],
    right: &[GrayImage],
    out: &Path,
) -> anyhow::Result<ExitCode> {
    if left.len() != 1 || right.len() != 1 {
        bail!("--rectified: expected one left and one right image");
    }
    let (l, r) = (&left[0], &right[0]);
    if !l.same_size(r) {
        bail!(
            "{}: expected the size of {} ({} x {}), got {} x {}",
            a.right[0].display(),
            a.left[0].display(),
            l.width,
            l.height,
            r.width,
            r.height
        );
    }
    let range = match &a.disparity_range {
        Some(text) => parse_range(text, l.width)?,
        None => (0.0, (l.width / 3) as f32),
    };
    for (flag, v) in [("--focal-px", a.focal_px), ("--baseline-mm", a.baseline_mm)] {
        if let Some(v) = v {
            if !(v.is_finite() && v > 0.0) {
                bail!("{flag}: expected a positive finite number, got {v}");
            }
        }
    }
    let span = (range.1 - range.0).ceil() as usize + 1;
    let mut elas = Elas::new(&cell.stereo, l.width, l.height, span);
    let mut disparity = FloatImage::default();
    // A first, untimed run warms the buffers, as a camera loop would be warm.
    elas.compute(l, r, range, &mut disparity)?;
    let mut times = Vec::with_capacity(a.runs as usize);
    for _ in 0..a.runs {
        let t = std::time::Instant::now();
        elas.compute(l, r, range, &mut disparity)?;
        times.push(t.elapsed().as_secs_f64() * 1e3);
    }
    times.sort_by(f64::total_cmp);
    let ms = times[times.len() / 2];
    camplace_config::write_pfm(&out.join("disparity.pfm"), disparity.width, disparity.height, &disparity.data)?;
    let f = a.focal_px.unwrap_or(1.0);
    let b = a.baseline_mm.unwrap_or(1.0);
    let depth: Vec<f32> =
        disparity.data.iter().map(|&d| if d > 0.0 { (f * b) as f32 / d } else { f32::INFINITY }).collect();
    camplace_config::write_pfm(&out.join("depth.pfm"), disparity.width, disparity.height, &depth)?;
    let valid = disparity.data.iter().filter(|d| d.is_finite()).count();
    println!(
        "disparity {:.1} % valid, median {ms:.1} ms over {} runs; wrote {}",
        100.0 * valid as f64 / disparity.data.len().max(1) as f64,
        a.runs,
        out.display()
    );
    Ok(ExitCode::SUCCESS)
}

/// `MIN:MAX` in pixels: a search no wider than the image (a disparity of the image's width
/// or more cannot be seen) and within what the matcher stores (i16 pixels).
fn parse_range(text: &str, width: usize) -> anyhow::Result<(f32, f32)> {
    let most = (width as f32).min(i16::MAX as f32);
    let bad = || {
        anyhow::anyhow!(
            "--disparity-range: expected MIN:MAX in pixels with 0 <= MIN < MAX <= {most} (the image width), got \"{text}\""
        )
    };
    let (lo, hi) = text.split_once(':').ok_or_else(bad)?;
    let (lo, hi): (f32, f32) = (lo.trim().parse().map_err(|_| bad())?, hi.trim().parse().map_err(|_| bad())?);
    if !(lo.is_finite() && hi.is_finite() && 0.0 <= lo && lo < hi && hi <= most) {
        return Err(bad());
    }
    Ok((lo, hi))
}

fn read_all(paths: &[PathBuf]) -> anyhow::Result<Vec<GrayImage>> {
    paths
        .iter()
        .map(|p| {
            let g = camplace_config::read_gray(p)?;
            Ok(GrayImage::from_vec(g.width, g.height, g.data).expect("decoded size"))
        })
        .collect()
}

fn method_for(left: usize, right: usize, first: &Path) -> anyhow::Result<Method> {
    match (left, right) {
        (1, 1) => Ok(Method::OneShot),
        (12, 12) => Ok(Method::Phase12),
        _ => bail!(
            "{}: expected 1 or 12 images per side in shot order, got {left} left and {right} right",
            first.display()
        ),
    }
}

/// Writes the rectified images, disparity, depth and cloud of one frame into `dir`.
fn write_outputs(dir: &Path, rec: &Reconstructor, r: &Reconstruction) -> anyhow::Result<()> {
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
pub fn rectified_file(cam: &RectifiedCamera) -> camplace_config::RectifiedFile {
    camplace_config::RectifiedFile {
        width: cam.width as u32,
        height: cam.height as u32,
        k: std::array::from_fn(|r| std::array::from_fn(|c| cam.k[(r, c)])),
        baseline: cam.baseline,
        t_world_rectified: camplace_estimator::isometry_to_rows(&cam.t_world_rectified),
    }
}

fn total_ms(r: &Reconstruction) -> f64 {
    r.timings.rectify_ms + r.timings.disparity_ms + r.timings.cloud_ms
}
