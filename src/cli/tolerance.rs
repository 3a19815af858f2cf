//! `camplace tolerance`: how far each placement parameter may be off before its success is
//! shown to drop (each edge found to the parameter's resolution), and the success at the
//! corners of that box; into a study folder (resumable) with tolerance.json and a plot per
//! parameter.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::bail;
use camplace_config::PlacementParam;
use camplace_sim::{
    measure_tolerance, scenes_for_power, write_tolerance_plots, ToleranceRequest, TOLERANCE_LEVEL, TOLERANCE_POWER,
};

use super::cell_args::{refuse_installed_rig, CellArgs};
use super::study_args::{check_scenarios, SceneArgs};

/// Flags of `camplace tolerance`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    cell: CellArgs,
    #[command(flatten)]
    scene: SceneArgs,
    /// The drop of the success rate the scene count is to detect, as a share (0.15: 15
    /// points); a point is outside when the paired test shows it lower than the nominal.
    #[arg(long, default_value_t = 0.15)]
    margin: f64,
    /// Scenarios 0..N-1 of the seed at every placement (the same scenes everywhere);
    /// default: the fewest that catch a drop of the margin with 80 % power.
    #[arg(long)]
    scenarios: Option<u64>,
    /// The share of each found tolerance the corners of the box are placed at (1: the edges).
    #[arg(long, default_value_t = 1.0)]
    corner_fraction: f64,
    /// The parameters to walk, comma-separated (the others stay nominal).
    #[arg(long, value_name = "LIST", default_value = "r,alpha,baseline,vergence,azimuth")]
    parameters: String,
    /// Study folder: results.jsonl (appended as scenes finish), settings.json,
    /// tolerance.json and tolerance_PARAMETER.svg/.png.
    #[arg(long, default_value = "tolerance")]
    out: PathBuf,
}

/// Runs `camplace tolerance`.
pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    if !(a.margin.is_finite() && a.margin > 0.0 && a.margin < 1.0) {
        bail!("--margin: expected a share of scenes between 0 and 1 (0.15 is 15 points), got {}", a.margin);
    }
    // A cell that lists several trays: one placement for all of them, judged by the lowest.
    let (trays, placement) = a.cell.load_trays()?;
    refuse_installed_rig(&trays[0].1, "tolerance")?;
    let seed = a.scene.seed(&trays[0].1);
    let mut parameters = Vec::new();
    for name in a.parameters.split(',').map(str::trim).filter(|n| !n.is_empty()) {
        let Some(param) = PlacementParam::from_name(name) else {
            bail!("--parameters: unknown parameter \"{name}\", expected some of {}", PlacementParam::names());
        };
        if !parameters.contains(&param) {
            parameters.push(param);
        }
    }
    if parameters.is_empty() {
        bail!("--parameters: expected at least one of {}", PlacementParam::names());
    }
    parameters.sort_unstable();
    let scenarios = match a.scenarios {
        Some(n) => check_scenarios(n)?,
        None => match scenes_for_power(a.margin, TOLERANCE_POWER, TOLERANCE_LEVEL) {
            Some(n) => check_scenarios(n as u64)?,
            None => bail!(
                "--margin: a drop of {} needs more than 100000 scenes to be caught; give a larger margin",
                a.margin
            ),
        },
    };
    let request = ToleranceRequest {
        placement,
        method: a.scene.method,
        seed,
        scenarios,
        margin: a.margin,
        corner_fraction: a.corner_fraction,
        parameters,
    };
    // The whole run holds the folder: a second run on it is refused naming this one.
    let _lock = camplace_sim::lock_folder(&a.out)?;
    let report = measure_tolerance(&a.out, trays, &request)?;
    let plots = write_tolerance_plots(&a.out, &report)?;
    outln!("{}", report.table());
    outln!("wrote {} ({} plots)", a.out.join("tolerance.json").display(), plots.len());
    Ok(ExitCode::SUCCESS)
}
