//! `camplace project`: the structured-light pattern full screen on the projector's monitor
//! (feature `display`). One shot shows the random dots; phase-12 shows the 12 fringes in
//! turn. With `--source` and `--out`, each pattern is shown, left to settle and captured in
//! step, and the shots are written as the next frame of a recorded dataset; without them the
//! patterns stay on (phase-12 cycles) until Ctrl-C.

use camplace_estimator::depth::Method;
use std::path::PathBuf;
use std::process::ExitCode;

/// Flags of `camplace project`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Cell file (TOML) with the projector's resolution and pattern settings; the built-in
    /// default when not given.
    #[arg(long, value_name = "FILE")]
    cell: Option<PathBuf>,
    /// one-shot (random dots) or phase-12 (12 phase-shift fringes).
    #[arg(long, default_value = "one-shot")]
    method: Method,
    /// Seed of the random dots (default: the cell's scenarios.seed, as `camplace model` uses).
    #[arg(long)]
    seed: Option<u64>,
    /// The projector's monitor: an index in the X server's monitor list (default: the primary).
    #[arg(long, value_name = "N")]
    monitor: Option<usize>,
    /// Time a pattern stays on screen before the cameras are read: the projector's input
    /// lag plus one exposure, ms.
    #[arg(long, value_name = "MS", default_value_t = 150)]
    settle_ms: u64,
    /// Capture each pattern in step from this source (a spec as `run --source` takes).
    #[arg(long, value_name = "SPEC", requires = "out")]
    source: Option<String>,
    /// The dataset folder the captured frame is added to (frames/NNNN/, the next number).
    #[arg(long, value_name = "DIR", requires = "source")]
    out: Option<PathBuf>,
    /// Calibration copied to the dataset's rig.json when it has none yet.
    #[arg(long, value_name = "FILE", requires = "out")]
    rig: Option<PathBuf>,
    /// Camera frames thrown away after each pattern settled, so frames queued in the
    /// driver before the pattern changed are not kept.
    #[arg(long, value_name = "N", default_value_t = 1)]
    skip: usize,
}

/// Runs `camplace project`.
#[cfg(not(feature = "display"))]
pub fn run(_a: Args) -> anyhow::Result<ExitCode> {
    anyhow::bail!(
        "project: the projector window needs the `display` feature, which this build lacks; \
         rebuild with `cargo build --release --features display`"
    )
}

/// Runs `camplace project`.
#[cfg(feature = "display")]
pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    shown::run(a)
}

/// The patterns `method` projects: one-shot's random dots of `seed` (default: the cell's
/// scenarios.seed, as `camplace model` uses), or phase-12's 12 fringes.
#[cfg(feature = "display")]
pub(crate) fn patterns(
    cell: &camplace_config::Cell,
    method: Method,
    seed: Option<u64>,
) -> Vec<camplace_config::GrayImage> {
    match method {
        Method::OneShot => vec![camplace_estimator::depth::one_shot(&cell.sensor, seed.unwrap_or(cell.scenarios.seed))],
        Method::Phase12 => camplace_estimator::depth::fringe_set(&cell.sensor),
    }
}

/// Says so when the monitor of size `(w, h)` is not the cell's projector resolution.
#[cfg(feature = "display")]
pub(crate) fn note_monitor_size((w, h): (u32, u32), cell: &camplace_config::Cell) {
    let [pw, ph] = cell.sensor.projector_resolution;
    if (w, h) != (pw, ph) {
        noteln!(
            "note: the monitor is {w}x{h} but the cell's projector is {pw}x{ph}; the pattern is shown \
             at the top-left pixel for pixel (set the projector to its native resolution)"
        );
    }
}

#[cfg(feature = "display")]
mod shown {
    use super::Args;
    use anyhow::Context;
    use camplace_config::Cell;
    use camplace_config::GrayImage;
    use camplace_hwio::Projector;
    use camplace_hwio::{append_frame, open_source, parse_source, FrameSource};
    use std::path::Path;
    use std::process::ExitCode;
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::Arc;

    pub fn run(a: Args) -> anyhow::Result<ExitCode> {
        let cell = Cell::load_or_default(a.cell.as_deref())?;
        let patterns = super::patterns(&cell, a.method, a.seed);
        // The source first: a missing camera is reported before a window opens.
        let source = a.source.as_deref().map(|s| open_source(&parse_source(s)?)).transpose()?;
        let mut projector = Projector::open(a.monitor)?;
        super::note_monitor_size(projector.size(), &cell);
        match (source, &a.out) {
            (Some(source), Some(out)) => capture(&a, source, &mut projector, &patterns, out),
            _ => until_interrupted(&a, &mut projector, &patterns),
        }
    }

    /// Shows the patterns (cycling through them) until Ctrl-C.
    fn until_interrupted(a: &Args, projector: &mut Projector, patterns: &[GrayImage]) -> anyhow::Result<ExitCode> {
        let stop = Arc::new(AtomicBool::new(false));
        let on_signal = stop.clone();
        ctrlc::set_handler(move || on_signal.store(true, Ordering::SeqCst)).context("Ctrl-C handler")?;
        noteln!("showing {} pattern(s) ({}); Ctrl-C ends", patterns.len(), a.method);
        // A single pattern is redrawn now and then, which also repairs an expose.
        let hold = if patterns.len() == 1 { 100 } else { a.settle_ms };
        'shown: loop {
            for p in patterns {
                projector.show(p, hold)?;
                if stop.load(Ordering::SeqCst) {
                    break 'shown;
                }
            }
        }
        Ok(ExitCode::SUCCESS)
    }

    /// Shows each pattern, lets it settle, reads the source, and writes the shots as the
    /// next frame of the dataset `out`.
    fn capture(
        a: &Args,
        mut source: Box<dyn FrameSource + Send>,
        projector: &mut Projector,
        patterns: &[GrayImage],
        out: &Path,
    ) -> anyhow::Result<ExitCode> {
        let frame = projector.capture(source.as_mut(), patterns, a.settle_ms, a.skip)?;
        let dir = append_frame(out, &frame, a.rig.as_deref())?;
        outln!("captured {} pattern(s) ({}) into {}", patterns.len(), a.method, dir.display());
        Ok(ExitCode::SUCCESS)
    }
}
