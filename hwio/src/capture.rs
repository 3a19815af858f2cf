//! The live capture thread: reads a `FrameSource` into a fixed pool of frame buffers and
//! hands them over a bounded channel. When the consumer (the estimator) falls behind, the
//! oldest waiting frame is dropped and counted, so the newest frame is never late
//! ([`WhenBehind::DropOldest`], what a camera needs); a recording replayed frame by frame
//! may instead wait for the consumer ([`WhenBehind::Wait`]).
//! Buffers come back through `recycle`; none is allocated after the pool is filled.
//! A buffer is taken before the source says the stream has ended, so a consumer that is
//! behind at the end also loses the oldest waiting frame then.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Instant;

use crossbeam_channel::{bounded, Receiver, Sender, TryRecvError};

use crate::frames::{FrameInfo, FrameSource, Frames};
use crate::{Error, ErrorKind, Result};

/// One frame as the capture thread handed it over.
#[derive(Debug)]
pub struct Captured {
    /// What the source said about it.
    pub info: FrameInfo,
    /// Its images (give them back with [`Capture::recycle`]).
    pub frames: Frames,
    /// When the source had filled it: the start of the frame's capture-to-pose latency.
    pub at: Instant,
}

/// What the capture thread does when every buffer waits for the consumer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum WhenBehind {
    /// Reuse the oldest waiting frame's buffer and count the frame as dropped.
    #[default]
    DropOldest,
    /// Wait until the consumer gives a buffer back: no frame is lost.
    Wait,
}

type Filled = Result<Captured>;

/// A source read on its own thread into recycled buffers.
pub struct Capture {
    full: Receiver<Filled>,
    free: Sender<Frames>,
    dropped: Arc<AtomicU64>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl Capture {
    /// Starts reading `source` on a new thread with `buffers` frame buffers (at least 2:
    /// one being filled, one with the consumer), dropping the oldest frame when behind.
    pub fn spawn(source: Box<dyn FrameSource + Send>, buffers: usize) -> Result<Capture> {
        Self::spawn_with(source, buffers, WhenBehind::DropOldest)
    }

    /// As [`Capture::spawn`], doing `when_behind` when every buffer waits for the consumer.
    pub fn spawn_with(
        mut source: Box<dyn FrameSource + Send>,
        buffers: usize,
        when_behind: WhenBehind,
    ) -> Result<Capture> {
        let buffers = buffers.max(2);
        let (full_tx, full_rx) = bounded::<Filled>(buffers);
        let (free_tx, free_rx) = bounded::<Frames>(buffers);
        for _ in 0..buffers {
            // Cannot fail: the channel holds exactly `buffers`.
            let _ = free_tx.send(Frames::new(source.shots()));
        }
        let dropped = Arc::new(AtomicU64::new(0));
        let stop = Arc::new(AtomicBool::new(false));
        let (oldest, count, stopping) = (full_rx.clone(), dropped.clone(), stop.clone());
        let thread = std::thread::Builder::new()
            .name("camplace-capture".into())
            .spawn(move || {
                while !stopping.load(Ordering::Relaxed) {
                    // A free buffer, else the oldest unread frame's (counted as dropped),
                    // else wait for the consumer to give one back.
                    let mut frames = match free_rx.try_recv() {
                        Ok(f) => f,
                        Err(TryRecvError::Disconnected) => return,
                        Err(TryRecvError::Empty) if when_behind == WhenBehind::Wait => match free_rx.recv() {
                            Ok(f) => f,
                            Err(_) => return,
                        },
                        Err(TryRecvError::Empty) => match oldest.try_recv() {
                            Ok(Ok(c)) => {
                                count.fetch_add(1, Ordering::Relaxed);
                                c.frames
                            }
                            Ok(Err(_)) => return,
                            Err(_) => match free_rx.recv() {
                                Ok(f) => f,
                                Err(_) => return,
                            },
                        },
                    };
                    match source.next(&mut frames) {
                        Ok(Some(info)) => {
                            if full_tx.send(Ok(Captured { info, frames, at: Instant::now() })).is_err() {
                                return;
                            }
                        }
                        Ok(None) => return,
                        Err(e) => {
                            let _ = full_tx.send(Err(e));
                            return;
                        }
                    }
                }
            })
            .map_err(|e| Error::new(ErrorKind::Device, format!("cannot start the capture thread: {e}")))?;
        Ok(Capture { full: full_rx, free: free_tx, dropped, stop, thread: Some(thread) })
    }

    /// The next frame, waiting for it; `Ok(None)` once the source has ended.
    pub fn recv(&self) -> Result<Option<Captured>> {
        match self.full.recv() {
            Ok(r) => r.map(Some),
            Err(_) => Ok(None),
        }
    }

    /// Gives a frame's buffers back for the next capture.
    pub fn recycle(&self, frames: Frames) {
        // Full only if the caller made extra buffers; those are simply let go.
        let _ = self.free.try_send(frames);
    }

    /// Frames dropped so far because the consumer was behind.
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }
}

