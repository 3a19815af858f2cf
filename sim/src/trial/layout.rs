//! A trial folder: `plan.json` (and `plan.csv`) at the top and one recorded dataset per
//! placement in `NNN/` (its number in the plan), each with the rig it was captured with,
//! its frames, `poses.jsonl` once estimated and `labels.jsonl` once reviewed. A placement
//! folder's rig is checked against the cell and the plan before anything is counted.

use std::path::Path;

use camplace_config::{Cell, Placement, RigFile};
use camplace_estimator::Rig;

use crate::{Error, Result};
use camplace_estimator::geometry::as_built;

/// How far an installed rig's distance r may lie from the plan's, as a share of it: a robot
/// carrying the rig reaches its pose to a millimetre, a rig clamped by hand to a few
/// centimetres; a rig of another placement or cell lies further off.
pub const RIG_R_MARGIN: f64 = 0.15;
/// How far an installed rig's polar angle may lie from the plan's, deg.
pub const RIG_ALPHA_MARGIN_DEG: f64 = 10.0;

/// Checks that the rig of placement folder `dir` belongs to `cell` (its cameras' image size)
/// and sits where the plan puts placement `planned` (r within [`RIG_R_MARGIN`], alpha within
/// [`RIG_ALPHA_MARGIN_DEG`]); the error names the file and the key.
pub fn check_placement_rig(dir: &Path, cell: &Cell, planned: &Placement) -> Result<Rig> {
    let path = dir.join("rig.json");
    if !path.is_file() {
        return Err(Error::Other(format!(
            "{}: missing: expected the rig the placement was captured with (camplace capture --trial)",
            path.display()
        )));
    }
    let file = RigFile::load(&path)?;
    let [w, h] = cell.sensor.camera_resolution;
    for (side, cam) in [("left", &file.left), ("right", &file.right)] {
        if (cam.width, cam.height) != (w, h) {
            return Err(Error::Other(format!(
                "{}: {side}.width × {side}.height: expected {w} × {h} (the cell's sensor.camera_resolution), found {} × {}: \
                 the rig of another cell",
                path.display(),
                cam.width,
                cam.height
            )));
        }
    }
    let rig = Rig::from_file(&file);
    let built = as_built(&rig).map_err(|e| Error::Other(format!("{}: left/right: {e}", path.display())))?.placement;
    let r_off = (built.r - planned.r).abs();
    if r_off > RIG_R_MARGIN * planned.r || (built.alpha - planned.alpha).abs() > RIG_ALPHA_MARGIN_DEG {
        return Err(Error::Other(format!(
            "{}: left.t_world_camera: expected a rig at the plan's r={:.0} mm, alpha={:.1}° (within {:.0} % and {}°), \
             found r={:.0} mm, alpha={:.1}°: the rig of another placement or cell",
            path.display(),
            planned.r,
            planned.alpha,
            100.0 * RIG_R_MARGIN,
            RIG_ALPHA_MARGIN_DEG,
            built.r,
            built.alpha
        )));
    }
    Ok(rig)
}
