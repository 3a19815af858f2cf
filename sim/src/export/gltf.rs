//! The cell's parts as glTF 2.0 binary (`.glb`), written by hand: a 12-byte header, a JSON
//! chunk and a BIN chunk. glTF is in metres with y up; the world frame is in mm with z up,
//! so a world point (x, y, z) mm is written as (x, z, −y) / 1000 (docs/formats.md).

use std::path::Path;

use camplace_config::write_atomic;
use camplace_estimator::geometry::Camera;
use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};
use serde_json::{json, Value};

use super::cell_parts::{CellPart, Primitive};
use crate::Result;

/// What a written `.glb` holds.
#[derive(Debug, Clone, PartialEq)]
pub struct GlbSummary {
    /// The nodes' names, in the file's order.
    pub nodes: Vec<String>,
    /// Points of the measured cloud (0 without one).
    pub cloud_points: usize,
    /// The file's size, bytes.
    pub bytes: usize,
}

/// glTF's frame from the world's: x stays, glTF y is world z, glTF z is world −y.
fn gltf_from_world() -> Matrix3<f64> {
    Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, -1.0, 0.0)
}

/// A world point, mm, in glTF's frame, metres.
fn to_gltf(p: [f64; 3]) -> Vector3<f64> {
    gltf_from_world() * Vector3::from(p) / 1000.0
}

/// The BIN chunk under construction and the accessors and views into it.
#[derive(Default)]
struct Buffers {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Buffers {
    /// Appends a view of `bytes` (4-byte aligned, as accessors of floats and u32 need).
    fn view(&mut self, bytes: &[u8], target: u32) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let offset = self.bin.len();
        self.bin.extend_from_slice(bytes);
        self.views.push(json!({"buffer": 0, "byteOffset": offset, "byteLength": bytes.len(), "target": target}));
        self.views.len() - 1
    }

    /// A VEC3 float accessor of `points` with the min and max glTF requires of positions.
    fn positions(&mut self, points: &[[f32; 3]]) -> usize {
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        let mut bytes = Vec::with_capacity(12 * points.len());
        for p in points {
            for i in 0..3 {
                lo[i] = lo[i].min(p[i]);
                hi[i] = hi[i].max(p[i]);
                bytes.extend_from_slice(&p[i].to_le_bytes());
            }
        }
        let view = self.view(&bytes, 34962);
        self.accessors.push(json!({
            "bufferView": view, "componentType": 5126, "count": points.len(), "type": "VEC3",
            "min": lo, "max": hi
        }));
        self.accessors.len() - 1
    }

    /// A SCALAR u32 accessor of triangle indices.
    fn indices(&mut self, indices: &[u32]) -> usize {
        let bytes: Vec<u8> = indices.iter().flat_map(|i| i.to_le_bytes()).collect();
        let view = self.view(&bytes, 34963);
        self.accessors.push(json!({
            "bufferView": view, "componentType": 5125, "count": indices.len(), "type": "SCALAR"
        }));
        self.accessors.len() - 1
    }
}

/// A camera's node orientation in glTF: a glTF camera looks down its −z with y up, an
/// OpenCV camera down its z with y down, so the node is the camera turned half way about x.
fn camera_rotation(c: &Camera) -> Rotation3<f64> {
    let flip = Matrix3::new(1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0);
    let r = gltf_from_world() * c.t_world_camera.rotation.to_rotation_matrix().into_inner() * flip;
    Rotation3::from_matrix_unchecked(r)
}

/// A glTF perspective camera with the camera's vertical field of view and aspect ratio.
fn perspective(c: &Camera) -> Value {
    let (fx, fy) = (c.k[(0, 0)], c.k[(1, 1)]);
    let (w, h) = (c.width as f64, c.height as f64);
    let half_y = (h / 2.0 / fy).atan();
    let half_x = (w / 2.0 / fx).atan();
    json!({
        "type": "perspective",
        "perspective": {"yfov": 2.0 * half_y, "aspectRatio": half_x.tan() / half_y.tan(), "znear": 0.01}
    })
}

