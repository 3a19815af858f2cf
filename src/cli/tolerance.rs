//! `camplace tolerance`: how far each placement parameter may be off before the success
//! rate drops by more than a margin, and the success at the corners of that box; into a
//! study folder (resumable) with tolerance.json and a plot per parameter.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::bail;
use camplace_sim::{measure_tolerance, write_tolerance_plots, ToleranceRequest, TOLERANCE_STEPS};

use super::cell_args::{refuse_installed_rig, CellArgs};
use super::study_args::{check_scenarios, SceneArgs};

/// The most steps a walk may take in one direction.
const MAX_STEPS: u32 = 100;

/// Flags of `camplace tolerance`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    cell: CellArgs,
    #[command(flatten)]
    scene: SceneArgs,
    /// Largest drop of the success rate still tolerated, as a share (0.02: 2 points).
    #[arg(long, default_value_t = 0.02)]
    margin: f64,
    /// Scenarios 0..N-1 of the seed at every placement (the same scenes everywhere).
    #[arg(long, default_value_t = 50)]
    scenarios: u64,
    /// Steps walked out at most in each direction (r 10 mm, alpha 2 deg, baseline 5 mm,
    /// vergence 0.5 deg, azimuth 5 deg a step).
    #[arg(long, default_value_t = 6)]
    steps: u32,
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
    // A cell that lists several trays: one placement for all of them, judged by the lowest.
    let (trays, placement) = a.cell.load_trays()?;
    refuse_installed_rig(&trays[0].1, "tolerance")?;
    let seed = a.scene.seed(&trays[0].1);
    if !(1..=MAX_STEPS).contains(&a.steps) {
        bail!("--steps: expected 1 to {MAX_STEPS} steps, got {}", a.steps);
    }
    let mut parameters = Vec::new();
    for name in a.parameters.split(',').map(str::trim).filter(|n| !n.is_empty()) {
        let Some(i) = TOLERANCE_STEPS.iter().position(|(n, _, _)| *n == name) else {
            bail!("--parameters: unknown parameter \"{name}\", expected some of r, alpha, baseline, vergence, azimuth");
        };
        if !parameters.contains(&i) {
            parameters.push(i);
        }
    }
    if parameters.is_empty() {
        bail!("--parameters: expected at least one of r, alpha, baseline, vergence, azimuth");
    }
    parameters.sort_unstable();
    let request = ToleranceRequest {
        placement,
        method: a.scene.method,
        seed,
        scenarios: check_scenarios(a.scenarios)?,
        margin: a.margin,
        max_steps: a.steps,
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
