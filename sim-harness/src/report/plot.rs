//! Writing one plot as `NAME.svg` and `NAME.png` from a single drawing routine.

use std::path::{Path, PathBuf};

use plotters::coord::Shift;
use plotters::prelude::*;

use super::font;
use crate::{Error, Result};

/// A figure that can draw itself on any plotters backend.
pub trait Plot {
    /// Size in pixels.
    fn size(&self) -> (u32, u32);
    /// Draws on `root` (already white), errors in words.
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> std::result::Result<(), String>;
}

/// Where a plot went.
#[derive(Debug, Clone, PartialEq)]
pub struct SavedPlot {
    /// `NAME.svg`.
    pub svg: PathBuf,
    /// `NAME.png`.
    pub png: PathBuf,
}

/// Draws `plot` into `dir/NAME.svg` and `dir/NAME.png`. `Ok(None)` when no font is found
/// (said once on stderr): the study goes on without pictures.
pub fn save_plot(plot: &impl Plot, dir: &Path, name: &str) -> Result<Option<SavedPlot>> {
    if let Err(why) = font::ensure() {
        static SAID: std::sync::Once = std::sync::Once::new();
        SAID.call_once(|| eprintln!("note: {why}; plots skipped"));
        return Ok(None);
    }
    let (w, h) = plot.size();
    let svg = dir.join(format!("{name}.svg"));
    let png = dir.join(format!("{name}.png"));
    let fail = |path: &Path, e: String| Error::Other(format!("{}: cannot draw the plot: {e}", path.display()));
    {
        let root = SVGBackend::new(&svg, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| fail(&svg, e.to_string()))?;
        plot.draw(&root).map_err(|e| fail(&svg, e))?;
        root.present().map_err(|e| fail(&svg, e.to_string()))?;
    }
    {
        let root = BitMapBackend::new(&png, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| fail(&png, e.to_string()))?;
        plot.draw(&root).map_err(|e| fail(&png, e))?;
        root.present().map_err(|e| fail(&png, e.to_string()))?;
    }
    Ok(Some(SavedPlot { svg, png }))
}

/// A colour on a perceptually even ramp (viridis, piecewise linear), t in [0, 1].
pub fn viridis(t: f64) -> RGBColor {
    const STOPS: [(u8, u8, u8); 6] =
        [(68, 1, 84), (65, 68, 135), (42, 120, 142), (34, 168, 132), (122, 209, 81), (253, 231, 37)];
    let t = if t.is_finite() { t.clamp(0.0, 1.0) } else { 0.0 } * (STOPS.len() - 1) as f64;
    let i = (t.floor() as usize).min(STOPS.len() - 2);
    let f = t - i as f64;
    let mix = |a: u8, b: u8| (a as f64 + (b as f64 - a as f64) * f).round() as u8;
    let (a, b) = (STOPS[i], STOPS[i + 1]);
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}
