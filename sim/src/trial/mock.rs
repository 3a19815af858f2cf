//! A mock trial for tests and for learning the procedure without a rig: each placement of a
//! plan rendered as a recorded dataset by a "real" cell the study does not know (its own
//! seed, sensor noise and blur, whatever its file says), with the truth moved aside. Each
//! frame's `truth.json` goes to `HIDDEN/NNN/NNNN.json`, outside the trial folder, and the
//! files that would give the truth away (true depth, ids, the preview, the true disparity)
//! are deleted, so the trial folder holds what a real capture holds. Frame k is scenario k
//! of the seed at every placement: the same tray set-down seen from each, as in the paper's
//! trial.

use std::path::{Path, PathBuf};

use camplace_config::{Cell, TruthFile};
use camplace_estimator::{geometry::isometry_from_rows, pose::pose_errors};

use super::judge::{frame_names, read_poses, Label, Mark};
use crate::render::render_files::render_dataset;
use crate::render::Method;
use crate::{Error, Result};
use camplace_config::{placement_dir, placement_folder_name, TrialPlan, PLAN_FILE};

/// The files of a rendered frame that give its truth away.
const TRUTH_FILES: [&str; 6] =
    ["depth_left.pfm", "depth_right.pfm", "ids_left.png", "ids_right.png", "preview.png", "disparity_truth.pfm"];

/// Renders `plan` into the trial folder `dir` (which must not hold a plan yet) with `real`
/// as the cell the frames come from: `frames` scenarios of `seed` per placement, each
/// frame's truth moved to `hidden`. Writes `dir/plan.json`.
pub fn make_mock_trial(
    dir: &Path,
    hidden: &Path,
    real: &Cell,
    plan: &TrialPlan,
    method: Method,
    seed: u64,
    frames: u64,
) -> Result<()> {
    if dir.join(PLAN_FILE).exists() {
        return Err(Error::Other(format!(
            "{}: exists: a mock trial is made into a new folder",
            dir.join(PLAN_FILE).display()
        )));
    }
    if hidden.starts_with(dir) {
        return Err(Error::Other(format!(
            "--hidden {}: expected a folder outside the trial folder {}, so the truth stays hidden",
            hidden.display(),
            dir.display()
        )));
    }
    for (i, _) in plan.placements.iter().enumerate() {
        let out = placement_dir(dir, i);
        render_dataset(&out, real, &plan.placement(i), method, seed, frames)?;
        let aside = hidden.join(placement_folder_name(i));
        std::fs::create_dir_all(&aside).map_err(|e| camplace_config::Error::io(&aside, &e))?;
        for name in frame_names(&out)? {
            let frame = out.join("frames").join(&name);
            move_file(&frame.join("truth.json"), &aside.join(format!("{name}.json")))?;
            for f in TRUTH_FILES {
                let p = frame.join(f);
                if p.exists() {
                    std::fs::remove_file(&p)
                        .map_err(|e| Error::Other(format!("{}: cannot remove: {e}", p.display())))?;
                }
            }
        }
    }
    plan.save(&dir.join(PLAN_FILE))?;
    Ok(())
}

fn move_file(from: &Path, to: &Path) -> Result<()> {
    std::fs::rename(from, to)
        .map_err(|e| Error::Other(format!("{}: cannot move to {}: {e}", from.display(), to.display())))
}

/// The hidden truth of frame `name` of placement `index`.
pub fn hidden_truth_path(hidden: &Path, index: usize, name: &str) -> PathBuf {
    hidden.join(placement_folder_name(index)).join(format!("{name}.json"))
}

/// The marks a scripted reviewer who knows the hidden truth gives placement `index`'s
/// estimated poses (`poses.jsonl`): correct when a pose was found within `cell`'s success
/// tolerances of the true one, wrong otherwise — what a careful person sees when the
/// outline lies on the tray or beside it.
pub fn scripted_marks(dir: &Path, hidden: &Path, index: usize, cell: &Cell) -> Result<Vec<Label>> {
    let folder = placement_dir(dir, index);
    let poses = read_poses(&folder)?;
    let mut out = Vec::with_capacity(poses.len());
    for pose in poses {
        let truth = TruthFile::load(&hidden_truth_path(hidden, index, &pose.frame))?;
        let symmetries: Vec<f32> = truth.symmetries.iter().map(|&s| s as f32).collect();
        let errors = pose_errors(
            &isometry_from_rows(&pose.t_world_tray),
            &isometry_from_rows(&truth.t_world_tray),
            &symmetries,
            &cell.metrics,
        );
        let mark = if pose.found && errors.success { Mark::Correct } else { Mark::Wrong };
        out.push(Label { frame: pose.frame, mark, pose: None });
    }
    Ok(out)
}
