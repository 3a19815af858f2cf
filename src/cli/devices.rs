//! `camplace devices`: the cameras this machine has (V4L2 nodes with their formats, USB
//! cameras, FireWire cameras). Finding none is an error (exit 2) with what was looked at, so
//! a script checking the cell PC stops there.

use anyhow::bail;
use camplace_hwio::list_devices;
use std::process::ExitCode;

/// Flags of `camplace devices`.
#[derive(clap::Args, Debug)]
pub struct Args {}

/// Runs `camplace devices`.
pub fn run(_a: Args) -> anyhow::Result<ExitCode> {
    let list = list_devices()?;
    if list.is_empty() {
        let mut why = format!(
            "no camera found: no V4L2 node in /dev, no USB video-class or stereo camera, no FireWire camera{}",
            if cfg!(feature = "dc1394") { "" } else { " in sysfs (build with --features dc1394 to ask libdc1394)" }
        );
        for note in &list.notes {
            why.push_str("; ");
            why.push_str(note);
        }
        bail!(why);
    }
    out!("{list}");
    Ok(ExitCode::SUCCESS)
}
