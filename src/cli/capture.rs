//! `camplace capture`: frames from any source saved as a recorded dataset — the images of a
//! calibration board, the empty cell's background, or frames to replay later. Each frame
//! is appended as `frames/NNNN/` (the next number), so captures can be taken one run at a
//! time, e.g. one board pose each. With `--trial DIR --placement I` the dataset is the trial's
//! folder of that placement.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{Duration, Instant};

use anyhow::bail;
use camplace_config::{placement_dir, TrialPlan, PLAN_FILE};
use camplace_hwio::{append_frame, open_source, parse_source, write_background, write_table_view, Frames, SourceSpec};

/// The most frames one run may capture.
const MAX_COUNT: u64 = 1_000_000;
/// The longest wait between frames, s.
const MAX_EVERY_S: f64 = 86_400.0;

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
    if !(1..=MAX_COUNT).contains(&a.count) {
        bail!("--count: expected 1 to {MAX_COUNT} frames, got {}", a.count);
    }
    if !(a.every.is_finite() && (0.0..=MAX_EVERY_S).contains(&a.every)) {
        bail!("--every: expected 0 to {MAX_EVERY_S} seconds, got {}", a.every);
    }
    if a.background && a.count != 1 {
        bail!("--background: the background is one frame; leave out --count {}", a.count);
    }
    if a.table && a.count != 1 {
        bail!("--table: the table view is one frame; leave out --count {}", a.count);
    }
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
    let rig = match (&a.rig, &spec) {
        (Some(r), _) => Some(r.clone()),
        (None, SourceSpec::Recorded(dir)) => Some(dir.join("rig.json")).filter(|p| p.is_file()),
        (None, _) => None,
    };
    if let Some(r) = &rig {
        camplace_config::RigFile::load(r)?;
    }
    let mut source = open_source(&spec)?;
    let mut frames = Frames::new(source.shots());
    let started = Instant::now();
    let mut captured = 0;
    while captured < a.count {
        if captured > 0 && a.every > 0.0 {
            // Kept to the schedule from the start, so slow writes do not add up.
            let due = started + Duration::from_secs_f64(a.every * captured as f64);
            std::thread::sleep(due.saturating_duration_since(Instant::now()));
        }
        let mut info = None;
        for _ in 0..=a.skip {
            info = source.next(&mut frames)?;
            if info.is_none() {
                break;
            }
        }
        let Some(info) = info else { break };
        let dir = if a.background {
            write_background(&out, &frames, rig.as_deref())?
        } else if a.table {
            write_table_view(&out, &frames, rig.as_deref())?
        } else {
            append_frame(&out, &frames, rig.as_deref())?
        };
        captured += 1;
        outln!(
            "captured {} ({} shot(s) per side, source frame {}) into {} at {:.1} s",
            info.name,
            frames.left.len(),
            info.index,
            dir.display(),
            started.elapsed().as_secs_f64()
        );
    }
    if captured == 0 {
        bail!("--source {}: the source gave no frame", a.source);
    }
    if captured < a.count {
        noteln!("note: the source ended after {captured} of {} frames", a.count);
    }
    if rig.is_none() && !out.join("rig.json").exists() {
        noteln!("note: {} has no rig.json yet; calibrate the rig and copy it there (or pass --rig)", out.display());
    }
    Ok(ExitCode::SUCCESS)
}
