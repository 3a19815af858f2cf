//! `camplace reconstruct`: depth and clouds from stereo frames — every frame of a recorded
//! dataset, one raw pair with its `rig.json`, or one already rectified pair.

use anyhow::{bail, Context};
use camplace_estimator::{depth::method_for, depth::Method};
use camplace_hwio::{match_rectified, reconstruct_dataset, reconstruct_pair, RectifiedPair};
use std::path::PathBuf;
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
    /// Every row is matched, whatever the cell's `[stereo] row_step` (which the dataset and
    /// pair modes follow, as the estimator does: the rows between stay empty).
    #[arg(long, requires_all = ["focal_px", "baseline_mm"], conflicts_with = "rig")]
    rectified: bool,
    /// Focal length of a rectified pair, px.
    #[arg(long, allow_negative_numbers = true)]
    focal_px: Option<f64>,
    /// Baseline of a rectified pair, mm.
    #[arg(long, allow_negative_numbers = true)]
    baseline_mm: Option<f64>,
    /// Disparity search range of a rectified pair, MIN:MAX px (default 0 to a third of the width).
    #[arg(long, value_name = "MIN:MAX", value_parser = parse_range)]
    disparity_range: Option<(f32, f32)>,
    /// Times the matcher this many times on a rectified pair and reports the median.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    runs: u32,
    /// Output folder for a single pair.
    #[arg(long)]
    out: Option<PathBuf>,
    /// One-shot datasets and raw pairs: match every row, not only every `[stereo] row_step`-th
    /// one as the estimator does.
    #[arg(long)]
    all_rows: bool,
}

/// Runs `camplace reconstruct`.
pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let (mut cell, _) = a.cell.load()?;
    if a.all_rows {
        cell.stereo.row_step = 1;
    }
    if let Some(dir) = &a.dataset {
        let d = reconstruct_dataset(&cell, dir)?;
        outln!(
            "reconstructed {} frames ({}), {:.0} points per frame on average, into {}; {}",
            d.frames,
            d.method,
            d.mean_points,
            dir.display(),
            rows_text(d.method, cell.stereo.row_step)
        );
        return Ok(ExitCode::SUCCESS);
    }
    if a.left.is_empty() {
        bail!("give --dataset DIR, or --left and --right with --rig (or --rectified)");
    }
    let out = a.out.as_ref().context("--out: expected the output folder for a single pair")?;
    if a.rectified {
        let ([left], [right]) = (a.left.as_slice(), a.right.as_slice()) else {
            bail!("--rectified: expected one left and one right image");
        };
        let pair = RectifiedPair {
            focal_px: a.focal_px.context("--focal-px: expected the focal length, px")?,
            baseline_mm: a.baseline_mm.context("--baseline-mm: expected the baseline, mm")?,
            disparity_range: a.disparity_range,
            runs: a.runs,
        };
        let d = match_rectified(&cell, left, right, &pair, out)?;
        outln!(
            "disparity {:.1} % valid, median {:.1} ms over {} runs; wrote {}",
            100.0 * d.valid_fraction,
            d.median_ms,
            a.runs,
            out.display()
        );
        return Ok(ExitCode::SUCCESS);
    }
    let rig = a.rig.as_ref().context("--rig: expected the rig.json of the pair (or --rectified)")?;
    let d = reconstruct_pair(&cell, rig, &a.left, &a.right, out)?;
    let method = method_for(a.left.len());
    outln!("{} points, {:.1} ms; wrote {}; {}", d.points, d.ms, out.display(), rows_text(method, cell.stereo.row_step));
    Ok(ExitCode::SUCCESS)
}

/// Which rows `disparity.pfm` covers, in words.
fn rows_text(method: Method, row_step: u32) -> String {
    match (method, row_step) {
        (Method::Phase12, _) | (_, 0 | 1) => "disparity.pfm covers every row".to_string(),
        (_, n) => format!(
            "disparity.pfm covers one row in {n} (rows 0, {n}, {} ...) as the estimator matches ([stereo] row_step = {n}); \
             the rows between are empty (--all-rows matches every row)",
            2 * n
        ),
    }
}

/// `MIN:MAX` in pixels, 0 <= MIN < MAX (the image bounds MAX, checked once it is read).
fn parse_range(text: &str) -> Result<(f32, f32), String> {
    let bad = || format!("expected MIN:MAX in pixels with 0 <= MIN < MAX, got \"{text}\"");
    let (lo, hi) = text.split_once(':').ok_or_else(bad)?;
    let (lo, hi): (f32, f32) = (lo.trim().parse().map_err(|_| bad())?, hi.trim().parse().map_err(|_| bad())?);
    if !(lo.is_finite() && hi.is_finite() && 0.0 <= lo && lo < hi) {
        return Err(bad());
    }
    Ok((lo, hi))
}
