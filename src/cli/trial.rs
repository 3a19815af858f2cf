//! `camplace trial`: the real-world trial, from plan to report — `plan` (the placements to
//! visit, with the robot's flange poses for a rig on the flange), `mock` (a trial rendered
//! by a cell the study does not know, its truth moved aside), `estimate` (every placement's
//! frames through the estimator), `mark` (the scripted reviewer of a mock trial) and
//! `report` (real against simulated success).

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{bail, Context};
use camplace_config::{placement_dir, Axis, Cell, Grid, TrialPlan, PLAN_FILE};
use camplace_estimator::{depth::Method, Model};
use camplace_hwio::{estimate_dataset, DatasetEstimate};
use camplace_sim::{
    append_label, check_placement_rig, frame_names, make_mock_trial, make_plan, rho_text, scripted_marks, study_grid,
    tie_marks_to_poses, trial_report, LABELS_FILE, REPORT_HTML, REPORT_JSON,
};

use super::cell_args::CellArgs;

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

fn plan(a: PlanArgs) -> anyhow::Result<ExitCode> {
    let (cell, base) = a.cell.load()?;
    let (grid, placements) = if let Some(list) = &a.placements {
        let ps = list
            .split(';')
            .map(str::trim)
            .filter(|p| !p.is_empty())
            .map(|p| base.with_overrides(p))
            .collect::<Result<Vec<_>, _>>()
            .context("--placements")?;
        (None, ps)
    } else {
        let (grid, base) = match (&a.study, &a.x, &a.y) {
            (Some(dir), _, _) => {
                let (g, _, b) = study_grid(dir)?;
                (g, b)
            }
            (None, Some(x), Some(y)) => (Grid { x: x.clone(), y: y.clone() }, base),
            _ => bail!("--study DIR, --x AXIS --y AXIS or --placements LIST: expected the placements to visit"),
        };
        let ps = grid.placements(&base).context("--x/--y")?;
        (Some(grid), ps)
    };
    let plan = make_plan(&cell, grid, &placements).context("--placements")?;
    let csv = plan.save(&a.out)?;
    let flange = if plan.placements[0].t_robot_flange.is_some() { ", with the flange pose of each" } else { "" };
    outln!("{} placements to visit{flange}; wrote {} and {}", plan.placements.len(), a.out.display(), csv.display());
    Ok(ExitCode::SUCCESS)
}

fn mock(a: MockArgs) -> anyhow::Result<ExitCode> {
    let mut real = cell_of(&a.cell)?;
    if let Some(n) = a.noise_amplitude {
        real.sensor.noise_amplitude = n;
    }
    if let Some(b) = a.blur {
        real.sensor.blur = b;
    }
    real.validate().context("--noise-amplitude/--blur")?;
    let plan = TrialPlan::load(&a.plan)?;
    make_mock_trial(&a.out, &a.hidden, &real, &plan, a.method, a.seed, a.frames)?;
    outln!(
        "rendered {} placements × {} frames (seed {}, noise {}, blur {}) into {}; truth moved to {}",
        plan.placements.len(),
        a.frames,
        a.seed,
        real.sensor.noise_amplitude,
        real.sensor.blur,
        a.out.display(),
        a.hidden.display()
    );
    Ok(ExitCode::SUCCESS)
}

fn estimate(a: EstimateArgs) -> anyhow::Result<ExitCode> {
    let cell = cell_of(&a.cell)?;
    let plan = TrialPlan::load(&a.trial.join(PLAN_FILE))?;
    // One model for every placement: read and checked once.
    let model = Model::load_checked(&a.model, &cell, a.cell.as_deref())?;
    for i in 0..plan.placements.len() {
        let dir = placement_dir(&a.trial, i);
        if !dir.exists() {
            noteln!("note: {} not captured yet", dir.display());
            continue;
        }
        check_placement_rig(&dir, &cell, &plan.placement(i))?;
        tie_marks_to_poses(&dir)?;
        let DatasetEstimate { records, method, .. } = estimate_dataset(&cell, model.clone(), &dir)?;
        let found = records.iter().filter(|r| r.found).count();
        let accepted = records.iter().filter(|r| r.accepted()).count();
        outln!(
            "{}: {} frames ({method}), a pose in {found}, accepted {accepted}; wrote {}",
            dir.display(),
            records.len(),
            dir.join("poses.jsonl").display()
        );
    }
    Ok(ExitCode::SUCCESS)
}

fn mark(a: MarkArgs) -> anyhow::Result<ExitCode> {
    let cell = cell_of(&a.cell)?;
    let plan = TrialPlan::load(&a.trial.join(PLAN_FILE))?;
    for i in 0..plan.placements.len() {
        let dir = placement_dir(&a.trial, i);
        let names = frame_names(&dir)?;
        let marks = scripted_marks(&a.trial, &a.hidden, i, &cell)?;
        let labels = dir.join(LABELS_FILE);
        if labels.exists() {
            bail!("{}: exists: the scripted reviewer marks a placement not reviewed yet", labels.display());
        }
        for m in &marks {
            append_label(&dir, &names, m)?;
        }
        let correct = marks.iter().filter(|m| m.mark == camplace_sim::Mark::Correct).count();
        outln!("{}: {correct} of {} marked correct; wrote {}", dir.display(), marks.len(), labels.display());
    }
    Ok(ExitCode::SUCCESS)
}

fn report(a: ReportArgs) -> anyhow::Result<ExitCode> {
    let cell = cell_of(&a.cell)?;
    let out = a.out.clone().unwrap_or_else(|| a.trial.clone());
    let r = trial_report(&a.trial, &cell, a.study.as_deref(), &out)?;
    for p in &r.placements {
        let real = p.real.map_or("-".to_string(), |x| {
            format!(
                "{:.1} % ({} of {}, {:.1}–{:.1} %)",
                100.0 * x.success_rate,
                x.successes,
                x.frames,
                100.0 * x.success_interval[0],
                100.0 * x.success_interval[1]
            )
        });
        let sim = p.simulated.map_or("-".to_string(), |x| {
            format!(
                "{:.1} % ({} of {}, {:.1}–{:.1} %)",
                100.0 * x.success_rate,
                x.successes,
                x.frames,
                100.0 * x.success_interval[0],
                100.0 * x.success_interval[1]
            )
        });
        let earlier = match p.marked_on_earlier_poses {
            0 => String::new(),
            n => format!(", {n} of them marked on earlier poses: mark again"),
        };
        let open = if p.unsure + p.not_judged > 0 {
            format!(" [{} unsure, {} not judged{earlier}]", p.unsure, p.not_judged)
        } else {
            String::new()
        };
        outln!(
            "{:03} {}: real {real}, simulated {sim}{}{open}",
            p.index,
            p.placement,
            if p.in_real_top_set { " (real top set)" } else { "" }
        );
    }
    outln!("{}", rho_text(&r.rank_correlation));
    outln!("{}", r.verdict_text());
    outln!("{}", r.paired_text());
    outln!("wrote {} and {}", out.join(REPORT_JSON).display(), out.join(REPORT_HTML).display());
    Ok(ExitCode::SUCCESS)
}
