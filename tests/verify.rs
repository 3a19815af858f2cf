//! The verification end to end on rendered frames: frames without the tray, another tray
//! under this tray's model and the tray half out of view are each rejected with a reason,
//! while the tray in plain view is accepted, and the camera's depth shows no view past the
//! true pose but one past the truth moved by a slot's pitch; for the built-in 8-slot tray
//! and for a mesh tray of the test's own. A tray turned so that its tab stands behind its
//! own far wall is found the right way round and its half turn rejected, the see-through
//! evidence of the tab against the rendered scene's true depth; a tray whose symmetries
//! list the half turn has it accepted. A quarter turn reaching past the box a one-shot frame
//! was matched in is judged on the background's depth as on the whole image's, a turn that
//! neither the scene's points nor its depth tell from the pose leaves the pose ambiguous,
//! and a frame's verification is its pose's weighed afresh.

use camplace_config::{Cell, TrayKind};
use camplace_estimator::pose::{
    see_through, tray_points, Alternative, DepthEvidence, Verdict, AMBIGUOUS_TURN_SIGMAS, OCCLUDED_MARGIN_MM,
    SEE_THROUGH_MARGIN_MM, SEE_THROUGH_MIN_TESTED,
};
use camplace_estimator::{Estimator, EstimatorConfig, Model, PoseEstimate};
use camplace_sim::{
    background_scene, build_model, draw_scenario, hard_negatives, noise_key, weigh_negatives, Frame, Method, SceneSpec,
    Simulator,
};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};

use crate::meshes::tray_stl;

const OPTIMUM: &str = "r=605,alpha=32,baseline=81,vergence=3.5";

/// The default cell's tray-8 model at the optimum, an estimator with the background set and
/// the simulator it was captured with.
fn setup(cell: &Cell, seed: u64) -> (Simulator, Estimator) {
    let placement = cell.placement.with_overrides(OPTIMUM).unwrap();
    let model = build_model(cell, &placement, Method::OneShot, seed).unwrap();
    let mut sim = Simulator::new(cell, &placement, seed).unwrap();
    let mut frame = Frame::default();
    sim.render(&background_scene(cell, seed), Method::OneShot, noise_key(seed, 0, true), &mut frame);
    let mut estimator = Estimator::new(&EstimatorConfig::from(cell), sim.rig(), model, Method::OneShot).unwrap();
    estimator.set_background(&frame.shots.left, &frame.shots.right).unwrap();
    (sim, estimator)
}

/// The offset, tray frame, from the first slot to its nearest neighbour.
fn slot_pitch(model: &Model) -> Vector3<f64> {
    let slots = &model.slots.as_ref().expect("a model built now carries its slots").slots;
    let at = |s: &[f64; 4]| Vector3::new(s[0], s[1], 0.0);
    slots[1..].iter().map(|s| at(s) - at(&slots[0])).min_by(|a, b| a.norm().total_cmp(&b.norm())).expect("two slots")
}

fn rejected(pose: &PoseEstimate, what: &str) {
    let v = pose.verification;
    assert!(!v.verdict.accepted(), "{what}: accepted with score {} ({v:?})", v.score);
    assert!(v.verdict.as_str().starts_with("rejected: "), "{what}: {}", v.verdict);
    eprintln!("{what}: {} (score {:.3}, coverage {:.3}, explained {:.3})", v.verdict, v.score, v.coverage, v.explained);
}

