//! One mounting tolerance for people: success against the offset of one parameter, with the
//! 95 % interval of each point, the margin's floor dashed and the tolerated range shaded.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use super::font::FAMILY;
use super::plot::{save_plot, Plot, SavedPlot};
use crate::study::tolerance::{AxisTolerance, ToleranceReport};
use crate::Result;

/// The plot of one parameter's walk.
#[derive(Debug, Clone, PartialEq)]
struct TolerancePlot<'a> {
    axis: &'a AxisTolerance,
    /// Nominal success minus the margin, 0..1.
    floor: f64,
}

/// Writes `tolerance_PARAMETER.svg` and `.png` into `dir` for every parameter of `report`.
pub fn write_tolerance_plots(dir: &Path, report: &ToleranceReport) -> Result<Vec<SavedPlot>> {
    let mut saved = Vec::new();
    for axis in &report.axes {
        let plot = TolerancePlot { axis, floor: report.nominal.success_rate - report.margin };
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
        let lo = a.points.iter().map(|p| p.offset).fold(-a.step, f64::min) - 0.5 * a.step;
        let hi = a.points.iter().map(|p| p.offset).fold(a.step, f64::max) + 0.5 * a.step;
        let mut chart = ChartBuilder::on(root)
            .caption(format!("{}: tolerated −{} / +{} {}", a.parameter, a.minus, a.plus, a.unit), (FAMILY, 18))
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
        let floor = vec![(lo, 100.0 * self.floor), (hi, 100.0 * self.floor)];
        chart.draw_series(DashedLineSeries::new(floor, 8, 6, RED.stroke_width(2))).map_err(e)?;
        let blue = RGBColor(31, 119, 180);
        let bars = a.points.iter().map(|p| {
            let (x, cap) = (p.offset, 0.08 * a.step);
            let (lo, hi) = (100.0 * p.success_interval[0], 100.0 * p.success_interval[1]);
            PathElement::new(vec![(x - cap, lo), (x + cap, lo), (x, lo), (x, hi), (x - cap, hi), (x + cap, hi)], blue)
        });
        chart.draw_series(bars).map_err(e)?;
        let line = a.points.iter().map(|p| (p.offset, 100.0 * p.success_rate));
        chart.draw_series(LineSeries::new(line, blue.stroke_width(2))).map_err(e)?;
        let dots = a.points.iter().map(|p| Circle::new((p.offset, 100.0 * p.success_rate), 3, blue.filled()));
        chart.draw_series(dots).map_err(e)?;
        Ok(())
    }
}
