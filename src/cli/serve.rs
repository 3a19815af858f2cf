//! `camplace serve`: flags parsed, the cell, model, rig and source opened, the estimator
//! built, and `camplace_serve::Service` run until SIGTERM or Ctrl-C. Prints the addresses it
//! listens on to standard output and one log line per trigger to standard error.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use anyhow::{bail, Context};
use camplace_config::{Cell, LengthUnit, PoseConvention, RobotPoseFormat, ToleranceReport};
use camplace_estimator::{depth::method_for, depth::Method};
use camplace_estimator::{Model, Rig};
use camplace_hwio::{
    estimator_for, open_source, parse_source, read_background, DeploySource, FrameSource, InStepSource, PatternScreen,
    RecordedSource, SourceSpec,
};
use camplace_serve::{ConnectionLimits, DriftLimits, RecorderSettings, Service, Settings, Status};

use super::deploy_args::DeployArgs;

/// Flags of `camplace serve`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    deploy: DeployArgs,
    /// The robot interface's address, e.g. 0.0.0.0:50010 (port 0: any free port, printed).
    #[arg(long, value_name = "ADDR:PORT")]
    listen: String,
    /// The status page's address, e.g. 0.0.0.0:8080.
    #[arg(long, value_name = "ADDR:PORT")]
    status: Option<String>,
    /// Keep the frames of every NO_POSE and REJECTED trigger in this dataset folder.
    #[arg(long, value_name = "DIR")]
    record: Option<PathBuf>,
    /// Most the flight recorder's folder may hold, MB (oldest frames dropped first).
    #[arg(long, value_name = "MB", default_value_t = 500.0, requires = "record")]
    record_quota_mb: f64,
    /// The study's tolerance.json: the drift watch warns when the rig's implied turn passes
    /// alpha's tolerance or its move r's.
    #[arg(long, value_name = "FILE", conflicts_with_all = ["drift_deg", "drift_mm"])]
    tolerance: Option<PathBuf>,
    /// Without --tolerance: the largest turn of the rig before the drift watch warns, deg.
    #[arg(long, value_name = "DEG")]
    drift_deg: Option<f64>,
    /// Without --tolerance: the largest move of the rig along the table's normal, mm.
    #[arg(long, value_name = "MM")]
    drift_mm: Option<f64>,
    /// Clients served at once; more get one BUSY line.
    #[arg(long, value_name = "N", default_value_t = 8)]
    max_clients: usize,
    /// A frame not captured within this is a CAMERA_ERROR and the camera is opened again, ms.
    #[arg(long, value_name = "MS", default_value_t = 2000)]
    camera_timeout_ms: u64,
    /// Show the structured-light patterns on the projector (feature `display`) and take each
    /// camera frame in step with them, as `project --source` does: phase-12's 12 fringes per
    /// trigger, or one-shot's random dots (shown once and left on).
    #[arg(long, value_name = "METHOD")]
    project: Option<Method>,
    /// With --project: the projector's monitor, an index in the X server's list (default: the
    /// primary).
    #[arg(long, value_name = "N", requires = "project")]
    monitor: Option<usize>,
    /// With --project: time a pattern stays on screen before the cameras are read, ms.
    #[arg(long, value_name = "MS", default_value_t = 150, requires = "project")]
    settle_ms: u64,
    /// With --project: camera frames thrown away after each pattern settled.
    #[arg(long, value_name = "N", default_value_t = 1, requires = "project")]
    skip: usize,
    /// With --project one-shot: the random dots' seed (default: the cell's scenarios.seed, as
    /// `camplace model` uses).
    #[arg(long, requires = "project")]
    seed: Option<u64>,
}

fn address(text: &str, flag: &str) -> anyhow::Result<SocketAddr> {
    text.parse().map_err(|_| anyhow::anyhow!("{flag} {text:?}: expected ADDR:PORT, e.g. 127.0.0.1:50010"))
}

fn positive(v: f64, flag: &str) -> anyhow::Result<f64> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        bail!("{flag} {v}: expected a number above 0")
    }
}

/// The drift limits: alpha's and r's tolerances (the smaller side of each), or the flags.
fn drift_limits(a: &Args) -> anyhow::Result<DriftLimits> {
    Ok(match &a.tolerance {
        Some(path) => DriftLimits::from_tolerance(&ToleranceReport::load(path)?, path)?,
        None => DriftLimits::given(a.drift_deg, a.drift_mm)?,
    })
}

/// Opens `spec` again each time the service asks (at the start, after a failure, at the end
/// of a recording), read in step with `screen` when the projector is driven.
fn opener(spec: SourceSpec, screen: Option<(Arc<dyn PatternScreen>, usize)>) -> camplace_serve::SourceOpener {
    Box::new(move || -> camplace_hwio::Result<Box<dyn FrameSource + Send>> {
        let camera: Box<dyn FrameSource + Send> = match &spec {
            SourceSpec::Recorded(dir) => Box::new(RecordedSource::open(dir)?),
            other => open_source(other)?,
        };
        Ok(match &screen {
            Some((screen, skip)) => Box::new(InStepSource::new(camera, screen.clone(), *skip)),
            None => camera,
        })
    })
}