/// Renders `cell`'s tray in plain view (at least 3 of 4 accepted), the empty cell, the tray
/// with its origin at the image's border and `other`'s tray under `cell`'s model: each of
/// the last three rejected.
fn rejections(cell: &Cell, other: &Cell, other_name: &str) {
    let seed = 2;
    let (mut sim, mut estimator) = setup(cell, seed);
    let threshold = estimator.verifier().threshold;
    let mut frame = Frame::default();

    // The tray in plain view: accepted, so the rejections below are the verification's
    // judgement and not a verifier that rejects everything.
    let mut accepted = 0;
    let pitch = slot_pitch(estimator.model());
    for i in 0..4 {
        let scenario = draw_scenario(cell, seed, i);
        sim.render(&scenario.scene(), Method::OneShot, noise_key(seed, i, false), &mut frame);
        let pose = estimator.process(&frame.shots.left, &frame.shots.right).unwrap();
        eprintln!("tray in view {i}: {} (score {:.3})", pose.verification.verdict, pose.verification.score);
        accepted += usize::from(pose.verification.verdict.accepted());
        // The camera's depth against the true pose and against the truth moved by one slot's
        // pitch, which lies on the same slots and dividers but puts an end wall over the table.
        let truth = estimator.verify(&scenario.t_world_tray);
        let shifted = estimator.verify(&(scenario.t_world_tray * Translation3::from(pitch)));
        eprintln!(
            "scene {i}: seen past {:.3} at the truth ({:.3} a pitch away), {:.3} one slot's pitch off ({:.3} a pitch away)",
            truth.see_through.share(),
            truth.see_through_shifted.share(),
            shifted.see_through.share(),
            shifted.see_through_shifted.share()
        );
        assert!(truth.see_through.tested >= SEE_THROUGH_MIN_TESTED, "scene {i}: {truth:?}");
        assert!(!truth.seen_past(), "scene {i}: the true pose seen past: {truth:?}");
        assert!(shifted.seen_past(), "scene {i}: the truth moved by {pitch:?} not seen past: {shifted:?}");
        if shifted.score >= threshold && shifted.rests_on_table() {
            assert_eq!(shifted.verdict, Verdict::SeenThrough, "scene {i}: the truth moved by {pitch:?}: {shifted:?}");
        }
    }
    assert!(accepted >= 3, "{accepted} of 4 trays in plain view accepted at threshold {threshold}");

    // The empty cell, under each of three scenarios' light.
    for i in 1..4 {
        let empty = draw_scenario(cell, seed, i).scene().background();
        sim.render(&empty, Method::OneShot, noise_key(seed, i, true), &mut frame);
        let pose = estimator.process(&frame.shots.left, &frame.shots.right).unwrap();
        rejected(&pose, &format!("empty cell {i}"));
    }

    // Half the tray out of view: moved along world y until its origin projects onto the
    // left image's border, so about half of it lies outside the image.
    let scenario = draw_scenario(cell, seed, 1);
    let left = &sim.rig().left;
    let (width, height) = (left.width as f64, left.height as f64);
    let outside = |dy: f64| {
        let p = scenario.t_world_tray.translation.vector + nalgebra::Vector3::new(0.0, dy, 0.0);
        left.project(&Point3::from(p)).is_none_or(|uv| uv.x <= 0.0 || uv.x >= width || uv.y <= 0.0 || uv.y >= height)
    };
    let edge_shift = (0..2000).map(f64::from).find(|&dy| outside(dy)).expect("the tray leaves the image along y");
    let mut half = scenario.scene();
    half.t_world_tray = Translation3::new(0.0, edge_shift, 0.0) * half.t_world_tray;
    sim.render(&half, Method::OneShot, noise_key(seed, 1, false), &mut frame);
    let pose = estimator.process(&frame.shots.left, &frame.shots.right).unwrap();
    rejected(&pose, &format!("tray moved {edge_shift} mm along y, half out of view"));

    // The other tray under this tray's model, in four scenarios' poses.
    let placement = other.placement.with_overrides(OPTIMUM).unwrap();
    let mut other_sim = Simulator::new(other, &placement, seed).unwrap();
    for i in 0..4 {
        let scene = draw_scenario(other, seed, i).scene();
        other_sim.render(&scene, Method::OneShot, noise_key(seed, i, false), &mut frame);
        let pose = estimator.process(&frame.shots.left, &frame.shots.right).unwrap();
        rejected(&pose, &format!("{other_name} scene {i} under this tray's model"));
    }
}

#[test]
fn without_the_tray_the_four_slot_tray_and_half_a_tray_are_rejected() {
    let cell = Cell::default();
    let mut other = cell.clone();
    other.tray.kind = TrayKind::Tray4;
    rejections(&cell, &other, "tray-4");
}

/// A mesh tray of this test's own (an open box with a tab, items in four slots), and the
/// built-in 8-slot tray under its model.
#[test]
fn the_same_holds_for_a_mesh_tray() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("own.stl"), tray_stl(200.0, 140.0, 6.0, 8.0, 28.0)).unwrap();
    let text = "[tray]\nkind = \"mesh\"\nmesh = \"own.stl\"\n\
                slots = [[-45.0, -30.0, 6.0, 0.0], [45.0, -30.0, 6.0, 0.0], [-45.0, 30.0, 6.0, 0.0], [45.0, 30.0, 6.0, 0.0]]\n";
    let cell = Cell::from_toml_str(text, dir.path()).unwrap();
    rejections(&cell, &Cell::default(), "tray-8");
}

/// Scenario `i` of `seed` rendered without its occluder, one shot, and processed by
/// `estimator`: the scene, for its truth.
fn processed_without_occluder(
    cell: &Cell,
    seed: u64,
    i: u64,
    sim: &mut Simulator,
    estimator: &mut Estimator,
    frame: &mut Frame,
) -> SceneSpec {
    let mut scene = draw_scenario(cell, seed, i).scene();
    scene.occluder = None;
    sim.render(&scene, Method::OneShot, noise_key(seed, i, false), frame);
    estimator.process(&frame.shots.left, &frame.shots.right).unwrap();
    scene
}

/// The half turn about the tray's z axis.
fn half_turn() -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::identity(),
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::PI),
    )
}

