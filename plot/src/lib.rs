//! camplace's plots as files: one drawing routine written as `NAME.svg` and `NAME.png`, and the
//! TrueType font their text is drawn with. plotters' pure-Rust text needs one, and camplace
//! ships none: it is looked for once in `CAMPLACE_FONT` and the usual system places
//! (Debian's fonts-dejavu-core, macOS, Windows); without one, plots are skipped and the
//! caller keeps its tables. And the 3D view the HTML pages share (`view3d_html`), a canvas
//! viewer inlined into the page.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use plotters::coord::Shift;
use plotters::prelude::*;

mod view3d;
pub use view3d::{legend_entry, view3d_html, ViewCanvas};

/// A plot that could not be drawn into its file: `PATH: cannot draw the plot: why`.
#[derive(Debug, Clone, PartialEq)]
pub struct Error {
    /// The file being drawn.
    pub path: PathBuf,
    /// What the drawing backend said.
    pub message: String,
}

impl std::fmt::Display for Error {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: cannot draw the plot: {}", self.path.display(), self.message)
    }
}

impl std::error::Error for Error {}

/// The family name plots ask for.
pub const PLOT_FONT_FAMILY: &str = "sans-serif";

const FONT_CANDIDATES: [&str; 7] = [
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
    "/System/Library/Fonts/Supplemental/Arial.ttf",
    "/Library/Fonts/Arial.ttf",
    "C:\\Windows\\Fonts\\arial.ttf",
];

/// Registers a font for [`PLOT_FONT_FAMILY`] once; `Err` says what to install when none is
/// found.
pub fn ensure_plot_font() -> Result<(), String> {
    static READY: OnceLock<Result<(), String>> = OnceLock::new();
    READY
        .get_or_init(|| {
            let paths = std::env::var("CAMPLACE_FONT").into_iter().chain(FONT_CANDIDATES.iter().map(|s| s.to_string()));
            for path in paths {
                let Ok(bytes) = std::fs::read(&path) else { continue };
                let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
                for style in [plotters::style::FontStyle::Normal, plotters::style::FontStyle::Bold] {
                    if plotters::style::register_font(PLOT_FONT_FAMILY, style, bytes).is_err() {
                        break;
                    }
                }
                return Ok(());
            }
            Err("no TrueType font found for plot text (install fonts-dejavu-core or set CAMPLACE_FONT to a .ttf file)"
                .to_string())
        })
        .clone()
}

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
/// (said once on stderr): the caller goes on without pictures.
pub fn save_plot(plot: &impl Plot, dir: &Path, name: &str) -> Result<Option<SavedPlot>, Error> {
    if let Err(why) = ensure_plot_font() {
        static SAID: std::sync::Once = std::sync::Once::new();
        SAID.call_once(|| eprintln!("note: {why}; plots skipped"));
        return Ok(None);
    }
    let (w, h) = plot.size();
    let svg = dir.join(format!("{name}.svg"));
    let png = dir.join(format!("{name}.png"));
    let fail = |path: &Path, message: String| Error { path: path.to_path_buf(), message };
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
