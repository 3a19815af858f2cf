//! The virtual X server, the screenshot camera and the set-up the projector tests share.
#![allow(dead_code)]

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use camplace_config::GrayImage;
use camplace_hwio::{FrameInfo, FrameSource, Frames};

pub const W: usize = 160;
pub const H: usize = 120;

/// An Xvfb server killed when dropped.
pub struct Xvfb(Child);

impl Drop for Xvfb {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

pub fn on_path(tool: &str) -> bool {
    std::env::var_os("PATH").is_some_and(|p| std::env::split_paths(&p).any(|d| d.join(tool).is_file()))
}

/// Starts Xvfb on a free display number; returns it and its name (":N").
pub fn start_xvfb() -> Option<(Xvfb, String)> {
    let n = (90..200).find(|n| {
        !Path::new(&format!("/tmp/.X11-unix/X{n}")).exists() && !Path::new(&format!("/tmp/.X{n}-lock")).exists()
    })?;
    let name = format!(":{n}");
    let child = Command::new("Xvfb")
        .args([name.as_str(), "-screen", "0", &format!("{W}x{H}x24"), "-nolisten", "tcp"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .ok()?;
    let server = Xvfb(child);
    let start = Instant::now();
    while !Path::new(&format!("/tmp/.X11-unix/X{n}")).exists() {
        if start.elapsed() > Duration::from_secs(10) {
            return None;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    Some((server, name))
}

/// The root window as grey (checking r = g = b), read from `xwd`'s output.
pub fn screenshot(display: &str) -> GrayImage {
    let out = Command::new("xwd").args(["-root", "-silent", "-display", display]).output().expect("xwd runs");
    assert!(out.status.success(), "xwd failed: {}", String::from_utf8_lossy(&out.stderr));
    let d = out.stdout;
    // The XWD header is big-endian 32-bit words whatever the machine.
    let word = |i: usize| u32::from_be_bytes(d[4 * i..4 * i + 4].try_into().unwrap()) as usize;
    let (header_size, width, height) = (word(0), word(4), word(5));
    let (byte_order, bits_per_pixel, bytes_per_line, ncolors) = (word(7), word(11), word(12), word(19));
    assert_eq!(bits_per_pixel, 32, "expected a 24-bit visual in 32-bit pixels");
    let start = header_size + 12 * ncolors;
    let mut img = GrayImage::new(width, height, 0);
    for y in 0..height {
        for x in 0..width {
            let p = &d[start + y * bytes_per_line + 4 * x..][..4];
            let px = if byte_order == 0 {
                u32::from_le_bytes(p.try_into().unwrap())
            } else {
                u32::from_be_bytes(p.try_into().unwrap())
            };
            let (r, g, b) = ((px >> 16) & 0xff, (px >> 8) & 0xff, px & 0xff);
            assert!(r == g && g == b, "pixel ({x},{y}) is not grey: {px:06x}");
            img.set(x, y, r as u8);
        }
    }
    img
}

/// A camera that sees the whole screen: each frame is one screenshot, on both sides.
pub struct ScreenCamera {
    pub display: String,
    pub reads: usize,
}

impl FrameSource for ScreenCamera {
    fn next(&mut self, frames: &mut Frames) -> camplace_hwio::Result<Option<FrameInfo>> {
        let shot = screenshot(&self.display);
        *frames = Frames::new(1);
        frames.left[0] = shot.clone();
        frames.right[0] = shot;
        self.reads += 1;
        Ok(Some(FrameInfo { index: self.reads as u64 - 1, name: String::new(), timestamp_us: 0 }))
    }

    fn shots(&self) -> usize {
        1
    }
}

/// A display to open the window on: a new Xvfb (kept alive by the returned guard, and set
/// as DISPLAY) or the session's own; `None` (after saying why) when there is neither or xwd
/// is missing. Each test binary calls it once, before any other thread runs.
pub fn display() -> Option<(Option<Xvfb>, String)> {
    if !on_path("xwd") {
        println!("skipped: xwd (x11-apps) is not installed");
        return None;
    }
    let server = if on_path("Xvfb") { start_xvfb() } else { None };
    match (server, std::env::var("DISPLAY")) {
        (Some((server, name)), _) => {
            std::env::set_var("DISPLAY", &name);
            Some((Some(server), name))
        }
        (None, Ok(d)) => Some((None, d)),
        (None, Err(_)) => {
            println!("skipped: no Xvfb could be started and no DISPLAY is set");
            None
        }
    }
}

/// Three test patterns: noise, a ramp, and one smaller than the screen (black around it).
pub fn patterns() -> Vec<GrayImage> {
    use rand::{RngExt, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let noise = GrayImage::from_vec(W, H, (0..W * H).map(|_| rng.random::<u8>()).collect()).unwrap();
    let ramp = GrayImage::from_vec(W, H, (0..W * H).map(|i| ((i % W) * 255 / (W - 1)) as u8).collect()).unwrap();
    vec![noise, ramp, GrayImage::new(W / 2, H / 3, 200)]
}

/// Checks that shot `i` of `frame` is pattern `i` pixel for pixel on both sides.
pub fn assert_shots_are_patterns(frame: &Frames, patterns: &[GrayImage]) {
    for (i, p) in patterns.iter().enumerate() {
        assert_eq!(frame.left[i].data, frame.right[i].data);
        let shot = &frame.left[i];
        assert_eq!((shot.width, shot.height), (W, H));
        for y in 0..H {
            for x in 0..W {
                let want = if x < p.width && y < p.height { p.get(x, y) } else { 0 };
                assert_eq!(shot.get(x, y), want, "pattern {i} at ({x},{y})");
            }
        }
    }
}
