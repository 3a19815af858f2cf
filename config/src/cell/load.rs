//! Reading a cell: the file's text laid over the built-in default (`default_cell.toml`)
//! key by key, the paper preset's keys, relative mesh paths, a fragment laid over a cell,
//! and TOML syntax errors placed at their key and line. Every value is then checked
//! (`check.rs`).

use std::path::Path;

use super::schema::Cell;
use super::toml_merge::{explain, merge};
use super::trays::parse_trays;
use crate::{Error, ErrorKind};

/// The commented default cell file, as `camplace init` writes it.
pub const DEFAULT_CELL_TOML: &str = include_str!("default_cell.toml");
/// The keys the paper preset sets, and to what (the feature radius from SRes).
fn paper_preset_keys(surface_resolution: f64) -> [(&'static str, toml::Value); 8] {
    [
        ("model_viewpoints", toml::Value::Integer(6)),
        ("icp_trim", toml::Value::Float(0.0)),
        ("icp_on_table", toml::Value::Boolean(false)),
        ("pose_on_table", toml::Value::Boolean(false)),
        ("ransac_sample", toml::Value::Integer(3)),
        ("feature_radius", toml::Value::Float(10.0 * surface_resolution)),
        ("turn_check", toml::Value::Boolean(false)),
        ("verify", toml::Value::Boolean(false)),
    ]
}

/// Lays the paper preset's keys over the merged `[estimator]` table when the user's asks
/// for it; a key the preset sets given beside it is refused, since one of the two would be
/// ignored.
fn apply_preset(merged: &mut toml::Table, user: &toml::Table) -> Result<(), Error> {
    let user_est = match user.get("estimator") {
        Some(toml::Value::Table(t)) => t,
        _ => return Ok(()),
    };
    if user_est.get("preset").and_then(|v| v.as_str()) != Some("paper") {
        return Ok(());
    }
    let Some(toml::Value::Table(est)) = merged.get_mut("estimator") else { return Ok(()) };
    let sres = est.get("surface_resolution").and_then(|v| v.as_float()).unwrap_or(2.0);
    for (key, value) in paper_preset_keys(sres) {
        // The same value again (a cell written out and read back) is no conflict.
        let same = |given: &toml::Value| match (given, &value) {
            (toml::Value::Integer(a), toml::Value::Float(b)) => *a as f64 == *b,
            (a, b) => a == b,
        };
        if let Some(given) = user_est.get(key).filter(|g| !same(g)) {
            return Err(Error::value(
                format!("estimator.{key}"),
                format!(
                    "given as {given} beside preset = \"paper\", which sets it to {value}; leave it out or use preset = \"ours\""
                ),
            ));
        }
        est.insert(key.to_string(), value);
    }
    Ok(())
}
impl Default for Cell {
    /// The built-in default cell (`default_cell.toml`).
    fn default() -> Self {
        Cell::from_toml_str(DEFAULT_CELL_TOML, Path::new(".")).expect("the built-in cell file is valid")
    }
}

impl Cell {
    /// Reads a cell file, laid over the built-in default, and checks every value.
    pub fn load(path: &Path) -> Result<Cell, Error> {
        let text = crate::formats::read::read_text(path)?;
        let base = path.parent().unwrap_or(Path::new("."));
        Cell::from_toml_str(&text, base).map_err(|e| e.in_file(path))
    }

    /// The cell of the file `path`, or the built-in cell without one: what every command's
    /// `--cell` reads.
    pub fn load_or_default(path: Option<&Path>) -> Result<Cell, Error> {
        path.map_or_else(|| Ok(Cell::default()), Cell::load)
    }

    /// [`Cell::load_or_default`] narrowed to one tray ([`Cell::one_tray`]): `tray` by name,
    /// or the cell's only one; an error names the file.
    pub fn load_one(path: Option<&Path>, tray: Option<&str>) -> Result<Cell, Error> {
        let cell = Cell::load_or_default(path)?;
        cell.one_tray(tray).map_err(|e| match path {
            Some(p) => e.in_file(p),
            None => e,
        })
    }

    /// Parses cell text laid over the default; mesh paths are resolved against `base`.
    pub fn from_toml_str(text: &str, base: &Path) -> Result<Cell, Error> {
        let mut user: toml::Table = text.parse().map_err(|e: toml::de::Error| {
            let (key, line) = toml_error_place(text, e.span().map_or(0, |s| s.start));
            let msg = e.message().to_string();
            Error::new(ErrorKind::Format, key, format!("line {line}: not valid TOML: {msg}")).with_source(e)
        })?;
        let listed = user.remove("trays");
        let mut merged: toml::Table = DEFAULT_CELL_TOML.parse().expect("built-in cell parses");
        let asked = user.clone();
        merge(&mut merged, user);
        apply_preset(&mut merged, &asked)?;
        let section = |name: &str| match merged.get(name) {
            Some(toml::Value::Table(t)) => t.clone(),
            _ => toml::Table::new(),
        };
        let (tray_table, items_table) = (section("tray"), section("items"));
        let mut cell: Cell = serde_path_to_error::deserialize(toml::Value::Table(merged)).map_err(|e| {
            let key = e.path().to_string();
            let inner = e.into_inner();
            Error::value(key, explain(&inner.to_string())).with_source(inner)
        })?;
        for p in [&mut cell.tray.mesh, &mut cell.items.mesh] {
            if !p.as_os_str().is_empty() && p.is_relative() {
                *p = base.join(&*p);
            }
        }
        if let Some(list) = listed {
            cell.trays = parse_trays(list, &tray_table, &items_table, base)?;
        }
        cell.validate()?;
        Ok(cell)
    }

    /// This cell with the cell text `fragment` laid over it key by key, as a cell file is
    /// laid over the default (a fragment from `camplace fit-sensor`, say); mesh paths of the
    /// fragment are resolved against `base`, and every value is checked again.
    pub fn overlaid(&self, fragment: &str, base: &Path) -> Result<Cell, Error> {
        let fragment: toml::Table = fragment.parse().map_err(|e: toml::de::Error| {
            let (key, line) = toml_error_place(fragment, e.span().map_or(0, |s| s.start));
            let msg = e.message().to_string();
            Error::new(ErrorKind::Format, key, format!("line {line}: not valid TOML: {msg}")).with_source(e)
        })?;
        let mut merged: toml::Table = self.to_toml_string().parse().expect("a cell's own text parses");
        merge(&mut merged, fragment);
        Cell::from_toml_str(&toml::to_string(&merged).expect("a table serialises"), base)
    }

    /// The cell as TOML text (no comments; `camplace init` writes the commented file).
    pub fn to_toml_string(&self) -> String {
        toml::to_string(self).expect("a cell always serialises")
    }
}

/// Where a TOML syntax error sits: the dotted key being written there (the table header
/// above it and the key on its line, as far as they can be read) and the 1-based line.
fn toml_error_place(text: &str, at: usize) -> (String, usize) {
    let before = text.get(..at.min(text.len())).unwrap_or(text);
    let line_no = before.matches('\n').count() + 1;
    let line = text.lines().nth(line_no - 1).unwrap_or("").trim();
    let table = before
        .lines()
        .rev()
        // The last piece of `before` is the start of the error's own line, unless the error
        // sits at a line's first byte.
        .skip(usize::from(!before.is_empty() && !before.ends_with('\n')))
        .map(str::trim)
        .find(|l| l.starts_with('['))
        .map(|l| l.trim_matches(|c| c == '[' || c == ']').trim().to_string());
    let on_line = line
        .split('=')
        .next()
        .map(str::trim)
        .filter(|k| line.contains('=') && !k.is_empty() && !k.starts_with('[') && !k.starts_with('#'));
    let key = match (line.starts_with('['), table, on_line) {
        (true, _, _) => line.trim_matches(|c| c == '[' || c == ']').trim().to_string(),
        (false, Some(t), Some(k)) => format!("{t}.{k}"),
        (false, None, Some(k)) => k.to_string(),
        (false, Some(t), None) => t,
        (false, None, None) => String::new(),
    };
    (key, line_no)
}