/// Scenarios of `cell` with the tray turned so that its +x side (the tab's) faces away from
/// the camera, without the occluder: the tab stands behind the tray's far wall. Each frame:
/// the share of the tab's points `tab` (tray frame) the rendered scene hides (its true depth
/// in front of them), the pose found, and the truth and its half turn verified, their
/// see-through shares set against the same count on the rendered scene's true depth. In
/// frames that hide at least 60 % of the tab the half turn must be rejected as seen
/// through and the pose found must be the right way round.
fn hidden_tab(cell: &Cell, tab: &[Point3<f64>]) {
    let seed = 3;
    let (mut sim, mut estimator) = setup(cell, seed);
    let sensor = estimator.sensor_position().cast::<f64>();
    let mut frame = Frame::default();
    let mut hidden_scenes = 0;
    for i in 0..6 {
        let scenario = draw_scenario(cell, seed, i);
        let mut scene = scenario.scene();
        scene.occluder = None;
        let t = scene.t_world_tray.translation.vector;
        let yaw = (t.y - sensor.y).atan2(t.x - sensor.x);
        scene.t_world_tray = Isometry3::new(t, Vector3::z() * yaw);
        sim.render(&scene, Method::OneShot, noise_key(seed, i, false), &mut frame);
        // The tab's share the rendered scene hides: its true depth more than 3 mm in front.
        let left = &sim.rig().left;
        let hidden = tab
            .iter()
            .filter(|m| {
                let world = scene.t_world_tray * *m;
                let z = left.t_world_camera.inverse_transform_point(&world).z;
                left.project(&world).is_none_or(|uv| {
                    let (u, v) = (uv.x.round() as usize, uv.y.round() as usize);
                    u >= frame.depth_left.width
                        || v >= frame.depth_left.height
                        || f64::from(frame.depth_left.row(v)[u]) < z - 3.0
                })
            })
            .count() as f64
            / tab.len() as f64;
        // The tray's half-turn parts at the truth and at its half turn against the rendered
        // scene's true depth (the renderer's ray cast), as the verification counts them
        // against the measured depth: facing the sensor, the nearest surface within two
        // pixels more than the see-through margin behind.
        let parts = &estimator.verifier().turn_parts.parts[1];
        let true_share = |pose: &Isometry3<f64>| {
            let (mut tested, mut past) = (0, 0);
            let eye = pose.inverse() * sensor;
            for (m, n) in parts.0.iter().zip(&parts.1) {
                let (m, n) = (m.cast::<f64>(), n.cast::<f64>());
                if n.dot(&(eye - m)) <= 0.0 {
                    continue;
                }
                let world = pose * m;
                let z = left.t_world_camera.inverse_transform_point(&world).z;
                let Some(uv) = left.project(&world) else { continue };
                let (u, v) = (uv.x.round() as isize, uv.y.round() as isize);
                let mut nearest = f64::INFINITY;
                for y in (v - 2).max(0)..=(v + 2).min(frame.depth_left.height as isize - 1) {
                    for x in (u - 2).max(0)..=(u + 2).min(frame.depth_left.width as isize - 1) {
                        nearest = nearest.min(f64::from(frame.depth_left.row(y as usize)[x as usize]));
                    }
                }
                if nearest.is_finite() {
                    tested += 1;
                    past += usize::from(nearest > z + f64::from(SEE_THROUGH_MARGIN_MM));
                }
            }
            past as f64 / tested.max(1) as f64
        };
        let truth_true = true_share(&scene.t_world_tray);
        let turned_true = true_share(&(scene.t_world_tray * half_turn()));
        let pose = estimator.process(&frame.shots.left, &frame.shots.right).unwrap();
        let truth = estimator.verify(&scene.t_world_tray);
        let turned = estimator.verify(&(scene.t_world_tray * half_turn()));
        let rotation = (pose.t_world_tray.rotation.inverse() * scene.t_world_tray.rotation).angle().to_degrees();
        eprintln!(
            "scene {i}: tab {:.0} % hidden; found {} ({:.1} deg off the truth); truth: tab parts seen past {:.3} \
             of {} (true depth {truth_true:.3}), the turn's {:.3} of {} ({}); half turn: {:.3} of {} (true depth \
             {turned_true:.3}), the truth's {:.3} of {} ({})",
            100.0 * hidden,
            pose.verification.verdict,
            rotation,
            truth.turn_see_through.share(),
            truth.turn_see_through.tested,
            truth.turn_see_through_other.share(),
            truth.turn_see_through_other.tested,
            truth.verdict,
            turned.turn_see_through.share(),
            turned.turn_see_through.tested,
            turned.turn_see_through_other.share(),
            turned.turn_see_through_other.tested,
            turned.verdict
        );
        // The measured depth tells what the true depth does.
        for (what, v, t) in [("truth", &truth, truth_true), ("half turn", &turned, turned_true)] {
            let measured = f64::from(v.turn_see_through.share());
            assert!(
                (measured - t).abs() <= 0.1,
                "scene {i}, {what}: seen past {measured:.3}, by the true depth {t:.3}"
            );
        }
        if hidden < 0.6 {
            continue;
        }
        hidden_scenes += 1;
        // The camera saw the table where the half turn puts the tab, and nothing says the
        // truth is turned.
        assert!(turned.turned_wrong_way(), "scene {i}: the half turn not seen past: {turned:?}");
        assert_eq!(turned.verdict, Verdict::SeenThrough, "scene {i}: the half turn: {turned:?}");
        assert!(!truth.turned_wrong_way(), "scene {i}: the truth taken for turned: {truth:?}");
        if pose.found {
            assert!(rotation < 5.0, "scene {i}: the pose found is {rotation:.1} deg off the truth: {pose:?}");
        }
    }
    assert!(hidden_scenes >= 3, "only {hidden_scenes} of 6 scenes hide most of the tab: the test shows nothing");
}

