//! See-through evidence against a pose: where the model at the pose puts a surface facing
//! the sensor, the left camera's measured depth along the same pixel ray says whether the
//! sensor saw that surface (or something in front of it) or saw past it, to the table or
//! the floor behind. A wrong pose that scores well on the points it explains (a tray
//! shifted by one slot's pitch) still puts parts of the model where the sensor looked
//! through empty space; a half turn whose telling feature the camera does not see puts
//! none, and is left to the turn check.
//!
//! The measured depth is the rectified left disparity map before the background was
//! removed: a pixel that saw the table still holds the table's depth. A one-shot frame is
//! matched only in the box where it differs from the background capture; outside it the
//! sensor saw the empty cell, and the background's depth stands in for the unmatched
//! pixels, so a turned or shifted pose reaching past the box is judged as one inside it
//! (a rectangular tray turned a quarter turn stands out of its own box). A model point
//! hidden behind another part of the model is measured in front of it, never behind, so
//! only a measurement clearly behind the model's surface counts against the pose; but a
//! turn's evidence counts only the distinct parts in sight at each pose (`self_occlusion`):
//! a tab hidden behind the far wall, measured in front of it there, would otherwise read as
//! a tab the camera saw.
//!
//! The same depth answers the coverage's question the other way round ([`Occlusion`]):
//! whether the sensor could have seen a model point at all, or a nearer surface hid it, or
//! nothing was measured there.

use nalgebra::{Isometry3, Point3, Vector3};

use crate::depth::PixelRegion;
use crate::pose::self_occlusion::{HiddenInViews, Occluder};
use crate::pose::Alternatives;
use crate::spatial::NearestGrid;
use crate::{FloatImage, Model, RectifiedCamera};

/// A measured depth more than this behind the model's surface along the pixel's ray means
/// the sensor saw past it, mm: beyond the depth noise of a good placement and the
/// refined pose's error, below the height of the walls and features that tell poses apart.
pub const SEE_THROUGH_MARGIN_MM: f32 = 8.0;
/// Pixels either side of a model point's projection searched for the nearest measured
/// surface: a pose error of a millimetre or two, or a row the one-shot matcher skipped,
/// must not turn a wall's edge into a view past it.
const WINDOW_PX: isize = 2;
/// How far around a slot's item outline (the footprint grown by this, mm) and above its
/// floor (by [`ITEM_FLOOR_MM`]) a model point is the item's, not the tray's: the model was
/// captured with its slots filled, and an empty slot is no view past the tray.
const ITEM_GROWTH_MM: f32 = 6.0;
const ITEM_FLOOR_MM: f32 = 2.0;
/// The views the tray's distinct parts are merged from: this many spread evenly round the
/// tray (every view of a model with fewer). The stereo smear beside a wall differs between
/// views this far apart (60°, the paper's steps), so a cell two of them captured is the
/// tray's surface; views 30° apart can share the smear.
pub const SPREAD_VIEWS: usize = 6;

/// Of `n` views (the tray turned in `n` equal steps), the [`SPREAD_VIEWS`] nearest to
/// equal turns apart (view j × n / 6, rounded), in order; every view when there are fewer.
fn spread_views(n: usize) -> Vec<usize> {
    if n <= SPREAD_VIEWS {
        return (0..n).collect();
    }
    (0..SPREAD_VIEWS).map(|j| (j * n + SPREAD_VIEWS / 2) / SPREAD_VIEWS).collect()
}

/// The tray's points of a view tested at most (every k-th of them): a few thousand keep
/// the count's deviation far below the gap between a pose and its neighbour a pitch away,
/// and a pass a few tens of microseconds on one core.
const SEE_THROUGH_POINTS: usize = 4000;
/// The points where the tray and one turn of it about its centre differ, tested at most.
const TURN_POINTS: usize = 3000;
/// The same for a turn shifted onto the slot grid, whose parts apart are whole ends and
/// sides of the tray rather than a tab: fewer points keep the share's deviation far below
/// the gap the test asks for.
const SHIFTED_POINTS: usize = 1000;

/// The measured depth a pose is set against: the rectified left camera's disparity map
/// (px; +inf where nothing was measured) and the camera.
#[derive(Debug, Clone, Copy)]
pub struct DepthEvidence<'a> {
    pub disparity: &'a FloatImage,
    pub camera: &'a RectifiedCamera,
    /// Where `disparity` was matched, when only part of the frame was, and the background's
    /// depth (mm, [`crate::depth::Background::depth`]) that stands in outside it.
    pub beyond: Option<(PixelRegion, &'a FloatImage)>,
    /// An unmeasured pixel in a measured row is one the projector did not light: the phase
    /// decoder's (too little fringe contrast), where the surface may stand unseen. The
    /// one-shot matcher leaves holes wherever a match is not unique, lit or not.
    pub holes_unlit: bool,
}

