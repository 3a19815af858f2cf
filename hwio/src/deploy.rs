//! The deployed loop: a capture thread reads the source (a recorded dataset or cameras)
//! into recycled buffers; an estimator thread estimates each frame with the same
//! `Estimator` every other path uses and turns it into the caller's record; the calling
//! thread hands each record on as it comes. When the estimator falls behind a camera, the
//! oldest waiting frame is dropped and counted.
//!
//! A recorded dataset (`dir:`) is read frame by frame with nothing dropped, as fast as the
//! estimator goes, unless a frame rate paces it like a camera; only then can frames be
//! dropped. Unpaced, a frame may wait for the estimator to finish the one before, and that
//! wait counts in its latency.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use camplace_config::RigFile;
use camplace_estimator::{Estimator, PoseEstimate, StageTimings};

use crate::capture::{Capture, WhenBehind};
use crate::cpu_time::process_cpu_time;
use crate::frames::{FrameInfo, FrameSource, Frames};
use crate::open::open_source;
use crate::paced::Paced;
use crate::recorded::RecordedSource;
use crate::spec::SourceSpec;
use crate::{Error, ErrorKind, Result};
use camplace_config::read_background;

/// Frame buffers between the capture and the estimator: one being filled, one being
/// estimated, one waiting. More would only make a late estimator later.
const BUFFERS: usize = 3;

/// A source opened for the deployed loop, with its calibration and background.
pub struct DeploySource {
    /// Where frames come from.
    pub source: Box<dyn FrameSource + Send>,
    /// The calibration file of the cameras.
    pub rig: RigFile,
    /// Its path, for messages.
    pub rig_path: PathBuf,
    /// The empty cell's images, when there are any.
    pub background: Option<Frames>,
    /// The recorded dataset's folder (where frames carry their truth), for a `dir:` source.
    pub dataset: Option<PathBuf>,
    /// What to do when the estimator is behind.
    pub when_behind: WhenBehind,
}

impl DeploySource {
    /// Opens `spec`: a recorded dataset brings its own `rig.json` and `background/` unless
    /// `rig` or `background` is given, and is paced at `fps` when given; a camera needs
    /// `rig` and runs at its own rate.
    pub fn open(
        spec: &SourceSpec,
        rig: Option<&Path>,
        background: Option<&Path>,
        fps: Option<f64>,
    ) -> Result<DeploySource> {
        if let SourceSpec::Recorded(dir) = spec {
            let source = RecordedSource::open(dir)?;
            let rig_path = rig.map_or_else(|| dir.join("rig.json"), Path::to_path_buf);
            let rig = RigFile::load(&rig_path)?;
            let background = match background {
                Some(bg) => Some(read_given_background(bg, &rig, source.shots())?),
                None => {
                    let mut frames = Frames::new(source.shots());
                    source.background(&mut frames)?.then_some(frames)
                }
            };
            let (source, when_behind): (Box<dyn FrameSource + Send>, _) = match fps {
                Some(fps) => (
                    Box::new(Paced::new(source, fps).map_err(|e| Error::new(e.kind(), format!("--fps: {e}")))?),
                    WhenBehind::DropOldest,
                ),
                None => (Box::new(source), WhenBehind::Wait),
            };
            return Ok(DeploySource { source, rig, rig_path, background, dataset: Some(dir.clone()), when_behind });
        }
        if fps.is_some() {
            return Err(Error::new(ErrorKind::Spec, "--fps paces a dir: source only; a camera runs at its own rate"));
        }
        let source = open_source(spec)?;
        let Some(rig_path) = rig.map(Path::to_path_buf) else {
            return Err(Error::new(
                ErrorKind::Spec,
                "--rig: a camera source needs its calibration (rig.json); expected --rig FILE (see docs/hardware.md)",
            ));
        };
        let rig = RigFile::load(&rig_path)?;
        let background = background.map(|bg| read_given_background(bg, &rig, source.shots())).transpose()?;
        Ok(DeploySource { source, rig, rig_path, background, dataset: None, when_behind: WhenBehind::DropOldest })
    }
}

/// The empty cell's images in `dir`, named as a frame's.
fn read_given_background(dir: &Path, rig: &RigFile, shots: usize) -> Result<Frames> {
    read_background(dir, rig, shots).map_err(|e| {
        let e = Error::from(e);
        Error::new(e.kind(), format!("--background: expected {shots} images per side: {e}"))
    })
}

/// One estimated frame as the loop hands it over.
#[derive(Debug, Clone)]
pub struct Estimated<T> {
    /// The source's capture time, µs (a camera's driver clock; a recording's file time).
    pub timestamp_us: u64,
    /// The frame's place in the stream, where its time went and the CPU time it took.
    pub timing: FrameTiming,
    /// What the caller made of the frame's pose.
    pub record: T,
}

