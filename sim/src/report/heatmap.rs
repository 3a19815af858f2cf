//! A sweep panel as a heat map: one coloured cell per grid placement with its value
//! written in, the best cell ringed in green (as in the paper's Figures 5 and 6), and a
//! legend beside it. A success map is coloured on a fixed 0–100 % scale, so one colour
//! means one rate on every map; another map is coloured over its own range, which the
//! legend states; a map of one value is drawn in one colour, its legend saying so.

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use camplace_plot::{Plot, PLOT_FONT_FAMILY as FAMILY};

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
    /// What the colours span.
    pub scale: ColourScale,
}

/// What a heat map's colours span.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ColourScale {
    /// From `lo` (the ramp's dark end) to `hi` on every map of this kind (success: 0–100).
    Fixed {
        /// The value of the dark end.
        lo: f64,
        /// The value of the bright end.
        hi: f64,
    },
    /// From the map's lowest value to its highest.
    Range,
}

/// The span the colours cover and where a value sits on the ramp (0..1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Legend {
    /// The value of the dark end.
    pub lo: f64,
    /// The value of the bright end.
    pub hi: f64,
    /// Whether every cell holds the same value (a map's own range of one value).
    pub uniform: bool,
}

impl Legend {
    /// The legend of `values` on `scale` (`None`: no finite value).
    pub fn of(scale: ColourScale, values: &[Option<f64>]) -> Option<Legend> {
        let finite: Vec<f64> = values.iter().flatten().copied().filter(|v| v.is_finite()).collect();
        if finite.is_empty() {
            return None;
        }
        let lo = finite.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = finite.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        Some(match scale {
            ColourScale::Fixed { lo, hi } => Legend { lo, hi, uniform: false },
            ColourScale::Range => Legend { lo, hi, uniform: hi == lo },
        })
    }

    /// Where `v` sits on the ramp: by its place in the span, or the middle for a uniform map.
    pub fn position(&self, v: f64) -> f64 {
        if self.uniform || self.hi <= self.lo {
            0.5
        } else {
            ((v - self.lo) / (self.hi - self.lo)).clamp(0.0, 1.0)
        }
    }
}

impl Plot for HeatMap {
    fn size(&self) -> (u32, u32) {
        (660, 460)
    }

