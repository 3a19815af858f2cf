//! The steps of `camplace trial`, one function each: flags in, one library call, what it
//! wrote printed.

use std::process::ExitCode;

use anyhow::{bail, Context};
use camplace_config::{placement_dir, Grid, TrialPlan, PLAN_FILE};
use camplace_estimator::Model;
use camplace_hwio::{estimate_dataset, DatasetEstimate};
use camplace_sim::{
    append_label, check_placement_rig, frame_names, make_mock_trial, make_plan, rho_text, scripted_marks, study_grid,
    tie_marks_to_poses, trial_report, LABELS_FILE, REPORT_HTML, REPORT_JSON,
};

use super::{cell_of, EstimateArgs, MarkArgs, MockArgs, PlanArgs, ReportArgs};

pub(super) fn plan(a: PlanArgs) -> anyhow::Result<ExitCode> {
    let (cell, base) = a.cell.load()?;
    let (grid, placements) = if let Some(list) = &a.placements {
        let ps = list
            .split(';')
            .map(str::trim)
            .filter(|p| !p.is_empty())
            .map(|p| base.with_overrides(p))
            .collect::<Result<Vec<_>, _>>()
            .context("--placements")?;
        (None, ps)
    } else {
        let (grid, base) = match (&a.study, &a.x, &a.y) {
            (Some(dir), _, _) => {
                let (g, _, b) = study_grid(dir)?;
                (g, b)
            }
            (None, Some(x), Some(y)) => (Grid { x: x.clone(), y: y.clone() }, base),
            _ => bail!("--study DIR, --x AXIS --y AXIS or --placements LIST: expected the placements to visit"),
        };
        let ps = grid.placements(&base).context("--x/--y")?;
        (Some(grid), ps)
    };
    let plan = make_plan(&cell, grid, &placements).context("--placements")?;
    let csv = plan.save(&a.out)?;
    let flange = if plan.placements[0].t_robot_flange.is_some() { ", with the flange pose of each" } else { "" };
    outln!("{} placements to visit{flange}; wrote {} and {}", plan.placements.len(), a.out.display(), csv.display());
    Ok(ExitCode::SUCCESS)
}

pub(super) fn mock(a: MockArgs) -> anyhow::Result<ExitCode> {
    let mut real = cell_of(&a.cell)?;
    if let Some(n) = a.noise_amplitude {
        real.sensor.noise_amplitude = n;
    }
    if let Some(b) = a.blur {
        real.sensor.blur = b;
    }
    real.validate().context("--noise-amplitude/--blur")?;
    let plan = TrialPlan::load(&a.plan)?;
    make_mock_trial(&a.out, &a.hidden, &real, &plan, a.method, a.seed, a.frames)?;
    outln!(
        "rendered {} placements × {} frames (seed {}, noise {}, blur {}) into {}; truth moved to {}",
        plan.placements.len(),
        a.frames,
        a.seed,
        real.sensor.noise_amplitude,
        real.sensor.blur,
        a.out.display(),
        a.hidden.display()
    );
    Ok(ExitCode::SUCCESS)
}

pub(super) fn estimate(a: EstimateArgs) -> anyhow::Result<ExitCode> {
    let cell = cell_of(&a.cell)?;
    let plan = TrialPlan::load(&a.trial.join(PLAN_FILE))?;
    // One model for every placement: read and checked once.
    let model = Model::load_checked(&a.model, &cell, a.cell.as_deref())?;
    for i in 0..plan.placements.len() {
        let dir = placement_dir(&a.trial, i);
        if !dir.exists() {
            noteln!("note: {} not captured yet", dir.display());
            continue;
        }
        check_placement_rig(&dir, &cell, &plan.placement(i))?;
        tie_marks_to_poses(&dir)?;
        let DatasetEstimate { records, method, .. } = estimate_dataset(&cell, model.clone(), &dir)?;
        let found = records.iter().filter(|r| r.found).count();
        let accepted = records.iter().filter(|r| r.accepted()).count();
        outln!(
            "{}: {} frames ({method}), a pose in {found}, accepted {accepted}; wrote {}",
            dir.display(),
            records.len(),
            dir.join("poses.jsonl").display()
        );
    }
    Ok(ExitCode::SUCCESS)
}

pub(super) fn mark(a: MarkArgs) -> anyhow::Result<ExitCode> {
    let cell = cell_of(&a.cell)?;
    let plan = TrialPlan::load(&a.trial.join(PLAN_FILE))?;
    for i in 0..plan.placements.len() {
        let dir = placement_dir(&a.trial, i);
        let names = frame_names(&dir)?;
        let marks = scripted_marks(&a.trial, &a.hidden, i, &cell)?;
        let labels = dir.join(LABELS_FILE);
        if labels.exists() {
            bail!("{}: exists: the scripted reviewer marks a placement not reviewed yet", labels.display());
        }
        for m in &marks {
            append_label(&dir, &names, m)?;
        }
        let correct = marks.iter().filter(|m| m.mark == camplace_sim::Mark::Correct).count();
        outln!("{}: {correct} of {} marked correct; wrote {}", dir.display(), marks.len(), labels.display());
    }
    Ok(ExitCode::SUCCESS)
}

pub(super) fn report(a: ReportArgs) -> anyhow::Result<ExitCode> {
    let cell = cell_of(&a.cell)?;
    let out = a.out.clone().unwrap_or_else(|| a.trial.clone());
    let r = trial_report(&a.trial, &cell, a.study.as_deref(), &out)?;
    for p in &r.placements {
        let real = p.real.map_or("-".to_string(), |x| {
            format!(
                "{:.1} % ({} of {}, {:.1}–{:.1} %)",
                100.0 * x.success_rate,
                x.successes,
                x.frames,
                100.0 * x.success_interval[0],
                100.0 * x.success_interval[1]
            )
        });
        let sim = p.simulated.map_or("-".to_string(), |x| {
            format!(
                "{:.1} % ({} of {}, {:.1}–{:.1} %)",
                100.0 * x.success_rate,
                x.successes,
                x.frames,
                100.0 * x.success_interval[0],
                100.0 * x.success_interval[1]
            )
        });
        let earlier = match p.marked_on_earlier_poses {
            0 => String::new(),
            n => format!(", {n} of them marked on earlier poses: mark again"),
        };
        let open = if p.unsure + p.not_judged > 0 {
            format!(" [{} unsure, {} not judged{earlier}]", p.unsure, p.not_judged)
        } else {
            String::new()
        };
        outln!(
            "{:03} {}: real {real}, simulated {sim}{}{open}",
            p.index,
            p.placement,
            if p.in_real_top_set { " (real top set)" } else { "" }
        );
    }
    outln!("{}", rho_text(&r.rank_correlation));
    outln!("{}", r.verdict_text());
    outln!("{}", r.paired_text());
    outln!("wrote {} and {}", out.join(REPORT_JSON).display(), out.join(REPORT_HTML).display());
    Ok(ExitCode::SUCCESS)
}
