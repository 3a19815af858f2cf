//! The projector window under a virtual X server: each pattern shown must be on screen
//! pixel for pixel when the capture in step reads the camera (here a camera that
//! screenshots the screen). Runs only with the `display` feature, and
//! skips (saying why) when neither Xvfb nor a DISPLAY is there, or xwd is missing.
#![cfg(feature = "display")]

mod common;

use camplace_hwio::Projector;
use common::{assert_shots_are_patterns, display, patterns, ScreenCamera};

#[test]
fn patterns_reach_the_screen_pixel_for_pixel() {
    let Some((_server, display)) = display() else { return };
    let patterns = patterns();
    let mut camera = ScreenCamera { display, reads: 0 };
    let mut projector = Projector::open(None).unwrap();
    // One frame thrown away after each pattern settled: two reads a pattern.
    let frame = projector.capture(&mut camera, &patterns, 150, 1).unwrap();
    assert_eq!(camera.reads, 6);
    assert_shots_are_patterns(&frame, &patterns);
}
