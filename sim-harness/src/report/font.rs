//! The TrueType font plot text is drawn with: plotters' pure-Rust text needs one, and
//! camplace ships none. It is looked for once in `CAMPLACE_FONT` and the usual system
//! places (Debian's fonts-dejavu-core, macOS, Windows); without one, plots are skipped and
//! the report keeps its tables.

use std::sync::OnceLock;

/// The family name plots ask for.
pub const FAMILY: &str = "sans-serif";

const CANDIDATES: [&str; 7] = [
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
    "/System/Library/Fonts/Supplemental/Arial.ttf",
    "/Library/Fonts/Arial.ttf",
    "C:\\Windows\\Fonts\\arial.ttf",
];

/// Registers a font for [`FAMILY`] once; `Err` says what to install when none is found.
pub fn ensure() -> Result<(), String> {
    static READY: OnceLock<Result<(), String>> = OnceLock::new();
    READY
        .get_or_init(|| {
            let paths = std::env::var("CAMPLACE_FONT").into_iter().chain(CANDIDATES.iter().map(|s| s.to_string()));
            for path in paths {
                let Ok(bytes) = std::fs::read(&path) else { continue };
                let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
                for style in [plotters::style::FontStyle::Normal, plotters::style::FontStyle::Bold] {
                    if plotters::style::register_font(FAMILY, style, bytes).is_err() {
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
