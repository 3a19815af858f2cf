//! A cell as a content hash, so that a study folder, a cached model or a model file can tell
//! whether it was made from this very cell: SHA-256 over a canonical text of every setting,
//! with each mesh path replaced by the hash of the mesh file's bytes (so a mesh edited in
//! place changes the hash, and a cell moved with its meshes does not). The tray hash covers
//! the tray's and the items' geometry alone, which is what decides whether a model fits a
//! cell. Deciding what to do about a mismatch is the caller's business.

use std::fmt;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use serde_json::{json, Value};
use sha2::{Digest, Sha256};

use crate::{Cell, Error, ItemsKind, TrayKind};

/// First line of the text a cell hash is taken over; a new canonical form gets a new one.
const CELL_PREFIX: &str = "camplace cell 1\n";
/// First line of the text a tray hash is taken over.
const TRAY_PREFIX: &str = "camplace tray 1\n";

/// A SHA-256 digest; written as 64 lowercase hex digits.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct ContentHash(pub [u8; 32]);

impl ContentHash {
    /// The SHA-256 of `bytes`.
    pub fn of(bytes: &[u8]) -> ContentHash {
        ContentHash(Sha256::digest(bytes).into())
    }

    /// The first 12 hex digits: enough to tell hashes apart in a message.
    pub fn short(&self) -> String {
        self.to_string()[..12].to_string()
    }

    /// Parses 64 hex digits.
    pub fn from_hex(text: &str) -> Option<ContentHash> {
        if text.len() != 64 || !text.is_ascii() {
            return None;
        }
        let mut out = [0u8; 32];
        for (i, b) in out.iter_mut().enumerate() {
            *b = u8::from_str_radix(&text[2 * i..2 * i + 2], 16).ok()?;
        }
        Some(ContentHash(out))
    }
}

impl fmt::Display for ContentHash {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for b in self.0 {
            write!(f, "{b:02x}")?;
        }
        Ok(())
    }
}

impl fmt::Debug for ContentHash {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "ContentHash({self})")
    }
}

impl Serialize for ContentHash {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&self.to_string())
    }
}

impl<'de> Deserialize<'de> for ContentHash {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let text = String::deserialize(d)?;
        ContentHash::from_hex(&text)
            .ok_or_else(|| serde::de::Error::custom(format!("expected 64 hex digits of a SHA-256, got \"{text}\"")))
    }
}

/// A mesh file a cell uses, and the hash of its bytes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MeshHash {
    /// The cell key naming it: `tray.mesh` or `items.mesh`.
    pub key: &'static str,
    /// The file as the cell names it (resolved against the cell file's folder).
    pub path: PathBuf,
    /// SHA-256 of the file's bytes.
    pub hash: ContentHash,
}

/// What a cell hashes to.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CellHashes {
    /// Every setting and the bytes of every mesh file the cell uses.
    pub cell: ContentHash,
    /// The tray's and the items' geometry: kinds, mesh bytes, slots, symmetries, box size.
    pub tray: ContentHash,
    /// The mesh files the cell uses, tray first.
    pub meshes: Vec<MeshHash>,
}

