//! The flags the study commands share: method and seed (also taken by `render`, `model`
//! and `accept`), the shard, and a study folder's recommended placement.

use std::path::Path;

use anyhow::{bail, Context};
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
    let path = dir.join("recommended.json");
    let text = camplace_config::read_text(&path)?;
    let v: serde_json::Value = serde_json::from_str(&text).with_context(|| format!("{}: not JSON", path.display()))?;
    let Some(p) = v["placement"].as_str() else {
        bail!(
            "{}: placement: expected a placement such as \"r=605,alpha=32,baseline=81,vergence=3.5\"",
            path.display()
        );
    };
    let method = v["method"]
        .as_str()
        .and_then(|m| m.parse::<Method>().ok())
        .with_context(|| format!("{}: method: expected \"one-shot\" or \"phase-12\"", path.display()))?;
    let base = Placement { r: 0.0, alpha: 0.0, baseline: 0.0, vergence: camplace_config::Vergence::Auto, azimuth: 0.0 };
    Ok((base.with_overrides(p).with_context(|| format!("{}: placement", path.display()))?, method))
}
