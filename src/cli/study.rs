//! `camplace study`: the placement study (both built-in trays × both methods, each a
//! sweep then a search) into one folder, ending with `report.html`.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use camplace_config::Cell;
use camplace_sim::{run_study, Preset, Shard};

/// Flags of `camplace study`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Cell file (TOML); the built-in default cell when not given. Its tray kind is
    /// replaced by each built-in tray in turn.
    #[arg(long, value_name = "FILE")]
    cell: Option<PathBuf>,
    /// Study seed (default: the cell's scenarios.seed).
    #[arg(long)]
    seed: Option<u64>,
    /// A small preset for a first look (3 × 3 grid, few scenes, short search).
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
    let base_cell = match &a.cell {
        Some(p) => Cell::load(p)?,
        None => Cell::default(),
    };
    let seed = a.seed.unwrap_or(base_cell.scenarios.seed);
    let shard = match &a.shard {
        Some(t) => t.parse::<Shard>().map_err(|e| anyhow::anyhow!("--shard: {e}"))?,
        None => Shard::WHOLE,
    };
    let preset = if a.quick { Preset::quick() } else { Preset::full() };
    match run_study(&a.out, &base_cell, seed, &preset, shard, started, |line| println!("{line}"))? {
        Some(report) => println!("wrote {} ({:.0} s)", report.display(), started.elapsed().as_secs_f64()),
        None => println!(
            "shard {shard} of the sweeps done into {}; merge the parts, then run camplace study on the merged folder",
            a.out.display()
        ),
    }
    Ok(ExitCode::SUCCESS)
}