/// Points on the built-in 8-slot tray's tab (its top and outer face), tray frame: 12 mm out
/// of the +x wall at x = 100, 40 mm wide, 15 mm high.
fn builtin_tab() -> Vec<Point3<f64>> {
    grid_on_tab(100.0, 12.0, 40.0, 15.0)
}

/// Points on a box tab from `hx` to `hx + tx`, `ty` wide, `tz` high: its top and outer face.
fn grid_on_tab(hx: f64, tx: f64, ty: f64, tz: f64) -> Vec<Point3<f64>> {
    let mut out = Vec::new();
    for a in 1..8 {
        for b in 1..8 {
            let (fa, fb) = (f64::from(a) / 8.0, f64::from(b) / 8.0);
            out.push(Point3::new(hx + fa * tx, (fb - 0.5) * ty, tz));
            out.push(Point3::new(hx + tx, (fb - 0.5) * ty, fa * tz));
        }
    }
    out
}

#[test]
fn a_half_turn_whose_tab_the_camera_cannot_see_is_rejected_where_it_saw_the_table() {
    hidden_tab(&Cell::default(), &builtin_tab());
}

#[test]
fn a_mesh_trays_half_turn_with_its_tab_hidden_is_rejected() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("own.stl"), tray_stl(200.0, 140.0, 6.0, 8.0, 28.0)).unwrap();
    let text = "[tray]\nkind = \"mesh\"\nmesh = \"own.stl\"\n\
                slots = [[-45.0, -30.0, 6.0, 0.0], [45.0, -30.0, 6.0, 0.0], [-45.0, 30.0, 6.0, 0.0], [45.0, 30.0, 6.0, 0.0]]\n";
    let cell = Cell::from_toml_str(text, dir.path()).unwrap();
    hidden_tab(&cell, &grid_on_tab(100.0, 20.0, 30.0, 28.0 * 0.6));
}

/// A tray truly symmetric under a half turn (a box tray without a tab) whose cell lists the
/// half turn: the truth and its half turn are both accepted, the turn no evidence against
/// either; with the symmetry not listed, the half turn is ambiguous or worse.
/// A one-shot frame is matched only in the box where it differs from the background. The
/// 8-slot tray turned a quarter turn about its centre stands out of that box at both ends;
/// there the verification reads the background's depth. The turned pose's see-through
/// evidence is that against the same frame matched over the whole image, to the matchers'
/// noise, where the box's own map alone tests a fraction of its points.
#[test]
fn a_quarter_turn_reaching_past_the_matched_box_is_judged_on_the_background() {
    let cell = Cell::default();
    let seed = 4;
    let (mut sim, mut estimator) = setup(&cell, seed);
    let sensor = estimator.sensor_position();
    let points = tray_points(estimator.model());
    let quarter = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::FRAC_PI_2);
    let mut frame = Frame::default();
    for i in 0..3 {
        let mut scene = draw_scenario(&cell, seed, i).scene();
        scene.occluder = None;
        // The tray's length pointing away from the sensor, so that its quarter turn lies
        // across the image, out of the box around the tray at both ends.
        let t = scene.t_world_tray.translation.vector;
        let yaw = (t.y - f64::from(sensor.y)).atan2(t.x - f64::from(sensor.x));
        scene.t_world_tray = Isometry3::new(t, Vector3::z() * yaw);
        sim.render(&scene, Method::OneShot, noise_key(seed, i, false), &mut frame);
        estimator.process(&frame.shots.left, &frame.shots.right).unwrap();
        assert!(!estimator.matched_whole(), "scene {i}: matched whole");
        let turned = scene.t_world_tray * quarter;
        let judged = estimator.verify(&turned).see_through;
        let camera = estimator.rectified_camera().clone();
        let in_box = DepthEvidence {
            disparity: &estimator.reconstruction().disparity,
            camera: &camera,
            beyond: None,
            holes_unlit: false,
        };
        let box_only = see_through(estimator.model(), &points, &in_box, &sensor, &turned);
        let (whole, _) = estimator.whole_disparity().unwrap();
        let whole = whole.clone();
        let oracle = DepthEvidence { disparity: &whole, camera: &camera, beyond: None, holes_unlit: false };
        let oracle = see_through(estimator.model(), &points, &oracle, &sensor, &turned);
        eprintln!(
            "scene {i}: quarter turn tested {} seen past {:.3} (whole image: {} {:.3}; the box alone: {} {:.3})",
            judged.tested,
            judged.share(),
            oracle.tested,
            oracle.share(),
            box_only.tested,
            box_only.share()
        );
        // At least a twentieth of the points the whole image tests lie out of the box.
        assert!(
            box_only.tested * 20 < oracle.tested * 19,
            "scene {i}: the turn stays in the box: {box_only:?} {oracle:?}"
        );
        let tested_off = judged.tested.abs_diff(oracle.tested) as f32 / oracle.tested as f32;
        assert!(tested_off <= 0.03, "scene {i}: tested {judged:?} against the whole image's {oracle:?}");
        assert!((judged.share() - oracle.share()).abs() <= 0.03, "scene {i}: {judged:?} against {oracle:?}");
    }
}

