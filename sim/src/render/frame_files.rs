//! Writes rendered frames to disk in the layout of docs/design/interchange-formats.md: a single render folder, or
//! a frame of a recorded dataset (its camera images through config's dataset writer, so
//! simulated and real data take one path), with what only a simulation knows: the true
//! depth and ids, `truth.json` and a preview.

use std::path::Path;

use camplace_config::write_shots;
use camplace_config::{FloatImage, GrayImage};
use camplace_config::{LightingTruth, Placement, TruthFile};
use camplace_estimator::geometry::isometry_to_rows;
use camplace_estimator::Rig;

use crate::render::{Frame, Method};
use crate::scene::scenario::Scenario;
use crate::Result;

/// Writes the camera images of a frame (and nothing else) into `dir`.
pub fn write_images(dir: &Path, frame: &Frame) -> Result<()> {
    Ok(write_shots(dir, &frame.shots)?)
}

/// Writes a whole rendered frame: images, ground-truth depth and ids, `truth.json` and
/// `preview.png`; the rig is written by the caller (once per dataset).
pub fn write_frame(
    dir: &Path,
    frame: &Frame,
    scenario: &Scenario,
    placement: &Placement,
    method: Method,
    symmetries: &[f64],
) -> Result<()> {
    write_images(dir, frame)?;
    write_float(&dir.join("depth_left.pfm"), &frame.depth_left)?;
    write_float(&dir.join("depth_right.pfm"), &frame.depth_right)?;
    write_gray(&dir.join("ids_left.png"), &frame.ids_left)?;
    write_gray(&dir.join("ids_right.png"), &frame.ids_right)?;
    truth_of(scenario, placement, method, symmetries).save(&dir.join("truth.json"))?;
    write_preview(&dir.join("preview.png"), &frame.shots.left[0], &frame.depth_left)?;
    Ok(())
}

/// The `truth.json` content of a scenario.
pub fn truth_of(scenario: &Scenario, placement: &Placement, method: Method, symmetries: &[f64]) -> TruthFile {
    TruthFile {
        t_world_tray: isometry_to_rows(&scenario.t_world_tray),
        filled: scenario.filled.clone(),
        lighting: LightingTruth {
            ambient: scenario.ambient,
            lamp_strength: scenario.lamp_strength,
            lamp_position: scenario.lamp_position.coords.into(),
        },
        seed: scenario.seed,
        scenario: scenario.index,
        symmetries: symmetries.to_vec(),
        placement: Some(*placement),
        method: Some(method.to_string()),
    }
}

/// Writes `rig.json`.
pub fn write_rig(path: &Path, rig: &Rig) -> Result<()> {
    Ok(rig.to_file().save(path)?)
}

fn write_gray(path: &Path, img: &GrayImage) -> Result<()> {
    Ok(camplace_config::write_gray(path, img.width, img.height, &img.data)?)
}

fn write_float(path: &Path, img: &FloatImage) -> Result<()> {
    Ok(camplace_config::write_pfm(path, img.width, img.height, &img.data)?)
}

/// The left image beside a colour map of its depth (near red, far blue, nothing black).
pub fn write_preview(path: &Path, image: &GrayImage, depth: &FloatImage) -> Result<()> {
    let (w, h) = (image.width, image.height);
    let mut finite: Vec<f32> = depth.data.iter().copied().filter(|d| d.is_finite()).collect();
    finite.sort_by(f32::total_cmp);
    let pick = |q: f64| finite.get(((finite.len().saturating_sub(1)) as f64 * q) as usize).copied();
    let (lo, hi) = (pick(0.01).unwrap_or(0.0), pick(0.99).unwrap_or(1.0));
    let span = (hi - lo).max(1e-3);
    let mut rgb = vec![0u8; 3 * 2 * w * h];
    for y in 0..h {
        for x in 0..w {
            let g = image.get(x, y);
            let o = 3 * (y * 2 * w + x);
            rgb[o..o + 3].copy_from_slice(&[g, g, g]);
            let d = depth.get(x, y);
            let c = if d.is_finite() { turbo(1.0 - ((d - lo) / span).clamp(0.0, 1.0)) } else { [0, 0, 0] };
            let o = 3 * (y * 2 * w + w + x);
            rgb[o..o + 3].copy_from_slice(&c);
        }
    }
    Ok(camplace_config::write_rgb(path, 2 * w, h, &rgb)?)
}

/// Google's Turbo colour map (polynomial approximation), t in [0, 1].
fn turbo(t: f32) -> [u8; 3] {
    let t = t as f64;
    let r =
        0.13572138 + t * (4.6153926 + t * (-42.66032258 + t * (132.13108234 + t * (-152.94239396 + t * 59.28637943))));
    let g = 0.09140261 + t * (2.19418839 + t * (4.84296658 + t * (-14.18503333 + t * (4.27729857 + t * 2.82956604))));
    let b =
        0.1066733 + t * (12.64194608 + t * (-60.58204836 + t * (110.36276771 + t * (-89.90310912 + t * 27.34824973))));
    let c = |v: f64| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
    [c(r), c(g), c(b)]
}
