//! The cell's named parts in the world frame (mm, z up): the table, the tray and a
//! scenario's items and occluder, the lamp, and each camera's and the projector's frustum
//! from its centre to where its image corners meet the table. Encodings are elsewhere.

use camplace_config::Cell;
use camplace_estimator::{geometry::Camera, Rig};
use nalgebra::{Point3, Vector3};

use crate::scene::scenario::Scenario;
use crate::scene::{Objects, SceneTriangle, ID_FIRST_ITEM, ID_OCCLUDER, ID_TABLE, ID_TRAY};
use crate::Result;

/// How a part's vertices are joined.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Primitive {
    /// Three indices a triangle.
    Triangles,
    /// Every vertex a point (no indices).
    Points,
}

/// One named part of the cell.
#[derive(Debug, Clone)]
pub struct CellPart {
    /// `table`, `tray`, `item_N` (N the slot), `occluder`, `lamp`, `camera_left`,
    /// `camera_right`, `projector` or `cloud`.
    pub name: String,
    /// How the vertices are joined.
    pub primitive: Primitive,
    /// Vertices, world mm.
    pub positions: Vec<[f64; 3]>,
    /// Vertex indices for triangles.
    pub indices: Vec<u32>,
    /// Red, green, blue and opacity, 0 to 1.
    pub colour: [f64; 4],
    /// The camera (or projector) a frustum belongs to: its vertex 0 is the centre.
    pub sensor: Option<Camera>,
}

/// The lamp is drawn as a cube of this edge, mm: it is a point light, only its place matters.
const LAMP_EDGE_MM: f64 = 40.0;

/// The parts of `cell` with scenario `scenario`'s tray, items, occluder and lamp, seen by
/// `rig`: table, tray, items by slot, occluder, lamp, then the left and right camera and the
/// projector (when the rig has one).
pub fn cell_parts(cell: &Cell, rig: &Rig, scenario: &Scenario) -> Result<Vec<CellPart>> {
    let objects = Objects::from_cell(cell)?;
    let mut triangles = Vec::new();
    objects.triangles(&scenario.scene(), &mut triangles);
    let mut parts = Vec::new();
    let soup = |name: String, id: u8, colour: [f64; 4], parts: &mut Vec<CellPart>| {
        let tris: Vec<&SceneTriangle> = triangles.iter().filter(|t| t.id == id).collect();
        if tris.is_empty() {
            return;
        }
        let positions: Vec<[f64; 3]> = tris.iter().flat_map(|t| t.vertices.map(|p| [p.x, p.y, p.z])).collect();
        let indices = (0..positions.len() as u32).collect();
        parts.push(CellPart { name, primitive: Primitive::Triangles, positions, indices, colour, sensor: None });
    };
    soup("table".into(), ID_TABLE, [0.82, 0.80, 0.76, 1.0], &mut parts);
    soup("tray".into(), ID_TRAY, [0.45, 0.47, 0.50, 1.0], &mut parts);
    for &n in &scenario.filled {
        if let Some(id) = u8::try_from(n).ok().and_then(|n| n.checked_add(ID_FIRST_ITEM)) {
            soup(format!("item_{n}"), id, [0.85, 0.55, 0.20, 1.0], &mut parts);
        }
    }
    soup("occluder".into(), ID_OCCLUDER, [0.35, 0.35, 0.35, 0.6], &mut parts);
    parts.push(lamp(scenario.lamp_position));
    let far = 2.0 * rig.left.t_world_camera.translation.vector.norm().max(1.0);
    parts.push(frustum("camera_left", &rig.left, [0.12, 0.47, 0.71, 0.25], far));
    parts.push(frustum("camera_right", &rig.right, [0.84, 0.15, 0.16, 0.25], far));
    if let Some(p) = &rig.projector {
        parts.push(frustum("projector", p, [1.0, 0.50, 0.05, 0.25], far));
    }
    Ok(parts)
}

