//! `camplace trial`: the real-world trial, from plan to report — `plan` (the placements to
//! visit, with the robot's flange poses for a rig on the flange), `mock` (a trial rendered
//! by a cell the study does not know, its truth moved aside), `estimate` (every placement's
//! frames through the estimator), `mark` (the scripted reviewer of a mock trial) and
//! `report` (real against simulated success).

use std::path::PathBuf;
use std::process::ExitCode;

use camplace_config::{Axis, Cell};
use camplace_estimator::depth::Method;

use super::cell_args::CellArgs;

mod steps;
use steps::{estimate, mark, mock, plan, report};

/// Flags of `camplace trial`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    step: Step,
}

#[derive(clap::Subcommand, Debug)]
enum Step {
    /// The placements to visit: a study's sweep grid (--study), another grid (--x, --y) or a list.
    Plan(PlanArgs),
    /// A mock trial: each placement rendered by a cell the study does not know, truth hidden.
    Mock(MockArgs),
    /// Every placement's frames through the estimator (poses.jsonl in each NNN/).
    Estimate(EstimateArgs),
    /// The scripted reviewer of a mock trial: marks from the hidden truth into labels.jsonl.
    Mark(MarkArgs),
    /// Real success beside simulated success: maps, rank correlation, verdict; HTML + JSON.
    Report(ReportArgs),
}

/// Flags of `trial plan`.
#[derive(clap::Args, Debug)]
struct PlanArgs {
    #[command(flatten)]
    cell: CellArgs,
    /// A study (or sweep) folder: its sweep's grid is visited.
    #[arg(long, value_name = "DIR", conflicts_with_all = ["x", "y", "placements"])]
    study: Option<PathBuf>,
    /// The grid's horizontal axis (as `sweep` takes it), over the cell's placement.
    #[arg(long, value_parser = parse_axis, requires = "y", conflicts_with = "placements")]
    x: Option<Axis>,
    /// The grid's vertical axis.
    #[arg(long, value_parser = parse_axis, requires = "x")]
    y: Option<Axis>,
    /// A list of placements separated by ';' (each as --placement takes it), in visiting order.
    #[arg(long, value_name = "P;P;...")]
    placements: Option<String>,
    /// The plan file to write (plan.csv is written beside it).
    #[arg(long, value_name = "FILE")]
    out: PathBuf,
}

fn parse_axis(s: &str) -> Result<Axis, String> {
    s.parse()
}

/// Flags of `trial mock`.
#[derive(clap::Args, Debug)]
struct MockArgs {
    /// The plan to render (from `trial plan`).
    #[arg(long, value_name = "FILE")]
    plan: PathBuf,
    /// The "real" cell the frames come from (the study's cell with other values); the
    /// built-in default when not given.
    #[arg(long, value_name = "FILE")]
    cell: Option<PathBuf>,
    /// Overrides the real cell's sensor.noise_amplitude (grey levels).
    #[arg(long, value_name = "N")]
    noise_amplitude: Option<u32>,
    /// Overrides the real cell's sensor.blur (odd filter side).
    #[arg(long, value_name = "N")]
    blur: Option<u32>,
    /// The real cell's seed (another than the study's).
    #[arg(long, default_value_t = 9001)]
    seed: u64,
    /// Tray set-downs (frames) per placement, 1 to 10000.
    #[arg(long, default_value_t = 20, value_parser = clap::value_parser!(u64).range(1..=10_000))]
    frames: u64,
    /// one-shot or phase-12.
    #[arg(long, default_value = "one-shot")]
    method: Method,
    /// Where each frame's truth.json is moved (outside the trial folder).
    #[arg(long, value_name = "DIR")]
    hidden: PathBuf,
    /// The trial folder to make.
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
}

/// Flags of `trial estimate`.
#[derive(clap::Args, Debug)]
struct EstimateArgs {
    /// The trial folder.
    #[arg(long, value_name = "DIR")]
    trial: PathBuf,
    /// The tray model (from `camplace model`).
    #[arg(long, value_name = "FILE")]
    model: PathBuf,
    /// Cell file; the built-in default when not given. The model must be built for its tray.
    #[arg(long, value_name = "FILE")]
    cell: Option<PathBuf>,
}

/// Flags of `trial mark`.
#[derive(clap::Args, Debug)]
struct MarkArgs {
    /// The trial folder (estimated).
    #[arg(long, value_name = "DIR")]
    trial: PathBuf,
    /// The hidden truth of `trial mock`.
    #[arg(long, value_name = "DIR")]
    hidden: PathBuf,
    /// Cell file with the success tolerances; the built-in default when not given.
    #[arg(long, value_name = "FILE")]
    cell: Option<PathBuf>,
}

/// Flags of `trial report`.
#[derive(clap::Args, Debug)]
struct ReportArgs {
    /// The trial folder.
    #[arg(long, value_name = "DIR")]
    trial: PathBuf,
    /// The study (or sweep) folder of the simulated side.
    #[arg(long, value_name = "DIR")]
    study: Option<PathBuf>,
    /// Cell file the rigs are checked against; the built-in default when not given.
    #[arg(long, value_name = "FILE")]
    cell: Option<PathBuf>,
    /// Where trial_report.json and .html go (the trial folder when not given).
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
}

fn cell_of(path: &Option<PathBuf>) -> anyhow::Result<Cell> {
    Ok(Cell::load_one(path.as_deref(), None)?)
}

/// Runs `camplace trial`.
pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    match a.step {
        Step::Plan(a) => plan(a),
        Step::Mock(a) => mock(a),
        Step::Estimate(a) => estimate(a),
        Step::Mark(a) => mark(a),
        Step::Report(a) => report(a),
    }
}
