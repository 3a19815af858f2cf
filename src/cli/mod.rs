//! The subcommands and their flags; one module per subcommand. The simulation's commands
//! (and the modules only they use) are built with the `sim` feature, on by default; a deploy
//! build without it has the cell PC's commands alone.

#[macro_use]
pub mod output;

#[cfg(feature = "sim")]
mod ablate;
#[cfg(feature = "sim")]
mod accept;
mod calibrate;
mod capture;
mod cell_args;
mod deploy_args;
mod devices;
mod estimate;
#[cfg(feature = "sim")]
mod evaluate;
#[cfg(feature = "sim")]
mod export;
#[cfg(feature = "sim")]
mod fit_sensor;
mod hand_eye;
mod init;
#[cfg(feature = "sim")]
mod merge;
#[cfg(feature = "sim")]
mod model;
#[cfg(feature = "sim")]
mod optimize;
#[cfg(feature = "sim")]
mod placement;
#[cfg(feature = "sim")]
mod progress;
mod project;
mod reconstruct;
#[cfg(feature = "sim")]
mod render;
mod replay;
#[cfg(feature = "sim")]
mod review;
mod run;
mod serve;
#[cfg(feature = "sim")]
mod study;
#[cfg(feature = "sim")]
mod study_args;
#[cfg(feature = "sim")]
mod sweep;
#[cfg(feature = "sim")]
mod tolerance;
#[cfg(feature = "sim")]
mod trial;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

/// Where to mount a stereo camera and projector above a robot cell, and the tray-pose
/// estimator that runs there. Lengths in mm, angles in degrees.
#[derive(Parser, Debug)]
#[command(name = "camplace", version, about, propagate_version = true)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Write the default cell file, with a comment on every key.
    Init(init::Args),
    /// Render a simulated scene (or a dataset of scenes) with its ground truth.
    #[cfg(feature = "sim")]
    Render(render::Args),
    /// Depth and point clouds from stereo frames (a dataset, one pair, or a rectified pair).
    Reconstruct(reconstruct::Args),
    /// Build the tray model at a placement in simulation.
    #[cfg(feature = "sim")]
    Model(model::Args),
    /// Estimate the tray's pose in a recorded dataset or one point cloud.
    Estimate(estimate::Args),
    /// The placement study: both trays x both methods, sweep then search, and report.html.
    #[cfg(feature = "sim")]
    Study(study::Args),
    /// One placement over N scenarios into a study folder (resumable, shardable), each scene with its hard negatives.
    #[cfg(feature = "sim")]
    Evaluate(evaluate::Args),
    /// What each effect of the simulation costs: success with each switched off in turn.
    #[cfg(feature = "sim")]
    Ablate(ablate::Args),
    /// A grid over two placement parameters with heat maps (resumable, shardable).
    #[cfg(feature = "sim")]
    Sweep(sweep::Args),
    /// RBF surrogate search over placement parameters, or over a standard test function.
    #[cfg(feature = "sim")]
    Optimize(optimize::Args),
    /// How far each placement parameter may be off before success drops by a margin.
    #[cfg(feature = "sim")]
    Tolerance(tolerance::Args),
    /// The placement a rig is really mounted at (from rig.json), against the plan and its tolerances.
    #[cfg(feature = "sim")]
    Placement(placement::Args),
    /// Acceptance test of a placement: exit 0 when the success rate's lower bound reaches the minimum, else 1.
    #[cfg(feature = "sim")]
    Accept(accept::Args),
    /// Join the folders of shards into one and compute the summaries again.
    #[cfg(feature = "sim")]
    Merge(merge::Args),
    /// Estimate every frame of a recorded dataset; with truth, the evaluation's summary.
    Replay(replay::Args),
    /// The deployed loop: frames from cameras or a recording, one pose per frame, latency.
    Run(run::Args),
    /// Serve the robot: poses over TCP on request, a status page, a flight recorder, a drift watch.
    Serve(serve::Args),
    /// The installed rig's rig.json from stereo pairs of a chessboard (with one lying on the table).
    Calibrate(calibrate::Args),
    /// Save frames from a source as a recorded dataset (calibration images, the background, frames to replay).
    Capture(capture::Args),
    /// List the cameras of this machine.
    Devices(devices::Args),
    /// Show the projector's pattern full screen (and capture each one in step).
    Project(project::Args),
    /// The real-world trial: plan, mock trial, estimate, scripted marks, report against the study.
    #[cfg(feature = "sim")]
    Trial(trial::Args),
    /// The review page of a dataset without truth: mark each pose correct, wrong or unsure.
    #[cfg(feature = "sim")]
    Review(review::Args),
    /// The cell (table, tray, items, lamp, cameras, projector) as a glTF 2.0 binary for 3D tools.
    #[cfg(feature = "sim")]
    Export(export::Args),
    /// Fit the cell's sensor keys (noise, blur, projector gain and dots, ambient) to a real dataset.
    #[cfg(feature = "sim")]
    FitSensor(fit_sensor::Args),
}