impl DepthEvidence<'_> {
    /// The columns of `lo..hi` in row `y` that `disparity` holds a match for: all of them
    /// when the frame was matched whole, those inside the matched region otherwise (none on
    /// a row outside it).
    #[inline]
    fn matched_columns(&self, y: usize, lo: usize, hi: usize) -> (usize, usize) {
        match self.beyond {
            None => (lo, hi),
            Some((region, _)) if (region.y0..region.y1).contains(&y) => {
                let a = region.x0.clamp(lo, hi);
                (a, region.x1.clamp(a, hi))
            }
            Some(_) => (lo, lo),
        }
    }

    /// The largest disparity (the nearest surface) measured in columns `lo..hi` of row `y`,
    /// or seen there as the background outside the matched region; 0 when none.
    #[inline]
    fn nearest_in_row(&self, y: usize, lo: usize, hi: usize, focal_baseline: f32) -> f32 {
        let (a, b) = self.matched_columns(y, lo, hi);
        let measured = nearest_measured(&self.disparity.row(y)[a..b]);
        let Some((_, background)) = self.beyond else { return measured };
        // The background on either side of the matched columns.
        let depth = background.row(y);
        let background_nearest = depth[lo..a].iter().chain(&depth[b..hi]).copied().fold(f32::INFINITY, f32::min);
        // Unmeasured background (+inf depth) gives 0.
        measured.max(focal_baseline / background_nearest)
    }

    /// Whether row `y` holds, in its matched columns of `lo..hi`, both a measured and an
    /// unmeasured pixel: a gap in a row the matcher measured (a row it skipped, or one
    /// outside the matched region, holds none).
    #[inline]
    fn gap_in_row(&self, y: usize, lo: usize, hi: usize) -> bool {
        let (a, b) = self.matched_columns(y, lo, hi);
        let row = &self.disparity.row(y)[a..b];
        row.iter().any(|d| d.is_finite()) && row.iter().any(|d| !d.is_finite())
    }
}

/// A measured depth more than this in front of the model's surface along the pixel's ray
/// means something stood between the sensor and that surface (a gripper or an arm above the
/// tray, the tray's own wall), mm: the same margin as a view past it, the other way.
pub const OCCLUDED_MARGIN_MM: f32 = SEE_THROUGH_MARGIN_MM;
/// Pixels either side of a point's projection that must all hold a nearer surface, where
/// measured, for the point to be hidden: a row the one-shot matcher skipped is bridged, and
/// a single pixel of a wall's edge hides nothing.
const HIDDEN_WINDOW_PX: isize = 1;

/// The rectified left camera's projection in f32, as both tests against the measured depth
/// take it: a camera-frame point's pixel, and focal length × baseline (depth = that over
/// disparity).
#[derive(Debug, Clone, Copy)]
struct Pinhole {
    fx: f32,
    fy: f32,
    cx: f32,
    cy: f32,
    focal_baseline: f32,
}

impl Pinhole {
    fn of(camera: &RectifiedCamera) -> Pinhole {
        let kk = &camera.k;
        Pinhole {
            fx: kk[(0, 0)] as f32,
            fy: kk[(1, 1)] as f32,
            cx: kk[(0, 2)] as f32,
            cy: kk[(1, 2)] as f32,
            focal_baseline: (camera.focal() * camera.baseline) as f32,
        }
    }

    /// The pixel (column, row) of camera-frame `p`, rounded.
    #[inline]
    fn pixel(&self, p: &Point3<f32>) -> (isize, isize) {
        ((self.fx * p.x / p.z + self.cx).round() as isize, (self.fy * p.y / p.z + self.cy).round() as isize)
    }
}

/// The test of world points against a frame's measured depth for whether the sensor could
/// see them at all ([`DepthEvidence::occlusion`]).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Occlusion<'a> {
    depth: &'a DepthEvidence<'a>,
    world_to_camera: Isometry3<f32>,
    pinhole: Pinhole,
}

impl<'a> DepthEvidence<'a> {
    /// The occlusion test of world points against this depth.
    pub(crate) fn occlusion(&'a self) -> Occlusion<'a> {
        Occlusion {
            depth: self,
            world_to_camera: self.camera.t_world_rectified.inverse().cast::<f32>(),
            pinhole: Pinhole::of(self.camera),
        }
    }
}

/// What a frame's measured depth says of a point the model puts on a surface.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Sight {
    /// The sensor could have measured it: nothing nearer stood in front of it.
    Open,
    /// A surface more than [`OCCLUDED_MARGIN_MM`] nearer stood in front of it.
    Hidden,
    /// Nothing was measured around its pixel: no evidence either way.
    Unmeasured,
}

