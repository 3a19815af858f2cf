//! A cell that handles several products: `[[trays]]`, a list of trays each with its mesh,
//! slots, symmetries and items. An entry names only what differs from the cell's `[tray]`
//! and `[items]` tables; a study asks one placement to serve every tray listed. Everything
//! that works on one tray sees each entry as a cell of its own ([`Cell::tray_cells`]).

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::cell::merge;
use crate::{Cell, Error, Items, Tray, TrayKind};

/// The most trays a cell may list.
pub const MAX_TRAYS: usize = 16;

/// One tray of a cell's list, with the items its slots hold.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrayEntry {
    /// The tray's name in folders and reports: letters, digits, `-`, `_` and `.`.
    pub name: String,
    pub tray: Tray,
    pub items: Items,
}

/// How an entry is written in the cell file: the tray's keys, `name` and an `items` table.
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
            (Some(name), true) => Err(Error::value(
                "trays",
                format!("--tray {name}: the cell lists no trays (its one tray is [tray])"),
            )),
            (None, false) => Err(Error::value(
                "trays",
                format!("the cell lists {} trays ({}); this command works on one: give --tray NAME", self.trays.len(), names()),
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
            Error::value(entry_key(&key, &path), crate::cell::explain(&inner.to_string())).with_source(inner)
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