/// A frame's verification reuses what the turn check weighed of its pose (its counts
/// against its quarter turns, their see-through evidence); the pose weighed afresh gets the
/// same verification, field for field. The fit is handed on as fitted, so the pose handed on
/// is the one verified.
#[test]
fn a_turn_that_nothing_tells_from_the_pose_leaves_it_ambiguous() {
    // The tray in plain view, its scene cloud with every point beyond either end wall's
    // inside taken out (where the tab is and where its turns put it: what an occluder or a
    // shadow over both ends leaves), verified from the cloud alone (no depth to see past
    // either): no evidence for the truth over its half turn, so the truth is ambiguous;
    // with the whole cloud it is accepted. Taking the ends out takes their share of the
    // coverage (about half), so the threshold stands below it: the verdict is the turn's.
    let mut cell = Cell::default();
    cell.estimator.verify_threshold = 0.3;
    let seed = 2;
    let (mut sim, mut estimator) = setup(&cell, seed);
    let mut frame = Frame::default();
    let mut judged = 0;
    for i in 0..6 {
        let scene = processed_without_occluder(&cell, seed, i, &mut sim, &mut estimator, &mut frame);
        let truth = scene.t_world_tray;
        let whole: Vec<Point3<f32>> = estimator.scene_cloud().to_vec();
        let without_ends: Vec<Point3<f32>> = whole
            .iter()
            .filter(|p| {
                let q = truth.inverse_transform_point(&p.cast::<f64>());
                q.x.abs() <= 90.0
            })
            .copied()
            .collect();
        estimator.process_cloud(&whole).unwrap();
        let seen = estimator.verify(&truth);
        if seen.verdict != Verdict::Accepted || seen.turn_own == 0 {
            // The tab itself out of view: nothing to take away.
            continue;
        }
        assert!(!seen.turn_unseen, "scene {i}: {seen:?}");
        estimator.process_cloud(&without_ends).unwrap();
        let unseen = estimator.verify(&truth);
        if unseen.turn_own + unseen.turn_other > 0 {
            // A shifted alternative's parts inside the end walls kept a few points.
            continue;
        }
        judged += 1;
        assert!(unseen.turn_unseen && !unseen.turn_confirmed, "scene {i}: {unseen:?}");
        assert_eq!(unseen.verdict, Verdict::Ambiguous, "scene {i}: {unseen:?}");
    }
    assert!(
        judged >= 2,
        "only {judged} of 6 scenes show the tab and lose every point that tells: the test shows nothing"
    );
}

#[test]
fn a_frames_verification_is_its_pose_weighed_afresh() {
    let mut cell = Cell::default();
    cell.estimator.pose_on_table = false;
    let seed = 5;
    let (mut sim, mut estimator) = setup(&cell, seed);
    let mut frame = Frame::default();
    for i in 0..4 {
        sim.render(&draw_scenario(&cell, seed, i).scene(), Method::OneShot, noise_key(seed, i, false), &mut frame);
        let pose = estimator.process(&frame.shots.left, &frame.shots.right).unwrap();
        assert!(pose.found, "scene {i}");
        assert!(pose.verification.turn_see_through.tested > 0, "scene {i}: no turn weighed: {:?}", pose.verification);
        assert_eq!(estimator.verify(&pose.t_world_tray), pose.verification, "scene {i}");
    }
}

#[test]
fn a_listed_half_turn_is_accepted() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("plain.stl"),
        crate::meshes::boxes_stl(&[
            ([-100.0, -70.0, 0.0], [100.0, 70.0, 6.0]),
            ([-100.0, -70.0, 0.0], [-92.0, 70.0, 28.0]),
            ([92.0, -70.0, 0.0], [100.0, 70.0, 28.0]),
            ([-100.0, -70.0, 0.0], [100.0, -62.0, 28.0]),
            ([-100.0, 62.0, 0.0], [100.0, 70.0, 28.0]),
        ]),
    )
    .unwrap();
    let text = "[tray]\nkind = \"mesh\"\nmesh = \"plain.stl\"\nsymmetries = [180.0]\n\
                slots = [[-45.0, -30.0, 6.0, 0.0], [45.0, -30.0, 6.0, 0.0], [-45.0, 30.0, 6.0, 0.0], [45.0, 30.0, 6.0, 0.0]]\n";
    let cell = Cell::from_toml_str(text, dir.path()).unwrap();
    let seed = 4;
    let (mut sim, mut estimator) = setup(&cell, seed);
    let mut frame = Frame::default();
    let mut accepted = 0;
    for i in 0..4 {
        let scene = processed_without_occluder(&cell, seed, i, &mut sim, &mut estimator, &mut frame);
        let truth = estimator.verify(&scene.t_world_tray);
        let turned = estimator.verify(&(scene.t_world_tray * half_turn()));
        eprintln!(
            "scene {i}: truth {} ({:.3}), half turn {} ({:.3})",
            truth.verdict, truth.score, turned.verdict, turned.score
        );
        assert!(!turned.turned_wrong_way() && !truth.turned_wrong_way(), "scene {i}: {truth:?} {turned:?}");
        assert_eq!(
            turned.turn_seen.map(|a| a.quarters % 2),
            Some(1),
            "scene {i}: the listed half turn weighed: {turned:?}"
        );
        assert!(turned.verdict != Verdict::Ambiguous && truth.verdict != Verdict::Ambiguous, "scene {i}");
        accepted += usize::from(truth.verdict.accepted() && turned.verdict.accepted());
    }
    assert!(accepted >= 3, "{accepted} of 4 scenes had the truth and its listed half turn both accepted");
}

