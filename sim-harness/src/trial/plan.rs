//! The trial plan: the placements the real rig is carried to, in the order they are
//! visited (`plan.json`), and for a rig on a robot's flange the flange pose of each, as
//! the robot program reads it (`plan.csv`). Reading a plan back checks it whole.

use std::path::Path;

use camplace_config::{format_pose, write_atomic, Cell, LengthUnit, Placement, PoseConvention, RobotPoseFormat};
use camplace_estimator::{isometry_from_rows, isometry_to_rows};
use serde::{Deserialize, Serialize};

use crate::study::grid::Grid;
use crate::{Error, Result};
use camplace_estimator::sensor_rig;

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
    /// The plan of `placements` (with `grid` when they span one) for `cell`: flange poses
    /// when the cell's robot carries the rig.
    pub fn new(cell: &Cell, grid: Option<Grid>, placements: &[Placement]) -> Result<TrialPlan> {
        if placements.is_empty() {
            return Err(Error::Other("placements: expected at least one placement to visit".into()));
        }
        if placements.len() > MAX_PLACEMENTS {
            return Err(Error::Other(format!(
                "placements: {} placements; expected at most {MAX_PLACEMENTS}",
                placements.len()
            )));
        }
        let flange = cell.robot.as_ref().and_then(|r| r.t_flange_rig.map(|f| (r.t_robot_world, f)));
        let placements = placements
            .iter()
            .enumerate()
            .map(|(index, p)| PlannedPlacement {
                index,
                placement: p.to_string(),
                t_robot_flange: flange.map(|(robot_world, flange_rig)| {
                    // The rig's frame is its left camera's.
                    let world_rig = sensor_rig(cell, p).left.t_world_camera;
                    isometry_to_rows(
                        &(isometry_from_rows(&robot_world) * world_rig * isometry_from_rows(&flange_rig).inverse()),
                    )
                }),
            })
            .collect();
        Ok(TrialPlan { grid, placements })
    }

    /// Reads and checks `path`: at least one placement, numbered 0 … n−1 in order, each a
    /// valid placement, as many as the grid spans when it has one.
    pub fn load(path: &Path) -> Result<TrialPlan> {
        let text = camplace_config::read_text(path)?;
        let at = |key: &str, what: String| Error::Other(format!("{}: {key}: {what}", path.display()));
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
    pub fn save(&self, path: &Path) -> Result<std::path::PathBuf> {
        if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent).map_err(|e| camplace_config::Error::io(parent, &e))?;
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
                crate::trial::layout::placement_folder_name(e.index),
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
pub fn parse_placement(text: &str) -> std::result::Result<Placement, camplace_config::Error> {
    let p = Cell::default().placement;
    let p = Placement { azimuth: 0.0, ..p }.with_overrides(text)?;
    p.validate("placement")?;
    Ok(p)
}

#[cfg(test)]
mod tests {
    use super::*;
    use camplace_config::Robot;

    #[test]
    fn each_flange_pose_carries_the_rig_to_its_placement_and_reads_back() {
        let mut cell = Cell::default();
        let turn = nalgebra::Isometry3::new(
            nalgebra::Vector3::new(800.0, -120.0, 95.0),
            nalgebra::Vector3::new(0.1, -0.2, 1.3),
        );
        let flange_rig = nalgebra::Isometry3::new(
            nalgebra::Vector3::new(10.0, 55.0, 130.0),
            nalgebra::Vector3::new(0.3, 0.05, -0.4),
        );
        cell.robot = Some(Robot {
            t_robot_world: isometry_to_rows(&turn),
            t_flange_rig: Some(isometry_to_rows(&flange_rig)),
            pose_format: None,
        });
        let grid = Grid { x: "r=500:800:2".parse().unwrap(), y: "alpha=10:50:2".parse().unwrap() };
        let ps = grid.placements(&cell.placement).unwrap();
        let plan = TrialPlan::new(&cell, Some(grid), &ps).unwrap();
        for (i, p) in ps.iter().enumerate() {
            // The flange pose then the rig on it: the rig where the placement puts it.
            let flange = isometry_from_rows(&plan.placements[i].t_robot_flange.unwrap());
            let rig = turn.inverse() * flange * flange_rig;
            let want = sensor_rig(&cell, p).left.t_world_camera;
            assert!((rig.translation.vector - want.translation.vector).norm() < 1e-9);
            assert!(rig.rotation.angle_to(&want.rotation) < 1e-12);
        }
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t").join(PLAN_FILE);
        plan.save(&path).unwrap();
        assert_eq!(TrialPlan::load(&path).unwrap(), plan);
        let csv = std::fs::read_to_string(dir.path().join("t").join(PLAN_CSV)).unwrap();
        assert_eq!(csv.lines().count(), 5);
        assert_eq!(csv.lines().nth(1).unwrap().split(',').count(), 13);
        std::fs::write(&path, "{\"placements\": []}").unwrap();
        let e = TrialPlan::load(&path).unwrap_err().to_string();
        assert!(e.contains("placements") && e.contains(PLAN_FILE), "{e}");
    }
}
