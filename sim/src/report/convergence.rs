//! The search's convergence like the paper's Figure 7: the best verified success rate found so far
//! against the evaluation count, one line per search, and each search's sweep best as a
//! dashed line of the same colour.

use plotters::coord::Shift;
use plotters::prelude::*;

use camplace_plot::{Plot, PLOT_FONT_FAMILY as FAMILY};

/// One search's curve.
#[derive(Debug, Clone, PartialEq)]
pub struct Curve {
    /// Legend text.
    pub label: String,
    /// Success rate of each evaluation, in order (0..1).
    pub rates: Vec<f64>,
    /// The 2-parameter sweep's best rate, drawn dashed, if a sweep was run.
    pub sweep_best: Option<f64>,
}

/// The convergence figure.
#[derive(Debug, Clone, PartialEq)]
pub struct Convergence {
    /// Title above the plot.
    pub title: String,
    /// The curves.
    pub curves: Vec<Curve>,
}

const COLOURS: [RGBColor; 4] =
    [RGBColor(31, 119, 180), RGBColor(214, 39, 40), RGBColor(44, 160, 44), RGBColor(148, 103, 189)];

impl Plot for Convergence {
    fn size(&self) -> (u32, u32) {
        (720, 440)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String> {
        let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
        let n = self.curves.iter().map(|c| c.rates.len()).max().unwrap_or(1).max(2);
        let mut chart = ChartBuilder::on(root)
            .caption(&self.title, (FAMILY, 20))
            .margin(12)
            .x_label_area_size(42)
            .y_label_area_size(56)
            .build_cartesian_2d(1f64..n as f64, 0f64..100f64)
            .map_err(e)?;
        chart
            .configure_mesh()
            .x_desc("evaluation")
            .y_desc("verified success rate, %")
            .label_style((FAMILY, 13))
            .axis_desc_style((FAMILY, 15))
            .draw()
            .map_err(e)?;
        for (k, c) in self.curves.iter().enumerate() {
            let colour = COLOURS[k % COLOURS.len()];
            let mut best = f64::NEG_INFINITY;
            let running: Vec<(f64, f64)> = c
                .rates
                .iter()
                .enumerate()
                .map(|(i, &r)| {
                    best = best.max(r);
                    ((i + 1) as f64, 100.0 * best)
                })
                .collect();
            chart
                .draw_series(LineSeries::new(running, colour.stroke_width(2)))
                .map_err(e)?
                .label(c.label.clone())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], colour.stroke_width(2)));
            let dots =
                c.rates.iter().enumerate().map(|(i, &r)| Circle::new(((i + 1) as f64, 100.0 * r), 2, colour.filled()));
            chart.draw_series(dots).map_err(e)?;
            if let Some(s) = c.sweep_best {
                let line = vec![(1.0, 100.0 * s), (n as f64, 100.0 * s)];
                chart.draw_series(DashedLineSeries::new(line, 8, 6, colour.stroke_width(1))).map_err(e)?;
            }
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::LowerRight)
            .label_font((FAMILY, 13))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()
            .map_err(e)?;
        Ok(())
    }
}