impl Cell {
    /// The cell's hashes; reads the mesh files it uses.
    pub fn hashes(&self) -> Result<CellHashes, Error> {
        let mut meshes = Vec::new();
        if self.tray.kind == TrayKind::Mesh {
            meshes.push(mesh_hash("tray.mesh", &self.tray.mesh)?);
        }
        if self.items.kind == ItemsKind::Mesh {
            meshes.push(mesh_hash("items.mesh", &self.items.mesh)?);
        }
        let hash_of = |key: &str| meshes.iter().find(|m| m.key == key).map(|m| m.hash);
        let (tray_mesh, items_mesh) = (hash_of("tray.mesh"), hash_of("items.mesh"));
        let mut cell = self.settings_value();
        cell["tray"]["mesh"] = mesh_value(tray_mesh);
        cell["items"]["mesh"] = mesh_value(items_mesh);
        // A listed tray's meshes count by their bytes too.
        for (i, e) in self.trays.iter().enumerate() {
            let listed = |key: &'static str, kind_is_mesh: bool, path: &Path| -> Result<Value, Error> {
                Ok(mesh_value(if kind_is_mesh { Some(mesh_hash(key, path)?.hash) } else { None }))
            };
            cell["trays"][i]["mesh"] = listed("trays.mesh", e.tray.kind == TrayKind::Mesh, &e.tray.mesh)?;
            cell["trays"][i]["items"]["mesh"] =
                listed("trays.items.mesh", e.items.kind == ItemsKind::Mesh, &e.items.mesh)?;
        }
        let geometry = json!({
            "tray": {
                "kind": cell["tray"]["kind"],
                "mesh": mesh_value(tray_mesh),
                // Built-in trays have their own slots; the cell's count only for a mesh.
                "slots": if tray_mesh.is_some() { cell["tray"]["slots"].clone() } else { json!([]) },
                "symmetries": cell["tray"]["symmetries"],
            },
            "items": {
                "kind": cell["items"]["kind"],
                "mesh": mesh_value(items_mesh),
                "size": if items_mesh.is_none() { cell["items"]["size"].clone() } else { json!([]) },
            },
        });
        Ok(CellHashes {
            cell: ContentHash::of(format!("{CELL_PREFIX}{}", canonical_json(&cell)).as_bytes()),
            tray: ContentHash::of(format!("{TRAY_PREFIX}{}", canonical_json(&geometry)).as_bytes()),
            meshes,
        })
    }

    /// The tray as the cell file names it: `tray-8`, `tray-4`, or `mesh` and the mesh's file
    /// name.
    pub fn tray_name(&self) -> String {
        match self.tray.kind {
            TrayKind::Tray4 => "tray-4".to_string(),
            TrayKind::Tray8 => "tray-8".to_string(),
            TrayKind::Mesh => {
                let name = self.tray.mesh.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
                format!("mesh {name}")
            }
        }
    }

    /// The first setting in which `self` and `other` differ, as (dotted key, value here,
    /// value there), each value as compact JSON; where the mesh files lie is no difference.
    pub fn first_difference(&self, other: &Cell) -> Option<(String, String, String)> {
        let (mut a, mut b) = (self.settings_value(), other.settings_value());
        for v in [&mut a, &mut b] {
            v["tray"]["mesh"] = Value::Null;
            v["items"]["mesh"] = Value::Null;
            if let Some(Value::Array(list)) = v.get_mut("trays") {
                for e in list {
                    e["mesh"] = Value::Null;
                    e["items"]["mesh"] = Value::Null;
                }
            }
        }
        first_difference(&a, &b, "")
    }

    /// Every setting that shapes a simulated scene or an estimate, as a JSON value: all but
    /// `[robot]`, which only re-expresses poses, so adding it to a cell keeps its study
    /// folders and models.
    fn settings_value(&self) -> Value {
        let mut v = serde_json::to_value(self).expect("a cell always serialises");
        if let Some(map) = v.as_object_mut() {
            map.remove("robot");
        }
        v
    }
}

fn mesh_hash(key: &'static str, path: &Path) -> Result<MeshHash, Error> {
    let bytes =
        crate::formats::read::read_bounded(path, crate::formats::read::FileKind::Data).map_err(|e| e.under_key(key))?;
    Ok(MeshHash { key, path: path.to_path_buf(), hash: ContentHash::of(&bytes) })
}

/// A used mesh as `sha256:HEX`, an unused one as the empty string.
fn mesh_value(hash: Option<ContentHash>) -> Value {
    Value::String(hash.map_or(String::new(), |h| format!("sha256:{h}")))
}

/// JSON with object keys in byte order and no spaces: the same text for the same value
/// whichever order serde wrote the fields in.
fn canonical_json(v: &Value) -> String {
    let mut out = String::new();
    write_canonical(v, &mut out);
    out
}