/// The projector showing `method`'s patterns on its own thread (`--project`).
#[cfg(feature = "display")]
fn projector(a: &Args, cell: &Cell, method: Method) -> anyhow::Result<Arc<dyn PatternScreen>> {
    let patterns = super::project::patterns(cell, method, a.seed);
    let screen = camplace_hwio::ProjectorThread::open(a.monitor, patterns, a.settle_ms)?;
    super::project::note_monitor_size(screen.size(), cell);
    Ok(Arc::new(screen))
}

/// The projector showing `method`'s patterns (`--project`): not in this build.
#[cfg(not(feature = "display"))]
fn projector(_a: &Args, _cell: &Cell, _method: Method) -> anyhow::Result<Arc<dyn PatternScreen>> {
    Err(no_display())
}

/// `--project` in a build without the projector window.
#[cfg(not(feature = "display"))]
fn no_display() -> anyhow::Error {
    anyhow::anyhow!(
        "--project: the projector window needs the `display` feature, which this build lacks; \
         rebuild with `cargo build --release --features display`"
    )
}

/// Runs `camplace serve`.
pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    // Before anything large is read: the estimator's buffers commit only what frames touch.
    camplace_hwio::keep_large_buffers_unbacked();
    let listen = address(&a.listen, "--listen")?;
    let status = a.status.as_deref().map(|s| address(s, "--status")).transpose()?;
    let drift = drift_limits(&a)?;
    let quota_bytes = (positive(a.record_quota_mb, "--record-quota-mb")? * 1e6) as u64;
    if a.camera_timeout_ms == 0 {
        bail!("--camera-timeout-ms 0: expected at least 1");
    }
    // Said before any source is opened.
    #[cfg(not(feature = "display"))]
    if a.project.is_some() {
        return Err(no_display());
    }
    let spec = parse_source(&a.deploy.source)?;
    let cell = a.deploy.cell()?;
    let pose_format = match &cell.robot {
        Some(r) => r.reply_format().map_err(|e| match &a.deploy.cell {
            Some(path) => e.in_file(path),
            None => e,
        })?,
        None => RobotPoseFormat { convention: PoseConvention::Matrix, unit: LengthUnit::Mm },
    };
    // The source opened once here: its calibration, background and shots, and a missing
    // camera reported before anything listens.
    // With the projector driven, the background holds a shot per pattern and is read below.
    let given_background = if a.project.is_some() { None } else { a.deploy.background.as_deref() };
    let mut opened = DeploySource::open(&spec, a.deploy.rig.as_deref(), given_background, None)?;
    let rig = Rig::from_file(&opened.rig);
    let model = Model::load_checked(&a.deploy.model, &cell, a.deploy.cell.as_deref())?;
    let screen = match a.project {
        Some(method) => {
            if opened.source.shots() != 1 {
                bail!(
                    "--project with --source {}: expected a camera giving one image a side, which the \
                     projector's patterns are captured from; this source gives {} a frame",
                    a.deploy.source,
                    opened.source.shots()
                );
            }
            Some((projector(&a, &cell, method)?, a.skip))
        }
        None => None,
    };
    let shots = screen.as_ref().map_or(opened.source.shots(), |(s, _)| s.patterns());
    if screen.is_some() {
        opened.background =
            match &a.deploy.background {
                Some(dir) => Some(read_background(dir, &opened.rig, shots).map_err(|e| {
                    anyhow::anyhow!("--background: expected {shots} images per side, one a pattern: {e}")
                })?),
                None => None,
            };
    }
    let method = method_for(shots);
    let estimator = estimator_for(&cell, model, &rig, &opened.rig_path, method, opened.background.as_ref())?;
    if opened.background.is_none() {
        noteln!("note: no background to remove (give --background DIR with the empty cell's images)");
    }
    drop(opened.source);
    let settings = Settings {
        listen,
        status,
        pose_format,
        t_robot_world: cell.robot.as_ref().map(|r| r.t_robot_world),
        rig,
        rig_path: opened.rig_path.clone(),
        background: opened.background,
        shots,
        recorder: a.record.clone().map(|dir| RecorderSettings { dir, quota_bytes }),
        drift,
        limits: ConnectionLimits { max_clients: a.max_clients, ..ConnectionLimits::default() },
        camera_timeout: Duration::from_millis(a.camera_timeout_ms),
        version: env!("CARGO_PKG_VERSION").to_string(),
    };
    let service = Service::bind(settings)?;
    let stop = Arc::new(AtomicBool::new(false));
    let on_signal = stop.clone();
    ctrlc::set_handler(move || on_signal.store(true, Ordering::SeqCst)).context("SIGTERM/Ctrl-C handler")?;
    outln!(
        "robot interface {} on {} ({method}, poses as {pose_format})",
        camplace_serve::PROTOCOL,
        service.robot_addr()?
    );
    if let Some(addr) = service.status_addr()? {
        outln!("status page on http://{addr}/");
    }
    let log: camplace_serve::Log = Arc::new(|line: &str| noteln!("{line}"));
    let served = service.run(estimator, opener(spec, screen), stop, log)?;
    let counts: Vec<String> =
        Status::ALL.iter().map(|s| format!("{} {}", s.as_str(), served.counts[s.index()])).collect();
    noteln!("stopped: {}", counts.join(", "));
    Ok(ExitCode::SUCCESS)
}
