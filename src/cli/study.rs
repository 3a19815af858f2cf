//! `camplace study`: where to mount the rig for the cell's trays (each method a sweep then
//! a search, the best checked on fresh scenes, the recommended placement's tolerances)
//! into one folder, ending with `report.html`; `--paper` runs the paper's experiment.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use camplace_config::Cell;
use camplace_sim::{run_study, write_report, Method, Preset, Shard, StudyRequest};

/// Flags of `camplace study`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Cell file (TOML); the built-in default cell when not given. Its tray, or every tray
    /// of its [[trays]] list (one placement must serve them all), is studied.
    #[arg(long, value_name = "FILE")]
    cell: Option<PathBuf>,
    /// The paper's experiment instead: both built-in trays (8 and 4 slots), each on its
    /// own, with the findings against the paper; the cell's trays are not used.
    #[arg(long)]
    paper: bool,
    /// Study only this method (one-shot or phase-12); both when not given.
    #[arg(long)]
    method: Option<Method>,
    /// Study seed (default: the cell's scenarios.seed).
    #[arg(long)]
    seed: Option<u64>,
    /// A coarse preview in about two minutes (3 × 3 grid of few scenes, no search, no tolerances).
    #[arg(long)]
    quick: bool,
    /// Run only part I of N of the sweeps; merge the parts, then run study on the merged folder.
    #[arg(long, value_name = "I/N")]
    shard: Option<String>,
    /// Output folder.
    #[arg(long, default_value = "out/study")]
    out: PathBuf,
}

/// Runs `camplace study`.
pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let started = Instant::now();
    let cell = Cell::load_or_default(a.cell.as_deref())?;
    super::cell_args::refuse_installed_rig(&cell, "study")?;
    let seed = a.seed.unwrap_or(cell.scenarios.seed);
    let shard = match &a.shard {
        Some(t) => t.parse::<Shard>().map_err(|e| anyhow::anyhow!("--shard: {e}"))?,
        None => Shard::WHOLE,
    };
    let preset = if a.quick { Preset::quick() } else { Preset::full() };
    let methods = match a.method {
        Some(m) => vec![m],
        None => vec![Method::OneShot, Method::Phase12],
    };
    // The whole run holds the folder: a second run on it is refused naming this one.
    let _lock = camplace_sim::lock_folder(&a.out)?;
    let request = StudyRequest { out: &a.out, cell: &cell, seed, preset: &preset, paper: a.paper, methods, shard };
    match run_study(&request, |line| outln!("{line}"))? {
        Some(outcome) => {
            let report = write_report(&request, &outcome, started)?;
            outln!("wrote {} ({:.0} s)", report.display(), started.elapsed().as_secs_f64())
        }
        None => outln!(
            "shard {shard} of the sweeps done into {}; merge the parts, then run camplace study on the merged folder",
            a.out.display()
        ),
    }
    Ok(ExitCode::SUCCESS)
}
