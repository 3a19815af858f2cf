//! A source held to a frame rate: frame i is released no earlier than i / fps after the
//! first, as a camera running at that rate would deliver it. It turns a recording into a
//! stand-in for a live camera, so the capture thread's dropping can be seen and tested.

use std::time::{Duration, Instant};

use crate::frames::{FrameInfo, FrameSource, Frames};
use crate::{Error, ErrorKind, Result};

/// `inner`'s frames at `fps` frames per second at most.
pub struct Paced<S> {
    inner: S,
    period: Duration,
    start: Option<Instant>,
    released: u32,
}

impl<S: FrameSource> Paced<S> {
    /// Paces `inner` to `fps` frames per second (a positive, finite rate).
    pub fn new(inner: S, fps: f64) -> Result<Self> {
        if !(fps.is_finite() && (MIN_FPS..=MAX_FPS).contains(&fps)) {
            return Err(Error::new(
                ErrorKind::Spec,
                format!("frame rate {fps:?}: expected a positive rate from {MIN_FPS} to {MAX_FPS} frames per second"),
            ));
        }
        Ok(Paced { inner, period: Duration::from_secs_f64(1.0 / fps), start: None, released: 0 })
    }
}

/// The slowest pace, frames per second: one frame in about 17 minutes.
pub const MIN_FPS: f64 = 0.001;
/// The fastest pace, frames per second.
pub const MAX_FPS: f64 = 1000.0;

impl<S: FrameSource> FrameSource for Paced<S> {
    fn next(&mut self, frames: &mut Frames) -> Result<Option<FrameInfo>> {
        // Due times count from the first frame, so a slow read does not push later ones back.
        let start = *self.start.get_or_insert_with(Instant::now);
        let due = start + self.period * self.released;
        let now = Instant::now();
        if due > now {
            std::thread::sleep(due - now);
        }
        self.released = self.released.saturating_add(1);
        self.inner.next(frames)
    }

    fn shots(&self) -> usize {
        self.inner.shots()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Endless(u64);

    impl FrameSource for Endless {
        fn next(&mut self, _frames: &mut Frames) -> Result<Option<FrameInfo>> {
            self.0 += 1;
            Ok(Some(FrameInfo { index: self.0 - 1, ..Default::default() }))
        }

        fn shots(&self) -> usize {
            1
        }
    }

    #[test]
    fn frames_are_released_no_earlier_than_their_due_time() {
        let mut paced = Paced::new(Endless(0), 100.0).unwrap();
        let mut frames = Frames::new(1);
        let start = Instant::now();
        let mut released = Vec::new();
        for _ in 0..6 {
            paced.next(&mut frames).unwrap().unwrap();
            released.push(start.elapsed());
        }
        // Lower bounds only: a loaded machine may be late, never early.
        for (i, t) in released.iter().enumerate() {
            assert!(*t >= Duration::from_millis(10) * i as u32, "frame {i} at {t:?}");
        }
    }

    #[test]
    fn a_rate_that_is_not_positive_is_refused() {
        for fps in [0.0, -5.0, f64::NAN, f64::INFINITY] {
            assert_eq!(Paced::new(Endless(0), fps).err().map(|e| e.kind()), Some(ErrorKind::Spec), "{fps}");
        }
    }
}
