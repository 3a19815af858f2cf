//! The projector window on its own thread, read in step by a source on another thread (as
//! `serve --project` runs it): each frame's shots are the patterns pixel for pixel, frame
//! after frame. A test binary of its own, since a process opens one window loop. Runs only
//! with the `display` feature and skips (saying why) without Xvfb or a DISPLAY, or xwd.
#![cfg(feature = "display")]

mod common;

use std::sync::Arc;

use camplace_hwio::{FrameSource, Frames, InStepSource, ProjectorThread};
use common::{assert_shots_are_patterns, display, patterns, ScreenCamera, H, W};

#[test]
fn a_source_on_another_thread_captures_in_step_with_the_projector_thread() {
    let Some((_server, display)) = display() else { return };
    let patterns = patterns();
    let screen = Arc::new(ProjectorThread::open(None, patterns.clone(), 150).unwrap());
    assert_eq!(screen.size(), (W as u32, H as u32));
    let camera = ScreenCamera { display, reads: 0 };
    let mut source = InStepSource::new(Box::new(camera), screen, 1);
    assert_eq!(source.shots(), 3);
    let frames = std::thread::spawn(move || {
        let mut frames = Frames::new(0);
        let mut seen = Vec::new();
        for _ in 0..2 {
            let info = source.next(&mut frames).unwrap().unwrap();
            seen.push((info.name, frames.clone()));
        }
        seen
    })
    .join()
    .unwrap();
    assert_eq!(frames.iter().map(|(n, _)| n.as_str()).collect::<Vec<_>>(), ["0000", "0001"]);
    for (_, frame) in &frames {
        assert_shots_are_patterns(frame, &patterns);
    }
}
