//! `camplace run`: the deployed loop (see `camplace_hwio::Deployment`) over a recorded
//! dataset or cameras, one JSON line per frame on stdout or into a file; at the end (the
//! source ran out, or Ctrl-C) the capture-to-pose latency percentiles and the drop count on
//! stderr, with each stage's p50 and p99 and the CPU time per frame; `--latency-plot` draws
//! them. Give `--fps` at the camera's rate to measure on a recording what a camera would
//! see.

use anyhow::{bail, Context};
use camplace_config::truth_path;
use camplace_estimator::{depth::method_for, scoring::FrameRecord, scoring::Summary};
use camplace_estimator::{Model, Rig};
use camplace_hwio::{
    estimator_for, frame_budget_ms, frame_record, latency_plot_target, parse_source, write_latency_plot, DeploySource,
    Deployment,
};
use serde::Serialize;
use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::Ordering;
use std::time::Duration;

use super::deploy_args::DeployArgs;

/// Flags of `camplace run`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    deploy: DeployArgs,
    /// Write the JSON lines here instead of stdout.
    #[arg(long, value_name = "FILE")]
    out: Option<PathBuf>,
    /// Pace a dir: source like a camera at this many frames per second (frames may then be
    /// dropped); default: every frame, as fast as the estimator goes.
    #[arg(long, value_name = "F")]
    fps: Option<f64>,
    /// Also draw the latency (per frame stacked by stage, and a histogram) into FILE.svg and
    /// FILE.png.
    #[arg(long, value_name = "FILE")]
    latency_plot: Option<PathBuf>,
    /// For testing only: make the estimator this much slower per frame, ms.
    #[arg(long, value_name = "MS", default_value_t = 0, hide = true)]
    debug_delay_ms: u64,
}

/// One output line: the frame's record with its place in the stream and its latency.
#[derive(Serialize)]
struct RunLine<'a> {
    /// Position in the source's stream, from 0 (gaps are dropped frames).
    sequence: u64,
    /// The source's capture time, µs (a camera's driver clock; a recording's file time).
    timestamp_us: u64,
    /// From the frame being in memory to its pose, ms.
    latency_ms: f64,
    /// CPU time of the process while the frame was estimated (every thread), ms.
    cpu_ms: f64,
    #[serde(flatten)]
    record: &'a FrameRecord,
}

/// Runs `camplace run`.
pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    // Before anything large is read: the estimator's buffers commit only what frames touch.
    camplace_hwio::keep_large_buffers_unbacked();
    let spec = parse_source(&a.deploy.source)?;
    let plot = a.latency_plot.as_deref().map(latency_plot_target).transpose()?;
    let cell = a.deploy.cell()?;
    let opened = DeploySource::open(&spec, a.deploy.rig.as_deref(), a.deploy.background.as_deref(), a.fps)?;
    let rig = Rig::from_file(&opened.rig);
    let model = Model::load_checked(&a.deploy.model, &cell, a.deploy.cell.as_deref())?;
    let method = method_for(opened.source.shots());
    let (max_wrong, metrics) = (cell.estimator.verify_max_wrong, cell.metrics.clone());
    let estimator = estimator_for(&cell, model, &rig, &opened.rig_path, method, opened.background.as_ref())?;
    let threshold = estimator.verifier().threshold_in_force();
    if opened.background.is_none() {
        noteln!("note: no background to remove (give --background DIR with the empty cell's images)");
    }

    let deployment = Deployment::new(opened.source, opened.when_behind, estimator)
        .with_extra_delay(Duration::from_millis(a.debug_delay_ms));
    let on_signal = deployment.stop_flag();
    // A second handler cannot be set in one process; only tests would try.
    let _ = ctrlc::set_handler(move || on_signal.store(true, Ordering::SeqCst));

    let mut out: Box<dyn Write> = match &a.out {
        Some(path) => Box::new(std::io::BufWriter::new(
            std::fs::File::create(path)
                .with_context(|| format!("{}: cannot create the output file", path.display()))?,
        )),
        None => Box::new(std::io::stdout().lock()),
    };
    let dataset = opened.dataset;
    let mut records = Vec::new();
    let stats = deployment.run(
        move |estimator, pose, info| -> anyhow::Result<FrameRecord> {
            let truth = dataset.as_deref().and_then(|d| truth_path(d, &info.name));
            Ok(frame_record(&cell, estimator, pose, &info.name, truth.as_deref())?)
        },
        |e| {
            let line = RunLine {
                sequence: e.timing.sequence,
                timestamp_us: e.timestamp_us,
                latency_ms: e.timing.latency_ms,
                cpu_ms: e.timing.cpu_ms,
                record: &e.record,
            };
            let text = serde_json::to_string(&line).context("frame record")?;
            // Flushed per line so a reader of the stream sees each pose as it comes.
            if let Err(err) = writeln!(out, "{text}").and_then(|_| out.flush()) {
                let name = a.out.as_ref().map_or("stdout".to_string(), |p| p.display().to_string());
                bail!("{name}: cannot write the poses: {err}");
            }
            records.push(e.record);
            Ok(())
        },
    )?;
    noteln!("{}", stats.report());
    let summary = Summary::from_records(&records).verified_at(&records, threshold, max_wrong, &metrics);
    if summary.scored > 0 {
        noteln!("{}", summary.line());
    }
    if let Some((dir, name)) = &plot {
        if let Some(saved) = write_latency_plot(dir, name, &stats.frames, frame_budget_ms(method))? {
            noteln!("latency plot: {} and {}", saved.svg.display(), saved.png.display());
        }
    }
    Ok(ExitCode::SUCCESS)
}
