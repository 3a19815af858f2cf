//! The tray hiding parts of itself, and the parts a captured model holds that are not
//! there. Seen from one of the model's views, a point of the tray that lies behind another
//! part of the tray (a low tab behind the far wall) is one the sensor cannot have measured
//! from there; scene points found on it are something else, such as the stereo smear beyond
//! the nearer wall's edge. And that smear is in the captured model too: from the views
//! that saw the tab hidden, the smear beyond the wall stands above it as phantom points,
//! which a turned pose whose tab is hidden would take for its own.
//!
//! So, once per model, each view's direction from the sensor's distance gets two z-buffers
//! (per cell of the surface resolution at that distance, the point nearest the eye): of what
//! the view itself captured, and of the tray's whole surface (every view's points merged at
//! the surface resolution, with their normals). A point that some view saw past, its
//! capture clearly farther in the point's cell and all around it, is a phantom: a view
//! looked through where it stands. The whole surface without its phantoms is the occluder:
//! a point is hidden from a view where the surface's nearest point in its cell stands
//! clearly in front of it along the ray and clearly in front of its own plane (so that points
//! of one slanted surface sharing a cell do not hide each other). The turn check counts a
//! distinct part's scene points, and tests the part against the measured depth, only where
//! the part is no phantom and in sight at the pose weighed.

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

use crate::Model;

/// The z-buffer's cell, in surface resolutions at the eye's distance: the merged surface
/// has a point every resolution or so, so a cell this wide over the surface seen face-on
/// holds one; an occluder's silhouette reaches up to a cell past its edge.
const CELL_RESOLUTIONS: f32 = 1.0;
/// A point this much farther along the ray than the nearest surface in its cell, mm,
/// and ...
const DEPTH_MARGIN_MM: f32 = 4.0;
/// ... this far behind that surface's plane (along its normal), mm, is hidden by it: beyond
/// a captured model's depth noise, below a wall's thickness.
const PLANE_MARGIN_MM: f32 = 2.0;
/// A point this much nearer the eye than everything a view captured in its cell and the
/// cells around it, mm, is one that view saw past: beyond the capture's depth noise.
const SEEN_PAST_MM: f32 = 3.0;
/// The z-buffer's side at most, cells: a tray larger than this many cells takes wider ones.
const MAX_SIDE: f32 = 2048.0;
/// The eye's distance at least, mm: nearer than this no tray is seen whole.
const MIN_DISTANCE_MM: f32 = 100.0;

/// Per model view, one bit a point of a set (point i at bit i % 64 of word i / 64): set
/// where the tray hides the point from that view's direction.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct HiddenInViews(Vec<Vec<u64>>);

impl HiddenInViews {
    /// Whether point `i` of the set is hidden from view `view` (false past the views).
    #[inline]
    pub(crate) fn hidden(&self, view: usize, i: usize) -> bool {
        self.0.get(view).and_then(|bits| bits.get(i / 64)).is_some_and(|w| w & (1 << (i % 64)) != 0)
    }
}

/// The tray's whole surface without its phantoms, as one occluder seen from each view's
/// direction at the sensor's distance, and each view's own capture.
pub(crate) struct Occluder {
    /// Every view's points, one a surface-resolution cell (the first met, in view order),
    /// but the phantoms; with normals.
    points: Vec<Point3<f32>>,
    normals: Vec<Vector3<f32>>,
    /// Per view: the z-buffer of what it captured, and of `points`.
    views: Vec<(ZBuffer, ZBuffer)>,
}

impl Occluder {
    /// The occluder of `model`'s whole surface, seen from `distance` (mm, the sensor's from
    /// the tray) along each of its views' directions.
    pub(crate) fn of(model: &Model, distance: f32) -> Occluder {
        let resolution = model.surface_resolution.max(0.1);
        let key = |m: &Point3<f32>| (m.coords / resolution).map(|c| c.floor() as i32);
        let mut seen = std::collections::HashSet::new();
        let (mut points, mut normals) = (Vec::new(), Vec::new());
        for view in &model.views {
            for (m, n) in view.points.iter().zip(&view.normals) {
                if seen.insert(key(m)) {
                    points.push(*m);
                    normals.push(*n);
                }
            }
        }
        let distance = if distance.is_finite() { distance.max(MIN_DISTANCE_MM) } else { MIN_DISTANCE_MM };
        let cell = resolution * CELL_RESOLUTIONS;
        let eyes: Vec<Point3<f32>> = model.views.iter().map(|v| Point3::from(v.view_direction * distance)).collect();
        let captures: Vec<ZBuffer> =
            model.views.par_iter().zip(&eyes).map(|(v, eye)| ZBuffer::new(&v.points, *eye, cell)).collect();
        let real: Vec<bool> = points.par_iter().map(|p| !captures.iter().any(|z| z.sees_past(p))).collect();
        let (points, normals): (Vec<_>, Vec<_>) =
            points.into_iter().zip(normals).zip(&real).filter(|(_, &r)| r).map(|(pn, _)| pn).unzip();
        let surfaces: Vec<ZBuffer> = eyes.par_iter().map(|eye| ZBuffer::new(&points, *eye, cell)).collect();
        Occluder { points, normals, views: captures.into_iter().zip(surfaces).collect() }
    }

