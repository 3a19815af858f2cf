//! The flags the study commands share: method, seed, output folder and shard, and opening
//! a study folder (its settings checked, its results read).

use std::path::Path;

use anyhow::{bail, Context};
use camplace_config::Cell;
use camplace_sim::study::results::ResultsStore;
use camplace_sim::study::settings::RunSettings;
use camplace_sim::study::shard::Shard;
use camplace_sim::Method;

/// `--method`, `--seed`, `--shard` / `--shards`.
#[derive(clap::Args, Debug, Clone)]
pub struct RunArgs {
    /// one-shot (random dots) or phase-12 (12 phase-shift fringes).
    #[arg(long, default_value = "one-shot")]
    pub method: Method,
    /// Study seed: scenario i of a seed is the same scene everywhere (default: the cell's scenarios.seed).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Run only part I of N (0-based) of the (placement, scenario) pairs; `camplace merge` joins the parts.
    #[arg(long, value_name = "I/N", conflicts_with = "shards")]
    pub shard: Option<String>,
    /// Split into N parts, this one's index from SLURM_ARRAY_TASK_ID or JOB_COMPLETION_INDEX.
    #[arg(long, value_name = "N")]
    pub shards: Option<usize>,
}

impl RunArgs {
    /// The seed: the flag, else the cell's.
    pub fn seed(&self, cell: &Cell) -> u64 {
        self.seed.unwrap_or(cell.scenarios.seed)
    }

    /// The shard to run (the whole work by default).
    pub fn shard(&self) -> anyhow::Result<Shard> {
        if let Some(text) = &self.shard {
            return text.parse::<Shard>().map_err(|e| anyhow::anyhow!("--shard: {e}"));
        }
        let Some(count) = self.shards else { return Ok(Shard::WHOLE) };
        for var in ["SLURM_ARRAY_TASK_ID", "JOB_COMPLETION_INDEX"] {
            if let Ok(v) = std::env::var(var) {
                let index: usize =
                    v.trim().parse().map_err(|_| anyhow::anyhow!("{var}: expected a shard index, got \"{v}\""))?;
                return Shard::new(index, count).map_err(|e| anyhow::anyhow!("{var} with --shards {count}: {e}"));
            }
        }
        bail!(
            "--shards {count}: expected the shard index in SLURM_ARRAY_TASK_ID or JOB_COMPLETION_INDEX, neither is set"
        )
    }
}

/// Creates `dir`, checks (or writes) its settings and opens its results file.
pub fn open_folder(dir: &Path, cell: &Cell, method: Method, seed: u64) -> anyhow::Result<ResultsStore> {
    std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create the folder", dir.display()))?;
    RunSettings::new(cell, method, seed).check_or_write(dir)?;
    Ok(ResultsStore::open(&dir.join("results.jsonl"))?)
}

/// `--scenarios` must be at least 1.
pub fn check_scenarios(n: u64) -> anyhow::Result<u64> {
    if n == 0 {
        bail!("--scenarios: expected at least 1 scenario");
    }
    Ok(n)
}