/// Parses the command line and runs the subcommand.
pub fn dispatch() -> anyhow::Result<ExitCode> {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        // --help and --version print as clap shows them.
        Err(e) if !e.use_stderr() => {
            if let Err(io) = e.print() {
                output::stdout_failed(&io);
            }
            std::process::exit(e.exit_code())
        }
        // A bad flag: one line, exit code 2 like every other bad input.
        Err(e) => anyhow::bail!("{}", one_line(&e.to_string())),
    };
    #[cfg(feature = "sim")]
    progress::install();
    match cli.command {
        Command::Init(a) => init::run(a),
        #[cfg(feature = "sim")]
        Command::Render(a) => render::run(a),
        Command::Reconstruct(a) => reconstruct::run(a),
        #[cfg(feature = "sim")]
        Command::Model(a) => model::run(a),
        Command::Estimate(a) => estimate::run(a),
        #[cfg(feature = "sim")]
        Command::Study(a) => study::run(a),
        #[cfg(feature = "sim")]
        Command::Evaluate(a) => evaluate::run(a),
        #[cfg(feature = "sim")]
        Command::Ablate(a) => ablate::run(a),
        #[cfg(feature = "sim")]
        Command::Sweep(a) => sweep::run(a),
        #[cfg(feature = "sim")]
        Command::Optimize(a) => optimize::run(a),
        #[cfg(feature = "sim")]
        Command::Tolerance(a) => tolerance::run(a),
        #[cfg(feature = "sim")]
        Command::Placement(a) => placement::run(a),
        #[cfg(feature = "sim")]
        Command::Accept(a) => accept::run(a),
        #[cfg(feature = "sim")]
        Command::Merge(a) => merge::run(a),
        Command::Replay(a) => replay::run(a),
        Command::Run(a) => run::run(a),
        Command::Serve(a) => serve::run(a),
        Command::Calibrate(a) => calibrate::run(a),
        Command::Capture(a) => capture::run(a),
        Command::Devices(a) => devices::run(a),
        Command::Project(a) => project::run(a),
        #[cfg(feature = "sim")]
        Command::Trial(a) => trial::run(a),
        #[cfg(feature = "sim")]
        Command::Review(a) => review::run(a),
        #[cfg(feature = "sim")]
        Command::Export(a) => export::run(a),
        #[cfg(feature = "sim")]
        Command::FitSensor(a) => fit_sensor::run(a),
    }
}

/// clap's message on one line: what is wrong and the flags it names (clap lists missing
/// flags on the lines below its first), without the usage and help pointers.
fn one_line(text: &str) -> String {
    let said: Vec<&str> = text
        .lines()
        .map(str::trim)
        .take_while(|l| !l.starts_with("Usage:") && !l.starts_with("For more information"))
        .filter(|l| !l.is_empty())
        .collect();
    let joined = said.join(" ");
    let joined = joined.trim_start_matches("error: ");
    if joined.is_empty() {
        "bad arguments".to_string()
    } else {
        joined.to_string()
    }
}
