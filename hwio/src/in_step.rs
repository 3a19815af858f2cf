//! Capture in step with a projector: a frame of one shot per pattern, each shot read from
//! a one-image camera after its pattern has been put on screen and left to settle. The
//! screen is anything that can show pattern `i` (the projector window, or a stand-in in
//! tests); `project --source` and `serve --project` both capture through
//! [`capture_in_step`].

use std::sync::Arc;

use crate::frames::{FrameInfo, FrameSource, Frames};
use crate::{Error, ErrorKind, Result};

/// A screen that shows one of a fixed list of patterns at a time.
pub trait PatternScreen: Send + Sync {
    /// Patterns in the list.
    fn patterns(&self) -> usize;

    /// Puts pattern `index` on screen and returns once it has settled (at once when it is
    /// already on show).
    fn show(&self, index: usize) -> Result<()>;
}

/// Shows each of `count` patterns through `show`, throws away `skip` camera frames queued
/// before it changed, and keeps the next: the camera's left and right image of that read
/// become shot `i` of `frame` (any further shots a camera frame has are ignored). `shot` is
/// the camera's own buffer, kept between calls. Says which camera frame the last shot was.
pub fn capture_in_step(
    show: &mut dyn FnMut(usize) -> Result<()>,
    camera: &mut dyn FrameSource,
    count: usize,
    skip: usize,
    shot: &mut Frames,
    frame: &mut Frames,
) -> Result<Option<FrameInfo>> {
    frame.set_shots(count);
    shot.set_shots(camera.shots().max(1));
    let mut last = None;
    for i in 0..count {
        show(i)?;
        for _ in 0..=skip {
            match camera.next(shot)? {
                Some(info) => last = Some(info),
                None if i == 0 => return Ok(None),
                None => {
                    return Err(Error::new(
                        ErrorKind::Device,
                        format!("the camera's stream ended before pattern {i} of {count} was captured"),
                    ))
                }
            }
        }
        std::mem::swap(&mut frame.left[i], &mut shot.left[0]);
        std::mem::swap(&mut frame.right[i], &mut shot.right[0]);
    }
    Ok(last)
}

/// A frame source whose every frame is captured in step with a projector: one shot per
/// pattern on `screen`, read from `camera`. A camera stream that ends before the first
/// pattern ends this source too.
pub struct InStepSource {
    camera: Box<dyn FrameSource + Send>,
    screen: Arc<dyn PatternScreen>,
    skip: usize,
    shot: Frames,
    index: u64,
}

impl InStepSource {
    /// `camera` read in step with `screen`, `skip` frames thrown away after each pattern.
    pub fn new(camera: Box<dyn FrameSource + Send>, screen: Arc<dyn PatternScreen>, skip: usize) -> Self {
        InStepSource { camera, screen, skip, shot: Frames::new(1), index: 0 }
    }
}

impl FrameSource for InStepSource {
    fn next(&mut self, frames: &mut Frames) -> Result<Option<FrameInfo>> {
        let screen = &self.screen;
        let mut show = |i: usize| screen.show(i);
        let count = self.screen.patterns();
        let Some(last) = capture_in_step(&mut show, self.camera.as_mut(), count, self.skip, &mut self.shot, frames)?
        else {
            return Ok(None);
        };
        // Frames are numbered by this source, as a recording of them would be.
        let info = FrameInfo {
            index: self.index,
            name: camplace_config::frame_name(self.index),
            timestamp_us: last.timestamp_us,
        };
        self.index += 1;
        Ok(Some(info))
    }