/// A tray of six slots, 3 x 2 at 80 mm both ways, with a low tab outside one end: turned a
/// quarter turn and moved 40 mm along each axis, it lays four of its slots (and their items)
/// onto four of the right pose's. Set against the right pose, such a pose is weighed
/// against the turns that lay the slot grid onto itself (the model's alternatives), and
/// the scene's points on the parts where it and the right pose differ speak for the right
/// pose: the wrong pose is rejected, the right one accepted.
#[test]
fn a_turn_laying_four_of_six_slots_onto_slots_is_told_from_the_truth() {
    let dir = tempfile::tempdir().unwrap();
    let (hx, hy) = (130.0, 85.0);
    let mut boxes = vec![
        ([-hx, -hy, 0.0], [hx, hy, 6.0]),
        ([-hx, -hy, 0.0], [-hx + 4.0, hy, 35.0]),
        ([hx - 4.0, -hy, 0.0], [hx, hy, 35.0]),
        ([-hx, -hy, 0.0], [hx, -hy + 4.0, 35.0]),
        ([-hx, hy - 4.0, 0.0], [hx, hy, 35.0]),
    ];
    boxes.push(([hx, -20.0, 0.0], [hx + 12.0, 20.0, 15.0]));
    std::fs::write(dir.path().join("six.stl"), crate::meshes::boxes_stl(&boxes)).unwrap();
    let slots = "[[-80.0, -40.0, 6.0, 0.0], [0.0, -40.0, 6.0, 0.0], [80.0, -40.0, 6.0, 0.0], \
                 [-80.0, 40.0, 6.0, 0.0], [0.0, 40.0, 6.0, 0.0], [80.0, 40.0, 6.0, 0.0]]";
    let text = format!("[tray]\nkind = \"mesh\"\nmesh = \"six.stl\"\nslots = {slots}\n");
    let cell = Cell::from_toml_str(&text, dir.path()).unwrap();
    let seed = 3;
    let (mut sim, mut estimator) = setup(&cell, seed);
    // The model's own alternatives: the quarter turns 1 to 3, then the grid's.
    let alternatives = estimator.verifier().turn_parts.alternatives.list().to_vec();
    let lattice: Vec<Alternative> = alternatives[3..].to_vec();
    assert_eq!(lattice.len(), 10, "{lattice:?}");
    let quarter = Alternative { quarters: 1, shift: Vector3::new(40.0, 40.0, 0.0) };
    assert!(lattice.iter().any(|a| a.quarters == 1 && (a.shift - quarter.shift).norm() < 1e-6), "{lattice:?}");
    let mut frame = Frame::default();
    let mut accepted = 0;
    for i in 0..4 {
        let scene = processed_without_occluder(&cell, seed, i, &mut sim, &mut estimator, &mut frame);
        let truth = estimator.verify(&scene.t_world_tray);
        // The wrong pose W with W * quarter = truth: the truth is W's alternative.
        let wrong_pose = scene.t_world_tray * quarter.inverse().transform();
        let wrong = estimator.verify(&wrong_pose);
        eprintln!(
            "scene {i}: truth {} ({:.3}, {} / {} on the parts apart), turned and shifted {} ({:.3}, {} / {})",
            truth.verdict,
            truth.score,
            truth.turn_own,
            truth.turn_other,
            wrong.verdict,
            wrong.score,
            wrong.turn_own,
            wrong.turn_other
        );
        assert!(!wrong.verdict.accepted(), "scene {i}: {wrong:?}");
        // Its closest alternative's parts hold more scene points than its own, by the
        // deviations that make a pose ambiguous.
        assert!(wrong.turn_sigmas() < -AMBIGUOUS_TURN_SIGMAS, "scene {i}: {wrong:?}");
        accepted += usize::from(truth.verdict.accepted());
    }
    assert!(accepted >= 3, "{accepted} of 4 true poses accepted");
}

