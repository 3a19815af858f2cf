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
use camplace_estimator::{Estimator, PoseEstimate};

use crate::capture::{Capture, WhenBehind};
use crate::frames::{FrameInfo, FrameSource, Frames};
use crate::paced::Paced;
use crate::recorded::{read_background, RecordedSource};
use crate::spec::{open_source, SourceSpec};
use crate::{Error, ErrorKind, Result};

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
    read_background(dir, rig, shots)
        .map_err(|e| Error::new(e.kind(), format!("--background: expected {shots} images per side: {e}")))
}

/// One estimated frame as the loop hands it over.
#[derive(Debug, Clone)]
pub struct Estimated<T> {
    /// Position in the source's stream, from 0 (gaps are dropped frames).
    pub sequence: u64,
    /// The source's capture time, µs (a camera's driver clock; a recording's file time).
    pub timestamp_us: u64,
    /// From the frame being in memory to its pose, ms.
    pub latency_ms: f64,
    /// What the caller made of the frame's pose.
    pub record: T,
}

/// What a finished loop measured.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct DeployStats {
    /// Capture-to-pose latency of every frame handed over, ms, in stream order.
    pub latencies_ms: Vec<f64>,
    /// Frames the capture dropped because the estimator was behind.
    pub dropped: u64,
}

impl DeployStats {
    /// The end-of-run line: frames, drops and latency percentiles.
    pub fn line(&self) -> String {
        let mut sorted = self.latencies_ms.clone();
        sorted.sort_by(f64::total_cmp);
        let p = |q| percentile(&sorted, q).map_or("n/a".to_string(), |v| format!("{v:.1} ms"));
        format!(
            "{} frames estimated, {} dropped; capture-to-pose latency p50 {}, p90 {}, p99 {}",
            self.latencies_ms.len(),
            self.dropped,
            p(50.0),
            p(90.0),
            p(99.0)
        )
    }
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
        let capture = Capture::spawn_with(source, BUFFERS, when_behind)?;
        let (tx, rx) = crossbeam_channel::bounded::<Estimated<T>>(64);
        let stopping = stop.clone();
        let estimator_thread = std::thread::Builder::new()
            .name("camplace-estimator".into())
            .spawn(move || -> std::result::Result<u64, E> {
                while !stopping.load(Ordering::SeqCst) {
                    let Some(c) = capture.recv()? else { break };
                    let pose = estimator
                        .process(&c.frames.left, &c.frames.right)
                        .map_err(|e| Error::new(ErrorKind::Estimate, format!("frame {}: {e}", c.info.name)))?;
                    if !extra_delay.is_zero() {
                        std::thread::sleep(extra_delay);
                    }
                    let latency_ms = c.at.elapsed().as_secs_f64() * 1e3;
                    capture.recycle(c.frames);
                    let record = record(&estimator, &pose, &c.info)?;
                    let e = Estimated { sequence: c.info.index, timestamp_us: c.info.timestamp_us, latency_ms, record };
                    if tx.send(e).is_err() {
                        break;
                    }
                }
                Ok(capture.dropped())
            })
            .map_err(|e| Error::new(ErrorKind::Estimate, format!("cannot start the estimator thread: {e}")))?;

        let mut latencies_ms = Vec::new();
        let mut emitted = Ok(());
        for e in rx {
            let latency_ms = e.latency_ms;
            emitted = emit(e);
            if emitted.is_err() {
                stop.store(true, Ordering::SeqCst);
                break;
            }
            latencies_ms.push(latency_ms);
        }
        let dropped = match estimator_thread.join() {
            Ok(result) => result?,
            Err(_) => return Err(Error::new(ErrorKind::Estimate, "the estimator thread stopped unexpectedly").into()),
        };
        emitted?;
        Ok(DeployStats { latencies_ms, dropped })
    }
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
