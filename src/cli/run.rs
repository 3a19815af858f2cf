//! `camplace run`: the deployed loop. A capture thread reads the source (a recorded dataset
//! or cameras) into recycled buffers; an estimator thread reconstructs and estimates each
//! frame with the same `Estimator` every other command uses; this thread writes one JSON
//! line per frame. When the estimator falls behind a camera, the oldest waiting frame is
//! dropped and counted. At the end (the source ran out, or Ctrl-C) the capture-to-pose
//! latency percentiles and the drop count are printed on stderr.
//!
//! A recorded dataset (`dir:`) is read frame by frame with nothing dropped, as fast as the
//! estimator goes, unless `--fps F` paces it like a camera at F frames per second; only then
//! can frames be dropped. Without `--fps` a frame may wait for the estimator to finish the
//! one before, and that wait counts in its latency: give `--fps` at the camera's rate to
//! measure what a camera would see.

use anyhow::{bail, Context};
use camplace_config::formats::dataset::image_name;
use camplace_config::formats::png::read_gray;
use camplace_config::{Cell, RigFile};
use camplace_estimator::{GrayImage, Rig};
use camplace_hwio::{
    open_source, parse_source, Capture, FrameSource, Frames, Paced, RecordedSource, SourceSpec, WhenBehind,
};
use camplace_sim::study::{FrameRecord, Summary};
use serde::Serialize;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use super::recording::{estimator_for, load_model, method_for, record, truth_path};

/// Frame buffers between the capture and the estimator: one being filled, one being
/// estimated, one waiting. More would only make a late estimator later.
const BUFFERS: usize = 3;

/// Flags of `camplace run`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Where frames come from: dir:PATH, v4l2:LEFT,RIGHT, v4l2-sbs:DEV, v4l2-16:DEV or dc1394[:GUID]
    /// (see docs/hardware.md).
    #[arg(long, value_name = "SPEC")]
    source: String,
    /// The tray model (from `camplace model`).
    #[arg(long, value_name = "FILE")]
    model: PathBuf,
    /// Write the JSON lines here instead of stdout.
    #[arg(long, value_name = "FILE")]
    out: Option<PathBuf>,
    /// Cell file (TOML) with the estimator settings; the built-in default when not given.
    #[arg(long, value_name = "FILE")]
    cell: Option<PathBuf>,
    /// Calibration of the cameras (needed for cameras; a dataset's own rig.json otherwise).
    #[arg(long, value_name = "FILE")]
    rig: Option<PathBuf>,
    /// A folder with the empty cell's images, named as a frame's (left.png, right.png); a
    /// dataset's own background/ otherwise.
    #[arg(long, value_name = "DIR")]
    background: Option<PathBuf>,
    /// Pace a dir: source like a camera at this many frames per second (frames may then be
    /// dropped); default: every frame, as fast as the estimator goes.
    #[arg(long, value_name = "F")]
    fps: Option<f64>,
    /// For testing only: make the estimator this much slower per frame, ms.
    #[arg(long, value_name = "MS", default_value_t = 0, hide = true)]
    debug_delay_ms: u64,
}

/// One output line: the frame's record with its place in the stream and its latency.
#[derive(Serialize)]
struct RunLine<'a> {
    /// Position in the source's stream, from 0 (gaps are dropped frames).
    sequence: u64,
    /// The source's capture time, µs (a camera's driver clock; a recording's file time).
    timestamp_us: u64,
    /// From the frame being in memory to its pose, ms.
    latency_ms: f64,
    #[serde(flatten)]
    record: &'a FrameRecord,
}

/// What the estimator thread hands over per frame.
struct Estimated {
    sequence: u64,
    timestamp_us: u64,
    latency_ms: f64,
    record: FrameRecord,
}

/// Runs `camplace run`.
pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let spec = parse_source(&a.source)?;
    let cell = match &a.cell {
        Some(path) => Cell::load(path)?,
        None => Cell::default(),
    };
    let (source, rig_path, background, dataset, when_behind) = open(&a, &spec)?;
    let rig = Rig::from_file(&RigFile::load(&rig_path)?);
    let model = load_model(&a.model)?;
    let method = method_for(source.shots());
    let mut estimator = estimator_for(&cell, model, &rig, &rig_path, method, background.as_ref())?;
    if background.is_none() {
        eprintln!("note: no background to remove (give --background DIR with the empty cell's images)");
    }

    let stop = Arc::new(AtomicBool::new(false));
    let on_signal = stop.clone();
    // A second handler cannot be set in one process; only tests would try.
    let _ = ctrlc::set_handler(move || on_signal.store(true, Ordering::SeqCst));

    let capture = Capture::spawn_with(source, BUFFERS, when_behind)?;
    let (tx, rx) = crossbeam_channel::bounded::<Estimated>(64);
    let delay = Duration::from_millis(a.debug_delay_ms);
    let stopping = stop.clone();
    let estimator_thread =
        std::thread::Builder::new().name("camplace-estimator".into()).spawn(move || -> anyhow::Result<u64> {
            while !stopping.load(Ordering::SeqCst) {
                let Some(c) = capture.recv()? else { break };
                let pose = estimator
                    .process(&c.frames.left, &c.frames.right)
                    .with_context(|| format!("frame {}", c.info.name))?;
                if !delay.is_zero() {
                    std::thread::sleep(delay);
                }
                let latency_ms = c.at.elapsed().as_secs_f64() * 1e3;
                capture.recycle(c.frames);
                let truth = dataset.as_deref().and_then(|d| truth_path(d, &c.info.name));
                let record = record(&cell, &estimator, &pose, &c.info.name, truth.as_deref())?;
                let e = Estimated { sequence: c.info.index, timestamp_us: c.info.timestamp_us, latency_ms, record };
                if tx.send(e).is_err() {
                    break;
                }
            }
            Ok(capture.dropped())
        })?;

    let mut out: Box<dyn Write> = match &a.out {
        Some(path) => Box::new(std::io::BufWriter::new(
            std::fs::File::create(path)
                .with_context(|| format!("{}: cannot create the output file", path.display()))?,
        )),
        None => Box::new(std::io::stdout().lock()),
    };
    let mut latencies = Vec::new();
    let mut records = Vec::new();
    let mut written = Ok(());
    for e in rx {
        let line =
            RunLine { sequence: e.sequence, timestamp_us: e.timestamp_us, latency_ms: e.latency_ms, record: &e.record };
        let text = serde_json::to_string(&line).context("frame record")?;
        // Flushed per line so a reader of the stream sees each pose as it comes.
        written = writeln!(out, "{text}").and_then(|_| out.flush());
        if written.is_err() {
            stop.store(true, Ordering::SeqCst);
            break;
        }
        latencies.push(e.latency_ms);
        records.push(e.record);
    }
    let dropped = match estimator_thread.join() {
        Ok(result) => result?,
        Err(_) => bail!("the estimator thread stopped unexpectedly"),
    };
    if let Err(e) = written {
        let name = a.out.as_ref().map_or("stdout".to_string(), |p| p.display().to_string());
        bail!("{name}: cannot write the poses: {e}");
    }
    eprintln!("{}", report(&latencies, dropped));
    let summary = Summary::from_records(&records);
    if summary.scored > 0 {
        eprintln!("{}", summary.line());
    }
    Ok(ExitCode::SUCCESS)
}

