//! The verification's evidence on simulated scenes with their truth: builds the model at a
//! placement, runs scenarios FIRST..FIRST+N of a seed as `evaluate` does (each scene's miscalibrated
//! rig included) and prints per scene whether the pose is correct, its errors, and the
//! score, coverage, hidden and unmeasured shares, explained share, turn margin, height and tilt, the share of the tray's
//! surface the camera saw past at the pose and at the pose a slot's pitch away, the turn the
//! see-through evidence weighs with the shares of the pose's and the turn's distinct parts
//! seen past and how many of each were tested, then the score's distribution for correct and
//! for wrong poses.
//!
//! ```text
//! cargo run --release -p camplace-sim --example verify_features -- \
//!     [--placement r=1000,alpha=60,baseline=81,vergence=3.5] [--method one-shot] \
//!     [--first 0] [--count 100] [--seed 1] [--cell cell.toml] [--quiet]
//! ```

use camplace_config::Cell;
use camplace_sim::{Evaluator, Method};

fn main() {
    let mut placement = "r=1000,alpha=60,baseline=81,vergence=3.5".to_string();
    let (mut method, mut first, mut count, mut seed, mut cell, mut quiet) =
        (Method::OneShot, 0u64, 100u64, 1u64, None, false);
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let mut value = || it.next().unwrap_or_else(|| panic!("{flag} needs a value"));
        match flag.as_str() {
            "--placement" => placement = value(),
            "--method" => method = value().parse().expect("--method: one-shot or phase-12"),
            "--first" => first = value().parse().expect("--first: a number"),
            "--count" => count = value().parse().expect("--count: a number"),
            "--seed" => seed = value().parse().expect("--seed: a number"),
            "--cell" => cell = Some(Cell::load(std::path::Path::new(&value())).expect("cell file")),
            "--quiet" => quiet = true,
            other => panic!("unknown flag {other}"),
        }
    }
    let cell = cell.unwrap_or_default();
    let placement = cell.placement.with_overrides(&placement).expect("placement");
    let evaluator = Evaluator::new(&cell, &placement, method, seed).expect("evaluator");
    let mut worker = evaluator.worker().expect("worker");
    if !quiet {
        println!("scene found ok  pos_mm  rot_deg  score coverage hidden unmeasured explained turn_margin own other height_mm tilt_deg icp_rms icp_pairs seen_past shifted turn_q turn_own_st turn_other_st n_own n_other verdict");
    }
    let (mut right, mut wrong) = (Vec::new(), Vec::new());
    for i in first..first + count {
        let record = worker.scene(i).expect("scene");
        let pose = worker.last_pose();
        let s = record.score.expect("scored");
        let v = pose.verification;
        if pose.found {
            if s.success { &mut right } else { &mut wrong }.push(v.score);
        }
        if !quiet {
            println!(
                "{i:5} {:5} {:2} {:7.2} {:8.2} {:6.3} {:8.3} {:6.3} {:6.3} {:9.3} {:11.3} {:5} {:5} {:9.2} {:8.2} {:7.3} {:9} {:9.3} {:7.3} {} {:6.3} {:6.3} {:4} {:4} {}",
                u8::from(pose.found),
                u8::from(s.success),
                s.position_error_mm,
                s.rotation_error_deg,
                v.score,
                v.coverage,
                v.hidden,
                v.unmeasured,
                v.explained,
                v.turn_margin,
                v.turn_own,
                v.turn_other,
                v.height_mm,
                v.tilt_deg,
                pose.icp.rms_mm,
                pose.icp.correspondences,
                v.see_through.share(),
                v.see_through_shifted.share(),
                v.turn_seen.map_or(0, |a| a.quarters),
                v.turn_see_through.share(),
                v.turn_see_through_other.share(),
                v.turn_see_through.tested,
                v.turn_see_through_other.tested,
                v.verdict
            );
        }
    }
    let quantiles = |v: &mut Vec<f32>| {
        v.sort_by(f32::total_cmp);
        let q = |p: f64| v.get(((v.len() as f64 - 1.0) * p).round() as usize).copied().unwrap_or(f32::NAN);
        format!(
            "n {} min {:.3} p5 {:.3} p25 {:.3} median {:.3} p75 {:.3} max {:.3}",
            v.len(),
            q(0.0),
            q(0.05),
            q(0.25),
            q(0.5),
            q(0.75),
            q(1.0)
        )
    };
    println!("{placement} {method}: correct poses score {}", quantiles(&mut right));
    println!("{placement} {method}: wrong poses score   {}", quantiles(&mut wrong));
}
