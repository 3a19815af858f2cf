//! Rendering into folders: one scenario with its ground truth (images, `truth.json`,
//! `rig.json`, the true disparity), or a recorded dataset of scenarios `0..N` with the
//! background capture, which `evaluate` and `replay` read alike. A dataset is rendered into
//! an empty folder only, so no frame of an earlier rig is left among the new ones; a folder
//! that holds nothing but camplace's dataset files may be emptied first.

use std::path::{Path, PathBuf};

use camplace_config::FloatImage;
use camplace_config::{is_image_name, is_temp_file_name, DATASET_FILES, FRAME_FILES};
use camplace_config::{Cell, Placement};
use camplace_estimator::{depth::Rectification, Rig};
use rayon::prelude::*;

use super::frame_files::{write_frame, write_images, write_rig};
use super::{Frame, Method, Simulator};
use crate::scene::scenario::{background_scene, draw_scenario};
use crate::seeds::noise_key;
use crate::{Error, Result};
use camplace_config::DatasetLayout;

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
/// `out`, with its `rig.json` and background capture. `out` must be empty or not exist yet
/// (see [`clear_dataset`]).
pub fn render_dataset(
    out: &Path,
    cell: &Cell,
    placement: &Placement,
    method: Method,
    seed: u64,
    count: u64,
) -> Result<()> {
    if let Some(first) = first_entry(out)? {
        return Err(Error::Other(format!(
            "{}: not empty (it holds {}): a dataset is rendered into an empty folder; give --force to replace a dataset there",
            out.display(),
            first.display()
        )));
    }
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

/// Empties the dataset folder `dir` of the files camplace writes there (`rig.json`,
/// `poses.jsonl`, `summary.json`, `background/`, `frames/NNNN/` with their images, truth,
/// reconstructions and temporary files) and returns how many files went. When the folder
/// holds anything else, nothing is removed and the error names the first such entry: a
/// folder of other files is not camplace's to empty. A missing folder is empty.
pub fn clear_dataset(dir: &Path) -> Result<usize> {
    if !dir.exists() {
        return Ok(0);
    }
    let mut files = Vec::new();
    let mut folders = Vec::new();
    for entry in list(dir)? {
        let name = file_name(&entry);
        match (is_real_dir(&entry), name.as_str()) {
            (true, "background") => {
                folders.push(entry.clone());
                files.extend(known_files(&entry, is_image_name)?);
            }
            (true, "frames") => {
                folders.push(entry.clone());
                for frame in list(&entry)? {
                    if !(is_real_dir(&frame) && file_name(&frame).bytes().all(|b| b.is_ascii_digit())) {
                        return Err(not_ours(dir, &frame));
                    }
                    folders.push(frame.clone());
                    files.extend(known_files(&frame, |n| is_image_name(n) || FRAME_FILES.contains(&n))?);
                }
            }
            (false, n) if DATASET_FILES.contains(&n) || is_temp_file_name(n) => files.push(entry),
            _ => return Err(not_ours(dir, &entry)),
        }
    }
    for f in &files {
        std::fs::remove_file(f).map_err(|e| Error::Other(format!("{}: cannot remove: {e}", f.display())))?;
    }
    // Frame folders before `frames/` itself.
    for d in folders.iter().rev() {
        std::fs::remove_dir(d).map_err(|e| Error::Other(format!("{}: cannot remove: {e}", d.display())))?;
    }
    Ok(files.len())
}

/// The files of `dir`, each of which must pass `known` (or be a temporary file).
fn known_files(dir: &Path, known: impl Fn(&str) -> bool) -> Result<Vec<PathBuf>> {
    let entries = list(dir)?;
    for e in &entries {
        let name = file_name(e);
        if is_real_dir(e) || !(known(&name) || is_temp_file_name(&name)) {
            return Err(not_ours(dir, e));
        }
    }
    Ok(entries)
}

fn not_ours(dir: &Path, entry: &Path) -> Error {
    Error::Other(format!(
        "{}: holds {}, which camplace does not write into a dataset; nothing was removed: empty the folder yourself or choose another --out",
        dir.display(),
        entry.display()
    ))
}

/// The entries of `dir`, sorted; symbolic links are listed as themselves, never followed.
fn list(dir: &Path) -> Result<Vec<PathBuf>> {
    let cannot = |e: std::io::Error| Error::Other(format!("{}: cannot list: {e}", dir.display()));
    let mut out = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(cannot)? {
        out.push(entry.map_err(cannot)?.path());
    }
    out.sort();
    Ok(out)
}

/// A folder, and not a link to one.
fn is_real_dir(p: &Path) -> bool {
    std::fs::symlink_metadata(p).is_ok_and(|m| m.is_dir())
}

fn file_name(p: &Path) -> String {
    p.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default()
}

/// The first entry of `dir` (by name), or `None` when it is empty or missing.
fn first_entry(dir: &Path) -> Result<Option<PathBuf>> {
    if !dir.exists() {
        return Ok(None);
    }
    if !dir.is_dir() {
        return Err(Error::Other(format!("{}: expected a folder for the dataset, found a file", dir.display())));
    }
    Ok(list(dir)?.into_iter().next())
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
