//! The deployed loop's latency for people: per frame, the estimator's stages stacked with
//! the capture-to-pose latency on top (the gap is the wait for the frame before), and a
//! histogram of the capture-to-pose latency against the frame budget (each method's, from
//! docs/design/performance-budgets.md); and where a `--latency-plot` path puts the two files.

use std::path::{Path, PathBuf};

use camplace_estimator::{depth::Method, StageTimings};
use camplace_plot::{save_plot, Plot, SavedPlot, PLOT_FONT_FAMILY as FAMILY};
use plotters::coord::Shift;
use plotters::prelude::*;

use crate::{Error, FrameTiming, Result};

/// The capture-to-pose budget of one frame of `method`, ms: 100 for one shot, a p99 of 150
/// for 12 shots.
pub fn frame_budget_ms(method: Method) -> f64 {
    match method {
        Method::OneShot => 100.0,
        Method::Phase12 => 150.0,
    }
}

/// The folder and file name stem of a latency plot at `path`, checked before a run so a bad
/// path cannot end a run whose poses were written. A name ending in `.png` or `.svg` stands
/// for its stem: both files are drawn either way. The error names `--latency-plot`.
pub fn latency_plot_target(path: &Path) -> Result<(PathBuf, String)> {
    let dir = path.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let stem = |name: &str| {
        [".png", ".svg"]
            .iter()
            .find_map(|ext| name.strip_suffix(ext))
            .filter(|s| !s.is_empty())
            .unwrap_or(name)
            .to_string()
    };
    match path.file_name().and_then(|n| n.to_str()) {
        Some(name) if dir.is_dir() => Ok((dir.to_path_buf(), stem(name))),
        _ => {
            Err(Error::input(format!("--latency-plot {}: expected a file name in an existing folder", path.display())))
        }
    }
}

/// Stage colours, in [`StageTimings::STAGES`] order (a qualitative palette: neighbours
/// differ).
const STAGE_COLOURS: [RGBColor; 10] = [
    RGBColor(141, 211, 199),
    RGBColor(31, 119, 180),
    RGBColor(255, 187, 120),
    RGBColor(152, 223, 138),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(255, 127, 14),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
];

/// Histogram bins over the latency axis.
const BINS: usize = 30;

/// The two-panel latency figure of one run.
#[derive(Debug, Clone, PartialEq)]
pub struct LatencyPlot<'a> {
    /// Every estimated frame, in stream order.
    pub frames: &'a [FrameTiming],
    /// The capture-to-pose budget drawn as a dashed line, ms.
    pub budget_ms: f64,
}

/// Draws `frames` into `dir/NAME.svg` and `dir/NAME.png` (see [`save_plot`]).
pub fn write_latency_plot(dir: &Path, name: &str, frames: &[FrameTiming], budget_ms: f64) -> Result<Option<SavedPlot>> {
    Ok(save_plot(&LatencyPlot { frames, budget_ms }, dir, name)?)
}

impl LatencyPlot<'_> {
    /// The top of both panels' latency axis, ms: the slowest frame or the budget, with room.
    fn top_ms(&self) -> f64 {
        let slowest = self.frames.iter().map(|f| f.latency_ms.max(f.stages.total_ms)).fold(0.0, f64::max);
        (slowest.max(self.budget_ms) * 1.1).max(1.0)
    }

    /// Frames per histogram bin of width `top / BINS`, from 0.
    fn histogram(&self, top: f64) -> [u32; BINS] {
        let mut counts = [0u32; BINS];
        for f in self.frames {
            let bin = ((f.latency_ms / top) * BINS as f64).floor();
            let bin = if bin.is_finite() { (bin.max(0.0) as usize).min(BINS - 1) } else { BINS - 1 };
            counts[bin] += 1;
        }
        counts
    }
}

