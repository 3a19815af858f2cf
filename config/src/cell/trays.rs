//! A cell that handles several products: `[[trays]]`, a list of trays each with its mesh,
//! slots, symmetries and items. An entry names only what differs from the cell's `[tray]`
//! and `[items]` tables; a study asks one placement to serve every tray listed. Everything
//! that works on one tray sees each entry as a cell of its own ([`Cell::tray_cells`]).

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::toml_merge::merge;
use crate::{Cell, Error, Items, Tray, TrayKind};

/// The most trays a cell may list.
pub const MAX_TRAYS: usize = 16;

/// Names a study folder gives its own entries beside the trays' folders (the joint search,
/// the tolerances, the report, the lock, a tray folder's method folders and files): a tray
/// named so would mix its results with them.
pub const STUDY_FOLDER_NAMES: &[&str] = &[
    "all-trays",
    "tolerance",
    "models",
    "one-shot",
    "phase-12",
    "report.html",
    "recommended.json",
    "best_preview.png",
    "settings.json",
    "results.jsonl",
    "results.rejected.jsonl",
    "summary.json",
    "summary.csv",
    "sweep.json",
    "tolerance.json",
    "optimize.json",
    "study.lock",
];

/// Endings of the files a study writes (reports, plots, tables, the lock): no tray name
/// ends so, so no tray folder can be taken for one of them.
pub const STUDY_FILE_ENDINGS: &[&str] = &[".html", ".json", ".jsonl", ".csv", ".png", ".svg", ".md", ".lock", ".model"];

/// Why `name` cannot name a tray's folder in a study, if it cannot.
pub fn reserved_tray_name(name: &str) -> Option<String> {
    let lower = name.to_ascii_lowercase();
    if STUDY_FOLDER_NAMES.contains(&lower.as_str()) {
        return Some(format!(
            "\"{name}\" is a name the study folder uses for its own files; give the tray another name"
        ));
    }
    STUDY_FILE_ENDINGS
        .iter()
        .find(|e| lower.ends_with(*e))
        .map(|e| format!("\"{name}\" ends like a file the study writes ({e}); give the tray another name"))
}

/// One tray of a cell's list, with the items its slots hold. Written as in the cell file:
/// the name and the tray's keys side by side, the items as a table.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(from = "Flat", into = "Flat")]
pub struct TrayEntry {
    /// The tray's name in folders and reports: letters, digits, `-`, `_` and `.`.
    pub name: String,
    pub tray: Tray,
    pub items: Items,
}

/// A [`TrayEntry`] as written.
#[derive(Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Flat {
    name: String,
    kind: TrayKind,
    mesh: std::path::PathBuf,
    slots: Vec<[f64; 4]>,
    symmetries: Vec<f64>,
    albedo: f64,
    specular: f64,
    roughness: f64,
    items: Items,
}

impl From<Flat> for TrayEntry {
    fn from(f: Flat) -> Self {
        let tray = Tray {
            kind: f.kind,
            mesh: f.mesh,
            slots: f.slots,
            symmetries: f.symmetries,
            albedo: f.albedo,
            specular: f.specular,
            roughness: f.roughness,
        };
        TrayEntry { name: f.name, tray, items: f.items }
    }
}

impl From<TrayEntry> for Flat {
    fn from(e: TrayEntry) -> Self {
        let t = e.tray;
        Flat {
            name: e.name,
            kind: t.kind,
            mesh: t.mesh,
            slots: t.slots,
            symmetries: t.symmetries,
            albedo: t.albedo,
            specular: t.specular,
            roughness: t.roughness,
            items: e.items,
        }
    }
}

/// How an entry is read from the cell file: the tray's keys, `name` and an `items` table.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Written {
    tray: Tray,
    items: Items,
}

impl Cell {
    /// The trays this cell serves, each as a cell of its own (no list), with its name: the
    /// listed trays, or the cell's one tray named by [`Cell::tray_folder_name`].
    pub fn tray_cells(&self) -> Vec<(String, Cell)> {
        if self.trays.is_empty() {
            let mut one = self.clone();
            one.trays.clear();
            return vec![(self.tray_folder_name(), one)];
        }
        self.trays.iter().map(|e| (e.name.clone(), self.with_entry(e))).collect()
    }

