//! The projector output (feature `display`): a borderless full-screen window on a chosen
//! monitor showing grey patterns pixel for pixel, each held for a settle delay so a camera
//! exposed afterwards sees it (12-shot capture in step). X11 only (XWayland serves Wayland
//! desktops).
//!
//! winit allows one event loop per process, so a `Projector` is opened once and kept.

use std::num::NonZeroU32;
use std::rc::Rc;
use std::time::{Duration, Instant};

use camplace_config::GrayImage;
use winit::application::ApplicationHandler;
use winit::dpi::{PhysicalPosition, PhysicalSize};
use winit::event::WindowEvent;
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::platform::pump_events::{EventLoopExtPumpEvents, PumpStatus};
use winit::platform::x11::EventLoopBuilderExtX11;
use winit::window::{Fullscreen, Window, WindowId};

use crate::frames::{FrameSource, Frames};
use crate::in_step::{capture_in_step, PatternScreen};
use crate::{Error, ErrorKind, Result};

/// How long to wait for the window to appear before giving up.
const OPEN_TIMEOUT: Duration = Duration::from_secs(5);

/// A full-screen window on one monitor that shows one grey pattern at a time.
pub struct Projector {
    event_loop: EventLoop<()>,
    app: App,
}

struct App {
    monitor: Option<usize>,
    window: Option<Rc<Window>>,
    surface: Option<softbuffer::Surface<Rc<Window>, Rc<Window>>>,
    /// The pattern on show, kept to redraw after an expose or a resize.
    pattern: GrayImage,
    /// When the last frame was handed to the X server.
    presented: Option<Instant>,
    error: Option<Error>,
}

impl Projector {
    /// Opens the window full screen on monitor `monitor` (an index into the X server's
    /// monitors; the primary one when `None`).
    pub fn open(monitor: Option<usize>) -> Result<Projector> {
        let event_loop = EventLoop::builder().with_any_thread(true).build().map_err(|e| {
            Error::new(ErrorKind::Display, format!("no display to show patterns on ({e}); expected an X11 DISPLAY"))
        })?;
        let mut projector = Projector {
            event_loop,
            app: App {
                monitor,
                window: None,
                surface: None,
                pattern: GrayImage::default(),
                presented: None,
                error: None,
            },
        };
        let start = Instant::now();
        while projector.app.surface.is_none() {
            projector.pump(Duration::from_millis(10))?;
            if start.elapsed() > OPEN_TIMEOUT {
                return Err(Error::new(ErrorKind::Display, "the projector window did not appear within 5 s"));
            }
        }
        Ok(projector)
    }

    /// The window's size in pixels (the monitor's, once full screen).
    pub fn size(&self) -> (u32, u32) {
        self.app.window.as_ref().map_or((0, 0), |w| {
            let s = w.inner_size();
            (s.width, s.height)
        })
    }

    /// Shows `pattern` at the window's top-left pixel for pixel (black elsewhere, clipped
    /// if larger) and returns once it has been on screen for `settle_ms`.
    pub fn show(&mut self, pattern: &GrayImage, settle_ms: u64) -> Result<()> {
        self.app.pattern.clone_from(pattern);
        self.app.presented = None;
        self.app.draw()?;
        let settle = Duration::from_millis(settle_ms);
        loop {
            // A resize or expose redraws and restarts the settle time.
            let Some(t) = self.app.presented else {
                self.pump(Duration::from_millis(5))?;
                continue;
            };
            let left = settle.saturating_sub(t.elapsed());
            if left.is_zero() {
                return Ok(());
            }
            self.pump(left.min(Duration::from_millis(20)))?;
        }
    }

    /// Shows each of `patterns` in turn, lets it settle for `settle_ms`, throws away
    /// `skip` camera frames queued before it changed, and keeps the next: one frame with a
    /// shot per pattern (a camera's frame is one image a side; any further shots it has are
    /// ignored).
    pub fn capture(
        &mut self,
        source: &mut dyn FrameSource,
        patterns: &[GrayImage],
        settle_ms: u64,
        skip: usize,
    ) -> Result<Frames> {
        let mut shot = Frames::new(source.shots());
        let mut frame = Frames::new(patterns.len());
        let mut show = |i: usize| self.show(&patterns[i], settle_ms);
        match capture_in_step(&mut show, source, patterns.len(), skip, &mut shot, &mut frame)? {
            Some(_) => Ok(frame),
            None => Err(Error::new(ErrorKind::Device, "the source ended before pattern 0 was captured")),
        }
    }

    fn pump(&mut self, timeout: Duration) -> Result<()> {
        let status = self.event_loop.pump_app_events(Some(timeout), &mut self.app);
        if let Some(e) = self.app.error.take() {
            return Err(e);
        }
        if let PumpStatus::Exit(code) = status {
            return Err(Error::new(ErrorKind::Display, format!("the projector window closed (code {code})")));
        }
        Ok(())
    }
}

