//! The slots a robot picks from, end to end: `serve`'s `slots=` letters and `SLOT n` frames
//! against `replay`'s records and the composition of the tray's pose with the model's slot
//! poses in every pose convention, the states against the rendered truth, and a tilted item
//! and a foreign box flagged askew in rendered scenes.

use std::path::Path;

use camplace_config::{parse_pose, Cell, LengthUnit, PoseConvention, RobotPoseFormat, TruthFile};
use camplace_estimator::{
    geometry::isometry_from_rows, pose::pose_errors, pose::SlotState, Estimator, EstimatorConfig, Model,
};
use camplace_sim::{background_scene, draw_scenario, noise_key, Frame, Method, Simulator};
use nalgebra::{Translation3, UnitQuaternion, Vector3};

use crate::deploy::{fixture, OPTIMUM};
use crate::served::{ask, parse_reply, replayed_dataset, Served};

/// `[robot] T_robot_world` of the robot these tests speak for: turned a quarter about z and
/// standing off the world's origin.
const T_ROBOT_WORLD: [[f64; 4]; 4] =
    [[0.0, -1.0, 0.0, 450.0], [1.0, 0.0, 0.0, -120.0], [0.0, 0.0, 1.0, 35.0], [0.0, 0.0, 0.0, 1.0]];

fn robot_cell(dir: &Path, name: &str, format: RobotPoseFormat) {
    let rows: Vec<String> = T_ROBOT_WORLD.iter().map(|r| format!("{r:?}")).collect();
    let text = format!("[robot]\nT_robot_world = [{}]\npose_format = \"{format}\"\n", rows.join(", "));
    std::fs::write(dir.join(name), text).unwrap();
}

/// Every trigger's `slots=` is replay's states letter for letter, and `SLOT n` gives
/// `T_robot_world · T_world_tray · T_tray_slot` (the model's slot pose) in every convention
/// to 1e-9; the states of the accepted poses match the rendered truth's filled slots.
#[test]
fn serve_gives_each_slots_state_and_frame_in_every_convention() {
    let f = fixture();
    let dir = tempfile::tempdir().unwrap();
    for entry in ["data", "tray.model"] {
        let o = std::process::Command::new("cp").arg("-r").arg(f.root.join(entry)).arg(dir.path()).output().unwrap();
        assert!(o.status.success());
    }
    let model = Model::from_bytes(&std::fs::read(dir.path().join("tray.model")).unwrap()).unwrap();
    let layout = model.slots.clone().expect("a model built now carries its slots");
    assert_eq!(layout.slots.len(), 8, "tray-8");
    robot_cell(dir.path(), "robot.toml", RobotPoseFormat { convention: PoseConvention::Matrix, unit: LengthUnit::Mm });
    let replay = replayed_dataset(dir.path(), "data", &["--cell", "robot.toml"]);
    let (mut judged, mut wrong, mut compared) = (0, 0, 0);
    for (name, record) in &replay {
        if !record.accepted() {
            continue;
        }
        let truth = TruthFile::load(&dir.path().join("data/frames").join(name).join("truth.json")).unwrap();
        for (n, slot) in record.slots.as_ref().expect("an accepted pose's slots").iter().enumerate() {
            judged += 1;
            let filled = truth.filled.contains(&n);
            match slot.state.as_str() {
                "filled" => wrong += usize::from(!filled),
                "empty" => wrong += usize::from(filled),
                _ => {}
            }
        }
    }
    assert!(judged >= 8, "no accepted pose to judge slots under");
    assert_eq!(wrong, 0, "{wrong} wrong filled/empty calls of {judged} slots");

    for (k, convention) in PoseConvention::ALL.into_iter().enumerate() {
        let unit = if k % 2 == 0 { LengthUnit::Mm } else { LengthUnit::M };
        let format = RobotPoseFormat { convention, unit };
        let cell = format!("robot-{k}.toml");
        robot_cell(dir.path(), &cell, format);
        let served = Served::start(
            dir.path(),
            &["--source", "dir:data", "--model", "tray.model", "--cell", &cell],
            &format!("slots-{k}.log"),
            false,
        );
        let mut robot = served.connect();
        for i in 0..replay.len() {
            let line = ask(&mut robot, &format!("TRIGGER s{i}"));
            let (status, _, fields) = parse_reply(&line);
            let want = &replay[&fields["frame"]];
            if status != "OK" {
                assert!(!fields.contains_key("slots"), "{line}");
                assert_eq!(ask(&mut robot, "SLOT 0"), "NO_POSE slot=0");
                continue;
            }
            let slots = want.slots.as_ref().unwrap();
            let letters: String = slots
                .iter()
                .map(|s| match (s.state.as_str(), s.askew) {
                    ("filled", false) => 'F',
                    ("filled", true) => 'A',
                    ("empty", _) => 'E',
                    _ => '?',
                })
                .collect();
            assert_eq!(fields["slots"], letters, "{line}");
            let t_robot_tray = isometry_from_rows(&want.t_robot_tray.unwrap());
            for (n, slot) in slots.iter().enumerate() {
                let reply = ask(&mut robot, &format!("SLOT {n}"));
                let (status, _, f) = parse_reply(&reply);
                assert_eq!(status, "OK", "{reply}");
                assert_eq!((f["slot"].as_str(), f["state"].as_str()), (n.to_string().as_str(), slot.state.as_str()));
                assert_eq!(f["frame"], fields["frame"], "{reply}");
                let got = parse_pose(&f["pose"], format).unwrap_or_else(|e| panic!("{format}: {reply}: {e}"));
                let composed = (t_robot_tray * layout.slot_pose(n).unwrap()).to_homogeneous();
                for r in 0..4 {
                    for c in 0..4 {
                        assert!(
                            (got[r][c] - composed[(r, c)]).abs() <= 1e-9,
                            "{format} slot {n} [{r}][{c}]: {reply} vs {composed}"
                        );
                    }
                }
                if let Some(t) = slot.t_robot_slot {
                    assert!((0..4).all(|r| (0..4).all(|c| (t[r][c] - composed[(r, c)]).abs() <= 1e-9)));
                }
                compared += 1;
            }
            assert_eq!(parse_reply(&ask(&mut robot, "SLOT 8")).1.as_deref(), Some("no-such-slot"));
        }
        served.stop();
    }
    assert!(compared >= 7 * 8, "{compared} slot frames compared");
}