impl Occlusion<'_> {
    /// What the measured depth says of `world` on the pixels within [`HIDDEN_WINDOW_PX`]
    /// of its projection: hidden where every measured one holds a surface more than
    /// [`OCCLUDED_MARGIN_MM`] in front of it, unmeasured where none is measured (the
    /// matcher's search covers the work volume, so a gripper high above the tray is
    /// measured nowhere), open otherwise. Outside the matched region the sensor saw the
    /// empty cell's background, which hides nothing; a point off the image or behind the
    /// camera is open (counted as the coverage counts it).
    pub(crate) fn sight(&self, world: &Point3<f32>) -> Sight {
        let p = self.world_to_camera * world;
        if p.z <= OCCLUDED_MARGIN_MM + 1.0 {
            return Sight::Open;
        }
        let (u, v) = self.pinhole.pixel(&p);
        let disparity = self.depth.disparity;
        let (width, height) = (disparity.width as isize, disparity.height as isize);
        let w = HIDDEN_WINDOW_PX;
        if u - w < 0 || v - w < 0 || u + w >= width || v + w >= height {
            return Sight::Open;
        }
        if let Some((region, _)) = self.depth.beyond {
            let inside = |x: isize, y: isize| {
                (region.x0 as isize..region.x1 as isize).contains(&x)
                    && (region.y0 as isize..region.y1 as isize).contains(&y)
            };
            if !inside(u - w, v - w) || !inside(u + w, v + w) {
                return Sight::Open;
            }
        }
        // Nearer than the surface by the margin: a disparity above this.
        let nearer = self.pinhole.focal_baseline / (p.z - OCCLUDED_MARGIN_MM);
        let mut measured = false;
        for y in (v - w)..=(v + w) {
            for &d in &disparity.row(y as usize)[(u - w) as usize..=(u + w) as usize] {
                if d.is_finite() && d > 0.0 {
                    if d <= nearer {
                        return Sight::Open;
                    }
                    measured = true;
                }
            }
        }
        if measured {
            Sight::Hidden
        } else {
            Sight::Unmeasured
        }
    }
}

/// The largest finite disparity of `row`, 0 when none.
#[inline]
fn nearest_measured(row: &[f32]) -> f32 {
    let mut nearest = 0.0f32;
    for &d in row {
        if d.is_finite() && d > nearest {
            nearest = d;
        }
    }
    nearest
}

/// Counts of one pose's see-through evidence.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SeeThroughCounts {
    /// The closest view's points facing the sensor that fall on a measured pixel.
    pub tested: u32,
    /// Of them, those the sensor measured more than [`SEE_THROUGH_MARGIN_MM`] behind.
    pub seen_through: u32,
}

impl SeeThroughCounts {
    /// `seen_through / tested`, 0 when nothing was tested.
    pub fn share(&self) -> f32 {
        if self.tested == 0 {
            0.0
        } else {
            self.seen_through as f32 / self.tested as f32
        }
    }
}

/// Per view of `model`, the indices of its points that are the tray's, not a slot's item:
/// outside every slot's item outline grown by [`ITEM_GROWTH_MM`], or below
/// [`ITEM_FLOOR_MM`] above the slot's floor; every k-th of them, at most
/// `SEE_THROUGH_POINTS` a view. Found once per model.
pub fn tray_points(model: &Model) -> Vec<Vec<u32>> {
    thin_tray_points(&all_tray_points(model))
}

/// [`tray_points`] from every view's tray points (`all_tray_points` of the model).
pub(crate) fn thin_tray_points(all: &[Vec<u32>]) -> Vec<Vec<u32>> {
    all.iter().map(|tray| camplace_config::thinned(tray, SEE_THROUGH_POINTS).copied().collect()).collect()
}

