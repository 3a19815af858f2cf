//! The objects on the table as triangle meshes in their own frames: the built-in trays
//! ("tray-4", "tray-8") with their slots, the built-in box item, and trays and items read
//! from mesh files. Where the objects stand in the world is the scene's business.

use camplace_config::Mesh;
use camplace_config::{Cell, ItemsKind, TrayKind};
use camplace_estimator::{pose::SlotLayout, pose::EDGE_CELL, pose::MAX_FOOTPRINT_CELLS};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};

use crate::{Error, Result};

/// Thickness of a built-in tray's base plate, mm; the slots sit on its top face.
pub const BASE_THICKNESS: f64 = 5.0;
/// Height of a built-in tray's rim above its bottom face, mm.
pub const RIM_HEIGHT: f64 = 25.0;
/// Thickness of a built-in tray's outer walls, mm.
pub const WALL_THICKNESS: f64 = 4.0;
/// Height of the low dividers between slots above the bottom face, mm.
pub const DIVIDER_HEIGHT: f64 = 15.0;
/// Thickness of the dividers, mm.
pub const DIVIDER_THICKNESS: f64 = 2.0;
/// The tab on the tray's +x side that breaks its symmetry: how far it sticks out, its
/// width along y and its height, mm.
pub const TAB_SIZE: [f64; 3] = [12.0, 40.0, 15.0];

/// The twelve triangles of the axis-aligned box `[min, max]`, its faces wound outwards.
pub fn box_triangles(min: [f64; 3], max: [f64; 3]) -> impl Iterator<Item = [Point3<f64>; 3]> {
    let p =
        move |i: usize, j: usize, k: usize| Point3::new([min[0], max[0]][i], [min[1], max[1]][j], [min[2], max[2]][k]);
    let faces = [
        [p(0, 0, 0), p(0, 0, 1), p(0, 1, 1), p(0, 1, 0)],
        [p(1, 0, 0), p(1, 1, 0), p(1, 1, 1), p(1, 0, 1)],
        [p(0, 0, 0), p(1, 0, 0), p(1, 0, 1), p(0, 0, 1)],
        [p(0, 1, 0), p(0, 1, 1), p(1, 1, 1), p(1, 1, 0)],
        [p(0, 0, 0), p(0, 1, 0), p(1, 1, 0), p(1, 0, 0)],
        [p(0, 0, 1), p(1, 0, 1), p(1, 1, 1), p(0, 1, 1)],
    ];
    faces.into_iter().flat_map(|[a, b, c, d]| [[a, b, c], [a, c, d]])
}

/// A triangle soup in its object's frame, mm.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Solid {
    /// Triangles, each counter-clockwise seen from outside where the source says so.
    pub triangles: Vec<[Point3<f64>; 3]>,
}

impl Solid {
    /// Adds the axis-aligned box `[min, max]`, its faces wound outwards.
    pub fn push_box(&mut self, min: [f64; 3], max: [f64; 3]) {
        self.triangles.extend(box_triangles(min, max));
    }

    /// The triangles of a loaded mesh; an index past the vertex list is an error.
    pub fn from_mesh(m: &Mesh) -> Result<Solid> {
        let vertex = |i: u32| {
            m.vertices
                .get(i as usize)
                .map(|v| Point3::new(v[0] as f64, v[1] as f64, v[2] as f64))
                .ok_or_else(|| Error::Other(format!("mesh triangle refers to vertex {i} of {}", m.vertices.len())))
        };
        let mut triangles = Vec::with_capacity(m.triangles.len());
        for t in &m.triangles {
            triangles.push([vertex(t[0])?, vertex(t[1])?, vertex(t[2])?]);
        }
        Ok(Solid { triangles })
    }

    /// About `count` points spread over the surface by area (each triangle gets its share,
    /// placed by the R2 low-discrepancy sequence): the same points every call, whatever the
    /// mesh's triangle count. Empty for a solid without area.
    pub fn surface_points(&self, count: usize) -> Vec<Point3<f64>> {
        let area = |t: &[Point3<f64>; 3]| 0.5 * (t[1] - t[0]).cross(&(t[2] - t[0])).norm();
        let total: f64 = self.triangles.iter().map(area).sum();
        if total.is_nan() || total <= 0.0 || count == 0 {
            return Vec::new();
        }
        // R2's constants: 1/g and 1/g² for g the plastic number's root of x³ = x + 1.
        const G: f64 = 1.324_717_957_244_746;
        let mut out = Vec::with_capacity(count + self.triangles.len().min(count));
        let (mut owed, mut k) = (0.0, 0u64);
        for t in &self.triangles {
            owed += area(t) / total * count as f64;
            while owed >= 0.5 {
                owed -= 1.0;
                k += 1;
                let (mut a, mut b) = ((k as f64 / G).fract(), (k as f64 / (G * G)).fract());
                if a + b > 1.0 {
                    (a, b) = (1.0 - a, 1.0 - b);
                }
                out.push(t[0] + (t[1] - t[0]) * a + (t[2] - t[0]) * b);
            }
        }
        out
    }

