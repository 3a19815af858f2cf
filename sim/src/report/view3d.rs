//! The report's 3D view of the cell at the recommended placement: the table, the tray and
//! items of the shown scenario, the lamp, each camera's and the projector's frustum, the
//! table region all three cover, the box the rig's position may move in within its mounting
//! tolerances, and the other checked placements coloured by success. The scene is an inline
//! JSON block (`#scene3d`, world mm, z up) drawn by camplace-plot's shared viewer, inlined
//! too: no request leaves the page.

use camplace_config::{Cell, Placement, ToleranceReport};
use camplace_estimator::{geometry::rig_pose, Rig};
use camplace_plot::{legend_entry, view3d_html, ViewCanvas};
use serde_json::{json, Value};

use super::heatmap::viridis;
use crate::export::{cell_parts, table_footprint, Primitive};
use crate::scene::scenario::Scenario;
use crate::Result;

/// A placement checked by the study, drawn as a marker where its rig would hang.
#[derive(Debug, Clone)]
pub struct CheckedPlacement {
    /// The placement.
    pub placement: Placement,
    /// "grid", "search" or "recheck".
    pub from: String,
    /// Its success rate (its lowest tray's), 0 to 1.
    pub success: f64,
}

/// What the view shows.
pub struct View3d<'a> {
    /// The cell (its table, tray and items).
    pub cell: &'a Cell,
    /// The recommended placement.
    pub placement: Placement,
    /// Its rig.
    pub rig: &'a Rig,
    /// The scenario whose tray, items and lamp are drawn.
    pub scenario: &'a Scenario,
    /// The mounting tolerances, when measured.
    pub tolerance: Option<&'a ToleranceReport>,
    /// The other checked placements.
    pub checked: Vec<CheckedPlacement>,
}

/// `#rrggbb` of a 0..1 RGB.
fn hex(rgb: [f64; 3]) -> String {
    let c = |v: f64| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
    format!("#{:02x}{:02x}{:02x}", c(rgb[0]), c(rgb[1]), c(rgb[2]))
}

/// A heat-map colour of a success rate on the reports' one 0–100 % scale.
fn success_colour(rate: f64) -> String {
    let c = viridis(rate);
    format!("#{:02x}{:02x}{:02x}", c.0, c.1, c.2)
}

/// A coordinate to a micrometre: far below what the view or a test resolves, and short.
fn um(v: f64) -> f64 {
    (v * 1000.0).round() / 1000.0
}

fn point(p: [f64; 3]) -> Value {
    json!([um(p[0]), um(p[1]), um(p[2])])
}

/// The part of convex polygon `poly` on the left of the directed edge a→b (Sutherland–Hodgman).
fn clip(poly: &[[f64; 2]], a: [f64; 2], b: [f64; 2]) -> Vec<[f64; 2]> {
    let side = |p: [f64; 2]| (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]);
    let mut out = Vec::new();
    for i in 0..poly.len() {
        let (p, q) = (poly[i], poly[(i + 1) % poly.len()]);
        let (sp, sq) = (side(p), side(q));
        if sp >= 0.0 {
            out.push(p);
        }
        if (sp >= 0.0) != (sq >= 0.0) {
            let t = sp / (sp - sq);
            out.push([p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])]);
        }
    }
    out
}

/// `poly` turned counter-clockwise (positive area), as `clip` keeps the left side.
fn counter_clockwise(mut poly: Vec<[f64; 2]>) -> Vec<[f64; 2]> {
    let area: f64 = (0..poly.len())
        .map(|i| {
            let (p, q) = (poly[i], poly[(i + 1) % poly.len()]);
            p[0] * q[1] - q[0] * p[1]
        })
        .sum();
    if area < 0.0 {
        poly.reverse();
    }
    poly
}

/// The intersection of convex polygons (each any orientation).
pub fn intersect(polys: &[Vec<[f64; 2]>]) -> Vec<[f64; 2]> {
    let mut acc = counter_clockwise(polys[0].clone());
    for other in &polys[1..] {
        let other = counter_clockwise(other.clone());
        for i in 0..other.len() {
            if acc.is_empty() {
                return acc;
            }
            acc = clip(&acc, other[i], other[(i + 1) % other.len()]);
        }
    }
    acc
}

/// The rig origin's positions at the corners of the tolerances of r, alpha and azimuth
/// (the parameters that move it; baseline and vergence turn the cameras about it), in the
/// order x-, x+ fastest over (r, alpha, azimuth): the box the rig may hang in.
fn tolerance_corners(p: &Placement, t: &ToleranceReport) -> Option<[[f64; 3]; 8]> {
    let range = |name: &str| t.axes.iter().find(|a| a.parameter == name).map_or([0.0, 0.0], |a| [-a.minus, a.plus]);
    let (r, alpha, azimuth) = (range("r"), range("alpha"), range("azimuth"));
    if [r, alpha, azimuth].iter().all(|s| s == &[0.0, 0.0]) {
        return None;
    }
    let mut out = [[0.0; 3]; 8];
    for (i, c) in out.iter_mut().enumerate() {
        let q = Placement {
            r: p.r + r[i & 1],
            alpha: p.alpha + alpha[(i >> 1) & 1],
            azimuth: p.azimuth + azimuth[(i >> 2) & 1],
            ..*p
        };
        let o = rig_pose(&q).translation.vector;
        *c = [o.x, o.y, o.z];
    }
    Some(out)
}