/// A cube around the lamp's position.
fn lamp(at: Point3<f64>) -> CellPart {
    let h = LAMP_EDGE_MM / 2.0;
    let (lo, hi) = ([at.x - h, at.y - h, at.z - h], [at.x + h, at.y + h, at.z + h]);
    let positions: Vec<[f64; 3]> =
        crate::scene::tray::box_triangles(lo, hi).flat_map(|t| t.map(|p| [p.x, p.y, p.z])).collect();
    let indices = (0..positions.len() as u32).collect();
    CellPart {
        name: "lamp".into(),
        primitive: Primitive::Triangles,
        positions,
        indices,
        colour: [1.0, 0.85, 0.2, 1.0],
        sensor: None,
    }
}

/// Where the rays through a camera's four image corners (the outer edges of the corner
/// pixels, top-left first, clockwise in the image) meet the table, or stop `far` mm out
/// when one points above it; and whether all four met it.
fn corner_ends(c: &Camera, far: f64) -> ([Point3<f64>; 4], bool) {
    let centre = Point3::from(c.t_world_camera.translation.vector);
    let kinv = c.k.try_inverse().unwrap_or_else(nalgebra::Matrix3::identity);
    let (w, h) = (c.width as f64 - 0.5, c.height as f64 - 0.5);
    let mut on_table = true;
    let mut corner = |u: f64, v: f64| {
        let d = c.t_world_camera.rotation * (kinv * Vector3::new(u, v, 1.0)).normalize();
        let t = if d.z < -1e-9 { -centre.z / d.z } else { f64::INFINITY };
        if t > far {
            on_table = false;
        }
        centre + d * t.min(far)
    };
    let ends = [corner(-0.5, -0.5), corner(w, -0.5), corner(w, h), corner(-0.5, h)];
    (ends, on_table)
}

/// A frustum: the centre (vertex 0) and the four corner rays down to the table, as four
/// side triangles.
fn frustum(name: &str, c: &Camera, colour: [f64; 4], far: f64) -> CellPart {
    let centre = c.t_world_camera.translation.vector;
    let (ends, _) = corner_ends(c, far);
    let mut positions = vec![[centre.x, centre.y, centre.z]];
    positions.extend(ends.iter().map(|p| [p.x, p.y, p.z]));
    let indices = vec![0, 1, 2, 0, 2, 3, 0, 3, 4, 0, 4, 1];
    CellPart { name: name.into(), primitive: Primitive::Triangles, positions, indices, colour, sensor: Some(c.clone()) }
}

/// The quadrilateral a camera's image covers on the table (x, y in mm), when all four
/// corner rays meet the table within `far` mm.
pub fn table_footprint(c: &Camera, far: f64) -> Option<[[f64; 2]; 4]> {
    let (ends, on_table) = corner_ends(c, far);
    on_table.then(|| ends.map(|p| [p.x, p.y]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::scenario::draw_scenario;
    use camplace_estimator::geometry::rig_for;

    #[test]
    fn frustums_start_at_the_centres_and_end_on_the_table_inside_the_image() {
        let cell = Cell::default();
        let rig = rig_for(&cell.placement, &cell.sensor);
        let parts = cell_parts(&cell, &rig, &draw_scenario(&cell, 1, 0)).unwrap();
        for (name, cam) in [("camera_left", &rig.left), ("camera_right", &rig.right)] {
            let part = parts.iter().find(|p| p.name == name).unwrap();
            let c = cam.t_world_camera.translation.vector;
            assert_eq!(part.positions[0], [c.x, c.y, c.z]);
            for p in &part.positions[1..] {
                assert!(p[2].abs() < 1e-6, "{name}: a corner on the table, {p:?}");
                // Projected back, each corner lands on the image's outer edge.
                let local = cam.t_world_camera.inverse_transform_point(&Point3::from(*p));
                let uv = cam.k * local.coords / local.z;
                let on_edge = |v: f64, size: usize| (v + 0.5).abs() < 1e-6 || (v - (size as f64 - 0.5)).abs() < 1e-6;
                assert!(on_edge(uv.x, cam.width) && on_edge(uv.y, cam.height), "{name}: {uv:?}");
            }
        }
        let names: Vec<&str> = parts.iter().map(|p| p.name.as_str()).collect();
        assert_eq!(&names[..2], ["table", "tray"]);
        assert!(names.contains(&"lamp") && names.contains(&"projector"), "{names:?}");
        let items = names.iter().filter(|n| n.starts_with("item_")).count();
        assert_eq!(items, draw_scenario(&cell, 1, 0).filled.len());
    }
}
