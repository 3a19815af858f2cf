//! `camplace init [PATH]`: writes the default cell file, a comment on every key.

use anyhow::bail;
use camplace_config::DEFAULT_CELL_TOML;
use std::path::PathBuf;
use std::process::ExitCode;

/// Flags of `camplace init`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Where to write the cell file.
    #[arg(default_value = "cell.toml")]
    path: PathBuf,
    /// Overwrite an existing file.
    #[arg(long)]
    force: bool,
}

/// Runs `camplace init`.
pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    if a.path.exists() && !a.force {
        bail!("{}: already exists; pass --force to overwrite it", a.path.display());
    }
    camplace_config::write_atomic(&a.path, DEFAULT_CELL_TOML.as_bytes())?;
    outln!("wrote {}", a.path.display());
    Ok(ExitCode::SUCCESS)
}