/// The tray's surface, the tray points of [`SPREAD_VIEWS`] views spread round it merged (one
/// a surface-resolution cell, kept where two of them captured the cell or a neighbour of it), split per alternative `k` (the
/// model's [`Alternatives`]: the quarter turns 1 to 3 at 0 to 2, then the turns shifted onto
/// the slot grid) into the points that the whole tray at that alternative has nothing
/// within `margin` of, mm: the parts (a tab, a chamfer, a whole end) where the tray and
/// that alternative to it differ. Merged
/// from every view because a view captured close up may miss a part another view shows.
/// Every k-th of them, at most `TURN_POINTS` a turn about the centre and `SHIFTED_POINTS` a
/// shifted one. Found once per model.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TurnParts {
    /// The alternatives the parts are of ([`Alternatives::of`] the model).
    pub alternatives: Alternatives,
    /// Per alternative, the distinct points (tray frame, mm) and their outward normals.
    pub parts: Vec<SurfacePoints>,
    /// Per alternative, its distinct points the tray itself hides from each view's
    /// direction: neither tested against the measured depth at a pose seen from there.
    pub(crate) hidden: Vec<HiddenInViews>,
}

/// Surface points (tray frame, mm) and their outward normals, index for index.
pub type SurfacePoints = (Vec<Point3<f32>>, Vec<Vector3<f32>>);

impl TurnParts {
    /// The distinct parts of `model`'s tray for each of its `alternatives`
    /// ([`Alternatives::of`] the model; see [`TurnParts`]), and which of them the tray hides
    /// from each view, seen from `sight` (mm, the sensor's distance from the tray).
    pub fn of(model: &Model, alternatives: &Alternatives, margin: f32, sight: f32) -> TurnParts {
        TurnParts::of_tray_points(model, alternatives, margin, &Occluder::of(model, sight), &all_tray_points(model))
    }

    /// [`TurnParts::of`] from every view's tray points (`all_tray_points` of the model,
    /// found once for the verifier's see-through points too).
    pub(crate) fn of_tray_points(
        model: &Model,
        alternatives: &Alternatives,
        margin: f32,
        occluder: &Occluder,
        tray_points: &[Vec<u32>],
    ) -> TurnParts {
        let alternatives = alternatives.clone();
        let resolution = model.surface_resolution.max(0.1);
        let key = |m: &Point3<f32>| (m.coords / resolution).map(|c| c.floor() as i32);
        // Every view's points, one a cell of the surface resolution (the first view's first,
        // in view order): the point, its normal, whether it is the tray's (not an item's)
        // and the views that captured a point in the cell (view k as bit k mod 64).
        let mut index = std::collections::HashMap::new();
        let mut cells: Vec<(Point3<f32>, Vector3<f32>, bool, u64)> = Vec::new();
        for k in spread_views(model.views.len()) {
            let (view, tray) = (&model.views[k], &tray_points[k]);
            let mut is_tray = vec![false; view.points.len()];
            for &i in tray {
                is_tray[i as usize] = true;
            }
            for (i, (m, n)) in view.points.iter().zip(&view.normals).enumerate() {
                let at = *index.entry(key(m)).or_insert_with(|| {
                    cells.push((*m, *n, is_tray[i], 0));
                    cells.len() - 1
                });
                cells[at].3 |= 1 << (k % 64);
            }
        }
        if cells.is_empty() {
            let parts = vec![SurfacePoints::default(); alternatives.list().len()];
            let hidden = vec![HiddenInViews::default(); parts.len()];
            return TurnParts { alternatives, parts, hidden };
        }
        let whole: Vec<Point3<f32>> = cells.iter().map(|c| c.0).collect();
        let grid = NearestGrid::new(&whole, resolution, margin);
        let margin2 = margin * margin;
        // Whether the tray at alternative a has a point within the margin of m: m taken
        // back by a, looked up in the untouched tray.
        let turn_has = |m: &Point3<f32>, a: &crate::pose::Alternative| {
            let back = a.back(m);
            grid.lookup(&back).is_some_and(|i| (back - whole[i as usize]).norm_squared() <= margin2)
        };
        // The tray's cells that two views captured (in the cell or a neighbour): a captured
        // model's stereo smear beside a wall differs from view to view, the surface does not.
        let supported = |m: &Point3<f32>| {
            let c = key(m);
            let mut views = 0u64;
            for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        if let Some(&at) = index.get(&(c + nalgebra::Vector3::new(dx, dy, dz))) {
                            views |= cells[at].3;
                        }
                    }
                }
            }
            views.count_ones() >= 2
        };
        // Nor are a capture's phantoms, which a view saw past.
        let merged: Vec<(Point3<f32>, Vector3<f32>)> =
            cells.iter().filter(|c| c.2 && supported(&c.0) && !occluder.phantom(&c.0)).map(|c| (c.0, c.1)).collect();
        let parts = alternatives
            .list()
            .iter()
            .map(|a| {
                let apart: Vec<&(Point3<f32>, Vector3<f32>)> = merged.iter().filter(|(m, _)| !turn_has(m, a)).collect();
                let most = if a.about_centre() { TURN_POINTS } else { SHIFTED_POINTS };
                camplace_config::thinned(&apart, most).map(|&&(m, n)| (m, n)).unzip()
            })
            .collect::<Vec<SurfacePoints>>();
        let sets: Vec<&[Point3<f32>]> = parts.iter().map(|(points, _)| points.as_slice()).collect();
        let hidden = occluder.hidden(&sets);
        TurnParts { alternatives, parts, hidden }
    }
}