fn write_canonical(v: &Value, out: &mut String) {
    match v {
        Value::Object(map) => {
            let mut keys: Vec<&String> = map.keys().collect();
            keys.sort();
            out.push('{');
            for (i, k) in keys.into_iter().enumerate() {
                if i > 0 {
                    out.push(',');
                }
                out.push_str(&Value::String(k.clone()).to_string());
                out.push(':');
                write_canonical(&map[k], out);
            }
            out.push('}');
        }
        Value::Array(items) => {
            out.push('[');
            for (i, item) in items.iter().enumerate() {
                if i > 0 {
                    out.push(',');
                }
                write_canonical(item, out);
            }
            out.push(']');
        }
        scalar => out.push_str(&scalar.to_string()),
    }
}

fn first_difference(a: &Value, b: &Value, at: &str) -> Option<(String, String, String)> {
    if a == b {
        return None;
    }
    if let (Value::Object(x), Value::Object(y)) = (a, b) {
        let mut keys: Vec<&String> = x.keys().chain(y.keys()).collect();
        keys.sort();
        keys.dedup();
        for k in keys {
            let key = if at.is_empty() { k.clone() } else { format!("{at}.{k}") };
            let (va, vb) = (x.get(k).unwrap_or(&Value::Null), y.get(k).unwrap_or(&Value::Null));
            if let Some(d) = first_difference(va, vb, &key) {
                return Some(d);
            }
        }
        return None;
    }
    let show = |v: &Value| {
        let text = canonical_json(v);
        match text.char_indices().nth(60) {
            Some((i, _)) => format!("{}...", &text[..i]),
            None => text,
        }
    };
    Some((at.to_string(), show(a), show(b)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, bytes).unwrap();
        p
    }

    fn triangle(z: f32) -> Vec<u8> {
        let mut stl = vec![0u8; 80];
        stl.extend(1u32.to_le_bytes());
        stl.extend([0u8; 12]);
        for v in [[0.0, 0.0, z], [100.0, 0.0, z], [0.0, 100.0, z]] {
            for c in v {
                stl.extend(c.to_le_bytes());
            }
        }
        stl.extend([0u8; 2]);
        stl
    }

    #[test]
    fn the_robot_frame_is_checked_and_leaves_the_hash_alone() {
        let text = "[robot]\nT_robot_world = [[0.0, -1.0, 0.0, 450.0], [1.0, 0.0, 0.0, -120.0], [0.0, 0.0, 1.0, 3.0], [0.0, 0.0, 0.0, 1.0]]\n";
        let cell = Cell::from_toml_str(text, Path::new(".")).unwrap();
        assert_eq!(cell.robot.as_ref().unwrap().t_robot_world[0][3], 450.0);
        assert_eq!(cell.hashes().unwrap().cell, Cell::default().hashes().unwrap().cell);
        assert_eq!(cell.first_difference(&Cell::default()), None);
        let back = Cell::from_toml_str(&cell.to_toml_string(), Path::new(".")).unwrap();
        assert_eq!(back.robot, cell.robot);
        for bad in [
            "[robot]\nT_robot_world = [[2.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]\n",
            "[robot]\nT_robot_world = [[1.0, 0.0, 0.0, 1e9], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]\n",
            "[robot]\nT_robot_world = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]\n",
            "[robot]\nT_robot_world = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 1.0, 1.0]]\n",
        ] {
            let e = Cell::from_toml_str(bad, Path::new(".")).unwrap_err();
            assert!(e.key().starts_with("robot.T_robot_world"), "{bad}: {e}");
        }
        let flange = "[robot]\nT_robot_world = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]\n";
        let ok = format!("{flange}T_flange_rig = [[0.0, -1.0, 0.0, 40.0], [1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 90.0], [0.0, 0.0, 0.0, 1.0]]\n");
        let cell = Cell::from_toml_str(&ok, Path::new(".")).unwrap();
        assert_eq!(cell.robot.as_ref().unwrap().t_flange_rig.unwrap()[2][3], 90.0);
        let bad = format!("{flange}T_flange_rig = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, -1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]\n");
        let e = Cell::from_toml_str(&bad, Path::new(".")).unwrap_err();
        assert_eq!(e.key(), "robot.T_flange_rig", "{e}");
        assert!(e.to_string().contains("determinant"), "{e}");
        let e = Cell::from_toml_str("[robot]\nframe = 1\n", Path::new(".")).unwrap_err();
        assert!(e.key().starts_with("robot"), "{e}");
    }

    #[test]
    fn the_default_cell_hashes_the_same_every_time_and_its_text_round_trip_too() {
        let a = Cell::default().hashes().unwrap();
        assert_eq!(a, Cell::default().hashes().unwrap());
        let back = Cell::from_toml_str(&Cell::default().to_toml_string(), Path::new(".")).unwrap();
        assert_eq!(back.hashes().unwrap(), a);
        assert!(a.meshes.is_empty());
        assert_eq!(ContentHash::from_hex(&a.cell.to_string()), Some(a.cell));
        assert_eq!(a.cell.short().len(), 12);
    }

    #[test]
    fn every_setting_changes_the_cell_hash_and_only_geometry_the_tray_hash() {
        let base = Cell::default().hashes().unwrap();
        let mut c = Cell::default();
        c.estimator.k += 1;
        let h = c.hashes().unwrap();
        assert_ne!(h.cell, base.cell);
        assert_eq!(h.tray, base.tray, "an estimator setting is not the tray");
        let mut c = Cell::default();
        c.tray.kind = TrayKind::Tray4;
        let h = c.hashes().unwrap();
        assert_ne!(h.cell, base.cell);
        assert_ne!(h.tray, base.tray);
        let mut c = Cell::default();
        c.tray.albedo = 0.5;
        assert_eq!(c.hashes().unwrap().tray, base.tray, "albedo is not geometry");
        let mut c = Cell::default();
        c.items.size[0] += 1.0;
        assert_ne!(c.hashes().unwrap().tray, base.tray);
    }

    #[test]
    fn mesh_bytes_count_and_their_place_does_not() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        write(d, "a.stl", &triangle(0.0));
        std::fs::create_dir(d.join("moved")).unwrap();
        write(&d.join("moved"), "a.stl", &triangle(0.0));
        let text = "[tray]\nkind = \"mesh\"\nmesh = \"a.stl\"\n";
        let here = Cell::from_toml_str(text, d).unwrap();
        let there = Cell::from_toml_str(text, &d.join("moved")).unwrap();
        let h = here.hashes().unwrap();
        assert_eq!(h.meshes.len(), 1);
        assert_eq!(h.meshes[0].key, "tray.mesh");
        assert_eq!(there.hashes().unwrap(), CellHashes { meshes: there.hashes().unwrap().meshes, ..h.clone() });
        assert_eq!(here.first_difference(&there), None);
        write(d, "a.stl", &triangle(1.0));
        let edited = here.hashes().unwrap();
        assert_ne!(edited.cell, h.cell);
        assert_ne!(edited.tray, h.tray);
        assert_ne!(edited.meshes[0].hash, h.meshes[0].hash);
        assert_eq!(here.tray_name(), "mesh a.stl");
    }

    #[test]
    fn the_first_difference_is_named_by_its_key() {
        let mut c = Cell::default();
        c.tray.kind = TrayKind::Tray4;
        let (key, here, there) = c.first_difference(&Cell::default()).unwrap();
        assert_eq!((key.as_str(), here.as_str(), there.as_str()), ("tray.kind", "\"tray-4\"", "\"tray-8\""));
        assert_eq!(Cell::default().first_difference(&Cell::default()), None);
    }

    #[test]
    fn canonical_json_sorts_keys_at_every_depth() {
        let v = json!({"b": 1, "a": {"d": [1.5, "x"], "c": null}});
        assert_eq!(canonical_json(&v), r#"{"a":{"c":null,"d":[1.5,"x"]},"b":1}"#);
    }
}
