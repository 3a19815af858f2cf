//! A sweep panel as a heat map: one coloured cell per grid placement with its value
//! written in, the best cell ringed in green (as in the paper's Figures 5 and 6).

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::font::FAMILY;
use super::plot::{viridis, Plot};

/// One panel of a sweep.
#[derive(Debug, Clone, PartialEq)]
pub struct HeatMap {
    /// Title above the panel.
    pub title: String,
    /// Axis captions.
    pub x_label: String,
    pub y_label: String,
    /// Grid values along each axis (ascending).
    pub xs: Vec<f64>,
    pub ys: Vec<f64>,
    /// One value per cell, index iy·nx + ix; `None` for a cell without data.
    pub values: Vec<Option<f64>>,
    /// The cell to ring, if any.
    pub best: Option<usize>,
    /// Digits after the decimal point written in the cells.
    pub decimals: usize,
}

impl Plot for HeatMap {
    fn size(&self) -> (u32, u32) {
        (560, 460)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String> {
        let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
        let (nx, ny) = (self.xs.len(), self.ys.len());
        let half = |v: &[f64]| if v.len() > 1 { 0.5 * (v[1] - v[0]) } else { 0.5 * v[0].abs().max(1.0) };
        let (hx, hy) = (half(&self.xs), half(&self.ys));
        let (x0, x1) = (self.xs[0] - hx, self.xs[nx - 1] + hx);
        let (y0, y1) = (self.ys[0] - hy, self.ys[ny - 1] + hy);
        let mut chart = ChartBuilder::on(root)
            .caption(&self.title, (FAMILY, 20))
            .margin(12)
            .x_label_area_size(42)
            .y_label_area_size(56)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(e)?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_desc(&self.x_label)
            .y_desc(&self.y_label)
            // The grid values label their own cells below (plotters would tick round numbers).
            .x_labels(0)
            .y_labels(0)
            .label_style((FAMILY, 13))
            .axis_desc_style((FAMILY, 15))
            .draw()
            .map_err(e)?;
        let finite: Vec<f64> = self.values.iter().flatten().copied().filter(|v| v.is_finite()).collect();
        let lo = finite.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = finite.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let span = if hi > lo { hi - lo } else { 1.0 };
        for iy in 0..ny {
            for ix in 0..nx {
                let (x, y) = (self.xs[ix], self.ys[iy]);
                let cell = [(x - hx, y - hy), (x + hx, y + hy)];
                let value = self.values[iy * nx + ix].filter(|v| v.is_finite());
                let (fill, ink) = match value {
                    Some(v) => {
                        let t = (v - lo) / span;
                        (viridis(t), if t < 0.55 { WHITE } else { BLACK })
                    }
                    None => (RGBColor(225, 225, 225), BLACK),
                };
                chart.draw_series(std::iter::once(Rectangle::new(cell, fill.filled()))).map_err(e)?;
                let text = value.map_or("–".to_string(), |v| format!("{v:.*}", self.decimals));
                let style =
                    TextStyle::from((FAMILY, 14).into_font()).color(&ink).pos(Pos::new(HPos::Center, VPos::Center));
                chart.draw_series(std::iter::once(Text::new(text, (x, y), style))).map_err(e)?;
            }
        }
        let label = |anchor: Pos| TextStyle::from((FAMILY, 13).into_font()).color(&BLACK).pos(anchor);
        for &x in &self.xs {
            let (px, py) = chart.backend_coord(&(x, y0));
            root.draw_text(&axis_value(x), &label(Pos::new(HPos::Center, VPos::Top)), (px, py + 6)).map_err(e)?;
        }
        for &y in &self.ys {
            let (px, py) = chart.backend_coord(&(x0, y));
            root.draw_text(&axis_value(y), &label(Pos::new(HPos::Right, VPos::Center)), (px - 6, py)).map_err(e)?;
        }
        if let Some(b) = self.best {
            let (x, y) = (self.xs[b % nx], self.ys[b / nx]);
            let area = chart.plotting_area().dim_in_pixel();
            let radius = (0.42 * (area.0 as f64 / nx as f64).min(area.1 as f64 / ny as f64)) as i32;
            let ring = ShapeStyle { color: RGBColor(0, 200, 0).to_rgba(), filled: false, stroke_width: 3 };
            chart.draw_series(std::iter::once(Circle::new((x, y), radius, ring))).map_err(e)?;
        }
        Ok(())
    }
}

/// A grid value as an axis label: up to two decimals, without trailing zeros ("400",
/// "5.54").
fn axis_value(v: f64) -> String {
    let text = format!("{v:.2}");
    text.trim_end_matches('0').trim_end_matches('.').to_string()
}

#[cfg(test)]
mod tests {
    use super::axis_value;

    #[test]
    fn axis_values_drop_trailing_zeros() {
        assert_eq!(axis_value(400.0), "400");
        assert_eq!(axis_value(0.0), "0");
        assert_eq!(axis_value(5.54), "5.54");
        assert_eq!(axis_value(81.5), "81.5");
        assert_eq!(axis_value(-12.0), "-12");
    }
}