    /// Axis-aligned bounds `(min, max)`; both at the origin for an empty solid.
    pub fn bounds(&self) -> (Point3<f64>, Point3<f64>) {
        let mut it = self.triangles.iter().flatten();
        let Some(first) = it.next() else { return (Point3::origin(), Point3::origin()) };
        it.fold((*first, *first), |(lo, hi), p| (lo.inf(p), hi.sup(p)))
    }
}

/// The tray: its mesh, its slots and the dimensions the tests and the study refer to.
#[derive(Debug, Clone, PartialEq)]
pub struct TrayModel {
    /// The tray in the tray frame (origin at the bottom face centre, z up).
    pub solid: Solid,
    /// Slot poses `[x, y, z, yaw]` (mm, deg): where an item's bottom centre sits.
    pub slots: Vec<[f64; 4]>,
    /// Height of the rim top above the bottom face, mm.
    pub rim_height: f64,
    /// Outer extent of the walls along tray x and y, mm (the tab sticks out beyond it).
    pub outer: [f64; 2],
    /// Wall thickness, mm (0 for a mesh tray, whose walls are unknown).
    pub wall: f64,
}

impl TrayModel {
    /// The tray the cell asks for: built in, or loaded from its mesh file.
    pub fn from_cell(cell: &Cell) -> Result<TrayModel> {
        match cell.tray.kind {
            TrayKind::Tray4 => Ok(TrayModel::builtin(2, 2, [130.0, 130.0])),
            TrayKind::Tray8 => Ok(TrayModel::builtin(4, 2, [200.0, 120.0])),
            TrayKind::Mesh => {
                let solid = Solid::from_mesh(&camplace_config::load_mesh(&cell.tray.mesh)?)?;
                let (lo, hi) = solid.bounds();
                Ok(TrayModel {
                    slots: cell.tray.slots.clone(),
                    rim_height: hi.z,
                    outer: [hi.x - lo.x, hi.y - lo.y],
                    wall: 0.0,
                    solid,
                })
            }
        }
    }

    /// A built-in tray with `cols` x `rows` slots inside walls of `outer` size: base plate,
    /// rim walls, low dividers and the tab on +x (off centre in neither axis, but alone on
    /// its side, so no rotation about z maps the tray onto itself).
    fn builtin(cols: usize, rows: usize, outer: [f64; 2]) -> TrayModel {
        let (hx, hy) = (outer[0] / 2.0, outer[1] / 2.0);
        let (ix, iy) = (hx - WALL_THICKNESS, hy - WALL_THICKNESS);
        let mut s = Solid::default();
        // The base spans only the inside so no visible face coincides with a wall's.
        s.push_box([-ix, -iy, 0.0], [ix, iy, BASE_THICKNESS]);
        s.push_box([-hx, -hy, 0.0], [-ix, hy, RIM_HEIGHT]);
        s.push_box([ix, -hy, 0.0], [hx, hy, RIM_HEIGHT]);
        s.push_box([-ix, -hy, 0.0], [ix, -iy, RIM_HEIGHT]);
        s.push_box([-ix, iy, 0.0], [ix, hy, RIM_HEIGHT]);
        let (pitch_x, pitch_y) = (2.0 * ix / cols as f64, 2.0 * iy / rows as f64);
        let half = DIVIDER_THICKNESS / 2.0;
        for i in 1..cols {
            let x = -ix + i as f64 * pitch_x;
            s.push_box([x - half, -iy, BASE_THICKNESS], [x + half, iy, DIVIDER_HEIGHT]);
        }
        for j in 1..rows {
            let y = -iy + j as f64 * pitch_y;
            s.push_box([-ix, y - half, BASE_THICKNESS], [ix, y + half, DIVIDER_HEIGHT]);
        }
        let [tab_x, tab_y, tab_z] = TAB_SIZE;
        s.push_box([hx, -tab_y / 2.0, 0.0], [hx + tab_x, tab_y / 2.0, tab_z]);
        let mut slots = Vec::with_capacity(cols * rows);
        for j in 0..rows {
            for i in 0..cols {
                let x = -ix + (i as f64 + 0.5) * pitch_x;
                let y = -iy + (j as f64 + 0.5) * pitch_y;
                slots.push([x, y, BASE_THICKNESS, 0.0]);
            }
        }
        TrayModel { solid: s, slots, rim_height: RIM_HEIGHT, outer, wall: WALL_THICKNESS }
    }

