//! camplace's service on the cell PC (`camplace serve`): robots ask for the tray's pose over
//! plain TCP (`CAMPLACE/1`, one request line and one reply line, docs/robot-interface.md);
//! one worker owns the camera and the estimator; a status page shows the last frame with the
//! model's outline, the counts and the latency; a flight recorder keeps refused frames as a
//! recorded dataset; a drift watch compares the table the rig sees with its calibration.
//! The caller builds the estimator and opens the source; this crate never renders.

mod camera;
mod connections;
mod drift;
mod error;
mod outline;
mod protocol;
mod recorder;
mod state;
mod status_page;
mod worker;

use std::net::{SocketAddr, TcpListener};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use camplace_config::RobotPoseFormat;
use camplace_estimator::{Estimator, Rig};
use camplace_hwio::Frames;

pub use camera::SourceOpener;
pub use connections::ConnectionLimits;
pub use drift::{DriftLimits, DriftState, DriftWatch, DRIFT_WINDOW};
pub use error::{Error, ErrorKind, Result};
pub use protocol::{parse_request, BadRequest, Request, Status, TriggerReply, MAX_REQUEST_BYTES, PROTOCOL};
pub use recorder::RecorderSettings;

/// Where log lines go (one per trigger); the binary writes them to standard error.
pub type Log = Arc<dyn Fn(&str) + Send + Sync>;

/// Triggers that may wait while one is estimated; one more is answered `BUSY queue-full`.
pub const TRIGGER_QUEUE: usize = 4;

/// Everything `serve` needs besides the estimator and the source.
pub struct Settings {
    /// The robot interface's address.
    pub listen: SocketAddr,
    /// The status page's address, when there is one.
    pub status: Option<SocketAddr>,
    /// How poses are written in replies.
    pub pose_format: RobotPoseFormat,
    /// World to robot base (`[robot] T_robot_world`); poses are in the world frame without it.
    pub t_robot_world: Option<[[f64; 4]; 4]>,
    /// The calibrated rig: its left camera draws the outline, its file goes with recorded frames.
    pub rig: Rig,
    /// The rig's `rig.json`, copied into the flight recorder's dataset.
    pub rig_path: PathBuf,
    /// The empty cell's images (the background reference), kept with recorded frames.
    pub background: Option<Frames>,
    /// Images per side of the source's frames.
    pub shots: usize,
    /// The flight recorder, when one is wanted.
    pub recorder: Option<RecorderSettings>,
    /// When the drift watch warns.
    pub drift: DriftLimits,
    /// Clients, idle and write limits of the robot interface.
    pub limits: ConnectionLimits,
    /// A frame not read within this is a `CAMERA_ERROR` (and the source is opened again).
    pub camera_timeout: Duration,
    /// The program's version, as `VERSION` replies it.
    pub version: String,
}

/// A bound service: its sockets are listening, nothing is served until [`Service::run`].
pub struct Service {
    settings: Settings,
    robot: TcpListener,
    status: Option<TcpListener>,
}

/// What a service did by the time it stopped.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Served {
    /// Replies by status, in [`Status::ALL`]'s order.
    pub counts: [u64; 6],
}

impl Service {
    /// Binds the robot interface and the status page.
    pub fn bind(settings: Settings) -> Result<Service> {
        if settings.limits.max_clients == 0 {
            return Err(Error::new(ErrorKind::Setting, "--max-clients: expected at least 1"));
        }
        let bind = |addr: SocketAddr, flag: &str| {
            TcpListener::bind(addr)
                .map_err(|e| Error::new(ErrorKind::Network, format!("{flag} {addr}: cannot listen there: {e}")))
        };
        let robot = bind(settings.listen, "--listen")?;
        let status = settings.status.map(|a| bind(a, "--status")).transpose()?;
        Ok(Service { settings, robot, status })
    }

    /// The robot interface's address (with the port chosen when 0 was asked for).
    pub fn robot_addr(&self) -> Result<SocketAddr> {
        self.robot.local_addr().map_err(|e| Error::new(ErrorKind::Network, format!("--listen: {e}")))
    }

    /// The status page's address, when there is one.
    pub fn status_addr(&self) -> Result<Option<SocketAddr>> {
        self.status
            .as_ref()
            .map(|l| l.local_addr().map_err(|e| Error::new(ErrorKind::Network, format!("--status: {e}"))))
            .transpose()
    }

    /// Serves until `stop` is set: the trigger in hand is finished and its reply written,
    /// clients are closed, then it returns the counts.
    pub fn run(self, estimator: Estimator, opener: SourceOpener, stop: Arc<AtomicBool>, log: Log) -> Result<Served> {
        let Service { settings, robot, status } = self;
        let shared = Arc::new(state::Shared::default());
        shared.lock().drift_limits = Some(settings.drift.clone());
        let recorder = settings
            .recorder
            .clone()
            .map(|r| recorder::FlightRecorder::new(r, &settings.rig_path, settings.background.clone()))
            .transpose()?;
        let worker = worker::Worker {
            estimator,
            camera: camera::Camera::new(opener, settings.shots, settings.camera_timeout),
            format: settings.pose_format,
            t_robot_world: settings.t_robot_world,
            left: settings.rig.left.clone(),
            recorder,
            drift: drift::DriftWatch::new(settings.drift.clone()),
            shared: shared.clone(),
            log,
        };
        let (jobs, queued) = crossbeam_channel::bounded(TRIGGER_QUEUE);
        let spawn = |name: &str, f: Box<dyn FnOnce() + Send>| {
            std::thread::Builder::new()
                .name(name.into())
                .spawn(f)
                .map_err(|e| Error::new(ErrorKind::Thread, format!("cannot start the {name} thread: {e}")))
        };
        let worker_stop = stop.clone();
        let worker_thread = spawn("camplace-worker", Box::new(move || worker.run(queued, worker_stop)))?;
        let active = Arc::new(AtomicUsize::new(0));
        let cx = connections::Context {
            jobs,
            shared: shared.clone(),
            stop: stop.clone(),
            limits: settings.limits,
            active: active.clone(),
            version: settings.version.clone(),
        };
        let acceptor = spawn("camplace-accept", Box::new(move || connections::accept(robot, cx)))?;
        let page = match status {
            Some(listener) => {
                let (shared, stop) = (shared.clone(), stop.clone());
                Some(spawn("camplace-status", Box::new(move || status_page::serve_page(listener, shared, stop)))?)
            }
            None => None,
        };
        let joined = worker_thread.join().is_ok() & acceptor.join().is_ok() & page.is_none_or(|p| p.join().is_ok());
        // Client threads write their last reply and close within a poll or two.
        let since = Instant::now();
        while active.load(Ordering::SeqCst) > 0 && since.elapsed() < Duration::from_secs(5) {
            std::thread::sleep(Duration::from_millis(10));
        }
        if !joined {
            return Err(Error::new(ErrorKind::Thread, "a service thread ended unexpectedly"));
        }
        let counts = shared.lock().counts;
        Ok(Served { counts })
    }
}
