//! `camplace capture`: frames from any source saved as a recorded dataset — the images of a
//! calibration board, the empty cell's background, or frames to replay later. Each frame
//! is appended as `frames/NNNN/` (the next number), so captures can be taken one run at a
//! time, e.g. one board pose each. With `--trial DIR --placement I` the dataset is the trial's
//! folder of that placement.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::bail;
use camplace_config::{placement_dir, TrialPlan, PLAN_FILE};
use camplace_hwio::{capture_dataset, capture_rig, open_source, parse_source, CaptureKind, CapturePlan};

/// Flags of `camplace capture`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Where frames come from: dir:PATH, v4l2:A,B, v4l2-sbs:DEV, dc1394[:GUID] (as `run` takes).
    #[arg(long, value_name = "SPEC")]
    source: String,
    /// The dataset folder the frames are added to (created when missing).
    #[arg(long, value_name = "DIR", required_unless_present = "trial", conflicts_with = "trial")]
    out: Option<PathBuf>,
    /// A trial folder (with the plan.json of `camplace trial plan`): the frames go to the
    /// dataset of placement --placement, `DIR/NNN/`.
    #[arg(long, value_name = "DIR", requires = "placement")]
    trial: Option<PathBuf>,
    /// With --trial: the placement's number in the plan, 0 … n−1.
    #[arg(long, value_name = "I", requires = "trial")]
    placement: Option<usize>,
    /// Frames to capture.
    #[arg(long, default_value_t = 1)]
    count: u64,
    /// Seconds from one capture to the next (0: each frame as the source gives it).
    #[arg(long, value_name = "SECONDS", default_value_t = 0.0, allow_negative_numbers = true)]
    every: f64,
    /// Frames thrown away before each capture (frames a driver queued earlier).
    #[arg(long, value_name = "N", default_value_t = 0)]
    skip: u64,
    /// Calibration copied to the dataset's rig.json when it has none (a dir: source's own
    /// rig.json when not given).
    #[arg(long, value_name = "FILE")]
    rig: Option<PathBuf>,
    /// The frame is the empty cell: write it as the dataset's background/ (one frame).
    #[arg(long, conflicts_with = "table")]
    background: bool,
    /// The frame shows the calibration board lying flat on the table: write it as table/
    /// (one frame), which `calibrate` takes the world frame from.
    #[arg(long)]
    table: bool,
}

/// Runs `camplace capture`.
pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let kind = match (a.background, a.table) {
        (true, _) => CaptureKind::Background,
        (_, true) => CaptureKind::TableView,
        _ => CaptureKind::Frames,
    };
    let plan = CapturePlan::new(a.count, a.every, a.skip, kind)?;
    let out = match (&a.out, &a.trial, a.placement) {
        (Some(out), _, _) => out.clone(),
        (None, Some(trial), Some(i)) => {
            let plan = TrialPlan::load(&trial.join(PLAN_FILE))?;
            if i >= plan.placements.len() {
                bail!(
                    "--placement {i}: expected a placement of {} (0 to {})",
                    trial.join(PLAN_FILE).display(),
                    plan.placements.len() - 1
                );
            }
            placement_dir(trial, i)
        }
        _ => bail!("--out DIR or --trial DIR --placement I: expected where the frames go"),
    };
    let spec = parse_source(&a.source)?;
    let rig = capture_rig(a.rig.as_deref(), &spec)?;
    let mut source = open_source(&spec)?;
    let outcome = capture_dataset(source.as_mut(), &plan, &out, rig.as_deref(), |f| {
        outln!(
            "captured {} ({} shot(s) per side, source frame {}) into {} at {:.1} s",
            f.source.name,
            f.shots,
            f.source.index,
            f.dir.display(),
            f.elapsed_s
        )
    })?;
    if outcome.captured == 0 {
        bail!("--source {}: the source gave no frame", a.source);
    }
    if outcome.captured < outcome.requested {
        noteln!("note: the source ended after {} of {} frames", outcome.captured, outcome.requested);
    }
    if !outcome.has_rig {
        noteln!("note: {} has no rig.json yet; calibrate the rig and copy it there (or pass --rig)", out.display());
    }
    Ok(ExitCode::SUCCESS)
}