/// The scene as the view's JSON.
pub fn scene_json(v: &View3d) -> Result<Value> {
    let mut parts = Vec::new();
    let mut legend = Vec::new();
    let mut sensors = serde_json::Map::new();
    for part in cell_parts(v.cell, v.rig, v.scenario)? {
        if part.primitive != Primitive::Triangles {
            continue;
        }
        let colour = hex([part.colour[0], part.colour[1], part.colour[2]]);
        let triangles: Vec<[u32; 3]> = part.indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
        let kind = if part.sensor.is_some() { "frustum" } else { "solid" };
        let mut out = json!({
            "name": part.name, "kind": kind, "colour": colour, "opacity": part.colour[3],
            "positions": part.positions.iter().map(|&p| point(p)).collect::<Vec<_>>(),
            "triangles": triangles,
        });
        if let Some(c) = &part.sensor {
            // The frustum's edges: from the centre to each corner and round the corners.
            out["edges"] = json!([[0, 1], [0, 2], [0, 3], [0, 4], [1, 2], [2, 3], [3, 4], [4, 1]]);
            let t = c.t_world_camera.translation.vector;
            let axis = c.t_world_camera.rotation * nalgebra::Vector3::z();
            sensors.insert(part.name.clone(), json!({"centre": [t.x, t.y, t.z], "axis": [axis.x, axis.y, axis.z]}));
        }
        let label = match part.name.as_str() {
            "camera_left" => Some("left camera and its view"),
            "camera_right" => Some("right camera and its view"),
            "projector" => Some("projector and its pattern"),
            "table" | "tray" | "lamp" | "occluder" => Some(part.name.as_str()),
            _ if part.name == "item_0" || (part.name.starts_with("item_") && !legend_has(&legend, "items")) => {
                Some("items")
            }
            _ => None,
        };
        if let Some(label) = label {
            if !legend_has(&legend, label) {
                legend.push(json!({"label": label, "colour": colour}));
            }
        }
        parts.push(out);
    }
    // The table region every sensor covers: where a tray can be seen and lit.
    let far = 4.0 * v.placement.r.max(1.0);
    let [sx, sy] = v.cell.table.size;
    let mut polys =
        vec![vec![[-sx / 2.0, -sy / 2.0], [sx / 2.0, -sy / 2.0], [sx / 2.0, sy / 2.0], [-sx / 2.0, sy / 2.0]]];
    let sensors_rig = [Some(&v.rig.left), Some(&v.rig.right), v.rig.projector.as_ref()];
    for c in sensors_rig.into_iter().flatten() {
        if let Some(f) = table_footprint(c, far) {
            polys.push(f.to_vec());
        }
    }
    let covered = intersect(&polys);
    let covered_area = if covered.len() >= 3 {
        // Lifted half a mm so that it is drawn over the table, not into it.
        let positions: Vec<Value> = covered.iter().map(|p| point([p[0], p[1], 0.5])).collect();
        let triangles: Vec<[usize; 3]> = (1..covered.len() - 1).map(|i| [0, i, i + 1]).collect();
        let edges: Vec<[usize; 2]> = (0..covered.len()).map(|i| [i, (i + 1) % covered.len()]).collect();
        parts.push(json!({
            "name": "covered", "kind": "region", "colour": "#2ca02c", "opacity": 0.45,
            "positions": positions, "triangles": triangles, "edges": edges,
        }));
        legend.push(json!({"label": "table seen by both cameras and lit by the projector", "colour": "#2ca02c"}));
        (0..covered.len())
            .map(|i| {
                let (p, q) = (covered[i], covered[(i + 1) % covered.len()]);
                p[0] * q[1] - q[0] * p[1]
            })
            .sum::<f64>()
            .abs()
            / 2.0
    } else {
        0.0
    };
    if let Some(corners) = v.tolerance.and_then(|t| tolerance_corners(&v.placement, t)) {
        // Bit 0 of a corner's index is r, bit 1 alpha, bit 2 azimuth: the six faces.
        let faces = [[0, 2, 6, 4], [1, 5, 7, 3], [0, 4, 5, 1], [2, 3, 7, 6], [0, 1, 3, 2], [4, 6, 7, 5]];
        let triangles: Vec<[usize; 3]> = faces.iter().flat_map(|f| [[f[0], f[1], f[2]], [f[0], f[2], f[3]]]).collect();
        let edges = [[0, 1], [2, 3], [4, 5], [6, 7], [0, 2], [1, 3], [4, 6], [5, 7], [0, 4], [1, 5], [2, 6], [3, 7]];
        parts.push(json!({
            "name": "tolerance_box", "kind": "box", "colour": "#9467bd", "opacity": 0.3,
            "positions": corners.iter().map(|&p| point(p)).collect::<Vec<_>>(),
            "triangles": triangles, "edges": edges,
        }));
        legend.push(json!({"label": "where the rig may hang within its mounting tolerances (r, alpha, azimuth)", "colour": "#9467bd"}));
    }
    let recommended = rig_pose(&v.placement).translation.vector;
    let mut markers = vec![json!({
        "placement": v.placement.to_string(), "from": "recommended", "recommended": true,
        "position": point([recommended.x, recommended.y, recommended.z]),
        "success": Value::Null, "colour": "#ffffff",
    })];
    for c in &v.checked {
        let o = rig_pose(&c.placement).translation.vector;
        markers.push(json!({
            "placement": c.placement.to_string(), "from": c.from, "recommended": false,
            "position": point([o.x, o.y, o.z]), "success": c.success, "colour": success_colour(c.success),
        }));
    }
    let scale: Vec<Value> = (0..=10).map(|i| json!([i * 10, success_colour(i as f64 / 10.0)])).collect();
    Ok(json!({
        "frame": "world: mm, z up, origin at the table's centre on its surface",
        "placement": v.placement.to_string(),
        "scenario": {"seed": v.scenario.seed, "index": v.scenario.index},
        "view_azimuth_deg": v.placement.azimuth,
        "covered_area_mm2": covered_area.round(),
        "parts": parts,
        "sensors": sensors,
        "markers": markers,
        "legend": legend,
        "success_scale": scale,
    }))
}

