//! The trigger worker: the one thread that owns the camera and the estimator. It takes
//! triggers from a small queue one at a time: capture, estimate, verify, reply; then it
//! updates the page's state, keeps a refused frame in the flight recorder and runs the
//! drift watch, after the reply has gone. It keeps the last accepted pose's slot frames and
//! answers `SLOT n` from them, in turn with the triggers.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use camplace_config::{format_pose_exact, thinned, RobotPoseFormat};
use camplace_estimator::{
    geometry::isometry_from_rows, geometry::isometry_to_rows, geometry::Camera as LensCamera, pose::slot_letters,
    pose::SlotState, pose::Verdict, Estimator,
};
use camplace_hwio::Frames;
use crossbeam_channel::{Receiver, RecvTimeoutError, Sender};
use nalgebra::Point3;

use crate::camera::Camera;
use crate::drift::DriftWatch;
use crate::outline::{outline, outline_points};
use crate::protocol::{
    bad_request_line, rejected_reason, slot_line, slot_without_pose_line, BadRequest, Status, TriggerReply,
};
use crate::recorder::FlightRecorder;
use crate::state::{LastTrigger, Shared};
use crate::Log;

/// One trigger waiting for the worker.
pub(crate) struct Job {
    pub(crate) id: Option<String>,
    /// When the request line was read.
    pub(crate) at: Instant,
    pub(crate) reply: Sender<String>,
    /// `SLOT n`: the slot asked for, answered from the last trigger instead of a capture.
    pub(crate) slot: Option<usize>,
}

/// The last trigger's slots, for `SLOT n`.
#[derive(Default)]
struct LastSlots {
    /// Whether the last trigger's pose was accepted (only then are its frames handed on).
    accepted: bool,
    /// The frame's name.
    frame: String,
    /// Each slot's state, askew flag and frame (slot -> robot base, or world without a
    /// `[robot]`) in the robot's pose format.
    slots: Vec<(SlotState, bool, String)>,
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

/// Most scene points and model points the status page's 3D view is handed.
const CLOUD_POINTS: usize = 3000;
const MODEL_POINTS: usize = 2000;

/// Slot `n` of `last` as the reply to `SLOT n`; `slot_count` is the model's slots.
fn slot_reply(n: usize, last: &LastSlots, slot_count: usize) -> String {
    if n >= slot_count && slot_count > 0 {
        return bad_request_line(BadRequest::NoSuchSlot);
    }
    match last.slots.get(n) {
        Some((state, askew, pose)) if last.accepted => slot_line(n, state.as_str(), *askew, &last.frame, pose),
        _ => slot_without_pose_line(n),
    }
}

impl Worker {
    /// Serves `jobs` until `stop` is set; the trigger in hand is finished first.
    pub(crate) fn run(mut self, jobs: Receiver<Job>, stop: Arc<AtomicBool>) {
        let points = outline_points(self.estimator.model());
        let slot_count = self.estimator.model().slots.as_ref().map_or(0, |l| l.slots.len());
        let mut frames = Frames::new(0);
        let mut last = LastSlots::default();
        while !stop.load(Ordering::SeqCst) {
            match jobs.recv_timeout(Duration::from_millis(100)) {
                Ok(job) => match job.slot {
                    Some(n) => {
                        let _ = job.reply.send(slot_reply(n, &last, slot_count));
                    }
                    None => self.trigger(job, &mut frames, &points, &mut last),
                },
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

    fn trigger(&mut self, job: Job, frames: &mut Frames, points: &[Point3<f64>], last: &mut LastSlots) {
        let start = Instant::now();
        // A `SLOT n` after this trigger answers for its pose, not an older one.
        last.accepted = false;
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
            slots: None,
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
                let readings = self.estimator.slots();
                if !readings.is_empty() {
                    let mut letters = String::with_capacity(readings.len());
                    slot_letters(readings, &mut letters);
                    reply.slots = Some(letters);
                    // Each slot's frame as the pose is formatted: rows, then the robot's frame.
                    last.frame.clone_from(&info.name);
                    last.slots.clear();
                    for r in readings {
                        let rows = isometry_to_rows(&r.t_world_slot);
                        let t = match &self.t_robot_world {
                            Some(w) => isometry_to_rows(&(isometry_from_rows(w) * isometry_from_rows(&rows))),
                            None => rows,
                        };
                        last.slots.push((r.state, r.askew, format_pose_exact(&t, self.format).replace(' ', ",")));
                    }
                    last.accepted = true;
                }
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
        let drift = if self.drift.due(self.estimator.matched_whole()) {
            match self.estimator.whole_disparity() {
                Ok((disparity, camera)) => self.drift.check(disparity, camera).clone(),
                Err(e) => {
                    (self.log)(&format!("drift watch: {e}"));
                    self.drift.state().clone()
                }
            }
        } else {
            self.drift.state().clone()
        };
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
            // The 3D view: the buffers keep their capacity, so no frame allocates once warm.
            let cloud = self.estimator.scene_cloud();
            s.cloud.clear();
            s.cloud.extend(thinned(cloud, CLOUD_POINTS).map(|p| [p.x, p.y, p.z]));
            s.model_at_pose.clear();
            if pose.found {
                let t = pose.t_world_tray.cast::<f32>();
                s.model_at_pose.extend(thinned(points, MODEL_POINTS).map(|p| {
                    let q = t * p.cast::<f32>();
                    [q.x, q.y, q.z]
                }));
            }
            s.pose_accepted = reply.status == Status::Ok;
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

#[cfg(test)]
mod tests {
    use super::*;

    fn last(accepted: bool) -> LastSlots {
        LastSlots {
            accepted,
            frame: "0012".into(),
            slots: vec![(SlotState::Filled, false, "1,2,3".into()), (SlotState::Empty, true, "4,5,6".into())],
        }
    }

    #[test]
    fn a_slot_of_an_accepted_pose_is_handed_on_with_its_state_and_frame() {
        assert_eq!(slot_reply(0, &last(true), 2), "OK slot=0 state=filled askew=0 frame=0012 pose=1,2,3");
        assert_eq!(slot_reply(1, &last(true), 2), "OK slot=1 state=empty askew=1 frame=0012 pose=4,5,6");
    }

    #[test]
    fn a_slot_past_the_tray_s_last_is_a_bad_request() {
        assert_eq!(slot_reply(2, &last(true), 2), "BAD_REQUEST no-such-slot");
        assert_eq!(slot_reply(9999, &last(false), 2), "BAD_REQUEST no-such-slot");
    }

    #[test]
    fn without_an_accepted_pose_a_slot_has_no_frame() {
        assert_eq!(slot_reply(0, &last(false), 2), "NO_POSE slot=0");
        assert_eq!(slot_reply(1, &LastSlots::default(), 2), "NO_POSE slot=1");
        // A model without slots: nothing to hand on, whatever the number.
        assert_eq!(slot_reply(5, &LastSlots { accepted: true, ..LastSlots::default() }, 0), "NO_POSE slot=5");
    }
}
