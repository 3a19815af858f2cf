//! `camplace placement`: the placement a rig is really mounted at, from its `rig.json`
//! (a calibration, or a rendered rig), against the planned placement, and with a study's
//! or a tolerance run's tolerances whether each parameter is within them (exit 1 when
//! one is not).

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Context};
use camplace_config::{RigFile, ToleranceReport};
use camplace_estimator::Rig;
use camplace_estimator::{geometry::as_built, geometry::mounting_check, geometry::MountingVerdict};
use camplace_sim::tolerance_dir;

use super::cell_args::CellArgs;
use super::study_args::recommended;

/// Flags of `camplace placement`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The rig as installed: `rig.json` (from calibration, or written by render).
    #[arg(long, value_name = "FILE")]
    rig: PathBuf,
    /// The plan: the cell's placement, with --placement overrides (unless --study or
    /// --tolerance give it).
    #[command(flatten)]
    cell: CellArgs,
    /// A study folder: its recommended placement is the plan, its tolerances the limits.
    #[arg(long, value_name = "DIR", conflicts_with = "tolerance")]
    study: Option<PathBuf>,
    /// A `tolerance.json` (camplace tolerance): its placement is the plan, its tolerances the limits.
    #[arg(long, value_name = "FILE")]
    tolerance: Option<PathBuf>,
}

/// Runs `camplace placement`.
pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let file = RigFile::load(&a.rig)?;
    let built = as_built(&Rig::from_file(&file)).map_err(|e| anyhow::anyhow!("{}: {e}", a.rig.display()))?;
    let (_, cell_plan) = a.cell.load()?;
    let (plan, limits) = match (&a.study, &a.tolerance) {
        (Some(dir), _) => {
            let (plan, method) = recommended(dir)?;
            let file = tolerance_dir(dir, method).join("tolerance.json");
            let limits = if file.exists() {
                Some(read_tolerance(&file)?)
            } else {
                noteln!("note: {} has none: the study measured no tolerances (a --quick preview?)", file.display());
                None
            };
            (plan, limits)
        }
        (None, Some(f)) => {
            let t = read_tolerance(f)?;
            (cell_plan.with_overrides(&t.placement).context("tolerance.json: placement")?, Some(t))
        }
        (None, None) => (cell_plan, None),
    };
    if a.cell.placement.is_some() && (a.study.is_some() || a.tolerance.is_some()) && plan != cell_plan {
        bail!("--placement: the plan comes from the study or tolerance.json ({plan}); leave --placement out");
    }
    outln!("as built ({}): {}", a.rig.display(), built.placement.to_step_text());
    outln!("planned: {}", plan.to_step_text());
    outln!("{:<10} {:>12} {:>12} {:>12} {:>16}", "parameter", "as built", "planned", "difference", "tolerance");
    let check = mounting_check(&built, &plan, limits.as_ref());
    for c in &check.params {
        let (name, unit) = (c.param.name(), c.param.unit());
        let verdict = match (c.limit, c.verdict) {
            (Some(l), MountingVerdict::Outside) => format!("-{}/+{} OUTSIDE", l.minus, l.plus),
            (Some(l), _) => format!("-{}/+{} within", l.minus, l.plus),
            (None, _) => "not measured".to_string(),
        };
        let digits = c.param.decimals();
        outln!(
            "{name:<10} {:>8.digits$} {unit:<3} {:>8.digits$} {unit:<3} {:>+8.digits$} {unit:<3} {verdict:>16}",
            c.as_built,
            c.planned,
            c.difference
        );
    }
    outln!("toe-in: left {:.2} deg, right {:.2} deg", built.toe_in[0], built.toe_in[1]);
    match built.aim_point {
        Some([x, y]) => outln!(
            "aim: {:.2} deg off the table centre; the rig looks at ({x:.1}, {y:.1}) mm on the table",
            built.aim_error
        ),
        None => {
            outln!("aim: {:.2} deg off the table centre; the rig does not look down at the table", built.aim_error)
        }
    }
    outln!("baseline slope: {:.2} deg from level", built.baseline_tilt);
    if let Some(t) = &limits {
        outln!(
            "tolerances: the edges where success is shown to drop from {:.1} % at the plan ({} method; {})",
            100.0 * t.nominal.success_rate,
            t.method,
            t.test_text()
        );
    }
    let outside = check.outside();
    if outside.is_empty() {
        Ok(ExitCode::SUCCESS)
    } else {
        let names: Vec<&str> = outside.iter().map(|p| p.name()).collect();
        outln!("outside its tolerance: {}", names.join(", "));
        Ok(ExitCode::from(1))
    }
}

fn read_tolerance(path: &Path) -> anyhow::Result<ToleranceReport> {
    Ok(ToleranceReport::load(path)?)
}