fn legend_has(legend: &[Value], label: &str) -> bool {
    legend.iter().any(|l| l["label"] == label)
}

/// The view's markup: the canvas, the reset button, the legend, the scene and its script.
pub fn view_html(scene: &Value) -> String {
    let mut legend = String::new();
    for l in scene["legend"].as_array().into_iter().flatten() {
        legend.push_str(&legend_entry(l["colour"].as_str().unwrap_or("#000"), l["label"].as_str().unwrap_or("")));
    }
    let stops: Vec<String> = scene["success_scale"]
        .as_array()
        .into_iter()
        .flatten()
        .map(|s| format!("{} {}%", s[1].as_str().unwrap_or("#000"), s[0]))
        .collect();
    let side = format!(
        "<ul style=\"list-style:none;padding:0\">{legend}\
<li><span class=\"sw\" style=\"background:#fff;border:3px solid #00c800;border-radius:50%\"></span>the recommended rig</li>\
<li>other checked placements' rigs, by success:<div style=\"height:12px;width:220px;margin-top:4px;\
background:linear-gradient(to right,{})\"></div><div style=\"display:flex;justify-content:space-between;width:220px\">\
<span>0 %</span><span>50 %</span><span>100 %</span></div></li></ul>",
        stops.join(",")
    );
    view3d_html(&scene.to_string(), &side, ViewCanvas { size: [820, 560], persist: None })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_covered_region_is_the_intersection_of_the_polygons() {
        let square = |c: [f64; 2], h: f64| {
            vec![[c[0] - h, c[1] - h], [c[0] + h, c[1] - h], [c[0] + h, c[1] + h], [c[0] - h, c[1] + h]]
        };
        let mut b = square([1.0, 1.0], 1.0);
        b.reverse();
        let got = intersect(&[square([0.0, 0.0], 1.0), b]);
        let area: f64 = (0..got.len())
            .map(|i| got[i][0] * got[(i + 1) % got.len()][1] - got[(i + 1) % got.len()][0] * got[i][1])
            .sum();
        assert!((area / 2.0 - 1.0).abs() < 1e-12, "{got:?}");
        // Slow and obvious: a grid of points inside both squares against inside the result.
        let inside = |poly: &[[f64; 2]], p: [f64; 2]| {
            (0..poly.len()).all(|i| {
                let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
                (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]) >= -1e-12
            })
        };
        for i in 0..40 {
            for j in 0..40 {
                let p = [-1.0 + 3.0 * (i as f64 + 0.5) / 40.0, -1.0 + 3.0 * (j as f64 + 0.5) / 40.0];
                let want = p[0].abs() <= 1.0 && p[1].abs() <= 1.0 && p[0] >= 0.0 && p[1] >= 0.0;
                assert_eq!(inside(&got, p), want, "{p:?}");
            }
        }
        assert!(intersect(&[square([0.0, 0.0], 1.0), square([5.0, 5.0], 1.0)]).is_empty());
    }
}
