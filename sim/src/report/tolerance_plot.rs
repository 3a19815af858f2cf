//! One mounting tolerance for people: success against the offset of one parameter, with the
//! 95 % interval of each point, the points judged outside in red and the tolerated range
//! shaded.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::Result;
use camplace_config::{AxisTolerance, TolerancePoint, ToleranceReport, WalkEnd};
use camplace_plot::{save_plot, Plot, SavedPlot, PLOT_FONT_FAMILY as FAMILY};

/// The plot of one parameter's walk.
#[derive(Debug, Clone, PartialEq)]
struct TolerancePlot<'a> {
    axis: &'a AxisTolerance,
    /// The paired test's level: below it a point is outside.
    level: f64,
}

/// Writes `tolerance_PARAMETER.svg` and `.png` into `dir` for every parameter of `report`.
pub fn write_tolerance_plots(dir: &Path, report: &ToleranceReport) -> Result<Vec<SavedPlot>> {
    let mut saved = Vec::new();
    for axis in &report.axes {
        let plot = TolerancePlot { axis, level: report.level };
        if let Some(s) = save_plot(&plot, dir, &format!("tolerance_{}", axis.parameter))? {
            saved.push(s);
        }
    }
    Ok(saved)
}

impl Plot for TolerancePlot<'_> {
    fn size(&self) -> (u32, u32) {
        (560, 380)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> std::result::Result<(), String> {
        let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
        let a = self.axis;
        let step = a.resolution;
        let lo = a.points.iter().map(|p| p.offset).fold(-step, f64::min) - 2.0 * step;
        let hi = a.points.iter().map(|p| p.offset).fold(step, f64::max) + 2.0 * step;
        let side = |t: f64, end: WalkEnd, sign: &str| {
            let bound = if end == WalkEnd::RangeEnd { "at least " } else { "" };
            format!("{bound}{sign}{t}")
        };
        let mut chart = ChartBuilder::on(root)
            .caption(
                format!(
                    "{}: tolerated {} / {} {}",
                    a.parameter,
                    side(a.minus, a.minus_end, "−"),
                    side(a.plus, a.plus_end, "+"),
                    a.unit
                ),
                (FAMILY, 18),
            )
            .margin(12)
            .x_label_area_size(42)
            .y_label_area_size(56)
            .build_cartesian_2d(lo..hi, 0f64..105f64)
            .map_err(e)?;
        let plain = |v: &f64| format!("{v}");
        let whole = |v: &f64| format!("{v:.0}");
        chart
            .configure_mesh()
            .x_label_formatter(&plain)
            .y_label_formatter(&whole)
            .x_desc(format!("offset from the nominal {}, {}", a.parameter, a.unit))
            .y_desc("success rate, %")
            .label_style((FAMILY, 13))
            .axis_desc_style((FAMILY, 15))
            .draw()
            .map_err(e)?;
        let shade = RGBColor(44, 160, 44).mix(0.15).filled();
        chart.draw_series([Rectangle::new([(-a.minus, 0.0), (a.plus, 105.0)], shade)]).map_err(e)?;
        let blue = RGBColor(31, 119, 180);
        let red = RGBColor(214, 39, 40);
        // A point is outside when the paired test showed a drop there.
        let ink = |p: &TolerancePoint| if p.p_lower < self.level { red } else { blue };
        let cap = 0.004 * (hi - lo);
        let bars = a.points.iter().map(|p| {
            let x = p.offset;
            let (lo, hi) = (100.0 * p.success_interval[0], 100.0 * p.success_interval[1]);
            PathElement::new(vec![(x - cap, lo), (x + cap, lo), (x, lo), (x, hi), (x - cap, hi), (x + cap, hi)], ink(p))
        });
        chart.draw_series(bars).map_err(e)?;
        let line = a.points.iter().map(|p| (p.offset, 100.0 * p.success_rate));
        chart.draw_series(LineSeries::new(line, blue.mix(0.5).stroke_width(1))).map_err(e)?;
        let dots = a.points.iter().map(|p| Circle::new((p.offset, 100.0 * p.success_rate), 3, ink(p).filled()));
        chart.draw_series(dots).map_err(e)?;
        Ok(())
    }
}
