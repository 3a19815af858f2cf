//! `camplace merge`: joins the folders of shards (or of any runs with the same settings)
//! into one and computes the summaries and plots again.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::bail;
use camplace_sim::merge;

/// Flags of `camplace merge`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The folders to join (shards of one evaluate, sweep or study).
    #[arg(required = true, value_name = "DIR")]
    dirs: Vec<PathBuf>,
    /// The joined folder (may be one of the inputs or hold results already).
    #[arg(long)]
    out: PathBuf,
}

/// Runs `camplace merge`.
pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    for d in &a.dirs {
        if !d.is_dir() {
            bail!("{}: expected a study folder", d.display());
        }
    }
    let n = merge(&a.dirs, &a.out)?;
    if n == 0 {
        bail!("{}: no study results found to merge (expected settings.json and results.jsonl)", a.dirs[0].display());
    }
    outln!("merged {} folders: {n} scenes into {}", a.dirs.len(), a.out.display());
    Ok(ExitCode::SUCCESS)
}
