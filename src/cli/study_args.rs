//! The flags the study commands share: method and seed (also taken by `render`, `model`
//! and `accept`), the shard, and a study folder's recommended placement.

use std::path::Path;

use anyhow::bail;
use camplace_config::{Cell, Placement};
use camplace_sim::{Method, Shard};

/// `--method` and `--seed`: which sensor and which scenes.
#[derive(clap::Args, Debug, Clone)]
pub struct SceneArgs {
    /// one-shot (random dots) or phase-12 (12 phase-shift fringes).
    #[arg(long, default_value = "one-shot")]
    pub method: Method,
    /// Study seed: scenario i of a seed is the same scene everywhere, and the seed picks the
    /// projected dots and the camera noise (default: the cell's scenarios.seed).
    #[arg(long)]
    pub seed: Option<u64>,
}

impl SceneArgs {
    /// The seed: the flag, else the cell's.
    pub fn seed(&self, cell: &Cell) -> u64 {
        self.seed.unwrap_or(cell.scenarios.seed)
    }
}

/// `--method`, `--seed`, `--shard` / `--shards`.
#[derive(clap::Args, Debug, Clone)]
pub struct StudyArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Run only part I of N (0-based) of the (placement, scenario) pairs; `camplace merge` joins the parts.
    #[arg(long, value_name = "I/N", conflicts_with = "shards")]
    pub shard: Option<String>,
    /// Split into N parts, this one's index from SLURM_ARRAY_TASK_ID or JOB_COMPLETION_INDEX.
    #[arg(long, value_name = "N")]
    pub shards: Option<usize>,
}

impl StudyArgs {
    /// The seed: the flag, else the cell's.
    pub fn seed(&self, cell: &Cell) -> u64 {
        self.scene.seed(cell)
    }

    /// The method.
    pub fn method(&self) -> Method {
        self.scene.method
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

/// The most scenarios one placement may be evaluated on (a 95 % interval is then about
/// ±0.1 points wide; more buys nothing).
pub const MAX_SCENARIOS: u64 = 1_000_000;

/// `--scenarios` must be from 1 to [`MAX_SCENARIOS`].
pub fn check_scenarios(n: u64) -> anyhow::Result<u64> {
    if !(1..=MAX_SCENARIOS).contains(&n) {
        bail!("--scenarios: expected 1 to {MAX_SCENARIOS} scenarios, got {n}");
    }
    Ok(n)
}

/// The recommended placement and its method from a study folder's `recommended.json`.
pub fn recommended(dir: &Path) -> anyhow::Result<(Placement, Method)> {
    let r = camplace_sim::Recommended::load(dir)?;
    Ok((r.placement, r.method))
}
