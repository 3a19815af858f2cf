//! `camplace render`: one simulated scene with its ground truth, or (`--dataset`) a
//! recorded-dataset folder of scenarios 0..N-1 that `evaluate` and `replay` read alike.

use anyhow::Context;
use camplace_config::formats::pfm;
use camplace_estimator::{FloatImage, Rectification};
use camplace_sim::{draw_scenario, write_frame, write_images, write_rig, DatasetLayout, Frame, Method, Simulator};
use rayon::prelude::*;
use std::path::PathBuf;
use std::process::ExitCode;

use super::cell_args::CellArgs;

/// Flags of `camplace render`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    cell: CellArgs,
    /// one-shot (random dots) or phase-12 (12 phase-shift fringes).
    #[arg(long, default_value = "one-shot")]
    method: Method,
    /// Study seed (default: the cell's scenarios.seed).
    #[arg(long)]
    seed: Option<u64>,
    /// Scenario index within the seed.
    #[arg(long, default_value_t = 0)]
    scenario: u64,
    /// Write a recorded-dataset folder of scenarios 0..count-1 instead of one scene.
    #[arg(long)]
    dataset: bool,
    /// Number of scenarios with --dataset.
    #[arg(long, default_value_t = 10, requires = "dataset")]
    count: u64,
    /// Output folder.
    #[arg(long)]
    out: PathBuf,
}

/// Runs `camplace render`.
pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let (cell, placement) = a.cell.load()?;
    let seed = a.seed.unwrap_or(cell.scenarios.seed);
    std::fs::create_dir_all(&a.out).with_context(|| format!("{}: cannot create the folder", a.out.display()))?;
    let symmetries = cell.tray.symmetries.clone();
    let mut sim = Simulator::new(&cell, &placement, seed)?;
    let rectification = Rectification::new(sim.rig(), &cell.work_volume)?;
    if !a.dataset {
        let scenario = draw_scenario(&cell, seed, a.scenario);
        let mut frame = Frame::default();
        sim.render(&scenario.scene(), a.method, camplace_sim::noise_key(seed, a.scenario, false), &mut frame);
        write_rig(&a.out.join("rig.json"), sim.rig())?;
        write_frame(&a.out, &frame, &scenario, &placement, a.method, &symmetries)?;
        write_disparity_truth(&a.out, &rectification, sim.rig(), &frame)?;
        println!(
            "rendered scenario {} of seed {seed} at {placement} ({}) into {}",
            a.scenario,
            a.method,
            a.out.display()
        );
        return Ok(ExitCode::SUCCESS);
    }
    let layout = DatasetLayout::new(&a.out);
    write_rig(&layout.rig(), sim.rig())?;
    let mut frame = Frame::default();
    let background = camplace_sim::background_scene(&cell, seed);
    sim.render(&background, a.method, camplace_sim::noise_key(seed, 0, true), &mut frame);
    write_images(&layout.background(), &frame)?;
    (0..a.count).into_par_iter().try_for_each_init(
        || (Simulator::new(&cell, &placement, seed), Frame::default()),
        |(sim, frame), i| -> anyhow::Result<()> {
            let sim = sim.as_mut().map_err(|e| anyhow::anyhow!("{e}"))?;
            let scenario = draw_scenario(&cell, seed, i);
            sim.render(&scenario.scene(), a.method, camplace_sim::noise_key(seed, i, false), frame);
            write_frame(&layout.frame(i), frame, &scenario, &placement, a.method, &symmetries)?;
            write_disparity_truth(&layout.frame(i), &rectification, sim.rig(), frame)?;
            Ok(())
        },
    )?;
    println!("rendered {} scenarios of seed {seed} at {placement} ({}) into {}", a.count, a.method, a.out.display());
    Ok(ExitCode::SUCCESS)
}

/// `disparity_truth.pfm`: the true disparity in rectified-left pixels, so any matcher can be scored.
fn write_disparity_truth(
    dir: &std::path::Path,
    rectification: &Rectification,
    rig: &camplace_estimator::Rig,
    frame: &Frame,
) -> anyhow::Result<()> {
    let mut truth = FloatImage::default();
    rectification.disparity_truth(&rig.left, &frame.depth_left, &mut truth);
    pfm::write(&dir.join("disparity_truth.pfm"), truth.width, truth.height, &truth.data)?;
    Ok(())
}
