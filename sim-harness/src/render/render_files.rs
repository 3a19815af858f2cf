//! Rendering into folders: one scenario with its ground truth (images, `truth.json`,
//! `rig.json`, the true disparity), or a recorded dataset of scenarios `0..N` with the
//! background capture, which `evaluate` and `replay` read alike.

use std::path::Path;

use camplace_config::FloatImage;
use camplace_config::{Cell, Placement};
use camplace_estimator::{Rectification, Rig};
use rayon::prelude::*;

use super::frame_files::{write_frame, write_images, write_rig, DatasetLayout};
use super::{Frame, Method, Simulator};
use crate::scene::scenario::{background_scene, draw_scenario};
use crate::seeds::noise_key;
use crate::{Error, Result};

/// Renders scenario `scenario` of `seed` at `placement` into the folder `out`.
pub fn render_scene(
    out: &Path,
    cell: &Cell,
    placement: &Placement,
    method: Method,
    seed: u64,
    scenario: u64,
) -> Result<()> {
    create_folder(out)?;
    let symmetries = cell.tray.symmetries.clone();
    let mut sim = Simulator::new(cell, placement, seed)?;
    let rectification = Rectification::new(sim.rig(), &cell.work_volume)?;
    let drawn = draw_scenario(cell, seed, scenario);
    let mut frame = Frame::default();
    sim.render(&drawn.scene(), method, noise_key(seed, scenario, false), &mut frame);
    write_rig(&out.join("rig.json"), sim.rig())?;
    write_frame(out, &frame, &drawn, placement, method, &symmetries)?;
    write_disparity_truth(out, &rectification, sim.rig(), &frame)
}

/// Renders scenarios `0..count` of `seed` at `placement` into the recorded-dataset folder
/// `out`, with its `rig.json` and background capture.
pub fn render_dataset(
    out: &Path,
    cell: &Cell,
    placement: &Placement,
    method: Method,
    seed: u64,
    count: u64,
) -> Result<()> {
    create_folder(out)?;
    let symmetries = cell.tray.symmetries.clone();
    let mut sim = Simulator::new(cell, placement, seed)?;
    let rectification = Rectification::new(sim.rig(), &cell.work_volume)?;
    let layout = DatasetLayout::new(out);
    write_rig(&layout.rig(), sim.rig())?;
    let mut frame = Frame::default();
    let background = background_scene(cell, seed);
    sim.render(&background, method, noise_key(seed, 0, true), &mut frame);
    write_images(&layout.background(), &frame)?;
    (0..count).into_par_iter().try_for_each_init(
        || (Simulator::new(cell, placement, seed), Frame::default()),
        |(sim, frame), i| -> Result<()> {
            let sim = sim.as_mut().map_err(|e| Error::Other(e.to_string()))?;
            let scenario = draw_scenario(cell, seed, i);
            sim.render(&scenario.scene(), method, noise_key(seed, i, false), frame);
            write_frame(&layout.frame(i), frame, &scenario, placement, method, &symmetries)?;
            write_disparity_truth(&layout.frame(i), &rectification, sim.rig(), frame)?;
            Ok(())
        },
    )
}

fn create_folder(out: &Path) -> Result<()> {
    std::fs::create_dir_all(out).map_err(|e| Error::Other(format!("{}: cannot create the folder: {e}", out.display())))
}

/// `disparity_truth.pfm`: the true disparity in rectified-left pixels, so any matcher can be scored.
fn write_disparity_truth(dir: &Path, rectification: &Rectification, rig: &Rig, frame: &Frame) -> Result<()> {
    let mut truth = FloatImage::default();
    rectification.disparity_truth(&rig.left, &frame.depth_left, &mut truth);
    camplace_config::write_pfm(&dir.join("disparity_truth.pfm"), truth.width, truth.height, &truth.data)?;
    Ok(())
}
