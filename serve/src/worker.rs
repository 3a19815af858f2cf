//! The trigger worker: the one thread that owns the camera and the estimator. It takes
//! triggers from a small queue one at a time: capture, estimate, verify, reply; then it
//! updates the page's state, keeps a refused frame in the flight recorder and runs the
//! drift watch, after the reply has gone.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use camplace_config::{format_pose_exact, RobotPoseFormat};
use camplace_estimator::{isometry_from_rows, isometry_to_rows, Camera as LensCamera, Estimator, Verdict};
use camplace_hwio::Frames;
use crossbeam_channel::{Receiver, RecvTimeoutError, Sender};
use nalgebra::Point3;

use crate::camera::Camera;
use crate::drift::DriftWatch;
use crate::outline::{outline, outline_points};
use crate::protocol::{rejected_reason, Status, TriggerReply};
use crate::recorder::FlightRecorder;
use crate::state::{LastTrigger, Shared};
use crate::Log;

/// One trigger waiting for the worker.
pub(crate) struct Job {
    pub(crate) id: Option<String>,
    /// When the request line was read.
    pub(crate) at: Instant,
    pub(crate) reply: Sender<String>,
}

pub(crate) struct Worker {
    pub(crate) estimator: Estimator,
    pub(crate) camera: Camera,
    pub(crate) format: RobotPoseFormat,
    pub(crate) t_robot_world: Option<[[f64; 4]; 4]>,
    pub(crate) left: LensCamera,
    pub(crate) recorder: Option<FlightRecorder>,
    pub(crate) drift: DriftWatch,
    pub(crate) shared: Arc<Shared>,
    pub(crate) log: Log,
}

impl Worker {
    /// Serves `jobs` until `stop` is set; the trigger in hand is finished first.
    pub(crate) fn run(mut self, jobs: Receiver<Job>, stop: Arc<AtomicBool>) {
        let points = outline_points(self.estimator.model());
        let mut frames = Frames::new(0);
        while !stop.load(Ordering::SeqCst) {
            match jobs.recv_timeout(Duration::from_millis(100)) {
                Ok(job) => self.trigger(job, &mut frames, &points),
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => break,
            }
        }
        // Triggers still queued are told the service is stopping.
        for job in jobs.try_iter() {
            let _ = job.reply.send(crate::protocol::busy_line("stopping", job.id.as_deref()));
            self.shared.count(Status::Busy);
        }
    }

    fn trigger(&mut self, job: Job, frames: &mut Frames, points: &[Point3<f64>]) {
        let start = Instant::now();
        let grabbed = self.camera.grab(frames);
        let capture_ms = start.elapsed().as_secs_f64() * 1e3;
        let mut reply = TriggerReply {
            status: Status::CameraError,
            reason: None,
            id: job.id.clone(),
            frame: None,
            pose: None,
            score: None,
            capture_ms,
            compute_ms: 0.0,
        };
        let info = match grabbed {
            Ok(info) => info,
            Err(e) => {
                self.finish(&job, &reply, false);
                (self.log)(&format!("{}: {e}", reply.line()));
                self.shared.lock().camera_error = Some(e);
                return;
            }
        };
        reply.frame = Some(info.name.clone());
        let estimated = self.estimator.process(&frames.left, &frames.right);
        reply.compute_ms = start.elapsed().as_secs_f64() * 1e3 - capture_ms;
        let pose = match estimated {
            Ok(pose) => pose,
            Err(e) => {
                self.finish(&job, &reply, false);
                let e = format!("frame {}: {e}", info.name);
                (self.log)(&format!("{}: {e}", reply.line()));
                self.shared.lock().camera_error = Some(e);
                return;
            }
        };
        let verdict = pose.verification.verdict;
        reply.score = Some(pose.verification.score);
        // The pose as `replay` writes it: rows first, then into the robot's frame.
        let t_world_tray = isometry_to_rows(&pose.t_world_tray);
        match (pose.found, verdict) {
            (false, _) | (true, Verdict::NoTray) => reply.status = Status::NoPose,
            (true, Verdict::Accepted) => {
                let t = match &self.t_robot_world {
                    Some(r) => isometry_to_rows(&(isometry_from_rows(r) * isometry_from_rows(&t_world_tray))),
                    None => t_world_tray,
                };
                reply.status = Status::Ok;
                reply.pose = Some(format_pose_exact(&t, self.format).replace(' ', ","));
            }
            (true, v) => {
                reply.status = Status::Rejected;
                reply.reason = Some(rejected_reason(v));
            }
        }
        let latency_ms = self.finish(&job, &reply, true);

        // After the reply: the page, the recorder and the drift watch.
        let hull =
            if reply.status == Status::Ok { outline(points, &pose.t_world_tray, &self.left) } else { Vec::new() };
        let mut recorded = None;
        if matches!(reply.status, Status::NoPose | Status::Rejected) {
            if let Some(recorder) = &mut self.recorder {
                match recorder.keep(frames) {
                    Ok(dir) => recorded = dir,
                    Err(e) => (self.log)(&format!("flight recorder: {e}")),
                }
            }
        }
        let drift =
            self.drift.check(&self.estimator.reconstruction().disparity, self.estimator.rectified_camera()).clone();
        {
            let mut s = self.shared.lock();
            s.camera_error = None;
            s.last = Some(LastTrigger {
                id: job.id.clone(),
                frame: info.name.clone(),
                status: reply.status.as_str().to_string(),
                verdict: verdict.as_str().to_string(),
                score: pose.verification.score,
                latency_ms,
            });
            if let Some(left) = frames.left.first() {
                s.image.width = left.width;
                s.image.height = left.height;
                s.image.data.clone_from(&left.data);
                s.image_serial += 1;
            }
            s.outline = hull;
            if recorded.is_some() {
                s.recorded += 1;
            }
            s.drift = drift.clone();
            self.shared.settle(s);
        }
        let mut line = reply.line();
        if let Some(dir) = recorded {
            line.push_str(&format!(" recorded={}", dir.display()));
        }
        if drift.warning {
            line.push_str(" drift=warning");
        }
        (self.log)(&line);
    }

    /// Sends the reply, counts it and its latency; returns the latency, ms. With `more`, the
    /// state is marked settling until the work after the reply calls [`Shared::settle`].
    fn finish(&self, job: &Job, reply: &TriggerReply, more: bool) -> f64 {
        // Marked before the reply goes, so a reader who has the reply waits for the rest.
        self.shared.lock().settling = more;
        let _ = job.reply.send(reply.line());
        let latency_ms = job.at.elapsed().as_secs_f64() * 1e3;
        let mut s = self.shared.lock();
        s.counts[reply.status.index()] += 1;
        s.add_latency(latency_ms);
        latency_ms
    }
}
