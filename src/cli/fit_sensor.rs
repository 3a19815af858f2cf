//! `camplace fit-sensor`: the cell file's sensor keys fitted to a recorded dataset of the
//! real sensor (its rig, the empty cell's background and frames of the tray), written as a
//! cell fragment beside the fit's statistics, real and simulated (the fit is
//! `camplace_sim::fit_sensor`).

use std::path::PathBuf;
use std::process::ExitCode;

use camplace_config::Cell;
use camplace_sim::{fit_sensor, write_fit, FIT_FRAGMENT, FIT_HTML, FIT_JSON, MAX_FIT_FRAMES};

/// Flags of `camplace fit-sensor`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The recorded dataset of the real sensor: rig.json, background/ and frames/NNNN/.
    #[arg(long, value_name = "DIR")]
    dataset: PathBuf,
    /// The cell file whose keys are fitted (its table's albedo and geometry are taken as
    /// known); the built-in default when not given.
    #[arg(long, value_name = "FILE")]
    cell: Option<PathBuf>,
    /// Frames compared with the background at most (the dataset's first ones).
    #[arg(long, default_value_t = 20, value_parser = clap::value_parser!(u64).range(2..=MAX_FIT_FRAMES as u64))]
    frames: u64,
    /// Where fit-sensor.toml, .json and .html go.
    #[arg(long, value_name = "DIR", default_value = "fit-sensor")]
    out: PathBuf,
}

/// Runs `camplace fit-sensor`.
pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let cell = Cell::load_one(a.cell.as_deref(), None)?;
    let fit = fit_sensor(&a.dataset, &cell, a.frames as usize)?;
    write_fit(&fit, &a.out)?;
    outln!("{} frames ({}) against the background, {} table tiles", fit.frames, fit.method, fit.tiles);
    outln!(
        "{:<24} {:>8} {:>10} {:>8}   statistic: real / simulated fitted / cell's",
        "key",
        "fitted",
        "estimate",
        "cell's"
    );
    for k in &fit.keys {
        let se = if k.standard_error.is_finite() { format!(" ±{:.3}", k.standard_error) } else { String::new() };
        outln!(
            "{:<24} {:>8} {:>10.3} {:>8}   {:.3} / {:.3} / {:.3}{se}",
            k.key,
            k.value,
            k.estimate,
            k.cell_value,
            k.real,
            k.simulated_fitted,
            k.simulated_cell
        );
    }
    let am = &fit.ambient;
    outln!(
        "{:<24} [{}, {}] (cell's [{}, {}]) from {} frames' light levels",
        "lighting.ambient",
        am.range[0],
        am.range[1],
        am.cell_range[0],
        am.cell_range[1],
        am.frame_levels.len()
    );
    outln!(
        "wrote {}, {}, {}",
        a.out.join(FIT_FRAGMENT).display(),
        a.out.join(FIT_JSON).display(),
        a.out.join(FIT_HTML).display()
    );
    Ok(ExitCode::SUCCESS)
}