    fn shots(&self) -> usize {
        self.screen.patterns()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use camplace_config::GrayImage;
    use std::sync::atomic::{AtomicUsize, Ordering};
    use std::sync::Mutex;

    /// A screen that remembers what it shows, and every call.
    struct Screen {
        count: usize,
        on_show: Arc<AtomicUsize>,
        calls: Mutex<Vec<usize>>,
    }

    impl PatternScreen for Screen {
        fn patterns(&self) -> usize {
            self.count
        }
        fn show(&self, index: usize) -> Result<()> {
            self.on_show.store(index, Ordering::SeqCst);
            self.calls.lock().unwrap().push(index);
            Ok(())
        }
    }

    /// A camera whose frames are filled with 10 × the pattern on show plus 1 for the right
    /// side, and which lags: a frame read right after a change shows the pattern before it.
    struct LaggingCamera {
        on_show: Arc<AtomicUsize>,
        seen: Option<usize>,
        reads: u64,
        limit: u64,
    }

    impl FrameSource for LaggingCamera {
        fn next(&mut self, frames: &mut Frames) -> Result<Option<FrameInfo>> {
            if self.reads == self.limit {
                return Ok(None);
            }
            let now = self.on_show.load(Ordering::SeqCst);
            let shown = self.seen.unwrap_or(now);
            self.seen = Some(now);
            frames.left[0] = GrayImage::new(4, 3, 10 * shown as u8);
            frames.right[0] = GrayImage::new(4, 3, 10 * shown as u8 + 1);
            self.reads += 1;
            Ok(Some(FrameInfo { index: self.reads - 1, name: String::new(), timestamp_us: 1000 * self.reads }))
        }
        fn shots(&self) -> usize {
            1
        }
    }

    fn rig(count: usize, limit: u64, skip: usize) -> (InStepSource, Arc<Screen>) {
        let on_show = Arc::new(AtomicUsize::new(0));
        let screen = Arc::new(Screen { count, on_show: on_show.clone(), calls: Mutex::new(Vec::new()) });
        let camera = LaggingCamera { on_show, seen: None, reads: 0, limit };
        (InStepSource::new(Box::new(camera), screen.clone(), skip), screen)
    }

    #[test]
    fn each_shot_is_its_patterns_after_the_lagging_frame_is_thrown_away() {
        let (mut source, screen) = rig(12, 1000, 1);
        assert_eq!(source.shots(), 12);
        let mut frames = Frames::new(0);
        for k in 0..3u64 {
            let info = source.next(&mut frames).unwrap().unwrap();
            assert_eq!((info.index, info.name.as_str()), (k, camplace_config::frame_name(k).as_str()));
            // Two camera reads a pattern; the time is the last read's.
            assert_eq!(info.timestamp_us, 1000 * 24 * (k + 1));
            for i in 0..12 {
                assert_eq!(frames.left[i].data, vec![10 * i as u8; 12], "frame {k} shot {i}");
                assert_eq!(frames.right[i].data, vec![10 * i as u8 + 1; 12]);
            }
        }
        assert_eq!(*screen.calls.lock().unwrap(), (0..3).flat_map(|_| 0..12).collect::<Vec<_>>());
    }

    #[test]
    fn without_skipping_a_lagging_camera_gives_the_pattern_before() {
        // The check above is not vacuous: with no frame thrown away, shot i holds pattern i − 1.
        let (mut source, _) = rig(3, 1000, 0);
        let mut frames = Frames::new(0);
        source.next(&mut frames).unwrap().unwrap();
        let firsts: Vec<u8> = frames.left.iter().map(|s| s.data[0]).collect();
        assert_eq!(firsts, [0, 0, 10]);
    }

    #[test]
    fn a_stream_that_ends_between_frames_ends_the_source_and_within_one_is_an_error() {
        let (mut source, _) = rig(3, 6, 1);
        let mut frames = Frames::new(0);
        assert!(source.next(&mut frames).unwrap().is_some());
        assert!(source.next(&mut frames).unwrap().is_none());
        let (mut source, _) = rig(3, 4, 1);
        let e = source.next(&mut frames).unwrap_err();
        assert_eq!(e.kind(), ErrorKind::Device);
        assert!(e.to_string().contains("before pattern 2 of 3"), "{e}");
    }
}