impl Plot for LatencyPlot<'_> {
    fn size(&self) -> (u32, u32) {
        (1200, 460)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> std::result::Result<(), String> {
        let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
        let (left, rest) = root.split_horizontally(680);
        let (legend, right) = rest.split_horizontally(150);
        let top = self.top_ms();
        let first = self.frames.first().map_or(0, |f| f.sequence) as f64;
        let last = self.frames.last().map_or(1, |f| f.sequence) as f64;
        let whole = |v: &f64| format!("{v:.0}");
        let mut chart = ChartBuilder::on(&left)
            .caption("per frame: the estimator's stages and capture to pose", (FAMILY, 18))
            .margin(12)
            .x_label_area_size(42)
            .y_label_area_size(56)
            .build_cartesian_2d((first - 0.5)..(last + 0.5), 0f64..top)
            .map_err(e)?;
        chart
            .configure_mesh()
            .disable_x_mesh()
            .x_labels(12)
            .x_label_formatter(&whole)
            .y_label_formatter(&whole)
            .x_desc("frame (stream sequence; gaps are dropped frames)")
            .y_desc("ms")
            .label_style((FAMILY, 13))
            .axis_desc_style((FAMILY, 15))
            .draw()
            .map_err(e)?;
        let mut keys: Vec<(String, ShapeStyle)> = Vec::new();
        for (k, name) in StageTimings::STAGES.iter().enumerate() {
            if self.frames.iter().all(|f| f.stages.by_stage()[k] == 0.0) {
                continue;
            }
            let colour = STAGE_COLOURS[k];
            let bars = self.frames.iter().map(|f| {
                let times = f.stages.by_stage();
                let below: f64 = times[..k].iter().sum();
                let x = f.sequence as f64;
                Rectangle::new([(x - 0.4, below), (x + 0.4, below + times[k])], colour.filled())
            });
            chart.draw_series(bars).map_err(e)?;
            keys.push((name.to_string(), colour.filled()));
        }
        let latency = self.frames.iter().map(|f| Circle::new((f.sequence as f64, f.latency_ms), 3, BLACK.filled()));
        chart.draw_series(latency).map_err(e)?;
        let budget = vec![(first - 0.5, self.budget_ms), (last + 0.5, self.budget_ms)];
        chart.draw_series(DashedLineSeries::new(budget, 8, 6, RED.stroke_width(2))).map_err(e)?;

        // The key, beside the chart so it hides no frame.
        let text = (FAMILY, 13).into_font().color(&BLACK);
        let mut y = 50;
        for (name, style) in keys.iter().rev() {
            legend.draw(&Rectangle::new([(4, y - 6), (18, y + 6)], *style)).map_err(e)?;
            legend.draw(&Text::new(name.clone(), (26, y - 7), text.clone())).map_err(e)?;
            y += 20;
        }
        legend.draw(&Circle::new((11, y), 3, BLACK.filled())).map_err(e)?;
        legend.draw(&Text::new("capture to pose", (26, y - 7), text.clone())).map_err(e)?;
        y += 20;
        legend.draw(&PathElement::new(vec![(2, y), (20, y)], RED.stroke_width(2))).map_err(e)?;
        legend.draw(&Text::new(format!("budget {:.0} ms", self.budget_ms), (26, y - 7), text)).map_err(e)?;

        let counts = self.histogram(top);
        let most = counts.iter().copied().max().unwrap_or(0).max(1);
        let mut hist = ChartBuilder::on(&right)
            .caption("capture to pose", (FAMILY, 18))
            .margin(12)
            .x_label_area_size(42)
            .y_label_area_size(48)
            .build_cartesian_2d(0f64..top, 0f64..f64::from(most) * 1.15)
            .map_err(e)?;
        hist.configure_mesh()
            .disable_x_mesh()
            .x_labels(5)
            .y_labels((most as usize + 1).min(8))
            .x_label_formatter(&whole)
            .y_label_formatter(&whole)
            .x_desc("ms")
            .y_desc("frames")
            .label_style((FAMILY, 13))
            .axis_desc_style((FAMILY, 15))
            .draw()
            .map_err(e)?;
        let width = top / BINS as f64;
        let bars = counts.iter().enumerate().map(|(i, &n)| {
            let x = i as f64 * width;
            Rectangle::new([(x, 0.0), (x + width * 0.95, f64::from(n))], RGBColor(31, 119, 180).filled())
        });
        hist.draw_series(bars).map_err(e)?;
        let line = vec![(self.budget_ms, 0.0), (self.budget_ms, f64::from(most) * 1.15)];
        hist.draw_series(DashedLineSeries::new(line, 8, 6, RED.stroke_width(2))).map_err(e)?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_latency_plot_named_with_its_extension_is_drawn_under_its_stem() {
        let dir = std::env::temp_dir();
        for (given, stem) in
            [("lat", "lat"), ("lat.png", "lat"), ("lat.svg", "lat"), ("lat.v2", "lat.v2"), (".png", ".png")]
        {
            let (folder, name) = latency_plot_target(&dir.join(given)).unwrap();
            assert_eq!((folder, name.as_str()), (dir.clone(), stem), "--latency-plot {given}");
        }
        assert!(latency_plot_target(&dir.join("no/such/folder/lat.png")).is_err());
    }

    fn frame(sequence: u64, latency_ms: f64) -> FrameTiming {
        let stages = StageTimings {
            disparity_ms: 10.0,
            ransac_ms: latency_ms - 10.0,
            total_ms: latency_ms,
            ..StageTimings::default()
        };
        FrameTiming { sequence, latency_ms, stages, cpu_ms: latency_ms }
    }

    #[test]
    fn the_histogram_counts_every_frame_once_in_its_bin() {
        let frames: Vec<FrameTiming> = (0..200).map(|i| frame(i, 10.0 + (i % 97) as f64)).collect();
        let plot = LatencyPlot { frames: &frames, budget_ms: 100.0 };
        let top = plot.top_ms();
        let counts = plot.histogram(top);
        assert_eq!(counts.iter().sum::<u32>(), 200);
        for (i, &n) in counts.iter().enumerate() {
            let (lo, hi) = (i as f64 * top / BINS as f64, (i + 1) as f64 * top / BINS as f64);
            let slow = frames.iter().filter(|f| f.latency_ms >= lo && f.latency_ms < hi).count() as u32;
            assert_eq!(n, slow, "bin {i} [{lo}, {hi})");
        }
    }

    #[test]
    fn both_files_are_written_when_a_font_is_found() {
        let dir = tempfile::tempdir().unwrap();
        let frames: Vec<FrameTiming> = (0..20).filter(|i| i % 5 != 3).map(|i| frame(i, 40.0 + i as f64)).collect();
        match write_latency_plot(dir.path(), "latency", &frames, 100.0).unwrap() {
            Some(saved) => {
                let svg = std::fs::read_to_string(&saved.svg).unwrap();
                assert!(svg.contains("capture to pose") && svg.contains("ransac"), "legend missing");
                assert!(std::fs::metadata(&saved.png).unwrap().len() > 1000);
            }
            None => assert!(camplace_plot::ensure_plot_font().is_err(), "a font was found but nothing was drawn"),
        }
    }
}
