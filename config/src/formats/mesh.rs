//! Triangle meshes from STL (binary or ASCII), OBJ and PLY, chosen by file extension and
//! checked for content, so a file that is not a mesh says so.

use std::path::Path;

use crate::{Error, ErrorKind};

/// An indexed triangle mesh, mm.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mesh {
    pub vertices: Vec<[f32; 3]>,
    pub triangles: Vec<[u32; 3]>,
}

/// Loads a mesh by extension (`.stl`, `.obj`, `.ply`).
pub fn load_mesh(path: &Path) -> Result<Mesh, Error> {
    let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
    let bytes = super::read::read_bounded(path, super::read::FileKind::Data)?;
    let mesh = match ext.as_str() {
        "stl" => decode_stl(&bytes),
        "obj" => decode_obj(&bytes),
        "ply" => super::ply::decode_ply(&bytes).map(|d| Mesh { vertices: d.vertices, triangles: d.faces }),
        _ => Err(Error::new(ErrorKind::Format, "", "expected a mesh file ending in .stl, .obj or .ply")),
    }
    .map_err(|e| e.in_file(path))?;
    if mesh.triangles.is_empty() {
        return Err(Error::new(ErrorKind::Format, "", "not a mesh: no triangles found").in_file(path));
    }
    if mesh.vertices.iter().flatten().any(|v| !v.is_finite()) {
        return Err(Error::new(ErrorKind::Format, "", "not a mesh: a vertex is not finite").in_file(path));
    }
    Ok(mesh)
}

/// Decodes binary or ASCII STL (vertices are not shared).
pub fn decode_stl(bytes: &[u8]) -> Result<Mesh, Error> {
    if bytes.len() >= 84 {
        let n = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as usize;
        if n > 0 && bytes.len() == 84 + n * 50 {
            let mut m = Mesh::default();
            for t in 0..n {
                let o = 84 + t * 50 + 12;
                let base = m.vertices.len() as u32;
                for v in 0..3 {
                    let mut p = [0f32; 3];
                    for (c, pc) in p.iter_mut().enumerate() {
                        let i = o + v * 12 + c * 4;
                        *pc = f32::from_le_bytes([bytes[i], bytes[i + 1], bytes[i + 2], bytes[i + 3]]);
                    }
                    m.vertices.push(p);
                }
                m.triangles.push([base, base + 1, base + 2]);
            }
            return Ok(m);
        }
    }
    let text = std::str::from_utf8(bytes).map_err(|e| {
        Error::new(ErrorKind::Format, "", "not an STL mesh: neither binary nor ASCII STL").with_source(e)
    })?;
    if !text.trim_start().starts_with("solid") {
        return Err(Error::new(ErrorKind::Format, "", "not an STL mesh: expected binary STL or \"solid\""));
    }
    let mut m = Mesh::default();
    let mut corner = Vec::with_capacity(3);
    for line in text.lines() {
        let t: Vec<&str> = line.split_whitespace().collect();
        if t.first() == Some(&"vertex") && t.len() == 4 {
            let p: Result<Vec<f32>, _> = t[1..].iter().map(|s| s.parse::<f32>()).collect();
            let p =
                p.map_err(|_| Error::new(ErrorKind::Format, "vertex", format!("bad vertex line \"{}\"", line.trim())))?;
            corner.push([p[0], p[1], p[2]]);
            if corner.len() == 3 {
                let base = m.vertices.len() as u32;
                m.vertices.append(&mut corner);
                m.triangles.push([base, base + 1, base + 2]);
            }
        } else if t.first() == Some(&"endloop") {
            corner.clear();
        }
    }
    Ok(m)
}

/// Decodes a Wavefront OBJ (`v` and `f` lines; polygons are fanned into triangles).
pub fn decode_obj(bytes: &[u8]) -> Result<Mesh, Error> {
    let text = std::str::from_utf8(bytes)
        .map_err(|e| Error::new(ErrorKind::Format, "", "not an OBJ mesh: not text").with_source(e))?;
    let mut m = Mesh::default();
    for (n, line) in text.lines().enumerate() {
        let mut t = line.split_whitespace();
        match t.next() {
            Some("v") => {
                let p: Vec<f32> = t.take(3).filter_map(|s| s.parse().ok()).collect();
                if p.len() != 3 {
                    return Err(Error::new(ErrorKind::Format, format!("line {}", n + 1), "expected \"v x y z\""));
                }
                m.vertices.push([p[0], p[1], p[2]]);
            }
            Some("f") => {
                let nv = m.vertices.len() as i64;
                let mut idx = Vec::new();
                for s in t {
                    let i: i64 = s.split('/').next().and_then(|v| v.parse().ok()).ok_or_else(|| {
                        Error::new(ErrorKind::Format, format!("line {}", n + 1), "expected \"f i j k\"")
                    })?;
                    let i = if i < 0 { nv + i } else { i - 1 };
                    if i < 0 || i >= nv {
                        return Err(Error::new(
                            ErrorKind::Format,
                            format!("line {}", n + 1),
                            "face index out of range",
                        ));
                    }
                    idx.push(i as u32);
                }
                for j in 1..idx.len().saturating_sub(1) {
                    m.triangles.push([idx[0], idx[j], idx[j + 1]]);
                }
            }
            _ => {}
        }
    }
    Ok(m)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn obj_and_ascii_stl() {
        let obj = decode_obj(b"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n").unwrap();
        assert_eq!(obj.triangles, vec![[0, 1, 2], [0, 2, 3]]);
        let stl = decode_stl(
            b"solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid\n",
        )
        .unwrap();
        assert_eq!(stl.triangles.len(), 1);
    }

    #[test]
    fn text_that_is_not_a_mesh() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("notes.stl");
        std::fs::write(&p, "this is a shopping list").unwrap();
        let e = load_mesh(&p).unwrap_err();
        assert!(e.to_string().contains("notes.stl") && e.to_string().contains("not"), "{e}");
    }
}
