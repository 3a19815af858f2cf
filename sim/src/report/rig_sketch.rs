//! A side and a top sketch of the rig at a placement: the table, the tray's footprint at
//! the work volume's centre, the two cameras and the projector with their view frustums
//! down to the table.

use camplace_config::Placement;
use camplace_estimator::{geometry::Camera, Rig};
use nalgebra::{Point3, Vector3};
use plotters::coord::Shift;
use plotters::prelude::*;

use camplace_plot::{Plot, PLOT_FONT_FAMILY as FAMILY};

/// The sketch's contents.
#[derive(Debug, Clone)]
pub struct RigSketch {
    /// Title above both views.
    pub title: String,
    /// The placement drawn.
    pub placement: Placement,
    /// Its rig (cameras and projector in the world).
    pub rig: Rig,
    /// Table extent along world x and y, mm.
    pub table: [f64; 2],
    /// Tray extent along its x and y, mm (drawn at the origin, unturned).
    pub tray: [f64; 2],
}

/// A camera's centre and where its four corner rays meet the table (or stop, if they
/// point above the horizon).
fn frustum(c: &Camera, far: f64) -> (Point3<f64>, [Point3<f64>; 4]) {
    let centre = Point3::from(c.t_world_camera.translation.vector);
    let kinv = c.k.try_inverse().unwrap_or_else(nalgebra::Matrix3::identity);
    let (w, h) = ((c.width.max(1) - 1) as f64, (c.height.max(1) - 1) as f64);
    let corner = |u: f64, v: f64| {
        let d = c.t_world_camera.rotation * (kinv * Vector3::new(u, v, 1.0)).normalize();
        let t = if d.z < -1e-9 { (-centre.z / d.z).min(far) } else { far };
        centre + d * t
    };
    (centre, [corner(0.0, 0.0), corner(w, 0.0), corner(w, h), corner(0.0, h)])
}

impl Plot for RigSketch {
    fn size(&self) -> (u32, u32) {
        (960, 440)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String> {
        let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
        let root = root.titled(&self.title, (FAMILY, 18)).map_err(e)?;
        let (side, top) = root.split_horizontally(480);
        let phi = self.placement.azimuth.to_radians();
        let along = |p: &Point3<f64>| p.x * phi.cos() + p.y * phi.sin();
        let far = 2.0 * self.placement.r;
        let mut cams: Vec<(&str, RGBColor, &Camera)> =
            vec![("left", RGBColor(31, 119, 180), &self.rig.left), ("right", RGBColor(214, 39, 40), &self.rig.right)];
        if let Some(p) = &self.rig.projector {
            cams.push(("projector", RGBColor(255, 127, 14), p));
        }
        let frusta: Vec<_> = cams.iter().map(|(n, col, c)| (*n, *col, frustum(c, far))).collect();
        let (tx, ty) = (0.5 * self.table[0], 0.5 * self.table[1]);

        // Side view: along the rig's azimuth against height.
        let mut s_lo = -tx.max(ty);
        let mut s_hi = tx.max(ty);
        let mut z_hi: f64 = 100.0;
        for (_, _, (c, ends)) in &frusta {
            for p in std::iter::once(c).chain(ends.iter()) {
                s_lo = s_lo.min(along(p));
                s_hi = s_hi.max(along(p));
            }
            z_hi = z_hi.max(c.z);
        }
        let pad = 0.08 * (s_hi - s_lo);
        let mut chart = ChartBuilder::on(&side)
            .caption("side", (FAMILY, 15))
            .margin(10)
            .x_label_area_size(36)
            .y_label_area_size(50)
            .build_cartesian_2d(s_lo - pad..s_hi + pad, -30.0..z_hi * 1.1)
            .map_err(e)?;
        chart
            .configure_mesh()
            .x_desc("along the rig's azimuth, mm")
            .y_desc("height, mm")
            .label_style((FAMILY, 12))
            .axis_desc_style((FAMILY, 13))
            .draw()
            .map_err(e)?;
        chart
            .draw_series(std::iter::once(PathElement::new(vec![(-tx, 0.0), (tx, 0.0)], BLACK.stroke_width(3))))
            .map_err(e)?;
        let half_tray = 0.5 * self.tray[0].max(self.tray[1]);
        chart
            .draw_series(std::iter::once(Rectangle::new(
                [(-half_tray, 0.0), (half_tray, 25.0)],
                RGBColor(150, 150, 150).filled(),
            )))
            .map_err(e)?;
        for (name, col, (c, ends)) in &frusta {
            let lines =
                ends.iter().map(|p| PathElement::new(vec![(along(c), c.z), (along(p), p.z)], col.stroke_width(1)));
            chart.draw_series(lines).map_err(e)?;
            chart
                .draw_series(std::iter::once(Circle::new((along(c), c.z), 4, col.filled())))
                .map_err(e)?
                .label(*name)
                .legend(move |(x, y)| Circle::new((x + 6, y), 4, col.filled()));
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .label_font((FAMILY, 12))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()
            .map_err(e)?;

        // Top view: world x and y.
        let mut x_lo = -tx;
        let mut x_hi = tx;
        let mut y_lo = -ty;
        let mut y_hi = ty;
        for (_, _, (c, ends)) in &frusta {
            for p in std::iter::once(c).chain(ends.iter()) {
                x_lo = x_lo.min(p.x);
                x_hi = x_hi.max(p.x);
                y_lo = y_lo.min(p.y);
                y_hi = y_hi.max(p.y);
            }
        }
        let pad = 0.06 * (x_hi - x_lo).max(y_hi - y_lo);
        let mut chart = ChartBuilder::on(&top)
            .caption("top", (FAMILY, 15))
            .margin(10)
            .x_label_area_size(36)
            .y_label_area_size(50)
            .build_cartesian_2d(x_lo - pad..x_hi + pad, y_lo - pad..y_hi + pad)
            .map_err(e)?;
        chart
            .configure_mesh()
            .x_desc("world x, mm")
            .y_desc("world y, mm")
            .label_style((FAMILY, 12))
            .axis_desc_style((FAMILY, 13))
            .draw()
            .map_err(e)?;
        chart.draw_series(std::iter::once(Rectangle::new([(-tx, -ty), (tx, ty)], BLACK.stroke_width(2)))).map_err(e)?;
        let (hx, hy) = (0.5 * self.tray[0], 0.5 * self.tray[1]);
        chart
            .draw_series(std::iter::once(Rectangle::new([(-hx, -hy), (hx, hy)], RGBColor(150, 150, 150).filled())))
            .map_err(e)?;
        for (_, col, (c, ends)) in &frusta {
            let mut outline: Vec<(f64, f64)> = ends.iter().map(|p| (p.x, p.y)).collect();
            outline.push(outline[0]);
            chart.draw_series(std::iter::once(PathElement::new(outline, col.stroke_width(2)))).map_err(e)?;
            let rays =
                ends.iter().map(|p| PathElement::new(vec![(c.x, c.y), (p.x, p.y)], col.mix(0.4).stroke_width(1)));
            chart.draw_series(rays).map_err(e)?;
            chart.draw_series(std::iter::once(Circle::new((c.x, c.y), 4, col.filled()))).map_err(e)?;
        }
        Ok(())
    }
}
