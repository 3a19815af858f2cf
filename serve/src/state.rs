//! What the service has done, shared by the worker, the connections, `STATUS` and the status
//! page: counts by status, the latency histogram, the last trigger (its left image and the
//! model's outline at its pose, its scene cloud and the model's points at the pose) and the
//! drift watch's state.

use std::collections::VecDeque;
use std::sync::{Condvar, Mutex};
use std::time::Duration;

use camplace_config::GrayImage;
use serde::Serialize;

use crate::drift::{DriftLimits, DriftState};
use crate::protocol::{Status, PROTOCOL};

/// Width of one latency histogram bar, ms.
pub const HISTOGRAM_STEP_MS: f64 = 10.0;
/// Bars of the histogram; the last takes everything from its start on.
pub const HISTOGRAM_BARS: usize = 21;
/// Latencies kept for the percentiles (the most recent).
const RECENT: usize = 1000;

/// The last trigger that reached the estimator.
#[derive(Debug, Clone, Default, Serialize)]
pub struct LastTrigger {
    /// The robot's id.
    pub id: Option<String>,
    /// The frame's name.
    pub frame: String,
    /// The reply's status word.
    pub status: String,
    /// The verification's verdict (`accepted`, `rejected: poor fit`, ...).
    pub verdict: String,
    /// The verification's score.
    pub score: f32,
    /// Trigger to reply, ms.
    pub latency_ms: f64,
}

/// Everything the page and `STATUS` show.
#[derive(Debug, Default)]
pub(crate) struct State {
    pub(crate) counts: [u64; 6],
    pub(crate) histogram: [u64; HISTOGRAM_BARS],
    pub(crate) recent: VecDeque<f64>,
    pub(crate) last: Option<LastTrigger>,
    /// The last frame's first left shot.
    pub(crate) image: GrayImage,
    /// Bumped with every new image, so the page asks for the new one.
    pub(crate) image_serial: u64,
    /// The model's outline at the last pose, left-image pixels (empty without a pose).
    pub(crate) outline: Vec<[f32; 2]>,
    /// The last frame's scene cloud, thinned (world mm): the page's 3D view.
    pub(crate) cloud: Vec<[f32; 3]>,
    /// The model's points at the last frame's pose (world mm; empty when no pose was found),
    /// and whether that pose was handed to the robot.
    pub(crate) model_at_pose: Vec<[f32; 3]>,
    pub(crate) pose_accepted: bool,
    pub(crate) drift: DriftState,
    pub(crate) drift_limits: Option<DriftLimits>,
    pub(crate) camera_error: Option<String>,
    pub(crate) recorded: u64,
    /// A trigger has been answered and its page, recorder and drift work is still running.
    pub(crate) settling: bool,
}

/// The shared state behind one lock; every holder keeps it for a copy's time only.
#[derive(Debug, Default)]
pub(crate) struct Shared {
    pub(crate) state: Mutex<State>,
    /// Signalled when the work after a reply is done.
    settled: Condvar,
}

/// Longest a reader waits for the work after a reply before reading the state as it is.
const SETTLE_WAIT: Duration = Duration::from_secs(2);

impl Shared {
    pub(crate) fn lock(&self) -> std::sync::MutexGuard<'_, State> {
        // A panicking holder leaves plain counters behind, still worth showing.
        self.state.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// The state once the work after the last reply is done (the last frame, its outline and
    /// the drift check of the trigger just answered), waiting at most [`SETTLE_WAIT`].
    pub(crate) fn settled(&self) -> std::sync::MutexGuard<'_, State> {
        let guard = self.lock();
        match self.settled.wait_timeout_while(guard, SETTLE_WAIT, |s| s.settling) {
            Ok((guard, _)) => guard,
            Err(p) => p.into_inner().0,
        }
    }

    /// Ends the work after a reply and wakes the readers waiting for it.
    pub(crate) fn settle(&self, mut state: std::sync::MutexGuard<'_, State>) {
        state.settling = false;
        drop(state);
        self.settled.notify_all();
    }

    pub(crate) fn count(&self, status: Status) {
        self.lock().counts[status.index()] += 1;
    }
}

