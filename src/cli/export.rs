//! `camplace export`: the cell at a placement, a calibrated rig or a study's recommendation
//! as a glTF 2.0 binary (`.glb`) for 3D tools: table, tray, a scenario's items, the lamp,
//! the cameras' and the projector's frustums, and optionally a frame's measured cloud.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::bail;
use camplace_config::{RecordedDataset, RigFile};
use camplace_estimator::{geometry::as_built, geometry::rig_for, geometry::sensor_rig, Rig};
use camplace_sim::{cell_parts, draw_scenario, write_cell_glb};

use super::cell_args::CellArgs;

/// Flags of `camplace export`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The cell, and the placement its rig is drawn at (unless --rig or --study give it).
    #[command(flatten)]
    cell: CellArgs,
    /// A calibrated rig.json: its cameras (and its projector, else the one its as-built
    /// placement would have, relative to its left camera).
    #[arg(long, value_name = "FILE", conflicts_with_all = ["placement", "study"])]
    rig: Option<PathBuf>,
    /// A study folder: the rig at its recommended placement (recommended.json).
    #[arg(long, value_name = "DIR", conflicts_with = "placement")]
    study: Option<PathBuf>,
    /// The scenario whose tray pose, items and lamp are drawn.
    #[arg(long, default_value_t = 0)]
    scenario: u64,
    /// The scenarios' seed (default: the cell's scenarios.seed).
    #[arg(long)]
    seed: Option<u64>,
    /// A recorded dataset: with --frame, its frame's cloud.ply as points.
    #[arg(long, value_name = "DIR", requires = "frame")]
    dataset: Option<PathBuf>,
    /// The frame of --dataset (0-based) whose cloud.ply is drawn.
    #[arg(long, value_name = "N", requires = "dataset")]
    frame: Option<usize>,
    /// The .glb to write.
    #[arg(long, value_name = "FILE")]
    out: PathBuf,
}

/// Runs `camplace export`.
pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    if a.out.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() != Some("glb") {
        bail!("--out {}: expected a file name ending in .glb (glTF 2.0 binary)", a.out.display());
    }
    let (mut cell, mut placement) = a.cell.load()?;
    if let Some(dir) = &a.study {
        placement = camplace_sim::Recommended::load(dir)?.placement;
    }
    let rig = match &a.rig {
        Some(path) => {
            let file = RigFile::load(path)?;
            // A rig.json without a projector gets the one its as-built placement would have.
            let built = as_built(&Rig::from_file(&file)).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
            placement = built.placement;
            cell.rig = Some(file);
            sensor_rig(&cell, &placement)
        }
        None => rig_for(&placement, &cell.sensor),
    };
    let seed = a.seed.unwrap_or(cell.scenarios.seed);
    let scenario = draw_scenario(&cell, seed, a.scenario);
    let cloud = match (&a.dataset, a.frame) {
        (Some(dir), Some(frame)) => {
            let data = RecordedDataset::open(dir)?;
            let Some(frame_dir) = data.frame_dirs().get(frame) else {
                bail!(
                    "--frame {frame}: expected 0 to {} ({} has {} frames)",
                    data.frame_dirs().len() - 1,
                    dir.display(),
                    data.frame_dirs().len()
                );
            };
            let path = frame_dir.join("cloud.ply");
            if !path.is_file() {
                bail!(
                    "{}: no cloud.ply; camplace reconstruct --dataset {} writes each frame's",
                    frame_dir.display(),
                    dir.display()
                );
            }
            Some(camplace_config::read_cloud(&path)?.points)
        }
        _ => None,
    };
    let parts = cell_parts(&cell, &rig, &scenario)?;
    let written = write_cell_glb(&a.out, &parts, cloud.as_deref())?;
    let source = match (&a.rig, &a.study) {
        (Some(rig), _) => format!("the rig of {}", rig.display()),
        (None, Some(dir)) => format!("{}'s recommendation, {placement}", dir.display()),
        (None, None) => format!("{placement}"),
    };
    let cloud_text =
        if written.cloud_points > 0 { format!(", {} cloud points", written.cloud_points) } else { String::new() };
    outln!(
        "wrote {} ({} bytes): the cell at {source}, scenario {} of seed {seed}; nodes {}{cloud_text}",
        a.out.display(),
        written.bytes,
        a.scenario,
        written.nodes.join(", ")
    );
    Ok(ExitCode::SUCCESS)
}