/// Per view of `model`, every point that is the tray's and not a slot's item.
pub(crate) fn all_tray_points(model: &Model) -> Vec<Vec<u32>> {
    // Each slot's tray -> slot frame (the layout's own slot poses) and its item's outline
    // there, grown: [x0, y0, x1, y1].
    let items: Vec<(Isometry3<f32>, [f32; 4])> = model.slots.as_ref().map_or_else(Vec::new, |layout| {
        let [x0, y0] = layout.footprint_min_mm;
        let g = ITEM_GROWTH_MM;
        let (x1, y1) = (x0 + layout.cols as f32 * layout.cell_mm[0], y0 + layout.rows as f32 * layout.cell_mm[1]);
        (0..layout.slots.len())
            .filter_map(|n| layout.slot_pose(n))
            .map(|pose| (pose.inverse().cast::<f32>(), [x0 - g, y0 - g, x1 + g, y1 + g]))
            .collect()
    });
    let on_an_item = |m: &Point3<f32>| {
        items.iter().any(|(to_slot, [x0, y0, x1, y1])| {
            let q = to_slot * m;
            q.z > ITEM_FLOOR_MM && q.x >= *x0 && q.x <= *x1 && q.y >= *y0 && q.y <= *y1
        })
    };
    model
        .views
        .iter()
        .map(|view| (0..view.points.len() as u32).filter(|&i| !on_an_item(&view.points[i as usize])).collect())
        .collect()
}

/// The see-through counts of `model` at `pose` (tray -> world) seen from `sensor` (world),
/// against `depth`, over the tray's points of each view (`tray_points` of the model).
/// One thread, no allocation.
pub fn see_through(
    model: &Model,
    tray_points: &[Vec<u32>],
    depth: &DepthEvidence,
    sensor: &Point3<f32>,
    pose: &Isometry3<f64>,
) -> SeeThroughCounts {
    if model.views.is_empty() {
        return SeeThroughCounts::default();
    }
    let k = model.closest_view(pose, sensor);
    let (view, indices) = (&model.views[k], tray_points.get(k).map_or(&[][..], Vec::as_slice));
    let points = indices.iter().map(|&i| (&view.points[i as usize], &view.normals[i as usize]));
    count_seen_through(points, depth, sensor, pose, false)
}

/// The see-through counts of the pose and of its alternative `k` (an index into
/// `turn_parts.alternatives`), each over its own parts that the other lacks: the camera
/// sees past the turned pose's tab where the tray stands the right way round, whether or
/// not it sees the tab itself. On a frame whose holes are unlit pixels (phase-12), a view
/// past a part counts only where the part's whole window was measured
/// (`count_seen_through`). One thread, no allocation.
pub fn turn_see_through(
    model: &Model,
    turn_parts: &TurnParts,
    depth: &DepthEvidence,
    sensor: &Point3<f32>,
    pose: &Isometry3<f64>,
    k: usize,
) -> (SeeThroughCounts, SeeThroughCounts) {
    let back = turn_parts.alternatives.inverse_of(k);
    let (Some(alternative), Some((own_points, own_normals)), Some((points, normals))) =
        (turn_parts.alternatives.list().get(k), turn_parts.parts.get(k), turn_parts.parts.get(back))
    else {
        return Default::default();
    };
    // Each side's parts in sight at its pose: a part the tray's own wall hides is measured
    // in front of it whether or not it is there.
    let in_sight = |parts: usize, pose: &Isometry3<f64>| {
        let view = model.closest_view(pose, sensor);
        let hidden = turn_parts.hidden.get(parts);
        move |&(i, _): &(usize, _)| !hidden.is_some_and(|h| h.hidden(view, i))
    };
    let own_sight = in_sight(k, pose);
    let own_parts = own_points.iter().zip(own_normals).enumerate().filter(own_sight).map(|(_, pn)| pn);
    let own = count_seen_through(own_parts, depth, sensor, pose, true);
    let turned = pose * alternative.transform();
    let their_sight = in_sight(back, &turned);
    let their_parts = points.iter().zip(normals).enumerate().filter(their_sight).map(|(_, pn)| pn);
    let other = count_seen_through(their_parts, depth, sensor, &turned, true);
    (own, other)
}