impl Drop for Capture {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        // Closing the free channel wakes a thread waiting for a buffer.
        let (tx, _) = bounded(0);
        drop(std::mem::replace(&mut self.free, tx));
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use camplace_config::GrayImage;

    /// Frames whose every pixel is the frame index (mod 256), `total` of them, each
    /// taking `delay_ms` to capture.
    struct Counter {
        next: u64,
        total: u64,
        delay_ms: u64,
        ended: Arc<AtomicBool>,
    }

    impl FrameSource for Counter {
        fn next(&mut self, frames: &mut Frames) -> Result<Option<FrameInfo>> {
            if self.next == self.total {
                self.ended.store(true, Ordering::SeqCst);
                return Ok(None);
            }
            std::thread::sleep(std::time::Duration::from_millis(self.delay_ms));
            let v = self.next as u8;
            for img in frames.left.iter_mut().chain(frames.right.iter_mut()) {
                img.reset(8, 4, v);
            }
            let index = self.next;
            self.next += 1;
            Ok(Some(FrameInfo { index, name: crate::frames::frame_name(index), timestamp_us: index }))
        }

        fn shots(&self) -> usize {
            2
        }
    }

    fn run(total: u64, capture_ms: u64, process_ms: u64) -> (Vec<u64>, u64) {
        run_with(total, capture_ms, process_ms, WhenBehind::DropOldest)
    }

    fn run_with(total: u64, capture_ms: u64, process_ms: u64, when_behind: WhenBehind) -> (Vec<u64>, u64) {
        let source = Counter { next: 0, total, delay_ms: capture_ms, ended: Arc::default() };
        let capture = Capture::spawn_with(Box::new(source), 3, when_behind).unwrap();
        let mut seen = Vec::new();
        while let Some(Captured { info, frames, .. }) = capture.recv().unwrap() {
            assert_eq!(frames.shots(), 2);
            let want = GrayImage::new(8, 4, info.index as u8);
            assert!(frames.left.iter().chain(&frames.right).all(|i| *i == want), "frame {} mixed up", info.index);
            seen.push(info.index);
            std::thread::sleep(std::time::Duration::from_millis(process_ms));
            capture.recycle(frames);
        }
        (seen, capture.dropped())
    }

    #[test]
    fn a_fast_consumer_sees_every_frame_in_order() {
        // 25 ms a frame and 3 buffers: a frame is dropped only when the consumer, which
        // does nothing else, is kept off the CPU for 75 ms.
        let (seen, dropped) = run(20, 25, 0);
        assert_eq!(seen, (0..20).collect::<Vec<_>>());
        assert_eq!(dropped, 0);
    }

    #[test]
    fn a_slow_consumer_loses_old_frames_and_gets_the_newest() {
        let (seen, dropped) = run(40, 1, 8);
        assert!(seen.windows(2).all(|w| w[0] < w[1]), "{seen:?}");
        assert_eq!(seen.len() as u64 + dropped, 40, "{seen:?} + {dropped}");
        assert_eq!(seen.last(), Some(&39));
    }

    #[test]
    fn waiting_for_a_slow_consumer_loses_nothing() {
        let (seen, dropped) = run_with(20, 0, 3, WhenBehind::Wait);
        assert_eq!(seen, (0..20).collect::<Vec<_>>());
        assert_eq!(dropped, 0);
    }

    #[test]
    fn a_consumer_that_reads_after_the_end_gets_the_newest_frames() {
        let ended = Arc::new(AtomicBool::new(false));
        let source = Counter { next: 0, total: 40, delay_ms: 0, ended: ended.clone() };
        let capture = Capture::spawn(Box::new(source), 3).unwrap();
        while !ended.load(Ordering::SeqCst) {
            std::thread::yield_now();
        }
        let mut seen = Vec::new();
        while let Some(Captured { info, frames, .. }) = capture.recv().unwrap() {
            seen.push(info.index);
            capture.recycle(frames);
        }
        // Three buffers: the last three frames waited, and the end of the stream took one.
        assert_eq!(seen, [38, 39]);
        assert_eq!(capture.dropped(), 38);
    }

    #[test]
    fn dropping_the_capture_stops_the_thread() {
        let capture =
            Capture::spawn(Box::new(Counter { next: 0, total: u64::MAX, delay_ms: 1, ended: Arc::default() }), 2)
                .unwrap();
        // Frames may be dropped before the first receive (the source outruns a busy test
        // machine), but what arrives arrives in order.
        let first = capture.recv().unwrap().unwrap();
        capture.recycle(first.frames);
        let first = first.info.index;
        let second = capture.recv().unwrap().unwrap().info.index;
        assert!(second > first, "{first} then {second}");
        drop(capture); // joins; a hang here fails the test run
    }
}