    fn draw<DB: DrawingBackend>(&self, whole: &DrawingArea<DB, Shift>) -> Result<(), String> {
        let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
        let (root, key) = whole.split_horizontally(560);
        let root = &root;
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
        let legend = Legend::of(self.scale, &self.values);
        for iy in 0..ny {
            for ix in 0..nx {
                let (x, y) = (self.xs[ix], self.ys[iy]);
                let cell = [(x - hx, y - hy), (x + hx, y + hy)];
                let value = self.values[iy * nx + ix].filter(|v| v.is_finite());
                let (fill, ink) = match value {
                    Some(v) => {
                        let t = legend.map_or(0.5, |l| l.position(v));
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
        if let Some(l) = legend {
            self.draw_legend(&key, &l).map_err(e)?;
        }
        Ok(())
    }
}

impl HeatMap {
    /// The colour bar with its ticks (or one swatch for a uniform map) and a caption that
    /// states the span: "fixed 0–100", "range 12.5–80.1" or "uniform: 100".
    fn draw_legend<DB: DrawingBackend>(
        &self,
        key: &DrawingArea<DB, Shift>,
        l: &Legend,
    ) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
        let text = |anchor: Pos| TextStyle::from((FAMILY, 12).into_font()).color(&BLACK).pos(anchor);
        let value = |v: f64| format!("{v:.*}", self.decimals);
        let (x0, x1, top, bottom) = (10, 30, 60, 400);
        if l.uniform {
            key.draw(&Rectangle::new([(x0, 200), (x1, 240)], viridis(0.5).filled()))?;
            key.draw(&Rectangle::new([(x0, 200), (x1, 240)], BLACK.stroke_width(1)))?;
            key.draw_text(&format!("uniform: {}", value(l.lo)), &text(Pos::new(HPos::Left, VPos::Top)), (4, 250))?;
            return Ok(());
        }
        let rows = bottom - top;
        for i in 0..rows {
            let t = 1.0 - (i as f64 + 0.5) / rows as f64;
            key.draw(&Rectangle::new([(x0, top + i), (x1, top + i + 1)], viridis(t).filled()))?;
        }
        key.draw(&Rectangle::new([(x0, top), (x1, bottom)], BLACK.stroke_width(1)))?;
        for k in 0..=4 {
            let t = k as f64 / 4.0;
            let y = bottom - (t * rows as f64).round() as i32;
            key.draw(&PathElement::new(vec![(x1, y), (x1 + 4, y)], BLACK))?;
            key.draw_text(&value(l.lo + t * (l.hi - l.lo)), &text(Pos::new(HPos::Left, VPos::Center)), (x1 + 6, y))?;
        }
        let caption = match self.scale {
            ColourScale::Fixed { .. } => format!("fixed {}–{}", value(l.lo), value(l.hi)),
            ColourScale::Range => format!("range {}–{}", value(l.lo), value(l.hi)),
        };
        key.draw_text(&caption, &text(Pos::new(HPos::Left, VPos::Top)), (4, bottom + 12))?;
        Ok(())
    }
}

/// A grid value as an axis label: up to two decimals, without trailing zeros ("400",
/// "5.54").
fn axis_value(v: f64) -> String {
    let text = format!("{v:.2}");
    text.trim_end_matches('0').trim_end_matches('.').to_string()
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

#[cfg(test)]
mod tests {
    use super::*;
    use camplace_config::PlacementParam;

    #[test]
    fn axis_values_drop_trailing_zeros() {
        assert_eq!(axis_value(400.0), "400");
        assert_eq!(axis_value(0.0), "0");
        assert_eq!(axis_value(5.54), "5.54");
        assert_eq!(axis_value(81.5), "81.5");
        assert_eq!(axis_value(-12.0), "-12");
    }

    #[test]
    fn a_success_map_means_the_same_colour_everywhere_and_a_uniform_range_says_so() {
        let fixed = ColourScale::Fixed { lo: 0.0, hi: 100.0 };
        // 100 % is the bright end whether the map holds only 100 or 75 to 100.
        let all = Legend::of(fixed, &[Some(100.0), Some(100.0)]).unwrap();
        let some = Legend::of(fixed, &[Some(75.0), Some(100.0), None]).unwrap();
        assert_eq!(all.position(100.0), 1.0);
        assert_eq!(some.position(100.0), 1.0);
        assert_eq!(some.position(75.0), 0.75);
        assert!(!all.uniform);
        // A map's own range: its ends, and one value drawn in the middle colour, said so.
        let range = Legend::of(ColourScale::Range, &[Some(12.0), Some(30.0), Some(f64::NAN)]).unwrap();
        assert_eq!((range.lo, range.hi, range.position(12.0), range.position(30.0)), (12.0, 30.0, 0.0, 1.0));
        let flat = Legend::of(ColourScale::Range, &[Some(4.0), Some(4.0)]).unwrap();
        assert!(flat.uniform);
        assert_eq!(flat.position(4.0), 0.5);
        assert!(Legend::of(ColourScale::Range, &[None]).is_none());
    }

    /// A drawn map: the pixel at the top of the legend's bar, every pixel (RGB), the size.
    type Drawn = ([u8; 3], Vec<u8>, (u32, u32));

    /// Draws `map` into an RGB buffer (`None` without a font).
    fn drawn(map: &HeatMap) -> Option<Drawn> {
        camplace_plot::ensure_plot_font().ok()?;
        let (w, h) = map.size();
        let mut buf = vec![0u8; (w * h * 3) as usize];
        {
            let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
            root.fill(&WHITE).unwrap();
            map.draw(&root).unwrap();
            root.present().unwrap();
        }
        // The legend's bar spans x 570..590 of the picture, y 60..400, bright at the top.
        let at = |x: u32, y: u32| {
            let i = ((y * w + x) * 3) as usize;
            [buf[i], buf[i + 1], buf[i + 2]]
        };
        Some((at(580, 62), buf, (w, h)))
    }

    #[test]
    fn a_uniform_full_success_map_is_drawn_in_the_colour_of_100_on_its_legend() {
        let map = HeatMap {
            title: "success rate, % (phase-12)".into(),
            x_label: PlacementParam::R.label(),
            y_label: PlacementParam::Alpha.label(),
            xs: vec![400.0, 500.0, 600.0],
            ys: vec![0.0, 30.0, 60.0],
            values: vec![Some(100.0); 9],
            best: None,
            decimals: 0,
            scale: ColourScale::Fixed { lo: 0.0, hi: 100.0 },
        };
        let Some((legend_top, buf, (w, h))) = drawn(&map) else {
            eprintln!("no font: the drawn map is not checked");
            return;
        };
        let bright = viridis(1.0);
        let near = |p: [u8; 3], c: RGBColor| p.iter().zip([c.0, c.1, c.2]).all(|(a, b)| a.abs_diff(b) <= 6);
        assert!(near(legend_top, bright), "the bar's top is 100's colour: {legend_top:?}");
        // Most of the plot's pixels are 100's colour (the cells), none is the dark end's.
        let pixels: Vec<[u8; 3]> = buf.chunks(3).map(|p| [p[0], p[1], p[2]]).collect();
        let plot_area = |i: usize| (i as u32 % w) < 560;
        let bright_share = pixels.iter().enumerate().filter(|(i, p)| plot_area(*i) && near(**p, bright)).count() as f64
            / (560 * h) as f64;
        assert!(bright_share > 0.5, "cells in 100's colour: {bright_share}");
        let dark = viridis(0.0);
        assert!(!pixels.iter().enumerate().any(|(i, p)| plot_area(i) && near(*p, dark)), "no cell in 0's colour");
    }
}
