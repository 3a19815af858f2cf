//! `camplace optimize`: the RBF surrogate search over placement parameters into a study
//! folder (evaluations found in its results.jsonl are reused, so a re-run resumes), with a
//! convergence plot like the paper's Figure 7; or, with `--test-function`, the same search
//! on a standard function, printing one JSON line.
//!
//! Shards: each step of the search depends on the ones before, so optimize runs in one
//! process and refuses `--shard`; shard the sweep instead (its scenes are independent).

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{bail, Context};
use camplace_config::PlacementParam;
use camplace_sim::{optimize, run_test_function, test_function, SearchParameter, SearchPlan};

use super::cell_args::{refuse_installed_rig, CellArgs};
use super::study_args::{check_scenarios, StudyArgs};

/// Flags of `camplace optimize`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    cell: CellArgs,
    #[command(flatten)]
    run: StudyArgs,
    /// Parameters searched, comma separated, each optionally with its box (baseline=40:200).
    #[arg(long, default_value = "r,alpha,baseline,vergence", value_delimiter = ',', value_parser = parse_param)]
    params: Vec<SearchParameter>,
    /// Evaluations the search may spend, 1 to 10000 (default 100; 300 with --test-function).
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=10_000))]
    budget: Option<u64>,
    /// Scenarios per evaluation.
    #[arg(long, default_value_t = 250)]
    scenarios: u64,
    /// Candidates evaluated again on fresh scenarios (the next seed), 1 to 100.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u64).range(1..=100))]
    top: u64,
    /// Search a standard function instead: branin, goldstein-price, hartmann3 or hartmann6.
    #[arg(long, value_name = "NAME")]
    test_function: Option<String>,
    /// Study folder.
    #[arg(long, required_unless_present = "test_function")]
    out: Option<PathBuf>,
}

fn parse_param(s: &str) -> Result<SearchParameter, String> {
    s.parse()
}

/// Runs `camplace optimize`.
pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    if let Some(name) = &a.test_function {
        let key = name.replace('-', "_");
        if test_function(&key).is_none() {
            bail!("--test-function: expected branin, goldstein-price, hartmann3 or hartmann6, got \"{name}\"");
        }
        let seed = a.run.scene.seed.unwrap_or(1);
        let run = run_test_function(&key, seed, a.budget.unwrap_or(300) as usize);
        let line = serde_json::json!({
            "function": name,
            "seed": seed,
            "evaluations_to_within_1pct": run.evaluations_to_within_1pct,
            "best_value": run.best_value,
        });
        outln!("{line}");
        return Ok(ExitCode::SUCCESS);
    }
    if a.run.shard.is_some() || a.run.shards.is_some() {
        bail!("--shard: optimize runs in one process (each step depends on the last); shard the sweep, merge, then optimize");
    }
    let out = a.out.as_ref().context("--out: expected a study folder")?;
    let (cell, base) = a.cell.load()?;
    refuse_installed_rig(&cell, "optimize")?;
    let seed = a.run.seed(&cell);
    let mut names: Vec<PlacementParam> = a.params.iter().map(|p| p.name).collect();
    names.sort_unstable();
    if names.windows(2).any(|w| w[0] == w[1]) {
        bail!("--params: expected each parameter once");
    }
    // The whole run holds the folder: a second run on it is refused naming this one.
    let _lock = camplace_sim::lock_folder(out)?;
    let plan = SearchPlan {
        parameters: a.params.clone(),
        budget: a.budget.unwrap_or(100) as usize,
        scenarios: check_scenarios(a.scenarios)?,
        optimizer_seed: seed,
        top: a.top as usize,
        recheck_scenarios: a.scenarios,
    };
    let outcome = optimize(out, &cell, &base, a.run.method(), seed, &plan, "optimize")?;
    let best = outcome.best();
    outln!(
        "best of {} evaluations, re-evaluated on fresh scenarios: {}: {}; wrote {}",
        outcome.history.len(),
        best.placement,
        best.summary.line(),
        out.display()
    );
    Ok(ExitCode::SUCCESS)
}