    /// The one tray a command that works on one tray uses: the cell itself when it lists
    /// no trays, else the listed tray named `choice`.
    pub fn one_tray(&self, choice: Option<&str>) -> Result<Cell, Error> {
        let names = || self.trays.iter().map(|e| e.name.as_str()).collect::<Vec<_>>().join(", ");
        match (choice, self.trays.is_empty()) {
            (None, true) => Ok(self.clone()),
            (Some(name), true) => {
                Err(Error::value("trays", format!("--tray {name}: the cell lists no trays (its one tray is [tray])")))
            }
            (None, false) => Err(Error::value(
                "trays",
                format!(
                    "the cell lists {} trays ({}); this command works on one: give --tray NAME",
                    self.trays.len(),
                    names()
                ),
            )),
            (Some(name), false) => match self.trays.iter().find(|e| e.name == name) {
                Some(e) => Ok(self.with_entry(e)),
                None => Err(Error::value("trays", format!("--tray {name}: expected one of {}", names()))),
            },
        }
    }

    /// A folder-safe name of the cell's `[tray]`: `tray-8`, `tray-4`, or the mesh file's stem.
    pub fn tray_folder_name(&self) -> String {
        folder_name_of(&self.tray)
    }

    fn with_entry(&self, e: &TrayEntry) -> Cell {
        let mut c = self.clone();
        c.trays.clear();
        c.tray = e.tray.clone();
        c.items = e.items.clone();
        c
    }
}

/// `tray-8`, `tray-4`, or the mesh file's stem made folder-safe.
fn folder_name_of(tray: &Tray) -> String {
    match tray.kind {
        TrayKind::Tray4 => "tray-4".to_string(),
        TrayKind::Tray8 => "tray-8".to_string(),
        TrayKind::Mesh => {
            let stem = tray.mesh.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
            let safe: String = stem.chars().map(|c| if name_char(c) { c } else { '_' }).collect();
            if safe.is_empty() || safe.starts_with('.') {
                format!("mesh{safe}")
            } else {
                safe
            }
        }
    }
}

fn name_char(c: char) -> bool {
    c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.')
}

/// Reads the cell file's `trays` value: each entry laid over the cell's merged `[tray]`
/// and `[items]` tables, mesh paths resolved against `base`.
pub(crate) fn parse_trays(
    value: toml::Value,
    tray: &toml::Table,
    items: &toml::Table,
    base: &Path,
) -> Result<Vec<TrayEntry>, Error> {
    let toml::Value::Array(list) = value else {
        return Err(Error::value("trays", "expected a list of tray tables ([[trays]] sections)"));
    };
    if list.is_empty() || list.len() > MAX_TRAYS {
        return Err(Error::value("trays", format!("expected 1 to {MAX_TRAYS} trays, got {}", list.len())));
    }
    let mut entries: Vec<TrayEntry> = Vec::with_capacity(list.len());
    for (i, v) in list.into_iter().enumerate() {
        let key = format!("trays[{i}]");
        let toml::Value::Table(mut t) = v else {
            return Err(Error::value(key, "expected a table of tray keys ([[trays]])"));
        };
        let name = match t.remove("name") {
            None => None,
            Some(toml::Value::String(s)) => Some(s),
            Some(_) => return Err(Error::value(format!("{key}.name"), "expected a string")),
        };
        let (mut tray_t, mut items_t) = (tray.clone(), items.clone());
        match t.remove("items") {
            None => {}
            Some(toml::Value::Table(u)) => merge(&mut items_t, u),
            Some(_) => return Err(Error::value(format!("{key}.items"), "expected a table of item keys")),
        }
        merge(&mut tray_t, t);
        let mut both = toml::Table::new();
        both.insert("tray".into(), toml::Value::Table(tray_t));
        both.insert("items".into(), toml::Value::Table(items_t));
        let w: Written = serde_path_to_error::deserialize(toml::Value::Table(both)).map_err(|e| {
            let path = e.path().to_string();
            let inner = e.into_inner();
            Error::value(entry_key(&key, &path), super::toml_merge::explain(&inner.to_string())).with_source(inner)
        })?;
        let mut entry = TrayEntry { name: String::new(), tray: w.tray, items: w.items };
        for p in [&mut entry.tray.mesh, &mut entry.items.mesh] {
            if !p.as_os_str().is_empty() && p.is_relative() {
                *p = base.join(&*p);
            }
        }
        entry.name = match name {
            Some(n) if !n.is_empty() && n.len() <= 64 && n.chars().all(name_char) && !n.starts_with('.') => n,
            Some(n) => {
                return Err(Error::value(
                    format!("{key}.name"),
                    format!("expected 1 to 64 letters, digits, '-', '_' or '.' (not first), got \"{n}\""),
                ))
            }
            None => folder_name_of(&entry.tray),
        };
        if let Some(why) = reserved_tray_name(&entry.name) {
            return Err(Error::value(format!("{key}.name"), why));
        }
        if entries.iter().any(|e| e.name == entry.name) {
            return Err(Error::value(
                format!("{key}.name"),
                format!("\"{}\" names an earlier tray too; give each tray its own name", entry.name),
            ));
        }
        entries.push(entry);
    }
    Ok(entries)
}

