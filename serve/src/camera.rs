//! The camera link of the trigger worker: a thread that owns the frame source and reads one
//! frame per request, so a camera that stops answering costs one `CAMERA_ERROR` after a
//! timeout instead of a hang. A source that fails is dropped and opened again at the next
//! trigger (reconnection); a source that ends (a recorded dataset read to its last frame)
//! is opened again from its first frame, so a recording serves triggers for ever.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use camplace_hwio::{FrameInfo, FrameSource, Frames};
use crossbeam_channel::{bounded, Receiver, RecvTimeoutError, Sender};

/// Opens the frame source, once at the start and again after each failure.
pub type SourceOpener = Box<dyn FnMut() -> camplace_hwio::Result<Box<dyn FrameSource + Send>> + Send>;

type Grabbed = (Frames, Result<FrameInfo, String>);

struct Link {
    ask: Sender<Frames>,
    got: Receiver<Grabbed>,
}

/// The worker's side of the camera thread.
pub(crate) struct Camera {
    opener: Arc<Mutex<SourceOpener>>,
    link: Option<Link>,
    timeout: Duration,
    shots: usize,
    spare: Frames,
}

impl Camera {
    /// A camera reading through `opener`, giving up on a frame after `timeout`.
    pub(crate) fn new(opener: SourceOpener, shots: usize, timeout: Duration) -> Camera {
        Camera { opener: Arc::new(Mutex::new(opener)), link: None, timeout, shots, spare: Frames::new(shots) }
    }

    /// Reads the next frame into `frames`; the error is one line for the log and the page.
    pub(crate) fn grab(&mut self, frames: &mut Frames) -> Result<FrameInfo, String> {
        if self.link.is_none() {
            self.link = Some(spawn(self.opener.clone()).map_err(|e| format!("cannot start the camera thread: {e}"))?);
        }
        let link = self.link.as_ref().expect("set above");
        // The buffer travels to the camera thread and back; a spare stands in meanwhile.
        std::mem::swap(frames, &mut self.spare);
        if link.ask.send(std::mem::take(&mut self.spare)).is_err() {
            self.link = None;
            *frames = Frames::new(self.shots);
            return Err("the camera thread ended".to_string());
        }
        match link.got.recv_timeout(self.timeout) {
            Ok((back, result)) => {
                *frames = back;
                self.spare = Frames::new(0);
                result
            }
            Err(RecvTimeoutError::Timeout) => {
                // The thread may stay blocked in the driver; it is left to end when the
                // driver returns, and a new one opens the source again.
                self.link = None;
                *frames = Frames::new(self.shots);
                Err(format!("no frame within {} ms", self.timeout.as_millis()))
            }
            Err(RecvTimeoutError::Disconnected) => {
                self.link = None;
                *frames = Frames::new(self.shots);
                Err("the camera thread ended".to_string())
            }
        }
    }
}

fn spawn(opener: Arc<Mutex<SourceOpener>>) -> std::io::Result<Link> {
    let (ask, asked) = bounded::<Frames>(1);
    let (give, got) = bounded::<Grabbed>(1);
    std::thread::Builder::new().name("camplace-camera".into()).spawn(move || {
        let mut source: Option<Box<dyn FrameSource + Send>> = None;
        for mut frames in asked {
            let result = read_one(&opener, &mut source, &mut frames);
            if result.is_err() {
                source = None;
            }
            if give.send((frames, result)).is_err() {
                break;
            }
        }
    })?;
    Ok(Link { ask, got })
}

/// One frame from `source`, opening it first when there is none; at the end of a
/// recording, opens it again and reads its first frame.
fn read_one(
    opener: &Mutex<SourceOpener>,
    source: &mut Option<Box<dyn FrameSource + Send>>,
    frames: &mut Frames,
) -> Result<FrameInfo, String> {
    let open = || -> Result<Box<dyn FrameSource + Send>, String> {
        let mut opener = opener.lock().map_err(|_| "the source opener failed earlier".to_string())?;
        (*opener)().map_err(|e| format!("cannot open the source: {e}"))
    };
    for _ in 0..2 {
        let s = match source {
            Some(s) => s,
            None => source.insert(open()?),
        };
        frames.set_shots(s.shots());
        match s.next(frames) {
            Ok(Some(info)) => return Ok(info),
            Ok(None) => *source = None,
            Err(e) => return Err(e.to_string()),
        }
    }
    Err("the source gives no frames".to_string())
}