/// The see-through counts of the model points `points` (tray frame, with their normals)
/// at `pose`: those facing the sensor that fall on a measured pixel, and of them those the
/// sensor measured clearly behind. With `whole_windows` (a turn's distinct parts) and
/// holes that mean an unlit pixel ([`DepthEvidence::holes_unlit`]), a point the sensor
/// measured behind counts, as tested and seen past, only where every pixel of its window
/// was measured, rows the matcher skipped aside: an unmeasured pixel beside it may be the
/// surface itself, in the projector's shadow, and the lit table next to it no view past
/// it. A low tab beside a wall's shadow is where this happens, and its few points decide
/// a turn; the tray's whole surface, weighed against itself a slot's pitch away, keeps
/// every measured window. (Applied to a one-shot frame, whose holes are everywhere, the
/// same rule takes away real views past a turned tab: on the example tray, one shot at
/// r=605, alpha=32, 300 scenes, two more half turns were accepted.)
fn count_seen_through<'a>(
    points: impl Iterator<Item = (&'a Point3<f32>, &'a Vector3<f32>)>,
    depth: &DepthEvidence,
    sensor: &Point3<f32>,
    pose: &Isometry3<f64>,
    whole_windows: bool,
) -> SeeThroughCounts {
    let camera = depth.camera;
    let disparity = depth.disparity;
    let (width, height) = (disparity.width as isize, disparity.height as isize);
    let tray_to_camera = (camera.t_world_rectified.inverse() * pose).cast::<f32>();
    let eye = pose.inverse().cast::<f32>() * sensor;
    let pinhole = Pinhole::of(camera);
    let focal_baseline = pinhole.focal_baseline;
    let mut counts = SeeThroughCounts::default();
    for (m, n) in points {
        if n.dot(&(eye - m)) <= 0.0 {
            continue;
        }
        let p = tray_to_camera * m;
        if p.z <= 1.0 {
            continue;
        }
        let (u, v) = pinhole.pixel(&p);
        if u + WINDOW_PX < 0 || v + WINDOW_PX < 0 || u - WINDOW_PX >= width || v - WINDOW_PX >= height {
            continue;
        }
        // The nearest measured surface around the projection: the largest disparity.
        let (lo, hi) = ((u - WINDOW_PX).max(0) as usize, (u + WINDOW_PX + 1).min(width) as usize);
        let nearest = ((v - WINDOW_PX).max(0)..=(v + WINDOW_PX).min(height - 1))
            .map(|y| depth.nearest_in_row(y as usize, lo, hi, focal_baseline))
            .fold(0.0f32, f32::max);
        if nearest <= 0.0 {
            continue;
        }
        let past = focal_baseline / nearest > p.z + SEE_THROUGH_MARGIN_MM;
        if past
            && whole_windows
            && depth.holes_unlit
            && ((v - WINDOW_PX).max(0)..=(v + WINDOW_PX).min(height - 1)).any(|y| depth.gap_in_row(y as usize, lo, hi))
        {
            continue;
        }
        counts.tested += 1;
        if past {
            counts.seen_through += 1;
        }
    }
    counts
}