    /// Pose of slot `n` in the tray frame (item frame -> tray frame); `None` past the end.
    pub fn slot_pose(&self, n: usize) -> Option<Isometry3<f64>> {
        let [x, y, z, yaw] = *self.slots.get(n)?;
        Some(Isometry3::from_parts(
            Translation3::new(x, y, z),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw.to_radians()),
        ))
    }

    /// Whether tray-frame (x, y) lies on the rim's top face, at least `margin` mm inside
    /// its edges (always false for a mesh tray).
    pub fn on_rim_top(&self, x: f64, y: f64, margin: f64) -> bool {
        if self.wall <= 2.0 * margin {
            return false;
        }
        let (hx, hy) = (self.outer[0] / 2.0 - margin, self.outer[1] / 2.0 - margin);
        let (ix, iy) = (hx - self.wall + 2.0 * margin, hy - self.wall + 2.0 * margin);
        let inside_outer = x.abs() < hx && y.abs() < hy;
        let inside_inner = x.abs() < ix && y.abs() < iy;
        inside_outer && !inside_inner
    }
}

/// How far the slot footprint keeps inside the item's outline, mm: the item's side faces
/// and a millimetre or two of pose error stay outside it.
const FOOTPRINT_MARGIN_MM: f64 = 2.0;
/// Samples per footprint cell along each axis when the item's top is traced.
const PROFILE_SAMPLES: usize = 4;
/// How much an item's top may vary over one cell and the cell still be compared, mm.
const PROFILE_FLAT_MM: f64 = 1.0;

/// The slots of `tray` holding `item`, as the model carries them: the slot poses, and the
/// item's outline (less a margin) cut into cells of about `cell_mm` with the top of an
/// upright item over each, traced down onto its triangles. `None` for a tray without slots
/// or an item without an outline larger than the margins.
pub fn slot_layout(tray: &TrayModel, item: &Solid, cell_mm: f64) -> Option<SlotLayout> {
    if tray.slots.is_empty() {
        return None;
    }
    let (lo, hi) = item.bounds();
    let (x0, y0) = (lo.x + FOOTPRINT_MARGIN_MM, lo.y + FOOTPRINT_MARGIN_MM);
    let (w, d) = (hi.x - lo.x - 2.0 * FOOTPRINT_MARGIN_MM, hi.y - lo.y - 2.0 * FOOTPRINT_MARGIN_MM);
    if !(w > 0.0 && d > 0.0 && cell_mm > 0.0) {
        return None;
    }
    let cols = (w / cell_mm).ceil().max(1.0) as usize;
    let rows = (d / cell_mm).ceil().max(1.0) as usize;
    // A footprint past what a model may hold gives no slot layout (the model says so), not
    // a layout its own loader would refuse.
    if cols.saturating_mul(rows) > MAX_FOOTPRINT_CELLS {
        return None;
    }
    let (cx, cy) = (w / cols as f64, d / rows as f64);
    let mut top_mm = Vec::with_capacity(cols * rows);
    for j in 0..rows {
        for i in 0..cols {
            let mut tops = Vec::with_capacity(PROFILE_SAMPLES * PROFILE_SAMPLES);
            for a in 0..PROFILE_SAMPLES {
                for b in 0..PROFILE_SAMPLES {
                    let x = x0 + (i as f64 + (a as f64 + 0.5) / PROFILE_SAMPLES as f64) * cx;
                    let y = y0 + (j as f64 + (b as f64 + 0.5) / PROFILE_SAMPLES as f64) * cy;
                    tops.push(top_at(item, x, y));
                }
            }
            let hits: Vec<f64> = tops.iter().flatten().copied().collect();
            let value = if hits.is_empty() {
                0.0
            } else {
                let (low, high) =
                    hits.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &z| (l.min(z), h.max(z)));
                if hits.len() == tops.len() && high - low <= PROFILE_FLAT_MM {
                    high as f32
                } else {
                    EDGE_CELL
                }
            };
            top_mm.push(value);
        }
    }
    let layout = SlotLayout {
        slots: tray.slots.clone(),
        footprint_min_mm: [x0 as f32, y0 as f32],
        cell_mm: [cx as f32, cy as f32],
        cols: cols as u32,
        rows: rows as u32,
        top_mm,
    };
    layout.validate().is_ok().then_some(layout)
}