/// The times of one estimated frame.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FrameTiming {
    /// Position in the source's stream, from 0 (gaps are dropped frames).
    pub sequence: u64,
    /// From the frame being in memory to its pose, ms: the estimator's stages plus any wait
    /// for the frame before it.
    pub latency_ms: f64,
    /// Each stage of the estimator on this frame.
    pub stages: StageTimings,
    /// CPU time of the process while this frame was estimated, ms: the estimator thread and
    /// the worker threads its stereo stages use (a capture reading the next frame meanwhile
    /// counts too).
    pub cpu_ms: f64,
}

/// What a finished loop measured.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct DeployStats {
    /// The times of every frame handed over, in stream order.
    pub frames: Vec<FrameTiming>,
    /// Frames the capture dropped because the estimator was behind.
    pub dropped: u64,
    /// Wall time of the whole run, s.
    pub wall_s: f64,
    /// CPU time of the whole process over the run (capture, estimator and output threads), s.
    pub process_cpu_s: f64,
}

impl DeployStats {
    /// The end-of-run line: frames, drops and latency percentiles.
    pub fn line(&self) -> String {
        let latencies: Vec<f64> = self.frames.iter().map(|f| f.latency_ms).collect();
        let (p50, p90, p99) = (p_text(&latencies, 50.0), p_text(&latencies, 90.0), p_text(&latencies, 99.0));
        format!(
            "{} frames estimated, {} dropped; capture-to-pose latency p50 {p50}, p90 {p90}, p99 {p99}",
            self.frames.len(),
            self.dropped,
        )
    }

    /// The end-of-run report: [`DeployStats::line`], then each stage's p50 and p99, and
    /// the CPU time per frame (while estimating it, and the whole process's share).
    pub fn report(&self) -> String {
        let mut text = self.line();
        if self.frames.is_empty() {
            return text;
        }
        text.push_str(&format!("\n  {:<11} {:>9} {:>9}", "stage", "p50 ms", "p99 ms"));
        for (k, name) in StageTimings::STAGES.iter().enumerate() {
            let times: Vec<f64> = self.frames.iter().map(|f| f.stages.by_stage()[k]).collect();
            if times.iter().all(|&t| t == 0.0) {
                continue; // a stage this method skips
            }
            text.push_str(&format!("\n  {name:<11} {:>9.1} {:>9.1}", p_value(&times, 50.0), p_value(&times, 99.0)));
        }
        let totals: Vec<f64> = self.frames.iter().map(|f| f.stages.total_ms).collect();
        text.push_str(&format!(
            "\n  {:<11} {:>9.1} {:>9.1}",
            "estimator",
            p_value(&totals, 50.0),
            p_value(&totals, 99.0)
        ));
        let cpu: Vec<f64> = self.frames.iter().map(|f| f.cpu_ms).collect();
        let per_frame = 1e3 * self.process_cpu_s / self.frames.len() as f64;
        let busy = if self.wall_s > 0.0 { self.process_cpu_s / self.wall_s } else { 0.0 };
        text.push_str(&format!(
            "\nCPU time per frame: while estimating p50 {:.1} ms, p99 {:.1} ms; over the whole run {per_frame:.1} \
             ms a frame ({:.1} s of CPU in {:.1} s: {busy:.2} cores busy)",
            p_value(&cpu, 50.0),
            p_value(&cpu, 99.0),
            self.process_cpu_s,
            self.wall_s,
        ));
        text
    }
}

/// The nearest-rank `q`-th percentile of `values` in any order; 0 when empty.
fn p_value(values: &[f64], q: f64) -> f64 {
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    camplace_estimator::scoring::percentile(&sorted, q).unwrap_or(0.0)
}

/// [`p_value`] as text with its unit, "n/a" when empty.
fn p_text(values: &[f64], q: f64) -> String {
    if values.is_empty() {
        return "n/a".to_string();
    }
    format!("{:.1} ms", p_value(values, q))
}

/// The deployed loop over one source.
pub struct Deployment {
    source: Box<dyn FrameSource + Send>,
    when_behind: WhenBehind,
    estimator: Estimator,
    stop: Arc<AtomicBool>,
    extra_delay: Duration,
}

impl Deployment {
    /// The loop estimating every frame of `source` with `estimator`.
    pub fn new(source: Box<dyn FrameSource + Send>, when_behind: WhenBehind, estimator: Estimator) -> Deployment {
        Deployment {
            source,
            when_behind,
            estimator,
            stop: Arc::new(AtomicBool::new(false)),
            extra_delay: Duration::ZERO,
        }
    }

    /// The flag that stops the loop when set (e.g. from a Ctrl-C handler).
    pub fn stop_flag(&self) -> Arc<AtomicBool> {
        self.stop.clone()
    }

    /// Makes the estimator this much slower per frame (to test dropping).
    pub fn with_extra_delay(mut self, delay: Duration) -> Deployment {
        self.extra_delay = delay;
        self
    }

