//! The trial plan's files: the placements the real rig is carried to, in the order they are
//! visited (`plan.json`), and for a rig on a robot's flange the flange pose of each, as the
//! robot program reads it (`plan.csv`); a trial folder's `NNN/` per placement. Reading a
//! plan back checks it whole. The simulator makes plans (the flange poses need the rig's
//! geometry); `capture --trial` and the trial's other steps read them.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::{format_pose, write_atomic_all, Cell, LengthUnit, Placement, PoseConvention, RobotPoseFormat};
use crate::{Error, Grid, MAX_AXIS_STEPS};

type Result<T> = std::result::Result<T, Error>;

/// The plan's file name inside a trial folder.
pub const PLAN_FILE: &str = "plan.json";
/// The robot program's table beside the plan.
pub const PLAN_CSV: &str = "plan.csv";
/// The most placements one trial may visit (a 100 × 100 grid).
pub const MAX_PLACEMENTS: usize = 10_000;

/// One placement to visit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlannedPlacement {
    /// Its number, 0 … n−1: the trial folder `NNN/` it is captured into.
    pub index: usize,
    /// The placement as written (`r=605,alpha=32,...`).
    pub placement: String,
    /// Where the robot's flange goes so that the rig sits at the placement (base ← flange,
    /// row-major 4 × 4, mm); only for a cell whose `[robot]` has `T_flange_rig`.
    #[serde(rename = "T_robot_flange", default, skip_serializing_if = "Option::is_none")]
    pub t_robot_flange: Option<[[f64; 4]; 4]>,
}

/// The placements of a trial and, when they span a grid, the grid (for the maps).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrialPlan {
    /// The grid the placements span, x fastest, when they come from one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub grid: Option<Grid>,
    /// The placements in visiting order.
    pub placements: Vec<PlannedPlacement>,
}

impl TrialPlan {
    /// Reads and checks `path` (see [`TrialPlan::from_json`]).
    pub fn load(path: &Path) -> Result<TrialPlan> {
        let text = crate::read_text(path)?;
        Self::from_json(&text).map_err(|e| e.in_file(path))
    }

    /// Parses and checks a plan's JSON text: at least one placement, numbered 0 … n−1 in
    /// order, each a valid placement, as many as the grid spans when it has one.
    pub fn from_json(text: &str) -> Result<TrialPlan> {
        let at = |key: &str, what: String| Error::value(key, what);
        let plan: TrialPlan = serde_json::from_str(text)
            .map_err(|e| at("plan", format!("expected a trial plan (camplace trial plan writes one): {e}")))?;
        if plan.placements.is_empty() {
            return Err(at("placements", "expected at least one placement to visit, found none".into()));
        }
        if plan.placements.len() > MAX_PLACEMENTS {
            return Err(at("placements", format!("expected at most {MAX_PLACEMENTS} placements")));
        }
        for (i, p) in plan.placements.iter().enumerate() {
            if p.index != i {
                return Err(at(&format!("placements[{i}].index"), format!("expected {i}, found {}", p.index)));
            }
            parse_placement(&p.placement)
                .map_err(|e| at(&format!("placements[{i}].placement"), format!("expected a placement: {e}")))?;
            if let Some(t) = &p.t_robot_flange {
                crate::check_rigid(t).map_err(|m| at(&format!("placements[{i}].T_robot_flange"), m))?;
            }
        }
        if let Some(g) = &plan.grid {
            for (key, a) in [("grid.x", &g.x), ("grid.y", &g.y)] {
                if !(a.lo.is_finite() && a.hi.is_finite() && (1..=MAX_AXIS_STEPS).contains(&a.steps)) {
                    let what =
                        format!("expected an axis from a finite lo to a finite hi in 1 to {MAX_AXIS_STEPS} steps");
                    return Err(at(key, what));
                }
            }
            if g.x.name == g.y.name {
                return Err(at("grid.y", format!("expected another parameter than grid.x's ({})", g.x.name)));
            }
            if g.x.steps.checked_mul(g.y.steps) != Some(plan.placements.len()) {
                return Err(at(
                    "grid",
                    format!(
                        "spans {} × {} placements, but the plan lists {}",
                        g.x.steps,
                        g.y.steps,
                        plan.placements.len()
                    ),
                ));
            }
        }
        Ok(plan)
    }

    /// The placement of entry `i` (checked on load).
    pub fn placement(&self, i: usize) -> Placement {
        parse_placement(&self.placements[i].placement).expect("checked when the plan was made or read")
    }