/// The highest point of `solid` straight above item-frame (x, y), if any triangle is there.
fn top_at(solid: &Solid, x: f64, y: f64) -> Option<f64> {
    let mut best: Option<f64> = None;
    for [a, b, c] in &solid.triangles {
        let det = (b.y - c.y) * (a.x - c.x) + (c.x - b.x) * (a.y - c.y);
        if det.abs() < 1e-12 {
            continue;
        }
        let l1 = ((b.y - c.y) * (x - c.x) + (c.x - b.x) * (y - c.y)) / det;
        let l2 = ((c.y - a.y) * (x - c.x) + (a.x - c.x) * (y - c.y)) / det;
        let l3 = 1.0 - l1 - l2;
        if l1 >= 0.0 && l2 >= 0.0 && l3 >= 0.0 {
            let z = l1 * a.z + l2 * b.z + l3 * c.z;
            best = Some(best.map_or(z, |t| t.max(z)));
        }
    }
    best
}

/// The number of slots of the cell's tray, known without loading a mesh.
pub fn slot_count(cell: &Cell) -> usize {
    match cell.tray.kind {
        TrayKind::Tray4 => 4,
        TrayKind::Tray8 => 8,
        TrayKind::Mesh => cell.tray.slots.len(),
    }
}

/// The item the cell asks for, in the item frame (origin at its bottom centre, z up).
pub fn item_for(cell: &Cell) -> Result<Solid> {
    match cell.items.kind {
        ItemsKind::Box => {
            let [x, y, z] = cell.items.size;
            let mut s = Solid::default();
            s.push_box([-x / 2.0, -y / 2.0, 0.0], [x / 2.0, y / 2.0, z]);
            Ok(s)
        }
        ItemsKind::Mesh => Solid::from_mesh(&camplace_config::load_mesh(&cell.items.mesh)?),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The default box's profile is flat at its height over every cell, the slots are the
    /// tray's, and a sample point's top is the highest triangle above it.
    #[test]
    fn a_box_items_profile_is_its_top() {
        let tray = TrayModel::builtin(4, 2, [200.0, 120.0]);
        let mut item = Solid::default();
        item.push_box([-17.0, -17.0, 0.0], [17.0, 17.0, 30.0]);
        let l = slot_layout(&tray, &item, 4.0).unwrap();
        assert_eq!((l.cols, l.rows, l.slots.len()), (8, 8, 8));
        assert_eq!(l.footprint_min_mm, [-15.0, -15.0]);
        assert!(l.top_mm.iter().all(|&t| t == 30.0), "{:?}", l.top_mm);
        assert_eq!(l.slots, tray.slots);
        // A stepped item: a 10 mm block with a 20 mm tower over x > 0; the cells the step
        // crosses are edges.
        let mut step = Solid::default();
        step.push_box([-17.0, -17.0, 0.0], [17.0, 17.0, 10.0]);
        step.push_box([1.0, -17.0, 0.0], [17.0, 17.0, 20.0]);
        let l = slot_layout(&tray, &step, 4.0).unwrap();
        for j in 0..8 {
            for i in 0..8 {
                let x0 = -15.0 + i as f32 * 3.75;
                let want = if x0 + 3.75 <= 1.0 {
                    10.0
                } else if x0 >= 1.0 {
                    20.0
                } else {
                    EDGE_CELL
                };
                assert_eq!(l.top_mm[j * 8 + i], want, "cell {i}, {j}");
            }
        }
        assert!(slot_layout(&TrayModel { slots: vec![], ..tray.clone() }, &item, 4.0).is_none());
    }

    /// Signed volume by the divergence theorem: positive when every face is wound outwards.
    fn volume(s: &Solid) -> f64 {
        s.triangles.iter().map(|[a, b, c]| a.coords.dot(&b.coords.cross(&c.coords)) / 6.0).sum()
    }

    #[test]
    fn surface_points_lie_on_the_surface_shared_by_area() {
        // A 2 x 1 x 1 box: faces of area 2 (four) and 1 (two), 10 in all.
        let mut solid = Solid::default();
        solid.push_box([0.0, 0.0, 0.0], [2.0, 1.0, 1.0]);
        let points = solid.surface_points(10_000);
        assert_eq!(points, solid.surface_points(10_000), "the same points every call");
        assert!(points.len().abs_diff(10_000) <= solid.triangles.len(), "{}", points.len());
        // Each point on exactly the faces it belongs to; counted per face (slow and obvious).
        let mut per_face = [0usize; 6];
        for p in &points {
            let on = [p.x == 0.0, p.x == 2.0, p.y == 0.0, p.y == 1.0, p.z == 0.0, p.z == 1.0];
            let near = |v: f64, w: f64| (v - w).abs() < 1e-12;
            let close =
                [near(p.x, 0.0), near(p.x, 2.0), near(p.y, 0.0), near(p.y, 1.0), near(p.z, 0.0), near(p.z, 1.0)];
            let inside = (-1e-12..=2.0 + 1e-12).contains(&p.x)
                && (-1e-12..=1.0 + 1e-12).contains(&p.y)
                && (-1e-12..=1.0 + 1e-12).contains(&p.z);
            assert!(inside && close.iter().any(|&c| c), "{p} is off the box's surface ({on:?})");
            per_face[close.iter().position(|&c| c).unwrap()] += 1;
        }
        // x faces have area 1, y and z faces area 2: 1 000 and 2 000 points, each to a few.
        let want = [1000, 1000, 2000, 2000, 2000, 2000];
        for (face, (&got, &want)) in per_face.iter().zip(&want).enumerate() {
            assert!(got.abs_diff(want) <= 25, "face {face}: {got} points, expected about {want}");
        }
        assert!(Solid::default().surface_points(100).is_empty());
    }

    #[test]
    fn boxes_are_wound_outwards() {
        let mut s = Solid::default();
        s.push_box([-1.0, 2.0, 0.0], [3.0, 5.0, 7.0]);
        assert!((volume(&s) - 4.0 * 3.0 * 7.0).abs() < 1e-9);
    }

    #[test]
    fn builtin_trays_hold_their_items_and_fit_the_view() {
        let mut cell = Cell::default();
        for (kind, n) in [(TrayKind::Tray4, 4), (TrayKind::Tray8, 8)] {
            cell.tray.kind = kind;
            let tray = TrayModel::from_cell(&cell).unwrap();
            assert_eq!(tray.slots.len(), n);
            assert_eq!(slot_count(&cell), n);
            let (lo, hi) = tray.solid.bounds();
            assert!(hi.x - lo.x <= 215.0 && hi.y - lo.y <= 135.0 && lo.z == 0.0 && hi.z == RIM_HEIGHT);
            let item = item_for(&cell).unwrap();
            let (ilo, ihi) = item.bounds();
            // Every item, placed in its slot, stays inside the walls and clear of dividers
            // and of the other items.
            let mut boxes = Vec::new();
            for k in 0..n {
                let pose = tray.slot_pose(k).unwrap();
                let a = pose.transform_point(&ilo);
                let b = pose.transform_point(&ihi);
                let (bl, bh) = (a.inf(&b), a.sup(&b));
                assert!(bl.x.abs() < tray.outer[0] / 2.0 - tray.wall && bh.x.abs() < tray.outer[0] / 2.0 - tray.wall);
                assert!(bl.y.abs() < tray.outer[1] / 2.0 - tray.wall && bh.y.abs() < tray.outer[1] / 2.0 - tray.wall);
                assert_eq!(bl.z, BASE_THICKNESS);
                boxes.push((bl, bh));
            }
            for (i, (al, ah)) in boxes.iter().enumerate() {
                for (bl, bh) in &boxes[i + 1..] {
                    let apart = ah.x + DIVIDER_THICKNESS < bl.x
                        || bh.x + DIVIDER_THICKNESS < al.x
                        || ah.y + DIVIDER_THICKNESS < bl.y
                        || bh.y + DIVIDER_THICKNESS < al.y;
                    assert!(apart, "{kind:?}: items {i} overlap");
                }
            }
        }
    }

    #[test]
    fn tab_breaks_every_rotation() {
        for kind in [TrayKind::Tray4, TrayKind::Tray8] {
            let mut cell = Cell::default();
            cell.tray.kind = kind;
            let tray = TrayModel::from_cell(&cell).unwrap();
            let (lo, hi) = tray.solid.bounds();
            // The bounds are lopsided in x only because of the tab, so no turn about z
            // (which would move the tab to another side) leaves them unchanged.
            assert!((hi.x + lo.x - TAB_SIZE[0]).abs() < 1e-9);
            assert!((hi.y + lo.y).abs() < 1e-9);
        }
    }
}