/// The hard negatives of scenes at the optimum (each turn the tray's symmetries do not
/// list, the half turns shifted onto the slot grid, the truth a slot's pitch off either
/// way along both slot directions, the truth tilted off the table), refined and verified
/// against each frame: every one that stays grossly wrong is rejected, and every one
/// refined back to the truth is correct by the truth itself, not by the verdict.
#[test]
fn hard_negatives_at_the_optimum_are_rejected() {
    let cell = Cell::default();
    let seed = 6;
    let (mut sim, mut estimator) = setup(&cell, seed);
    let mut frame = Frame::default();
    let (mut gross, mut kinds) = (0, std::collections::BTreeSet::new());
    for i in 0..4 {
        let scene = draw_scenario(&cell, seed, i).scene();
        sim.render(&scene, Method::OneShot, noise_key(seed, i, false), &mut frame);
        let pose = estimator.process(&frame.shots.left, &frame.shots.right).unwrap();
        let made = hard_negatives(&estimator, &scene.t_world_tray);
        // Tray-8: three turns, the half turn shifted a pitch either way along x, four
        // shifts, one tilt.
        assert_eq!(made.len(), 3 + 2 + 4 + 1, "scene {i}: {made:?}");
        let negatives = weigh_negatives(&mut estimator, &scene.t_world_tray, &cell.metrics).unwrap();
        for n in &negatives {
            kinds.insert(n.kind.clone());
            eprintln!(
                "scene {i}: {} {} ({:.3}), {:.1} mm / {:.1} deg",
                n.kind, n.verdict, n.score, n.position_error_mm, n.rotation_error_deg
            );
            let limits = n.position_error_mm <= cell.metrics.success_position
                && n.rotation_error_deg <= cell.metrics.success_rotation;
            assert_eq!(n.correct, limits, "scene {i}: {n:?}");
            if n.gross {
                gross += 1;
                assert!(!n.accepted(), "scene {i}: {n:?}");
            }
        }
        // The frame's own pose is untouched by the negatives weighed after it.
        assert!(pose.verification.verdict.accepted(), "scene {i}: {:?}", pose.verification);
    }
    assert!(gross >= 30, "{gross} gross negatives in 4 scenes");
    assert_eq!(kinds.into_iter().collect::<Vec<_>>(), ["grid turn", "shift", "tilt", "turn"]);
}

#[test]
fn every_verdict_reads_back_from_its_text() {
    for v in [
        Verdict::Accepted,
        Verdict::NoTray,
        Verdict::OffTable,
        Verdict::Ambiguous,
        Verdict::PoorFit,
        Verdict::SeenThrough,
    ] {
        assert_eq!(Verdict::parse(v.as_str()), Some(v));
        assert_eq!(v.accepted(), v.as_str() == "accepted");
    }
}

/// A cloud moved as a miscalibrated rig moves it (lifted 2 mm and tilted 1°): the free fit
/// follows it, and with `pose_on_table` the pose handed on is that fit laid on the table,
/// its x, y and turn kept; the verification is the free fit's either way.
#[test]
fn a_fit_resting_on_the_table_is_handed_on_laid_on_it() {
    let cell = Cell::default();
    assert!(cell.estimator.pose_on_table, "on by default");
    let seed = 2;
    let (mut sim, mut laid) = setup(&cell, seed);
    let mut free_cell = cell.clone();
    free_cell.estimator.pose_on_table = false;
    let mut free =
        Estimator::new(&EstimatorConfig::from(&free_cell), sim.rig(), laid.model().clone(), Method::OneShot).unwrap();
    let mut frame = Frame::default();
    sim.render(&background_scene(&cell, seed), Method::OneShot, noise_key(seed, 0, true), &mut frame);
    free.set_background(&frame.shots.left, &frame.shots.right).unwrap();
    sim.render(&draw_scenario(&cell, seed, 0).scene(), Method::OneShot, noise_key(seed, 0, false), &mut frame);
    laid.process(&frame.shots.left, &frame.shots.right).unwrap();
    let moved = Isometry3::new(Vector3::new(0.0, 0.0, 2.0), Vector3::new(1f32.to_radians(), 0.0, 0.0));
    let cloud: Vec<Point3<f32>> = laid.reconstruction().cloud.points.iter().map(|p| moved * p).collect();
    let (a, b) = (laid.process_cloud(&cloud).unwrap(), free.process_cloud(&cloud).unwrap());
    assert!(a.found && b.found);
    assert_eq!(a.verification, b.verification);
    assert!(b.verification.rests_on_table(), "{:?}", b.verification);
    let (pa, pb) = (a.t_world_tray, b.t_world_tray);
    let (z, tilt) = (pb.translation.vector.z, (pb.rotation * Vector3::z()).z.acos().to_degrees());
    eprintln!("the free fit: {z:.2} mm above the table, tilted {tilt:.2} deg");
    assert!(z > 1.0 && tilt > 0.5, "the free fit follows the moved cloud: {z} mm, {tilt} deg");
    assert_eq!(pa.translation.vector.z, 0.0);
    assert!((pa.rotation * Vector3::z()).z > 1.0 - 1e-12, "{pa:?}");
    assert_eq!((pa.translation.x, pa.translation.y), (pb.translation.x, pb.translation.y));
    let yaw = |p: &nalgebra::Isometry3<f64>| {
        let x = p.rotation * Vector3::x();
        x.y.atan2(x.x)
    };
    assert!((yaw(&pa) - yaw(&pb)).abs() < 1e-9, "{} against {}", yaw(&pa), yaw(&pb));
}