/// Checks each entry as the cell it makes, naming the entry's keys in errors.
pub(crate) fn validate_trays(cell: &Cell) -> Result<(), Error> {
    for (i, e) in cell.trays.iter().enumerate() {
        cell.with_entry(e).validate_tray().map_err(|err| {
            let key = entry_key(&format!("trays[{i}]"), err.key());
            let mut out = Error::value(key, err.message().to_string());
            if let Some(f) = err.file() {
                out = out.in_file(f);
            }
            out
        })?;
    }
    Ok(())
}

/// `tray.X` of an entry is `trays[i].X`; `items.X` is `trays[i].items.X`.
fn entry_key(entry: &str, key: &str) -> String {
    match key.strip_prefix("tray") {
        Some(rest) if rest.is_empty() || rest.starts_with('.') || rest.starts_with('[') => format!("{entry}{rest}"),
        _ => format!("{entry}.{key}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A one-triangle binary STL: enough for a mesh key to load.
    fn triangle_stl(size: f32) -> Vec<u8> {
        let mut b = vec![0u8; 80];
        b.extend(1u32.to_le_bytes());
        b.extend([0u8; 12]);
        for v in [0.0, 0.0, 0.0, size, 0.0, 0.0, 0.0, size, 0.0] {
            b.extend(v.to_le_bytes());
        }
        b.extend([0u8; 2]);
        b
    }

    #[test]
    fn each_listed_tray_is_a_cell_of_its_own_with_defaults_from_tray_and_items() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("hex.stl"), triangle_stl(10.0)).unwrap();
        let text = "[tray]\nalbedo = 0.7\n[items]\nalbedo = 0.2\n\
            [[trays]]\nkind = \"tray-4\"\n\
            [[trays]]\nname = \"hex\"\nkind = \"mesh\"\nmesh = \"hex.stl\"\nslots = [[0.0, 0.0, 5.0, 0.0]]\n\
            [trays.items]\nsize = [20.0, 20.0, 10.0]\n";
        let cell = Cell::from_toml_str(text, dir.path()).unwrap();
        let cells = cell.tray_cells();
        let names: Vec<&str> = cells.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(names, ["tray-4", "hex"]);
        let (four, hex) = (&cells[0].1, &cells[1].1);
        assert_eq!(four.tray.kind, TrayKind::Tray4);
        assert_eq!((four.tray.albedo, four.items.albedo), (0.7, 0.2), "[tray] and [items] lend defaults");
        assert_eq!(hex.tray.mesh, dir.path().join("hex.stl"), "relative to the cell file");
        assert_eq!(hex.items.size, [20.0, 20.0, 10.0]);
        assert!(four.trays.is_empty() && hex.trays.is_empty());
        assert_eq!(cell.one_tray(Some("hex")).unwrap(), *hex);
        // Written out and read back, the list is the same.
        let again = Cell::from_toml_str(&cell.to_toml_string(), dir.path()).unwrap();
        assert_eq!(again.trays, cell.trays);
        // The hash covers each listed mesh's bytes.
        let before = cell.hashes().unwrap().cell;
        std::fs::write(dir.path().join("hex.stl"), triangle_stl(12.0)).unwrap();
        assert_ne!(cell.hashes().unwrap().cell, before);
        // Where the meshes lie is no difference: the same cell in another folder hashes the same.
        let moved = tempfile::tempdir().unwrap();
        std::fs::copy(dir.path().join("hex.stl"), moved.path().join("hex.stl")).unwrap();
        let there = Cell::from_toml_str(text, moved.path()).unwrap();
        assert_eq!(there.hashes().unwrap().cell, cell.hashes().unwrap().cell);
        assert_eq!(there.first_difference(&cell), None);
    }

    #[test]
    fn a_bad_list_names_the_entry_and_the_key() {
        let cases = [
            ("trays = 3\n", "trays"),
            ("trays = []\n", "trays"),
            ("trays = [1]\n", "trays[0]"),
            ("[[trays]]\nname = \"a\"\n[[trays]]\nname = \"a\"\n", "trays[1].name"),
            ("[[trays]]\n[[trays]]\n", "trays[1].name"),
            ("[[trays]]\nname = \"all-trays\"\n", "trays[0].name"),
            ("[[trays]]\nname = \"tolerance\"\n", "trays[0].name"),
            ("[[trays]]\nname = \"report.html\"\n", "trays[0].name"),
            ("[[trays]]\nname = \"Study.LOCK\"\n", "trays[0].name"),
            ("[[trays]]\nname = \"a.svg\"\n", "trays[0].name"),
            ("[[trays]]\nroughness = 0.0\n", "trays[0].roughness"),
            ("[[trays]]\nspecular = nan\n", "trays[0].specular"),
            (
                "[[trays]]\nname = \"a\"\n[[trays]]\nname = \"b\"\n[trays.items]\nroughness = 5.0\n",
                "trays[1].items.roughness",
            ),
            ("[[trays]]\nname = \"../up\"\n", "trays[0].name"),
            ("[[trays]]\nname = 4\n", "trays[0].name"),
            ("[[trays]]\ncolour = 3\n", "trays[0].colour"),
            ("[[trays]]\nitems = 3\n", "trays[0].items"),
            ("[[trays]]\n[trays.items]\nalbedo = 2.0\n", "trays[0].items.albedo"),
            ("[[trays]]\nkind = \"mesh\"\n", "trays[0].mesh"),
            ("[[trays]]\nname = \"b\"\n[[trays]]\nsymmetries = [7.7]\n", "trays[1].symmetries[0]"),
            ("[[trays]]\nkind = \"tray-4\"\nslots = [[0.0, 0.0, 0.0, 0.0]]\n", "trays[0].slots"),
        ];
        for (text, key) in cases {
            let e = Cell::from_toml_str(text, Path::new(".")).unwrap_err();
            assert_eq!(e.key(), key, "{text}: {e}");
        }
        let too_many = "[[trays]]\n".repeat(MAX_TRAYS + 1);
        assert_eq!(Cell::from_toml_str(&too_many, Path::new(".")).unwrap_err().key(), "trays");
    }

    #[test]
    fn a_command_of_one_tray_is_told_which() {
        let cell = Cell::from_toml_str("[[trays]]\nname = \"a\"\n[[trays]]\nname = \"b\"\n", Path::new(".")).unwrap();
        let e = cell.one_tray(None).unwrap_err();
        assert!(e.message().contains("--tray") && e.message().contains("a, b"), "{e}");
        assert!(cell.one_tray(Some("c")).unwrap_err().message().contains("a, b"));
        assert_eq!(Cell::default().one_tray(None).unwrap(), Cell::default());
        assert!(Cell::default().one_tray(Some("a")).is_err());
        // Through a file: the file is named, and the built-in cell stands in for none.
        let dir = std::env::temp_dir().join(format!("camplace-one-tray-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("cell.toml");
        std::fs::write(&file, "[[trays]]\nname = \"a\"\n[[trays]]\nname = \"b\"\n").unwrap();
        let e = Cell::load_one(Some(&file), None).unwrap_err();
        assert!(e.to_string().contains("cell.toml") && e.message().contains("a, b"), "{e}");
        assert_eq!(Cell::load_one(Some(&file), Some("b")).unwrap(), cell.one_tray(Some("b")).unwrap());
        assert_eq!(Cell::load_one(None, None).unwrap(), Cell::default());
        assert_eq!(Cell::load_or_default(Some(&file)).unwrap().trays.len(), 2);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