/// The tray's two shortest slot-to-slot offsets in different directions (tray frame, mm):
/// the shifts under which a tray of repeated slots lies on itself but for its ends. `None`
/// where the model carries fewer slots. Reads at most the first 64 slots' neighbours.
pub fn slot_pitches(model: &Model) -> [Option<Vector3<f64>>; 2] {
    let Some(layout) = &model.slots else { return [None, None] };
    let at = |s: &[f64; 4]| Vector3::new(s[0], s[1], 0.0);
    let offsets = || {
        layout
            .slots
            .iter()
            .take(64)
            .enumerate()
            .flat_map(|(i, a)| layout.slots[i + 1..].iter().map(move |b| at(b) - at(a)).filter(|d| d.norm() > 1.0))
    };
    let shortest = |keep: &dyn Fn(&Vector3<f64>) -> bool| {
        offsets().filter(|d| keep(d)).min_by(|a, b| a.norm().total_cmp(&b.norm()))
    };
    let first = shortest(&|_| true);
    // The second at more than 30° from the first, either way.
    let second = first.and_then(|f| shortest(&|d| d.dot(&f).abs() < (30f64).to_radians().cos() * d.norm() * f.norm()));
    [first, second]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::SlotLayout;
    use crate::testing;

    /// Six views about equal turns apart, each view once: 60° steps of 12 and of 8 (45°
    /// steps: 0, 45, 135, 180, 225 and 315° against 0, 60 … 300°), every view of fewer.
    #[test]
    fn the_spread_views_are_the_nearest_to_equal_turns() {
        assert_eq!(spread_views(12), [0, 2, 4, 6, 8, 10]);
        assert_eq!(spread_views(8), [0, 1, 3, 4, 5, 7]);
        assert_eq!(spread_views(6), [0, 1, 2, 3, 4, 5]);
        assert_eq!(spread_views(4), [0, 1, 2, 3]);
        for n in 7..=72usize {
            let views = spread_views(n);
            for (j, &k) in views.iter().enumerate() {
                let off = (k as f32 * 360.0 / n as f32 - j as f32 * 60.0).abs();
                assert!(off <= 180.0 / n as f32 + 1e-3, "{n} views: view {k} is {off}° from {}°", j * 60);
            }
        }
    }

    /// The turn parts of the synthetic tray against a search over every point of every
    /// view: each part point has no point of the turned tray within the margin (up to a
    /// cell's diagonal) and a point of two views within two cells' diagonals; the half turn's
    /// parts lie on the tab and nowhere else, and the symmetric tray has none.
    #[test]
    fn turn_parts_are_where_the_turned_tray_has_nothing() {
        let margin = 6.0;
        for symmetric in [false, true] {
            let model = testing::tray(symmetric, 1);
            let parts = TurnParts::of(&model, &Alternatives::of(&model), margin, testing::SENSOR_DISTANCE);
            let whole: Vec<(usize, Point3<f32>)> =
                model.views.iter().enumerate().flat_map(|(k, v)| v.points.iter().map(move |p| (k, *p))).collect();
            // A cell's first point stands for the cell: up to a cell's diagonal from another.
            let slack = model.surface_resolution * 3f32.sqrt();
            assert_eq!(parts.parts.len(), parts.alternatives.list().len());
            for (q, (points, normals)) in (1..4u32).zip(&parts.parts) {
                assert_eq!(points.len(), normals.len());
                assert!(points.len() <= TURN_POINTS);
                let turn = crate::pose::alternatives::quarter_turns(q).cast::<f32>();
                for p in points {
                    // The turned tray's points near p: p turned back, against the tray.
                    let back = turn.inverse() * p;
                    let nearest = whole.iter().map(|(_, w)| (w - back).norm()).fold(f32::INFINITY, f32::min);
                    assert!(nearest > margin - slack, "q {q}: {p} has a turned point {nearest} away");
                    let views_near =
                        model.views.iter().filter(|v| v.points.iter().any(|w| (w - p).norm() <= 2.0 * slack)).count();
                    assert!(views_near >= 2, "q {q}: {p} captured by {views_near} view");
                }
                if q == 2 {
                    // The half turn differs by the tab alone (x 100..116, y 15..45, z 0..15).
                    let on_tab = |p: &Point3<f32>| p.x >= 100.0 - 1e-3 && p.y >= 15.0 - 1e-3 && p.y <= 45.0 + 1e-3;
                    assert_eq!(
                        points.is_empty(),
                        symmetric,
                        "symmetric {symmetric}: {} half-turn points",
                        points.len()
                    );
                    let off: Vec<_> = points.iter().filter(|p| !on_tab(p)).collect();
                    assert!(off.is_empty(), "half-turn parts off the tab: {off:?}");
                    if !symmetric {
                        // The tab's top, captured by every view, is all there (thinning aside).
                        let top = whole.iter().filter(|(_, w)| on_tab(w) && w.x > 100.0 + margin + slack && w.z > 14.9);
                        let top_cells = top.map(|(_, w)| ((w.x / slack).floor() as i32, (w.y / slack).floor() as i32));
                        let cells: std::collections::HashSet<_> = top_cells.collect();
                        let found = points.iter().filter(|p| p.z > 14.9).count();
                        assert!(found + 2 >= cells.len(), "{found} tab-top points of {} cells", cells.len());
                    }
                }
            }
        }
    }

    /// A point 10 mm in front of a table at 1000 mm, straight ahead of a camera at the
    /// origin (f = 500 px, baseline 100 mm: the table at 50 px), judged in a turn's count
    /// (`whole_windows`) and in the tray's: the table measured all round it is a view past
    /// it; a gap in its window (the surface itself unmeasured, in the projector's shadow)
    /// is no evidence in the turn's count, though the tray's count, which takes the nearest
    /// measured pixel, still calls it seen past; a row the matcher skipped is no gap; the
    /// surface measured in the window is no view past it.
    #[test]
    fn a_view_past_a_turns_part_needs_its_whole_window_measured() {
        let (w, h) = (41, 41);
        let camera = RectifiedCamera {
            width: w,
            height: h,
            k: nalgebra::Matrix3::new(500.0, 0.0, 20.0, 0.0, 500.0, 20.0, 0.0, 0.0, 1.0),
            baseline: 100.0,
            t_world_rectified: Isometry3::identity(),
        };
        let (table, surface) = (50.0f32, 50_000.0 / 990.0);
        let point = [(Point3::new(0.0f32, 0.0, 990.0), Vector3::new(0.0f32, 0.0, -1.0))];
        let count = |disparity: &FloatImage, whole_windows: bool| {
            let depth = DepthEvidence { disparity, camera: &camera, beyond: None, holes_unlit: true };
            let points = point.iter().map(|(p, n)| (p, n));
            count_seen_through(points, &depth, &Point3::origin(), &Isometry3::identity(), whole_windows)
        };
        let seen_past = SeeThroughCounts { tested: 1, seen_through: 1 };
        let not_past = SeeThroughCounts { tested: 1, seen_through: 0 };
        let mut all_table = FloatImage::new(w, h, table);
        assert_eq!(count(&all_table, true), seen_past);
        // The rows above and below skipped, as the one-shot matcher skips every other row.
        for y in [19, 21] {
            all_table.row_mut(y).fill(f32::INFINITY);
        }
        assert_eq!(count(&all_table, true), seen_past);
        let mut shadowed = FloatImage::new(w, h, table);
        shadowed.set(20, 20, f32::INFINITY);
        assert_eq!(count(&shadowed, true), SeeThroughCounts::default());
        assert_eq!(count(&shadowed, false), seen_past);
        let mut measured = FloatImage::new(w, h, table);
        measured.set(21, 20, surface);
        assert_eq!(count(&measured, true), not_past);
        assert_eq!(count(&measured, false), not_past);
    }

    fn model_with_slots(slots: Vec<[f64; 4]>) -> Model {
        let layout = SlotLayout {
            slots,
            footprint_min_mm: [-15.0, -15.0],
            cell_mm: [3.75, 3.75],
            cols: 8,
            rows: 8,
            top_mm: vec![30.0; 64],
        };
        Model { slots: Some(layout), ..Model::default() }
    }

    /// The two pitches against every pair of slots compared by hand: the shortest offset,
    /// then the shortest more than 30° off it.
    #[test]
    fn slot_pitches_are_the_two_shortest_offsets_in_different_directions() {
        // A 4 x 2 grid at 48 x 56 mm, and a hexagonal six (60 mm apart, rows 52 mm apart).
        let grid: Vec<[f64; 4]> =
            (0..2).flat_map(|j| (0..4).map(move |i| [i as f64 * 48.0, j as f64 * 56.0, 5.0, 0.0])).collect();
        let hex: Vec<[f64; 4]> = (0..2)
            .flat_map(|j| (0..3).map(move |i| [i as f64 * 60.0 + 30.0 * j as f64, 52.0 * j as f64, 5.0, 0.0]))
            .collect();
        for (slots, want) in [(grid, [48.0, 56.0]), (hex, [60.0, 52.0f64.hypot(30.0)])] {
            let [first, second] = slot_pitches(&model_with_slots(slots.clone()));
            let (first, second) = (first.unwrap(), second.unwrap());
            // By hand: every pair's offset, sorted by length.
            let mut all: Vec<Vector3<f64>> = Vec::new();
            for a in &slots {
                for b in &slots {
                    let d = Vector3::new(b[0] - a[0], b[1] - a[1], 0.0);
                    if d.norm() > 1.0 {
                        all.push(d);
                    }
                }
            }
            all.sort_by(|a, b| a.norm().total_cmp(&b.norm()));
            assert!((first.norm() - all[0].norm()).abs() < 1e-9 && (first.norm() - want[0]).abs() < 1e-9, "{first}");
            let off = all.iter().find(|d| d.angle(&first).min(d.angle(&-first)) > 30f64.to_radians()).unwrap();
            assert!((second.norm() - off.norm()).abs() < 1e-9 && (second.norm() - want[1]).abs() < 1e-9, "{second}");
            assert!(second.angle(&first).min(second.angle(&-first)) > 30f64.to_radians());
        }
        assert_eq!(slot_pitches(&model_with_slots(vec![[0.0, 0.0, 5.0, 0.0]])), [None, None]);
        assert_eq!(slot_pitches(&Model::default()), [None, None]);
    }
}