    /// Whether some view saw past `p` (tray frame): a phantom of the capture.
    pub(crate) fn phantom(&self, p: &Point3<f32>) -> bool {
        self.views.iter().any(|(capture, _)| capture.sees_past(p))
    }

    /// Which of `sets`' points (tray frame) the tray hides from each view, per set. The
    /// views are taken side by side on the pool, each a whole answer.
    pub(crate) fn hidden(&self, sets: &[&[Point3<f32>]]) -> Vec<HiddenInViews> {
        let per_view: Vec<Vec<Vec<u64>>> = self
            .views
            .par_iter()
            .map(|(_, surface)| {
                sets.iter()
                    .map(|points| {
                        let mut bits = vec![0u64; points.len().div_ceil(64)];
                        for (i, p) in points.iter().enumerate() {
                            if surface.hides(&self.points, &self.normals, p) {
                                bits[i / 64] |= 1 << (i % 64);
                            }
                        }
                        bits
                    })
                    .collect()
            })
            .collect();
        (0..sets.len()).map(|s| HiddenInViews(per_view.iter().map(|v| v[s].clone()).collect())).collect()
    }
}

/// A z-buffer of a point set seen from an eye: the directions from the eye in cells of a
/// given size at the eye's distance, per cell the set's point nearest the eye and its range.
struct ZBuffer {
    eye: Point3<f32>,
    axis: Vector3<f32>,
    across: [Vector3<f32>; 2],
    origin: [f32; 2],
    /// The cell's side, as a tangent of the angle off the axis.
    cell: f32,
    side: [usize; 2],
    /// Per cell, the nearest point's index (`u32::MAX` for none) and range (infinite).
    nearest: Vec<u32>,
    range: Vec<f32>,
}

impl ZBuffer {
    /// The z-buffer of `points` from `eye` (looking at the origin), in cells `cell` wide at
    /// the eye's distance.
    fn new(points: &[Point3<f32>], eye: Point3<f32>, cell: f32) -> ZBuffer {
        let axis = -eye.coords.normalize();
        let other = if axis.z.abs() < 0.9 { Vector3::z() } else { Vector3::x() };
        let a = axis.cross(&other).normalize();
        let mut z = ZBuffer {
            eye,
            axis,
            across: [a, axis.cross(&a)],
            origin: [0.0; 2],
            cell: cell / eye.coords.norm(),
            side: [1, 1],
            nearest: Vec::new(),
            range: Vec::new(),
        };
        let (mut lo, mut hi) = ([f32::INFINITY; 2], [f32::NEG_INFINITY; 2]);
        for uv in points.iter().filter_map(|p| z.tangents(p)) {
            for k in 0..2 {
                lo[k] = lo[k].min(uv[k]);
                hi[k] = hi[k].max(uv[k]);
            }
        }
        if lo[0] > hi[0] {
            (lo, hi) = ([0.0; 2], [0.0; 2]);
        }
        z.cell = z.cell.max((hi[0] - lo[0]).max(hi[1] - lo[1]) / MAX_SIDE);
        z.origin = lo;
        z.side = [0, 1].map(|k| ((hi[k] - lo[k]) / z.cell).floor() as usize + 1);
        z.nearest = vec![u32::MAX; z.side[0] * z.side[1]];
        z.range = vec![f32::INFINITY; z.side[0] * z.side[1]];
        for (i, p) in points.iter().enumerate() {
            let Some(c) = z.cell_of(p) else { continue };
            let range = (p - eye).norm();
            if range < z.range[c] {
                (z.nearest[c], z.range[c]) = (i as u32, range);
            }
        }
        z
    }

    /// The point's direction from the eye as tangents of its angles off the axis; `None`
    /// behind the eye.
    fn tangents(&self, p: &Point3<f32>) -> Option<[f32; 2]> {
        let r = p - self.eye;
        let t = r.dot(&self.axis);
        (t > 1.0).then(|| [r.dot(&self.across[0]) / t, r.dot(&self.across[1]) / t])
    }

    /// The cell's column and row.
    fn cell_at(&self, p: &Point3<f32>) -> Option<[usize; 2]> {
        let uv = self.tangents(p)?;
        let [i, j] = [0, 1].map(|k| ((uv[k] - self.origin[k]) / self.cell).floor());
        let inside = i >= 0.0 && j >= 0.0 && (i as usize) < self.side[0] && (j as usize) < self.side[1];
        inside.then_some([i as usize, j as usize])
    }