    /// Writes `plan.json` to `path` and `plan.csv` beside it; returns the CSV's path.
    pub fn save(&self, path: &Path) -> Result<PathBuf> {
        if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent).map_err(|e| Error::io(parent, &e))?;
        }
        let json = serde_json::to_string_pretty(self).expect("a plan is plain data");
        let csv = path.with_file_name(PLAN_CSV);
        // Both or neither: a plan.json beside another plan's table would drive the robot wrong.
        write_atomic_all(&[(path, format!("{json}\n").as_bytes()), (&csv, self.csv().as_bytes())])?;
        Ok(csv)
    }

    /// The robot program's table: one row per placement, its parameters and, for a rig on
    /// the flange, the flange pose as KUKA's X Y Z A B C (mm, deg).
    pub fn csv(&self) -> String {
        let kuka = RobotPoseFormat { convention: PoseConvention::Kuka, unit: LengthUnit::Mm };
        let mut text =
            String::from("index,folder,r,alpha,baseline,vergence,azimuth,x_mm,y_mm,z_mm,a_deg,b_deg,c_deg\n");
        for (i, e) in self.placements.iter().enumerate() {
            let p = self.placement(i);
            let pose = e
                .t_robot_flange
                .map(|t| format_pose(&t, kuka).split(' ').collect::<Vec<_>>().join(","))
                .unwrap_or_else(|| ",,,,,".to_string());
            text.push_str(&format!(
                "{},{},{},{},{},{},{},{pose}\n",
                e.index,
                placement_folder_name(e.index),
                p.r,
                p.alpha,
                p.baseline,
                p.vergence,
                p.azimuth
            ));
        }
        text
    }
}

/// A placement as a plan writes it (every parameter named; the azimuth when not 0).
pub fn parse_placement(text: &str) -> Result<Placement> {
    let p = Cell::default().placement;
    let p = Placement { azimuth: 0.0, ..p }.with_overrides(text)?;
    p.validate("placement")?;
    Ok(p)
}

/// The folder name of placement `index`: three digits (more when the plan needs them).
pub fn placement_folder_name(index: usize) -> String {
    format!("{index:03}")
}

/// The dataset folder of placement `index` in trial `dir`.
pub fn placement_dir(dir: &Path, index: usize) -> PathBuf {
    dir.join(placement_folder_name(index))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plan() -> TrialPlan {
        let turn = [[0.0, -1.0, 0.0, 400.0], [1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 900.0], [0.0, 0.0, 0.0, 1.0]];
        let placements = ["r=605,alpha=32,baseline=81,vergence=3.5", "r=800,alpha=45,baseline=81,vergence=3.5"]
            .iter()
            .enumerate()
            .map(|(index, p)| PlannedPlacement { index, placement: p.to_string(), t_robot_flange: Some(turn) })
            .collect();
        TrialPlan { grid: None, placements }
    }

    fn json(plan: &TrialPlan) -> String {
        serde_json::to_string_pretty(plan).unwrap()
    }

    #[test]
    fn a_plan_reads_back_as_written() {
        let p = plan();
        assert_eq!(TrialPlan::from_json(&json(&p)).unwrap(), p);
        let grid: Grid = serde_json::from_str(
            r#"{"x": {"name": "r", "lo": 605, "hi": 800, "steps": 2}, "y": {"name": "alpha", "lo": 32, "hi": 32, "steps": 1}}"#,
        )
        .unwrap();
        let gridded = TrialPlan { grid: Some(grid), ..p };
        assert_eq!(TrialPlan::from_json(&json(&gridded)).unwrap(), gridded);
    }

    #[test]
    fn a_hostile_plan_is_refused_naming_the_key() {
        // The grid written into the text as it stands: a number past what a float holds too.
        let grid = |x: &str, y: &str| json(&plan()).replacen('{', &format!(r#"{{"grid": {{"x": {x}, "y": {y}}},"#), 1);
        let axis = |name: &str, lo: &str, steps: &str| {
            format!(r#"{{"name": "{name}", "lo": {lo}, "hi": 800, "steps": {steps}}}"#)
        };
        let edited = |f: &dyn Fn(&mut TrialPlan)| {
            let mut p = plan();
            f(&mut p);
            json(&p)
        };
        let cases: Vec<(String, &str)> = vec![
            ("[]".into(), "plan"),
            (r#"{"placements": []}"#.into(), "placements"),
            (edited(&|p| p.placements[1].index = 5), "placements[1].index"),
            (edited(&|p| p.placements[0].placement = "r=-3".into()), "placements[0].placement"),
            (edited(&|p| p.placements[1].t_robot_flange.as_mut().unwrap()[0][0] = 2.0), "placements[1].T_robot_flange"),
            // Steps whose product overflows a usize, and one past the axis limit.
            (grid(&axis("r", "605", &usize::MAX.to_string()), &axis("alpha", "0", "2")), "grid.x"),
            (grid(&axis("r", "605", "2"), &axis("alpha", "1e400", "1")), "plan"),
            (grid(&axis("r", "605", "2"), &axis("alpha", "0", "0")), "grid.y"),
            (grid(&axis("r", "605", "2"), &axis("r", "0", "1")), "grid.y"),
            (grid(&axis("r", "605", "2"), &axis("alpha", "0", "2")), "grid"),
        ];
        for (text, key) in cases {
            let e = TrialPlan::from_json(&text).expect_err(&text);
            assert_eq!(e.key(), key, "{text}: {e}");
        }
    }
}