impl State {
    pub(crate) fn add_latency(&mut self, ms: f64) {
        let bar = ((ms / HISTOGRAM_STEP_MS).floor().max(0.0) as usize).min(HISTOGRAM_BARS - 1);
        self.histogram[bar] += 1;
        if self.recent.len() == RECENT {
            self.recent.pop_front();
        }
        self.recent.push_back(ms);
    }

    /// The nearest-rank `q`-th percentile of the recent latencies.
    pub(crate) fn percentile(&self, q: f64) -> Option<f64> {
        let mut v: Vec<f64> = self.recent.iter().copied().collect();
        v.sort_by(f64::total_cmp);
        camplace_estimator::scoring::percentile(&v, q)
    }

    /// The `STATUS` reply line.
    pub(crate) fn status_line(&self) -> String {
        let mut s = String::from("STATUS");
        let triggers: u64 = self.counts[..4].iter().sum();
        s.push_str(&format!(" triggers={triggers}"));
        for status in Status::ALL {
            s.push_str(&format!(" {}={}", status.as_str().to_ascii_lowercase(), self.counts[status.index()]));
        }
        let p = |q| self.percentile(q).map_or("-".to_string(), |v| format!("{v:.1}"));
        s.push_str(&format!(" p50_ms={} p99_ms={}", p(50.0), p(99.0)));
        let d = &self.drift;
        let drift = match (d.warning, d.rotation_deg) {
            (true, _) => "warning",
            (false, Some(_)) => "ok",
            (false, None) => "unchecked",
        };
        s.push_str(&format!(" drift={drift}"));
        if let (Some(r), Some(t)) = (d.rotation_deg, d.translation_mm) {
            s.push_str(&format!(" drift_deg={r:.2} drift_mm={t:.1}"));
        }
        s.push_str(&format!(" camera={}", if self.camera_error.is_some() { "error" } else { "ok" }));
        s
    }

    /// The status as the page's JSON endpoint gives it.
    pub(crate) fn json(&self) -> StatusJson {
        StatusJson {
            protocol: PROTOCOL,
            counts: Status::ALL.iter().map(|s| (s.as_str(), self.counts[s.index()])).collect(),
            latency_ms: LatencyJson {
                p50: self.percentile(50.0),
                p99: self.percentile(99.0),
                histogram_step_ms: HISTOGRAM_STEP_MS,
                histogram: self.histogram.to_vec(),
            },
            last: self.last.clone(),
            image_serial: self.image_serial,
            outline: self.outline.clone(),
            drift: self.drift.clone(),
            drift_limits: self.drift_limits.clone(),
            camera_error: self.camera_error.clone(),
            recorded: self.recorded,
        }
    }
}

/// The JSON endpoint's body.
#[derive(Debug, Serialize)]
pub(crate) struct StatusJson {
    protocol: &'static str,
    counts: std::collections::BTreeMap<&'static str, u64>,
    latency_ms: LatencyJson,
    last: Option<LastTrigger>,
    image_serial: u64,
    outline: Vec<[f32; 2]>,
    drift: DriftState,
    drift_limits: Option<DriftLimits>,
    camera_error: Option<String>,
    recorded: u64,
}

#[derive(Debug, Serialize)]
struct LatencyJson {
    p50: Option<f64>,
    p99: Option<f64>,
    histogram_step_ms: f64,
    histogram: Vec<u64>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;

    #[test]
    fn a_reader_after_the_reply_waits_for_the_work_after_it() {
        let shared = Arc::new(Shared::default());
        shared.lock().settling = true;
        let worker = {
            let shared = shared.clone();
            std::thread::spawn(move || {
                std::thread::sleep(Duration::from_millis(100));
                let mut s = shared.lock();
                s.recorded = 7;
                shared.settle(s);
            })
        };
        assert_eq!(shared.settled().recorded, 7);
        assert!(!shared.lock().settling);
        worker.join().unwrap();
    }

