//! Making a trial plan (config's `TrialPlan`): the placements to visit and, for a rig on a
//! robot's flange, the flange pose that carries the rig to each.

use camplace_config::{Cell, Grid, Placement, PlannedPlacement, TrialPlan, MAX_PLACEMENTS};
use camplace_estimator::{geometry::isometry_from_rows, geometry::isometry_to_rows, geometry::sensor_rig};

use crate::{Error, Result};

/// The trial plan of `placements` (with `grid` when they span one) for `cell`: flange
/// poses when the cell's robot carries the rig.
pub fn make_plan(cell: &Cell, grid: Option<Grid>, placements: &[Placement]) -> Result<TrialPlan> {
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

#[cfg(test)]
mod tests {
    use super::*;
    use camplace_config::{Robot, PLAN_CSV, PLAN_FILE};
    use camplace_estimator::geometry::isometry_from_rows;

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
        let plan = make_plan(&cell, Some(grid), &ps).unwrap();
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
