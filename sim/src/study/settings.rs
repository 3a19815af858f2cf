//! What a study folder was run with (`settings.json`: the cell, its content hash and the
//! hashes of its mesh files, the method and the seed), so that a re-run or a merge into the
//! same folder cannot mix results of other settings, and a mesh edited in place is noticed.

use std::collections::BTreeMap;
use std::path::Path;

use camplace_config::write_atomic;
use camplace_config::{Cell, ContentHash, ItemsKind, TrayKind};
use serde::{Deserialize, Serialize};

use crate::render::Method;
use crate::{Error, Result};

/// The settings every result line of a folder shares.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunSettings {
    /// The hash of the whole cell: every setting and the bytes of its mesh files. Folders
    /// written before it was recorded have none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cell_hash: Option<ContentHash>,
    /// The hash of each mesh file the cell uses, by cell key (`tray.mesh`, `items.mesh`).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub mesh_hashes: BTreeMap<String, ContentHash>,
    /// The cell, as used (defaults filled in).
    pub cell: Cell,
    /// `one-shot` or `phase-12`.
    pub method: String,
    /// The study seed.
    pub seed: u64,
}

/// How two folders' (or a folder's and a run's) settings differ: the first difference found.
#[derive(Debug, Clone, PartialEq)]
pub enum Difference {
    /// Another seed: (first, second).
    Seed(u64, u64),
    /// Another method.
    Method(String, String),
    /// Another value of a cell setting: (dotted key, first value, second value).
    Setting(String, String, String),
    /// The same settings but another cell hash: a mesh file's bytes changed (the cell key
    /// and the second's path of the first such mesh), or none that can be named.
    Hash {
        /// The first's cell hash.
        first: ContentHash,
        /// The second's cell hash.
        second: ContentHash,
        /// The mesh whose bytes differ: (cell key, path).
        mesh: Option<(String, String)>,
    },
    /// The first records no hash and uses mesh files, whose bytes then cannot be checked.
    Unverifiable,
}

impl RunSettings {
    /// The settings of a run; reads the cell's mesh files to hash them.
    pub fn new(cell: &Cell, method: Method, seed: u64) -> Result<RunSettings> {
        let hashes = cell.hashes()?;
        Ok(RunSettings {
            cell_hash: Some(hashes.cell),
            mesh_hashes: hashes.meshes.iter().map(|m| (m.key.to_string(), m.hash)).collect(),
            cell: cell.clone(),
            method: method.to_string(),
            seed,
        })
    }

    /// The method as a value.
    pub fn method(&self) -> Result<Method> {
        self.method
            .parse()
            .map_err(|_| Error::Other(format!("method: expected one-shot or phase-12, got {}", self.method)))
    }

    /// Reads `dir/settings.json`, if there.
    pub fn load(dir: &Path) -> Result<Option<RunSettings>> {
        let path = dir.join("settings.json");
        if !path.exists() {
            return Ok(None);
        }
        let text = camplace_config::read_text(&path)?;
        let s = serde_json::from_str(&text).map_err(|e| {
            Error::Other(format!(
                "{}: expected the settings of a study folder (cell, method, seed): {e}",
                path.display()
            ))
        })?;
        Ok(Some(s))
    }

    /// Writes the settings as `dir/settings.json`, atomically.
    pub fn save(&self, dir: &Path) -> Result<()> {
        let text = serde_json::to_string_pretty(self).expect("settings are plain data");
        Ok(write_atomic(&dir.join("settings.json"), text.as_bytes())?)
    }

    /// Writes `dir/settings.json` when the folder has none; when it has, checks that they
    /// agree, naming the first difference. Settings of a folder written before cell hashes
    /// were recorded are given this run's hash when they agree.
    pub fn check_or_write(&self, dir: &Path) -> Result<()> {
        let path = dir.join("settings.json");
        let Some(old) = RunSettings::load(dir)? else {
            return self.save(dir);
        };
        match old.difference(self) {
            None if old.cell_hash.is_none() => self.save(dir),
            None => Ok(()),
            Some(d) => Err(Error::Other(format!("{}: {}", path.display(), d.against_run()))),
        }
    }