/// A box item tilted 20° about its y axis (resting on one bottom edge, leaning on the slot's
/// divider) and a foreign box of another size (20 x 20 x 14 mm) stand in two slots of a
/// full tray: under every pose found within the success limits both are filled and askew,
/// the upright items filled and not askew. The slots are judged under every pose found,
/// and the test is of them, not of the fixture's threshold (measured on 40 scenes of
/// random fills: a full tray's items hide more of it, and it scores at their low end).
#[test]
fn a_tilted_item_and_a_foreign_box_are_flagged_askew() {
    let f = fixture();
    let cell = Cell::default();
    let placement = cell.placement.with_overrides(OPTIMUM).unwrap();
    let seed = 1;
    let model = Model::from_bytes(&std::fs::read(f.root.join("tray.model")).unwrap()).unwrap();
    let mut sim = Simulator::new(&cell, &placement, seed).unwrap();
    let [x, _, z] = cell.items.size;
    // Turned 20° about the item's -x bottom edge, so that edge stays on the floor and the
    // +x side rises.
    let edge = Vector3::new(-x / 2.0, 0.0, 0.0);
    let about_edge = Translation3::from(edge)
        * UnitQuaternion::from_axis_angle(&Vector3::y_axis(), -20f64.to_radians())
        * Translation3::from(-edge);
    let mut tilted = sim.objects().item.clone();
    for t in &mut tilted.triangles {
        *t = t.map(|p| about_edge * p);
    }
    // The cell's box scaled to 20 x 20 x 14 mm.
    let mut foreign = sim.objects().item.clone();
    for t in &mut foreign.triangles {
        *t = t.map(|p| nalgebra::Point3::new(p.x * 20.0 / x, p.y * 20.0 / x, p.z * 14.0 / z));
    }
    sim.objects_mut().odd_items = vec![(2, tilted), (5, foreign)];
    let mut frame = Frame::default();
    sim.render(&background_scene(&cell, seed), Method::OneShot, noise_key(seed, 0, true), &mut frame);
    let mut estimator = Estimator::new(&EstimatorConfig::from(&cell), sim.rig(), model, Method::OneShot).unwrap();
    estimator.set_background(&frame.shots.left, &frame.shots.right).unwrap();
    let mut judged = 0;
    for index in 0..6 {
        let mut scene = draw_scenario(&cell, seed, index).scene();
        scene.filled = (0..8).collect();
        sim.render(&scene, Method::OneShot, noise_key(seed, 1000 + index, false), &mut frame);
        let pose = estimator.process(&frame.shots.left, &frame.shots.right).unwrap();
        let errors =
            pose_errors(&pose.t_world_tray, &scene.t_world_tray, &estimator.model().symmetries_deg, &cell.metrics);
        eprintln!("scene {index}: {} ({:.2} mm)", pose.verification.verdict, errors.position_mm);
        if !(pose.found && errors.success) {
            continue;
        }
        judged += 1;
        let slots = estimator.slots();
        for (n, r) in slots.iter().enumerate() {
            let askew = n == 2 || n == 5;
            assert!(r.state != SlotState::Empty, "scene {index} slot {n}: {r:?}");
            if r.state == SlotState::Filled {
                assert_eq!(r.askew, askew, "scene {index} slot {n}: {r:?}");
            }
        }
        assert!(
            slots[2].state == SlotState::Filled && slots[5].state == SlotState::Filled,
            "scene {index}: {:?} {:?}",
            slots[2],
            slots[5]
        );
    }
    assert!(judged >= 5, "{judged} poses of 6 scenes within the success limits");
}
