//! The estimator embedded in a program of one's own: a model, a rig and frames in, the
//! tray's pose out, handed on only when the verification accepts it.
//!
//! ```text
//! cargo run --example embed -p camplace-estimator
//! ```
//! The cameras are stood in for by the simulator, which renders the built-in cell's tray at
//! a known pose (and builds the tray's model, which `camplace model` writes to a file);
//! everything between the two rules below is what a cell PC's program does with camera
//! buffers, a `tray.model` and a `rig.json`.

use camplace_config::Cell;
use camplace_estimator::{depth::Method, Estimator, EstimatorConfig, ImageView, Model, Rig};
use camplace_sim::{background_scene, build_model, draw_scenario, noise_key, Frame, Simulator};

/// The estimator on one background pair and one pair with the tray, each camera's pixels a
/// row-major 8-bit buffer of `width` × `height`.
struct Buffers<'a> {
    width: usize,
    height: usize,
    background: [&'a [u8]; 2],
    frame: [&'a [u8]; 2],
}

fn estimate(
    model: Model,
    rig: &Rig,
    b: &Buffers<'_>,
) -> Result<Option<nalgebra::Isometry3<f64>>, Box<dyn std::error::Error>> {
    // ------------------------------------------------------------------------------------
    let mut estimator = Estimator::new(&EstimatorConfig::default(), rig, model, Method::OneShot)?;
    let view = |pixels| ImageView::new(pixels, b.width, b.height, b.width);
    estimator.set_background(&[view(b.background[0])?], &[view(b.background[1])?])?;
    let estimate = estimator.process(&[view(b.frame[0])?], &[view(b.frame[1])?])?;
    println!(
        "found {}, verdict {:?} (score {:.3}), {:.1} ms",
        estimate.found, estimate.verification.verdict, estimate.verification.score, estimate.timings.total_ms
    );
    // Only an accepted pose may be handed to the robot.
    Ok(estimate.accepted().then_some(estimate.t_world_tray))
    // ------------------------------------------------------------------------------------
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let cell = Cell::default();
    let seed = 1;
    let mut sim = Simulator::new(&cell, &cell.placement, seed)?;
    let model = build_model(&cell, &cell.placement, Method::OneShot, seed)?;
    let (mut background, mut frame) = (Frame::default(), Frame::default());
    sim.render(&background_scene(&cell, seed), Method::OneShot, noise_key(seed, 0, true), &mut background);
    let scenario = draw_scenario(&cell, seed, 0);
    sim.render(&scenario.scene(), Method::OneShot, noise_key(seed, 0, false), &mut frame);
    let (left, right) = (&frame.shots.left[0], &frame.shots.right[0]);
    let buffers = Buffers {
        width: left.width,
        height: left.height,
        background: [&background.shots.left[0].data, &background.shots.right[0].data],
        frame: [&left.data, &right.data],
    };
    match estimate(model, sim.rig(), &buffers)? {
        Some(pose) => {
            let d = scenario.t_world_tray.inverse() * pose;
            let (t, turn) = (pose.translation.vector, pose.rotation.scaled_axis());
            println!(
                "T_world_tray: ({:.2}, {:.2}, {:.2}) mm, turned {:.2}° about ({:.3}, {:.3}, {:.3})",
                t.x,
                t.y,
                t.z,
                turn.norm().to_degrees(),
                turn.x / turn.norm(),
                turn.y / turn.norm(),
                turn.z / turn.norm()
            );
            println!(
                "against the rendered truth: {:.2} mm, {:.3}°",
                d.translation.vector.norm(),
                d.rotation.angle().to_degrees()
            );
        }
        None => println!("no pose to hand on"),
    }
    Ok(())
}
