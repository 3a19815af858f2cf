//! The trial plan's files: the placements the real rig is carried to, in the order they are
//! visited (`plan.json`), and for a rig on a robot's flange the flange pose of each, as the
//! robot program reads it (`plan.csv`); a trial folder's `NNN/` per placement. Reading a
//! plan back checks it whole. The simulator makes plans (the flange poses need the rig's
//! geometry); `capture --trial` and the trial's other steps read them.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::{format_pose, write_atomic, Cell, LengthUnit, Placement, PoseConvention, RobotPoseFormat};
use crate::{Error, Grid};

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
    /// Reads and checks `path`: at least one placement, numbered 0 … n−1 in order, each a
    /// valid placement, as many as the grid spans when it has one.
    pub fn load(path: &Path) -> Result<TrialPlan> {
        let text = crate::read_text(path)?;
        let at = |key: &str, what: String| Error::value(key, what).in_file(path);
        let plan: TrialPlan = serde_json::from_str(&text)
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
        }
        if let Some(g) = &plan.grid {
            if g.x.steps * g.y.steps != plan.placements.len() {
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
        write_atomic(path, format!("{json}\n").as_bytes())?;
        let csv = path.with_file_name(PLAN_CSV);
        write_atomic(&csv, self.csv().as_bytes())?;
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