/// Scenarios with the cell's occluder (the gripper's box) moved over part of the tray,
/// rendered with it and without it: the share of the closest view's sensor-facing tray points the verification
/// sets aside as hidden at the truth (by the occluder, and by the tray's own walls where the
/// closest view looked from elsewhere) matches the share the rendered scene's true depth
/// (the renderer's ray cast) hides by more than the margin, and where the occluder hides a
/// tenth of the tray more than its walls do, the coverage is the coverage in plain view.
#[test]
fn the_tray_under_an_occluder_is_covered_as_in_plain_view() {
    let seed = 3;
    let mut cell = Cell::default();
    cell.occluder.probability = 1.0;
    let (mut sim, mut estimator) = setup(&cell, seed);
    let sensor = estimator.sensor_position();
    let mut frame = Frame::default();
    let mut occluded_scenes = 0;
    // The brute-force share at `truth` in the frame last rendered: every tray point of the
    // closest view that faces the sensor, hidden where the true depth at its pixel is more
    // than the margin in front of it.
    let true_hidden = |estimator: &Estimator, sim: &Simulator, frame: &Frame, truth: &Isometry3<f64>| {
        let model = estimator.model();
        let k = model.closest_view(truth, &sensor);
        let mask = &estimator.verifier().tray_mask[k];
        let left = &sim.rig().left;
        let eye = truth.inverse() * sensor.cast::<f64>();
        let (mut facing, mut hidden) = (0usize, 0usize);
        for (j, (m, n)) in model.views[k].points.iter().zip(&model.views[k].normals).enumerate() {
            let (m, n) = (m.cast::<f64>(), n.cast::<f64>());
            if mask[j / 64] & (1 << (j % 64)) == 0 || n.dot(&(eye - m)) <= 0.0 {
                continue;
            }
            facing += 1;
            let world = truth * m;
            let z = left.t_world_camera.inverse_transform_point(&world).z;
            let Some(uv) = left.project(&world) else { continue };
            let (u, v) = (uv.x.round() as usize, uv.y.round() as usize);
            if u < frame.depth_left.width && v < frame.depth_left.height {
                hidden += usize::from(f64::from(frame.depth_left.row(v)[u]) < z - f64::from(OCCLUDED_MARGIN_MM));
            }
        }
        hidden as f64 / facing.max(1) as f64
    };
    for i in 0..6 {
        let mut scene = draw_scenario(&cell, seed, i).scene();
        let truth = scene.t_world_tray;
        // The occluder moved onto the ray from the tray's centre to the sensor, 150 mm above
        // the tray, and made 60 x 60 x 30 mm: the gripper over part of the tray.
        let t = truth.translation.vector;
        let c = t + (sensor.coords.cast::<f64>() - t) * (150.0 / (f64::from(sensor.z) - t.z));
        let b = scene.occluder.as_mut().expect("the cell draws an occluder in every scene");
        (b.min, b.max) = ([c.x - 30.0, c.y - 30.0, c.z - 15.0], [c.x + 30.0, c.y + 30.0, c.z + 15.0]);
        let mut clear_scene = scene.clone();
        clear_scene.occluder = None;
        let mut seen = Vec::new();
        for spec in [&scene, &clear_scene] {
            sim.render(spec, Method::OneShot, noise_key(seed, i, false), &mut frame);
            estimator.process(&frame.shots.left, &frame.shots.right).unwrap();
            seen.push((estimator.verify(&truth), true_hidden(&estimator, &sim, &frame, &truth)));
        }
        let [(occluded, occluded_true), (clear, clear_true)] = [seen[0], seen[1]];
        eprintln!(
            "scene {i}: hidden {:.3} + unmeasured {:.3} (true depth {occluded_true:.3}), in plain view {:.3} + {:.3} \
             ({clear_true:.3}); coverage {:.3}, in plain view {:.3}",
            occluded.hidden, occluded.unmeasured, clear.hidden, clear.unmeasured, occluded.coverage, clear.coverage
        );
        // A surface nearer than the matcher's range (the gripper high above the tray) is
        // measured nowhere: hidden and unmeasured together are what the true depth hides.
        for (what, v, t) in [("under the occluder", occluded, occluded_true), ("in plain view", clear, clear_true)] {
            let set_aside = f64::from(v.hidden + v.unmeasured);
            assert!(
                (set_aside - t).abs() <= 0.1,
                "scene {i} {what}: hidden {:.3} and unmeasured {:.3}, by the true depth {t:.3} hidden",
                v.hidden,
                v.unmeasured
            );
        }
        if occluded_true - clear_true < 0.1 {
            continue;
        }
        occluded_scenes += 1;
        assert!(
            (occluded.coverage - clear.coverage).abs() <= 0.1,
            "scene {i}: coverage {:.3} under the occluder, {:.3} in plain view ({:.3} hidden)",
            occluded.coverage,
            clear.coverage,
            occluded.hidden
        );
    }
    assert!(
        occluded_scenes >= 2,
        "only {occluded_scenes} of 6 scenes hide a tenth of the tray: the test shows nothing"
    );
}