    /// The first difference between `self` (the folder's, or the first of a merge) and
    /// `other`, or `None` when results of the two can be mixed.
    pub fn difference(&self, other: &RunSettings) -> Option<Difference> {
        if self.seed != other.seed {
            return Some(Difference::Seed(self.seed, other.seed));
        }
        if self.method != other.method {
            return Some(Difference::Method(self.method.clone(), other.method.clone()));
        }
        if let Some((key, a, b)) = self.cell.first_difference(&other.cell) {
            return Some(Difference::Setting(key, a, b));
        }
        match (self.cell_hash, other.cell_hash) {
            (Some(a), Some(b)) if a != b => {
                let changed = other.mesh_hashes.iter().find(|(k, h)| self.mesh_hashes.get(*k) != Some(h));
                let mesh = changed.map(|(key, _)| (key.clone(), mesh_path(&other.cell, key)));
                Some(Difference::Hash { first: a, second: b, mesh })
            }
            // A folder from before hashes were recorded: its settings are all there is to
            // compare, which says everything unless the cell reads mesh files.
            (None, _) | (_, None) if uses_meshes(&self.cell) || uses_meshes(&other.cell) => {
                Some(Difference::Unverifiable)
            }
            _ => None,
        }
    }
}

impl Difference {
    /// The difference said of a folder (first) and a run into it (second), with what to do.
    pub fn against_run(&self) -> String {
        let resume = "resume with the same settings or choose another --out";
        match self {
            Difference::Seed(a, b) => format!("the folder holds seed {a}, this run has seed {b}; {resume}"),
            Difference::Method(a, b) => format!("the folder holds method {a}, this run has method {b}; {resume}"),
            Difference::Setting(key, a, b) => {
                format!("the folder holds results of a cell with {key} = {a}, this run has {key} = {b}; {resume}")
            }
            Difference::Hash { first, second, mesh } => {
                let hint = match mesh {
                    Some((key, path)) => format!("{} {path} changed?", mesh_noun(key)),
                    None => "a mesh file changed?".to_string(),
                };
                format!(
                    "built for a cell with hash {} ({hint}); this cell hashes to {} — use a new folder",
                    first.short(),
                    second.short()
                )
            }
            Difference::Unverifiable => "written by an earlier camplace without a cell hash, and the cell reads mesh \
                 files whose bytes then cannot be checked; use a new folder"
                .to_string(),
        }
    }

    /// The difference said of two folders being merged, the first's value first.
    pub fn between(&self, first: &Path, second: &Path) -> String {
        let (a, b) = (first.join("settings.json"), second.join("settings.json"));
        let (a, b) = (a.display(), b.display());
        let what = match self {
            Difference::Seed(x, y) => format!("{a} has seed {x}, {b} has seed {y}"),
            Difference::Method(x, y) => format!("{a} has method {x}, {b} has method {y}"),
            Difference::Setting(key, x, y) => format!("{a} has {key} = {x}, {b} has {key} = {y}"),
            Difference::Hash { first, second, mesh } => {
                let hint =
                    mesh.as_ref().map_or(String::new(), |(key, path)| format!(" ({} {path} changed?)", mesh_noun(key)));
                format!("{a} has cell hash {}, {b} has cell hash {}{hint}", first.short(), second.short())
            }
            Difference::Unverifiable => {
                format!("{a} or {b} records no cell hash and the cell reads mesh files, whose bytes then cannot be compared")
            }
        };
        format!("{what}; merge only folders run with the same cell, method and seed")
    }
}

fn uses_meshes(cell: &Cell) -> bool {
    cell.tray.kind == TrayKind::Mesh || cell.items.kind == ItemsKind::Mesh
}