impl App {
    fn create(&mut self, event_loop: &ActiveEventLoop) -> Result<()> {
        let monitors: Vec<_> = event_loop.available_monitors().collect();
        let monitor = match self.monitor {
            Some(i) => Some(monitors.get(i).cloned().ok_or_else(|| {
                Error::new(
                    ErrorKind::Display,
                    format!(
                        "monitor {i} does not exist; expected 0..{} (the X server has {})",
                        monitors.len(),
                        monitors.len()
                    ),
                )
            })?),
            None => event_loop.primary_monitor().or_else(|| monitors.first().cloned()),
        };
        let mut attrs = Window::default_attributes().with_title("camplace projector").with_decorations(false);
        if let Some(m) = &monitor {
            // Without a window manager full screen is not honoured: place and size by hand.
            let (pos, size): (PhysicalPosition<i32>, PhysicalSize<u32>) = (m.position(), m.size());
            attrs = attrs
                .with_position(pos)
                .with_inner_size(size)
                .with_fullscreen(Some(Fullscreen::Borderless(Some(m.clone()))));
        }
        let window = Rc::new(event_loop.create_window(attrs).map_err(|e| display_error("window", e))?);
        window.set_cursor_visible(false);
        let context = softbuffer::Context::new(window.clone()).map_err(|e| display_error("drawing context", e))?;
        let surface = softbuffer::Surface::new(&context, window.clone()).map_err(|e| display_error("surface", e))?;
        self.window = Some(window);
        self.surface = Some(surface);
        Ok(())
    }

    /// Draws the pattern into the window and presents it.
    fn draw(&mut self) -> Result<()> {
        let (Some(window), Some(surface)) = (&self.window, &mut self.surface) else { return Ok(()) };
        let size = window.inner_size();
        let (Some(w), Some(h)) = (NonZeroU32::new(size.width), NonZeroU32::new(size.height)) else { return Ok(()) };
        surface.resize(w, h).map_err(|e| display_error("resize", e))?;
        let mut buffer = surface.buffer_mut().map_err(|e| display_error("buffer", e))?;
        let (w, h) = (size.width as usize, size.height as usize);
        let p = &self.pattern;
        for y in 0..h {
            let row = &mut buffer[y * w..(y + 1) * w];
            if y < p.height {
                let src = &p.data[y * p.width..(y + 1) * p.width];
                let n = p.width.min(w);
                for (o, &v) in row[..n].iter_mut().zip(src) {
                    let v = v as u32;
                    *o = (v << 16) | (v << 8) | v;
                }
                row[n..].fill(0);
            } else {
                row.fill(0);
            }
        }
        buffer.present().map_err(|e| display_error("present", e))?;
        self.presented = Some(Instant::now());
        Ok(())
    }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.window.is_none() {
            if let Err(e) = self.create(event_loop) {
                self.error = Some(e);
            }
        }
    }

    fn window_event(&mut self, _event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        let result = match event {
            WindowEvent::Resized(_) | WindowEvent::RedrawRequested => self.draw(),
            WindowEvent::CloseRequested => {
                Err(Error::new(ErrorKind::Display, "the projector window was closed while showing patterns"))
            }
            _ => Ok(()),
        };
        if let Err(e) = result {
            self.error = Some(e);
        }
    }
}

fn display_error(what: &str, e: impl std::fmt::Display) -> Error {
    Error::new(ErrorKind::Display, format!("projector window: {what} failed: {e}"))
}

/// The projector window on a thread of its own, for a capture that runs on another thread
/// (the window's event loop stays on the thread that made it): `show(i)` sends pattern `i`
/// of the list given at the start and waits until it has settled. A pattern already on
/// show is not shown again, so one-shot's single pattern costs its settle time once.
pub struct ProjectorThread {
    ask: crossbeam_channel::Sender<(usize, crossbeam_channel::Sender<Result<()>>)>,
    patterns: usize,
    size: (u32, u32),
}

impl ProjectorThread {
    /// Opens the window on monitor `monitor` on a new thread showing `patterns`, each left
    /// `settle_ms` before `show` returns. Winit allows one window loop a process: open one
    /// and share it.
    pub fn open(monitor: Option<usize>, patterns: Vec<GrayImage>, settle_ms: u64) -> Result<ProjectorThread> {
        if patterns.is_empty() {
            return Err(Error::new(ErrorKind::Display, "the projector thread needs at least one pattern"));
        }
        let count = patterns.len();
        let (ask, asked) = crossbeam_channel::unbounded::<(usize, crossbeam_channel::Sender<Result<()>>)>();
        let (opened, on_open) = crossbeam_channel::bounded::<Result<(u32, u32)>>(1);
        std::thread::Builder::new()
            .name("camplace-projector".into())
            .spawn(move || {
                let mut projector = match Projector::open(monitor) {
                    Ok(p) => {
                        let _ = opened.send(Ok(p.size()));
                        p
                    }
                    Err(e) => {
                        let _ = opened.send(Err(e));
                        return;
                    }
                };
                let mut on_show = None;
                for (i, reply) in asked {
                    let result = if on_show == Some(i) {
                        Ok(())
                    } else {
                        on_show = None;
                        projector.show(&patterns[i], settle_ms).map(|()| on_show = Some(i))
                    };
                    let _ = reply.send(result);
                }
            })
            .map_err(|e| Error::new(ErrorKind::Display, format!("cannot start the projector thread: {e}")))?;
        let size = on_open
            .recv()
            .map_err(|_| Error::new(ErrorKind::Display, "the projector thread ended before its window opened"))??;
        Ok(ProjectorThread { ask, patterns: count, size })
    }

    /// The window's size in pixels.
    pub fn size(&self) -> (u32, u32) {
        self.size
    }
}

impl PatternScreen for ProjectorThread {
    fn patterns(&self) -> usize {
        self.patterns
    }

    fn show(&self, index: usize) -> Result<()> {
        if index >= self.patterns {
            return Err(Error::new(
                ErrorKind::Display,
                format!("pattern {index}: the projector holds {} patterns", self.patterns),
            ));
        }
        let ended = || Error::new(ErrorKind::Display, "the projector thread has ended");
        let (reply, answer) = crossbeam_channel::bounded(1);
        self.ask.send((index, reply)).map_err(|_| ended())?;
        answer.recv().map_err(|_| ended())?
    }
}