type Opened = (Box<dyn FrameSource + Send>, PathBuf, Option<Frames>, Option<PathBuf>, WhenBehind);

/// The source, its calibration, its background, the dataset folder (for truth) and what to
/// do when the estimator is behind.
fn open(a: &Args, spec: &SourceSpec) -> anyhow::Result<Opened> {
    if let SourceSpec::Recorded(dir) = spec {
        let source = RecordedSource::open(dir)?;
        let rig = a.rig.clone().unwrap_or_else(|| dir.join("rig.json"));
        let mut frames = Frames::new(source.shots());
        let background = match &a.background {
            Some(bg) => Some(read_background(bg, source.shots())?),
            None => source.background(&mut frames)?.then_some(frames),
        };
        let (source, when_behind): (Box<dyn FrameSource + Send>, _) = match a.fps {
            Some(fps) => (Box::new(Paced::new(source, fps).context("--fps")?), WhenBehind::DropOldest),
            None => (Box::new(source), WhenBehind::Wait),
        };
        return Ok((source, rig, background, Some(dir.clone()), when_behind));
    }
    if a.fps.is_some() {
        bail!("--fps paces a dir: source only; a camera runs at its own rate");
    }
    let source = open_source(spec)?;
    let Some(rig) = a.rig.clone() else {
        bail!("--rig: a camera source needs its calibration (rig.json); expected --rig FILE (see docs/hardware.md)")
    };
    let background = a.background.as_deref().map(|bg| read_background(bg, source.shots())).transpose()?;
    Ok((source, rig, background, None, WhenBehind::DropOldest))
}

/// The empty cell's images in `dir`, named as a frame's.
fn read_background(dir: &Path, shots: usize) -> anyhow::Result<Frames> {
    let mut frames = Frames::new(shots);
    for shot in 0..shots {
        for (side, images) in [("left", &mut frames.left), ("right", &mut frames.right)] {
            let path = dir.join(image_name(side, shot, shots));
            let g = read_gray(&path).with_context(|| format!("--background: expected {} images per side", shots))?;
            images[shot] = GrayImage::from_vec(g.width, g.height, g.data).context("background image")?;
        }
    }
    Ok(frames)
}

/// The end-of-run line: frames, drops and latency percentiles.
fn report(latencies: &[f64], dropped: u64) -> String {
    let mut sorted = latencies.to_vec();
    sorted.sort_by(f64::total_cmp);
    let p = |q| percentile(&sorted, q).map_or("n/a".to_string(), |v| format!("{v:.1} ms"));
    format!(
        "{} frames estimated, {dropped} dropped; capture-to-pose latency p50 {}, p90 {}, p99 {}",
        latencies.len(),
        p(50.0),
        p(90.0),
        p(99.0)
    )
}

/// The nearest-rank `q`-th percentile of ascending `sorted` values; `None` when empty.
fn percentile(sorted: &[f64], q: f64) -> Option<f64> {
    if sorted.is_empty() {
        return None;
    }
    let rank = ((q / 100.0) * sorted.len() as f64).ceil() as usize;
    Some(sorted[rank.clamp(1, sorted.len()) - 1])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_rank_percentiles_match_counting() {
        let values: Vec<f64> = (1..=200).rev().map(f64::from).collect();
        let mut sorted = values.clone();
        sorted.sort_by(f64::total_cmp);
        for q in [1.0, 50.0, 90.0, 99.0, 100.0] {
            let got = percentile(&sorted, q).unwrap();
            // The smallest value with at least q % of all values at or below it.
            let slow = values
                .iter()
                .copied()
                .filter(|&v| values.iter().filter(|&&w| w <= v).count() as f64 >= q / 100.0 * values.len() as f64)
                .fold(f64::INFINITY, f64::min);
            assert_eq!(got, slow, "q {q}");
        }
        assert_eq!(percentile(&[7.0], 99.0), Some(7.0));
        assert_eq!(percentile(&[], 50.0), None);
    }
}
