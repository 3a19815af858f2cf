//! `camplace accept`: the acceptance test of one placement. It passes when the lower
//! Wilson bound of the success rate reaches the required rate, with `--max-wrong` the
//! upper 95 % bound of the wrong poses among the verified ones stays within it, and with
//! `--min-slot-accuracy` the lower 95 % bound of the slots called right (filled or empty as
//! the truth has them) among the accepted poses reaches it: exit 0 on pass, 1 on fail.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::bail;
use camplace_sim::acceptance_summary;

use super::cell_args::{CellArgs, InstalledRigArg};
use super::study_args::check_scenarios;
use super::study_args::SceneArgs;

/// Flags of `camplace accept`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    cell: CellArgs,
    #[command(flatten)]
    installed: InstalledRigArg,
    #[command(flatten)]
    scene: SceneArgs,
    /// Required success rate, 0..1: the lower end of the 95 % interval must reach it.
    #[arg(long, required_unless_present_any = ["max_wrong", "min_slot_accuracy"])]
    min_success: Option<f64>,
    /// Largest share of wrong poses among the accepted ones, 0..1: the one-sided 95 % upper
    /// bound (Clopper–Pearson) at the threshold chosen from these scenes must stay within it.
    #[arg(long)]
    max_wrong: Option<f64>,
    /// Required share of slots called right (filled or empty as the truth has them) among
    /// the accepted poses' slots, 0..1: the one-sided 95 % lower bound (Clopper–Pearson)
    /// must reach it. A slot judged unseen is no wrong call (the robot is told to skip it).
    #[arg(long)]
    min_slot_accuracy: Option<f64>,
    /// Scenarios 0..N-1 of the seed.
    #[arg(long, default_value_t = 250)]
    scenarios: u64,
    /// Keep the results in this study folder (resumable); in memory only when not given.
    #[arg(long)]
    out: Option<PathBuf>,
}

/// Runs `camplace accept`.
pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    if let Some(m) = a.min_success.filter(|m| !(0.0..=1.0).contains(m)) {
        bail!("--min-success: expected a rate between 0 and 1 (e.g. 0.95), got {m}");
    }
    if let Some(w) = a.max_wrong.filter(|w| !(w.is_finite() && *w > 0.0 && *w < 1.0)) {
        bail!("--max-wrong: expected a share above 0 and below 1 (e.g. 0.005), got {w}");
    }
    if let Some(m) = a.min_slot_accuracy.filter(|m| !(0.0..=1.0).contains(m)) {
        bail!("--min-slot-accuracy: expected a share between 0 and 1 (e.g. 0.999), got {m}");
    }
    let (mut cell, mut placement) = a.cell.load()?;
    a.installed.apply(&mut cell, &mut placement)?;
    let seed = a.scene.seed(&cell);
    let scenarios = check_scenarios(a.scenarios)?;
    let s = acceptance_summary(a.out.as_deref(), &cell, &placement, a.scene.method, seed, scenarios)?;
    outln!("{placement} ({}, seed {seed}): {}", a.scene.method, s.line());
    let mut pass = true;
    if let Some(min) = a.min_success {
        let low = s.success_interval[0];
        let ok = low >= min;
        outln!(
            "{}: lower 95 % bound {:.1} % {} the required {:.1} %",
            if ok { "PASS" } else { "FAIL" },
            100.0 * low,
            if ok { "reaches" } else { "is below" },
            100.0 * min
        );
        pass &= ok;
    }
    if let Some(max) = a.max_wrong {
        // No scored pose at all is no evidence, so it fails.
        let upper = s.verification.map_or(1.0, |v| v.wrong_accepted_upper);
        let ok = upper <= max;
        outln!(
            "{}: upper 95 % bound of wrong poses among the accepted {:.2} % {} the allowed {:.2} %",
            if ok { "PASS" } else { "FAIL" },
            100.0 * upper,
            if ok { "is within" } else { "exceeds" },
            100.0 * max
        );
        pass &= ok;
    }
    if let Some(min) = a.min_slot_accuracy {
        // No accepted pose with slots is no evidence, so it fails.
        let (low, counts) = match &s.slots {
            Some(slots) => (
                slots.accuracy_lower(),
                format!(
                    "{} wrong of {} slots in {} accepted poses, {} unseen",
                    slots.wrong, slots.slots, slots.frames, slots.unseen
                ),
            ),
            None => (0.0, "no accepted pose with slots".to_string()),
        };
        let ok = low >= min;
        outln!(
            "{}: lower 95 % bound of slots called right {:.2} % {} the required {:.2} % ({counts})",
            if ok { "PASS" } else { "FAIL" },
            100.0 * low,
            if ok { "reaches" } else { "is below" },
            100.0 * min
        );
        pass &= ok;
    }
    Ok(if pass { ExitCode::SUCCESS } else { ExitCode::from(1) })
}