    /// Runs until the source runs out or the stop flag is set. `record` runs on the
    /// estimator thread after each frame's pose; `emit` gets each record in order on this
    /// thread, and an error from it stops the loop and is returned once the threads ended.
    pub fn run<T, E, R, W>(self, mut record: R, mut emit: W) -> std::result::Result<DeployStats, E>
    where
        T: Send + 'static,
        E: From<Error> + Send + 'static,
        R: FnMut(&Estimator, &PoseEstimate, &FrameInfo) -> std::result::Result<T, E> + Send + 'static,
        W: FnMut(Estimated<T>) -> std::result::Result<(), E>,
    {
        let Deployment { source, when_behind, mut estimator, stop, extra_delay } = self;
        let (wall_start, cpu_start) = (std::time::Instant::now(), process_cpu_time());
        let capture = Capture::spawn_with(source, BUFFERS, when_behind)?;
        let (tx, rx) = crossbeam_channel::bounded::<Estimated<T>>(64);
        let stopping = stop.clone();
        let estimator_thread = std::thread::Builder::new()
            .name("camplace-estimator".into())
            .spawn(move || -> std::result::Result<u64, E> {
                while !stopping.load(Ordering::SeqCst) {
                    let Some(c) = capture.recv()? else { break };
                    let cpu_start = process_cpu_time();
                    let pose = estimator
                        .process(&c.frames.left, &c.frames.right)
                        .map_err(|e| Error::new(ErrorKind::Estimate, format!("frame {}: {e}", c.info.name)))?;
                    if !extra_delay.is_zero() {
                        std::thread::sleep(extra_delay);
                    }
                    let latency_ms = c.at.elapsed().as_secs_f64() * 1e3;
                    let cpu_ms = (process_cpu_time() - cpu_start).as_secs_f64() * 1e3;
                    capture.recycle(c.frames);
                    let record = record(&estimator, &pose, &c.info)?;
                    let timing = FrameTiming { sequence: c.info.index, latency_ms, stages: pose.timings, cpu_ms };
                    let e = Estimated { timestamp_us: c.info.timestamp_us, timing, record };
                    if tx.send(e).is_err() {
                        break;
                    }
                }
                Ok(capture.dropped())
            })
            .map_err(|e| Error::new(ErrorKind::Estimate, format!("cannot start the estimator thread: {e}")))?;

        let mut frames = Vec::new();
        let mut emitted = Ok(());
        for e in rx {
            let timing = e.timing;
            emitted = emit(e);
            if emitted.is_err() {
                stop.store(true, Ordering::SeqCst);
                break;
            }
            frames.push(timing);
        }
        let dropped = match estimator_thread.join() {
            Ok(result) => result?,
            Err(_) => return Err(Error::new(ErrorKind::Estimate, "the estimator thread stopped unexpectedly").into()),
        };
        emitted?;
        let wall_s = wall_start.elapsed().as_secs_f64();
        let process_cpu_s = (process_cpu_time() - cpu_start).as_secs_f64();
        Ok(DeployStats { frames, dropped, wall_s, process_cpu_s })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The report's row for `name`: its p50 and p99 as printed.
    fn row(report: &str, name: &str) -> Option<(f64, f64)> {
        let line = report.lines().find(|l| l.split_whitespace().next() == Some(name))?;
        let v: Vec<f64> = line.split_whitespace().skip(1).map(|t| t.parse().unwrap()).collect();
        Some((v[0], v[1]))
    }

    #[test]
    fn the_report_gives_each_stages_percentiles_and_the_cpu_time() {
        // 100 frames: RANSAC takes 1..=100 ms, ICP 2 ms, the 12-shot stages none.
        let frames: Vec<FrameTiming> = (1..=100u32)
            .map(|i| {
                let stages = StageTimings {
                    disparity_ms: 20.0,
                    ransac_ms: f64::from(i),
                    icp_ms: 2.0,
                    total_ms: 22.0 + f64::from(i),
                    ..StageTimings::default()
                };
                FrameTiming { sequence: u64::from(i), latency_ms: 30.0 + f64::from(i), stages, cpu_ms: f64::from(i) }
            })
            .collect();
        let stats = DeployStats { frames, dropped: 3, wall_s: 10.0, process_cpu_s: 5.0 };
        let report = stats.report();
        assert!(report.starts_with("100 frames estimated, 3 dropped; capture-to-pose latency p50 80.0 ms"), "{report}");
        assert_eq!(row(&report, "ransac"), Some((50.0, 99.0)), "{report}");
        assert_eq!(row(&report, "icp"), Some((2.0, 2.0)), "{report}");
        assert_eq!(row(&report, "disparity"), Some((20.0, 20.0)), "{report}");
        assert_eq!(row(&report, "estimator"), Some((72.0, 121.0)), "{report}");
        assert_eq!(row(&report, "rectify"), None, "a stage no frame ran is left out: {report}");
        assert!(report.contains("while estimating p50 50.0 ms, p99 99.0 ms"), "{report}");
        assert!(report.contains("whole run 50.0 ms a frame (5.0 s of CPU in 10.0 s: 0.50 cores busy)"), "{report}");
        let empty = DeployStats::default().report();
        assert_eq!(empty, "0 frames estimated, 0 dropped; capture-to-pose latency p50 n/a, p90 n/a, p99 n/a");
    }
}