    #[test]
    fn a_worker_that_never_settles_holds_readers_for_the_wait_only() {
        let shared = Shared::default();
        shared.lock().settling = true;
        let start = std::time::Instant::now();
        let s = shared.settled();
        assert!(s.settling);
        assert!(start.elapsed() >= SETTLE_WAIT);
    }

    #[test]
    fn latencies_fall_in_their_bars_and_the_last_bar_takes_the_rest() {
        let mut s = State::default();
        for ms in [0.0, 9.99, 10.0, 25.0, 199.9, 200.0, 5000.0, -3.0] {
            s.add_latency(ms);
        }
        let mut expected = [0u64; HISTOGRAM_BARS];
        for bar in [0, 0, 1, 2, 19, 20, 20, 0] {
            expected[bar] += 1;
        }
        assert_eq!(s.histogram, expected);
    }

    #[test]
    fn percentiles_are_of_the_most_recent_latencies_only() {
        let mut s = State::default();
        // The first 500 are far slower and fall out of the window.
        let all: Vec<f64> =
            (0..RECENT + 500).map(|i| if i < 500 { 1000.0 + i as f64 } else { (i % 97) as f64 }).collect();
        for &ms in &all {
            s.add_latency(ms);
        }
        assert_eq!(s.recent.len(), RECENT);
        let window = &all[all.len() - RECENT..];
        for q in [1.0, 50.0, 99.0, 100.0] {
            // Brute force: the smallest value with at least q % of the window at or below it.
            let slow = window
                .iter()
                .copied()
                .filter(|&v| window.iter().filter(|&&w| w <= v).count() as f64 >= q / 100.0 * RECENT as f64)
                .fold(f64::INFINITY, f64::min);
            assert_eq!(s.percentile(q), Some(slow), "q {q}");
        }
        assert_eq!(State::default().percentile(50.0), None);
    }

    #[test]
    fn the_status_line_counts_every_status_and_triggers_only_once() {
        let shared = Shared::default();
        for (status, times) in [
            (Status::Ok, 3),
            (Status::NoPose, 2),
            (Status::Rejected, 1),
            (Status::CameraError, 1),
            (Status::Busy, 4),
            (Status::BadRequest, 5),
        ] {
            (0..times).for_each(|_| shared.count(status));
        }
        let line = shared.lock().status_line();
        assert_eq!(
            line,
            "STATUS triggers=7 ok=3 no_pose=2 rejected=1 camera_error=1 busy=4 bad_request=5 p50_ms=- p99_ms=- \
             drift=unchecked camera=ok"
        );
    }

    #[test]
    fn the_status_line_says_the_drift_and_the_camera_as_they_are() {
        let mut s = State::default();
        s.add_latency(12.0);
        s.drift.rotation_deg = Some(0.123);
        s.drift.translation_mm = Some(1.25);
        assert!(s.status_line().ends_with("p50_ms=12.0 p99_ms=12.0 drift=ok drift_deg=0.12 drift_mm=1.2 camera=ok"));
        s.drift.warning = true;
        s.camera_error = Some("left: gone".into());
        assert!(
            s.status_line().ends_with("drift=warning drift_deg=0.12 drift_mm=1.2 camera=error"),
            "{}",
            s.status_line()
        );
    }

    #[test]
    fn the_json_holds_the_same_counts_as_the_line() {
        let shared = Shared::default();
        shared.count(Status::Rejected);
        shared.count(Status::Busy);
        let v = serde_json::to_value(shared.lock().json()).unwrap();
        assert_eq!(v["protocol"], PROTOCOL);
        assert_eq!(v["counts"]["REJECTED"], 1);
        assert_eq!(v["counts"]["BUSY"], 1);
        assert_eq!(v["counts"]["OK"], 0);
        assert_eq!(v["latency_ms"]["histogram"].as_array().unwrap().len(), HISTOGRAM_BARS);
        assert!(v["latency_ms"]["p50"].is_null());
    }
}