    fn cell_of(&self, p: &Point3<f32>) -> Option<usize> {
        self.cell_at(p).map(|[i, j]| j * self.side[0] + i)
    }

    /// Whether the set (`points`, `normals`, those the buffer was made of) hides `p`: its
    /// nearest point in `p`'s cell stands more than the margins in front of `p`, along the
    /// ray and along its own normal.
    fn hides(&self, points: &[Point3<f32>], normals: &[Vector3<f32>], p: &Point3<f32>) -> bool {
        let Some(c) = self.cell_of(p) else { return false };
        let o = self.nearest[c];
        if o == u32::MAX {
            return false;
        }
        let o = o as usize;
        (p - self.eye).norm() - self.range[c] > DEPTH_MARGIN_MM && (points[o] - p).dot(&normals[o]) > PLANE_MARGIN_MM
    }

    /// Whether the set's points in `p`'s cell, and in every cell around it that holds one,
    /// all stand more than [`SEEN_PAST_MM`] behind `p`: the eye saw past it.
    fn sees_past(&self, p: &Point3<f32>) -> bool {
        let Some([i, j]) = self.cell_at(p) else { return false };
        if self.range[j * self.side[0] + i].is_infinite() {
            return false;
        }
        let limit = (p - self.eye).norm() + SEEN_PAST_MM;
        let (i0, j0) = (i.saturating_sub(1), j.saturating_sub(1));
        let (i1, j1) = ((i + 1).min(self.side[0] - 1), (j + 1).min(self.side[1] - 1));
        (j0..=j1).all(|y| (i0..=i1).all(|x| self.range[y * self.side[0] + x] > limit))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing;

    /// Against a ray cast of the synthetic tray's solids from far along each view's
    /// direction (the z-buffer's own projection): the points the cast finds hidden behind
    /// another part (facing the sensor, so not merely turned away) are found hidden, and
    /// the points it finds in sight are not, but along the silhouettes' edges (a cell wide);
    /// and the same from the model's own sensor distance (800 mm).
    /// An exact surface holds no phantom: no view saw past a point of the synthetic tray.
    /// A point floating above the tab's top, which a view looking down on the tab saw
    /// past, is one.
    #[test]
    fn a_phantom_is_a_point_some_view_saw_past() {
        let model = testing::tray(false, 1);
        let (points, _) = testing::surface(&testing::tray_cuboids(false), testing::SPACING);
        let occluder = Occluder::of(&model, testing::SENSOR_DISTANCE);
        let phantoms = points.iter().filter(|p| occluder.phantom(p)).count();
        assert_eq!(phantoms, 0, "of {} surface points", points.len());
        // 8 mm above the tab's top (15 mm), over its middle; and a point inside the tray's
        // walls' span but above them, where every view looks down past it to the floor.
        assert!(occluder.phantom(&Point3::new(108.0, 30.0, 23.0)));
        assert!(occluder.phantom(&Point3::new(-40.0, 20.0, 45.0)));
    }

    #[test]
    fn hidden_points_are_those_a_ray_cast_finds_behind_the_tray() {
        let model = testing::tray(false, 1);
        let cuboids = testing::tray_cuboids(false);
        let (points, normals) = testing::surface(&cuboids, testing::SPACING);
        for (distance, least, tab_least) in
            [(100.0 * testing::SENSOR_DISTANCE, 0.96, 0.85), (testing::SENSOR_DISTANCE, 0.98, 0.95)]
        {
            let hidden = &Occluder::of(&model, distance).hidden(&[&points])[0];
            let (mut agree, mut facing, mut tab_hidden, mut tab_cast) = (0, 0, 0, 0);
            for (k, view) in model.views.iter().enumerate() {
                let eye = Point3::from(view.view_direction * distance);
                let seen: std::collections::HashSet<usize> =
                    testing::visible(&cuboids, &points, &normals, &eye).into_iter().collect();
                for (i, (p, n)) in points.iter().zip(&normals).enumerate() {
                    if n.dot(&(eye - p)) <= 0.0 {
                        continue;
                    }
                    facing += 1;
                    let cast_hidden = !seen.contains(&i);
                    agree += usize::from(cast_hidden == hidden.hidden(k, i));
                    // The tab's top, outside the +x wall.
                    if p.x > 101.0 && n.z > 0.5 && cast_hidden {
                        tab_cast += 1;
                        tab_hidden += usize::from(hidden.hidden(k, i));
                    }
                }
            }
            let share = agree as f64 / facing as f64;
            assert!(share >= least, "{distance} mm: agree on {agree} of {facing} facing points");
            assert!(tab_cast > 50, "{distance} mm: the cast hides {tab_cast} points of the tab's top");
            assert!(
                tab_hidden as f64 >= tab_least * tab_cast as f64,
                "{distance} mm: {tab_hidden} of {tab_cast} tab points"
            );
        }
    }
}