fn mesh_noun(key: &str) -> &'static str {
    if key == "items.mesh" {
        "item mesh"
    } else {
        "tray mesh"
    }
}

fn mesh_path(cell: &Cell, key: &str) -> String {
    let path = if key == "items.mesh" { &cell.items.mesh } else { &cell.tray.mesh };
    path.display().to_string()
}

#[cfg(test)]
mod tests {
    use super::*;
    use camplace_config::TrayKind;

    fn stl(z: f32) -> Vec<u8> {
        let mut b = vec![0u8; 80];
        b.extend(1u32.to_le_bytes());
        b.extend([0u8; 12]);
        for c in [0.0, 0.0, z, 100.0, 0.0, z, 0.0, 100.0, z] {
            b.extend(c.to_le_bytes());
        }
        b.extend([0u8; 2]);
        b
    }

    #[test]
    fn differences_are_named_first_folder_first() {
        let cell = Cell::default();
        let a = RunSettings::new(&cell, Method::OneShot, 1).unwrap();
        let b = RunSettings::new(&cell, Method::OneShot, 2).unwrap();
        assert_eq!(a.difference(&a), None);
        let d = a.difference(&b).unwrap();
        assert_eq!(d, Difference::Seed(1, 2));
        let said = d.between(Path::new("first"), Path::new("second"));
        assert!(said.starts_with("first/settings.json has seed 1, second/settings.json has seed 2"), "{said}");
        assert!(d.against_run().starts_with("the folder holds seed 1, this run has seed 2"));
        let mut other = cell.clone();
        other.tray.kind = TrayKind::Tray4;
        let c = RunSettings::new(&other, Method::OneShot, 1).unwrap();
        let d = a.difference(&c).unwrap();
        assert_eq!(d, Difference::Setting("tray.kind".into(), "\"tray-8\"".into(), "\"tray-4\"".into()));
    }

    #[test]
    fn a_mesh_edited_in_place_is_named() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("a.stl"), stl(0.0)).unwrap();
        let cell = Cell::from_toml_str("[tray]\nkind = \"mesh\"\nmesh = \"a.stl\"\n", dir.path()).unwrap();
        let before = RunSettings::new(&cell, Method::OneShot, 1).unwrap();
        std::fs::write(dir.path().join("a.stl"), stl(2.0)).unwrap();
        let after = RunSettings::new(&cell, Method::OneShot, 1).unwrap();
        let d = before.difference(&after).unwrap();
        let said = d.against_run();
        let (x, y) = (before.cell_hash.unwrap().short(), after.cell_hash.unwrap().short());
        assert!(said.starts_with(&format!("built for a cell with hash {x} (tray mesh ")), "{said}");
        assert!(said.contains("a.stl changed?); this cell hashes to ") && said.contains(&y), "{said}");
    }

    #[test]
    fn settings_without_a_hash_are_upgraded_unless_meshes_cannot_be_checked() {
        let dir = tempfile::tempdir().unwrap();
        let run = RunSettings::new(&Cell::default(), Method::OneShot, 1).unwrap();
        let old = RunSettings { cell_hash: None, mesh_hashes: BTreeMap::new(), ..run.clone() };
        old.save(dir.path()).unwrap();
        run.check_or_write(dir.path()).unwrap();
        assert_eq!(RunSettings::load(dir.path()).unwrap(), Some(run));

        std::fs::write(dir.path().join("a.stl"), stl(0.0)).unwrap();
        let cell = Cell::from_toml_str("[tray]\nkind = \"mesh\"\nmesh = \"a.stl\"\n", dir.path()).unwrap();
        let run = RunSettings::new(&cell, Method::OneShot, 1).unwrap();
        let old = RunSettings { cell_hash: None, mesh_hashes: BTreeMap::new(), ..run.clone() };
        assert_eq!(old.difference(&run), Some(Difference::Unverifiable));
    }
}