/// The `.glb` of `parts` and, when given, a measured cloud (world mm) as a POINTS primitive
/// of the node `cloud`; with the names of its nodes.
pub fn glb_bytes(parts: &[CellPart], cloud: Option<&[[f32; 3]]>) -> (Vec<u8>, Vec<String>) {
    let mut buffers = Buffers::default();
    let (mut nodes, mut meshes, mut materials, mut cameras) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut names = Vec::new();
    let mut material = |colour: [f64; 4], lit: bool| {
        let mut m = json!({
            "pbrMetallicRoughness": {"baseColorFactor": colour, "metallicFactor": 0.0, "roughnessFactor": 1.0},
            "doubleSided": true
        });
        if colour[3] < 1.0 {
            m["alphaMode"] = json!("BLEND");
        }
        if !lit {
            m["emissiveFactor"] = json!([colour[0], colour[1], colour[2]]);
        }
        materials.push(m);
        materials.len() - 1
    };
    for part in parts {
        let mut node = json!({"name": part.name});
        // A sensor's node sits at its centre, turned as a glTF camera, so that viewers can
        // look through it; its frustum is then given in the node's frame.
        let (origin, turn) = match &part.sensor {
            Some(c) => {
                let t = c.t_world_camera.translation.vector;
                (to_gltf([t.x, t.y, t.z]), camera_rotation(c))
            }
            None => (Vector3::zeros(), Rotation3::identity()),
        };
        let local: Vec<[f32; 3]> = part
            .positions
            .iter()
            .map(|&p| {
                let v = turn.inverse() * (to_gltf(p) - origin);
                [v.x as f32, v.y as f32, v.z as f32]
            })
            .collect();
        let position = buffers.positions(&local);
        let mut primitive = json!({"attributes": {"POSITION": position}, "material": material(part.colour, true)});
        match part.primitive {
            Primitive::Triangles => {
                primitive["indices"] = json!(buffers.indices(&part.indices));
                primitive["mode"] = json!(4);
            }
            Primitive::Points => primitive["mode"] = json!(0),
        }
        meshes.push(json!({"name": part.name, "primitives": [primitive]}));
        node["mesh"] = json!(meshes.len() - 1);
        if let Some(c) = &part.sensor {
            node["translation"] = json!([origin.x, origin.y, origin.z]);
            let q = UnitQuaternion::from_rotation_matrix(&turn);
            node["rotation"] = json!([q.i, q.j, q.k, q.w]);
            // The projector is no camera to look through; only the cameras get one.
            if part.name.starts_with("camera_") {
                let mut cam = perspective(c);
                cam["name"] = json!(part.name);
                cameras.push(cam);
                node["camera"] = json!(cameras.len() - 1);
            }
        }
        nodes.push(node);
        names.push(part.name.clone());
    }
    if let Some(points) = cloud.filter(|p| !p.is_empty()) {
        let local: Vec<[f32; 3]> = points
            .iter()
            .map(|p| {
                let v = to_gltf([p[0] as f64, p[1] as f64, p[2] as f64]);
                [v.x as f32, v.y as f32, v.z as f32]
            })
            .collect();
        let position = buffers.positions(&local);
        let primitive =
            json!({"attributes": {"POSITION": position}, "mode": 0, "material": material([0.1, 0.6, 0.3, 1.0], false)});
        meshes.push(json!({"name": "cloud", "primitives": [primitive]}));
        nodes.push(json!({"name": "cloud", "mesh": meshes.len() - 1}));
        names.push("cloud".to_string());
    }
    while !buffers.bin.len().is_multiple_of(4) {
        buffers.bin.push(0);
    }
    let mut doc = json!({
        "asset": {"version": "2.0", "generator": concat!("camplace ", env!("CARGO_PKG_VERSION"))},
        "scene": 0,
        "scenes": [{"name": "cell", "nodes": (0..nodes.len()).collect::<Vec<_>>()}],
        "nodes": nodes,
        "meshes": meshes,
        "materials": materials,
        "accessors": buffers.accessors,
        "bufferViews": buffers.views,
        "buffers": [{"byteLength": buffers.bin.len()}],
    });
    if !cameras.is_empty() {
        doc["cameras"] = json!(cameras);
    }
    let mut text = doc.to_string().into_bytes();
    // The JSON chunk is padded with spaces, the BIN chunk with zeros, each to 4 bytes.
    while !text.len().is_multiple_of(4) {
        text.push(b' ');
    }
    let total = 12 + 8 + text.len() + 8 + buffers.bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(text.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&text);
    out.extend_from_slice(&(buffers.bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&buffers.bin);
    (out, names)
}

/// Writes `parts` (and the cloud) as a `.glb` to `path`, atomically.
pub fn write_cell_glb(path: &Path, parts: &[CellPart], cloud: Option<&[[f32; 3]]>) -> Result<GlbSummary> {
    let (bytes, nodes) = glb_bytes(parts, cloud);
    write_atomic(path, &bytes)?;
    Ok(GlbSummary { nodes, cloud_points: cloud.map_or(0, <[_]>::len), bytes: bytes.len() })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_axis_change_keeps_the_frame_right_handed_and_z_up_becomes_y_up() {
        let m = gltf_from_world();
        assert!((m.determinant() - 1.0).abs() < 1e-12);
        assert_eq!(to_gltf([0.0, 0.0, 1000.0]), Vector3::new(0.0, 1.0, 0.0));
        assert_eq!(to_gltf([0.0, 1000.0, 0.0]), Vector3::new(0.0, 0.0, -1.0));
    }
}
